"""Sweeps: many runs over a grid or a list of initial states and parameter sets.

:func:`sweep` runs a compiled simulator over the product (or the zip) of a table of initial
states and a table of parameter sets; :func:`sweep_boundary_value` solves a boundary-value
problem for each combination of start, end and parameters.  Runs are grouped into tasks; a
task advances its runs with :meth:`Simulator.simulate_batch`'s machinery and, with
``reduce``, keeps only ``reduce(trajectory)`` of each run: its runs are simulated in parts of
at most about :data:`BATCH_BYTES` of kept states and reduced run by run, so memory grows
with what is kept, not with the trajectories.

Where the tasks run (see :mod:`._executors`):

- ``executor="thread"`` (the default): ``workers`` threads (default: all cores) call the
  compiled kernel, which releases the GIL, while the calling thread reduces the runs as
  they come.  Nothing is pickled (``reduce`` may be any function, a lambda or a closure) and
  nothing is imported again: a plain script runs as written, without a ``__main__`` guard.
  With ``workers=1``, or one task, the calling thread does everything.
- ``executor="process"``: worker processes that import symgroupoid, never the user's
  script; ``reduce`` travels with cloudpickle when installed (lambdas, functions of the
  script), else with pickle (then it must be importable from a module).  A reduce that may
  crash or hang its process belongs here: a worker that dies is replaced and the runs of
  its task are run again one by one to find and record the run that killed it
  (status :data:`WORKER_DIED`); a task over ``timeout`` is stopped with its worker.
- ``client=`` a ``dask.distributed.Client``: on its cluster.  The simulator travels as its
  generated C, flags and content hash (:mod:`._pickle`), once per worker: each worker builds
  the kernel into its own cache, or loads it from there, and reuses it for all its tasks.
  A worker lost mid-sweep is survived through Dask's rescheduling of its tasks; results are
  placed by run index, so no run is lost or counted twice.

A run that fails (a singular Jacobian, Newton not converging, a non-finite value) is a
result: its status and failing step are recorded and the sweep goes on.  Errors in the
inputs are raised before any run starts.  Ctrl-C stops a sweep within about a second: the
``KeyboardInterrupt`` carries ``.result``, the :class:`SweepResult` of the runs completed so
far (the others with status :data:`INTERRUPTED`).
"""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .._arguments import (
    callable_argument,
    choice_argument,
    flag_argument,
    instance_argument,
    real_argument,
)
from .._errors import (
    CallableError,
    CutLocusError,
    DomainError,
    InputTypeError,
    NewtonDivergenceError,
    ShapeError,
    SingularJacobianError,
    SymgroupoidError,
)
from ..stepper import Status
from ._batch import (
    TrajectoryBatch,
    _at_row,
    _check_memory,
    check_constraints,
    parameter_table,
    run_batch,
    run_bytes,
    state_table,
    usable_cores,
)
from ._executors import TIMED_OUT, WORKER_DIED, execute
from ._options import NewtonOptions
from ._runs import INTERRUPTED, OK, BatchRun, batch_rows
from ._validate import integer_argument, system_argument

COMBINE = ("product", "zip")
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
#: kept states a part of a task holds at once with ``reduce`` (bytes; at least one run)
BATCH_BYTES = 1 << 24
#: status of a boundary-value run that met the cut locus of the chart
CUT_LOCUS = Status.CUT_LOCUS
#: the statuses of runs stopped from outside (not kernel statuses; see SweepResult) and
#: their texts
STOPPED = {s: s.message for s in (INTERRUPTED, TIMED_OUT, WORKER_DIED)}


class ReduceError(SymgroupoidError, RuntimeError):
    """``reduce`` raised an exception on a run (the message names the run)."""


# --- results ------------------------------------------------------------------------------------

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


# --- the runs -----------------------------------------------------------------------------------

@dataclass
class _Grid:
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


def _grid(combine: str, n_states: int, n_params: int, one_state: bool,
          one_param: bool, owner: str) -> _Grid:
    if combine == "zip" and not (one_state or one_param) and n_states != n_params:
        raise ShapeError(f"{owner}: combine='zip' pairs the i-th initial state with the i-th "
                         f"parameter set; got {n_states} states and {n_params} sets")
    return _Grid(combine, n_states, n_params, one_state, one_param)


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


