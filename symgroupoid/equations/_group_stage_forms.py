"""A Galerkin step on Lie-group factors printed in the stage notation (docs/conventions.md
§22, "The stage notation on a group factor"), checked at points of the group.

For the arrow g_j = (R_{j−1}, R_j) of a factor on a matrix Lie group with its retraction τ,
Cayley or exponential (Bogfjellmo–Marthinsen's partitioned Lie group scheme in the
retraction's chart),
the printed step is

    dτ_{Δ_k}^{−⊤} P_k + S_{k+1} − Ad_{τ(Δ_{k+1})⁻¹}^⊤ dτ_{Δ_{k+1}}^{−⊤} P_{k+1} = 0,
    h Σ_i b_i [ℓ_l(c_i) A_{j,i} + ℓ_l′(c_i) B_{j,i}/h] = 0   (stage l of g_j, j = k, k+1),

where Δ_j = τ⁻¹(R_{j−1}⁻¹R_j), the chart velocities V_{j,i} = (1/h)(d′_i Δ_j + Σ_l ℓ_l′(c_i)
ζ_{j,l}), the stage equations X_{j,i} = h Σ_m a_im V_{j,m}, the stage attitudes R_{j,i} =
R_{j−1}τ(X_{j,i}) and body velocities Ξ_{j,i} = dτ_{X_{j,i}}V_{j,i}; N and M are the
left-trivialised derivatives of L in the configuration and the body velocity, N_b =
⟨∂L/∂R, R E_b⟩ and M = ∂L/∂Ξ, at the nodes; A_{j,i} = dτ_{X_{j,i}}^⊤N_{j,i} +
(∂_X dτ_X V_{j,i})^⊤M_{j,i} and B_{j,i} = dτ_{X_{j,i}}^⊤M_{j,i} are ∂L̃/∂x and ∂L̃/∂v of the
chart Lagrangian; P_j = h Σ_i b_i (c_i A_{j,i} + B_{j,i}/h) and S_j = h Σ_i b_i
Ad_{τ(X_{j,i})⁻¹}^⊤N_{j,i}.  A Euclidean factor takes the same rows with τ(x) = q + x:
dτ = Ad = 1, ∂_X dτ_X = 0, A = N = ∂L/∂q, B = M = ∂L/∂v.

The rows hold on the group only, not in the free entries of the attitudes the residual is
written in, and the residuals are too large to expand; so this form is not checked by
expansion, as the printer's other forms are, but by evaluation: at :data:`CHECK_POINTS`
random points of the group (attitudes τ(x) of random x, random increments, stages and
parameters) every printed row, computed from its "where" list exactly as printed at
:data:`CHECK_DIGITS` digits, equals the step's residual (its program, evaluated at the same
precision, :func:`symgroupoid.ir.interpret_precise`) to within 10^−(CHECK_DIGITS − 15) of
the rows' size.  A derivation error changes a row by many orders more (leaving the term
(∂_X dτ_X V)^⊤M out changes it by more than 10⁻³); the identity holds exactly, so the
difference at the check's precision is its rounding (3–8·10⁻⁵¹ of the rows' size for the
heavy top at 50 digits).  With forces, the force F_{j,i} at each node (with the inputs
u_j of g_j) joins N_{j,i} in A_{j,i} and S_j.  A step the form does not match (holonomic
constraints, or any other difference) is not offered it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mpmath
import numpy as np
import sympy as sp

from .._sizes import ops_at_most
from .._symbols import latex_name, stage_symbols
from ..derivation import WindowAction, input_symbols
from ..ir import interpret_precise, precise_namespace, precise_number
from ._latex import MemoLatexPrinter
from ._layout import Definitions, PrintedRows, Row, Text, signed_terms
from ._stage_forms import exact_number, galerkin_origin, notation_clash, stage_coefficients

#: random points of the group at which the printed rows are compared with the residual
CHECK_POINTS = 3
#: decimal digits of that comparison; rows must agree to 10^−(CHECK_DIGITS − 15) of their size
CHECK_DIGITS = 50
_SEED = 20221127  # the check's points: the same printing on every run
#: where the system's own expressions hold floating-point numbers (L written with 0.5·k),
#: the printed rows and the step's program fold them with the rationals around them in
#: different places (0.5/3 rounded to a double in one, 0.5 and 1/3 kept apart in the other),
#: so the two agree to the doubles' precision only: they are compared to this fraction of
#: their size instead (a wrong form differs at the size of its terms)
FLOAT_TOLERANCE = 1e-12

#: the letters of the group stage notation's symbols (the module docstring; τ the
#: retraction), which no name of the system may read as
GROUP_LETTERS = ("X", "V", "A", "B", "N", "M", "P", "S", "F", r"\Delta", r"\Xi", r"\tau",
                 r"\zeta")

#: the letters a rule's group form prints (no B, F, Ξ or ζ: L is read at V itself, forces
#: on a group are refused for rules, and a rule has no interior stage)
RULE_LETTERS = ("X", "V", "A", "N", "M", "P", "S", r"\Delta", r"\tau")

_LABELS = {0: ("k", "k-1"), 1: ("k+1", "k")}
_GENERIC = ("j", "j-1")


def _nc(name: str) -> sp.Symbol:
    """A printed vector, matrix or operator: a non-commutative symbol named by its LaTeX, so
    that products keep their order."""
    return sp.Symbol(name, commutative=False)


@dataclass
class _Factor:
    """One factor of the configuration space: its printed names and, on a group, its
    retraction's maps at numbers (mpmath)."""

    f: object
    tag: str  # "" (one factor) or "^{(R)}"
    name: str  # the LaTeX of the configuration: R, or q (a Euclidean factor's vector)
    maps: dict = field(default_factory=dict)

    @property
    def is_group(self) -> bool:
        return self.f.is_group

    def sym(self, base: str, j: str, i: int | None = None) -> sp.Symbol:
        """``base^{tag}_{j,i}``."""
        sub = j if i is None else f"{j},{i}"
        return _nc(f"{base}{self.tag}_{{{sub}}}")

    def config(self, j: str, i: int | None = None) -> sp.Symbol:
        return _nc(_subscripted(self.name, j if i is None else f"{j},{i}"))


