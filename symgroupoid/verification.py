"""Independent checks of computed trajectories against the variational principle.

:func:`verify_stationary` evaluates the discrete action Σ [L + λ·φ] with NumPy from the
system's own Lagrangian and constraints (holonomic ones as λ·ψ(α(g)), docs/conventions.md
§15) — not from the derived equations — and differentiates
it numerically along random admissible variations (seed 000 §5.1, seed 001 eq. (11)):

    g_j ↦ h_{j-1}(t)⁻¹ · g_j · h_j(t),   h_j(t) ⊂ α⁻¹(β(g_j)),  h_j(0) = ε,   λ ↦ λ + t μ,

which keep the sequence composable and its product (so its end points) fixed; second-order
problems also keep the first and last arrows fixed (seed 001 §3.1).  On a solution
the derivative vanishes, so the central difference (S(ε) − S(−ε))/2ε is O(ε²).

A forced system's trajectory satisfies the discrete Lagrange–d'Alembert principle instead
(docs/conventions.md §20): dS/dt + W = 0, where W is the forces' virtual work along the same
variation, the exact pairing of each term's covectors with the variation at its base points
(first order: Σ_j h′_j(0)·(f⁺(g_j) + f⁻(g_{j+1})), h′_j(0) = Σ_a c_ja X_a(β(g_j))).  A
nonholonomic system (the Hölder principle, seed 002; §10) is varied along D_c only.  A
discrete Lagrangian with internal stages L(g, ζ) (§22) has the stages of every arrow solved
from its own stage rows first, then held while the arrows vary (the envelope theorem).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from ._arguments import input_rows, integer_argument, real_argument, real_array
from ._errors import DomainError, ShapeError, UnsupportedFeatureError
from .equations import action_program, solve_stages, structure_program
from .groupoids import Groupoid
from .ir import Graph, Program, forward, from_sympy, gradient
from .runtime import parameter_vector, system_argument

#: the smallest fraction of the given ε that :func:`verify_stationary` shrinks its
#: variations to where they leave the discrete Lagrangian's domain
SHRINK_LIMIT = 1e-6


@dataclass
class StationarityReport:
    """Central differences of the action along one random admissible variation."""

    derivatives: dict = field(default_factory=dict)  # ε -> (S(ε) − S(−ε)) / 2ε
    scale: float = 0.0  # Σ |first-order changes of the terms| (normalisation)
    stationary: bool = False
    extrapolated: float = 0.0  # dS/dt at t = 0 from the three differences (Richardson)
    work: float = 0.0  # the forces' virtual work along the variation (0 without forces)

    def __bool__(self) -> bool:
        return self.stationary

    def __repr__(self) -> str:
        ds = ", ".join(f"ε={e:.1e}: {d:.3e}" for e, d in self.derivatives.items())
        work = f" work={self.work:.3e}" if self.work else ""
        return (f"<StationarityReport stationary={self.stationary} scale={self.scale:.3e}"
                f"{work} {ds}>")


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows)."""
    return system._fs


