"""Continuous systems and their variational discretisations (docs/conventions.md §21).

A :class:`ContinuousSystem` is a configuration space Q — a Euclidean space, a matrix Lie
group, or a product of them — with a Lagrangian L(q, v): v is the velocity on a Euclidean
space and the body velocity ξ (g⁻¹ġ in the basis of the group's Lie algebra, ``G.hat``) on
a group.  :meth:`ContinuousSystem.discretize` writes its discrete Lagrangian on the pair
groupoid Q × Q ⇉ Q for a quadrature rule (Marsden–West §2.6; on groups through the group's
retraction τ, Bou-Rabee–Marsden's Hamilton–Pontryagin integrators): from an arrow
(q₀, q₁) a step h apart,

- on a Euclidean factor: v = (q₁ − q₀)/h, the midpoint q̄ = (q₀ + q₁)/2;
- on a group factor: ξ = τ⁻¹(g₀⁻¹g₁)/h, the midpoint ḡ = g₀·τ(hξ/2);

``"midpoint"``: L_d = h·L(q̄, v); ``"trapezoid"``: L_d = (h/2)·(L(q₀, v) + L(q₁, v)).  Both
are of order 2 (Marsden–West Thm 2.3.1 with the variational order of the quadrature).
:class:`GaussLegendre` (s) and :class:`LobattoIIIAB` (s) name the Galerkin families; their
one- and two-stage members are these two rules (Gauss–Legendre with one stage is the
midpoint rule, Lobatto IIIA–IIIB with two stages the trapezoid rule, i.e. Störmer–Verlet).
The members with internal stages are Galerkin discrete Lagrangians (:mod:`._galerkin`,
docs/conventions.md §22): the discrete system has internal stages ζ, unknowns of every step
and never part of the state.

Continuous forces F(q, v) (which may read the ``inputs``) give the discrete forces of the
same scheme (docs/conventions.md §20, :mod:`._forcing`): f⁻ = f⁺ = (h/2)·F(q̄, v) (midpoint),
f⁻ = (h/2)·F(q₀, v), f⁺ = (h/2)·F(q₁, v) (trapezoid), both on Euclidean factors; with
internal stages the quadrature of the virtual work h Σ_i b_i F(q_i, v_i)·δq_i, on Euclidean
and group factors (a body-frame torque paired with the nodes' body variations; the forced
Galerkin scheme of docs/conventions.md §22).  An input is held over each arrow.
"""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._arguments import caller_level, integer_argument, name_argument, sequence_argument
from .._errors import (
    CallableError,
    DegenerateSystemError,
    InputTypeError,
    ShapeError,
    UnsupportedFeatureError,
)
from ..derivation import (
    as_scalar,
    as_scalar_list,
    call_user,
    check_parameters,
    checked_callable,
    holonomic_functions,
    limit_points,
)
from ..groupoids import configuration_factors, pair_groupoid_of
from ..ir import Graph, Program, from_sympy, jacobian
from ._galerkin import MAX_NODES, GalerkinTableau, gauss_legendre_tableau, lobatto_tableau
from ._system import DiscreteSystem

#: the rules written directly (order 2), by name
RULES = ("midpoint", "trapezoid")


@dataclass(frozen=True)
class GaussLegendre:
    """The Galerkin variational integrator with s Gauss–Legendre nodes (order 2s;
    Marsden–West §2.6.6, Hairer–Lubich–Wanner VI.6).  s = 1 is the midpoint rule."""

    stages: int

    def __post_init__(self):
        object.__setattr__(self, "stages", integer_argument(
            self.stages, "stages", minimum=1, maximum=MAX_NODES, owner="GaussLegendre"))

    @property
    def order(self) -> int:
        return 2 * self.stages

    @property
    def rule(self) -> str | None:
        """The rule written without internal stages, or None."""
        return "midpoint" if self.stages == 1 else None

    @property
    def label(self) -> str:
        return f"gauss{self.stages}"

    def tableau(self) -> GalerkinTableau:
        return gauss_legendre_tableau(self.stages)


