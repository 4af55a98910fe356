"""The runs of a simulation sweep: its grid, its jobs, and the task every job runs with.

A sweep's runs are the cells of a :class:`Grid` (the product or the zip of a state table and
a parameter table); a :class:`SimulationJob` holds consecutive runs, and the
:class:`SimulationTask` (the simulator, the run's length and options, ``reduce``; sent once
per worker) simulates a job with the batch machinery (:func:`._batch_progress.run_batch`) and
finishes it: status, failing step and message of every run, and ``reduce``'s value of each
run or the raw arrays of its trajectory (a :class:`ChunkResult`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .._errors import ShapeError, SymgroupoidError
from ._batch import TrajectoryBatch
from ._batch_progress import run_batch
from ._options import NewtonOptions
from ._runs import INTERRUPTED, OK, BatchRun
from ._sweep_result import STOPPED

#: how a sweep pairs its inputs: every one with every other, or the i-th with the i-th
COMBINE = ("product", "zip")


class ReduceError(SymgroupoidError, RuntimeError):
    """``reduce`` raised an exception on a run (the message names the run)."""


def reduced(reduce: Callable, run, where: str):
    """``reduce(run)`` without references into a task's arrays (:func:`_detached`); an
    exception it raises becomes a :class:`ReduceError` that says ``where``."""
    try:
        return _detached(reduce(run))
    except (Exception, SystemExit) as exc:  # (sys.exit in a reduce ends no program)
        raise ReduceError(f"{where}: {type(exc).__name__}: {exc}") from exc


def _detached(value):
    """``value`` without references into a task's arrays: an array that is a view is
    copied (also inside lists, tuples and dicts), so that a kept value does not keep the
    states of a whole part of a task alive."""
    if isinstance(value, np.ndarray):
        return value.copy() if value.base is not None else value
    if isinstance(value, (list, tuple)):
        items = [_detached(v) for v in value]
        if hasattr(value, "_fields"):  # a named tuple
            return type(value)(*items)
        return type(value)(items)
    if isinstance(value, dict):
        return type(value)((k, _detached(v)) for k, v in value.items())
    return value


@dataclass
class Grid:
    """Run r ↦ (state row, parameter row) and the result's shape."""

    combine: str
    n_states: int
    n_params: int
    one_state: bool
    one_param: bool

    @property
    def shape(self) -> tuple:
        if self.combine == "product":
            return ((() if self.one_state else (self.n_states,))
                    + (() if self.one_param else (self.n_params,)))
        return () if self.one_state and self.one_param else (max(self.n_states,
                                                                  self.n_params),)

    @property
    def size(self) -> int:
        return int(np.prod(self.shape, dtype=np.int64))

    def rows(self, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
        r = np.arange(a, b, dtype=np.int64)
        if self.combine == "product":
            return r // self.n_params, r % self.n_params
        return (np.zeros_like(r) if self.one_state else r,
                np.zeros_like(r) if self.one_param else r)

    def index(self, r: int) -> tuple:
        i, j = self.rows(r, r + 1)
        return int(i[0]), int(j[0])


def sweep_grid(combine: str, n_states: int, n_params: int, one_state: bool,
               one_param: bool, owner: str) -> Grid:
    """The :class:`Grid` of a sweep's runs (``zip`` pairs tables of one length, or a single
    state or set with all)."""
    if combine == "zip" and not (one_state or one_param) and n_states != n_params:
        raise ShapeError(f"{owner}: combine='zip' pairs the i-th initial state with the i-th "
                         f"parameter set; got {n_states} states and {n_params} sets")
    return Grid(combine, n_states, n_params, one_state, one_param)


@dataclass
class ChunkResult:
    """What a task returns: per run of the task its status, failure data, and its value or
    the raw arrays of its trajectory."""

    first: int
    status: np.ndarray
    failed_step: np.ndarray
    messages: list
    values: list | None
    raw: BatchRun | None = None

    def unsendable(self, dumps: Callable) -> ReduceError | None:
        """Why these results cannot go back from a worker process (``dumps`` failed on
        them): a :class:`ReduceError` naming the first run whose reduced value does not
        pickle, or None when the values are not the cause."""
        for i, value in enumerate(self.values or ()):
            try:
                dumps(value)
            except Exception as why:  # noqa: BLE001 - any value that does not travel
                return ReduceError(
                    f"reduce's value on run {self.first + i} cannot be sent back from its "
                    f"worker process ({type(why).__name__}: {why}); return numbers, arrays "
                    f"or other values that pickle, or use executor='thread'")
        return None


@dataclass
class SimulationJob:
    """Runs ``first``, ``first + 1``, … of a simulation sweep: their initial states (rows
    of S), parameter sets (rows of P, or one row for all) and, for a forced system, input
    sequences (U: (runs, steps, m), or (steps, m) for all; docs/conventions.md §20)."""

    first: int
    S: np.ndarray
    P: np.ndarray
    U: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.S)

    def parts(self, size: int) -> list[SimulationJob]:
        """The job in consecutive parts of at most ``size`` runs."""
        one = len(self.P) == 1
        shared = self.U is None or self.U.ndim == 2
        return [SimulationJob(self.first + a, self.S[a:a + size],
                              self.P if one else self.P[a:a + size],
                              self.U if shared else self.U[a:a + size])
                for a in range(0, len(self), max(size, 1))] or [self]

    def split(self) -> list[SimulationJob]:
        """Its runs one by one (none for a single run)."""
        return self.parts(1) if len(self) > 1 else []

    def lost(self, status: int, message: str) -> ChunkResult:
        """The result of runs that have none (``status``, each run's ``message``)."""
        n = len(self)
        return ChunkResult(self.first, np.full(n, status, np.int64), np.full(n, -1, np.int64),
                           [f"run {self.first + b}: {message}" for b in range(n)], [None] * n)


