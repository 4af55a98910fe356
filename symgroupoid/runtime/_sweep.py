"""Sweeps: many runs over a grid or a list of initial states and parameter sets.

:func:`sweep` runs a compiled simulator over the product (or the zip) of a table of initial
states and a table of parameter sets; :func:`sweep_boundary_value` solves a boundary-value
problem for each combination of start, end and parameters.  Runs are grouped into chunks
(tasks); a task advances its runs with :meth:`Simulator.simulate_batch` (one kernel call)
and, with ``reduce``, returns only ``reduce(trajectory)`` of each run, so memory grows with
what is kept, not with the trajectories.

Where the tasks run:

- ``client=`` a ``dask.distributed.Client``: on its cluster.  The simulator travels as its
  generated C, flags and content hash (:mod:`._pickle`), once per worker: each worker builds
  the kernel into its own cache, or loads it from there, and reuses it for all its tasks.
  A worker lost mid-sweep is survived through Dask's rescheduling of its tasks; results are
  placed by run index, so no run is lost or counted twice.
- otherwise a local process pool over ``workers`` processes (default: all cores), started
  with ``spawn`` (scripts that call :func:`sweep` need the ``if __name__ == "__main__":``
  guard); with ``workers=1``, or when the whole sweep is estimated to take under
  ``IN_PROCESS_SECONDS``, the tasks run in this process (the kernel then shares runs among
  OpenMP threads).

``reduce`` and the simulator are sent to the workers with cloudpickle when it is installed
(it comes with ``dask[distributed]``), so ``reduce`` may be a lambda or a closure; without
cloudpickle it must be a module-level function.  A run that fails (a singular Jacobian,
Newton not converging, a non-finite value) is a result: its status and failing step are
recorded and the sweep goes on.  Errors in the inputs are raised before any run starts.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pickle
import sys
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .._arguments import (
    callable_argument,
    choice_argument,
    flag_argument,
    instance_argument,
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
from ._backends import OK, NewtonOptions, batch_rows
from ._batch import (
    TrajectoryBatch,
    _at_row,
    _check_memory,
    check_constraints,
    parameter_table,
    run_batch,
    state_table,
)
from ._validate import integer_argument, system_argument

COMBINE = ("product", "zip")
#: the options of :func:`solve_boundary_value` a boundary-value sweep passes on
SOLVER_OPTIONS = ("tol", "tol_step", "max_iterations")
#: a sweep estimated below this many seconds of work runs in this process
IN_PROCESS_SECONDS = 2.0
#: per-task overhead assumed when sizing chunks (seconds): a local pool, a Dask cluster
TASK_OVERHEAD = {"local": 2e-3, "dask": 2e-2, "serial": 1e-4}
#: the overhead a task may cost, as a fraction of its work
OVERHEAD_FRACTION = 0.05
#: tasks per worker aimed at (load balance), and tasks in flight per worker at most
TASKS_PER_WORKER, IN_FLIGHT_PER_WORKER = 4, 4
#: status of a boundary-value run that met the cut locus of the chart
CUT_LOCUS = 5


class ReduceError(SymgroupoidError, RuntimeError):
    """``reduce`` raised an exception on a run (the message names the run)."""


# --- results ------------------------------------------------------------------------------------

@dataclass
class SweepResult:
    """The runs of a sweep, indexed like its inputs.

    ``shape``: product: (number of initial states, number of parameter sets), zip: (number
    of runs,); an axis is absent when its input was a single state or set.  Per run:

    - ``status``: 0 completed, else the reason it stopped (1 singular Jacobian, 2 Newton not
      converged, 3 non-finite value; boundary-value runs: 5 the cut locus of the chart);
      ``ok``: ``status == 0``; ``failed_step``: the failing step (−1 if none; simulations);
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
class SimulationTask:
    """What every task of a simulation sweep shares (sent once per worker)."""

    simulator: object
    steps: int
    every: int
    options: NewtonOptions | None
    reduce: Callable | None
    reduce_failures: bool
    threads: int | None = 1


