"""Trajectory: the result of :meth:`Simulator.simulate`, with named arrays.

A run is computed in chunks (see :func:`~symgroupoid.runtime._backends.run_chunks`); a
:class:`Sampler` keeps every ``every``-th state of the chunks and summarises the Newton
data of the steps in between, so memory grows with the states kept, not the steps taken.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .._arguments import instance_argument, shown_value
from .._errors import (
    DomainError,
    InputNameError,
    InputTypeError,
    ShapeError,
    UnsupportedFeatureError,
)
from ._layout import MULTIPLIER_KEYS, StateLayout
from ._runs import OK, RawRun


def _check_parts(layout, states, iterations, residual_norms, parameters, backend) -> None:
    """An :class:`~symgroupoid.InputTypeError` unless the parts of a trajectory are those a
    simulator gives (a trajectory comes from ``Simulator.simulate`` or ``Trajectory.load``):
    a state layout, NumPy arrays of states (2-D), Newton iterations and residual norms
    (1-D), the parameters as a dict and the backend's name."""
    instance_argument(layout, StateLayout, "layout", "a StateLayout (a trajectory comes "
                      "from Simulator.simulate or Trajectory.load)", owner="Trajectory")
    for name, value, dims in (("states", states, 2), ("iterations", iterations, 1),
                              ("residual_norms", residual_norms, 1)):
        if not isinstance(value, np.ndarray) or value.ndim != dims:
            raise InputTypeError(f"{layout.step_name}: {name} must be a {dims}-D NumPy "
                                 f"array, got {type(value).__name__} {shown_value(value)}")
    instance_argument(parameters, dict, "parameters", "a dict", owner=layout.step_name)
    instance_argument(backend, str, "backend", "the backend's name", owner=layout.step_name)

