"""Simulator: advance a step's equations from user-stated initial conditions."""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from .._arguments import callable_argument, counted, hot_path, instance_argument
from .._errors import (
    BranchJumpError,
    DomainError,
    InputTypeError,
    NewtonDivergenceError,
    ShapeError,
    SingularJacobianError,
    TrajectoryTooLargeError,
    UnsupportedFeatureError,
)
from .._progress import Task
from ..codegen import time_layout
from ..stepper import STEP_RATIO, Status, hold_time, time_step_kept
from ._backends import real_vector
from ._initial_states import InitialStates
from ._inputs import input_chunks, input_sequence, step_inputs
from ._layout import StateLayout
from ._memory import available_memory
from ._options import NewtonOptions
from ._run_buffers import SampledRun, WholeRun
from ._runs import OK, run_chunks
from ._trajectory import Sampler, Trajectory, kept_rows
from ._validate import constraint_check, integer_argument, parameter_vector, real_array

#: an initial state may violate a constraint by this much (absolute) besides rounding
INITIAL_CONSTRAINT_TOLERANCE = 1e-10

#: the least time step of a state on a time groupoid, in spacings of the floating-point
#: numbers at its times (2¹⁰: about three significant digits of t_k − t_{k−1})
TIME_STEP_SPACINGS = 1024

#: steps per kernel call of a simulation: bounds the memory of a chunk and the delay of
#: Ctrl-C (a KeyboardInterrupt is raised between calls)
CHUNK_STEPS = 1 << 14


