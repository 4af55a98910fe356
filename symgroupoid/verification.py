"""Independent checks of computed trajectories against the variational principle.

:func:`verify_stationary` evaluates the discrete action Σ [L + λ·φ] with NumPy from the
system's own Lagrangian and constraints (holonomic ones as λ·ψ(α(g)), docs/conventions.md
§15) — not from the derived equations — and differentiates
it numerically along random admissible variations (seed 000 §5.1, seed 001 eq. (11)):

    g_j ↦ h_{j-1}(t)⁻¹ · g_j · h_j(t),   h_j(t) ⊂ α⁻¹(β(g_j)),  h_j(0) = ε,   λ ↦ λ + t μ,

which keep the sequence composable and its product (so its end points) fixed; second-order
problems also keep the first and last arrows fixed (seed 001 §3.1).  On a solution
the derivative vanishes, so the central difference (S(ε) − S(−ε))/2ε is O(ε²).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ._arguments import integer_argument, real_argument, real_array
from ._errors import DomainError, ShapeError, UnsupportedFeatureError
from .equations import action_program, structure_program
from .groupoids import Groupoid
from .runtime import parameter_vector, system_argument


@dataclass
class StationarityReport:
    """Central differences of the action along one random admissible variation."""

    derivatives: dict = field(default_factory=dict)  # ε -> (S(ε) − S(−ε)) / 2ε
    scale: float = 0.0  # Σ |first-order changes of the terms| (normalisation)
    stationary: bool = False
    extrapolated: float = 0.0  # dS/dt at t = 0 from the three differences (Richardson)

    def __bool__(self) -> bool:
        return self.stationary

    def __repr__(self) -> str:
        ds = ", ".join(f"ε={e:.1e}: {d:.3e}" for e, d in self.derivatives.items())
        return f"<StationarityReport stationary={self.stationary} scale={self.scale:.3e} {ds}>"


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows)."""
    return system._fs


class _NumericGroupoid:
    """Structure maps of a groupoid, evaluated from its structure program
    (:func:`~symgroupoid.equations.structure_program`)."""

    def __init__(self, G: Groupoid):
        self.G = G
        program = structure_program(G)
        self._multiply = program.numpy_function(["multiply"], ["a", "b"])
        self._inverse = program.numpy_function(["inverse"], ["a"])
        self._target = program.numpy_function(["target"], ["a"])
        self._flow = program.numpy_function(["flow_from"], ["q", "d"])

    def multiply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return self._multiply(a, b)[0]

    def inverse(self, a: np.ndarray) -> np.ndarray:
        return self._inverse(a)[0]

    def target(self, a: np.ndarray) -> np.ndarray:
        return self._target(a)[0]

    def flow(self, q: np.ndarray, coeffs: np.ndarray, t: float) -> np.ndarray:
        """h(t) ⊂ α⁻¹(q): the product of section curves h_a(c_a t), each at the target of the
        previous one, so h'(0) = Σ c_a X_a(q)."""
        return self._flow(np.asarray(q, float), np.asarray(coeffs, float) * t)[0]


def _section_sizes(ng: _NumericGroupoid, arrows: np.ndarray, rank: int) -> np.ndarray:
    """For each basis section, the size (at least 1) of the arrow coordinates its flow moves
    (positions on a pair groupoid; matrix entries, of size 1, on a Lie group)."""
    q = np.asarray(ng.target(arrows[0]), float)
    q = q / max(1.0, float(np.abs(q).max(initial=0.0)))  # probed where a move of 1e-3 shows
    still = np.asarray(ng.flow(q, np.zeros(rank), 0.0), float)
    sizes = np.ones(rank)
    with np.errstate(all="ignore"):
        for a in range(rank):
            moved = np.asarray(ng.flow(q, np.eye(rank)[a], 1e-3), float)
            mask = ~(np.abs(moved - still) <= 0.0)
            if mask.any():
                sizes[a] = max(1.0, float(np.nanmax(np.abs(arrows[:, mask]), initial=0.0)))
    return sizes


def _action_terms(system) -> tuple:
    """L and φ on the system's own slot coordinates (independent of the DEL): the program
    of :func:`~symgroupoid.equations.action_program`, a term per batch column."""
    program = action_program(system)
    f = program.numpy_function(["L", "phi"], ["a", "p"])
    fs = _functions(system)
    return f, len(fs.slots), len(fs.constraints)


@functools.lru_cache(maxsize=16)
def _cached_terms(system):
    return _action_terms(system)