class Trajectory:
    """States k = k_0, k_0 + e, k_0 + 2e, …, and the last one, of a run of N steps.

    With ``every`` = e = 1 (the default of :meth:`Simulator.simulate`) every state is kept:

    - ``traj.states``: (R, n_known) flat states (g_k, λ_k) of the kept steps (R = N + 1
      when e = 1, else 1 + ⌈N/e⌉: state 0, every e-th state and the last state N);
    - ``traj.step_indices`` (R,): the step index k of each kept state (0, e, 2e, …, N; a
      run that stopped early ends at the last state it reached);
    - ``traj[name]``: a named part per kept state, e.g. ``traj["g"]`` (R, 3, 3),
      ``traj["Gamma"]`` (R, 3); a coordinate of a pair-groupoid factor, held at several
      steps by each state (q_k, q_{k+1}), gives the older values of the first kept state
      followed by the newest value of every kept state — with e = 1 all positions
      q_0, q_1, …, q_{N+1} (N + 2 values), with e > 1 the positions q_0, q_1, q_{e+1},
      q_{2e+1}, …;
    - ``traj.multipliers``: (R, m) multipliers λ_k of each kept state;
    - ``traj.newton_iterations`` (R − 1,) and ``traj.residual_norms`` (R − 1,): for each
      interval between consecutive kept states, the total number of Newton updates and the
      largest final |F|_∞ of its steps (with e = 1: those of each step);
    - ``traj.steps``: the number of steps N covered; ``traj.every``: e;
    - ``traj.parameters``: the parameter values used, by name.

    Named views are computed on first access and cached (read-only arrays).  Diagnostics
    (:mod:`symgroupoid.diagnostics`): ``traj.energy()``, ``traj.momenta()``,
    ``traj.constraint_residuals()``, ``traj.conservation_summary()``; figures:
    ``traj.plot()`` and :func:`symgroupoid.plot_conservation`.  The configurations the run
    passes through, ``traj.configurations(start)`` (a Lie group's state is the increment
    W_k = R_k⁻¹R_{k+1}: the attitudes R_k are multiplied out from R_0), and the momenta in
    the spatial frame, ``traj.spatial_momenta(start)``.  Files: ``traj.save(path)``
    (``.npz`` or ``.csv``, as ``symgroupoid simulate -o`` writes) and
    ``Trajectory.load(path, sim)``.
    """

    def __init__(self, layout: StateLayout, states: np.ndarray, iterations: np.ndarray,
                 residual_norms: np.ndarray, parameters: dict, backend: str, *,
                 step_indices: np.ndarray | None = None, every: int = 1):
        _check_parts(layout, states, iterations, residual_norms, parameters, backend)
        rows = len(states)
        if step_indices is None:
            step_indices = np.arange(rows, dtype=np.int64)
        if not (len(iterations) == len(residual_norms) == rows - 1 == len(step_indices) - 1):
            raise ShapeError(f"inconsistent trajectory: {rows} states, {len(step_indices)} "
                             f"step indices, {len(iterations)} iteration counts and "
                             f"{len(residual_norms)} residual norms")
        self._layout = layout
        self.states = states
        self.step_indices = np.asarray(step_indices, dtype=np.int64)
        self.newton_iterations = iterations
        self.residual_norms = residual_norms
        self.parameters = parameters
        self.backend = backend
        self.every = int(every)
        for arr in (self.states, self.step_indices, iterations, residual_norms):
            arr.setflags(write=False)
        self._views: dict = {}  # named views, computed on first access (states are read-only)

    @property
    def system_name(self) -> str:
        """The name of the system whose run this is (a Noether quantity of another system
        refuses it)."""
        return self._layout.step_name

    def is_run_of(self, system) -> bool | None:
        """Whether this is a run of ``system``: True for the system its simulator was
        derived from or one with the same ``fingerprint`` (the same system built again),
        False for another (which may have the same name); None where the simulator has no
        symbolic system (restored from a pickle, or a file's trajectory).  A Noether
        quantity refuses a run of another system."""
        own = getattr(self._layout.equations, "system", None)
        if own is None or not hasattr(own, "fingerprint"):
            return None
        return own is system or own.fingerprint == getattr(system, "fingerprint", None)

    @property
    def steps(self) -> int:
        """Number of steps N covered (from the first kept state to the last)."""
        return int(self.step_indices[-1] - self.step_indices[0])

    def __len__(self) -> int:
        return len(self.states)

    @property
    def multipliers(self) -> np.ndarray:
        return self._view("lambda")

    def keys(self) -> list[str]:
        return list(self._layout.names) + (["lambda"] if self._layout.n_multipliers else [])

    def __getitem__(self, name: str) -> np.ndarray:
        """A named part at every kept state (read-only; computed once, then cached).

        A part held at several steps of a state (a pair-groupoid coordinate: x_{k−1}, x_k)
        gives the older values of the first state, then the newest value of every kept
        state: with ``every=e`` that is x_0, then x_1, x_{e+1}, x_{2e+1}, … — one more entry
        than ``step_indices`` (0, e, 2e, …), the first two one step apart, each later one
        the newest value of the state at the matching step index."""
        if not isinstance(name, str) or (name not in self._layout.parts
                                         and name not in MULTIPLIER_KEYS):
            raise InputNameError(f"{self._layout.step_name}: no part named {name!r}; "
                                 f"available: {', '.join(self.keys())}")
        return self._view(name)

    def _view(self, name: str) -> np.ndarray:
        key = "lambda" if name in MULTIPLIER_KEYS else name
        hit = self._views.get(key)
        if hit is None:
            hit = self._layout.view(self.states, key)
            hit.setflags(write=False)
            self._views[key] = hit
        return hit

    def __contains__(self, name: str) -> bool:
        return isinstance(name, str) and (name in self._layout.parts
                                          or name in MULTIPLIER_KEYS)

    def final_state(self) -> np.ndarray:
        """The last flat state (a valid initial state for a continuation)."""
        return self.states[-1].copy()

    # --- configurations -----------------------------------------------------------------------
    def configurations(self, start=None):
        """The configurations the run passes through, from the arrows of its states.

        The state of a Lie-group system holds increments, not attitudes: W_k = R_k⁻¹R_{k+1}
        (SO(3): R_kᵀR_{k+1}, the rotation from one attitude to the next, in the body frame).
        The attitudes are R_{k+1} = R_k W_k from R_0 = ``start`` (default: the identity) —
        the groupoid's own multiplication (:meth:`Groupoid.configurations_along`), so N
        steps give N + 2 configurations R_0, …, R_{N+1}, as ``traj[name]`` gives the N + 2
        positions of a pair-groupoid coordinate.  Each groupoid knows its configurations: a
        Lie group an (N + 2, n, n) array; a pair groupoid the points its arrows hold
        (``start`` left out, or equal to them); :class:`TrivialisedPairGroupoid` its q_k;
        products a tuple with one entry per factor (``start``: None, or one entry per
        factor, None for a part the state determines, e.g. ``(None, R0)`` for the
        plate-ball); action groupoids (points, R_k); time groupoids (times, the inner
        configurations).

        Needs every state (``every`` = 1; a :class:`DomainError` otherwise); second-order
        trajectories start at their oldest arrow g_{-1}.
        """
        from ._validate import partial_configuration

        G = self._layout.groupoid
        arrows = self._consecutive_arrows("configurations")
        start = partial_configuration(G, start, "start", owner=self._layout.step_name)
        return G.configurations_along(arrows, start)

    def spatial_momenta(self, start=None) -> np.ndarray:
        """The discrete momenta F⁻L(g_k) of every state (``momenta().minus``) in the spatial
        frame, (R, rank): on a Lie group, whose sections move the configuration R_k on the
        right, the body momentum μ_k becomes Ad*_{R_k⁻¹}μ_k (SO(3): R_k μ_k, the angular
        momentum in space, constant for a left-invariant Lagrangian such as the free rigid
        body: the Noether quantity of rotations of space, seed 000 Thm 4.9); components of a
        pair groupoid of Rⁿ stay as they are.  R_k from ``start`` as in
        :meth:`configurations`.  First-order trajectories with every state."""
        from ._validate import partial_configuration

        if getattr(self._layout.equations, "order", 1) != 1:
            raise UnsupportedFeatureError(f"{self._layout.step_name}: spatial momenta are "
                                          f"defined here for first-order systems")
        G = self._layout.groupoid
        arrows = self._consecutive_arrows("spatial momenta")
        start = partial_configuration(G, start, "start", owner=self._layout.step_name)
        return G.spatial_momenta(self.momenta().minus, arrows, start)

    def _consecutive_arrows(self, what: str) -> np.ndarray:
        if self.every != 1:
            raise DomainError(f"{self._layout.step_name}: {what} are rebuilt from every "
                              f"arrow of the run, but this trajectory keeps every "
                              f"{self.every}-th state; simulate with every=1")
        return self._layout.arrows(self.states)

    # --- files -----------------------------------------------------------------------------------
    def save(self, path) -> None:
        """Write the trajectory to ``path``: ``.npz`` (every array, the state columns and
        the parameters; read with ``numpy.load(path, allow_pickle=False)``) or ``.csv``
        (one row per kept state) — the files ``symgroupoid simulate -o`` writes
        (docs/cli.md).  Written beside the target and renamed into place."""
        from ._files import output_path, save_trajectory

        save_trajectory(self, output_path(path, self._layout.step_name))

    @classmethod
    def load(cls, path, simulator, params=None) -> Trajectory:
        """The trajectory :meth:`save` (or ``simulate -o``) wrote to ``path``, for
        ``simulator`` (a :class:`Simulator`, or the step equations).

        The file's state columns must be this system's (names and order, not merely as
        many; a :class:`~symgroupoid.TrajectoryFileError` otherwise), and so must its
        parameter names.  ``params``: the parameter values, by name or in order — required
        for a ``.csv`` file, which holds none; for an ``.npz`` they replace the file's.
        Never runs code from the file (``allow_pickle=False``)."""
        from .._errors import SymgroupoidError, TrajectoryFileError
        from ._files import read_trajectory
        from ._validate import parameter_vector

        layout, names, backend = _layout_of(simulator)
        data = read_trajectory(path, layout, names)
        parameters = data.parameters
        if params is not None:
            parameters = parameter_vector(layout.equations.parameters, params,
                                          owner=layout.step_name)[1]
        elif parameters is not None:  # checked as a run's: the diagnostics read them
            try:
                parameters = parameter_vector(layout.equations.parameters, parameters,
                                              owner=layout.step_name)[1]
            except SymgroupoidError as exc:
                raise TrajectoryFileError(f"{str(path)!r}: its parameter values are not "
                                          f"this system's: {exc}") from None
        else:
            raise TrajectoryFileError(f"{layout.step_name}: {str(path)!r} is a .csv "
                                      f"trajectory, which holds no parameter values: pass "
                                      f"params=...")
        rows = len(data.states)
        suspects = [0, rows - 1, *layout.off_group_rows(data.states)]  # every row at once;
        for row in dict.fromkeys(suspects):  # the ends and the suspects in full, as a state
            try:
                layout.check_arrows(data.states[row])
            except SymgroupoidError as exc:
                raise TrajectoryFileError(f"{str(path)!r}: its state {row} (of "
                                          f"{rows}) is not this system's: "
                                          f"{exc}") from None
        values = [parameters[str(s)] for s in layout.equations.parameters]
        row = layout.unjoined_row(data.states, data.step_indices, values)
        if row is not None:
            raise TrajectoryFileError(f"{str(path)!r}: its states {row} and {row + 1} (of "
                                      f"{rows}, at consecutive steps) do not join: the "
                                      f"arrows of a run compose, each starting where the one "
                                      f"before it ends (an edited value?)")
        return cls(layout, data.states, data.iterations, data.norms, parameters,
                   data.backend or backend, step_indices=data.step_indices, every=data.every)

    # --- diagnostics (symgroupoid.diagnostics) -------------------------------------------------
    def energy(self, step_parameter: str | None = None) -> np.ndarray:
        """The discrete energy at every kept state, (R,): E_d = −∂L_d/∂h for the time step h
        (``step_parameter`` names it; default: the system's ``time_step``, declared or
        identified by the continuous limit, docs/conventions.md §19), or on a time groupoid
        the energy conjugate to time, −∂L/∂t₁ (seed 000 §6.3).  See
        :mod:`symgroupoid.diagnostics`."""
        from ._diagnostics import energy

        return energy(self, step_parameter)

    def momenta(self):
        """The discrete momenta F⁻L, F⁺L (seed 000 §3.3) at every kept state: a
        :class:`~symgroupoid.diagnostics.Momenta` with arrays ``minus``, ``plus`` (R, rank)."""
        from ._diagnostics import momenta

        return momenta(self)

    def constraint_residuals(self) -> np.ndarray:
        """The system's constraints φ on the newest known arrows of every kept state, (R, m)."""
        from ._diagnostics import constraint_residuals

        return constraint_residuals(self)

    def conservation_summary(self, **options):
        """Max drift of each conserved quantity, with its rounding floor (see
        :func:`symgroupoid.diagnostics.conservation_summary` for the options)."""
        from ._diagnostics import conservation_summary

        return conservation_summary(self, **options)

    def plot(self, parts: Sequence[str] | None = None, *, path=None, **options):
        """A matplotlib figure of the named parts against time (or the step; see
        :func:`symgroupoid.plotting.plot_trajectory`); saved to ``path`` if given."""
        from .. import plotting  # a convenience that looks up (docs/architecture.md)

        return plotting.plot_trajectory(self, parts, path=path, **options)

    # --- display --------------------------------------------------------------------------------
    def _summary(self) -> list[tuple[str, str]]:
        rows = [("system", self._layout.step_name),
                ("steps", f"{self.steps} ({len(self)} states kept"
                          + (f", every {self.every})" if self.every != 1 else ")")),
                ("parts", ", ".join(f"{k} {self._part_shape(k)}" for k in self.keys())),
                ("parameters", ", ".join(f"{k}={v:g}" for k, v in self.parameters.items())
                 or "none"),
                ("backend", self.backend)]
        if len(self.newton_iterations):
            per_step = self.newton_iterations.sum() / max(self.steps, 1)
            rows.append(("Newton", f"{per_step:.2f} iterations per step, largest |F|∞ "
                                   f"{self.residual_norms.max():.1e}"))
        return rows

    def _part_shape(self, name: str) -> str:
        part = self._layout.multiplier_part if name == "lambda" else self._layout.parts[name]
        shape = part.shape if part is not None else ()
        return "×".join(map(str, shape)) if shape else "scalar"

    def __repr__(self) -> str:
        rows = dict(self._summary())
        steps = rows.pop("steps").split(" ", 1)
        head = (f"<Trajectory {rows.pop('system')!r}: {steps[0]} steps {steps[1]}, "
                f"backend {rows.pop('backend')}")
        return "\n  ".join([head] + [f"{k}: {v}" for k, v in rows.items()]) + ">"

    def _repr_html_(self) -> str:
        rows = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th>"
                       f"<td style='text-align:left'>{html.escape(v)}</td></tr>"
                       for k, v in self._summary())
        return f"<table><caption>Trajectory</caption>{rows}</table>"