@dataclass
class ChunkResult:
    """What a task returns: per run of the chunk its status, failure data, and its value or
    the raw arrays of its trajectory."""

    first: int
    status: np.ndarray
    failed_step: np.ndarray
    messages: list
    values: list | None
    raw: object = None


def run_simulation_chunk(task: SimulationTask, first: int, S: np.ndarray,
                         P: np.ndarray) -> ChunkResult:
    """Advance the runs ``first, first + 1, …`` (rows of S with the rows of P, or one P) in
    one batch (single-threaded on a worker, which is one core), and reduce them."""
    sim = task.simulator
    raw = run_batch(sim, S, P, task.steps, task.every, task.options, task.threads)
    batch = TrajectoryBatch(sim, raw, P, task.steps, task.every)
    messages = [None if batch.status[b] == OK else str(batch.error(b))
                for b in range(len(batch))]
    values = None
    if task.reduce is not None:
        values = []
        for b in range(len(batch)):
            if batch.status[b] != OK and not task.reduce_failures:
                values.append(None)
                continue
            try:
                values.append(task.reduce(batch[b]))
            except Exception as exc:
                raise ReduceError(f"{sim.name}: reduce raised on run {first + b}: "
                                  f"{type(exc).__name__}: {exc}") from exc
        raw = None
    return ChunkResult(first, batch.status.copy(), batch.failed_step.copy(), messages, values,
                       raw)


# --- executors ----------------------------------------------------------------------------------

def _dumps(obj) -> bytes:
    """``obj`` pickled for another process: cloudpickle when installed (lambdas, closures),
    else pickle (module-level functions only)."""
    try:
        import cloudpickle
    except ImportError:
        cloudpickle = None
    try:
        return cloudpickle.dumps(obj) if cloudpickle else pickle.dumps(obj)
    except (pickle.PicklingError, TypeError, AttributeError) as exc:
        if isinstance(exc, SymgroupoidError):
            raise
        hint = "" if cloudpickle else (" (install cloudpickle to send lambdas and closures, "
                                       "or use a module-level function)")
        raise TypeError(f"the sweep's reduce function cannot be sent to the worker "
                        f"processes: {exc}{hint}") from exc


_WORKER_TASK = None


def _init_worker(payload: bytes) -> None:
    global _WORKER_TASK
    _WORKER_TASK = pickle.loads(payload)


def _pool_call(fn_name: str, *args):
    return globals()[fn_name](_WORKER_TASK, *args)


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


def _run_serial(fn, task, chunks, receive) -> None:
    for args in chunks:
        receive(fn(task, *args))