@dataclass
class SimulationJob:
    """Runs ``first``, ``first + 1``, … of a simulation sweep: their initial states (rows
    of S) and parameter sets (rows of P, or one row for all)."""

    first: int
    S: np.ndarray
    P: np.ndarray

    def __len__(self) -> int:
        return len(self.S)

    def parts(self, size: int) -> list[SimulationJob]:
        """The job in consecutive parts of at most ``size`` runs."""
        one = len(self.P) == 1
        return [SimulationJob(self.first + a, self.S[a:a + size],
                              self.P if one else self.P[a:a + size])
                for a in range(0, len(self), max(size, 1))] or [self]

    def split(self) -> list[SimulationJob]:
        """Its runs one by one (none for a single run)."""
        return self.parts(1) if len(self) > 1 else []

    def lost(self, status: int, message: str) -> ChunkResult:
        """The result of runs that have none (``status``, each run's ``message``)."""
        n = len(self)
        return ChunkResult(self.first, np.full(n, status, np.int64), np.full(n, -1, np.int64),
                           [f"run {self.first + b}: {message}" for b in range(n)], [None] * n)


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
                         1, stop)

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
        try:
            return _detached(self.reduce(batch[b]))
        except Exception as exc:
            raise ReduceError(f"{self.simulator.name}: reduce raised on run {run}: "
                              f"{type(exc).__name__}: {exc}") from exc

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


class _Progress:
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


# --- where, and in tasks of how many runs ------------------------------------------------------

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
                     options) -> float:
    """The cost of one run, from a short pilot batch (a few runs, at most 200 steps)."""
    n, k = min(len(S), 4), min(steps, 200)
    if n == 0 or k == 0:
        return 1e-6
    t0 = time.perf_counter()
    run_batch(sim, S[:n], P[np.arange(n) % len(P)], k, min(every, k), options, 1)
    return (time.perf_counter() - t0) / n * (steps / k)


def _task_runs(sim, S, P, steps: int, every: int, options, total: int, workers: int,
               mode: str, chunk_size: int | None, batch_runs: int) -> int:
    """Runs per task: ``chunk_size``; on threads (no per-task cost to speak of) about
    ``TASKS_PER_WORKER`` tasks per worker, each at most one part (``batch_runs``); on
    processes and Dask, from a pilot run (:func:`chunk_runs`)."""
    if chunk_size is not None:
        return chunk_size
    if mode in ("serial", "thread"):
        balanced = math.ceil(total / (TASKS_PER_WORKER * max(workers, 1)))
        return max(1, min(total, balanced, batch_runs))
    return chunk_runs(total, _seconds_per_run(sim, S, P, steps, every, options), workers,
                      mode)


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
    value = real_argument(timeout, "timeout", minimum=0.0, owner=owner)
    if not 0 < value < math.inf:
        raise DomainError(f"{owner}: timeout must be a positive, finite number of seconds "
                          f"(or None), got {timeout!r}")
    return value


def _placement(client, executor, workers, portable: bool, owner: str) -> tuple[str, int]:
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