def _subscripted(base: str, sub: str) -> str:
    """``base_{sub}``, the base parenthesised when it has a subscript or superscript."""
    return f"({base})_{{{sub}}}" if "_" in base or "^" in base else f"{base}_{{{sub}}}"


def _factors(continuous) -> list[_Factor]:
    several = len(continuous.factors) > 1
    out = []
    for f in continuous.factors:
        if f.is_group:
            name = label = latex_name(f.space.symbol_name)
        else:  # a point of R^n, named by its coordinates: x, or q^{(x, y)} in a product
            names = [latex_name(n) for n in f.space.names]
            label = ", ".join(names)
            name = names[0] if len(names) == 1 else r"\mathbf{q}"
            if several and len(names) > 1:
                name = rf"\mathbf{{q}}^{{({label})}}"
        tag = f"^{{({label})}}" if several else ""
        out.append(_Factor(f, tag, name))
    return out


# --- the printed form ---------------------------------------------------------------------

@dataclass
class _Notation:
    """The printed rows (at k, k+1), the "where" rows of one arrow g_j (generic j, and at
    j = k, k+1 for the check), the operators' rules and the formulas of N and M."""

    rows: list = field(default_factory=list)  # vector expressions, 0 = row
    generic: list = field(default_factory=list)  # (lhs, rhs) at j, printed
    concrete: list = field(default_factory=list)  # (lhs, rhs) at k and k + 1, checked
    operators: dict = field(default_factory=dict)  # symbol -> (rule name, factor, args)
    formulas: list = field(default_factory=list)  # (factor index, N, M): formulas in L
    node_values: dict = field(default_factory=dict)  # N, M, F at a node -> (kind, f, j, i)
    dims: dict = field(default_factory=dict)  # a vector written 0 (X at c = 0) -> its size
    forces: list = field(default_factory=list)  # per factor: the force's formula (forced)
    kinds: dict = field(default_factory=dict)  # A, B -> "chart"; P -> "P"; S -> "S"


