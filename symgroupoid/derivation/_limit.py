"""The continuous limit of a first-order discrete Lagrangian (docs/conventions.md §19).

A discrete Lagrangian approximates the action of a continuous one over a step of length h.
Let g_h(q, v) be the arrow whose α-fibre chart coordinates are x₀(q) + h·v, x₀(q) those of
the identity ε(q): on Q×Q, g_h = (q, q + h v); on a Lie group, W = τ(h ξ); on the pair
groupoid of a Lie group, (q, q τ(h ξ)); on a time groupoid the time increment is h and the
inner arrow is as above.  For the time step h,

    L_d(g_h(q, v); h) = c/h + h L(q, v) + O(h²),                                       (1)

with c a constant (−tr J_d for the Moser–Veselov rigid body, 0 for a midpoint rule) and L the
continuous Lagrangian (seed 000 §6: L_d(g) ≈ h L(τ⁻¹(g)/h)).  Two probes follow from (1):

    K(h) = ∂²_v L_d(g_h(q, v); h) / h  →  ∂²L/∂v²(q, v) = M(q, v),                    (2)
    D(h) = [L_d(g_h(q₁, v₁); h) − L_d(g_h(q₂, v₂); h)] / h  →  L(q₁, v₁) − L(q₂, v₂).   (3)

M is the velocity Hessian of the continuous Lagrangian (the mass matrix of a mechanical
one).  A parameter p that is *not* the step, sent to 0 together with the chart scale while
the step stays fixed, gives K = p ∂²_x L_d(g_p) → 0 (the v-Hessian of a function of x₀ + p v
carries p²), unless L_d is singular at p = 0 — and then p enters the values of L_d, so that
D diverges like 1/p (a stiffness written as 1/compliance).  A height h beside a step dt:
K_h → 0; a mass m multiplying L_d: K_m → 0.  So the time step is the parameter for which K
has a finite non-zero limit and D a finite one; :meth:`ContinuousLimit.time_steps` lists the
parameters that pass.  K is probed along v itself, vᵀK(h)v = h d²/ds² L_d(g_s(q, v))|_{s=h}
(twice the kinetic energy of the limit), which is non-zero for a random v whenever M is;
the rank of M is read off the step's own Jacobian (:func:`symgroupoid.equations._regularity.
check_kinetic`), whose leading term in h is −M.

The probes are evaluated numerically, not by SymPy series: L_d is captured once on the
expression graph (:mod:`symgroupoid.ir`) with the base point, the chart of the identity, the
velocity, the chart scale and the parameters as inputs, d²/ds² is taken by algorithmic
differentiation (exact, no difference quotients), and the graph is walked once for all
points and scales h_j = 10⁻³·2⁻ʲ (j = 0…3).  A limit is the polynomial extrapolation of the
values to h = 0 (:func:`extrapolate`; error O(h₀⁴) ≈ 10⁻¹²), and a probe converges when its
values at the two smallest scales agree to 10 % (a wrong parameter changes them by 50 % or
more: they scale like h or 1/h).  The points are random (a fixed seed) with the parameters
at random values respecting their assumptions, so the outcome is deterministic.  SymPy's
``series`` of L_d(g_h)/h at one numeric point takes 0.6 s for the rigid body, 13 s for one
body of :func:`~symgroupoid.systems.spherical_chain` and more than 10 minutes for two, and
leaves rounding terms 10⁻¹⁶/h² in a limit that should have none; the probes take
milliseconds after the graph is built.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._errors import UnsupportedExpressionError
from ..groupoids import Groupoid
from ..ir import Graph, Program, forward, from_sympy, interpret

#: chart scales h_j at which the probes are evaluated (then extrapolated to h = 0)
SCALES = tuple(1e-3 * 0.5 ** j for j in range(4))
#: random points (q, v) at which every conclusion must hold
POINTS = 3
#: a probe converges when it changes by at most this fraction between the two smallest scales
_CONVERGED = 0.1


def parameter_value(s: sp.Symbol, rng: np.random.Generator) -> float:
    """A random value respecting the symbol's assumptions: positive/nonnegative → (0.5, 2),
    negative/nonpositive → (−2, −0.5), integer → 1…3 with that sign, zero → 0."""
    if s.is_zero:
        return 0.0
    sign = -1.0 if (s.is_negative or s.is_nonpositive) else 1.0
    if s.is_integer:
        return sign * float(rng.integers(1, 4))
    return sign * float(rng.uniform(0.5, 2.0))


def may_be_step(s: sp.Symbol) -> bool:
    """Whether the symbol can be a time step (a positive real number): not declared integer,
    zero, negative or non-positive."""
    return not (s.is_integer or s.is_zero or s.is_negative or s.is_nonpositive
                or s.is_real is False)


def extrapolate(values: Sequence[np.ndarray], scales: Sequence[float]) -> np.ndarray:
    """The value at h = 0 of the polynomial through (h_j, values_j) (Neville's scheme)."""
    table = [np.asarray(v, float) for v in values]
    n = len(table)
    for k in range(1, n):
        for i in range(n - k):
            a, b = scales[i], scales[i + k]
            table[i] = (-b * table[i] + a * table[i + 1]) / (a - b)
    return table[0]


def _converges(values: Sequence[np.ndarray], scale: float) -> bool:
    """Whether the last two values agree to :data:`_CONVERGED` of their size (plus
    ``scale``, the size the values are compared with)."""
    last, before = np.asarray(values[-1], float), np.asarray(values[-2], float)
    return bool(scaled_norm(last - before) <= _CONVERGED * (scaled_norm(last) + scale))


def scaled_norm(a: np.ndarray, axis: int | None = None) -> np.ndarray | float:
    """Euclidean norms (of the whole array, or along ``axis``) without overflow or
    underflow: each line scaled by its largest |entry| first (entries of 1e200 square to
    infinity, of 1e-200 to zero, which made a regular Lagrangian scaled by either constant
    read as degenerate).  NaN and inf entries give NaN and inf, as ``np.linalg.norm``."""
    a = np.asarray(a, float)
    if axis is None:
        a = a.ravel()
    line = 0 if axis is None else axis
    m = np.max(np.abs(a), axis=line, keepdims=True, initial=0.0)
    safe = np.where((m > 0) & np.isfinite(m), m, 1.0)
    out = np.squeeze(safe, axis=line) * np.linalg.norm(a / safe, axis=line)
    return float(out) if axis is None else out


@dataclass(frozen=True)
class LimitPoint:
    """Where the limit is probed: a base point q, the chart coordinates x₀ of ε(q), a chart
    velocity v (its time component 1 on a time groupoid) and parameter values p."""

    q: np.ndarray
    x0: np.ndarray
    v: np.ndarray
    p: np.ndarray


@dataclass
class Probes:
    """L_d and d²/ds² L_d(g_s(q, v)) (the second derivative along the chart scale, through the
    chart only) with the step and the chart scale at h, for every point (axis 0) and scale
    h_j (axis 1)."""

    L: np.ndarray  # (P, S)
    L2: np.ndarray  # (P, S)


class ContinuousLimit:
    """Probes of L(q, v) = lim_{h→0} L_d(g_h(q, v); h)/h of a first-order discrete Lagrangian
    (see the module docstring).

    ``lagrangian``: L_d as an expression in the coordinates ``slot`` of a generic arrow of
    ``groupoid`` and the ``parameters``.  The velocity v has one component per chart
    coordinate of the α-fibre; on a :class:`TimeGroupoid` its time component is 1, so that
    the arrow's time increment is the chart scale.
    """

    def __init__(self, groupoid: Groupoid, lagrangian: sp.Expr, slot: Sequence[sp.Symbol],
                 parameters: Sequence[sp.Symbol], name: str = "system"):
        self.groupoid, self.name = groupoid, name
        self.lagrangian, self.slot = sp.sympify(lagrangian), tuple(slot)
        self.parameters = list(parameters)

    @classmethod
    def of_system(cls, system) -> ContinuousLimit | None:
        """The limit of a first-order system's L_d, or None for a system of another order."""
        fs = getattr(system, "functions", None)
        if fs is None or len(fs.slots) != 1 or getattr(fs, "matrix_form", False):
            return None
        return cls(system.groupoid, fs.lagrangian, fs.slots[0], system.parameters,
                   system.name)

    @functools.cached_property
    def program(self) -> Program:
        """Inputs ``q``, ``x0``, ``v``, ``s`` (the chart scale) and ``p`` (the parameters);
        outputs ``L`` = L_d(g_s(q, v)) and ``L2`` = d²/ds² of it through the chart (two
        forward sweeps; vᵀ ∂²_x L_d v, so that s·L2 = vᵀ K v of (2)).  Raises
        :class:`~symgroupoid.UnsupportedExpressionError` for an expression the graph cannot
        evaluate."""
        G, g = self.groupoid, Graph()
        q = [sp.Dummy(f"q{i}", real=True) for i in range(G.base_dim)]
        x0 = [sp.Dummy(f"x0_{i}", real=True) for i in range(G.rank)]
        v = [sp.Dummy(f"v{i}", real=True) for i in range(G.rank)]
        x = [sp.Dummy(f"x{i}", real=True) for i in range(G.rank)]
        s = sp.Dummy("s", positive=True)
        nodes = {c: g.input(c) for c in (*q, *x0, *v, s, *self.parameters)}
        structure = {c: nodes[c] for c in (*q, *self.parameters)}
        structure.update({xi: g.add(nodes[a], g.mul(nodes[s], nodes[b]))
                          for xi, a, b in zip(x, x0, v)})
        memo: dict = {}
        arrow = [from_sympy(g, sp.sympify(c), structure, f"{self.name}: the arrow g_h(q, v)",
                            memo)
                 for c in G.arrow_from(q, G.fibre_chart(x, q))]
        symbols = {**dict(zip(self.slot, arrow)), **{p: nodes[p] for p in self.parameters}}
        L = from_sympy(g, self.lagrangian, symbols, f"{self.name}: the Lagrangian")
        (dL,) = forward(g, [L], {nodes[s]: g.one})
        (d2L,) = forward(g, [dL], {nodes[s]: g.one})
        return Program(g, {"q": q, "x0": x0, "v": v, "s": [s], "p": self.parameters},
                       {"L": [L], "L2": [d2L]})

    def points(self, count: int = POINTS, seed: int = 0) -> list[LimitPoint]:
        """:func:`limit_points` of the groupoid and the parameters."""
        return list(limit_points(self.groupoid, self.parameters, count, seed))

    def probes(self, points: Sequence[LimitPoint], step: sp.Symbol | None) -> Probes | None:
        """:class:`Probes` at ``points`` with the chart scale and the parameter ``step``
        (None: the chart scale alone) both at h = h_j; None when a value is not finite at
        some point (no evidence) or the graph cannot take L_d."""
        if not points:
            return None
        try:
            program = self.program
        except Exception:  # noqa: BLE001 - a map the graph cannot take: no evidence
            return None
        columns = [(pt, h) for pt in points for h in SCALES]
        Q, X0, V, P = (np.stack([getattr(pt, k) for pt, _ in columns], axis=-1)
                       for k in ("q", "x0", "v", "p"))
        S = np.array([[h for _, h in columns]])
        if step is not None:
            P = P.copy()
            P[self.parameters.index(step)] = S[0]
        try:
            L, L2 = interpret(program, ["L", "L2"], ["q", "x0", "v", "s", "p"], Q, X0, V, S, P)
        except (ArithmeticError, ValueError, TypeError):
            return None
        if not (np.all(np.isfinite(L)) and np.all(np.isfinite(L2))):
            return None
        shape = (len(points), len(SCALES))
        return Probes(L.reshape(shape), L2.reshape(shape))

    def is_time_step(self, points: Sequence[LimitPoint], step: sp.Symbol) -> bool:
        """Whether vᵀK(h)v (2) has a finite non-zero limit and D(h) (3) a finite one at every
        point, with ``step`` = h."""
        return self.step_verdict(points, step) is True

    def step_verdict(self, points: Sequence[LimitPoint], step: sp.Symbol) -> bool | None:
        """:meth:`is_time_step`, or None when the probes cannot tell (fewer than two points,
        or L_d not finite at them)."""
        probes = self.probes(points, step)
        if probes is None or len(points) < 2:
            return None
        h = np.asarray(SCALES)
        size = 0.0
        for kinetic in probes.L2 * h[None, :]:
            if kinetic[-1] == 0 or not _converges(list(kinetic), 0.0):
                return False
            size = max(size, abs(float(kinetic[-1])))
        D = (probes.L[1:] - probes.L[:-1]) / h[None, :]
        return all(_converges(list(d), size) for d in D)

    def time_steps(self, points: Sequence[LimitPoint] | None = None) -> list[sp.Symbol]:
        """The parameters that pass :meth:`is_time_step` (see the module docstring)."""
        points = self.points() if points is None else points
        return [p for p in self.parameters if may_be_step(p) and self.is_time_step(points, p)]


def limit_points(groupoid: Groupoid, parameters: Sequence[sp.Symbol], count: int = POINTS,
                 seed: int = 0) -> Iterator[LimitPoint]:
    """``count`` random points, drawn one at a time (fewer when the groupoid cannot draw
    them): q from the groupoid, x₀ the chart of ε(q), v uniform in (−1, 1) (time component
    1); the parameters by :func:`parameter_value`, the same at every point (a constant c/h
    in (1) depends on them)."""
    rng = np.random.default_rng(seed)
    p = np.array([parameter_value(s, rng) for s in parameters])
    for _ in range(count):
        try:
            q = tuple(float(c) for c in groupoid.random_base_point(rng))
            unit = groupoid.fibre_of(groupoid.identity(q))
            x0 = np.array([float(c) for c in groupoid.fibre_chart_inverse(unit, q)])
        except (ArithmeticError, ValueError, TypeError, NotImplementedError):
            continue
        v = rng.uniform(-1.0, 1.0, groupoid.rank)
        if groupoid.timed:  # its first section is ∂/∂t
            v[0] = 1.0
        if x0.shape == (groupoid.rank,) and np.all(np.isfinite(x0)):
            yield LimitPoint(np.array(q), x0, v, p)


def identified_time_steps(system) -> list[sp.Symbol]:
    """The parameters of a first-order system that behave as its time step
    (:meth:`ContinuousLimit.time_steps`), found once and kept with the system; [] for other
    systems."""
    found = system.__dict__.get("_identified_time_steps")
    if found is None:
        limit = ContinuousLimit.of_system(system)
        found = [] if limit is None else limit.time_steps()
        system.__dict__["_identified_time_steps"] = found
    return list(found)


def declared_step_behaves(system) -> bool | None:
    """Whether the time step a first-order system declares (``time_step=``) behaves as its
    step in the continuous limit, L_d(g_h(q, v)) = c/h + h L(q, v) + O(h²) (§19): None when
    it declares none, on a time groupoid, with internal stages, or where the probes cannot
    tell.  A declared step skips the identification; this is the check an energy
    −∂L_d/∂h makes of it, e.g. against an L_d written as L(q̄, Δq/h) without the factor h."""
    if "_declared_step_behaves" not in system.__dict__:  # probed once per system
        system.__dict__["_declared_step_behaves"] = _declared_step_verdict(system)
    return system.__dict__["_declared_step_behaves"]


def _declared_step_verdict(system) -> bool | None:
    declared = getattr(system, "time_step", None)
    fs = getattr(system, "functions", None)
    if declared is None or system.groupoid.timed or fs is None or getattr(fs, "stages", ()):
        return None
    limit = ContinuousLimit.of_system(system)
    if limit is None:
        return None
    step = next((p for p in system.parameters if str(p) == str(declared)), declared)
    try:
        return limit.step_verdict(list(limit.points()), step)
    except UnsupportedExpressionError:
        return None


def time_step_candidates(system) -> list:
    """The time steps a system's derivation checks its continuous limit with: the declared
    one, else those :func:`identified_time_steps` finds (none, one or several); [None] on a
    time groupoid, whose step is each arrow's t₁ − t₀."""
    declared = getattr(system, "time_step", None)
    if declared is not None:
        return [declared]
    if system.groupoid.timed:
        return [None]
    return identified_time_steps(system)