class _NumericGroupoid:
    """Structure maps of a groupoid, evaluated from its structure program
    (:func:`~symgroupoid.equations.structure_program`)."""

    def __init__(self, G: Groupoid, parameters: Sequence = (), values: Sequence = ()):
        self.G = G
        program = structure_program(G, tuple(parameters))  # (maps may use them)
        self._p = np.asarray(values, float)
        self._multiply = program.numpy_function(["multiply"], ["a", "b", "p"])
        self._inverse = program.numpy_function(["inverse"], ["a", "p"])
        self._target = program.numpy_function(["target"], ["a", "p"])
        self._flow = program.numpy_function(["flow_from"], ["q", "d", "p"])

    def multiply(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return self._multiply(a, b, self._p)[0]

    def inverse(self, a: np.ndarray) -> np.ndarray:
        return self._inverse(a, self._p)[0]

    def target(self, a: np.ndarray) -> np.ndarray:
        return self._target(a, self._p)[0]

    def flow(self, q: np.ndarray, coeffs: np.ndarray, t: float) -> np.ndarray:
        """h(t) ⊂ α⁻¹(q): the product of section curves h_a(c_a t), each at the target of the
        previous one, so h'(0) = Σ c_a X_a(q)."""
        return self._flow(np.asarray(q, float), np.asarray(coeffs, float) * t, self._p)[0]


def _section_sizes(ng: _NumericGroupoid, arrows: np.ndarray, rank: int) -> np.ndarray:
    """For each basis section, the size (at least 1) of the arrow coordinates its flow moves
    (positions on a pair groupoid; matrix entries, of size 1, on a Lie group).  On a time
    groupoid the time section ∂/∂t (seed 000 §6.3) is sized by the shortest step instead:
    L_d reads t only through t_{k+1} − t_k, often as 1/(t_{k+1} − t_k), so a variation of
    ε·|t| would leave the quadratic regime on a run far from t = 0 (:func:`_time_size`)."""
    sizes = _coordinate_sizes(ng, arrows, rank)
    if getattr(ng.G, "timed", False):
        sizes[0] = _time_size(arrows)
    return sizes


def _time_size(arrows: np.ndarray) -> float:
    """The shortest step |t_{k+1} − t_k| of a time groupoid's arrows (t_k, t_{k+1}, g), at
    most the times' size and at least 1e-9 of it (so that ε/4 of it is not lost in t's
    rounding)."""
    t = np.abs(arrows[:, :2])
    top = max(1.0, float(t.max(initial=0.0)))
    steps = np.abs(arrows[:, 1] - arrows[:, 0])
    steps = steps[steps > 0]
    shortest = float(steps.min()) if steps.size else top
    return min(top, max(shortest, 1e-9 * top))


#: the variations' size relative to the largest coordinate they move: large enough that
#: ε/4 of it (2.5·10⁻¹² at ε = 10⁻³) is ten thousand roundings of that coordinate, small
#: enough that an angle far from 0 (θ + 2πk) is varied as θ is (sized by the coordinate
#: itself, θ = 1257 was varied by 1.3 rad: out of the quadratic regime, "not stationary")
RESOLVED = 1e-8


def _coordinate_sizes(ng: _NumericGroupoid, arrows: np.ndarray, rank: int) -> np.ndarray:
    """For each basis section, the size of its variations: 1, or :data:`RESOLVED` times the
    largest arrow coordinate its flow moves where that is larger (coordinates beyond 10⁸,
    where a variation of ε/4 would be lost in their rounding)."""
    q = np.asarray(ng.target(arrows[0]), float)
    q = q / max(1.0, float(np.abs(q).max(initial=0.0)))  # probed where a move of 1e-3 shows
    still = np.asarray(ng.flow(q, np.zeros(rank), 0.0), float)
    sizes = np.ones(rank)
    with np.errstate(all="ignore"):
        for a in range(rank):
            moved = np.asarray(ng.flow(q, np.eye(rank)[a], 1e-3), float)
            mask = ~(np.abs(moved - still) <= 0.0)
            if mask.any():
                largest = float(np.nanmax(np.abs(arrows[:, mask]), initial=0.0))
                sizes[a] = max(1.0, RESOLVED * largest)
    return sizes


def _action_terms(system) -> tuple:
    """L and φ on the system's own slot coordinates (independent of the DEL): the program
    of :func:`~symgroupoid.equations.action_program`, a term per batch column (with internal
    stages, L(g, ζ): inputs a, z, p)."""
    program = action_program(system)
    fs = _functions(system)
    f = program.numpy_function(["L", "phi"], ["a", "z", "p"] if fs.stages else ["a", "p"])
    return f, len(fs.slots), len(fs.constraints)


@functools.lru_cache(maxsize=16)
def _cached_terms(system):
    return _action_terms(system)


def action_terms(system, arrows: np.ndarray, multipliers: np.ndarray | None,
                 params: Sequence, stages: np.ndarray | None = None) -> np.ndarray:
    """[L + λ_j·φ](g_j, …, g_{j+arity−1}) for every window of the arrow sequence; with
    internal stages (docs/conventions.md §22) L(g_j, ζ_j), ``stages`` (T, n_stages) the
    stages of every term (:func:`stage_values`)."""
    f, arity, m = _cached_terms(system)
    p = np.asarray(params, float)
    arrows = np.asarray(arrows, float)
    T = len(arrows) - arity + 1
    windows = np.hstack([arrows[o:o + T] for o in range(arity)])  # (T, arity·arrow_dim)
    if _functions(system).stages:
        L, phi = f(windows.T, np.asarray(stages, float).reshape(T, -1).T, p[:, None])
    else:
        L, phi = f(windows.T, p[:, None])
    terms = np.broadcast_to(L[0], (T,)).astype(float)
    if m:
        lam = np.asarray(multipliers, float)[:T]
        terms = terms + np.einsum("ta,at->t", lam, np.broadcast_to(phi, (m, T)))
    return terms


def action(system, arrows: np.ndarray, multipliers: np.ndarray | None, params: Sequence,
           stages: np.ndarray | None = None) -> float:
    """The discrete action Σ_j [L + λ_j·φ](window j) (with internal stages at ``stages``)."""
    return float(action_terms(system, arrows, multipliers, params, stages).sum())


def _stage_program(system) -> Program:
    """The stage rows of one term from the system's own L(g, ζ) and forces
    (docs/conventions.md §22), independent of the derived equations: ∂L/∂ζ + f_ζ (reverse
    mode) and their Jacobian ∂/∂ζ (forward mode, row-major); inputs ``a`` (the arrow's
    coordinates), ``z`` (ζ), ``u`` (the term's inputs), ``p`` (the parameters)."""
    fs = _functions(system)
    forces = fs.forces
    g = Graph()
    coords = list(fs.slots[0])
    nodes = {x: g.input(x) for x in (*coords, *fs.stages, *system.parameters)}
    inputs = list(forces.inputs) if forces is not None else []
    nodes.update({x: g.input(x) for x in inputs})
    memo: dict = {}
    L = from_sympy(g, fs.lagrangian, nodes, f"{system.name}: the Lagrangian", memo)
    zeta = [nodes[z] for z in fs.stages]
    rows = gradient(g, L, zeta)
    if forces is not None and forces.stage_forces:
        symbols = dict(nodes)
        symbols.update(zip(forces.slots[0], [nodes[c] for c in coords]))
        symbols.update(zip(forces.stages, zeta))
        rows = [g.add(r, from_sympy(g, sp.sympify(f), symbols,
                                    f"{system.name}: the stage forces", memo))
                for r, f in zip(rows, forces.stage_forces)]
    order = g.reachable(rows)
    columns = [forward(g, rows, {z: g.one}, order) for z in zeta]
    jac = [columns[b][a] for a in range(len(rows)) for b in range(len(zeta))]
    return Program(g, {"a": coords, "z": list(fs.stages), "u": inputs,
                       "p": list(system.parameters)}, {"F": rows, "J": jac})


@functools.lru_cache(maxsize=16)
def _cached_stage_rows(system):
    return _stage_program(system).numpy_function(["F", "J"], ["a", "z", "u", "p"])


def stage_values(system, arrows: np.ndarray, inputs: np.ndarray, params: Sequence
                 ) -> np.ndarray:
    """The internal stages ζ of every arrow (T, n_stages), solving its stage rows
    ∂L/∂ζ(g_j, ζ_j) + f_ζ(g_j, ζ_j, u_j) = 0 near ζ = 0 (docs/conventions.md §22; f_ζ with
    the inputs u_j of the arrow, row j of ``inputs``), by Newton's method on all arrows at
    once; a :class:`~symgroupoid.DiagnosticsError` where it does not converge."""
    f = _cached_stage_rows(system)
    arrows = np.asarray(arrows, float)
    U = np.asarray(inputs, float).reshape(len(arrows), -1).T
    p = np.asarray(params, float)[:, None]
    n_stages = len(_functions(system).stages)
    zeta = solve_stages(lambda known, z, p_: f(known, z, U, p_), arrows.T, p, n_stages,
                        system.name)
    return zeta.T


def _force_program(system) -> Program | None:
    """The discrete forces of one term on the expression graph (docs/conventions.md §20):
    inputs ``a`` (the term's arrow coordinates), ``u`` (its inputs), ``p`` (the parameters),
    ``z`` (its internal stages, §22; empty without); output ``f``: the covectors at the
    term's base points 0 … arity (first order f⁻, f⁺; second order f⁰, f¹, f²), rank
    components each.  None for a system without forces."""
    forces = _functions(system).forces
    if forces is None:
        return None
    g = Graph()
    coords = [c for arrow in forces.slots for c in arrow]
    symbols = {x: g.input(x) for x in (*coords, *forces.inputs, *forces.stages,
                                       *system.parameters)}
    memo: dict = {}
    nodes = [from_sympy(g, sp.sympify(f), symbols, f"{system.name}: the forces", memo)
             for node in forces.nodes for f in node]
    return Program(g, {"a": coords, "u": list(forces.inputs), "p": list(system.parameters),
                       "z": list(forces.stages)}, {"f": nodes})


@functools.lru_cache(maxsize=16)
def _cached_forces(system):
    program = _force_program(system)
    return None if program is None else program.numpy_function(["f"], ["a", "u", "z", "p"])


def force_terms(system, arrows: np.ndarray, inputs: np.ndarray, params: Sequence,
                stages: np.ndarray | None = None) -> np.ndarray:
    """The discrete forces of every term of the arrow sequence, shape (T, arity + 1, rank):
    [j, i] is the covector at base point i of the term starting at g_j (whose inputs are
    row j of ``inputs``, shape (T, m), and with internal stages its stages row j of
    ``stages``), in the basis sections' order."""
    f = _cached_forces(system)
    _, arity, _ = _cached_terms(system)
    rank = system.groupoid.rank
    arrows = np.asarray(arrows, float)
    T = len(arrows) - arity + 1
    windows = np.hstack([arrows[o:o + T] for o in range(arity)])
    zeta = np.zeros((T, 0)) if stages is None else np.asarray(stages, float).reshape(T, -1)
    (values,) = f(windows.T, np.asarray(inputs, float).reshape(T, -1).T, zeta.T,
                  np.asarray(params, float)[:, None])  # ((arity + 1)·rank, T)
    return values.T.reshape(T, arity + 1, rank)


def virtual_work(forces: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """The pairings of the forces (:func:`force_terms`, (T, arity + 1, rank)) with the
    variation h′_j(0) = Σ_a coeffs[j, a] X_a(β(g_j)) at each junction j = 0 … n − 2, shape
    (T, arity + 1): base point i of the term starting at g_j is the node β(g_{j−1+i}), the
    junction j − 1 + i (the nodes α(g_0) and β(g_{n−1}) are not varied)."""
    T, points, rank = forces.shape
    padded = np.vstack([np.zeros((1, rank)), coeffs, np.zeros((1, rank))])  # row j + 1: j
    at = np.stack([padded[i:i + T] for i in range(points)], axis=1)  # (T, points, rank)
    return np.einsum("tia,tia->ti", forces, at)


def verify_stationary(trajectory, system, params: Sequence | dict | None = None, *,
                      multipliers: np.ndarray | None = None,
                      inputs: np.ndarray | None = None, eps: float = 1e-3,
                      seed: int = 0) -> StationarityReport:
    """Check that a trajectory is a critical point of the discrete action — of the discrete
    Lagrange–d'Alembert principle for a forced system.

    ``trajectory`` is a :class:`~symgroupoid.runtime.Trajectory` (from
    :meth:`Simulator.simulate` with every state kept: its arrows g_0 … g_N, multipliers
    λ_0 … λ_N and, for a forced system, the inputs u_0 … u_N its states hold), a
    :class:`BoundaryValueSolution` (or any object with ``arrows`` and ``multipliers``), or an
    array of arrows (N, arrow_dim) with ``multipliers`` (one row per action term) and
    ``inputs`` (one row per action term: u_j belongs to the term starting at g_j; (m,), or
    a number for one input, held for every term) passed separately.  ``params`` default to
    the trajectory's own.  Returns a
    :class:`StationarityReport`; it is truthy when the central differences shrink like ε²
    (or sit at rounding level) and their extrapolation to ε = 0 is negligible against the
    first-order changes of the single terms — a non-solution gives an O(1) derivative.  At a
    trivial solution (all arrows identities: every term's first-order change vanishes) the
    differences are pure O(ε²), which the extrapolation removes.  The variations have size
    ε (ε times 10⁻⁸ of the largest coordinate they move where that is beyond 10⁸:
    :data:`RESOLVED`; ε times the largest multiplier, at least 1); on a time groupoid
    the time's, relative to the shortest step t_{k+1} − t_k (the check does not depend on
    when the run started).  An action that is not
    finite on the trajectory is a :class:`~symgroupoid.DomainError`; where a variation of
    size ε leaves the discrete Lagrangian's domain (a trajectory near its edge), ε is made
    ten times smaller until the varied action is finite, at most down to ε·10⁻⁶
    (:data:`SHRINK_LIMIT`; a :class:`~symgroupoid.DomainError` beyond), and the report's
    differences are at the ε used.

    A forced system (docs/conventions.md §20): each difference quotient gains the forces'
    virtual work W along the same variation (``report.work``), so the check is
    dS/dt + W = 0, δΣ L(g_k) + Σ [f⁻(g_k)·δ⁻g_k + f⁺(g_k)·δ⁺g_k] = 0 (second order: the
    covectors f⁰, f¹, f² of each pair at its three base points).  A nonholonomic system
    with the Hölder step (seed 002, §10) is varied along D_c only (its constraints M_c are
    not in the action; that the arrows lie in M_c is ``traj.constraint_residuals()``); the
    energy–momentum method (§14) is refused (:class:`~symgroupoid.UnsupportedFeatureError`):
    its rows on D⊥ are not a variational principle.

    A discrete Lagrangian with internal stages L(g, ζ) (docs/conventions.md §22): the
    stages of every arrow are solved first from the system's own stage rows,
    ∂L/∂ζ(g_j, ζ_j) + f_ζ(g_j, ζ_j, u_j) = 0 (:func:`stage_values`), and held while the arrows
    vary: by the envelope theorem the derivative of L_d(g) = L(g, ζ*(g)) along a variation
    of g is that of L(·, ζ*) at fixed ζ*, so the check is the (forced) principle of L_d.
    """
    system = system_argument(system, "system", owner="verify_stationary")
    holder = _holder(system)
    G = system.groupoid
    seed = integer_argument(seed, "seed", maximum=2**63 - 1, owner=system.name)
    eps = real_argument(eps, "eps", owner=system.name)
    if not 1e-300 <= eps <= 1:  # ε/4 is used too: it must stay a normal, nonzero double
        raise DomainError(f"{system.name}: eps must be in [1e-300, 1] (the size of the "
                          f"variations), got {eps!r}")
    arrows, lam, U, params = _unpack(trajectory, system, multipliers, inputs, params,
                                     holder is not None)
    _, arity, m = _cached_terms(system)
    ng = _NumericGroupoid(G, system.parameters, params)
    rng = np.random.default_rng(seed)
    n = len(arrows)
    sizes = _section_sizes(ng, arrows, G.rank)
    if holder is None:
        coeffs = rng.normal(size=(n - 1, G.rank)) * sizes
    else:  # along D_c at each junction node β(g_j) (the Hölder principle)
        coeffs = _distribution_variation(holder, ng, arrows, sizes, params, rng)
    # order-a problems fix the first and last a arrows (seed 001: g₀, g₁, g_{N−1}, g_N):
    # only junctions with a − 1 arrows before and after them stay free
    coeffs[:arity - 1] = 0.0
    coeffs[n - arity:] = 0.0
    varies_lambda = bool(m) and holder is None  # M_c is not in a nonholonomic action
    mus = rng.normal(size=lam.shape) if varies_lambda else None
    # variations relative to the size of what they move: an absolute ε would vanish in the
    # rounding of coordinates of size 1e150 and report any path as stationary
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
        return np.array(out), (lam + t * size_l * mus if varies_lambda else lam)

    # internal stages (§22): solved at every arrow of the trajectory, then held while the
    # arrows vary (at ζ*, d/dt L(g(t), ζ*(g(t))) = ∂L/∂g·g′ by the envelope theorem; forced,
    # the stages solve the forced stage rows, which the principle makes stationary in ζ)
    zeta = stage_values(system, arrows, U, params) if _functions(system).stages else None
    T0 = action_terms(system, arrows, lam, params, zeta)
    _check_finite(system, "the discrete action", T0, params)
    report = StationarityReport()
    pairings = np.zeros((len(T0), 1))
    if _cached_forces(system) is not None:
        forces = force_terms(system, arrows, U, params, zeta)
        _check_finite(system, "the discrete forces", forces.reshape(len(T0), -1), params)
        pairings = virtual_work(forces, coeffs)
        report.work = float(pairings.sum())
    magnitude = float(np.abs(T0).sum())  # what the sums of terms are rounded against
    # a variation of size ε can leave L_d's domain where the trajectory runs near its edge
    # (|q̇| → 1 under √(1 − q̇²)): ε is then made smaller, down to ε·SHRINK_LIMIT
    start = eps
    while True:
        varied_terms = [(action_terms(system, *varied(e), params, zeta),
                         action_terms(system, *varied(-e), params, zeta))
                        for e in (eps, eps / 2, eps / 4)]
        if all(np.isfinite(T).all() for pair in varied_terms for T in pair):
            break
        if eps / 10 < max(start * SHRINK_LIMIT, 1e-300):
            raise DomainError(
                f"{system.name}: the varied action is not finite at any variation of size "
                f"ε = {start:g} down to {eps:g} (the trajectory lies on the edge of the "
                f"discrete Lagrangian's domain, where no variation stays inside it)")
        eps /= 10
    for e, (Tp, Tm) in zip((eps, eps / 2, eps / 4), varied_terms):
        magnitude = max(magnitude, float(np.abs(Tp).sum()), float(np.abs(Tm).sum()))
        report.derivatives[e] = float(Tp.sum() - Tm.sum()) / (2 * e) + report.work
        if e == eps:  # how large the first-order changes of the single terms are
            report.scale = (float(np.abs(Tp - Tm).sum()) / (2 * e)
                            + float(np.abs(pairings).sum()) + 1e-300)
    d = list(report.derivatives.values())
    # d(ε) = S′(0) + W + c₂ε² + c₄ε⁴ + …: eliminating the ε² and ε⁴ terms (Richardson)
    # leaves S′(0) + W
    report.extrapolated = (64 * d[2] - 20 * d[1] + d[0]) / 45
    # the rounding of Σ T(±ε): relative to the largest terms summed (a large ε moves the
    # action's terms far from those of the trajectory itself)
    noise = 1e-13 * magnitude / (eps / 4) + 1e-15 * float(np.abs(pairings).sum())
    shrinking = abs(d[2]) <= 0.35 * abs(d[1]) + noise and abs(d[1]) <= 0.35 * abs(d[0]) + noise
    report.stationary = bool(shrinking and abs(report.extrapolated) <= 1e-4 * report.scale
                             + noise)
    return report


def _holder(system):
    """The nonholonomic system of a Hölder step (varied along D_c), None for a
    DiscreteSystem; the energy–momentum method refused."""
    from .equations import NonholonomicSystem

    if not isinstance(system, NonholonomicSystem):
        return None
    if system.method != "holder":
        raise UnsupportedFeatureError(
            f"{system.name}: verify_stationary checks a variational principle; the "
            f"energy–momentum method's rows on D⊥ are not one (docs/conventions.md §14): "
            f"check its conserved quantities instead (conserved_quantities())")
    return system


def _distribution_variation(system, ng: _NumericGroupoid, arrows: np.ndarray,
                            sizes: np.ndarray, params: Sequence,
                            rng: np.random.Generator) -> np.ndarray:
    """Random variations in D_c at each junction node β(g_j): Σ_a r_a c_a(β(g_j)) with
    c_a the coefficients of D_c's basis (seed 002; docs/conventions.md §10), each element
    scaled by the largest size of the sections it moves."""
    f, r = _cached_distribution(system)
    targets = np.array([ng.target(a) for a in arrows[:-1]], float)  # (n − 1, base_dim)
    (C,) = f(targets.T, np.asarray(params, float)[:, None])  # (r·rank, n − 1)
    C = C.T.reshape(-1, r, ng.G.rank)
    _check_finite(system, "the distribution D_c", C.reshape(len(C), -1), params)
    element = np.array([sizes[np.abs(C[:, a]).max(axis=0, initial=0.0) > 0].max(initial=1.0)
                        for a in range(r)])
    weights = rng.normal(size=(len(targets), r)) * element
    return np.einsum("ja,jab->jb", weights, C)


@functools.lru_cache(maxsize=16)
def _cached_distribution(system):
    """c_a^b(q) of D_c's basis at a base point ``q`` (input ``q``, ``p``), rows a."""
    from .derivation import distribution_coefficients

    G = system.groupoid
    q = [sp.Symbol(f"q{i}", real=True) for i in range(G.base_dim)]
    rows = distribution_coefficients(system.name, G, system.distribution, q)
    g = Graph()
    symbols = {x: g.input(x) for x in (*q, *system.parameters)}
    memo: dict = {}
    nodes = [from_sympy(g, sp.sympify(c), symbols, f"{system.name}: the distribution", memo)
             for row in rows for c in row]
    program = Program(g, {"q": q, "p": list(system.parameters)}, {"C": nodes})
    return program.numpy_function(["C"], ["q", "p"]), len(rows)


def _check_finite(system, what: str, values: np.ndarray, params: Sequence) -> None:
    """A :class:`DomainError` naming the first term whose ``what`` is not finite."""
    bad = ~np.isfinite(values)
    if not bad.any():
        return
    k = int(np.flatnonzero(bad.reshape(len(values), -1).any(axis=1))[0])
    given = ", ".join(f"{s}={v:.6g}" for s, v in zip(system.parameters, params))
    raise DomainError(f"{system.name}: {what} is not finite on this trajectory (term {k}: "
                      f"{np.ravel(values[k]).tolist()}: it overflows or is undefined there"
                      f"{f', with the parameters {given}' if given else ''}), so the "
                      f"variational principle cannot be checked")


def _unpack(trajectory, system, multipliers, inputs, params, nonholonomic: bool = False):
    """Arrows (N, arrow_dim), multipliers (one row per action term), inputs (one row per
    action term) and the parameter vector of a :class:`BoundaryValueSolution`, a
    :class:`Trajectory` or an array of arrows."""
    G, owner = system.groupoid, system.name
    layout = getattr(trajectory, "_layout", None)
    U = inputs
    if hasattr(trajectory, "arrows"):  # a BoundaryValueSolution, or any object with arrows
        arrows = trajectory.arrows() if callable(trajectory.arrows) else trajectory.arrows
        lam = trajectory.multipliers if multipliers is None else multipliers
        held = getattr(trajectory, "inputs", None)
        U = held if U is None and not callable(held) else U
    elif layout is not None and hasattr(trajectory, "states"):  # a Trajectory
        if getattr(trajectory, "every", 1) != 1:
            raise DomainError(f"{owner}: the variations move consecutive arrows, but this "
                              f"trajectory keeps every {trajectory.every}-th state; simulate "
                              f"with every=1")
        shape = np.shape(trajectory.states)
        if len(shape) != 2 or shape[1] != layout.n_known:  # not as its step wrote them
            raise ShapeError(f"{owner}: the trajectory's states have shape {shape}, but its "
                             f"step {layout.step_name} writes states of {layout.n_known} "
                             f"entries; use a trajectory as Simulator.simulate returns it")
        arrows = layout.arrows(trajectory.states)
        lam = trajectory.multipliers if multipliers is None else multipliers
        if U is None and layout.n_inputs:  # the input of each term, as the states hold it
            U = np.stack([layout.view(np.asarray(trajectory.states), name)
                          for name in layout.input_names], axis=1)
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
    if nonholonomic:  # M_c is not in the action: no multipliers (zeros for the program)
        if multipliers is not None and np.size(multipliers):
            raise ShapeError(f"{owner}: a nonholonomic system has no multipliers; leave "
                             f"multipliers= out")
        lam = np.zeros((terms, m))
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
    U = _inputs(system, U, terms)
    for what, values in (("arrows", arrows), ("multipliers", lam), ("inputs", U)):
        if not np.isfinite(values).all():
            row = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
            raise DomainError(f"{owner}: the trajectory's {what} have non-finite values "
                              f"(row {row}: {values[row].tolist()})")
    values, _ = parameter_vector(system.parameters, params, owner=owner)
    return arrows, lam, U, list(values)


def _inputs(system, inputs, terms: int) -> np.ndarray:
    """The inputs of every action term (terms, m): u_j belongs to the term starting at g_j
    (docs/conventions.md §20); none for a system without inputs."""
    forces = _functions(system).forces
    names = [str(u) for u in forces.inputs] if forces is not None else []
    owner, m = system.name, len(names)
    if not m:
        if inputs is not None and np.size(inputs):
            raise ShapeError(f"{owner}: the system has no inputs; leave inputs= out")
        return np.zeros((terms, 0))
    if inputs is None:
        raise ShapeError(f"{owner}: the system has inputs ({', '.join(names)}); give them "
                         f"with inputs= ({terms}, {m}), one row per action term (row j: the "
                         f"inputs of the term starting at g_j), or pass a Trajectory, whose "
                         f"states hold them")
    U = input_rows(inputs, m, terms, owner=owner, name="the inputs", names=names)
    if U.shape != (terms, m):
        raise ShapeError(f"{owner}: inputs must have shape ({terms}, {m}) (one row of "
                         f"{', '.join(names)} per action term), got {U.shape}")
    return U