class _Builder:
    """Builds :class:`_Notation` for one continuous system and tableau."""

    def __init__(self, continuous, tableau, h, rule: bool = False):
        self.c, self.t, self.h, self.rule = continuous, tableau, h, rule
        self.factors = _factors(continuous)
        self.M = len(tableau.control) - 1
        self.a = stage_coefficients(tableau.nodes)
        self.out = _Notation()

    # operators, each a symbol with the rule that gives its value
    def op(self, name: str, rule: str, fi: int, *args: sp.Symbol) -> sp.Expr:
        if not self.factors[fi].is_group:
            return sp.S.One
        s = _nc(name)
        self.out.operators[s] = (rule, fi, args)
        return s

    def tau(self, fi, x):
        return self.op(rf"\tau({sp.latex(x)})", "tau", fi, x)

    def dtau_t(self, fi, x):
        return self.op(rf"\mathrm{{d}}\tau_{{{sp.latex(x)}}}^{{T}}", "dtau_t", fi, x)

    def dtau(self, fi, x):
        return self.op(rf"\mathrm{{d}}\tau_{{{sp.latex(x)}}}", "dtau", fi, x)

    def dtau_inv_t(self, fi, x):
        return self.op(rf"\mathrm{{d}}\tau_{{{sp.latex(x)}}}^{{-T}}", "dtau_inv_t", fi, x)

    def ad_inv_t(self, fi, x):
        return self.op(rf"\mathrm{{Ad}}_{{\tau({sp.latex(x)})^{{-1}}}}^{{T}}", "ad_inv_t",
                       fi, x)

    def curvature_t(self, fi, x, v):
        return self.op(rf"\left(\partial_{{X}} \mathrm{{d}}\tau_{{{sp.latex(x)}}}"
                       rf" {sp.latex(v)}\right)^{{T}}", "curvature_t", fi, x, v)

    def arrow(self, j: str, jp: str, defs: list, zeta: list | None) -> dict:
        """The "where" rows of the arrow g_j into ``defs`` — first every factor's curve (all
        configurations at the nodes, which N and M of each factor read), then the
        derivatives — and per factor its P_j, S_j and stage rows."""
        out: dict = {"P": [], "S": [], "stages": [[None] * len(self.factors)
                                                  for _ in range(self.M - 1)]}
        n_all, at, curves = sum(f.f.dim for f in self.factors), 0, []
        for fi, F in enumerate(self.factors):
            curves.append(self.curve(fi, j, jp, defs, zeta, at, n_all))
            at += F.f.dim
        for fi, (X, V) in enumerate(curves):
            self.derivatives(fi, j, X, V, defs, out)
        return out

    def curve(self, fi: int, j: str, jp: str, defs: list, zeta, at: int, n_all: int):
        """Δ_j, the stage vectors, and at the nodes V, X, the configuration (and Ξ)."""
        F, t, h, M = self.factors[fi], self.t, self.h, self.M
        dim, delta = F.f.dim, F.sym(r"\Delta", j)
        if F.is_group:
            rel = _nc(rf"{F.config(jp).name}^{{-1}} {F.config(j).name}")
            self.out.operators[rel] = ("relative", fi, (F.config(jp), F.config(j)))
            defs.append((delta, self.op(rf"\tau^{{-1}}({sp.latex(rel)})", "tau_inverse",
                                        fi, rel)))
        else:
            defs.append((delta, F.config(j) - F.config(jp)))
        stage_vectors = []
        for m in range(1, M):
            z = F.sym(r"\zeta", j) if M == 2 else F.sym(r"\zeta", j, m)
            offset = (m - 1) * n_all + at
            entries = [_stage_name(j, offset + c + 1) for c in range(dim)] \
                if zeta is None else zeta[offset:offset + dim]
            defs.append((z, sp.ImmutableMatrix(entries)))
            stage_vectors.append(z)
        V = [F.sym("V", j, i) for i in range(1, len(t.nodes) + 1)]
        X = [F.sym("X", j, i) for i in range(1, len(t.nodes) + 1)]
        for v, slopes in zip(V, t.slopes):
            d = exact_number(sum((s * c for s, c in zip(slopes, t.control)), sp.S.Zero))
            defs.append((v, (d * delta + sp.Add(*[exact_number(slopes[m]) * z for m, z in
                                                  zip(range(1, M), stage_vectors)])) / h))
        for x, row in zip(X, self.a):
            terms = [a * v for a, v in zip(row, V) if a != 0]
            defs.append((x, h * sp.Add(*terms) if terms else sp.S.Zero))
            self.out.dims[x] = dim
        for i, (x, v) in enumerate(zip(X, V), start=1):
            if F.is_group:
                defs.append((F.config(j, i), F.config(jp) * self.tau(fi, x)))
                if not self.rule:  # (a rule reads L at the chart velocity itself: Ξ = V)
                    defs.append((F.sym(r"\Xi", j, i), self.dtau(fi, x) * v))
            else:
                defs.append((F.config(j, i), F.config(jp) + x))
        return X, V

    def derivatives(self, fi: int, j: str, X: list, V: list, defs: list, out: dict) -> None:
        """A and B (group factors) at the nodes, P_j, S_j and the stage rows."""
        F, t, h = self.factors[fi], self.t, self.h
        A, B, N = [], [], []
        for i, (x, v) in enumerate(zip(X, V), start=1):
            Ni, Mi = F.sym("N", j, i), F.sym("M", j, i)
            self.out.node_values[Ni] = ("N", fi, j, i)
            self.out.node_values[Mi] = ("M", fi, j, i)
            if self.c.forces is not None:  # the force at the node joins ∂L/∂q (§22)
                Fi = F.sym("F", j, i)
                self.out.node_values[Fi] = ("F", fi, j, i)
                Ni = Ni + Fi
            N.append(Ni)
            if F.is_group and self.rule:  # L̃(x, v) = L(R τ(x), v): no dτ on the velocity
                A.append(F.sym("A", j, i))
                B.append(Mi)
                self.out.kinds[A[-1]] = "chart"
                defs.append((A[-1], self.dtau_t(fi, x) * Ni))
            elif F.is_group:
                A.append(F.sym("A", j, i))
                B.append(F.sym("B", j, i))
                self.out.kinds[A[-1]] = self.out.kinds[B[-1]] = "chart"
                defs.append((A[-1], self.dtau_t(fi, x) * Ni + self.curvature_t(fi, x, v) * Mi))
                defs.append((B[-1], self.dtau_t(fi, x) * Mi))
            else:
                A.append(Ni)
                B.append(Mi)
        P, S = F.sym("P", j), F.sym("S", j)
        self.out.kinds[P], self.out.kinds[S] = "P", "S"
        w = [exact_number(b) for b in t.weights]
        defs.append((P, _expanded(h * sp.Add(*[
            b * (exact_number(c) * a + bb / h) for b, c, a, bb in zip(w, t.nodes, A, B)]))))
        defs.append((S, _expanded(h * sp.Add(*[b * self.ad_inv_t(fi, x) * n
                                               for b, x, n in zip(w, X, N)]))))
        out["P"].append(P)
        out["S"].append(S)
        for m in range(1, self.M):
            out["stages"][m - 1][fi] = _expanded(h * sp.Add(*[
                b * (exact_number(values[m]) * a + exact_number(slopes[m]) * bb / h)
                for b, values, slopes, a, bb in zip(w, t.values, t.slopes, A, B)]))

    def build(self, zetas: dict) -> _Notation:
        """The rows at k, k + 1 (and their "where" rows); the generic rows at j."""
        self.arrow(*_GENERIC, self.out.generic, None)
        parts = {s: self.arrow(*_LABELS[s], self.out.concrete, zetas[s]) for s in (0, 1)}
        for fi, _ in enumerate(self.factors):
            d0, d1 = (self.factors[fi].sym(r"\Delta", _LABELS[s][0]) for s in (0, 1))
            self.out.rows.append(self.dtau_inv_t(fi, d0) * parts[0]["P"][fi]
                                 + parts[1]["S"][fi]
                                 - self.ad_inv_t(fi, d1) * self.dtau_inv_t(fi, d1)
                                 * parts[1]["P"][fi])
        for s in (0, 1):
            for per_factor in parts[s]["stages"]:
                self.out.rows.extend(per_factor)
        self.formulas()
        return self.out

    def formulas(self) -> None:
        """N and M of every factor as formulas of generic configurations and velocities."""
        q, v, flat = [], [], []
        for F in self.factors:
            if F.is_group:
                G = F.f.space
                entries = [sp.Symbol(_subscripted(F.name, f"{r + 1}{c + 1}"), real=True)
                           for r, c in G.free_entries]
                q.append(G.matrix(entries))
                letter = "V" if self.rule else r"\Xi"  # (a rule reads L at V itself)
                vel = [sp.Symbol(rf"{letter}{F.tag}_{{{a + 1}}}", real=True)
                       for a in range(F.f.dim)]
            else:
                names = [latex_name(n) for n in F.f.space.names]
                entries = [sp.Symbol(n, real=True) for n in names]
                q.append(sp.Matrix(entries))
                vel = [sp.Symbol(rf"\dot{{{n}}}", real=True) for n in names]
            v.append(sp.Matrix(vel))
            flat.append((entries, vel))
        L = self.c._lagrangian_at(q, v)
        self.generic_configuration = flat
        for fi, (F, (entries, vel)) in enumerate(zip(self.factors, flat)):
            if F.is_group:
                G = F.f.space
                grad = {e: sp.diff(L, e) for e in entries}
                N = [sum((grad[e] * (q[fi] * E)[r, c] for e, (r, c) in
                          zip(entries, G.free_entries)), sp.S.Zero)
                     for E in G.basis_matrices()]
            else:
                N = [sp.diff(L, e) for e in entries]
            Mv = [sp.diff(L, e) for e in vel]
            self.out.formulas.append((fi, sp.ImmutableMatrix([_tidy(e) for e in N]),
                                      sp.ImmutableMatrix([_tidy(e) for e in Mv])))
        if self.c.forces is not None:
            force = self.c._force_at(q, v)
            at = 0
            for F in self.factors:
                self.out.forces.append(sp.ImmutableMatrix(
                    [_tidy(e) for e in force[at:at + F.f.dim]]))
                at += F.f.dim


