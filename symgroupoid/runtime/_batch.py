"""Many trajectories at once: :meth:`Simulator.simulate_batch` and :class:`TrajectoryBatch`.

A batch is B independent runs of the same step, from the rows of a state table with the rows
of a parameter table (or one parameter set for all), checked as one state and one set are
(:mod:`._tables`), their kept states allocated at once after a check that they fit
(:mod:`._memory`), and advanced by the compiled kernel in calls of bounded length on one or
more threads (:mod:`._batch_progress`): the states are bitwise those of B separate
``simulate`` calls.

Layout: the states of run b are one contiguous block (rows × n_known, row-major), the runs one
after the other.  The Newton solve of a step is branchy (pivoting, chord or refactor, the
convergence tests differ per run), so interleaving runs lane by lane (structure of arrays)
would run every lane through every branch; what the compiler vectorises is the straight-line
residual and Jacobian code within a run, which this layout keeps on contiguous memory.
"""

from __future__ import annotations

import numpy as np

from .._arguments import instance_argument
from .._errors import InputTypeError, ShapeError
from ..stepper import MAX_THREADS
from ._batch_progress import run_batch
from ._inputs import batch_inputs
from ._memory import check_memory
from ._options import NewtonOptions
from ._runs import INTERRUPTED, OK, BatchRun, batch_rows
from ._tables import check_constraints, parameter_table, state_table
from ._trajectory import Trajectory
from ._validate import integer_argument


class RunIndexError(ShapeError, IndexError):
    """A run number outside a batch (also an ``IndexError``)."""


class TrajectoryBatch:
    """B runs of :meth:`Simulator.simulate_batch`: arrays indexed by run, and each run as the
    :class:`Trajectory` that :meth:`Simulator.simulate` returns for it.

    - ``batch.states`` (B, R, n_known): the kept states of every run (state 0, every e-th,
      the last), R = 1 + ⌈steps/e⌉; ``batch.kept`` (B,): the valid rows of each run.  A run
      that failed at step s ends with state s and has fewer valid rows: its rows past
      ``kept[b]`` are NaN (and its ``newton_iterations`` there −1): they are not data.
    - ``batch.newton_iterations``, ``batch.residual_norms`` (B, R − 1): per interval between
      kept states, as in :class:`Trajectory`;
    - ``batch.status`` (B,): 0 for a completed run, else the kernel's status
      (1 singular Jacobian, 2 Newton's iteration cap, 3 non-finite value, 5 Newton stalled
      above the rounding floor, 6 a branch jump: :class:`~symgroupoid.Status`, with its
      ``message``), or ``INTERRUPTED`` (10) for a run that Ctrl-C stopped (in the partial
      batch of an interrupted call); ``batch.ok``; ``batch.failed_step`` (B,): the failing
      step s (the step an interrupted run reached), −1 for a completed run;
    - ``batch[b]``: run b as a :class:`Trajectory` (a failed run: up to state s, as
      ``err.trajectory`` of the error ``simulate`` raises); ``batch.error(b)``: that error;
    - ``batch.final_states`` (B, n_known): the last state each run reached;
    - ``batch.parameters`` (B, n_params): the parameters of each run.
    """

    def __init__(self, sim, raw: BatchRun, parameters: np.ndarray, steps: int, every: int,
                 options: NewtonOptions | None = None, *, fill: bool = True):
        """(``fill=False`` leaves the rows past each run's end as they are: for a caller
        that hands out each run's own rows only, ``batch[b]``, as sweeps do.)"""
        from ._simulator import Simulator

        instance_argument(sim, Simulator, "sim", "a Simulator (a batch comes from "
                          "Simulator.simulate_batch)", owner="TrajectoryBatch")
        instance_argument(raw, BatchRun, "raw", "the raw run of simulate_batch",
                          owner=sim.name)
        self._sim = sim
        self._options = sim.options if options is None else options
        self._raw = raw
        self.steps, self.every = int(steps), int(every)
        self.parameters = np.broadcast_to(parameters, (len(raw.kept), parameters.shape[-1]))
        self.states = raw.states
        self.kept = raw.kept
        self.newton_iterations = raw.iterations
        self.residual_norms = raw.residual_norms
        self.status = raw.status.astype(np.int64)
        self.failed_step = raw.failed_step
        rows = self.states.shape[1]
        short = np.flatnonzero(self.kept < rows) if fill and self.states.flags.writeable \
            else ()
        for b in short:
            k = int(self.kept[b])
            self.states[b, k:] = np.nan
            self.newton_iterations[b, max(k - 1, 0):] = -1
            self.residual_norms[b, max(k - 1, 0):] = np.nan
        for arr in (self.states, self.kept, self.newton_iterations, self.residual_norms,
                    self.status, self.failed_step):
            arr.setflags(write=False)

    def __len__(self) -> int:
        return len(self.kept)

    @property
    def ok(self) -> np.ndarray:
        """(B,) True for the runs that completed every step."""
        return self.status == OK

    @property
    def final_states(self) -> np.ndarray:
        """(B, n_known) the last state each run reached (state N, or s for a failed run)."""
        return self.states[np.arange(len(self)), self.kept - 1].copy()

    def step_indices(self, b: int) -> np.ndarray:
        """The step index of each kept state of run b."""
        b = self._run(b)
        k = int(self.kept[b])
        out = np.arange(k, dtype=np.int64) * self.every
        if k > 1:
            out[-1] = self.steps if self.status[b] == OK else int(self.failed_step[b])
        return out

    def _run(self, b) -> int:
        """``b`` as a run number 0 … B − 1 (negative counts from the end)."""
        if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)):
            raise InputTypeError(f"{self._sim.name}: a batch is indexed by run number, got "
                                 f"{type(b).__name__} {b!r}")
        run = int(b) + (len(self) if b < 0 else 0)
        if not 0 <= run < len(self):
            raise RunIndexError(f"{self._sim.name}: run {int(b)} out of range for a batch of "
                                f"{len(self)}")
        return run

    def __getitem__(self, b: int) -> Trajectory:
        b = self._run(b)
        k = int(self.kept[b])
        sim = self._sim
        return sim._trajectory(self.states[b, :k], self.newton_iterations[b, :k - 1],
                               self.residual_norms[b, :k - 1], self.parameters[b],
                               self.step_indices(b), self.every)

    def __iter__(self):
        return (self[b] for b in range(len(self)))

    def error(self, b: int) -> Exception | None:
        """The error :meth:`Simulator.simulate` raises for run b (None if it completed), with
        ``.trajectory`` the run up to the failing step."""
        b = self._run(b)
        if self.status[b] == OK:
            return None
        if self.status[b] == INTERRUPTED:
            err = KeyboardInterrupt(f"{self._sim.name}: run {b} was interrupted at step "
                                    f"{int(self.failed_step[b])}")
            err.trajectory = self[b]
            return err
        raw = self._raw
        run = self[b]
        err = self._sim._failure(int(self.status[b]), int(self.failed_step[b]),
                                 int(raw.failed_iterations[b]),
                                 float(raw.failed_residual_norms[b]), raw.last_iterate[b],
                                 self._options,
                                 known=run.states[-1] if len(run.states) else None,
                                 p=self.parameters[b])
        err.trajectory = run
        return err

    def __repr__(self) -> str:
        failed = int((~self.ok).sum())
        return (f"<TrajectoryBatch {self._sim.name!r}: {len(self)} runs of {self.steps} steps"
                f"{f', every {self.every}' if self.every != 1 else ''}, {failed} failed>")