@dataclass(frozen=True)
class LobattoIIIAB:
    """The Lobatto IIIA–IIIB partitioned Runge–Kutta method with s nodes (order 2s − 2;
    Marsden–West §2.6.6).  s = 2 is the trapezoid rule (Störmer–Verlet)."""

    stages: int

    def __post_init__(self):
        object.__setattr__(self, "stages", integer_argument(
            self.stages, "stages", minimum=2, maximum=MAX_NODES, owner="LobattoIIIAB"))

    @property
    def order(self) -> int:
        return 2 * self.stages - 2

    @property
    def rule(self) -> str | None:
        return "trapezoid" if self.stages == 2 else None

    @property
    def label(self) -> str:
        return f"lobatto{self.stages}"

    def tableau(self) -> GalerkinTableau:
        return lobatto_tableau(self.stages)


def scheme_rule(scheme) -> str | GaussLegendre | LobattoIIIAB:
    """The rule of a scheme: ``"midpoint"`` or ``"trapezoid"``, named or as the Galerkin
    member it is; the Galerkin scheme itself for members with internal stages."""
    if isinstance(scheme, str):
        if scheme not in RULES:
            raise InputTypeError(f"discretize: scheme must be one of {', '.join(RULES)}, "
                                 f"GaussLegendre(s) or LobattoIIIAB(s); got {scheme!r}")
        return scheme
    if isinstance(scheme, (GaussLegendre, LobattoIIIAB)):
        return scheme if scheme.rule is None else scheme.rule
    raise InputTypeError(f"discretize: scheme must be one of {', '.join(RULES)}, "
                         f"GaussLegendre(s) or LobattoIIIAB(s); got {type(scheme).__name__} "
                         f"{scheme!r}")


# --- the system ---------------------------------------------------------------------------------