def _stage_name(j: str, a: int) -> sp.Symbol:
    return sp.Symbol(rf"(\zeta_{{{j}}})_{{{a}}}")


def _expanded(e: sp.Expr) -> sp.Expr:
    """A weighted sum of printed vectors with each coefficient collected and simplified."""
    terms: dict = {}
    for term in sp.expand(e).as_ordered_terms():
        scalar, vector = term.args_cnc()
        key = sp.Mul(*vector)
        terms[key] = terms.get(key, sp.S.Zero) + sp.Mul(*scalar)
    return sp.Add(*[sp.factor_terms(sp.radsimp(c)) * v for v, c in terms.items()])


def _tidy(e: sp.Expr) -> sp.Expr:
    return sp.factor_terms(sp.expand(e)) if ops_at_most(e, 399) else e


# --- the check ------------------------------------------------------------------------------

class _Evaluator:
    """The printed notation at a point: every "where" row computed as printed, operators by
    the group's maps, N and M by their printed formulas."""

    def __init__(self, builder: _Builder, notation: _Notation, values: dict):
        self.b, self.n, self.table = builder, notation, dict(values)
        self._formulas = {}
        args = [s for entries, vel in builder.generic_configuration for s in (*entries, *vel)]
        params = list(builder.c.parameters)
        inputs = list(builder.c.inputs)
        for fi, N, Mv in notation.formulas:
            self._formulas[("N", fi)] = sp.lambdify([args, params, inputs], N, "mpmath")
            self._formulas[("M", fi)] = sp.lambdify([args, params, inputs], Mv, "mpmath")
        for fi, force in enumerate(notation.forces):
            self._formulas[("F", fi)] = sp.lambdify([args, params, inputs], force, "mpmath")
        self.params = [self.table[p] for p in params]
        self.inputs = {label: [self.table[u] for u in input_symbols(inputs, s)]
                       for s, (label, _) in _LABELS.items()}

    def value(self, e):
        if isinstance(e, sp.MatrixBase):
            return mpmath.matrix([[self.value(c) for c in row] for row in e.tolist()])
        if e in self.table:
            return self.table[e]
        if e.is_number:
            return precise_number(e, CHECK_DIGITS + 10)
        if e in self.n.operators:
            out = self.table[e] = self.operator(*self.n.operators[e])
            return out
        if e in self.n.node_values:
            out = self.table[e] = self.node(*self.n.node_values[e])
            return out
        if isinstance(e, sp.Add):
            total = self.value(e.args[0])
            for a in e.args[1:]:
                total = total + self.value(a)
            return total
        if isinstance(e, sp.Mul):
            product = self.value(e.args[0])
            for a in e.args[1:]:
                product = product * self.value(a)
            return product
        if isinstance(e, sp.Pow) and e.exp.is_Integer:
            return self.value(e.base) ** int(e.exp)
        raise KeyError(e)

    def operator(self, rule: str, fi: int, args: tuple):
        maps = self.b.factors[fi].maps
        x = [self.value(a) for a in args]
        if rule == "relative":
            return maps["inverse"](_flat(x[0])) * x[1]
        return maps[rule](*[_flat(a) for a in x])

    def node(self, kind: str, fi: int, j: str, i: int):
        flat = []
        for F in self.b.factors:
            q = self.value(F.config(j, i))
            if F.is_group:
                flat += [q[r, c] for r, c in F.f.space.free_entries]
                flat += _flat(self.value(F.sym("V" if self.b.rule else r"\Xi", j, i)))
            else:
                flat += _flat(q)
                flat += _flat(self.value(F.sym("V", j, i)))
        return mpmath.matrix(self._formulas[(kind, fi)](flat, self.params, self.inputs[j]))

    def define(self, rows: list) -> None:
        for lhs, rhs in rows:
            value = self.value(rhs)
            if lhs in self.n.dims and not isinstance(value, mpmath.matrix):
                value = mpmath.matrix(self.n.dims[lhs], 1)  # X_{j,1} = 0 at c₁ = 0
            self.table[lhs] = value