def _memory_plan(sim, steps: int, every: int, reduced: bool, total: int, mode: str,
                 workers: int) -> int:
    """Runs per part of a task (held at once by a worker), after checking that what the
    sweep holds at once fits in memory (a :class:`TrajectoryTooLargeError` up front).

    Without ``reduce`` every trajectory comes back: all of them must fit.  With it, a part
    holds at most :data:`BATCH_BYTES` of kept states (at least one run); threads hold
    ``2·workers + 1`` parts at once (being simulated, waiting, being reduced), each worker
    process one."""
    rows = batch_rows(steps, every)
    if not reduced:
        _check_memory(sim, total, rows, steps, every)
        return 1 << 62
    part = max(1, min(total, BATCH_BYTES // run_bytes(sim, rows)))
    held = {"thread": 2 * workers + 1, "process": workers}.get(mode, 1)
    runs = min(total, held * part)
    advice = ("reduce receives each run's whole trajectory: keep fewer states with every=k "
              "(or process a run this long on the fly with Simulator.stream)")
    if runs > part:
        advice += f", or use fewer workers (each holds a part of {part} run(s) at a time)"
    _check_memory(sim, runs, rows, steps, every, held=" held at once", advice=advice)
    return part


def _check_sendable(reduce, owner: str) -> None:
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


# --- simulation sweeps --------------------------------------------------------------------------

def _as_simulator(sim):
    """A :class:`Simulator`, or step equations compiled here; an
    :class:`~symgroupoid.InputTypeError` for anything else."""
    from ..equations import StepEquations
    from ._simulator import Simulator

    if isinstance(sim, Simulator):
        return sim
    instance_argument(sim, StepEquations, "sim", "a Simulator (step.compile()) or step "
                      "equations", owner="sweep")
    return sim.compile()


def progress_argument(progress, owner: str):
    """``progress`` of a sweep: None, True, False or a function ``progress(done, total)``."""
    if progress is None or callable(progress):
        return progress
    return flag_argument(progress, "progress", owner=owner)


def client_argument(client, owner: str):
    """``client``: None or a ``dask.distributed.Client`` (anything with ``submit`` and
    ``nthreads``)."""
    if client is None or all(callable(getattr(client, m, None)) for m in ("submit",
                                                                          "nthreads")):
        return client
    raise InputTypeError(f"{owner}: client must be a dask.distributed.Client (or None), got "
                         f"{type(client).__name__}")


def _validated_pairs(sim, S, P, grid: _Grid) -> None:
    """The constraints of every (state, parameters) pair, in blocks of runs."""
    from ._simulator import INITIAL_CONSTRAINT_TOLERANCE

    if grid.combine == "product" and len(P) == 1:
        check_constraints(sim, S, P, INITIAL_CONSTRAINT_TOLERANCE)
        return
    block = 1 << 16
    for a in range(0, grid.size, block):
        b = min(grid.size, a + block)
        i, j = grid.rows(a, b)
        check_constraints(sim, S[i], P[j], INITIAL_CONSTRAINT_TOLERANCE,
                          labels=lambda k, a=a: grid.index(a + k))


def _collect(shape: tuple, n: int):
    status = np.full(n, -1, dtype=np.int64)
    failed = np.full(n, -1, dtype=np.int64)
    messages = np.empty(n, dtype=object)
    return status, failed, messages


def _stack_values(parts: list[tuple[int, list]], status: np.ndarray, shape: tuple
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


def sweep(sim, initial, params=None, steps: int | None = None, *, combine: str = "product",
          reduce: Callable | None = None, every: int = 1,
          options: NewtonOptions | None = None, reduce_failures: bool = False,
          client=None, workers: int | None = None, chunk_size: int | None = None,
          progress=None, executor: str | None = None,
          timeout: float | None = None) -> SweepResult:
    """Simulate every combination of initial states and parameter sets.

    Parameters
    ----------
    sim : a compiled :class:`Simulator` (or step equations, compiled here).
    initial : one initial state, or a table of them (a 2-D array (n, n_known) of flat
        states, or a sequence of states as :meth:`Simulator.state` takes them).
    params : one parameter set, or a table of sets (a sequence of sets, a 2-D array
        (m, n_params), a mapping name → column of m values, a pandas DataFrame).
    steps, every, options : as for :meth:`Simulator.simulate`.
    combine : ``"product"`` (every state with every set: shape (n, m)) or ``"zip"`` (the
        i-th state with the i-th set: shape (n,); a single state or set goes with all).
    reduce : ``reduce(trajectory) -> value``, applied to each completed run (and to the
        partial trajectory of a failed or stopped run with ``reduce_failures``), run by run
        as the runs come; only its value is kept (arrays that are views are copied).
        Without it every :class:`Trajectory` comes back.
    executor : where a local sweep runs: ``"thread"`` (default: ``workers`` threads run the
        kernel, this thread reduces; nothing is pickled, a plain script needs no
        ``__main__`` guard) or ``"process"`` (worker processes, for a reduce that may crash
        or hang its process; see the module docstring).
    client : a ``dask.distributed.Client``: run on its cluster.
    workers : threads or processes (default: all cores; 1 runs everything in this thread).
    chunk_size : runs per task (default: about four tasks per worker, each holding at most
        about :data:`BATCH_BYTES` of kept states with ``reduce``; on processes and Dask
        sized from a short pilot run so the per-task overhead stays below 5 % of the work,
        see :func:`chunk_runs`).
    timeout : seconds a task may take (default: no limit): the runs of a task still running
        then are recorded with status ``TIMED_OUT`` (11) and the sweep goes on.  On threads
        the simulation stops within a kernel call (a reduce is not stopped: use
        ``executor="process"``, whose worker is killed); not with ``client``.
    progress : show a progress bar on stderr (default: when stderr is a terminal), or a
        callable ``progress(done, total)``.

    Every input is checked before any run starts (each state, each parameter set, and the
    constraints of every pair, as :meth:`Simulator.simulate` checks them; an error names
    the row); so is the memory the sweep will hold (a :class:`TrajectoryTooLargeError`).
    Returns a :class:`SweepResult`; a run that fails is recorded there, not raised.  The
    results do not depend on where or in how many tasks the runs were made: every run is
    computed as :meth:`Simulator.simulate` computes it.  Ctrl-C stops the sweep within
    about a second; the ``KeyboardInterrupt`` carries ``.result``, the runs done so far.
    """
    sim = _as_simulator(sim)
    owner = sim.name
    if steps is None:
        raise InputTypeError(f"{owner}: sweep needs steps= (the number of steps of every run)")
    steps = integer_argument(steps, "steps", owner=owner)
    every = integer_argument(every, "every", minimum=1, owner=owner)
    combine = choice_argument(combine, COMBINE, "combine", owner=owner)
    options = NewtonOptions.of(options, sim.options, owner=owner)
    reduce = callable_argument(reduce, "reduce", owner=owner, none=True)
    reduce_failures = flag_argument(reduce_failures, "reduce_failures", owner=owner)
    client = client_argument(client, owner)
    progress = progress_argument(progress, owner)
    timeout = _local_timeout(timeout, client, owner)
    if chunk_size is not None:
        chunk_size = integer_argument(chunk_size, "chunk_size", minimum=1, owner=owner)
    S, one_state = state_table(sim, initial)
    P, one_param = parameter_table(sim, params)
    grid = _grid(combine, len(S), len(P), one_state, one_param, sim.name)
    _validated_pairs(sim, S, P, grid)
    total = grid.size
    mode, workers = _placement(client, executor, workers, sim.backend == "c", owner)
    if mode == "process":
        _check_sendable(reduce, owner)
    batch_runs = _memory_plan(sim, steps, every, reduce is not None, total, mode, workers)
    size = _task_runs(sim, S, P, steps, every, options, total, workers, mode, chunk_size,
                      batch_runs)
    jobs = []
    for a in range(0, total, size):
        i, j = grid.rows(a, min(total, a + size))
        jobs.append(SimulationJob(a, S[i], P[j] if len(P) > 1 else P[:1]))
    task = SimulationTask(sim, steps, every, options, reduce, reduce_failures, batch_runs)
    collected = _Collected(sim.name, grid.shape, total, _Progress(total, progress,
                                                                   f"sweep {sim.name}"))
    trajectories = np.empty(total, dtype=object) if reduce is None else None

    def receive(res: ChunkResult) -> None:
        n = len(res.status)
        if trajectories is not None and res.raw is not None:
            i, j = grid.rows(res.first, res.first + n)
            batch = TrajectoryBatch(sim, res.raw, P[j] if len(P) > 1 else P[:1], steps, every,
                                    options, fill=False)
            for b in range(n):
                trajectories[res.first + b] = batch[b]
        collected.place(res.first, n, res.status, res.failed_step, res.messages, res.values)
        collected.bar.update(n)

    def result(partial: bool) -> SweepResult:
        status, failed, messages = collected.arrays(partial)
        shape = grid.shape
        return SweepResult(
            shape, combine, status, failed, messages,
            _stack_values(collected.values, status.reshape(-1), shape)
            if reduce is not None else None,
            trajectories.reshape(shape) if trajectories is not None else None, None,
            S, P, list(sim.parameter_names), grid.index, collected.seconds(), len(jobs))

    collected.run(lambda: execute(mode, task, jobs, receive, workers=workers,
                                  timeout=timeout, client=client), result)
    return result(False)


class _Collected:
    """The results of a sweep as they come (placed by run index, each run once), and the
    partial result of an interrupted sweep."""

    def __init__(self, name: str, shape: tuple, total: int, bar: _Progress):
        self.name, self.shape, self.bar = name, shape, bar
        self.status, self.failed, self.messages = _collect(shape, total)
        self.filled = np.zeros(total, dtype=bool)
        self.values: list = []
        self.t0 = time.perf_counter()
        self.t1: float | None = None

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
        """``work()``; a ``KeyboardInterrupt`` leaves with ``.result``, the partial
        :class:`SweepResult`."""
        try:
            work()
        except KeyboardInterrupt as interrupt:
            self.t1 = time.perf_counter()
            interrupt.result = result(True)
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
            messages[r] = f"{self.name}: run {r}: not run: {STOPPED[INTERRUPTED]}"
        return (status.reshape(self.shape), failed.reshape(self.shape),
                messages.reshape(self.shape))


def _local_timeout(timeout, client, owner: str) -> float | None:
    timeout = timeout_argument(timeout, owner)
    if timeout is not None and client is not None:
        raise InputTypeError(f"{owner}: timeout= limits the tasks of a local sweep (threads "
                             f"or processes); on a Dask cluster use Dask's own limits")
    return timeout


# --- boundary-value sweeps ----------------------------------------------------------------------

class _ParameterOwner:
    """The parameter checks of :mod:`._batch` for a system (no simulator needed)."""

    def __init__(self, system):
        self.equations = system
        self.name = system.name
        self.parameter_names = [str(s) for s in system.parameters]

    def parameters(self, params) -> np.ndarray:
        from ._validate import parameter_vector

        return parameter_vector(self.equations.parameters, params, owner=self.name)[0]


@dataclass
class BoundaryValueJob:
    """Chains of boundary-value runs (each a list of (run, start, end, parameters), solved
    in order: a continuation passes each solution on to the next)."""

    chains: list

    def __len__(self) -> int:
        return sum(len(chain) for chain in self.chains)

    def parts(self, size: int) -> list[BoundaryValueJob]:
        return [self]

    def split(self) -> list[BoundaryValueJob]:
        """Its chains one by one (none for a single chain, whose runs depend on each
        other)."""
        return [BoundaryValueJob([c]) for c in self.chains] if len(self.chains) > 1 else []

    def lost(self, status: int, message: str) -> list:
        return [(item[0], status, f"run {item[0]}: {message}", None, None)
                for chain in self.chains for item in chain]


@dataclass
class BoundaryValueTask:
    """What every task of a boundary-value sweep shares (sent once per worker)."""

    system: object
    steps: int
    solver_options: dict
    guess: object
    reduce: Callable | None
    reduce_failures: bool
    continuation: bool
    batch_runs: int = 1 << 62

    def simulate(self, job: BoundaryValueJob, stop=None) -> list:
        """Solve the runs of the job's chains; within a chain with continuation, each
        solve starts from the previous converged solution (falling back to the default
        initial path).  ``stop()`` is asked between solves (the runs left are returned as
        stopped).  Returns (run, status, solution or error) per run."""
        out = []
        for chain in job.chains:
            previous = None
            for r, start, end, p in chain:
                if stop is not None and stop():
                    out.append((r, INTERRUPTED, None))
                    continue
                sol, err = self._solve(r, start, end, p, previous)
                if sol is not None:
                    previous = (sol.arrows, sol.multipliers)
                out.append((r, OK, sol) if err is None else (r, _bvp_status(err), err))
        return out

    def _solve(self, r: int, start, end, p, previous):
        from ._bvp import solve_boundary_value

        if self.continuation and previous is not None:
            try:
                return solve_boundary_value(self.system, start, end, self.steps,
                                            guess=previous, params=p,
                                            **self.solver_options), None
            except SymgroupoidError:
                pass
        try:
            return solve_boundary_value(self.system, start, end, self.steps, guess=self.guess,
                                        params=p, **self.solver_options), None
        except (SingularJacobianError, NewtonDivergenceError, CutLocusError) as exc:
            return None, exc
        except SymgroupoidError as exc:
            raise _at_row(exc, "boundary-value run", r) from exc

    def finish(self, job: BoundaryValueJob, raw: list, cut: int | None = None) -> list:
        """(run, status, message, value, solution data) per run: ``reduce`` of each
        solution (and of a failure's error with ``reduce_failures``), or the solution's
        data."""
        out = []
        for r, status, got in raw:
            if status == INTERRUPTED:
                status = cut or INTERRUPTED
                out.append((r, status, f"run {r}: not completed: {STOPPED[status]}", None,
                            None))
                continue
            value = data = None
            if self.reduce is not None and (status == OK or self.reduce_failures):
                try:
                    value = _detached(self.reduce(got))
                except Exception as exc:
                    raise ReduceError(f"reduce raised on boundary-value run {r}: "
                                      f"{type(exc).__name__}: {exc}") from exc
            elif self.reduce is None and status == OK:
                data = _solution_data(got)
            out.append((r, status, None if status == OK else str(got), value, data))
        return out

    @staticmethod
    def merge(results: list) -> list:
        return [item for result in results for item in result]


def _solution_data(sol) -> dict:
    return {f.name: getattr(sol, f.name) for f in dataclasses.fields(sol) if f.name != "system"}


def _bvp_status(err: Exception) -> int:
    return Status.of_boundary_value_error(err)


def _sequence(value, what: str, owner: str) -> list:
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) \
            or (isinstance(value, np.ndarray) and value.ndim == 0):
        raise ShapeError(f"{owner}: {what} must be a sequence of boundary configurations "
                         f"(one per run; [c] for one), got {type(value).__name__}")
    out = list(value)
    if not out:
        raise ShapeError(f"{owner}: {what} is empty")
    return out


def sweep_boundary_value(step, starts, ends, steps: int, params=None, *,
                         combine: str = "zip", guess=None, continuation: bool = False,
                         reduce: Callable | None = None, reduce_failures: bool = False,
                         client=None, workers: int | None = None,
                         chunk_size: int | None = None, progress=None,
                         executor: str | None = None, timeout: float | None = None,
                         **solver_options) -> SweepResult:
    """Solve :func:`solve_boundary_value` for many boundary data and parameter sets.

    ``starts`` and ``ends`` are sequences of boundary configurations (as
    :func:`solve_boundary_value` takes one; ``[c]`` for a single one), ``params`` one
    parameter set or a table of sets (as for :func:`sweep`).  ``combine="zip"``: run i takes
    the i-th start, end and set (a sequence of length 1 goes with all), shape (n,);
    ``"product"``: every start with every end and every set, shape (starts, ends, sets).

    ``continuation=True``: runs along the last axis form a chain solved in order in one
    task, each from the previous converged solution of the chain (its arrows and
    multipliers) — a continuation along a parameter — and, if that fails, from the default
    initial path (or ``guess``).  Chains run in parallel.  ``solver_options`` (``tol``,
    ``tol_step``, ``max_iterations``) are passed on.  ``executor``, ``workers``,
    ``client``, ``chunk_size`` (chains per task), ``timeout`` and ``progress`` as for
    :func:`sweep` (on threads a solve runs to its end: ``timeout`` and Ctrl-C take effect
    between solves; with ``executor="process"`` the system travels with cloudpickle, its
    window kernels then built into, or loaded from, each worker's kernel cache).

    A run that does not converge (singular Jacobian, divergence, cut locus) is recorded in
    ``status`` and ``messages``; errors in the inputs are raised.  Returns a
    :class:`SweepResult` with ``solutions`` (or ``values`` with ``reduce``); Ctrl-C leaves
    with ``.result`` on the ``KeyboardInterrupt``, the runs solved so far.
    """
    system = system_argument(step, "step", owner="sweep_boundary_value")
    owner = system.name
    unknown = sorted(set(solver_options) - set(SOLVER_OPTIONS))
    if unknown:
        raise InputTypeError(f"{owner}: sweep_boundary_value got unknown option(s) "
                             f"{', '.join(unknown)}; the solver's options are "
                             f"{', '.join(SOLVER_OPTIONS)}")
    steps = integer_argument(steps, "steps", owner=owner)
    combine = choice_argument(combine, COMBINE, "combine", owner=owner)
    continuation = flag_argument(continuation, "continuation", owner=owner)
    reduce = callable_argument(reduce, "reduce", owner=owner, none=True)
    reduce_failures = flag_argument(reduce_failures, "reduce_failures", owner=owner)
    client = client_argument(client, owner)
    progress = progress_argument(progress, owner)
    timeout = _local_timeout(timeout, client, owner)
    if chunk_size is not None:
        chunk_size = integer_argument(chunk_size, "chunk_size", minimum=1, owner=owner)
    starts = _sequence(starts, "starts", owner)
    ends = _sequence(ends, "ends", owner)
    P, one_param = parameter_table(_ParameterOwner(system), params)
    shape, runs = _boundary_value_runs(combine, starts, ends, P, one_param, owner)
    total = len(runs)
    items = [(r, starts[i], ends[j], P[k]) for r, (i, j, k) in enumerate(runs)]
    if continuation:
        length = shape[-1]
        chains = [items[a:a + length] for a in range(0, total, length)]
    else:
        chains = [[item] for item in items]
    mode, n_workers = _placement(client, executor, workers, True, owner)
    if mode == "process":
        _check_sendable(reduce, owner)
    per_task = chunk_size or max(1, math.ceil(len(chains) / (TASKS_PER_WORKER * n_workers)))
    jobs = [BoundaryValueJob(chains[a:a + per_task]) for a in range(0, len(chains), per_task)]
    task = BoundaryValueTask(system, steps, dict(solver_options), guess, reduce,
                             reduce_failures, continuation)
    collected = _Collected(owner, shape, total, _Progress(total, progress,
                                                          f"boundary values {owner}"))
    solutions = np.empty(total, dtype=object) if reduce is None else None

    def receive(results: list) -> None:
        from ._bvp import BoundaryValueSolution

        for r, st, message, value, data in results:
            if solutions is not None and data is not None:
                solutions[r] = BoundaryValueSolution(system=system, **data)
            collected.place(r, 1, st, -1, [message], None if reduce is None else [value])
        collected.bar.update(len(results))

    param_index = np.array([k for _, _, k in runs], dtype=np.int64)

    def result(partial: bool) -> SweepResult:
        status, failed, messages = collected.arrays(partial)
        stacked = None
        if reduce is not None:
            stacked = _stack_values(collected.values, status.reshape(-1), shape)
        return SweepResult(
            shape, combine, status, failed, messages, stacked, None,
            solutions.reshape(shape) if solutions is not None else None,
            (starts, ends), P, [str(s) for s in system.parameters],
            lambda r: (int(r), int(param_index[r])), collected.seconds(), len(jobs))

    collected.run(lambda: execute(mode, task, jobs, receive, workers=n_workers,
                                  timeout=timeout, client=client), result)
    return result(False)


def _boundary_value_runs(combine: str, starts: list, ends: list, P: np.ndarray,
                         one_param: bool, owner: str) -> tuple[tuple, list]:
    """The result's shape and (start, end, parameter set) indices of each run."""
    counts = [len(starts), len(ends), len(P)]
    if combine == "product":
        shape = (len(starts), len(ends)) + (() if one_param else (len(P),))
        dims = (len(starts), len(ends), len(P))
        return shape, [tuple(int(v) for v in np.unravel_index(r, dims))
                       for r in range(int(np.prod(dims)))]
    n = max(counts)
    if any(c not in (1, n) for c in counts):
        raise ShapeError(f"{owner}: combine='zip' needs starts, ends and parameter sets "
                         f"of one length (or 1); got {counts[0]}, {counts[1]}, "
                         f"{counts[2]}")
    return (n,), [(r if len(starts) > 1 else 0, r if len(ends) > 1 else 0,
                   r if len(P) > 1 else 0) for r in range(n)]
