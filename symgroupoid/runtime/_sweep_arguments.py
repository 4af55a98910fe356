"""The arguments every sweep takes, checked before any run starts.

:func:`sweep` and :func:`sweep_boundary_value` share how their runs are reduced, where
and in tasks of how many runs they go, how long a task may take and how progress is shown:
:func:`sweep_controls` checks these in one order for both, each error naming the argument.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import NamedTuple

from .._arguments import callable_argument, flag_argument, real_argument
from .._errors import DomainError, InputTypeError
from ._validate import integer_argument


class SweepControls(NamedTuple):
    """The checked arguments a sweep shares with every other sweep."""

    reduce: Callable | None
    reduce_failures: bool
    client: object
    progress: object
    timeout: float | None
    chunk_size: int | None


def sweep_controls(reduce, reduce_failures, client, progress, timeout, chunk_size,
                   owner: str) -> SweepControls:
    """``reduce`` (None or a function), ``reduce_failures`` (a flag), ``client``
    (:func:`client_argument`), ``progress`` (:func:`progress_argument`), ``timeout``
    (:func:`local_timeout`) and ``chunk_size`` (None or an integer ≥ 1), in this order."""
    reduce = callable_argument(reduce, "reduce", owner=owner, none=True)
    reduce_failures = flag_argument(reduce_failures, "reduce_failures", owner=owner)
    client = client_argument(client, owner)
    progress = progress_argument(progress, owner)
    timeout = local_timeout(timeout, client, owner)
    if chunk_size is not None:
        chunk_size = integer_argument(chunk_size, "chunk_size", minimum=1, owner=owner)
    return SweepControls(reduce, reduce_failures, client, progress, timeout, chunk_size)


#: the most workers of a local sweep: four per core (at least 64)
MAX_WORKERS = max(64, 4 * (os.cpu_count() or 1))


def workers_argument(workers, owner: str) -> int:
    """``workers``: an integer 1 … :data:`MAX_WORKERS` (a sweep starts one thread or process
    per task up to this number, so a huge count would start thousands)."""
    return integer_argument(workers, "workers", minimum=1, maximum=MAX_WORKERS, owner=owner)


def timeout_argument(timeout, owner: str) -> float | None:
    """``timeout``: None or a positive number of seconds (per task)."""
    if timeout is None:
        return None
    value = real_argument(timeout, "timeout", finite=False, owner=owner)  # (range: below)
    if not 0 < value < math.inf:
        raise DomainError(f"{owner}: timeout must be a positive, finite number of seconds "
                          f"(or None), got {timeout!r}")
    return value



def local_timeout(timeout, client, owner: str) -> float | None:
    """``timeout`` (:func:`timeout_argument`) for a local sweep: not with ``client``."""
    timeout = timeout_argument(timeout, owner)
    if timeout is not None and client is not None:
        raise InputTypeError(f"{owner}: timeout= limits the tasks of a local sweep (threads "
                             f"or processes); on a Dask cluster use Dask's own limits")
    return timeout


def progress_argument(progress, owner: str):
    """``progress`` of a sweep: None, True, False or a function ``progress(done, total)``."""
    if progress is None or callable(progress):
        return progress
    return flag_argument(progress, "progress", owner=owner,
                         accepted="True, False, None or a function progress(done, total)")


def client_argument(client, owner: str):
    """``client``: None or a ``dask.distributed.Client`` (anything with ``submit`` and
    ``nthreads``)."""
    if client is None or all(callable(getattr(client, m, None)) for m in ("submit",
                                                                          "nthreads")):
        return client
    raise InputTypeError(f"{owner}: client must be a dask.distributed.Client (or None), got "
                         f"{type(client).__name__}")


def check_sendable(reduce, owner: str) -> None:
    """``reduce`` for worker processes: without cloudpickle, a function of the user's
    script cannot travel (the workers never import the script)."""
    if reduce is None or getattr(reduce, "__module__", None) != "__main__":
        return
    try:
        import cloudpickle  # noqa: F401
    except ImportError:
        from ._pickle import NotPortableError

        raise NotPortableError(
            f"{owner}: executor='process' sends reduce to worker processes, which do not run "
            f"your script; {getattr(reduce, '__qualname__', reduce)!r} is defined in it: "
            f"install cloudpickle (pip install cloudpickle; it sends such functions by "
            f"value), move reduce into a module you import, or use executor='thread'"
        ) from None