def _flat(m) -> list:
    """The entries of a matrix (row-major) or a vector."""
    if isinstance(m, mpmath.matrix):
        return [m[r, c] for r in range(m.rows) for c in range(m.cols)]
    return list(m)


def _group_maps(F: _Factor) -> None:
    """The retraction's maps of a group factor at mpmath numbers (a smooth function of the
    exponential map's at its closed form, :func:`~symgroupoid.ir.precise_namespace`)."""
    if not F.is_group or F.maps:
        return
    G = F.f.space
    x, w = sp.symbols(f"x0:{G.rank}"), sp.symbols(f"w0:{G.rank}")
    M = sp.Matrix(G.n, G.n, sp.symbols(f"m0:{G.n * G.n}"))
    T = G.tau(list(x))
    Ti = G.matrix(G.inverse(G.entries(T)))
    ad = sp.Matrix.hstack(*[G.vee(Ti * E * T) for E in G.basis_matrices()])
    dtau = G.dtau(list(x), "left")

    def made(expr, args):
        f = sp.lambdify(args, expr, [precise_namespace(expr), "mpmath"])
        return lambda *a: mpmath.matrix(f(*a))

    flat_M = list(M)
    F.maps.update({
        "tau": made(T, [x]), "dtau": made(dtau, [x]), "dtau_t": made(dtau.T, [x]),
        "dtau_inv_t": made(G.dtau_inverse(list(x), "left").T, [x]),
        "ad_inv_t": made(ad.T, [x]),
        "curvature_t": made((dtau * sp.Matrix(w)).jacobian(x).T, [x, w]),
        "tau_inverse": made(sp.Matrix(G.retraction_inverse(M)), [flat_M]),
        "inverse": made(G.matrix(G.inverse(G.entries(M))), [flat_M]),
    })