@dataclass
class SimulationTask:
    """What every task of a simulation sweep shares (sent once per worker): the
    simulator, the run's length and options, ``reduce``, and ``batch_runs``, the runs a
    part of a task holds at once (see :func:`._executors.run_job`)."""

    simulator: object
    steps: int
    every: int
    options: NewtonOptions | None
    reduce: Callable | None
    reduce_failures: bool
    batch_runs: int = 1 << 62

    def simulate(self, job: SimulationJob, stop=None) -> BatchRun:
        """The runs of ``job`` (one thread; ``stop()`` asked between kernel calls)."""
        return run_batch(self.simulator, job.S, job.P, self.steps, self.every, self.options,
                         1, stop, U=job.U)

    def finish(self, job: SimulationJob, raw: BatchRun, cut: int | None = None
               ) -> ChunkResult:
        """Status, failing step and message of every run, and its reduced value (run by
        run) or its raw arrays; runs stopped from outside get status ``cut`` (when
        given)."""
        sim = self.simulator
        batch = TrajectoryBatch(sim, raw, job.P, self.steps, self.every, self.options,
                                fill=False)
        status = batch.status.copy()
        messages = []
        for b in range(len(batch)):
            if status[b] == INTERRUPTED:
                status[b] = cut or INTERRUPTED
                messages.append(f"{sim.name}: run {job.first + b}: not completed: "
                                f"{STOPPED[int(status[b])]} (at step "
                                f"{int(batch.failed_step[b])} of {self.steps})")
            else:
                messages.append(None if status[b] == OK else str(batch.error(b)))
        values = None
        if self.reduce is not None:
            values = [self._reduced(batch, b, job.first + b, status[b])
                      for b in range(len(batch))]
            raw = None
        return ChunkResult(job.first, status, batch.failed_step.copy(), messages, values, raw)

    def _reduced(self, batch: TrajectoryBatch, b: int, run: int, status: int):
        if status != OK and not self.reduce_failures:
            return None
        return reduced(self.reduce, batch[b], f"{self.simulator.name}: reduce raised on run "
                                              f"{run}")

    @staticmethod
    def merge(results: list[ChunkResult]) -> ChunkResult:
        """The results of consecutive parts of a job as one."""
        if len(results) == 1:
            return results[0]
        raws = [r.raw for r in results]
        raw = None
        if all(r is not None for r in raws):
            raw = BatchRun(*(np.concatenate([getattr(r, f) for r in raws])
                             for f in BatchRun.__dataclass_fields__))
        values = None if results[0].values is None else [v for r in results for v in r.values]
        return ChunkResult(results[0].first, np.concatenate([r.status for r in results]),
                           np.concatenate([r.failed_step for r in results]),
                           [m for r in results for m in r.messages], values, raw)