def action_terms(system, arrows: np.ndarray, multipliers: np.ndarray | None,
                 params: Sequence) -> np.ndarray:
    """[L + λ_j·φ](g_j, …, g_{j+arity−1}) for every window of the arrow sequence."""
    f, arity, m = _cached_terms(system)
    p = np.asarray(params, float)
    arrows = np.asarray(arrows, float)
    T = len(arrows) - arity + 1
    windows = np.hstack([arrows[o:o + T] for o in range(arity)])  # (T, arity·arrow_dim)
    L, phi = f(windows.T, p[:, None])
    terms = np.broadcast_to(L[0], (T,)).astype(float)
    if m:
        lam = np.asarray(multipliers, float)[:T]
        terms = terms + np.einsum("ta,at->t", lam, np.broadcast_to(phi, (m, T)))
    return terms


def action(system, arrows: np.ndarray, multipliers: np.ndarray | None, params: Sequence) -> float:
    """The discrete action Σ_j [L + λ_j·φ](window j)."""
    return float(action_terms(system, arrows, multipliers, params).sum())


def verify_stationary(trajectory, system, params: Sequence | dict | None = None, *,
                      multipliers: np.ndarray | None = None, eps: float = 1e-3,
                      seed: int = 0) -> StationarityReport:
    """Check that a trajectory is a critical point of the discrete action.

    ``trajectory`` is a :class:`~symgroupoid.runtime.Trajectory` (from
    :meth:`Simulator.simulate`: its arrows g_0 … g_N and multipliers λ_0 … λ_N), a
    :class:`BoundaryValueSolution` (or any object with ``arrows`` and ``multipliers``), or an
    array of arrows (N, arrow_dim) with ``multipliers`` (one row per action term) passed
    separately.  ``params`` default to the trajectory's own.  Returns a
    :class:`StationarityReport`; it is truthy when the central differences shrink like ε²
    (or sit at rounding level) and their extrapolation to ε = 0 is negligible against the
    first-order changes of the single terms — a non-solution gives an O(1) derivative.  At a
    trivial solution (all arrows identities: every term's first-order change vanishes) the
    differences are pure O(ε²), which the extrapolation removes.  The variations have size
    ε relative to the largest coordinate and multiplier (at least 1).  An action that is not
    finite on the trajectory is a :class:`~symgroupoid.DomainError`.  A forced system is
    refused (:class:`~symgroupoid.UnsupportedFeatureError`): its trajectories are not
    critical points of the action (docs/conventions.md §20); so is a discrete Lagrangian
    with internal stages (its action needs the stages solved at every arrow, §22).
    """
    system = system_argument(system, "system", owner="verify_stationary")
    if getattr(system, "stages", 0):
        system._refuse_stages("verify_stationary (the discrete action along a trajectory)")
    if getattr(system, "forces", None) is not None:  # not a critical point of the action
        raise UnsupportedFeatureError(
            f"{system.name}: a forced system's trajectory is not a critical point of the "
            f"action but of the Lagrange–d'Alembert principle, whose check with the forces' "
            f"virtual work is not implemented (docs/conventions.md §20); verify_stationary "
            f"would report it not stationary")
    G = system.groupoid
    seed = integer_argument(seed, "seed", maximum=2**63 - 1, owner=system.name)
    eps = real_argument(eps, "eps", owner=system.name)
    if not 1e-300 <= eps <= 1:  # ε/4 is used too: it must stay a normal, nonzero double
        raise DomainError(f"{system.name}: eps must be in [1e-300, 1] (the size of the "
                          f"variations), got {eps!r}")
    arrows, lam, params = _unpack(trajectory, system, multipliers, params)
    _, arity, m = _cached_terms(system)
    ng = _NumericGroupoid(G)
    rng = np.random.default_rng(seed)
    n = len(arrows)
    coeffs = rng.normal(size=(n - 1, G.rank))
    # order-a problems fix the first and last a arrows (seed 001: g₀, g₁, g_{N−1}, g_N):
    # only junctions with a − 1 arrows before and after them stay free
    coeffs[:arity - 1] = 0.0
    coeffs[n - arity:] = 0.0
    mus = rng.normal(size=lam.shape) if m else None
    # variations relative to the size of what they move: an absolute ε would vanish in the
    # rounding of coordinates of size 1e150 and report any path as stationary
    coeffs = coeffs * _section_sizes(ng, arrows, G.rank)
    size_l = max(1.0, float(np.abs(lam).max(initial=0.0)))

    def varied(t: float) -> tuple[np.ndarray, np.ndarray | None]:
        hs = [ng.flow(ng.target(arrows[j]), coeffs[j], t) for j in range(n - 1)]
        out = []
        for j, g in enumerate(arrows):
            g = np.asarray(g, float)
            if j > 0:
                g = np.asarray(ng.multiply(ng.inverse(hs[j - 1]), g), float)
            if j < n - 1:
                g = np.asarray(ng.multiply(g, hs[j]), float)
            out.append(g)
        return np.array(out), (lam + t * size_l * mus if m else None)

    T0 = action_terms(system, arrows, lam, params)
    if not np.isfinite(T0).all():
        k = int(np.flatnonzero(~np.isfinite(T0))[0])
        given = ", ".join(f"{s}={v:.6g}" for s, v in zip(system.parameters, params))
        raise DomainError(f"{system.name}: the discrete action is not finite on this "
                          f"trajectory (term {k} = {T0[k]}: the Lagrangian or the constraints "
                          f"overflow or are undefined there"
                          f"{f', with the parameters {given}' if given else ''}), so its "
                          f"stationarity cannot be checked")
    report = StationarityReport()
    for e in (eps, eps / 2, eps / 4):
        Tp = action_terms(system, *varied(e), params)
        Tm = action_terms(system, *varied(-e), params)
        report.derivatives[e] = float(Tp.sum() - Tm.sum()) / (2 * e)
        if e == eps:  # how large the first-order changes of the single terms are
            report.scale = float(np.abs(Tp - Tm).sum()) / (2 * e) + 1e-300
    d = list(report.derivatives.values())
    # d(ε) = S′(0) + c₂ε² + c₄ε⁴ + …: eliminating the ε² and ε⁴ terms (Richardson) leaves S′(0)
    report.extrapolated = (64 * d[2] - 20 * d[1] + d[0]) / 45
    noise = 1e-13 * float(np.abs(T0).sum()) / (eps / 4)
    shrinking = abs(d[2]) <= 0.35 * abs(d[1]) + noise and abs(d[1]) <= 0.35 * abs(d[0]) + noise
    report.stationary = bool(shrinking and abs(report.extrapolated) <= 1e-4 * report.scale
                             + noise)
    return report