class ContinuousSystem:
    """A Lagrangian system on Q with L(q, v) (see the module docstring); discretised by
    :meth:`discretize` into a :class:`DiscreteSystem` on the pair groupoid Q × Q.

    ``L(q, v)``: q a configuration (a point as a column matrix, a group element as its
    matrix, a tuple of them on a product), v a velocity (a column matrix; on a group the
    body velocity ξ in the basis of ``G.hat``; a tuple on a product).  ``forces=F(q, v)``
    (a generalised force, one component per coordinate; on a group factor a body-frame
    torque, one component per direction of ``G.hat``'s basis, taken by the Galerkin schemes
    with internal stages only) may use the ``inputs``.  ``holonomic``: passed on to the
    discrete system (a function of its base point, docs/conventions.md §7).
    """

    def __init__(self, Q, L: Callable, parameters: Sequence[sp.Symbol] = (), *,
                 holonomic: Callable | None = None, forces: Callable | None = None,
                 inputs: Sequence[sp.Symbol] = (), name: str = "continuous"):
        name = name_argument(name, "the system's name", owner="ContinuousSystem")
        self.name = name
        self.factors, self.product = configuration_factors(Q)
        self.Q = Q
        if not callable(L):
            raise InputTypeError(f"{name}: L must be a function L(q, v), got "
                                 f"{type(L).__name__}")
        _check_arity(name, L)
        self.lagrangian = L
        for what, f, form in (("holonomic", holonomic, "lambda q: [...]"),
                              ("forces", forces, "lambda q, v: [...]")):
            if f is not None and not callable(f):
                raise CallableError(f"{name}: {what} must be a function of the configuration"
                                    f"{' and velocity' if what == 'forces' else ''} "
                                    f"({form}), got {type(f).__name__}")
        self.parameters = sequence_argument(
            [parameters] if isinstance(parameters, sp.Symbol) else parameters, "parameters",
            owner=name)
        check_parameters(name, "Lagrangian", self.parameters)  # symbols, each name once
        self.holonomic = holonomic
        self.forces = forces
        self.inputs = sequence_argument([inputs] if isinstance(inputs, sp.Symbol) else inputs,
                                        "inputs", owner=name)
        if self.inputs and forces is None:
            raise UnsupportedFeatureError(
                f"{name}: inputs {', '.join(map(str, self.inputs))} are declared but the "
                f"system has no forces to use them; pass forces=F with F(q, v) -> [one "
                f"generalised force per coordinate] in the inputs")

    def _values(self, parts: list):
        return tuple(parts) if self.product else parts[0]

    def discretize(self, step, scheme="midpoint") -> DiscreteSystem:
        """The discrete system of ``scheme`` (``"midpoint"``, ``"trapezoid"``,
        ``GaussLegendre(s)``, ``LobattoIIIAB(s)``) with time step ``step`` (a declared
        parameter, which becomes the system's ``time_step``).  Galerkin members with
        internal stages give a system with ``stages`` (docs/conventions.md §22)."""
        rule = scheme_rule(scheme)
        h = _step_symbol(self, step)
        G, read = pair_groupoid_of(self.Q, self.factors, self.product)
        if not isinstance(rule, str):
            return self._galerkin(rule, h, G, read)
        if self.forces is not None and any(f.is_group for f in self.factors):
            raise UnsupportedFeatureError(
                f"{self.name}: continuous forces on a Lie group factor are supported with the "
                f"Galerkin schemes with internal stages (GaussLegendre(s), s ≥ 2, "
                f"LobattoIIIAB(s), s ≥ 3; docs/conventions.md §22), not with the {rule} rule; "
                f"choose one of those, or pass the discrete forces (sg.body_torque) to a "
                f"DiscreteSystem written by hand")

        def pieces(g):
            pairs = read(g)
            v = [f.velocity(a, b, h) for f, (a, b) in zip(self.factors, pairs)]
            ends = ([f.point(a) for f, (a, _) in zip(self.factors, pairs)],
                    [f.point(b) for f, (_, b) in zip(self.factors, pairs)])
            mid = [f.midpoint(a, b, vi, h) for f, (a, b), vi in zip(self.factors, pairs, v)]
            return v, ends, mid

        # L and F on generic symbols, then at the points: an L that differentiates in
        # its configuration (sp.diff(V, q[0])) could not take the midpoint (q₀ + q₁)/2
        def L_d(g):
            v, (q0, q1), mid = pieces(g)
            if rule == "midpoint":
                return h * self._lagrangian_at(mid, v)
            return h / 2 * (self._lagrangian_at(q0, v) + self._lagrangian_at(q1, v))

        forces = None
        if self.forces is not None:
            @checked_callable  # made of the generic F, checked once (_force_at)
            def forces(g):
                v, (q0, q1), mid = pieces(g)
                if rule == "midpoint":
                    half = [h / 2 * f for f in self._force_at(mid, v)]
                    return half, list(half)
                return ([h / 2 * f for f in self._force_at(q0, v)],
                        [h / 2 * f for f in self._force_at(q1, v)])

        system = DiscreteSystem(G, L_d, parameters=self.parameters,
                                name=f"{self.name}_{rule}", holonomic=self.holonomic,
                                time_step=h, forces=forces, inputs=self.inputs)
        system.continuous = Discretization(self, h, rule, scheme)
        return system

    def _galerkin(self, scheme, h: sp.Symbol, G, read) -> DiscreteSystem:
        """The Galerkin discrete system of ``scheme`` (see :mod:`._galerkin`)."""
        self._check_galerkin(scheme, G)
        tableau = scheme.tableau()
        n_psi = 0 if self.holonomic is None else len(holonomic_functions(  # checked
            self.name, G, self.holonomic,
            tuple(sp.Dummy(f"q{i}", real=True) for i in range(G.base_dim)), self.parameters))
        inner = tableau.interior
        n_stage = inner * (sum(f.dim for f in self.factors) + n_psi)

        @checked_callable  # made of the generic L, checked once (_generic_lagrangian)
        def L_d(g, zeta):
            return self._galerkin_action(tableau, h, G, read(g), list(zeta), n_psi)

        forces = None
        if self.forces is not None:
            @checked_callable  # made of the generic F, checked once (_generic_forces)
            def forces(g, zeta):
                return self._galerkin_forces(tableau, h, G, g, read(g), list(zeta))

        system = DiscreteSystem(G, L_d, parameters=self.parameters,
                                name=f"{self.name}_{scheme.label}", holonomic=self.holonomic,
                                time_step=h, stages=n_stage, forces=forces,
                                inputs=self.inputs)
        system.continuous = Discretization(self, h, scheme.label, scheme)
        return system

    def _check_galerkin(self, scheme, G) -> None:
        label = f"{type(scheme).__name__}({scheme.stages})"
        if self.holonomic is not None:
            if isinstance(scheme, GaussLegendre):
                raise UnsupportedFeatureError(
                    f"{self.name}: holonomic constraints are supported with LobattoIIIAB(s) "
                    f"(constraints at every node, docs/conventions.md §22), not with {label}")
            if any(f.is_group for f in self.factors):
                raise UnsupportedFeatureError(
                    f"{self.name}: holonomic constraints with {label} are supported on "
                    f"Euclidean spaces only")

    def _holonomic_at(self, G, coords: list) -> list:
        if self.holonomic is None:
            return []
        raw = call_user(self.name, "holonomic", self.holonomic, G.base_view(tuple(coords)),
                        smooth=True, display={})
        return [sp.sympify(c) for c in (raw if isinstance(raw, (list, tuple, sp.MatrixBase))
                                        else [raw])]

    def _galerkin_controls(self, tableau: GalerkinTableau, pairs: list, zeta: list
                           ) -> list:
        """The control values of the Galerkin curve, per factor: X₀ = 0, X_j = d_j Δ + ζ_j,
        X_M = Δ (Δ the increment of the arrow, in the chart of its source)."""
        M, it = len(tableau.control) - 1, iter(zeta)
        controls = []
        for f, (a, b) in zip(self.factors, pairs):
            delta = f.increment(a, b)
            controls.append([sp.zeros(f.dim, 1)] + [None] * (M - 1) + [delta])
        for j in range(1, M):
            for f, X in zip(self.factors, controls):
                X[j] = tableau.control[j] * X[-1] + sp.Matrix([next(it) for _ in range(f.dim)])
        return controls

    def _galerkin_nodes(self, tableau: GalerkinTableau, h, pairs: list, controls: list):
        """Per quadrature node i: the chart values x_i, configurations q(c_i h) and
        velocities q̇(c_i h) (body velocities dτ_{x_i}(ẋ_i)/h on a group), per factor."""
        for values, slopes in zip(tableau.values, tableau.slopes):
            x, q, v = [], [], []
            for f, (a, _), X in zip(self.factors, pairs, controls):
                xi = sum((c * Xj for c, Xj in zip(values, X)), sp.zeros(f.dim, 1))
                xdot = sum((c * Xj for c, Xj in zip(slopes, X)), sp.zeros(f.dim, 1)) / h
                x.append(xi)
                q.append(f.along(a, xi))
                v.append(f.chart_velocity(xi, xdot))
            yield x, q, v

    def _galerkin_action(self, tableau: GalerkinTableau, h, G, pairs: list, zeta: list,
                         n_psi: int) -> sp.Expr:
        """h Σ_i b_i L(q(c_i h), q̇(c_i h)) + Σ_interior Λ_i·ψ(q(c_i h)) on the Galerkin
        curve through the arrow's ends and the control values d_j Δ + ζ_j."""
        controls = self._galerkin_controls(tableau, pairs, zeta)
        total, at_nodes = sp.S.Zero, []
        for b_i, (_, q, v) in zip(tableau.weights,
                                  self._galerkin_nodes(tableau, h, pairs, controls)):
            at_nodes.append(q)
            total += b_i * self._lagrangian_at(q, v)
        action = h * total
        interior = iter(zeta[tableau.interior * sum(f.dim for f in self.factors):])
        for q in at_nodes[1:-1] if n_psi else []:  # Lobatto: the interior nodes
            psi = self._holonomic_at(G, [c for part in q for c in part])
            action += sum((next(interior) * c for c in psi), sp.S.Zero)
        return action

    def _galerkin_forces(self, tableau: GalerkinTableau, h, G, g, pairs: list,
                         zeta: list) -> tuple[list, list, list]:
        """The discrete forces of the forced Galerkin scheme (docs/conventions.md §22): the
        quadrature of the continuous virtual work, W = h Σ_i b_i F(q_i, v_i)·δq_i, varied
        along the arrow's sections and the stages; (f⁻, f⁺, f_ζ): f⁺_b is the coefficient of
        the variation X⃖_b (the target moves), f⁻_b that of −X⃗_b (the source moves), f_ζ that
        of δζ (zero for the multipliers' stages).

        With q_i = a + x_i (Euclidean) or a·τ(x_i) (group), x_i = Σ_j ℓ_j(c_i) X_j and
        X_j = d_j Δ + ζ_j, the body variation is δq_i = Ad_{τ(x_i)⁻¹}η_a + dτ_{x_i}(δx_i)
        (η_a = a⁻¹δa; on a Euclidean factor δa + δx_i), and δΔ = dτ_Δ⁻¹(η_b − Ad_{W⁻¹}η_a),
        W = a⁻¹b = τ(Δ) (Euclidean: δb − δa).  So W = κ_a·η_a + κ_b·η_b + Σ_j σ_j·δζ_j with
        the covectors σ_j = h Σ_i b_i ℓ_j(c_i) dτ_{x_i}ᵀF_i, κ_b = dτ_Δ⁻ᵀ Σ_j d_j σ_j and
        κ_a = h Σ_i b_i Ad_{τ(x_i)⁻¹}ᵀF_i − Ad_{W⁻¹}ᵀκ_b, paired with η_a, η_b along each
        section."""
        controls = self._galerkin_controls(tableau, pairs, zeta)
        M = len(tableau.control) - 1
        sigma = [[sp.zeros(f.dim, 1) for _ in range(M + 1)] for f in self.factors]
        source = [sp.zeros(f.dim, 1) for f in self.factors]
        nodes = self._galerkin_nodes(tableau, h, pairs, controls)
        for b_i, values, (x, q, v) in zip(tableau.weights, tableau.values, nodes):
            F, at = self._force_at(q, v), 0
            for k, (f, xi) in enumerate(zip(self.factors, x)):
                Fi = sp.Matrix(F[at:at + f.dim])
                at += f.dim
                mu = f.space.dtau(list(xi), "left").T * Fi if f.is_group else Fi
                source[k] += h * b_i * (_adjoint_inverse(f.space, xi).T * Fi if f.is_group
                                        else Fi)
                for j in range(M + 1):
                    sigma[k][j] += h * b_i * values[j] * mu
        plus = [sp.S.Zero] * G.rank
        minus = [sp.S.Zero] * G.rank
        coords = tuple(g.coords)
        for k, (f, (a, b), X) in enumerate(zip(self.factors, pairs, controls)):
            P = sum((tableau.control[j] * sigma[k][j] for j in range(1, M + 1)),
                    sp.zeros(f.dim, 1))
            if f.is_group:
                Gk = f.space
                kappa_b = Gk.dtau_inverse(list(X[-1]), "left").T * P
                W = Gk.matrix(Gk.inverse(Gk.entries(a))) * b
                kappa_a = source[k] - _adjoint_inverse_of(Gk, W).T * kappa_b
            else:
                kappa_b, kappa_a = P, source[k] - P
            for point, kappa in ((a, kappa_a), (b, kappa_b)):
                left = _body_variations(f, point, coords, G.apply_left)
                right = _body_variations(f, point, coords, G.apply_right)
                for d in range(G.rank):
                    plus[d] += sum((c * e for c, e in zip(kappa, left[d])), sp.S.Zero)
                    minus[d] -= sum((c * e for c, e in zip(kappa, right[d])), sp.S.Zero)
        staged = [c for j in range(1, M) for k in range(len(self.factors)) for c in sigma[k][j]]
        staged += [sp.S.Zero] * (len(zeta) - len(staged))  # the multipliers' stages
        return minus, plus, staged

    def _generic_point(self) -> tuple[list, list, list, list]:
        """Generic symbols, made once: per factor the configuration (a group element's
        matrix in its coordinates, a point's column) and the velocity as L and F take them,
        and the symbols of each."""
        if getattr(self, "_point", None) is None:
            qs, vs, q, v = [], [], [], []
            for i, f in enumerate(self.factors):
                if f.is_group:
                    G = f.space
                    coords = [sp.Dummy(f"g{i}_{a}", real=True) for a in range(G.arrow_dim)]
                    q.append(G.matrix(coords))
                else:
                    coords = [sp.Dummy(f"q{i}_{a}", real=True) for a in range(f.dim)]
                    q.append(sp.Matrix(coords))
                velocity = [sp.Dummy(f"v{i}_{a}", real=True) for a in range(f.dim)]
                v.append(sp.Matrix(velocity))
                qs.append(coords)
                vs.append(velocity)
            self._point = (q, v, qs, vs)
            # messages show the generic symbols by their names (v0_1, not _v0_1)
            self._display = {d: sp.Symbol(d.name) for c in (*qs, *vs) for d in c}
        return self._point

    def _generic_lagrangian(self) -> tuple[sp.Expr, list, list]:
        """L on generic symbols, called (and checked) once: the expression, and per factor
        the symbols of its configuration (the coordinates of a group element's matrix) and
        velocity."""
        if getattr(self, "_generic", None) is None:
            q, v, qs, vs = self._generic_point()
            self._generic = (self._lagrangian(self._values(q), self._values(v)), qs, vs)
        return self._generic

    def _at(self, exprs: list, q: list, v: list) -> list:
        """``exprs``, written in :meth:`_generic_point`'s symbols, at configurations ``q``
        and velocities ``v`` (lists per factor), by substitution."""
        _, _, qs, vs = self._generic_point()
        sub = {}
        for f, coords, velocity, qi, vi in zip(self.factors, qs, vs, q, v):
            values = f.space.entries(qi) if f.is_group else list(qi)
            sub.update(zip(coords, values))
            sub.update(zip(velocity, list(vi)))
        return [e.xreplace(sub) for e in exprs]

    def _lagrangian_at(self, q: list, v: list) -> sp.Expr:
        """L at configurations ``q`` and velocities ``v`` (lists per factor), by substitution
        into :meth:`_generic_lagrangian`."""
        return self._at([self._generic_lagrangian()[0]], q, v)[0]

    def _force_at(self, q: list, v: list) -> list:
        """F at configurations ``q`` and velocities ``v`` (lists per factor): F called (and
        checked: finite, real) once on generic symbols, then substituted, so that a force
        that is not real is refused at once however large the points it is taken at (a
        Galerkin node on a group is a rational function of the stages)."""
        if getattr(self, "_generic_forces", None) is None:
            q0, v0, _, _ = self._generic_point()
            self._generic_forces = self._force(self._values(q0), self._values(v0))
        return self._at(self._generic_forces, q, v)

    def _lagrangian(self, q, v) -> sp.Expr:
        value = call_user(self.name, "L(q, v)", self.lagrangian, q, v, smooth=True,
                          display=getattr(self, "_display", {}))
        return as_scalar(self.name, "Lagrangian L(q, v)", value)

    def _force(self, q, v) -> list:
        value = call_user(self.name, "F(q, v)", self.forces, q, v,
                          display=getattr(self, "_display", {}))
        value = as_scalar_list(self.name, "F(q, v)", value)
        n = sum(f.dim for f in self.factors)
        if len(value) != n:
            raise ShapeError(f"{self.name}: F(q, v) returned {len(value)} components; one "
                             f"generalised force per coordinate ({n})")
        return value

    def momentum(self, q, v: Sequence[sp.Symbol]) -> list:
        """p = ∂L/∂v (the continuous Legendre transform) at the configuration ``q`` (as L
        takes it) for velocity symbols ``v`` (all components, factor after factor), one
        component per velocity component (on a group: the body momentum in the basis of
        ``G.hat``)."""
        parts, at = [], 0
        for f in self.factors:
            parts.append(sp.Matrix(list(v[at:at + f.dim])))
            at += f.dim
        L = self._lagrangian(q, self._values(parts))
        return [sp.diff(L, s) for s in v]

    def __repr__(self) -> str:
        return f"<ContinuousSystem {self.name!r} on {self.Q!r}>"