def _layout_of(simulator) -> tuple[StateLayout, list[str], str]:
    """(state layout, parameter names, backend) of a simulator or step equations."""
    from ..equations import StepEquations

    layout = getattr(simulator, "layout", None)
    if isinstance(layout, StateLayout):
        return layout, list(simulator.parameter_names), simulator.backend
    if isinstance(simulator, StepEquations):
        return StateLayout(simulator), [str(p) for p in simulator.parameters], ""
    raise InputTypeError(f"Trajectory.load: simulator must be a Simulator or the step "
                         f"equations the trajectory belongs to, got "
                         f"{type(simulator).__name__}")


@dataclass
class Segment:
    """States kept from one chunk, with the Newton summary of the interval before each."""

    states: np.ndarray  # (r, n_known)
    step_indices: np.ndarray  # (r,)
    iterations: np.ndarray  # (r,) total Newton updates since the previous kept state
    residual_norms: np.ndarray  # (r,) largest |F| since the previous kept state


class Sampler:
    """Keeps state 0, every ``every``-th state and the last state of a run of ``steps``
    steps delivered in chunks (a :class:`RawRun` each, in order).

    Between consecutive kept states it sums the Newton iterations and takes the largest
    residual norm of the steps; steps after the last kept state are carried to the next
    chunk.  When a chunk failed at step s, its last valid state s is kept too (the end of
    the trajectory up to the failure).
    """

    def __init__(self, every: int, steps: int, state0: np.ndarray):
        self.every, self.steps = every, steps
        self.last_index = 0
        self.last_state = np.array(state0, dtype=float)
        self._carry_iterations = 0
        self._carry_norm = 0.0

    def take(self, start: int, run: RawRun) -> Segment:
        """The states kept from ``run``, whose first state has step index ``start``."""
        m = run.completed
        end = start + m
        first = (start // self.every + 1) * self.every
        kept = np.arange(first, end + 1, self.every, dtype=np.int64)
        at_end = run.status != OK or end == self.steps
        if at_end and end != self.last_index and (kept.size == 0 or kept[-1] != end):
            kept = np.append(kept, end)
        its, norms = run.iterations[:m], run.residual_norms[:m]
        offsets = kept - start
        bounds = np.concatenate(([0], offsets))
        sums = np.zeros(len(kept), dtype=np.int64)
        maxima = np.zeros(len(kept))
        if len(kept):
            nonempty = np.diff(bounds) > 0
            if nonempty.any():
                starts = bounds[:-1][nonempty]
                sums[nonempty] = np.add.reduceat(its[:offsets[-1]], starts)
                maxima[nonempty] = np.maximum.reduceat(norms[:offsets[-1]], starts)
            sums[0] += self._carry_iterations
            maxima[0] = max(maxima[0], self._carry_norm)
            rest = slice(int(offsets[-1]), m)
            self._carry_iterations = int(its[rest].sum())
            self._carry_norm = float(norms[rest].max()) if m > offsets[-1] else 0.0
            self.last_index = int(kept[-1])
            self.last_state = run.states[offsets[-1]].copy()
        else:
            self._carry_iterations += int(its.sum())
            if m:
                self._carry_norm = max(self._carry_norm, float(norms.max()))
        return Segment(run.states[offsets], kept, sums, maxima)


def kept_rows(steps: int, every: int) -> int:
    """Rows of a complete run: state 0, every ``every``-th state and the last (1 + ⌈N/e⌉)."""
    return 1 + -(-steps // every)