def _point(builder: _Builder, step, arrows: dict, rng) -> tuple[dict, dict]:
    """A random point: values of the step's inputs (knowns, unknowns, parameters) and of the
    printed names at the arrows' ends (R_{k−1}, R_k, R_{k+1}, ...)."""
    values: dict = {}
    names: dict = {}
    for p in step.parameters:
        values[p] = mpmath.mpf(rng.uniform(0.5, 1.5)) / (10 if p == builder.h else 1)
    for u in step.unknowns:
        values[u] = mpmath.mpf(rng.uniform(-0.3, 0.3))
    for z in stage_symbols(len(step.unknowns), 0):
        values.setdefault(z, mpmath.mpf(rng.uniform(-0.05, 0.05)))
    for s in (0, 1):  # the inputs of g_k and g_{k+1} (a forced system)
        for u in input_symbols(builder.c.inputs, s):
            values[u] = mpmath.mpf(rng.uniform(-1, 1))
    pairs0, pairs1 = arrows[0], arrows[1]
    for F, (a0, b0), (_, b1) in zip(builder.factors, pairs0, pairs1):
        G = F.f.space
        if F.is_group:
            start = F.maps["tau"]([mpmath.mpf(rng.uniform(-0.8, 0.8)) for _ in range(G.rank)])
            end = start * F.maps["tau"]([mpmath.mpf(rng.uniform(-0.3, 0.3))
                                         for _ in range(G.rank)])
        else:
            start = mpmath.matrix([mpmath.mpf(rng.uniform(-1, 1)) for _ in range(F.f.dim)])
            end = start + mpmath.matrix([mpmath.mpf(rng.uniform(-0.3, 0.3))
                                         for _ in range(F.f.dim)])
        for symbolic, numeric in ((sp.Matrix(a0), start), (sp.Matrix(b0), end)):
            for r in range(symbolic.rows):
                for c in range(symbolic.cols):
                    if isinstance(symbolic[r, c], sp.Symbol):
                        values[symbolic[r, c]] = numeric[r, c]
        names[F.config("k-1")], names[F.config("k")] = start, end
        names[F.config("k+1")] = _reconstructed(step, b1, values)
    return values, names


def _reconstructed(step, target: sp.Matrix, values: dict):
    """The new arrow's target at the point: its entries (fibre variables) through the step's
    chart, ``step.reconstruction``, at ``values``."""
    target = sp.Matrix(target)
    exprs = sp.Matrix(target.rows, target.cols,
                      [sp.sympify(step.reconstruction.get(e, e)) for e in target])
    inputs = sorted(exprs.free_symbols, key=str)
    f = sp.lambdify([inputs], exprs, [precise_namespace(exprs), "mpmath"])
    return mpmath.matrix(f([values[s] for s in inputs]))


def _holds(builder: _Builder, notation: _Notation, step, arrows: dict) -> bool:
    """The printed rows equal the residual at :data:`CHECK_POINTS` random points of the
    group, to 10^−(CHECK_DIGITS − 15) of their size (:data:`FLOAT_TOLERANCE` where they
    hold doubles)."""
    for F in builder.factors:
        _group_maps(F)
    rng = np.random.default_rng(_SEED)
    program = step.program
    tolerance = (FLOAT_TOLERANCE if _double_floats(notation)
                 else mpmath.mpf(10) ** (15 - CHECK_DIGITS))
    with mpmath.workdps(CHECK_DIGITS):
        for _ in range(CHECK_POINTS):
            values, names = _point(builder, step, arrows, rng)
            ev = _Evaluator(builder, notation, {**values, **names})
            ev.define(notation.concrete)
            printed = [c for row in notation.rows for c in ev.value(row)]
            residual = interpret_precise(program, ["F"], values, CHECK_DIGITS)["F"]
            if len(printed) != len(residual):
                return False
            size = 1 + max(abs(x) for x in [*printed, *residual])
            worst = max(abs(a - b) for a, b in zip(printed, residual))
            if not worst <= size * tolerance:
                return False
    return True


def _double_floats(notation: _Notation) -> bool:
    """Whether the printed rows or their formulas hold a floating-point number of double
    precision (a user's 0.5; the tableau's nodes have 40 digits)."""
    exprs = [*notation.rows, *(rhs for _, rhs in notation.concrete), *notation.forces,
             *(e for _, N, M in notation.formulas for e in (N, M))]
    return any(f._prec <= 53 for e in exprs for f in sp.sympify(e).atoms(sp.Float))


# --- the face -------------------------------------------------------------------------------