def _check_arity(name: str, L: Callable) -> None:
    """A :class:`CallableError` when ``L`` cannot be called as L(q, v) (its signature, when
    it has one, does not take two positional arguments)."""
    try:
        signature = inspect.signature(L)
    except (TypeError, ValueError):  # a callable without a signature: called as it is
        return
    try:
        signature.bind(None, None)
    except TypeError:
        raise CallableError(f"{name}: L must be a function L(q, v) of a configuration and a "
                            f"velocity; {getattr(L, '__name__', 'it')}{signature} cannot be "
                            f"called with those two") from None


@dataclass(frozen=True)
class Discretization:
    """What a discretised system keeps of its continuous origin: the system, the step
    symbol and the rule (for initial states from a velocity, :func:`velocity_momentum`)."""

    system: ContinuousSystem
    step: sp.Symbol
    rule: str  # "midpoint", "trapezoid", or a Galerkin label ("gauss2", "lobatto3")
    scheme: object = None  # the scheme as discretize took it

    @property
    def order(self) -> int:
        """The theoretical order of the scheme (docs/conventions.md §21, §22)."""
        return self.scheme.order if isinstance(self.scheme, (GaussLegendre, LobattoIIIAB)) \
            else 2

    def check_kinetic(self, step) -> None:
        """The check of a degenerate kinetic energy (docs/conventions.md §19) for a scheme
        with internal stages, whose steps the check of the rules does not probe: when the
        velocity Hessian ∂²L/∂v² is singular at every sampled point
        (:func:`velocity_hessian_singular`), the midpoint rule of the same L and holonomic
        constraints (its forces left out: they do not change ∂²L/∂v²) is derived and
        checked, and its verdict — a :class:`DegenerateSystemError`, or the warning of a
        velocity-linear L — is the scheme's: the same continuous limit.  ``step``: the
        scheme's :class:`~symgroupoid.StepEquations` (its ∂L/∂v program is the one
        ``from_velocity`` uses, made once)."""
        discrete = step.system
        if not velocity_hessian_singular(step):
            return
        c = self.system
        probe = ContinuousSystem(c.Q, c.lagrangian, c.parameters, holonomic=c.holonomic,
                                 name=discrete.name)
        probe_name = f"{discrete.name}_midpoint:"
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                probe.discretize(self.step, "midpoint").euler_lagrange()
            except DegenerateSystemError as err:
                text = str(err).replace(probe_name, f"{discrete.name}:", 1)
                raise DegenerateSystemError(text, findings=err.findings) from None
        for found in caught:  # the probe's warnings, as the scheme's
            text = str(found.message).replace(probe_name, f"{discrete.name}:", 1)
            warnings.warn(found.category(text), stacklevel=caller_level())  # (the user's line)


