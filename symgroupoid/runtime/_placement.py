"""Where a sweep's tasks run, and in tasks of how many runs.

:func:`placement` chooses among the calling thread, threads, worker processes and a Dask
cluster (see :mod:`._executors`); :func:`task_runs` sizes the tasks: on threads about
:data:`TASKS_PER_WORKER` tasks per worker, on processes and Dask from a short pilot run so
that the per-task overhead stays below :data:`OVERHEAD_FRACTION` of the work
(:func:`chunk_runs`).
"""

from __future__ import annotations

import math
import os
import time

import numpy as np

from .._arguments import choice_argument
from .._errors import InputTypeError
from ._batch_progress import run_batch, usable_cores
from ._sweep_arguments import workers_argument

#: where the tasks of a local sweep run (see the module docstring)
EXECUTORS = ("thread", "process")
#: the options of :func:`solve_boundary_value` a boundary-value sweep passes on
SOLVER_OPTIONS = ("tol", "tol_step", "max_iterations")
#: per-task overhead assumed when sizing tasks (seconds)
TASK_OVERHEAD = {"thread": 2e-4, "process": 2e-3, "dask": 2e-2, "serial": 1e-4}
#: the overhead a task may cost, as a fraction of its work
OVERHEAD_FRACTION = 0.05
#: tasks per worker aimed at (load balance)
TASKS_PER_WORKER = 4


def chunk_runs(total: int, seconds_per_run: float, workers: int, mode: str,
               chunk_size: int | None = None) -> int:
    """Runs per task: enough that the per-task overhead (``TASK_OVERHEAD``) stays below
    ``OVERHEAD_FRACTION`` of the task's work, and, where that allows, about
    ``TASKS_PER_WORKER`` tasks per worker for load balance."""
    if chunk_size is not None:
        return chunk_size
    per_run = max(seconds_per_run, 1e-9)
    smallest = math.ceil(TASK_OVERHEAD[mode] / (OVERHEAD_FRACTION * per_run))
    balanced = math.ceil(total / (TASKS_PER_WORKER * max(workers, 1)))
    return max(1, min(total, max(smallest, balanced)))


def _seconds_per_run(sim, S: np.ndarray, P: np.ndarray, steps: int, every: int,
                     options, U: np.ndarray | None = None) -> float:
    """The cost of one run, from a short pilot batch (a few runs, at most 200 steps; the
    first runs' inputs ``U`` (runs, steps, m), or the inputs (steps, m) of every run)."""
    n, k = min(len(S), 4), min(steps, 200)
    if n == 0 or k == 0:
        return 1e-6
    if U is not None:
        U = U[:n, :k] if U.ndim == 3 else U[:k]
    t0 = time.perf_counter()
    run_batch(sim, S[:n], P[np.arange(n) % len(P)], k, min(every, k), options, 1, U=U)
    return (time.perf_counter() - t0) / n * (steps / k)


def task_runs(sim, S, P, steps: int, every: int, options, total: int, workers: int,
              mode: str, chunk_size: int | None, batch_runs: int,
              U: np.ndarray | None = None) -> int:
    """Runs per task: ``chunk_size``; on threads (no per-task cost to speak of) about
    ``TASKS_PER_WORKER`` tasks per worker, each at most one part (``batch_runs``); on
    processes and Dask, from a pilot run (:func:`chunk_runs`)."""
    if chunk_size is not None:
        return chunk_size
    if mode in ("serial", "thread"):
        balanced = math.ceil(total / (TASKS_PER_WORKER * max(workers, 1)))
        return max(1, min(total, balanced, batch_runs))
    return chunk_runs(total, _seconds_per_run(sim, S, P, steps, every, options, U), workers,
                      mode)



def placement(client, executor, workers, portable: bool, owner: str) -> tuple[str, int]:
    """(where the tasks run — ``serial``, ``thread``, ``process`` or ``dask`` —, how many
    workers)."""
    from ._pickle import NotPortableError

    if client is not None:
        if executor is not None:
            raise InputTypeError(f"{owner}: executor= chooses where a local sweep runs; with "
                                 f"client= the tasks run on the Dask cluster (give one of "
                                 f"them)")
        if not portable:
            raise NotPortableError(f"{owner}: a NumPy-backend simulator cannot be sent to a "
                                   f"cluster; compile the step with backend='c'")
        return "dask", max(1, len(client.nthreads()))
    executor = "thread" if executor is None else choice_argument(executor, EXECUTORS,
                                                                 "executor", owner=owner)
    n = usable_cores() if workers is None else workers_argument(workers, owner)
    if executor == "process":
        if not portable:
            raise NotPortableError(f"{owner}: a NumPy-backend simulator cannot be sent to "
                                   f"worker processes; compile the step with backend='c', "
                                   f"or use executor='thread'")
        if os.name != "posix":  # pragma: no cover - the workers' pipes are POSIX
            raise InputTypeError(f"{owner}: executor='process' needs a POSIX system; use "
                                 f"executor='thread'")
        return "process", n
    if not portable or n == 1:  # (NumPy kernels hold the GIL: threads would not help)
        return "serial", 1
    return "thread", n
