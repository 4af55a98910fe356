"""What a sweep returns: :class:`SweepResult`, and its runs collected as they come.

The results of a sweep's tasks arrive in any order, from threads, worker processes or a
Dask cluster; :class:`Collected` places them by run index (each run once), reports progress
(:class:`Progress`: a one-line bar on stderr or the user's callback) and, when the sweep is
interrupted, makes the partial result: the runs not done carry status
:data:`~symgroupoid.Status.INTERRUPTED`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._errors import CallableError, DomainError
from ._executors import TIMED_OUT, WORKER_DIED, ClusterLostError
from ._runs import INTERRUPTED, OK

#: the statuses of runs stopped from outside (not kernel statuses; see SweepResult) and
#: their texts
STOPPED = {s: s.message for s in (INTERRUPTED, TIMED_OUT, WORKER_DIED)}


@dataclass
class SweepResult:
    """The runs of a sweep, indexed like its inputs.

    ``shape``: product: (number of initial states, number of parameter sets), zip: (number
    of runs,); an axis is absent when its input was a single state or set.  Per run:

    - ``status``: 0 completed, else the reason it stopped, a :class:`~symgroupoid.Status`
      (``Status(code).message``; 1 singular Jacobian, 2 Newton's iteration cap, 3 non-finite
      value, 5 Newton stalled, 6 a branch jump — the kernel's statuses; boundary-value runs:
      1 singular Jacobian, 2 not converged, 7 the cut locus of the chart; stopped from
      outside: 10 ``INTERRUPTED`` — not run to its end because the sweep was interrupted, in
      the partial result of a ``KeyboardInterrupt``, 11 ``TIMED_OUT`` — its task exceeded
      ``timeout``, 12 ``WORKER_DIED`` — its worker process died while running it, alone);
      ``ok``: ``status == 0``; ``failed_step``: the failing step (the step a
      stopped run reached; −1 if none or unknown; simulations);
    - ``values`` (shape + the shape of one value): ``reduce``'s value of each run (a failed
      run, not reduced unless ``reduce_failures``, holds NaN for numeric values, None
      otherwise — check ``ok``); without ``reduce``: ``trajectories`` (simulations: each run's
      :class:`Trajectory`, up to its failure) or ``solutions`` (boundary values: each
      :class:`BoundaryValueSolution`, None where it failed);
    - ``messages``: the error text of each failed run (None where it completed);
    - ``initial``, ``parameters``: the input tables (rows: states, parameter sets);
      ``parameter_names``; ``seconds``: the wall time of the runs; ``tasks``: how many tasks.
    """

    shape: tuple
    combine: str
    status: np.ndarray
    failed_step: np.ndarray
    messages: np.ndarray
    values: np.ndarray | None
    trajectories: np.ndarray | None
    solutions: np.ndarray | None
    initial: object
    parameters: np.ndarray
    parameter_names: list
    index: Callable[[int], tuple]
    seconds: float = 0.0
    tasks: int = 0

    @property
    def ok(self) -> np.ndarray:
        return self.status == OK

    def __len__(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64))

    def masked(self) -> np.ma.MaskedArray:
        """``values`` with the failed runs masked."""
        if self.values is None:
            raise DomainError("masked: this sweep has no reduced values (no reduce was given)")
        mask = ~self.ok
        mask = mask.reshape(mask.shape + (1,) * (self.values.ndim - mask.ndim))
        return np.ma.masked_array(self.values, np.broadcast_to(mask, self.values.shape))

    def to_dataframe(self):
        """One row per run (pandas): its input indices, its parameters by name, status,
        failed step, error message and value (a vector value: one column per entry)."""
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - pandas is optional
            raise ImportError("SweepResult.to_dataframe needs pandas (pip install pandas)"
                              ) from exc
        n = len(self)
        columns: dict = {}
        where = [self.index(r) for r in range(n)]
        if self.combine == "product":
            columns["initial"] = [w[0] for w in where]
            columns["parameters"] = [w[1] for w in where]
        else:
            columns["run"] = np.arange(n)
        pidx = np.array([w[1] for w in where], dtype=np.int64)
        for k, name in enumerate(self.parameter_names):
            columns[name] = self.parameters[pidx, k]
        columns["status"] = self.status.reshape(-1)
        columns["failed_step"] = self.failed_step.reshape(-1)
        columns["message"] = self.messages.reshape(-1)
        if self.values is not None:
            flat = self.values.reshape(n, -1)
            if flat.shape[1] == 1:
                columns["value"] = flat[:, 0]
            else:
                for k in range(flat.shape[1]):
                    columns[f"value_{k}"] = flat[:, k]
        return pd.DataFrame(columns)

    def __repr__(self) -> str:
        return (f"<SweepResult: {len(self)} runs, shape {self.shape}, "
                f"{int((~self.ok).sum())} failed, {self.seconds:.2f} s>")



class Progress:
    """A one-line progress report on stderr (or a callable ``progress(done, total)``)."""

    def __init__(self, total: int, progress, label: str):
        self.total, self.label, self.done = total, label, 0
        self.callback = progress if callable(progress) else None
        enabled = sys.stderr.isatty() if progress is None else bool(progress)
        self.enabled = enabled and self.callback is None
        self.t0 = self.last = time.perf_counter()

    def update(self, n: int) -> None:
        self.done += n
        if self.callback is not None:
            try:
                self.callback(self.done, self.total)
            except Exception as exc:  # noqa: BLE001 - the user's callback, any failure
                raise CallableError(f"{self.label}: the progress callback progress(done, "
                                    f"total) raised {exc!r}") from exc
            return
        now = time.perf_counter()
        if self.enabled and (now - self.last > 0.2 or self.done == self.total):
            self.last = now
            frac = self.done / self.total if self.total else 1.0
            bar = "#" * int(30 * frac)
            sys.stderr.write(f"\r{self.label}: [{bar:<30}] {self.done}/{self.total} runs "
                             f"({100 * frac:.0f}%) {now - self.t0:.1f} s")
            sys.stderr.flush()

    def close(self) -> None:
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()



def _collect(shape: tuple, n: int):
    status = np.full(n, -1, dtype=np.int64)
    failed = np.full(n, -1, dtype=np.int64)
    messages = np.empty(n, dtype=object)
    return status, failed, messages


def stack_values(parts: list[tuple[int, list]], status: np.ndarray, shape: tuple
                 ) -> np.ndarray:
    """The reduced values as one array (numeric: shape + value shape, NaN where a run has
    no value; otherwise an object array)."""
    n = len(status)
    values = [None] * n
    for first, chunk in parts:
        values[first:first + len(chunk)] = chunk
    present = [v for v in values if v is not None]
    arrays = [np.asarray(v) for v in present]
    numeric = arrays and all(a.dtype.kind in "biuf" for a in arrays) and len(
        {a.shape for a in arrays}) == 1
    if numeric:
        vshape = arrays[0].shape
        dtype = np.result_type(*{a.dtype for a in arrays})
        if len(present) < n:
            dtype = np.result_type(dtype, np.float64)
        out = np.full((n,) + vshape, np.nan if dtype.kind == "f" else 0, dtype=dtype)
        k = 0
        for r, v in enumerate(values):
            if v is not None:
                out[r] = arrays[k]
                k += 1
        return out.reshape(shape + vshape)
    out = np.empty(n, dtype=object)
    for r, v in enumerate(values):
        out[r] = v
    return out.reshape(shape)



class Collected:
    """The results of a sweep as they come (placed by run index, each run once), and the
    partial result of an interrupted sweep."""

    def __init__(self, name: str, shape: tuple, total: int, bar: Progress):
        self.name, self.shape, self.bar = name, shape, bar
        self.status, self.failed, self.messages = _collect(shape, total)
        self.filled = np.zeros(total, dtype=bool)
        self.values: list = []
        self.t0 = time.perf_counter()
        self.t1: float | None = None
        #: why the runs without a result in a partial result have none
        self.unfinished = STOPPED[INTERRUPTED]

    def place(self, first: int, n: int, status, failed, messages, values) -> None:
        """Runs first … first + n − 1, marked received last (a Ctrl-C in between leaves
        them out of the partial result, never half in)."""
        where = slice(first, first + n)
        if self.filled[where].any():
            raise RuntimeError(f"internal error: runs {first}..{first + n - 1} received "
                               f"twice")
        self.status[where], self.failed[where] = status, failed
        self.messages[where] = messages
        if values is not None:
            self.values.append((first, values))
        self.filled[where] = True

    def seconds(self) -> float:
        return (self.t1 or time.perf_counter()) - self.t0

    def run(self, work, result) -> None:
        """``work()``; a ``KeyboardInterrupt`` or a ``ClusterLostError`` leaves with
        ``.result``, the partial :class:`SweepResult`."""
        try:
            work()
        except (KeyboardInterrupt, ClusterLostError) as stop:
            self.t1 = time.perf_counter()
            if isinstance(stop, ClusterLostError):
                self.unfinished = "the sweep's Dask cluster lost its workers"
            stop.result = result(True)
            raise
        finally:
            self.t1 = self.t1 or time.perf_counter()
            self.bar.close()

    def arrays(self, partial: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """status, failed step and messages in the sweep's shape; in a partial result the
        runs without a result are ``INTERRUPTED``."""
        missing = np.flatnonzero(~self.filled)
        if len(missing) and not partial:
            raise RuntimeError(f"internal error: {len(missing)} runs without a result")
        status, failed, messages = self.status.copy(), self.failed.copy(), self.messages.copy()
        status[missing] = INTERRUPTED
        for r in missing:
            messages[r] = f"{self.name}: run {r}: not run: {self.unfinished}"
        return (status.reshape(self.shape), failed.reshape(self.shape),
                messages.reshape(self.shape))

