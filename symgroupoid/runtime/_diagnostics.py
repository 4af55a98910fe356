"""Structure-preservation diagnostics along a trajectory: the programs of
:func:`symgroupoid.equations.state_programs` (discrete momenta, the discrete energy,
constraint residuals and Noether quantities of a step's known state; their mathematics and
seed references are in that module and docs/conventions.md §3, §7) evaluated on all the
states of a trajectory at once (the states are the batch axis), with the summaries, drifts
and rounding floors a user reads.
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .._arguments import flag_argument, real_array
from .._errors import (  # noqa: F401 (re-exported)
    DiagnosticsError,
    DomainError,
    ShapeError,
    SymgroupoidError,
    TimeStepError,
)
from ..equations import StatePrograms, solve_stages, state_programs

_EPS = float(np.finfo(float).eps)


@dataclass
class Momenta:
    """F⁻L and F⁺L along a trajectory: arrays (R, rank) in the section basis.  Of a forced
    first-order system the forced discrete Legendre transforms F⁻L − f⁻ and F⁺L + f⁺ of each
    state's arrow with its inputs (Marsden–West eq. (3.2.4)), at the stages the step solved
    for a system with internal stages (docs/conventions.md §20, §22)."""

    minus: np.ndarray
    plus: np.ndarray

    def matching(self, lag: int = 1) -> np.ndarray:
        """F⁺L(state k) − F⁻L(state k+lag), (R − lag, rank): zero along a solution of the DEL
        (lag 1 for first order, 2 for second order), when every state is kept."""
        return self.plus[:-lag] - self.minus[lag:]


def state_graph(step) -> StatePrograms:
    """The (cached) programs of a step's known state
    (:func:`~symgroupoid.equations.state_programs`)."""
    return state_programs(step)


# --- evaluation along trajectories ------------------------------------------------------------

@dataclass
class _Evaluator:
    """Programs of one step, compiled for NumPy once per output set."""

    sg: StatePrograms
    functions: dict = field(default_factory=dict)

    def _function(self, key: str, step_parameter: str | None, outputs=("out",)):
        label = f"{key}:{step_parameter}" if key == "energy" else key
        label += "|" + "/".join(outputs)
        f = self.functions.get(label)
        if f is None:
            program = self.sg.quantity(key, step_parameter)
            names = ["known", "zeta", "p"] if self.sg.n_stages else ["known", "p"]
            f = self.functions[label] = program.numpy_function(list(outputs), names)
        return f, label

    def __call__(self, key: str, states: np.ndarray, p: np.ndarray,
                 step_parameter: str | None = None, outputs=("out",)):
        """The quantity ``key`` (:meth:`StatePrograms.quantity`) at every state, (R, n); with
        several ``outputs``, one such array per output, from one evaluation (the stages of
        a system with stages solved once)."""
        f, label = self._function(key, step_parameter, outputs)
        known = np.ascontiguousarray(np.asarray(states, float).T)
        args = (known, self.stages(known, p), p) if self.sg.n_stages else (known, p)
        with np.errstate(all="ignore"):
            values = [np.asarray(out, float).T for out in f(*args)]  # each (R, n)
        for name, out in zip(outputs, values):
            if not np.isfinite(out).all():
                row = int(np.flatnonzero(~np.isfinite(out).all(axis=1))[0])
                shown = {"energy": "the energy", "stages": "the internal stages"}.get(key, key)
                if name != "out":
                    shown = f"the size of the terms of {shown}"
                raise DiagnosticsError(f"{self.sg.name}: {shown} is not finite at kept state "
                                       f"{row} ({out[row].tolist()}): it overflows there or is "
                                       f"not defined there (check the parameters, and that the "
                                       f"run stays where the Lagrangian is defined)")
        return values[0] if len(outputs) == 1 else values


    def stages(self, known: np.ndarray, p: np.ndarray) -> np.ndarray:
        """ζ* at every state (nz, R) (:func:`~symgroupoid.equations.solve_stages`,
        docs/conventions.md §22); of a forced system the forced stages, ∂L/∂ζ + f_ζ = 0 with
        the inputs u_k the state holds: the stages its step solved."""
        f, _ = self._function("stages", None, ("out", "J"))
        return solve_stages(f, known, p, self.sg.n_stages, self.sg.name)


_EVALUATORS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _setup(trajectory) -> tuple[_Evaluator, np.ndarray]:
    layout = getattr(trajectory, "_layout", None)
    if layout is None or not hasattr(trajectory, "states"):
        raise DiagnosticsError(f"trajectory must be a Trajectory (from Simulator.simulate), "
                               f"got {type(trajectory).__name__}")
    step = getattr(layout, "equations", None)
    if step is None:
        raise DiagnosticsError(f"{trajectory._layout.step_name}: this trajectory does not "
                               f"know the equations it solves")
    ev = _EVALUATORS.get(step)
    if ev is None:
        ev = _EVALUATORS[step] = _Evaluator(state_graph(step))
    p = np.array([trajectory.parameters[str(s)] for s in step.parameters], dtype=float)
    return ev, p


def trajectory_programs(trajectory) -> StatePrograms:
    """The programs of the known state of the step ``trajectory`` solves
    (:func:`~symgroupoid.equations.state_programs`); a :class:`DiagnosticsError` unless it
    is a :class:`~symgroupoid.Trajectory` that knows its equations."""
    return _setup(trajectory)[0].sg


def momenta(trajectory) -> Momenta:
    """The discrete momenta F⁻L, F⁺L at every kept state (see the module docstring)."""
    ev, p = _setup(trajectory)
    minus = ev("minus", trajectory.states, p)
    plus = ev("plus", trajectory.states, p)
    return Momenta(minus, plus)


def energy(trajectory, step_parameter: str | None = None) -> np.ndarray:
    """The discrete energy at every kept state, (R,) (see the module docstring).

    ``step_parameter``: the name of the parameter to differentiate by (default: the
    system's time step, declared with ``time_step=`` or identified by the continuous limit,
    else a :class:`TimeStepError`); on a :class:`TimeGroupoid` the default is the energy
    conjugate to time.
    """
    ev, p = _setup(trajectory)
    return ev("energy", trajectory.states, p, step_parameter)[:, 0]


def energy_magnitude(trajectory, step_parameter: str | None = None) -> np.ndarray:
    """The size of the terms the discrete energy is computed from at every kept state, (R,)
    (:func:`symgroupoid.ir.term_magnitude`): ε times it is the rounding of :func:`energy`
    there; E_d of a run far from the origin is a small difference of terms of the size of
    (x/h)², which round at that size."""
    return _energy_values(trajectory, step_parameter)[1]


def _energy_values(trajectory, step_parameter: str | None) -> tuple[np.ndarray, np.ndarray]:
    """(E_d, the size of its terms) at every kept state, from one evaluation."""
    ev, p = _setup(trajectory)
    values, sizes = ev("energy", trajectory.states, p, step_parameter, ("out", "scale"))
    return values[:, 0], sizes[:, 0]


def energy_drift(trajectory, step_parameter: str | None = None) -> Drift:
    """The :class:`Drift` of the discrete energy along ``trajectory``, its rounding floor
    from the size of its terms (:func:`energy_magnitude`)."""
    values, sizes = _energy_values(trajectory, step_parameter)
    return Drift(energy_label(trajectory, step_parameter), values, trajectory.step_indices,
                 sizes)


def energy_label(trajectory, step_parameter: str | None = None) -> str:
    """What :func:`energy` computes for this trajectory, e.g. ``"E_d = −∂L_d/∂h"``."""
    ev, _ = _setup(trajectory)
    return ev.sg.energy_label(step_parameter)


def constraint_residuals(trajectory) -> np.ndarray:
    """φ at every kept state, (R, m) (see the module docstring); (R, 0) without constraints."""
    ev, p = _setup(trajectory)
    if not ev.sg.has_constraints:
        return np.zeros((len(trajectory.states), 0))
    return ev("constraints", trajectory.states, p)


def _energy_missing(trajectory, step_parameter) -> str:
    """Why :func:`energy` is not defined for this trajectory (its error's message)."""
    try:
        energy_label(trajectory, step_parameter)
    except DiagnosticsError as err:
        return str(err)
    return "it is defined"


def energy_changes(trajectory, step_parameter: str | None = None) -> str | None:
    """Why the energy of :func:`energy` is not a conserved quantity of the trajectory's
    system, None when it is one (for a discrete energy E_d = −∂L_d/∂h of a fixed step, to
    within its bounded oscillation): a forced system's forces change it (§20); on a time
    groupoid E = −∂L/∂t₁ is conserved when the time section is a symmetry of the system
    (§7; with a fixed step t₁ − t₀ = h as a constraint, to within the bounded oscillation of
    a fixed step), not when L or the constraints depend on the time explicitly."""
    sg = _setup(trajectory)[0].sg
    if sg.forces is not None:
        return "the forces change it"
    if step_parameter is not None or not sg.groupoid.timed:
        return None
    if not _time_section_is_symmetry(sg.system):
        return ("the system depends on the time explicitly: the time section ∂/∂t is not a "
                "symmetry, so E = −∂L/∂t₁ changes along the motion (docs/conventions.md §7)")
    return None


def _time_section_is_symmetry(system) -> bool:
    """Whether the time section (basis section 0 of R × R × G) is a symmetry of the
    system's L, decided once per system by :meth:`~symgroupoid.DiscreteSystem.noether`."""
    found = system.__dict__.get("_time_section_symmetry")
    if found is None:
        try:
            found = bool(system.noether(0).is_symmetry)
        except SymgroupoidError:  # no Noether quantity here: nothing known against E
            found = True
        system.__dict__["_time_section_symmetry"] = found
    return found


def has_energy(trajectory, step_parameter: str | None = None) -> bool:
    """Whether :func:`energy` is defined for this trajectory; a ``step_parameter`` that is
    not the name of one of the system's parameters is a :class:`DiagnosticsError` (a
    misspelt name would otherwise leave the energy out without a word)."""
    if step_parameter is not None:
        ev, _ = _setup(trajectory)
        names = [str(p) for p in ev.sg.parameters]
        if not isinstance(step_parameter, (str, sp.Symbol)) or str(step_parameter) not in names:
            raise DiagnosticsError(f"{ev.sg.name}: step_parameter={step_parameter!r} is not "
                                   f"the name of a parameter of the system (parameters: "
                                   f"{', '.join(names) or 'none'})")
    try:
        energy_label(trajectory, step_parameter)
    except DiagnosticsError:
        return False
    return True


# --- drift and the rounding floor ----------------------------------------------------------------

def rounding_floor(values: np.ndarray, step_indices: np.ndarray,
                   magnitudes: np.ndarray | None = None) -> np.ndarray:
    """ε·(|Q|·√k + S): the drift of a conserved quantity Q after k steps (k counted from
    the first kept state; 0 at k = 0) when each step adds one independent rounding error of
    relative size ε (a random walk, |Q| = max_k |Q_k|), and each evaluation of Q rounds at
    ε·S, S = max_k of ``magnitudes``, the size of the terms Q is computed from
    (:meth:`NoetherQuantity.term_magnitude <symgroupoid.NoetherQuantity.term_magnitude>`,
    :func:`energy_magnitude`; 0 when not given).  A momentum (q_{k+1} − q_k)/h at large q
    is a small difference of large terms: it rounds at their size, S ≈ 2|q|/h, not at |Q|.

    A drift within a small multiple of this floor is rounding; a drift far above it, or
    growing like k rather than √k, is a defect of the scheme or of the solve — or rounding
    biased one way at every step (a step's change below the resolution of the coordinates,
    e.g. a slow orbit far from the origin), which :attr:`Drift.step_variation` shows.
    """
    values = real_array(values, "values", owner="rounding_floor").ravel()
    steps = real_array(step_indices, "step_indices", owner="rounding_floor")
    if steps.ndim != 1:
        raise ShapeError(f"rounding_floor: step_indices must be a vector of step counts, got "
                         f"shape {steps.shape}")
    if not (np.isfinite(values).all() and np.isfinite(steps).all()):
        raise DomainError("rounding_floor: the values and step indices must be finite")
    if magnitudes is not None:
        magnitudes = real_array(magnitudes, "magnitudes", owner="rounding_floor")
        if not np.isfinite(magnitudes).all():
            raise DomainError("rounding_floor: the magnitudes must be finite")
    scale = float(np.max(np.abs(values))) if values.size else 0.0
    size = (float(np.max(np.abs(magnitudes)))
            if magnitudes is not None and np.size(magnitudes) else 0.0)
    k = steps - (steps[0] if steps.size else 0.0)
    return np.where(k > 0, _EPS * (scale * np.sqrt(k) + size), 0.0)


@dataclass
class Drift:
    """A quantity Q along a trajectory and its drift |Q_k − Q_0| against the rounding floor
    (``magnitudes``: the size of the terms Q is computed from at each state, or None: |Q|;
    see :func:`rounding_floor`)."""

    name: str
    values: np.ndarray
    step_indices: np.ndarray
    magnitudes: np.ndarray | None = None

    @property
    def drift(self) -> np.ndarray:
        return np.abs(self.values - self.values[0])

    @property
    def max_drift(self) -> float:
        return float(self.drift.max()) if len(self.values) else 0.0

    @property
    def scale(self) -> float:
        """max |Q_k|."""
        return float(np.max(np.abs(self.values))) if len(self.values) else 0.0

    @property
    def floor(self) -> np.ndarray:
        """ε·(|Q|·√k + S) (:func:`rounding_floor`)."""
        return rounding_floor(self.values, self.step_indices, self.magnitudes)

    @property
    def final_floor(self) -> float:
        return float(self.floor[-1]) if len(self.values) else 0.0

    @property
    def step_variation(self) -> float:
        """σ = RMS over the intervals of (Q_{k+e} − Q_k)/√e: the measured size of one step's
        change of Q.  For a quantity conserved up to rounding this is the per-step rounding
        actually incurred (often above ε·|Q|: the Newton residual of a step sits at its own
        rounding floor, e.g. times rounded relative to t on a time groupoid), and σ·√k is
        the drift a random walk of it reaches; a drift far above σ·√k is systematic."""
        if len(self.values) < 2:
            return 0.0
        d = np.diff(self.values) / np.sqrt(np.diff(self.step_indices).astype(float))
        return float(np.sqrt(np.mean(d * d)))

    @property
    def measured_floor(self) -> np.ndarray:
        """σ·√k (see :attr:`step_variation`)."""
        k = np.asarray(self.step_indices, float) - float(self.step_indices[0])
        return self.step_variation * np.sqrt(k)


@dataclass
class ConservationSummary:
    """Max drift of each conserved quantity of a run, with the rounding floor
    ε·(|Q|·√N + S) (S the size of the terms Q is computed from: :func:`rounding_floor`).

    ``quantities``: one :class:`Drift` per quantity (the energy when defined, then each
    Noether quantity asked for); ``constraint_residual``: max |φ| over the states (None
    without constraints); ``momentum_matching``: max |F⁺L(g_k) − F⁻L(g_{k+1})| over
    consecutive states (the DEL as a momentum match; None unless every state is kept);
    ``momentum_scale``: max |F±L| (the size the matching is to be compared with).
    """

    name: str
    steps: int
    quantities: list
    constraint_residual: float | None = None
    momentum_matching: float | None = None
    momentum_scale: float | None = None
    notes: list = field(default_factory=list)

    def lines(self) -> list[str]:
        """Human-readable lines, one per check."""
        out = [f"{self.name}: {self.steps} steps"]
        for q in self.quantities:
            rel = q.max_drift / q.scale if q.scale else 0.0
            out.append(f"{q.name}: max |Q_k − Q_0| = {q.max_drift:.2e} (relative {rel:.1e}); "
                       f"rounding floor ε·(|Q|·√N + S) = {q.final_floor:.1e}, step-to-step "
                       f"variation σ·√N = {q.step_variation * np.sqrt(self.steps):.1e}")
        if self.momentum_matching is not None:
            out.append(f"momenta: max |F⁺L(g_k) − F⁻L(g_{{k+1}})| = {self.momentum_matching:.2e} "
                       f"(|F±L| up to {self.momentum_scale:.1e})")
        if self.constraint_residual is not None:
            out.append(f"constraints: max |φ| = {self.constraint_residual:.2e}")
        out.extend(self.notes)
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())


