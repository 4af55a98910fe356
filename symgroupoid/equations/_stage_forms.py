"""A Galerkin step printed in the papers' stage notation (docs/conventions.md §22).

Marsden–West §2.6 and Hairer–Lubich–Wanner VI.6 write a Galerkin (variational partitioned
Runge–Kutta) step through the values of the curve of each arrow at the quadrature nodes: for
the arrow g_k = (q_{k−1}, q_k) the configurations Q_{k,i} = q(c_i h) and velocities
V_{k,i} = q̇(c_i h), related by the stage equations

    Q_{k,i} = q_{k−1} + h Σ_j a_ij V_{k,j},   a_ij = ∫₀^{c_i} ℓ̃_j(τ) dτ

(ℓ̃_j the Lagrange basis on the nodes; exact, since V is a polynomial of degree M − 1 ≤ s − 1
interpolated at the s nodes: the Gauss and the Lobatto IIIA coefficients).  With them the
junction row of a Euclidean factor's coordinate is

    h Σ_i b_i [∂L/∂q(Q_{k,i}, V_{k,i}) c_i + ∂L/∂v(Q_{k,i}, V_{k,i})/h + c_i F_{k,i}]
      + h Σ_i b_i [∂L/∂q(Q_{k+1,i}, V_{k+1,i}) (1 − c_i) − ∂L/∂v(Q_{k+1,i}, V_{k+1,i})/h
      + (1 − c_i) F_{k+1,i}] = 0,

and the stage row of the internal stage ζ_j of an arrow h Σ_i b_i [∂L/∂q ℓ_j(c_i) +
∂L/∂v ℓ_j′(c_i)/h + ℓ_j(c_i) F_i] = 0 (the chain rule through q(c_i h) = q_{k−1} +
Σ_j ℓ_j(c_i) X_j, X_j = d_j Δ + ζ_j).  The velocities are given in the "where" list in the
step's unknowns, V_{k,i} = (Δ + Σ_j ℓ_j′(c_i) ζ_j)/h, and the configurations by the stage
equations; every printed row is checked against the step's residual, as every printed form
is (:mod:`._printing`).

With holonomic constraints ψ (``LobattoIIIAB(s)``, Jay's SPARK methods in variational form,
docs/conventions.md §22) the interior nodes carry the multipliers Λ_{k,i} (the arrow's last
internal stages, named in the "where" list), whose action term Λ_{k,i}·ψ(Q_{k,i}) adds
c_i Λ_{k,i}·∇ψ(Q_{k,i}) (target) or (1 − c_i) Λ_{k,i}·∇ψ(Q_{k,i}) (source) to the junction
rows and ℓ_j(c_i) Λ_{k,i}·∇ψ(Q_{k,i}) to the stage rows; the multiplier λ_{k+1} of the
arrow g_{k+1}, at its source q_k (§15), adds λ_{k+1}·∇ψ(q_k); the multipliers' rows are
ψ(Q_{k,i}) = 0 at the interior nodes, and the step ends with ψ(q_{k+1}) = 0.

This form is offered for Galerkin discretisations (with internal stages) on Euclidean
factors.  On a group factor the same step reads, in the chart of each arrow's source
(docs/conventions.md §22, "The stage notation on a group factor"; Bogfjellmo–Marthinsen's
scheme with the retraction τ), through X_{k,i} = h Σ_j a_ij V_{k,j}, the stage attitudes
R_{k,i} = R_{k−1} τ(X_{k,i}) and body velocities Ξ_{k,i} = dτ_{X_{k,i}}(V_{k,i}):

    dτ_{Δ_k}⁻ᵀ P_k + S_{k+1} − Ad_{τ(Δ_{k+1})⁻¹}ᵀ dτ_{Δ_{k+1}}⁻ᵀ P_{k+1} = 0,
    h Σ_i b_i [ℓ_j(c_i) ∂L̃/∂x + ℓ_j′(c_i) ∂L̃/∂v /h] = 0,

P_k = h Σ_i b_i [c_i ∂L̃/∂x + ∂L̃/∂v /h], S_k = h Σ_i b_i Ad_{τ(X_{k,i})⁻¹}ᵀ N_{k,i},
∂L̃/∂x = dτ_Xᵀ N + ∂_X(dτ_X V)ᵀ M, ∂L̃/∂v = dτ_Xᵀ M (N the left-trivialised derivative of L
in R, M = ∂L/∂Ξ at the node).  Those rows hold on the group only, not in the free entries
of the attitudes the residual is written in, so they are printed by
:mod:`._group_stage_forms`, checked there by evaluation at points of the group; this form
(checked by expansion) returns None for a step with a group factor.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

import sympy as sp

from .._symbols import latex_name, multiplier_symbols, node_symbol, stage_symbols
from ..derivation import WindowAction, input_symbols
from ._forms import Definition, Form
from ._galerkin import _lagrange, _tau
from ._latex import Collected


def galerkin_origin(step):
    """The discretisation a step with internal stages comes from (its continuous system,
    scheme and time step), or None for any other step."""
    from ._continuous import GaussLegendre, LobattoIIIAB

    origin = getattr(getattr(step, "system", None), "continuous", None)
    if origin is None or not isinstance(origin.scheme, (GaussLegendre, LobattoIIIAB)) \
            or origin.scheme.rule is not None:
        return None
    return origin


#: the letters of the stage notation on vector spaces (nodes Q, V, interior multipliers Λ,
#: the stages ζ; a forced system's F: :func:`stage_letters`)
STAGE_LETTERS = ("Q", "V", r"\Lambda", r"\zeta")


def _base(tex: str) -> str:
    """The letter a printed name starts with: ``X`` of ``X_{1}``, ``\\Xi`` of ``\\Xi^{2}``."""
    return re.split(r"[_^{ (]", tex, maxsplit=1)[0]


def notation_clash(continuous, letters: Sequence[str]) -> list[str]:
    """The names of a continuous system (its coordinates or group, parameters and inputs, as
    printed) that read as one of the notation's ``letters``: the printed rows would use one
    symbol for two things (the form is then not offered).  With several factors the
    notation's symbols carry the factor's tag (``S^{(R)}_{j}``) and read as none of them."""
    if len(continuous.factors) > 1:
        return []
    names = [latex_name(f.space.symbol_name) if f.is_group else latex_name(n)
             for f in continuous.factors
             for n in ([None] if f.is_group else f.space.names)]
    names += [latex_name(s.name) for s in (*continuous.parameters, *continuous.inputs)]
    return sorted({t for t in names if _base(t) in letters})


def stage_clash(step) -> list[str]:
    """:func:`notation_clash` of a Galerkin step's continuous system with the stage notation
    it would be printed in (on a group factor, :data:`GROUP_LETTERS`), or []."""
    from ._group_stage_forms import GROUP_LETTERS

    origin = galerkin_origin(step)
    if origin is None:
        return []
    continuous = origin.system
    grouped = any(f.is_group for f in continuous.factors)
    return notation_clash(continuous, GROUP_LETTERS if grouped else stage_letters(continuous))


def stage_letters(continuous) -> tuple[str, ...]:
    """:data:`STAGE_LETTERS`, and F for a forced system (its forces at the nodes)."""
    return STAGE_LETTERS + (("F",) if continuous.forces is not None else ())


def stage_form(step) -> Form | None:
    """The step in the stage notation (see the module docstring), or None when it does not
    apply (or the system's names clash with it: :func:`notation_clash`)."""
    origin = galerkin_origin(step)
    if origin is None:
        return None
    system, continuous = step.system, origin.system
    if any(f.is_group for f in continuous.factors):  # not checkable exactly: see above
        return None
    if notation_clash(continuous, stage_letters(continuous)):
        return None
    tableau, h = origin.scheme.tableau(), origin.step
    fs = system.functions
    action = WindowAction(step.groupoid, fs)
    arrows = action.named_arrows()
    from ..groupoids import pair_groupoid_of

    _, read = pair_groupoid_of(continuous.Q, continuous.factors, continuous.product)
    names = [latex_name(n) for f in continuous.factors for n in f.space.names]
    junction = [sp.S.Zero] * len(names)
    stage_rows, layer, definitions = [], {}, []
    constraint = _Constraint(continuous, step.groupoid)
    for s in action.starts:
        pairs = read(step.groupoid.view(arrows[s]))
        rows = _arrow_rows(continuous, tableau, h, s, pairs, names, layer, definitions,
                           constraint)
        towards, stages = rows
        junction = [a + b for a, b in zip(junction, towards)]
        stage_rows += stages
    last = read(step.groupoid.view(arrows[action.starts[-1]]))
    ends = constraint.at([c for _, b in last for c in b])  # ψ(q_{k+1}) = 0
    return Form(junction + stage_rows + ends, [layer], definitions)


class _Constraint:
    """The holonomic constraints ψ of a continuous system at given coordinates (none
    without), and their gradients."""

    def __init__(self, continuous, G):
        self.continuous, self.G = continuous, G
        self.count = len(continuous._holonomic_at(G, [sp.Dummy() for _ in range(G.base_dim)]))

    def at(self, coords: list) -> list:
        return self.continuous._holonomic_at(self.G, list(coords)) if self.count else []

    def pulled(self, coords: list, multipliers: list) -> list:
        """Σ_c μ_c ∂ψ_c/∂q_r at ``coords`` for every coordinate r."""
        psi = self.at(coords)
        return [sum((m * sp.diff(p, q) for m, p in zip(multipliers, psi)), sp.S.Zero)
                for q in coords]


def _arrow_rows(continuous, tableau, h, s: int, pairs: list, names: list, layer: dict,
                definitions: list, constraint: _Constraint) -> tuple[list, list]:
    """The arrow g_{k+s}'s part of the junction rows (its target moves for s = 0, its
    source for s = 1) and its stage rows (then its interior multipliers' rows), in the node
    symbols; fills ``layer`` (the symbols' values in the step's coordinates) and
    ``definitions`` (the "where" rows)."""
    M = len(tableau.control) - 1
    n, n_psi = len(names), constraint.count
    symbols = stage_symbols((M - 1) * (n + n_psi), s)
    zeta = iter(symbols[:(M - 1) * n])
    interior_multipliers = iter(symbols[(M - 1) * n:])
    source = sp.Matrix([c for a, _ in pairs for c in a])
    delta = sp.Matrix([c for a, b in pairs for c in (sp.Matrix(b) - sp.Matrix(a))])
    interior = [sp.Matrix([next(zeta) for _ in range(n)]) for _ in range(1, M)]
    a_matrix = stage_coefficients(tableau.nodes)
    Q = [[node_symbol("Q", s, i + 1, None if n == 1 else x) for x in names]
         for i in range(len(tableau.nodes))]
    V = [[node_symbol("V", s, i + 1, None if n == 1 else x) for x in names]
         for i in range(len(tableau.nodes))]
    towards = [sp.S.Zero] * n
    stages = [[sp.S.Zero] * n for _ in range(M - 1)]
    held: list = []  # ψ(Q_{k,i}) = 0 at the interior nodes: the multipliers' rows
    forces: list = []  # the "where" rows F_{k,i} = F(Q_{k,i}, V_{k,i}, u_k), after Q's
    u = dict(zip(continuous.inputs, input_symbols(continuous.inputs, s)))
    for i, (b_i, values, slopes) in enumerate(zip(tableau.weights, tableau.values,
                                                  tableau.slopes)):
        c_i = exact_number(sum((v * d for v, d in zip(values, tableau.control)), sp.S.Zero))
        q_value = source + c_i * delta + sum((v * z for v, z in zip(values[1:M], interior)),
                                             sp.zeros(n, 1))
        v_value = (exact_number(sum((d * t for d, t in zip(slopes, tableau.control)), sp.S.Zero))
                   * delta + sum((t * z for t, z in zip(slopes[1:M], interior)),
                                 sp.zeros(n, 1))) / h
        for r in range(n):
            layer[Q[i][r]], layer[V[i][r]] = q_value[r], v_value[r]
            definitions.append(Definition(V[i][r], v_value[r], frozenset({V[i][r]})))
        L, F = _at_node(continuous, Q[i], V[i], u)
        F = _named_forces(F, s, i, names, layer, forces)
        weight_q, weight_v = (c_i, 1 / h) if s == 0 else (1 - c_i, -1 / h)
        for r in range(n):
            dq, dv = sp.diff(L, Q[i][r]), sp.diff(L, V[i][r])
            towards[r] += h * b_i * (weight_q * (dq + F[r]) + weight_v * dv)
            for j in range(1, M):
                stages[j - 1][r] += h * b_i * (values[j] * (dq + F[r]) + slopes[j] * dv / h)
        if n_psi and 0 < i < len(tableau.nodes) - 1:  # Lobatto: an interior node
            Lam = [node_symbol(r"\Lambda", s, i + 1, None if n_psi == 1 else str(c + 1))
                   for c in range(n_psi)]
            for lam, value in zip(Lam, (next(interior_multipliers) for _ in range(n_psi))):
                layer[lam] = value
                definitions.append(Definition(lam, value, frozenset({lam})))
            pulled = constraint.pulled(Q[i], Lam)
            for r in range(n):
                towards[r] += weight_q * pulled[r]
                for j in range(1, M):
                    stages[j - 1][r] += values[j] * pulled[r]
            held.extend(constraint.at(Q[i]))
    if n_psi and s == 1:  # λ_{k+1}, at the source q_k of g_{k+1} (§15)
        pulled = constraint.pulled(list(source), multiplier_symbols(n_psi, 1))
        towards = [t + p for t, p in zip(towards, pulled)]
    for i, row in enumerate(a_matrix):  # the stage equations, after the velocities
        for r in range(n):
            terms = [a * V[j][r] for j, a in enumerate(row) if a != 0]
            rhs = (sp.Add(source[r], Collected(h, sp.Add(*terms, evaluate=False)),
                          evaluate=False) if terms else source[r])
            definitions.append(Definition(Q[i][r], rhs, frozenset({Q[i][r]}),
                                          as_written=True))
    definitions += forces
    return towards, [e for row in stages for e in row] + held


def _named_forces(F: list, s: int, i: int, names: list, layer: dict,
                  definitions: list) -> list:
    """The force at node i of g_{k+s} by name, F_{k+s,i} (``(F_{k,1})_{x}`` per coordinate),
    its value given in the "where" list as the papers give f± through it (Marsden–West
    §3.2; docs/conventions.md §22); a zero component stays 0."""
    named = []
    for r, value in enumerate(F):
        if value == 0:
            named.append(sp.S.Zero)
            continue
        symbol = node_symbol("F", s, i + 1, None if len(names) == 1 else names[r])
        layer[symbol] = value.xreplace(layer)  # in the step's coordinates, as Q's and V's
        definitions.append(Definition(symbol, value, frozenset({symbol})))
        named.append(symbol)
    return named


def _at_node(continuous, Q: list, V: list, u: dict) -> tuple[sp.Expr, list]:
    """L and the force F at the node symbols (per factor, as L takes them), the inputs of
    the arrow substituted."""
    q, v, at = [], [], 0
    for f in continuous.factors:
        q.append(sp.Matrix(Q[at:at + f.dim]))
        v.append(sp.Matrix(V[at:at + f.dim]))
        at += f.dim
    L = continuous._lagrangian_at(q, v)
    if continuous.forces is None:
        return L, [sp.S.Zero] * len(Q)
    F = continuous._force_at(q, v)
    return L, [e.xreplace(u) for e in F]


def stage_coefficients(nodes: tuple) -> list:
    """a_ij = ∫₀^{c_i} ℓ̃_j(τ) dτ, ℓ̃_j the Lagrange basis on the nodes (the collocation
    coefficients: Gauss, Lobatto IIIA)."""
    basis = _lagrange(list(nodes))
    return [[exact_number(sp.integrate(e, (_tau, 0, ci))) for e in basis] for ci in nodes]


def exact_number(value: sp.Expr) -> sp.Expr:
    """A tableau's number in its exact simplest form (radicals rationalised); a Float as it is."""
    return value if value.has(sp.Float) else sp.radsimp(sp.expand(value))


__all__ = ["STAGE_LETTERS", "notation_clash", "stage_clash", "stage_form"]