@dataclass
class GroupStageForm:
    """A step's group stage notation, checked (:func:`group_stage_form`): printed at any
    width by :meth:`rows` without checking it again."""

    builder: _Builder
    notation: _Notation

    def rows(self, width: float, printer=None) -> PrintedRows:
        """The rows and "where" list laid out for a page ``width`` pt wide; ``printer``
        (default: a :class:`~._latex.MemoLatexPrinter`) prints the terms."""
        return _printed(self.builder, self.notation, width, printer or MemoLatexPrinter())


def group_stage_form(step) -> GroupStageForm | None:
    """The step in the group stage notation (see the module docstring), checked at points of
    the group, or None when it does not apply or does not hold: a Galerkin step, or a rule's
    (:func:`group_rule_form`)."""
    origin = galerkin_origin(step)
    if origin is None:
        return group_rule_form(step)
    return _checked_form(step, origin, origin.scheme.tableau(), rule=False)


#: the Galerkin tableau whose nodes and weights a rule on a group factor reads L at
_RULE_TABLEAUX = {"midpoint": ("GaussLegendre", 1), "trapezoid": ("LobattoIIIAB", 2)}


def group_rule_form(step) -> GroupStageForm | None:
    """The midpoint or trapezoid rule on Lie-group factors (docs/conventions.md §21) in the
    group stage notation, checked at points of the group as :func:`group_stage_form`, or
    None.  The rule reads L at the chart velocity itself, L̃(x, v) = L(R τ(x), v) (no
    dτ_X on the velocity: Ξ = V = Δ/h), at the nodes of the one-stage Gauss–Legendre
    (midpoint, X = Δ/2) or two-stage Lobatto (trapezoid, X = 0 and Δ) tableau, with no
    interior stages: A_{j,i} = dτ_{X_{j,i}}^⊤N_{j,i} and B_{j,i} = M_{j,i} in P_j and S_j.
    The form a rule's step on a group prints in: written out, its Cayley quotients run to
    10⁶ operations (a free body on SE(3)) or take more than minutes to check (a pendulum on
    SO(2))."""
    origin = getattr(getattr(step, "system", None), "continuous", None)
    if origin is None or origin.rule not in _RULE_TABLEAUX:
        return None
    from . import _continuous

    family, stages = _RULE_TABLEAUX[origin.rule]
    tableau = getattr(_continuous, family)(stages).tableau()
    return _checked_form(step, origin, tableau, rule=True)


def group_rule_refusal(step) -> str | None:
    """Why a rule's step on a group factor is not offered its group form before the check
    (holonomic constraints, names that read as its letters, :data:`RULE_LETTERS`), or None.
    Written out, such a step takes too long to print and check (a pendulum on SO(2) did not
    finish in 400 s), so it is refused at once with this reason."""
    origin = getattr(getattr(step, "system", None), "continuous", None)
    if origin is None or origin.rule not in _RULE_TABLEAUX:
        return None
    continuous = origin.system
    if not any(f.is_group for f in continuous.factors):
        return None
    if continuous.holonomic is not None:
        return "it has holonomic constraints, which the notation does not print"
    clash = notation_clash(continuous, RULE_LETTERS)
    if clash:
        return (f"the system's names {', '.join(clash)} read as its symbols: rename them "
                f"(e.g. a mass m, a group named R)")
    return None


def _checked_form(step, origin, tableau, rule: bool) -> GroupStageForm | None:
    """The notation of ``step`` from ``origin`` (its discretisation) with ``tableau``, if it
    applies (a group factor, no holonomic constraint, no clash of names) and holds at the
    check's points of the group."""
    from ..groupoids import pair_groupoid_of

    system, continuous = step.system, origin.system
    if not any(f.is_group for f in continuous.factors) or continuous.holonomic is not None:
        return None
    if notation_clash(continuous, RULE_LETTERS if rule else GROUP_LETTERS):
        return None
    builder = _Builder(continuous, tableau, origin.step, rule)
    n_stage = tableau.interior * sum(f.dim for f in continuous.factors)
    zetas = {s: stage_symbols(n_stage, s) for s in (0, 1)}
    notation = builder.build(zetas)
    action = WindowAction(step.groupoid, system.functions)
    named = action.named_arrows()
    _, read = pair_groupoid_of(continuous.Q, continuous.factors, continuous.product)
    arrows = {s: read(step.groupoid.view(named[start]))
              for s, start in enumerate(action.starts)}
    if not _holds(builder, notation, step, arrows):
        return None
    return GroupStageForm(builder, notation)


def group_stage_rows(step, width: float, printer=None) -> PrintedRows | None:
    """:func:`group_stage_form` laid out for a page ``width`` pt wide, or None."""
    form = group_stage_form(step)
    return None if form is None else form.rows(width, printer)


#: characters of LaTeX above which the formulas of N and M are described, not written out
#: (a chain's L couples every body: its derivatives run to pages)
FORMULA_LIMIT = 1200