def _run_pool(fn, task, chunks, receive, workers: int) -> None:
    """The chunks on a spawned process pool; a pool that breaks (a worker killed) is started
    again for the chunks without a result, up to three times."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from concurrent.futures.process import BrokenProcessPool

    payload = _dumps(task)
    pending = dict(enumerate(chunks))
    workers = max(1, min(workers, len(pending)))  # no process without a task
    for attempt in range(4):
        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                 initializer=_init_worker, initargs=(payload,)) as pool:
            queue, flying = list(pending), {}
            try:
                while queue or flying:
                    while queue and len(flying) < IN_FLIGHT_PER_WORKER * workers:
                        k = queue.pop(0)
                        flying[pool.submit(_pool_call, fn.__name__, *pending[k])] = k
                    done, _ = wait(list(flying), return_when=FIRST_COMPLETED)
                    for fut in done:
                        k = flying.pop(fut)
                        receive(fut.result())
                        del pending[k]
                return
            except BrokenProcessPool:
                if attempt == 3:
                    raise


def _run_dask(fn, task, chunks, receive, client) -> None:
    """The chunks on a Dask cluster, at most a few tasks in flight per worker.  The shared
    task is itself a task (recomputed if the workers holding it are lost)."""
    from distributed import as_completed

    token = uuid.uuid4().hex[:12]
    held = client.submit(_hold, _dumps(task), key=f"symgroupoid-task-{token}", pure=False)
    workers = max(1, len(client.nthreads()))
    queue = list(enumerate(chunks))
    limit = IN_FLIGHT_PER_WORKER * workers

    def submit(item):
        k, args = item
        return client.submit(fn, held, *args, key=f"symgroupoid-chunk-{token}-{k}",
                             pure=False)

    flying = as_completed([submit(queue.pop(0)) for _ in range(min(limit, len(queue)))])
    try:
        for future in flying:
            receive(future.result())
            future.release()
            if queue:
                flying.add(submit(queue.pop(0)))
    finally:
        held.release()


def _hold(payload: bytes):
    return pickle.loads(payload)


def _execute(fn, task, chunks: list, receive, *, client, workers: int, mode: str) -> None:
    if mode == "dask":
        _run_dask(fn, task, chunks, receive, client)
    elif mode == "local":
        _run_pool(fn, task, chunks, receive, workers)
    else:
        _run_serial(fn, task, chunks, receive)


# --- chunk sizes --------------------------------------------------------------------------------

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


#: the most worker processes of a local pool: four per core (at least 64)
MAX_WORKERS = max(64, 4 * (os.cpu_count() or 1))


def workers_argument(workers, owner: str) -> int:
    """``workers``: an integer 1 … :data:`MAX_WORKERS` (a pool starts one process per
    task up to this number, so a huge count would start thousands of processes)."""
    return integer_argument(workers, "workers", minimum=1, maximum=MAX_WORKERS, owner=owner)


def _mode(client, workers: int | None, estimate: float, portable: bool, owner: str
          ) -> tuple[str, int]:
    if client is not None:
        if not portable:
            from ._pickle import NotPortableError

            raise NotPortableError(f"{owner}: a NumPy-backend simulator cannot be sent to a "
                                   f"cluster; compile the step with backend='c'")
        return "dask", max(1, len(client.nthreads()))
    explicit = workers is not None
    workers = os.cpu_count() or 1 if workers is None else workers_argument(workers, owner)
    if workers == 1 or (not explicit and estimate < IN_PROCESS_SECONDS):
        return "serial", 1
    if not portable:
        if explicit:
            from ._pickle import NotPortableError

            raise NotPortableError(f"{owner}: a NumPy-backend simulator cannot be sent to "
                                   f"worker processes; compile the step with backend='c', "
                                   f"or use workers=1")
        return "serial", 1
    return "local", workers


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
          progress=None) -> SweepResult:
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
    reduce : ``reduce(trajectory) -> value``, applied on the worker to each completed run
        (and to the partial trajectory of a failed run with ``reduce_failures``); only its
        value comes back.  Without it every :class:`Trajectory` comes back.
    client : a ``dask.distributed.Client``: run on its cluster.  Otherwise a local process
        pool of ``workers`` processes (default: all cores; see the module docstring for
        when a sweep runs in this process instead).
    chunk_size : runs per task (default: sized from a short pilot run so the per-task
        overhead stays below 5 % of the work; see :func:`chunk_runs`).
    progress : show a progress bar on stderr (default: when stderr is a terminal), or a
        callable ``progress(done, total)``.

    Every input is checked before any run starts (each state, each parameter set, and the
    constraints of every pair, as :meth:`Simulator.simulate` checks them; an error names
    the row).  Returns a :class:`SweepResult`; a run that fails is recorded there, not
    raised.  The results do not depend on where or in how many tasks the runs were made:
    every run is computed as :meth:`Simulator.simulate` computes it.
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
    if chunk_size is not None:
        chunk_size = integer_argument(chunk_size, "chunk_size", minimum=1, owner=owner)
    S, one_state = state_table(sim, initial)
    P, one_param = parameter_table(sim, params)
    grid = _grid(combine, len(S), len(P), one_state, one_param, sim.name)
    _validated_pairs(sim, S, P, grid)
    total = grid.size
    # every trajectory comes back without reduce; with it, a task holds its runs' states
    _check_memory(sim, total if reduce is None else 1, batch_rows(steps, every), steps,
                  every)
    per_run = _seconds_per_run(sim, S, P, steps, every, options)
    mode, workers = _mode(client, workers, per_run * total, sim.backend == "c", sim.name)
    size = chunk_runs(total, per_run, workers, mode, chunk_size)
    chunks = []
    for a in range(0, total, size):
        b = min(total, a + size)
        i, j = grid.rows(a, b)
        chunks.append((a, S[i], P[j] if len(P) > 1 else P[:1]))
    task = SimulationTask(sim, steps, every, options, reduce, reduce_failures,
                          None if mode == "serial" else 1)
    status, failed, messages = _collect(grid.shape, total)
    filled = np.zeros(total, dtype=bool)
    value_parts: list = []
    trajectories = np.empty(total, dtype=object) if reduce is None else None
    bar = _Progress(total, progress, f"sweep {sim.name}")

    def receive(res: ChunkResult) -> None:
        n = len(res.status)
        where = slice(res.first, res.first + n)
        if filled[where].any():
            raise RuntimeError(f"internal error: runs {res.first}..{res.first + n - 1} "
                               f"received twice")
        filled[where] = True
        status[where], failed[where] = res.status, res.failed_step
        messages[where] = res.messages
        if res.values is not None:
            value_parts.append((res.first, res.values))
        if trajectories is not None:
            i, j = grid.rows(res.first, res.first + n)
            batch = TrajectoryBatch(sim, res.raw, P[j] if len(P) > 1 else P[:1], steps, every)
            for b in range(n):
                trajectories[res.first + b] = batch[b]
        bar.update(n)

    t0 = time.perf_counter()
    try:
        _execute(run_simulation_chunk, task, chunks, receive, client=client, workers=workers,
                 mode=mode)
    finally:
        bar.close()
    if not filled.all():
        raise RuntimeError(f"internal error: {int((~filled).sum())} runs without a result")
    shape = grid.shape
    return SweepResult(
        shape, combine, status.reshape(shape), failed.reshape(shape), messages.reshape(shape),
        _stack_values(value_parts, status, shape) if reduce is not None else None,
        trajectories.reshape(shape) if trajectories is not None else None, None,
        S, P, list(sim.parameter_names), grid.index, time.perf_counter() - t0, len(chunks))


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
class BoundaryValueTask:
    """What every task of a boundary-value sweep shares (sent once per worker)."""

    system: object
    steps: int
    solver_options: dict
    guess: object
    reduce: Callable | None
    reduce_failures: bool
    continuation: bool


def _solution_data(sol) -> dict:
    return {f.name: getattr(sol, f.name) for f in dataclasses.fields(sol) if f.name != "system"}


def _bvp_status(err: Exception) -> int:
    if isinstance(err, SingularJacobianError):
        return 1
    if isinstance(err, CutLocusError):
        return CUT_LOCUS
    return 2


def run_boundary_value_chunk(task: BoundaryValueTask, chains: list) -> list:
    """Solve the runs of ``chains`` (lists of (run, start, end, parameters)); within a chain
    with continuation, each solve starts from the previous converged solution (falling
    back to the default initial path).  Returns (run, status, message, value, data)."""
    from ._bvp import solve_boundary_value

    out = []
    for chain in chains:
        previous = None
        for r, start, end, p in chain:
            sol, err = None, None
            if task.continuation and previous is not None:
                try:
                    sol = solve_boundary_value(task.system, start, end, task.steps,
                                               guess=previous, params=p, **task.solver_options)
                except SymgroupoidError:
                    sol = None
            if sol is None:
                try:
                    sol = solve_boundary_value(task.system, start, end, task.steps,
                                               guess=task.guess, params=p,
                                               **task.solver_options)
                except (SingularJacobianError, NewtonDivergenceError, CutLocusError) as exc:
                    err = exc
                except SymgroupoidError as exc:
                    raise _at_row(exc, "boundary-value run", r) from exc
            if sol is not None:
                previous = (sol.arrows, sol.multipliers)
            value = data = None
            if task.reduce is not None and (sol is not None or task.reduce_failures):
                try:
                    value = task.reduce(sol if sol is not None else err)
                except Exception as exc:
                    raise ReduceError(f"reduce raised on boundary-value run {r}: "
                                      f"{type(exc).__name__}: {exc}") from exc
            elif task.reduce is None and sol is not None:
                data = _solution_data(sol)
            out.append((r, OK if err is None else _bvp_status(err),
                        None if err is None else str(err), value, data))
    return out


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
    ``tol_step``, ``max_iterations``) are passed on.

    A run that does not converge (singular Jacobian, divergence, cut locus) is recorded in
    ``status`` and ``messages``; errors in the inputs are raised.  Returns a
    :class:`SweepResult` with ``solutions`` (or ``values`` with ``reduce``).  The system
    travels to worker processes with cloudpickle (its symbolic definition; the window
    kernels are then built into, or loaded from, each worker's kernel cache).
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
    if chunk_size is not None:
        chunk_size = integer_argument(chunk_size, "chunk_size", minimum=1, owner=owner)
    starts = _sequence(starts, "starts", owner)
    ends = _sequence(ends, "ends", owner)
    P, one_param = parameter_table(_ParameterOwner(system), params)
    counts = [len(starts), len(ends), len(P)]
    if combine == "product":
        shape = (len(starts), len(ends)) + (() if one_param else (len(P),))
        dims = (len(starts), len(ends), len(P))
        runs = [tuple(int(v) for v in np.unravel_index(r, dims))
                for r in range(int(np.prod(dims)))]
    else:
        n = max(counts)
        if any(c not in (1, n) for c in counts):
            raise ShapeError(f"{owner}: combine='zip' needs starts, ends and parameter sets "
                             f"of one length (or 1); got {counts[0]}, {counts[1]}, "
                             f"{counts[2]}")
        shape = (n,)
        runs = [(r if len(starts) > 1 else 0, r if len(ends) > 1 else 0,
                 r if len(P) > 1 else 0) for r in range(n)]
    total = len(runs)
    items = [(r, starts[i], ends[j], P[k]) for r, (i, j, k) in enumerate(runs)]
    if continuation:
        length = shape[-1]
        chains = [items[a:a + length] for a in range(0, total, length)]
    else:
        chains = [[item] for item in items]
    if client is not None:
        mode, n_workers = "dask", max(1, len(client.nthreads()))
    else:
        n_workers = os.cpu_count() or 1 if workers is None else workers_argument(workers,
                                                                                 owner)
        mode = "serial" if n_workers == 1 else "local"
    per_task = chunk_size or max(1, math.ceil(len(chains) / (TASKS_PER_WORKER * n_workers)))
    tasks = [(chains[a:a + per_task],) for a in range(0, len(chains), per_task)]
    task = BoundaryValueTask(system, steps, dict(solver_options), guess, reduce,
                             reduce_failures, continuation)
    status, failed, messages = _collect(shape, total)
    values: list = [None] * total
    solutions = np.empty(total, dtype=object) if reduce is None else None
    filled = np.zeros(total, dtype=bool)
    bar = _Progress(total, progress, f"boundary values {owner}")

    def receive(results: list) -> None:
        from ._bvp import BoundaryValueSolution

        for r, st, message, value, data in results:
            if filled[r]:
                raise RuntimeError(f"internal error: run {r} received twice")
            filled[r] = True
            status[r], messages[r], values[r] = st, message, value
            if solutions is not None and data is not None:
                solutions[r] = BoundaryValueSolution(system=system, **data)
        bar.update(len(results))

    t0 = time.perf_counter()
    try:
        _execute(run_boundary_value_chunk, task, tasks, receive, client=client,
                 workers=n_workers, mode=mode)
    finally:
        bar.close()
    if not filled.all():
        raise RuntimeError(f"internal error: {int((~filled).sum())} runs without a result")
    param_index = np.array([k for _, _, k in runs], dtype=np.int64)
    stacked = None
    if reduce is not None:
        stacked = _stack_values([(0, values)], status, shape)
    return SweepResult(
        shape, combine, status.reshape(shape), failed.reshape(shape), messages.reshape(shape),
        stacked, None, solutions.reshape(shape) if solutions is not None else None,
        (starts, ends), P, [str(s) for s in system.parameters],
        lambda r: (int(r), int(param_index[r])), time.perf_counter() - t0, len(tasks))
