"""Boundary-value sweeps: :func:`solve_boundary_value` for many boundary data and
parameter sets.

The runs are the cells of the product or the zip of starts, ends and parameter sets; with
``continuation`` the runs along the last axis form a chain solved in order in one task,
each from the previous converged solution.  A :class:`BoundaryValueJob` holds chains, the
:class:`BoundaryValueTask` (the system, the solver's options, ``reduce``; sent once per
worker) solves them; they run where a simulation sweep's tasks run (:mod:`._placement`,
:mod:`._executors`) and are collected alike (:mod:`._sweep_result`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .._arguments import choice_argument, flag_argument
from .._errors import (
    CutLocusError,
    InputTypeError,
    NewtonDivergenceError,
    ShapeError,
    SingularJacobianError,
    SymgroupoidError,
)
from ..stepper import Status
from ._executors import execute
from ._placement import TASKS_PER_WORKER, placement
from ._runs import INTERRUPTED, OK
from ._sweep_arguments import check_sendable, sweep_controls
from ._sweep_result import STOPPED, Collected, Progress, SweepResult, stack_values
from ._sweep_tasks import COMBINE, reduced
from ._tables import _at_row, parameter_table
from ._validate import system_argument

#: the options of :func:`solve_boundary_value` a boundary-value sweep passes on
SOLVER_OPTIONS = ("tol", "tol_step", "max_iterations")
#: status of a boundary-value run that met the cut locus of the chart
CUT_LOCUS = Status.CUT_LOCUS


class _ParameterOwner:
    """The parameter checks of :mod:`._tables` for a system (no simulator needed)."""

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
    inputs: list | None = None  # a forced system's input table per run (None: no inputs)

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

        inputs = None if self.inputs is None else self.inputs[r]
        if self.continuation and previous is not None:
            try:
                return solve_boundary_value(self.system, start, end, self.steps,
                                            guess=previous, params=p, inputs=inputs,
                                            **self.solver_options), None
            except SymgroupoidError:
                pass
        try:
            return solve_boundary_value(self.system, start, end, self.steps, guess=self.guess,
                                        params=p, inputs=inputs, **self.solver_options), None
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
                value = reduced(self.reduce, got, f"reduce raised on boundary-value run {r}")
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
                         combine: str = "zip", guess=None, inputs=None,
                         continuation: bool = False,
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
    initial path (or ``guess``).  Chains run in parallel.  ``inputs`` (a forced system,
    docs/conventions.md §20): one input table for every run, as :func:`solve_boundary_value`
    takes it, or an array (runs, terms, m), one table per run in the order of the runs
    (row-major over ``shape``); all are checked before any solve.  ``solver_options`` (``tol``,
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
    from ._bvp import boundary_steps

    steps = boundary_steps(system, steps)
    combine = choice_argument(combine, COMBINE, "combine", owner=owner)
    continuation = flag_argument(continuation, "continuation", owner=owner)
    reduce, reduce_failures, client, progress, timeout, chunk_size = sweep_controls(
        reduce, reduce_failures, client, progress, timeout, chunk_size, owner)
    starts = _sequence(starts, "starts", owner)
    ends = _sequence(ends, "ends", owner)
    P, one_param = parameter_table(_ParameterOwner(system), params)
    shape, runs = _boundary_value_runs(combine, starts, ends, P, one_param, owner)
    total = len(runs)
    tables = _run_inputs(system, inputs, steps, total, owner)
    items = [(r, starts[i], ends[j], P[k]) for r, (i, j, k) in enumerate(runs)]
    if continuation:
        length = shape[-1]
        chains = [items[a:a + length] for a in range(0, total, length)]
    else:
        chains = [[item] for item in items]
    mode, n_workers = placement(client, executor, workers, True, owner)
    if mode == "process":
        check_sendable(reduce, owner)
    per_task = chunk_size or max(1, math.ceil(len(chains) / (TASKS_PER_WORKER * n_workers)))
    jobs = [BoundaryValueJob(chains[a:a + per_task]) for a in range(0, len(chains), per_task)]
    task = BoundaryValueTask(system, steps, dict(solver_options), guess, reduce,
                             reduce_failures, continuation, inputs=tables)
    collected = Collected(owner, shape, total, Progress(total, progress,
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
            stacked = stack_values(collected.values, status.reshape(-1), shape)
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


def _run_inputs(system, inputs, steps: int, total: int, owner: str) -> list | None:
    """The checked input table of every run (:func:`~._bvp._inputs.run_inputs`), None for a
    system without inputs given none."""
    from ._bvp._inputs import input_names, run_inputs

    if inputs is None and not input_names(system):
        return None
    arity = len(system._fs.slots)
    if steps < 2 * arity:  # the solves refuse it, each naming the count
        return None
    return run_inputs(system, inputs, steps - arity + 1, total, owner=owner)