def conservation_summary(trajectory, *, energy: bool | None = None,
                         noether: Sequence = (), step_parameter: str | None = None
                         ) -> ConservationSummary:
    """The max drift of each conserved quantity along ``trajectory`` and its rounding floor.

    ``energy``: include the discrete energy (None: when it is defined — a step parameter
    ``step_parameter``, the system's time step (declared or identified), or a time groupoid;
    otherwise the summary notes why it is left out; True: required, an error otherwise);
    ``noether``: :class:`~symgroupoid.NoetherQuantity` objects, or sections (an index or
    coefficients) turned into them by ``system.noether(section)``.
    """
    ev, _ = _setup(trajectory)
    if energy is not None:
        energy = flag_argument(energy, "energy", owner=ev.sg.name)
    quantities: list[Drift] = []
    notes: list[str] = []
    idx = trajectory.step_indices
    want_energy = energy
    if energy is None:
        want_energy = has_energy(trajectory, step_parameter)
        if not want_energy and ev.sg.arity == 1:
            notes.append(f"energy: not included ({_energy_missing(trajectory, step_parameter)})")
        elif not want_energy:
            notes.append("energy: not included (the discrete energy is defined for "
                         "first-order systems, L: G → R, only)")
    changes = energy_changes(trajectory, step_parameter) if want_energy else None
    if energy is None and changes is not None:
        want_energy = False
        notes.append(f"energy: not included ({changes}; energy=True includes it)")
    if want_energy:
        quantities.append(energy_drift(trajectory, step_parameter))
    conserved, changes = noether_drifts(trajectory, ev.sg, noether)
    quantities += conserved
    notes += [f"{change.name.removesuffix(' (changed by the forces)')}: changed by the "
              f"forces' impulse (max |Q_k − Q_0| = {change.max_drift:.1e}); its balance with "
              f"the impulse, Q_k − Σ_{{j<k}} I_j, is the conserved quantity "
              f"(docs/conventions.md §20)" for change in changes]
    residual = None
    if ev.sg.has_constraints:
        residual = float(np.max(np.abs(constraint_residuals(trajectory))))
    matching = scale = None
    if _variational(ev.sg.system) and len(idx) > ev.sg.arity and np.all(np.diff(idx) == 1):
        try:
            mom = momenta(trajectory)
        except SymgroupoidError as err:  # e.g. a structure map the graph cannot take
            notes.append(f"momenta: not evaluated ({err})")
        else:
            matching = float(np.max(np.abs(mom.matching(ev.sg.arity))))
            scale = float(max(np.max(np.abs(mom.minus)), np.max(np.abs(mom.plus))))
    if matching is not None and ev.sg.forces is not None:
        notes.append("momenta: of a forced system the forced discrete Legendre transforms "
                     "F⁻L − f⁻ and F⁺L + f⁺ (at the forced stages), whose matching is the "
                     "forced DEL")
    return ConservationSummary(trajectory._layout.step_name, trajectory.steps, quantities,
                               residual, matching, scale, notes)