def simulate_batch(sim, states, steps: int, params, *, every: int = 1,
                   options: NewtonOptions | None = None, threads: int | None = None,
                   inputs=None) -> TrajectoryBatch:
    """See :meth:`Simulator.simulate_batch`."""
    steps = integer_argument(steps, "steps", owner=sim.name)
    every = integer_argument(every, "every", minimum=1, owner=sim.name)
    options = NewtonOptions.of(options, sim.options, owner=sim.name)
    if threads is not None:
        threads = integer_argument(threads, "threads", minimum=1, maximum=MAX_THREADS,
                                   owner=sim.name)
    S, _ = state_table(sim, states)
    P, one = parameter_table(sim, params)
    if not one and len(P) != len(S):
        raise ShapeError(f"{sim.name}: {len(S)} initial states but {len(P)} parameter sets; "
                         f"give one set for all, or one per state")
    from ._simulator import INITIAL_CONSTRAINT_TOLERANCE

    # (before the rows' own checks: a batch too large for memory is refused at once, not
    # after evaluating the constraints of a million rows)
    check_memory(sim, len(S), batch_rows(steps, every), steps, every)
    U = batch_inputs(sim.layout, inputs, len(S), steps, owner=sim.name)
    check_constraints(sim, S, P, INITIAL_CONSTRAINT_TOLERANCE)
    try:
        raw = run_batch(sim, S, P, steps, every, options, threads, U=U)
    except KeyboardInterrupt as interrupt:
        interrupt.batch = TrajectoryBatch(sim, interrupt.raw_batch, P, steps, every, options)
        raise
    return TrajectoryBatch(sim, raw, P, steps, every, options)