#: the velocity Hessian is singular where its singular values fall below this fraction of
#: the largest (or it is zero) at every sampled point
HESSIAN_RANK = 1e-10


def velocity_hessian_singular(step) -> bool:
    """Whether ∂²L/∂v² of the continuous L of a discretised system's step, exact on the
    expression graph of ∂L/∂v (its ``velocity_momentum`` program), is singular at every
    point of :func:`~symgroupoid.derivation.limit_points` (a point where it cannot be
    evaluated is no evidence)."""
    program = step.velocity_momentum
    g = program.graph
    v = [g.inputs[s] for s in program.inputs["v"] if s in g.inputs]
    if len(v) < len(program.inputs["v"]):
        return True  # L does not read some velocity: a zero row and column everywhere
    rows = jacobian(g, program.outputs["momentum"], v)
    hessian = Program(graph=g, inputs=program.inputs,
                      outputs={"M": [c for row in rows for c in row]})
    evaluate = hessian.numpy_function(["M"], ["q", "v", "p"])
    n = len(program.inputs["v"])
    found = False
    for point in limit_points(step.system.groupoid, step.system.parameters):
        with np.errstate(all="ignore"):
            M = np.asarray(evaluate(point.q, point.v[:n], point.p)[0], float).reshape(n, n)
        if not np.all(np.isfinite(M)):
            continue
        sv = np.linalg.svd(M, compute_uv=False)
        if sv[0] > 0 and sv[-1] > HESSIAN_RANK * sv[0]:
            return False
        found = True
    return found