def noether_drifts(trajectory, programs, items) -> tuple[list[Drift], list[Drift]]:
    """(the conserved quantities of the Noether quantities ``items`` along ``trajectory``
    — each J itself, or of a forced system its balance with the impulse —, the forced J
    themselves, which the forces change: :func:`impulse_balance`)."""
    idx = trajectory.step_indices
    conserved, changes = [], []
    for label, nq in noether_quantities(programs, items):
        values, sizes = nq.along_with_magnitude(trajectory)
        if nq.impulse_form is None:
            conserved.append(Drift(label, values, idx, sizes))
            continue
        balance, change = impulse_balance(trajectory, nq, label, values, sizes)
        if _impulse_negligible(balance, change):  # internal forces along X: J is conserved
            conserved.append(Drift(f"{label} (no net impulse)", values, idx, sizes))
            continue
        conserved.append(balance)
        changes.append(change)
    return conserved, changes


def _impulse_negligible(balance: Drift, change: Drift) -> bool:
    """Whether the forces' summed impulse Σ_{j<k} I_j (= J_k − balance_k) stays within the
    rounding floor of J at every k: forces that cancel along the section (internal forces,
    docs/conventions.md §20) leave J conserved, and J is not then "changed by the forces"."""
    summed = np.abs(change.values - balance.values)
    return bool(np.all(summed <= np.maximum(change.floor, balance.floor)))