def _printed(builder: _Builder, notation: _Notation, width: float, printer) -> PrintedRows:
    items: list = [Row("0", signed_terms(row, printer)) for row in notation.rows]
    pairs = []
    for fi, N, Mv in notation.formulas:
        F = builder.factors[fi]
        pairs.append((_nc(f"N{F.tag}"), _shown(N), True))
        pairs.append((_nc(f"M{F.tag}"), _shown(Mv), True))
        if notation.forces:
            pairs.append((_nc(f"F{F.tag}"), _shown(notation.forces[fi]), True))
    written = sum(len(printer.doprint(rhs)) for _, rhs, _ in pairs) <= FORMULA_LIMIT
    items.append(Text(
        r"where, for $j = k, k+1$ and the nodes $i$, with "
        + (r"$\zeta_{j}$ the internal stages of the arrow ending at $j$ (unknowns of the step), "
           if builder.t.interior else "")
        + r"$\tau$ " + _retraction_words(builder)
        + ", "
        r"$\mathrm{d}\tau_X$ its left-trivialised derivative and $\mathrm{Ad}$ the adjoint "
        r"action, " + _node_words(builder, printer, written)))
    groups: dict = {}
    for lhs, rhs in notation.generic:
        groups.setdefault(notation.kinds.get(lhs, "curve"), []).append((lhs, _shown(rhs), True))
    for kind, words in (("curve", None), ("chart", "the derivatives of the chart Lagrangian,"),
                        ("P", "and the sums"), ("S", None)):
        if kind in groups:
            if words:
                items.append(Text(words))
            items.append(Definitions(groups[kind], packed=kind in ("curve", "chart")))
    if written:
        items.append(Text("and"))
        items.append(Definitions(pairs))
    return PrintedRows(items, width, printer)


_RETRACTIONS = {"cayley": "the Cayley map", "exp": "the exponential map"}


def _retraction_words(builder: _Builder) -> str:
    """The retraction τ of the group factors, in words."""
    used = {F.f.space.retraction for F in builder.factors if F.is_group}
    if len(used) == 1:
        return _RETRACTIONS.get(next(iter(used)), f"the retraction {next(iter(used))}")
    return "each group's retraction (" + ", ".join(
        f"{_RETRACTIONS.get(F.f.space.retraction, F.f.space.retraction)} on "
        f"${F.name}$" for F in builder.factors if F.is_group) + ")"


def _shown(rhs):
    """A 1 × 1 matrix printed as its entry."""
    return rhs[0, 0] if isinstance(rhs, sp.MatrixBase) and rhs.shape == (1, 1) else rhs


def _node_words(builder: _Builder, printer, written: bool) -> str:
    """What N_{j,i} and M_{j,i} are: the derivatives of L at node i of g_j."""
    one = builder.factors[0]
    at = ", ".join(printer.doprint(F.config("j", "i")) + ", " + printer.doprint(
        F.sym(r"\Xi", "j", "i") if F.is_group and not builder.rule else F.sym("V", "j", "i"))
        for F in builder.factors)
    names = (f"${printer.doprint(one.sym('N', 'j', 'i'))}$ and "
             f"${printer.doprint(one.sym('M', 'j', 'i'))}$" if len(builder.factors) == 1
             else "$N^{(\\cdot)}_{j,i}$ and $M^{(\\cdot)}_{j,i}$ of each factor")
    which = "$N$ and $M$" if len(builder.factors) == 1 else r"$N^{(\cdot)}$ and $M^{(\cdot)}$"
    inputs = ""
    if builder.c.forces is not None:  # the force at the node, with the inputs of g_j
        names = names.replace(" and ", ", ", 1) + (
            f" and ${printer.doprint(one.sym('F', 'j', 'i'))}$" if len(builder.factors) == 1
            else r" and $F^{(\cdot)}_{j,i}$")
        which = which.replace(" and ", ", ", 1) + (
            " and $F$" if len(builder.factors) == 1 else r" and $F^{(\cdot)}$")
        listed = ", ".join(printer.doprint(u) for u in builder.c.inputs)
        inputs = (f", and the force, with the inputs (${listed}$ in its formula) at their "
                  f"values on $g_j$" if listed else ", and the force")
    group = next(F.name for F in builder.factors if F.is_group)
    words = (r"and, at the nodes, the derivatives of $L$ in the configuration "
             r"(left-trivialised on a group: $N_b = \langle \partial L/\partial " + group
             + ", " + group + r" E_b \rangle$) and in the velocity" + inputs + ": " + names
             + f" are {which} at (${at}$)")
    if written:
        return words + " (below),"
    return words + (r" (their formulas for this $L$ are too long to print usefully and are "
                    r"left out),")


__all__ = ["CHECK_DIGITS", "CHECK_POINTS", "FORMULA_LIMIT", "GROUP_LETTERS", "GroupStageForm",
           "RULE_LETTERS", "group_rule_form", "group_rule_refusal", "group_stage_form",
           "group_stage_rows"]