def velocity_momentum_program(system: DiscreteSystem) -> Program:
    """The continuous Legendre transform of a discretised system as a program: inputs
    ``q`` (the base point, in the coordinates of the discrete groupoid's source), ``v``
    (the velocity, factor after factor; body velocities on groups), ``p`` (parameters);
    output ``momentum`` = ∂L/∂v.  Its value is the discrete momentum F⁻L_d that starts the
    discrete trajectory of the same initial data (q₀, p₀) (Marsden–West §1.5, 2.6)."""
    origin: Discretization = system.continuous
    continuous = origin.system
    G = system.groupoid
    q = [sp.Dummy(f"q{i}", real=True) for i in range(G.base_dim)]
    v = [sp.Dummy(f"v{i}", real=True) for i in range(sum(f.dim for f in continuous.factors))]
    _, read = pair_groupoid_of(continuous.Q, continuous.factors, continuous.product)
    pairs = read(G.view(G.identity(q)))
    configuration = continuous._values([f.point(a) for f, (a, _) in zip(continuous.factors,
                                                                        pairs)])
    momentum = continuous.momentum(configuration, v)
    graph, symbols, memo = Graph(), {}, {}
    for s in (*q, *v, *system.parameters):
        symbols[s] = graph.input(s)
    nodes = [from_sympy(graph, e, symbols, f"{system.name}: ∂L/∂v", memo) for e in momentum]
    program = Program(graph=graph, inputs={"q": q, "v": v, "p": list(system.parameters)},
                      outputs={"momentum": nodes})
    program.check_inputs()
    return program