def impulse_balance(trajectory, nq, label: str, values: np.ndarray,
                    sizes: np.ndarray | None = None) -> tuple[Drift, Drift]:
    """A forced system's Noether quantity J: (the balance J_k − Σ_{j<k} I_j, conserved to
    rounding by the forced Noether theorem, docs/conventions.md §20; J itself, which changes
    by the impulses I_j, :meth:`NoetherQuantity.impulse`).  ``sizes``: the size of J's
    terms at each state (the balance's are those and Σ_{j<k} |I_j|)."""
    if getattr(trajectory, "every", 1) != 1:
        raise DomainError(f"{trajectory._layout.step_name}: {label} belongs to a forced "
                          f"system: its balance with the forces' impulse needs every state "
                          f"(simulate with every=1)")
    impulse = nq.impulse(trajectory)
    idx = trajectory.step_indices
    balance = values - np.concatenate([[0.0], np.cumsum(impulse)])
    summed = None if sizes is None else sizes + np.concatenate([[0.0],
                                                                np.cumsum(np.abs(impulse))])
    return (Drift(f"{label} − Σ impulse", balance, idx, summed),
            Drift(f"{label} (changed by the forces)", values, idx, sizes))


def _variational(system) -> bool:
    """Whether the system's step is the DEL F⁺L(g_k) = F⁻L(g_{k+1}) in every section (not a
    nonholonomic step, whose equations hold along D_c only)."""
    from ..equations import NonholonomicSystem

    return not isinstance(system, NonholonomicSystem)


def noether_quantities(sgraph: StatePrograms, items) -> list[tuple[str, object]]:
    """(label, NoetherQuantity) pairs from NoetherQuantity objects or sections, or from a
    mapping label → either."""
    from ..equations import NoetherQuantity

    if isinstance(items, (str, bytes)) or not isinstance(items, (Mapping, Sequence,
                                                                  np.ndarray)) \
            or (isinstance(items, np.ndarray) and items.ndim == 0):
        raise DiagnosticsError(f"{sgraph.name}: noether must be a list of Noether quantities "
                               f"or sections (or a mapping label → one), got "
                               f"{type(items).__name__} {items!r}")
    pairs = (list(items.items()) if isinstance(items, Mapping)
             else [(f"Noether F_X[{i}]", item) for i, item in enumerate(items)])
    out = []
    for label, item in pairs:
        if not isinstance(item, NoetherQuantity):
            system = sgraph.system
            if not hasattr(system, "noether"):
                raise DiagnosticsError(f"{sgraph.name}: Noether quantities from sections need a "
                                       f"DiscreteSystem; pass NoetherQuantity objects")
            item = system.noether(item)
        if not item.is_symmetry:
            label += " (not a verified symmetry)"
        out.append((str(label), item))
    return out