def _unpack(trajectory, system, multipliers, params):
    """Arrows (N, arrow_dim), multipliers (one row per action term) and the parameter vector
    of a :class:`BoundaryValueSolution`, a :class:`Trajectory` or an array of arrows."""
    G, owner = system.groupoid, system.name
    layout = getattr(trajectory, "_layout", None)
    if hasattr(trajectory, "arrows"):  # a BoundaryValueSolution, or any object with arrows
        arrows = trajectory.arrows() if callable(trajectory.arrows) else trajectory.arrows
        lam = trajectory.multipliers if multipliers is None else multipliers
    elif layout is not None and hasattr(trajectory, "states"):  # a Trajectory
        arrows = layout.arrows(trajectory.states)
        lam = trajectory.multipliers if multipliers is None else multipliers
    else:
        arrows, lam = trajectory, multipliers
    if params is None:
        params = getattr(trajectory, "parameters", None)
    try:
        arrows = real_array(arrows, "the arrows", owner=owner)
    except ShapeError as err:
        raise ShapeError(f"{owner}: the trajectory must be a BoundaryValueSolution, a "
                         f"Trajectory or an array of arrows (N, {G.arrow_dim}), got "
                         f"{type(trajectory).__name__} ({err})") from None
    if arrows.ndim != 2 or arrows.shape[1] != G.arrow_dim:
        raise ShapeError(f"{owner}: arrows must have shape (N, {G.arrow_dim}), got "
                         f"{arrows.shape}")
    fs = _functions(system)
    arity, m = len(fs.slots), len(fs.constraints)
    terms = len(arrows) - arity + 1
    if terms < 1:
        raise ShapeError(f"{owner}: {len(arrows)} arrows hold no term of the action "
                         f"(arity {arity})")
    lam = np.zeros((terms, 0)) if lam is None and not m else lam
    if lam is None:
        raise ShapeError(f"{owner}: the system has {m} constraints; give the multipliers "
                         f"({terms}, {m}), one row per action term")
    lam = real_array(lam, "the multipliers", owner=owner)
    if lam.size == 0 and not m:
        lam = np.zeros((terms, 0))
    if lam.shape != (terms, m):
        raise ShapeError(f"{owner}: multipliers must have shape ({terms}, {m}) (one row per "
                         f"action term), got {lam.shape}")
    for what, values in (("arrows", arrows), ("multipliers", lam)):
        if not np.isfinite(values).all():
            row = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
            raise DomainError(f"{owner}: the trajectory's {what} have non-finite values "
                              f"(row {row}: {values[row].tolist()})")
    values, _ = parameter_vector(system.parameters, params, owner=owner)
    return arrows, lam, list(values)
