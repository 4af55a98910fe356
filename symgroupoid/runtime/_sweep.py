"""Sweeps: many runs over a grid or a list of initial states and parameter sets.

:func:`sweep` runs a compiled simulator over the product (or the zip) of a table of initial
states and a table of parameter sets; :func:`sweep_boundary_value` solves a boundary-value
problem for each combination of start, end and parameters.  Runs are grouped into tasks; a
task advances its runs with :meth:`Simulator.simulate_batch`'s machinery and, with
``reduce``, keeps only ``reduce(trajectory)`` of each run: its runs are simulated in parts of
at most about :data:`._memory.BATCH_BYTES` of kept states and reduced run by run, so memory
grows with what is kept, not with the trajectories.

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

from collections.abc import Callable

import numpy as np

from .._arguments import choice_argument, instance_argument, named_columns
from .._errors import InputTypeError, ShapeError
from ._batch import TrajectoryBatch
from ._executors import execute
from ._inputs import batch_inputs
from ._memory import memory_plan
from ._options import NewtonOptions
from ._placement import placement, task_runs
from ._sweep_arguments import check_sendable, sweep_controls
from ._sweep_result import Collected, Progress, SweepResult, stack_values
from ._sweep_tasks import COMBINE, ChunkResult, Grid, SimulationJob, SimulationTask, sweep_grid
from ._tables import check_constraints, parameter_table, state_table
from ._validate import integer_argument, real_array


def _as_simulator(sim):
    """A :class:`Simulator`, or step equations compiled here; an
    :class:`~symgroupoid.InputTypeError` for anything else."""
    from ..equations import StepEquations
    from ._simulator import Simulator

    if not isinstance(sim, Simulator):
        instance_argument(sim, StepEquations, "sim", "a Simulator (step.compile()) or step "
                          "equations", owner="sweep")
        sim = sim.compile()
    return sim


def _input_table(sim, inputs, grid: Grid, steps: int) -> np.ndarray | None:
    """The inputs of a sweep's runs: (runs, steps, m) from one sequence per cell of the
    result (shape result shape + (steps, m)), or one sequence (steps, m) for every run
    (what :meth:`Simulator.simulate` takes); None for a system without inputs."""
    shape = grid.shape
    if inputs is not None:
        inputs = real_array(named_columns(inputs, sim.layout.input_names, owner=sim.name),
                            "inputs", owner=sim.name)
    if inputs is not None and inputs.ndim == len(shape) + 2 and shape:
        arr = inputs
        if arr.shape[:len(shape)] != shape:
            want = shape + (steps, sim.layout.n_inputs)
            raise ShapeError(f"{sim.name}: per-run inputs need shape {want} (a sequence for "
                             f"each run of the sweep's result); got {arr.shape}")
        return batch_inputs(sim.layout, arr.reshape((grid.size,) + arr.shape[len(shape):]),
                            grid.size, steps, owner=sim.name)
    return batch_inputs(sim.layout, inputs, grid.size, steps, owner=sim.name)


def _validated_pairs(sim, S, P, grid: Grid) -> None:
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


def sweep(sim, initial, params=None, steps: int | None = None, *, combine: str = "product",
          reduce: Callable | None = None, every: int = 1,
          options: NewtonOptions | None = None, reduce_failures: bool = False,
          client=None, workers: int | None = None, chunk_size: int | None = None,
          progress=None, executor: str | None = None,
          timeout: float | None = None, inputs=None) -> SweepResult:
    """Simulate every combination of initial states and parameter sets.

    Parameters
    ----------
    sim : a compiled :class:`Simulator` (or step equations, compiled here).
    initial : one initial state, or a table of them (a 2-D array (n, n_known) of flat
        states, or a sequence of states as :meth:`Simulator.state` takes them).
    params : one parameter set, or a table of sets (a sequence of sets, a 2-D array
        (m, n_params), a mapping name → column of m values, a pandas DataFrame).
    steps, every, options : as for :meth:`Simulator.simulate`.
    inputs : a forced system's inputs (docs/conventions.md §20): one sequence for every
        run, as :meth:`Simulator.simulate` takes it ((steps, m), or (m,) held constant), or
        one sequence per run of the result: an array of shape result shape + (steps, m)
        (``combine="product"``: (n, m_sets, steps, m)); each run is bitwise
        ``simulate(state, steps, params, inputs=its sequence)``.
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
        about :data:`._memory.BATCH_BYTES` of kept states with ``reduce``; on processes and
        Dask sized from a short pilot run so the per-task overhead stays below 5 % of the
        work, see :func:`._placement.chunk_runs`).
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
    reduce, reduce_failures, client, progress, timeout, chunk_size = sweep_controls(
        reduce, reduce_failures, client, progress, timeout, chunk_size, owner)
    S, one_state = state_table(sim, initial)
    P, one_param = parameter_table(sim, params)
    grid = sweep_grid(combine, len(S), len(P), one_state, one_param, sim.name)
    U = _input_table(sim, inputs, grid, steps)
    _validated_pairs(sim, S, P, grid)
    total = grid.size
    mode, workers = placement(client, executor, workers, sim.backend == "c", owner)
    if mode == "process":
        check_sendable(reduce, owner)
    batch_runs = memory_plan(sim, steps, every, reduce is not None, total, mode, workers)
    size = task_runs(sim, S, P, steps, every, options, total, workers, mode, chunk_size,
                     batch_runs, None if U is None else U[:4] if U.ndim == 3 else U)
    jobs = []
    for a in range(0, total, size):
        i, j = grid.rows(a, min(total, a + size))
        jobs.append(SimulationJob(a, S[i], P[j] if len(P) > 1 else P[:1],
                                  U[a:a + len(i)] if U is not None and U.ndim == 3 else U))
    task = SimulationTask(sim, steps, every, options, reduce, reduce_failures, batch_runs)
    collected = Collected(sim.name, grid.shape, total, Progress(total, progress,
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
            stack_values(collected.values, status.reshape(-1), shape)
            if reduce is not None else None,
            trajectories.reshape(shape) if trajectories is not None else None, None,
            S, P, list(sim.parameter_names), grid.index, collected.seconds(), len(jobs))

    collected.run(lambda: execute(mode, task, jobs, receive, workers=workers,
                                  timeout=timeout, client=client), result)
    return result(False)