def _adjoint_inverse(G, x: sp.Matrix) -> sp.Matrix:
    """Ad_{τ(x)⁻¹} on Lie-algebra coordinates: columns vee(τ(−x) E_c τ(x)) (τ(x)⁻¹ = τ(−x)
    for the Cayley retraction and for the exponential)."""
    forward, backward = G.tau(list(x)), G.tau([-c for c in x])
    return sp.Matrix.hstack(*[G.vee(backward * E * forward) for E in G.basis_matrices()])


def _adjoint_inverse_of(G, W: sp.Matrix) -> sp.Matrix:
    """Ad_{W⁻¹} on Lie-algebra coordinates: columns vee(W⁻¹ E_c W)."""
    inverse = G.matrix(G.inverse(G.entries(W)))
    return sp.Matrix.hstack(*[G.vee(inverse * E * W) for E in G.basis_matrices()])


def _body_variations(f, point, coords: tuple, apply) -> list:
    """The variation of one end of the arrow along every section (``apply``: the groupoid's
    apply_left or apply_right), per section: δp on a Euclidean factor, the body variation
    p⁻¹δp on a group factor."""
    if not f.is_group:
        moved = [apply(e, coords) for e in point]
        return [[row[d] for row in moved] for d in range(len(moved[0]))]
    G = f.space
    entries = G.entries(point)
    moved = [apply(e, coords) for e in entries]
    fixed = G.matrix([0] * len(entries))  # the entries a variation does not move
    inverse = G.matrix(G.inverse(entries))
    out = []
    for d in range(len(moved[0])):
        column = [row[d] for row in moved]
        out.append(list(G.vee(inverse * (G.matrix(column) - fixed)))
                   if any(c != 0 for c in column) else [sp.S.Zero] * G.rank)
    return out


def _step_symbol(system: ContinuousSystem, step) -> sp.Symbol:
    by_name = {str(p): p for p in system.parameters}
    if not isinstance(step, (str, sp.Symbol)) or str(step) not in by_name:
        raise InputTypeError(f"{system.name}: discretize(step=...) must be one of the "
                             f"parameters ({', '.join(by_name) or 'none'}), its symbol or "
                             f"name; got {step!r}")
    return by_name[str(step)]


__all__ = ["ContinuousSystem", "GaussLegendre", "LobattoIIIAB"]