class Simulator(InitialStates):
    """Runs the step (g_k, λ_k) ↦ (g_{k+1}, λ_{k+1}) of a :class:`StepEquations`.

    Obtain one with ``step.compile()`` (or :func:`compile_step`).  Initial states are given
    by name (see :meth:`state`), parameters by name or in ``step.parameters`` order.

    >>> sim = sg.systems.plate_ball().euler_lagrange().compile()         # doctest: +SKIP
    >>> params = {"h": 0.01, "r": 0.1, "Omega": 1.0, "c": 0.0}
    >>> state = sim.project_initial({"x": (0.0, 0.01), "y": (0.0, 0.0), "g": np.eye(3),
    ...                              "lambda": [0, 0, 0]}, params)     # onto φ = 0
    >>> traj = sim.simulate(state, steps=1000, params=params)            # doctest: +SKIP
    >>> traj["x"], traj["g"], traj.multipliers                          # doctest: +SKIP
    """

    def __init__(self, step, kernel, options: NewtonOptions | None = None,
                 cache_entry: Path | None = None):
        from ..equations import StepEquations

        instance_argument(step, StepEquations, "step", "the StepEquations of a system (a "
                          "simulator comes from system.compile())", owner="Simulator")
        if not all(callable(getattr(kernel, f, None)) for f in ("simulate", "warm_start")):
            raise InputTypeError(f"{step.name}: kernel must be a compiled kernel (a simulator "
                                 f"comes from system.compile()), got {type(kernel).__name__}")
        if options is not None:
            instance_argument(options, NewtonOptions, "options", "NewtonOptions",
                              owner=step.name)
        self.equations = step
        self.kernel = kernel
        self.options = options or NewtonOptions()
        self.cache_entry = cache_entry
        self.layout = StateLayout(step)
        self.time = time_layout(step)  # (kept when pickled: a restored step has no arrows)
        self.parameter_names = [str(s) for s in step.parameters]
        self._momentum = None
        self._forced_momentum = None

    @property
    def backend(self) -> str:
        """``"c"`` (compiled kernel) or ``"numpy"``."""
        return self.kernel.name

    @property
    def name(self) -> str:
        return self.equations.name

    # --- inputs ---------------------------------------------------------------------------------
    def parameters(self, params: Mapping | Sequence | None) -> np.ndarray:
        """Parameter vector in ``step.parameters`` order from a mapping or a sequence.

        One rule for every entry point (:func:`~symgroupoid.runtime._validate.parameter_vector`):
        every parameter named exactly once (unknown names are rejected), finite real values
        satisfying the assumptions the symbols are declared with (``positive=True``, …); a
        :class:`ParameterError` also for a zero the Lagrangian or the constraints divide by
        (a time step h = 0 not declared positive; :mod:`~symgroupoid.runtime._singular`).
        """
        p = parameter_vector(self.equations.parameters, params, owner=self.name)[0]
        if not p.all():  # a zero: refused where the equations divide by it (h = 0)
            from ._singular import check_zero_divisors

            check_zero_divisors(self.equations, p, self.name)
        return p

    def state(self, initial: Mapping | Sequence | np.ndarray, params=None) -> np.ndarray:
        """The flat known state (g_k, λ_k) from named parts or a flat vector.

        Named parts (a mapping): each coordinate of a pair-groupoid factor as two consecutive
        configurations ``(q_0, q_1)``; a group part (``"g"``, ``"W"``) as its matrix, checked
        to lie in the group; other coordinates (``"Gamma"``) by value; the multipliers as
        ``"lambda"`` (required when the system has constraints).  A flat vector must have
        ``len(step.knowns)`` finite entries, ordered as ``step.knowns``; its group parts are
        checked as named ones are.

        With ``params`` (as for :meth:`simulate`) the known arrows must also satisfy the
        system's constraints (first order φ(g_k); second order Φ on each known pair;
        nonholonomic ψ(g_k)) to rounding: |φ_i| ≤ max(INITIAL_CONSTRAINT_TOLERANCE,
        CONSTRAINT_ROUNDING·ε·M_i), M_i the size of φ_i's terms; a :class:`DomainError`
        gives the violation of each constraint that does not hold.
        """
        if isinstance(initial, Mapping):
            state = self.layout.pack(initial)
        else:
            if isinstance(initial, (str, bytes)) or initial is None:
                raise ShapeError(f"{self.name}: a state is a mapping of named parts or a flat "
                                 f"vector, got {initial!r}")
            arr = real_array(initial, "a flat state", owner=self.name)
            if arr.shape != (self.layout.n_known,):
                raise ShapeError(f"{self.name}: a flat state has shape ({self.layout.n_known},) "
                                 f"(the knowns {', '.join(s.name for s in self.equations.knowns)}"
                                 f"); got shape {arr.shape}")
            self.layout.check_finite(arr)
            state = self.layout.rounded(arr).copy()
            self.layout.check_arrows(state)
        if params is not None:
            self._check_constraints(state, self.parameters(params))
        return state

    def _check_constraints(self, state: np.ndarray, p: np.ndarray) -> None:
        self._check_time_step(state)
        constraint_check(self.equations)(state, p, atol=INITIAL_CONSTRAINT_TOLERANCE,
                                         owner=self.name)

    def _check_time_step(self, state: np.ndarray) -> None:
        """On a time groupoid: the known arrow's time step t_k − t_{k−1} is not 0, also
        not by rounding (t_{k−1} = 10¹⁷, t_k = t_{k−1} + 0.1); the step equations divide by
        it (a :class:`DomainError`, where Newton would meet NaN)."""
        t = self.time
        if t.known < 0 or t.before < 0:
            return
        before, now = float(state[t.before]), float(state[t.known])
        if now - before == 0.0:
            raise DomainError(f"{self.name}: the initial state's time step t_k - t_(k-1) is 0 "
                              f"(t_(k-1) = {before!r}, t_k = {now!r}: equal as floating-point "
                              f"numbers); the step equations divide by it, so give a nonzero "
                              f"time step that the times can represent")
        spacing = float(np.spacing(max(abs(before), abs(now))))
        if abs(now - before) < TIME_STEP_SPACINGS * spacing:
            raise DomainError(
                f"{self.name}: the initial state's time step t_k - t_(k-1) = {now - before:.3g} "
                f"is {abs(now - before) / spacing:.3g} times the spacing of floating-point "
                f"numbers at its times (t_k = {now!r}): the step equations, which read the "
                f"times and their differences, would hold fewer than three significant "
                f"digits of it, and their solution none (at least {TIME_STEP_SPACINGS} "
                f"spacings; shift the times toward 0)")

    def _run_parameters(self, params) -> np.ndarray:
        """:meth:`parameters`, through :meth:`step`'s screen first: a float64 vector or a
        dict of Python numbers whose values passed every check before is not parsed
        again (anything else, and every failure, takes :meth:`parameters`, which reports
        it)."""
        screened = self._fast_step.parameters(params)
        if screened is not None and np.isfinite(screened[0]).all():
            return screened[0]
        return self.parameters(params)

    def _initial_state(self, initial, p: np.ndarray) -> np.ndarray:
        """:meth:`state` (``initial``, the checked parameter vector ``p``), except that a
        flat float64 state this simulator checked or produced before, under the same values
        of the parameters its constraints use, is copied without checking it again (the
        table of :meth:`step`'s fast path: such a state is in its groups and on its
        constraints, and :meth:`state` would return it unchanged)."""
        fast = self._fast_step
        if (type(initial) is np.ndarray and initial.dtype == np.float64
                and initial.shape == (self.layout.n_known,)
                and initial.tobytes() + fast.key_tail(p) in fast.trusted):
            return initial.copy()
        known = self.state(initial)
        self._check_constraints(known, p)
        fast.trust(known, p)
        return known

    # --- running --------------------------------------------------------------------------------
    def simulate(self, initial, steps: int, params, *, options: NewtonOptions | None = None,
                 every: int = 1, callback: Callable[[Trajectory], None] | None = None,
                 progress: bool | None = None, inputs=None) -> Trajectory:
        """Advance ``steps`` steps from ``initial`` (see :meth:`state`).

        A forced system with inputs (docs/conventions.md §20) takes ``inputs`` of shape
        (steps, m): row j the inputs of the arrow step j computes (or (m,) for inputs held
        constant); the state carries the inputs of its own arrow (the part named after each
        input) and, after them, those of the next arrow (row j is written there before
        step j).  The inputs are checked (shape, finite) before any step runs.

        The run is computed in chunks of at most ``CHUNK_STEPS`` steps (bitwise the states
        of one uninterrupted run); with ``every`` = 1 the kernel writes every chunk straight
        into the arrays of the result.  ``every`` = e keeps state 0, every e-th state and the
        last one (1 + ⌈steps/e⌉ rows; see :class:`Trajectory` for the Newton data kept per
        interval), so long runs need memory only for what they keep.  ``callback``, if
        given, is called with each chunk's new states as soon as they are computed (a
        :class:`Trajectory` as yielded by :meth:`stream`).

        Raises :class:`SingularJacobianError` or :class:`NewtonDivergenceError` when step s
        fails, with the step index, its residual norm and last Newton iterate, and
        ``err.trajectory``: the trajectory up to state s (its kept states and state s).
        Ctrl-C (:class:`KeyboardInterrupt`, also when raised by ``callback``) stops the run
        within one chunk; the exception propagates with ``.trajectory``, the states kept so
        far.  Non-finite values are never returned.  ``steps`` and ``every`` are integers
        (integral floats such as ``1e7`` are accepted); ``options`` is None (the
        simulator's options) or a :class:`NewtonOptions`; ``callback`` None or a function;
        a :class:`TrajectoryTooLargeError` is raised up front when the states to keep
        exceed the machine's memory.  ``progress``: report a run taking longer than 2 s,
        updated between chunks (see :mod:`symgroupoid._progress`).
        """
        steps = integer_argument(steps, "steps", owner=self.name)
        every = integer_argument(every, "every", minimum=1, owner=self.name)
        options = NewtonOptions.of(options, self.options, owner=self.name)
        callback = callable_argument(callback, "callback", owner=self.name, none=True)
        p = self._run_parameters(params)
        known0 = self._initial_state(initial, p)
        U = input_sequence(self.layout, inputs, steps, owner=self.name, held=True)
        rows = kept_rows(steps, every)
        self._check_memory(steps, every, rows)
        U = U if self.layout.n_inputs else None  # (a system without inputs: none)
        run = (WholeRun(self, known0, p, rows, U) if every == 1
               else SampledRun(self, known0, p, rows, every, U))
        task = Task(f"{self.name}: simulating", total=steps, unit="steps",
                    progress=progress).start()
        try:
            run.advance(steps, options, task, callback, CHUNK_STEPS)
        except (SingularJacobianError, NewtonDivergenceError) as err:
            run.add_tail(getattr(err, "trajectory", None))
            err.trajectory = run.so_far()
            raise
        except KeyboardInterrupt as interrupt:
            interrupt.trajectory = run.so_far()
            raise
        finally:
            task.close(failed=run.filled < rows)
        traj = run.so_far()
        self._fast_step.trust(traj.states[-1], p)  # (a continuation starts from it)
        return traj

    def simulate_batch(self, states, steps: int, params, *, every: int = 1,
                       options: NewtonOptions | None = None, threads: int | None = None,
                       inputs=None):
        """Advance B runs at once: one run from each row of ``states``.

        ``states``: a table of initial states (a 2-D array (B, n_known) of flat states, or a
        sequence of states as :meth:`state` takes them); ``params``: one parameter set for
        all runs, or a table of B sets (a sequence of sets, a 2-D array (B, n_params) in
        ``step.parameters`` order, a mapping name → column of B values, or a pandas
        DataFrame).  Every row is checked as :meth:`simulate` checks its inputs (vectorised;
        an error names the row).  ``every`` keeps state 0, every e-th state and the last, as
        in :meth:`simulate`.

        The compiled kernel advances the runs by ``<prefix>_simulate_batch_until``, each run
        by the same code as :meth:`simulate` (bitwise the same states, iterations and
        residual norms), in calls of about 0.05 s with the Newton warm start carried across
        them, the runs shared among ``threads`` threads (None: all cores; an integer 1 …
        ``MAX_THREADS`` = 1024, never more than the groups of runs; the kernel releases the
        GIL).  A run that fails stops alone: its status, failing step and the error
        :meth:`simulate` would raise are recorded, the others go on.  Ctrl-C takes effect
        within a call: the ``KeyboardInterrupt`` carries ``.batch``, each run up to the step
        it reached (status ``INTERRUPTED``).  A :class:`TrajectoryTooLargeError` when the
        states to keep do not fit in memory.  Returns a
        :class:`~symgroupoid.runtime._batch.TrajectoryBatch` (``batch[b]`` is run b as a
        :class:`Trajectory`).

        A forced system (docs/conventions.md §20) takes ``inputs``: an array (B, steps, m),
        row j of run b the input of the arrow its step j computes, or the inputs of one run
        as :meth:`simulate` takes them ((steps, m), or (m,) held constant) for every run;
        each run is bitwise ``simulate(states[b], steps, params, inputs=inputs[b])``.
        """
        from ._batch import simulate_batch

        return simulate_batch(self, states, steps, params, every=every, options=options,
                              threads=threads, inputs=inputs)

    def __reduce__(self):
        """Pickled as its generated C, flags and content hash, options and the names and
        layout of its step (plain data; see :mod:`symgroupoid.runtime._pickle`).  In another
        process the kernel is built into, or loaded from, that process's kernel cache."""
        from ._pickle import recipe_of, restore_simulator

        return restore_simulator, (recipe_of(self),)

    def stream(self, initial, steps: int, params, *, options: NewtonOptions | None = None,
               every: int = 1, inputs=None) -> Iterator[Trajectory]:
        """:meth:`simulate` as an iterator: one :class:`Trajectory` per chunk, for processing
        a long run on the fly without keeping it.

        Each piece starts with the last state of the previous piece (the first with state
        0) followed by the states kept in the chunk, with their ``step_indices``; pieces
        without a new kept state are skipped.  Joining the pieces (dropping the first row
        of every piece after the first) gives ``simulate(..., every=every)``.  A failure at
        step s raises as in :meth:`simulate`, with ``err.trajectory`` the piece from the
        last state yielded to state s.  A forced system takes ``inputs`` as
        :meth:`simulate` does (checked before the first piece).
        """
        steps = integer_argument(steps, "steps", owner=self.name)
        every = integer_argument(every, "every", minimum=1, owner=self.name)
        options = NewtonOptions.of(options, self.options, owner=self.name)
        p = self.parameters(params)
        known0 = self.state(initial, p)
        U = input_sequence(self.layout, inputs, steps, owner=self.name, held=True)
        if steps == 0:  # one piece, state 0 alone: what simulate(initial, 0, ...) returns
            return iter([self._trajectory(known0[None], np.zeros(0, dtype=np.int64),
                                          np.zeros(0), p, np.zeros(1, dtype=np.int64),
                                          every)])
        return self._pieces(known0, p, steps, every, options,
                            inputs=U if self.layout.n_inputs else None)

    def _pieces(self, known0: np.ndarray, p: np.ndarray, steps: int, every: int,
                options: NewtonOptions, task: Task | None = None,
                inputs: np.ndarray | None = None) -> Iterator[Trajectory]:
        sampler = Sampler(every, steps, known0)
        chunks = (run_chunks(self.kernel, known0, p, steps, options, CHUNK_STEPS)
                  if inputs is None else
                  input_chunks(self.kernel, self.layout, known0, p, inputs, options,
                               CHUNK_STEPS))
        for start, run in chunks:
            before_index, before_state = sampler.last_index, sampler.last_state
            segment = sampler.take(start, run)
            if task is not None:
                task.update(start + run.completed)
            piece = self._trajectory(
                np.concatenate([before_state[None], segment.states]), segment.iterations,
                segment.residual_norms, p,
                np.concatenate([[before_index], segment.step_indices]), every)
            if run.status != OK:
                k = run.failed_step
                err = self._failure(run.status, start + k, run.iterations[k],
                                    run.residual_norms[k], run.last_iterate, options,
                                    known=run.states[k], p=p)
                err.trajectory = piece
                raise err
            if len(segment.states):
                yield piece

    def _chunk_failure(self, chunk, start: int, iterations: np.ndarray,
                       norms: np.ndarray, options: NewtonOptions,
                       states: np.ndarray | None = None,
                       p: np.ndarray | None = None) -> Exception:
        """The error of a :class:`~symgroupoid.runtime._backends.ChunkRun` that failed
        (its failed step's data at entry start + k of the run's buffers, its known state
        at row start + k of ``states``)."""
        k = chunk.failed_step
        if k < 0:  # nothing was solved: the kernel refused its arguments
            return self._failure(chunk.status, start, 0, float("nan"), chunk.last_iterate,
                                 options)
        known = None if states is None else states[start + k]
        return self._failure(chunk.status, start + k, iterations[start + k],
                             norms[start + k], chunk.last_iterate, options, known=known, p=p)

    def _trajectory(self, states, iterations, norms, p, indices, every) -> Trajectory:
        values = dict(zip(self.parameter_names, p.tolist()))
        return Trajectory(self.layout, states, iterations, norms, values, self.backend,
                          step_indices=indices, every=every)

    def _check_memory(self, steps: int, every: int, rows: int) -> None:
        """Refuse up front to keep more states than this process may allocate: the
        machine's physical memory, lowered by ``ulimit -v`` / ``-d``
        (:func:`~symgroupoid.runtime._memory.available_memory`, as batches check it)."""
        room = available_memory()
        needed = rows * (8 * self.layout.n_known + 28)
        if room is not None and needed > room:
            raise TrajectoryTooLargeError(
                f"{self.name}: keeping {rows} states (steps={steps}, every={every}) needs "
                f"{needed / 2**30:.1f} GiB, more than this process may allocate "
                f"({room / 2**30:.1f} GiB); keep fewer with every=k, or process the run "
                f"on the fly with Simulator.stream(...) or a callback")

    @hot_path  # (its calls are not wrapped: 2 µs of Python a call at most)
    def step(self, state, params, *, options: NewtonOptions | None = None, inputs=None
             ) -> np.ndarray:
        """One step: the next flat state from a state (named or flat), the same bits as
        ``simulate(state, 1, params, options=options).states[1]``.

        Made for a control loop, ``state = sim.step(state, p)``: the inputs are checked as
        :meth:`simulate` checks them, but a flat float64 state that this simulator
        returned (or checked) before, under the same values of the parameters its
        constraints use, is not checked again — it is on the constraints and in the group
        already, as the states inside a run are — and parameters given as a float64 vector
        in ``step.parameters`` order (``p = sim.parameters({...})``) or as a dict of
        Python numbers by name are screened without parsing.  The step itself is one call
        of the kernel; the Python around it costs under 2 µs (plate-ball:
        ``benchmarks/step.py``), least when the state passed is the array the last call
        returned.  Any other input, and every failure, goes through the checks and errors
        of :meth:`simulate`; a state changed in place is checked again.  The states
        returned are rows of blocks of up to 64 states (32 KiB), and a state kept keeps its
        block: to keep every k-th state of a long loop, keep copies (``s.copy()``).

        A forced system with inputs takes ``inputs``: the m inputs of the arrow this step
        computes (the state carries those of its own arrow), the same bits as
        ``simulate(state, 1, params, inputs=[inputs]).states[1]``.
        """
        fast = self.__dict__["step"] = self._fast_step.call  # this instance's step from now
        return fast(state, params, options=options, inputs=inputs)

    def _checked_call(self, state, params, options, inputs) -> np.ndarray:
        """:meth:`step` through every check (what its fast path does not take)."""
        return self._checked_step(state, params, options,
                                  step_inputs(self.layout, inputs, owner=self.name))

    def _checked_step(self, state, params, options, u=None) -> np.ndarray:
        """:meth:`step` with every check of :meth:`simulate` (the first call of a loop, or
        an input the fast path does not know); a failed step raises as :meth:`simulate`
        does, with ``err.trajectory``."""
        options = NewtonOptions.of(options, self.options, owner=self.name)
        p = self.parameters(params)
        known = self.state(state, p)
        fast = self._fast_step
        fast.trust(known, p)
        if u is None:
            status, after = fast.run(known, p, options)
        else:  # the kernel's entry with the new arrow's inputs
            entry, view_of, options_of, _ = self.kernel.step_entry()
            after = np.empty(self.layout.n_known)
            status = entry(view_of(known), view_of(p), view_of(u), options_of(options),
                           view_of(after))
        if status != OK:  # the run of one step raises the error, with its trajectory
            return self.simulate(known, 1, p, options=options,
                                 inputs=None if u is None else u[None]).states[1].copy()
        fast.trust(after, p)
        return after

    @functools.cached_property
    def _fast_step(self):
        from ._fast_step import FastStep

        return FastStep(self)

    def solve(self, state, params, *, guess=None, options: NewtonOptions | None = None,
              inputs=None):
        """Solve one step: (unknowns u, Newton iterations, residual norm); raises on failure.

        ``guess`` (default: the step's prediction, on a time groupoid solved onto the
        fixed-step equations as :meth:`simulate` does) must hold ``len(step.unknowns)``
        finite numbers (a :class:`ShapeError` otherwise).  On a time groupoid a solution
        whose time step reverses or changes by more than a factor 2 is a
        :class:`BranchJumpError` (docs/conventions.md §7).  ``options``: None (the simulator's) or a
        :class:`NewtonOptions`, as for :meth:`simulate`.  A forced system with inputs takes
        ``inputs``: the m inputs of the arrow the step computes, as for :meth:`step`.
        """
        options = NewtonOptions.of(options, self.options, owner=self.name)
        p = self.parameters(params)
        known = self.state(state, p)
        u_next = step_inputs(self.layout, inputs, owner=self.name)
        if u_next is not None:  # the slot of the new arrow's inputs (docs/conventions.md §20)
            known = known.copy()
            known[self.layout.upcoming_index] = u_next
        time = self.time
        if guess is None:
            u0 = self.kernel.predict(known, p)
            if not np.isfinite(u0).all():
                raise self._failure(Status.NON_FINITE, 0, 0, float("nan"), u0, options, known=known,
                                    p=p)
            u0 = hold_time(self.kernel.residual_jacobian, time, known, p, u0)
        else:
            u0 = real_vector(guess, len(self.equations.unknowns), "guess", owner=self.name,
                             finite=True)
        status, u, it, rn = self.kernel.solve_step(known, p, u0, options)
        if status == OK and not time_step_kept(time, known, u, options.trust_factor):
            status = Status.BRANCH_JUMP
        if status != OK:
            raise self._failure(status, 0, it, rn, u, options, known=known, p=p)
        return u, it, rn

    def input_jacobian(self, state, params, *, inputs=None, unknowns=None) -> np.ndarray:
        """∂F/∂(inputs) of the step from ``state`` with the new arrow's ``inputs``, exact,
        evaluated by the kernel (the compiled ``<prefix>_input_jacobian``; the NumPy
        backend's program gives the same bits), shape (len(step.unknowns), (r + 1)·m) for
        order r: the columns of u_k, then of u_{k+1} (second order: u_{k−1}, u_k, u_{k+1};
        docs/conventions.md §20).  At ``unknowns``, else at the step's solution
        (:meth:`solve`, which raises if the step fails).  With the step's Jacobian J
        (``kernel.residual_jacobian``) it gives the implicit derivative of the solution in
        the inputs, −J⁻¹ ∂F/∂u, which a controller or an optimiser linearises with.  Bad
        arguments are refused before the kernel runs; finite ones at which ∂F/∂u overflows
        are a :class:`DomainError`, never a matrix with NaN or inf."""
        m = self.layout.n_inputs  # (an unpickled simulator's step holds no symbols)
        if not m:
            raise UnsupportedFeatureError(f"{self.name}: the system has no inputs")
        p = self.parameters(params)
        known = self.state(state, p)
        u_next = step_inputs(self.layout, inputs, owner=self.name)
        if unknowns is None:
            unknowns = self.solve(known, p, inputs=inputs)[0]
        x = real_vector(unknowns, len(self.equations.unknowns), "unknowns", owner=self.name,
                        finite=True)
        known = known.copy()
        known[self.layout.upcoming_index] = u_next
        J = self.kernel.input_jacobian(x, known, p, (self.equations.order + 1) * m)
        if not np.isfinite(J).all():  # finite arguments whose derivative overflows
            rows, cols = np.nonzero(~np.isfinite(J))
            raise DomainError(f"{self.name}: input_jacobian: ∂F/∂(inputs) is not finite at "
                              f"these unknowns, state and inputs (entry ({int(rows[0])}, "
                              f"{int(cols[0])}) is {J[rows[0], cols[0]]}): it overflows "
                              f"there; use values of the size the system is meant for")
        return J

    def _failure(self, status: int, step: int, iterations: int, residual_norm: float,
                 iterate: np.ndarray, options: NewtonOptions | None = None, *,
                 known: np.ndarray | None = None, p: np.ndarray | None = None) -> Exception:
        """The error of a failed step ``step`` (of the run: the warm start holds two
        solutions from its step 2 on, so that a step of a run with ``extrapolate`` was tried
        twice, from the extrapolated guess and from the prediction).  A step that gave
        non-finite values at the known state ``known`` is explained where a cause is found
        (a half-turn, a zero parameter; :mod:`~symgroupoid.runtime._singular`)."""
        if status == Status.OUTSIDE_DOMAIN:  # a solution where L is not defined: say which
            from ._singular import outside_domain_error

            err = outside_domain_error(self, step, iterations, residual_norm, iterate, known, p,
                                       f"{self.name}: step {step} failed")
            err.trajectory = None
            return err
        if status == Status.NON_FINITE and known is not None:  # a half-turn, h = 0: say which
            from ._singular import non_finite_cause

            found = non_finite_cause(self, step, iterations, residual_norm, iterate, known,
                                     p, f"{self.name}: step {step} failed")
            if found is not None:
                found.trajectory = None
                return found
        options = self.options if options is None else options
        tries = ("" if not options.extrapolate or step < 2 else
                 f" in two tries of at most {options.max_iterations} each, from the "
                 f"extrapolated guess and from the step's prediction")
        text = (f"{self.name}: step {step} failed: {Status(status).message} (after "
                f"{counted(int(iterations), 'Newton iteration')}{tries}, "
                f"|F|_inf = {residual_norm:.3e})")
        if status == Status.INVALID_ARGUMENT:  # the checks above let nothing invalid through
            return DomainError(text)
        if status == Status.NOT_CONVERGED:
            text += (f"; the cap is NewtonOptions(max_iterations={options.max_iterations}) "
                     f"per try")
        if status == Status.BRANCH_JUMP:
            text += (self._time_step_jump(iterate, known)
                     or f"; NewtonOptions(trust_factor={options.trust_factor:g}) sets the "
                        f"trust region, trust_factor=0 turns the check off")
        cls = {Status.SINGULAR_JACOBIAN: SingularJacobianError,
               Status.BRANCH_JUMP: BranchJumpError}.get(status, NewtonDivergenceError)
        err = cls(text, step=int(step), residual_norm=float(residual_norm),
                  iterate=np.array(iterate, dtype=float))
        err.trajectory = None
        return err

    def _time_step_jump(self, iterate: np.ndarray, known: np.ndarray | None) -> str:
        """The sentence naming the time step check of a step on a time groupoid when the
        solution ``iterate`` from ``known`` fails it (docs/conventions.md §7), else ""."""
        t = self.time
        if t.unknown < 0 or known is None or len(iterate) <= t.unknown:
            return ""
        last = float(known[t.known] - known[t.before])
        new = float(iterate[t.unknown] - known[t.known])
        with np.errstate(all="ignore"):
            ratio = new / last
        if 1.0 / STEP_RATIO <= ratio <= STEP_RATIO:
            return ""
        return (f"; the time step check failed: the solution's step t_{{k+1}} - t_k = "
                f"{new:.6g} is {ratio:.3g} times the last step t_k - t_{{k-1}} = {last:.6g}"
                f" (a step on a time groupoid keeps its sign and changes by at most a factor "
                f"{STEP_RATIO:g}; docs/conventions.md §7): Newton did not reach a root with a "
                f"step of that sign and size from its guesses (there may be none: the energy "
                f"equation of an energy-preserving step can lose it, where no step near the "
                f"last one keeps the discrete energy); NewtonOptions(trust_factor=0) turns "
                f"the branch checks off")

    def __repr__(self) -> str:
        return (f"<Simulator {self.name!r}: {len(self.equations.unknowns)} unknowns, "
                f"backend {self.backend}>")
