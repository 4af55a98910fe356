"""Readable printed equations: named pieces, collected terms, a "where" list — each verified.

The residual of a step is the junction variation of the window action (seed 000 Thm 2.13;
docs/conventions.md §2): on the pair groupoid Q × Q, D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}).
The papers print it with named pieces rather than expanded.  For a discrete Lagrangian
written with midpoints and difference quotients (L_d = h·L(q̄, Δq)), the arrow
g_j = (q_{j−1}, q_j) is written as

    q_{j−1} = q̄_{j−1/2} − (h/2) Δq_{j−1/2},    q_j = q̄_{j−1/2} + (h/2) Δq_{j−1/2},

*before* the variation is substituted into the named arrows, so the derivative of L comes out
in q̄_{k∓1/2} and Δq_{k∓1/2} (the rule, and which parameter divides the differences, is
chosen as the one in which L and the constraints are shortest).  A second form names the
partial derivatives of L(q̄, Δq) themselves: the step reads ½(∂_q̄L_{k−1/2} + ∂_q̄L_{k+1/2})
− (∂_ΔqL_{k+1/2} − ∂_ΔqL_{k−1/2})/h = 0 and the "where" list gives each partial once.
Matrix parts (tr(g_k E_i E_j), W_kᵀΓ_k) and Ad*_{g_k} keep their names; what would print
with the numbers of a constant matrix (an entry (E_a)_{ij}, an entry of a product with one, a
trace with an explicit matrix) is evaluated, and a matrix form with no matrix left to name is
not offered (the explicit residuals print alike).  User abbreviations
(``abbreviations={name: expression or callable of an arrow}``) are recognised next, then the
terms are collected by multipliers and parameters, and the rows broken to the page width
(:mod:`._layout`).

Every printed equation — the pieces and abbreviations written out, matrices and named
operators by their values — is checked to equal the explicit residual (the expanded
difference is 0), and so is every "where" row; a form that fails is not printed.  The
explicit residuals always pass.  Of the verified forms, the shortest one that keeps a matrix
by name is printed when it is not longer than ``sympy.latex`` of the residuals, else the
shortest in total (equations and "where" list); the choice is remembered for the step.
Breaking a row into lines is checked too (:func:`._layout.same_sum`).

Nothing here runs unless LaTeX is asked for.
"""

from __future__ import annotations

import dataclasses
import warnings
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp
from sympy.matrices.expressions.matexpr import MatrixElement
from sympy.printing.conventions import split_super_sub

from .._errors import SymgroupoidError
from .._symbols import StepSymbol, latex_name, multiplier_symbols, step_label
from ..groupoids import PairCoordinate
from ._latex import (
    Collected,
    GroupoidLatexPrinter,
    LatexVerificationError,
    MemoLatexPrinter,
    NamedConstant,
    NamedOperator,
    latex,
    uncollected,
)
from ._layout import PAGE_WIDTH, Definitions, PrintedRows, Row, Term, Text

# --- names -------------------------------------------------------------------------------------


def indexed_name(base_latex: str, label: str) -> str:
    """``base`` with the subscript ``label``, parenthesised when ``base`` has one already
    (the convention of the step symbols: x_{k+1}, (θ_{1})_{k+1})."""
    if "_" in base_latex or "^" in base_latex:
        return f"({base_latex})_{{{label}}}"
    return f"{base_latex}_{{{label}}}"


def half_label(index: str, offset: int) -> str:
    """The subscript of the midpoint of the arrow g_{index+offset} = (q_{…−1}, q_{…}):
    ``k-1/2`` for offset 0, ``k+1/2`` for 1, ``k+3/2`` for 2."""
    twice = 2 * offset - 1
    return f"{index}{'+' if twice > 0 else '-'}{abs(twice)}/2"


def arrow_label(index: str, offset: int) -> str:
    """``k``, ``k+1``, ``j-1``: the subscript of a step index plus an offset."""
    return index if offset == 0 else f"{index}{offset:+d}"


def accented(name: str, accent: str) -> str:
    """LaTeX of a coordinate name with an accent on its root: ``theta1`` →
    ``\\bar{\\theta}_{1}``."""
    root, sups, subs = split_super_sub(name)
    tex = f"{accent}{{{latex_name(root)}}}"
    if sups:
        tex += "^{" + " ".join(latex_name(s) for s in sups) + "}"
    if subs:
        tex += "_{" + " ".join(latex_name(s) for s in subs) + "}"
    return tex


# --- pair coordinates and the rules that name their pieces --------------------------------------


def pair_coordinates(G) -> list[PairCoordinate]:
    """The pair-of-Euclidean-space coordinates of G's arrows (through products;
    ``G.pair_coordinates()``)."""
    return G.pair_coordinates()


@dataclass(frozen=True)
class PieceRule:
    """How a pair arrow (q₀, q₁) is written in named pieces, Δq = (q₁ − q₀)/τ:

    - ``midpoint``: q̄ = (q₀ + q₁)/2 and Δq; q₀ = q̄ − τΔq/2, q₁ = q̄ + τΔq/2;
    - ``source``: q₀ kept and Δq; q₁ = q₀ + τΔq;
    - ``target``: q₁ kept and Δq; q₀ = q₁ − τΔq.
    """

    kind: str
    tau: sp.Expr

    def coordinates(self, q0, q1, mid, diff) -> tuple:
        """(q₀, q₁) in the pieces."""
        if self.kind == "midpoint":
            return mid - self.tau * diff / 2, mid + self.tau * diff / 2
        if self.kind == "source":
            return q0, q0 + self.tau * diff
        return q1 - self.tau * diff, q1

    def definitions(self, q0, q1, mid, diff) -> list[tuple[sp.Expr, sp.Expr]]:
        """(piece, its value) pairs; the values are unevaluated, as printed."""
        difference = sp.Add(q1, sp.Mul(-1, q0, evaluate=False), evaluate=False)
        quotient = (difference if self.tau == 1 else
                    sp.Mul(difference, sp.Pow(self.tau, -1, evaluate=False), evaluate=False))
        rows = [(diff, quotient)]
        if self.kind == "midpoint":
            total = sp.Add(q0, q1, evaluate=False)
            rows.insert(0, (mid, sp.Mul(total, sp.Pow(sp.Integer(2), -1, evaluate=False),
                                        evaluate=False)))
        return rows


def piece_roots(coord: PairCoordinate) -> tuple[str, str]:
    """The LaTeX of q̄ and Δq of one coordinate, without index: ``\\bar{\\theta}_{1}``,
    ``\\Delta\\theta_{1}``."""
    return accented(coord.name, "\\bar"), f"\\Delta {latex_name(coord.name)}"


def piece_symbols(coord: PairCoordinate, label: str | None) -> tuple[StepSymbol, StepSymbol]:
    """q̄ and Δq of one coordinate at the subscript ``label`` (None: without index, the
    arguments of L(q̄, Δq) in the "where" rows of its partial derivatives)."""
    mid, diff = piece_roots(coord)
    if label is None:
        return StepSymbol(mid), StepSymbol(diff)
    return StepSymbol(indexed_name(mid, label)), StepSymbol(indexed_name(diff, label))


def _rule_score(fs, coords: Sequence[PairCoordinate], rule: PieceRule | None) -> int:
    """Operation count of L + Σφ with every slot written by ``rule`` (None: as given)."""
    expr = fs.lagrangian + sum(fs.constraints, sp.S.Zero)
    if rule is None:
        return sp.count_ops(expr)
    sub: dict = {}
    for s, slot in enumerate(fs.slots):
        for i, c in enumerate(coords):
            mid, diff = sp.Dummy(f"m{s}_{i}"), sp.Dummy(f"d{s}_{i}")
            sub[slot[c.source]], sub[slot[c.target]] = rule.coordinates(
                slot[c.source], slot[c.target], mid, diff)
    return sp.count_ops(expr.xreplace(sub))


def best_rule(fs, coords: Sequence[PairCoordinate], parameters: Sequence) -> PieceRule | None:
    """The rule in which L and the constraints are shortest, if shorter than as written:
    the pieces are those "L is written with"."""
    if not coords:
        return None
    best, score = None, _rule_score(fs, coords, None)
    for kind in ("midpoint", "source", "target"):
        for tau in [*parameters, sp.S.One]:
            rule = PieceRule(kind, tau)
            s = _rule_score(fs, coords, rule)
            if s < score:
                best, score = rule, s
    return best


# --- printed forms -------------------------------------------------------------------------------


@dataclass
class Definition:
    """A row of the "where" list: ``lhs`` (printed at a generic index j) = ``rhs``;
    ``names``: the symbols in the equations it defines."""

    lhs: sp.Expr
    rhs: sp.Expr
    names: frozenset
    literal: bool = True  # printed whole, several to a line (else collected and broken)
    as_written: bool = False  # terms in the order given (the pieces' definitions)
    intro: int = 0  # which of the form's intros (words before a group of rows) it follows
    abbreviation: str | None = None  # the user's abbreviation it defines (its LaTeX)


@dataclass
class Form:
    """The equations in named pieces, with what verification substitutes, layer by layer
    (abbreviations, then pieces, then matrices and operators), and the "where" list."""

    equations: list
    layers: list = field(default_factory=list)  # list of {symbol: value}
    definitions: list = field(default_factory=list)  # list of Definition
    intros: list = field(default_factory=lambda: ["where"])  # words before each group of rows
    generic: dict = field(default_factory=dict)  # symbol at index j → the same at k (checks)
    unindexed: bool = False  # "where" rows in pieces without index (L's partial derivatives)


def explicit_value(expr: sp.Expr, layers: Sequence[Mapping]) -> sp.Expr:
    """``expr`` with every layer substituted in order, named constants (J_d) by their
    values, matrices evaluated, expanded."""
    from ..groupoids import named_constants

    out = uncollected(sp.sympify(expr))
    for layer in layers:
        if layer:
            out = out.xreplace(dict(layer))
    return sp.expand(out.xreplace(named_constants(out)).doit())


def equals_explicit(printed: sp.Expr, explicit: sp.Expr, layers: Sequence[Mapping]) -> bool:
    """Whether the printed equation, written out, is exactly the explicit residual."""
    difference = sp.expand(explicit_value(printed, layers) - sp.expand(explicit))
    if difference == 0:
        return True
    return sp.cancel(sp.together(difference)) == 0


# --- the step's forms ----------------------------------------------------------------------------


def _junction_system(step):
    """The system whose step is the junction variation of L (+ λ·φ), if that is what
    ``step`` is; None otherwise (nonholonomic, reconstruction, …)."""
    from ._system import DiscreteSystem

    system = step.system
    if not isinstance(system, DiscreteSystem) or step.order != system._arity:
        return None
    return system


def matrix_values(step) -> dict:
    """MatrixSymbols of the step's matrix form → explicit matrices, its named constants (J_d)
    included (empty without one)."""
    from ..derivation._step import matrix_form_values, window
    from ..groupoids import named_constants

    if step.structured is None:
        return {}
    values = matrix_form_values(step.groupoid, window(step.order)[0])
    for e in step.structured:
        values.update(named_constants(e))
    return values


# --- constant matrix parts evaluated ------------------------------------------------------------


def constant_matrices(G) -> set:
    """The MatrixSymbols of G's matrix form that stand for constant matrices: the Lie-algebra
    basis E_a of each matrix part (the named constants, J_d, are known by their type,
    :func:`is_constant`)."""
    out: set = set()
    for _, group in G.matrix_parts():
        out.update(group.named_basis().values())
    return out


def is_constant(symbol, constants: set) -> bool:
    """Whether a MatrixSymbol stands for a constant matrix: one of ``constants``
    (:func:`constant_matrices`) or a named constant (J_d)."""
    from ..groupoids import is_constant_matrix

    return symbol in constants or is_constant_matrix(symbol)


def kept_by_name(atom, constants: set) -> bool:
    """Whether a matrix atom of the matrix form prints as the papers write it: an entry of a
    group matrix ((g_{k})_{12}), or the trace of a product of named matrices at least one of
    which is a group matrix (tr(g_k E_1 E_2), tr(J_d W_k E_1)).  Entries of constant matrices
    and of products ((E_1)_{23}, (W_k E_1)_{21}) and traces with an explicit matrix or of
    constants only are not: they are numbers, or sums of entries, when written out."""
    if isinstance(atom, MatrixElement):
        return isinstance(atom.parent, sp.MatrixSymbol) and not is_constant(atom.parent,
                                                                             constants)
    symbols = atom.arg.atoms(sp.MatrixSymbol)
    explicit = any(isinstance(a, sp.MatrixBase) for a in sp.preorder_traversal(atom.arg))
    return not explicit and any(not is_constant(s, constants) for s in symbols)


def evaluated_constants(expr: sp.Expr, values: Mapping, constants: set) -> sp.Expr:
    """``expr`` (in the matrix form) with every matrix atom that is not
    :func:`kept_by_name` written out through ``values`` and expanded, and the entries of
    group matrices as the step's symbols (they print alike): (E_1)_{11} (W_{k+1})_{12} is
    0, (W_k E_1)_{21} is −(W_k)_{31}, tr(E_1ᵀ W_k) is (W_k)_{32} − (W_k)_{23}."""
    from ..groupoids import to_explicit

    sub: dict = {}
    for atom in expr.atoms(MatrixElement, sp.Trace):
        if isinstance(atom, MatrixElement) and atom.parent in values and kept_by_name(
                atom, constants):
            sub[atom] = values[atom.parent][atom.i, atom.j]
        elif not kept_by_name(atom, constants):
            sub[atom] = to_explicit(atom, values)
    return sp.expand(expr.xreplace(sub)) if sub else expr


def keeps_matrices(equations: Sequence[sp.Expr]) -> bool:
    """Whether any of ``equations`` has a matrix by name (a trace, an operator)."""
    return any(sp.sympify(e).atoms(sp.MatrixSymbol) for e in equations)


def _matrix_form_keeps(step) -> bool:
    """Whether L or the constraints, evaluated in matrix form, keep a matrix by name (a
    trace :func:`kept_by_name`); if not, no derivative of them does (an entry varied along
    g E_a is an entry of a product), and the matrix form is not built for printing."""
    system = _junction_system(step)
    if system is None:
        return True
    try:
        fs = _system_functions(system, True)
    except _NOT_IN_PIECES:
        return False
    constants = constant_matrices(step.groupoid)
    return any(kept_by_name(t, constants)
               for e in [fs.lagrangian, *fs.constraints] for t in sp.sympify(e).atoms(sp.Trace))


#: each step's :func:`kept_matrix_form` (None too), built once
_KEPT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def kept_matrix_form(step) -> list | None:
    """The step's matrix form (:attr:`StepEquations.structured`) with its constant parts
    evaluated (:func:`evaluated_constants`), if it still keeps a matrix by name; else None
    (the explicit residuals are as short, and print alike)."""
    if step not in _KEPT:
        _KEPT[step] = _kept_matrix_form(step)
    return _KEPT[step]


def _kept_matrix_form(step) -> list | None:
    if not step.groupoid.matrix_parts() or not _matrix_form_keeps(step):
        return None
    structured = step.structured
    if structured is None:
        return None
    values, constants = matrix_values(step), constant_matrices(step.groupoid)
    equations = [evaluated_constants(e, values, constants) for e in structured]
    return equations if keeps_matrices(equations) else None


def base_form(step, matrix_form: bool = False) -> Form | None:
    """The residuals as derived: in matrix form, when it keeps a matrix by name (else None),
    or explicit."""
    if not matrix_form:
        return Form(list(step.residuals))
    structured = kept_matrix_form(step)
    return None if structured is None else Form(structured, [matrix_values(step)])


def _system_functions(system, matrix_form: bool):
    from ..derivation._step import evaluate_system

    if not matrix_form:
        return system.functions
    return evaluate_system(system.name, system.groupoid, system.lagrangian, system.constraints,
                           system.parameters, arity=system._arity, matrix_form=True)


@dataclass
class WindowPieces:
    """The window's variation with its pair arrows written in pieces: the rows (one per
    basis section, then the constraints on the newest arrow), the slots, and the
    substitution slot → named arrow (pair coordinates → pieces) with the pieces' values."""

    rows: list
    constraints: list
    slots: dict
    substitution: dict
    values: dict
    offsets: list


def window_in_pieces(step, rule: PieceRule, fs, matrix_form: bool,
                     lagrangian: bool = True) -> WindowPieces:
    """The junction variation of Σ_s [L + λ_s·φ](g_{k+s}) (``lagrangian=False``: of
    Σ_s λ_s·φ only) with each pair arrow written in the pieces of ``rule`` before the
    slots become the named arrows g_k, g_{k+1}, … (the window action of
    :class:`~symgroupoid.derivation.WindowAction`)."""
    from ..derivation import WindowAction

    G = step.groupoid
    action = WindowAction(G, fs)
    A = action.slots("p", matrix_form)
    variations = action.variation(A, lagrangian=lagrangian)
    arrows = action.named_arrows(matrix_form)
    sub = action.naming(A, arrows)
    values: dict = {}
    for o in action.offsets:
        for c in pair_coordinates(G):
            q0, q1 = arrows[o][c.source], arrows[o][c.target]
            mid, diff = piece_symbols(c, half_label("k", o))
            sub[A[o][c.source]], sub[A[o][c.target]] = rule.coordinates(q0, q1, mid, diff)
            values.update({p: v.doit() for p, v in rule.definitions(q0, q1, mid, diff)})
    constraints = action.constraints_on(A)
    return WindowPieces([v.xreplace(sub) for v in variations],
                        [c.xreplace(sub) for c in constraints], A, sub, values, action.offsets)


def _index_range(offsets: Sequence[int]) -> str:
    return "$j = " + ", ".join(step_label(o) for o in offsets) + "$"


def piece_form(step, rule: PieceRule, matrix_form: bool = False) -> Form | None:
    """The residuals with every pair arrow of the window written in the pieces of ``rule``
    before the variation meets the named arrows (so L's derivative comes out in them); in
    matrix form (constant parts evaluated) or explicitly."""
    from ..derivation._step import tidy

    system = _junction_system(step)
    fs = _system_functions(system, matrix_form)
    w = window_in_pieces(step, rule, fs, matrix_form)
    equations = [tidy(r) for r in w.rows + w.constraints]
    if matrix_form:
        values, constants = matrix_values(step), constant_matrices(step.groupoid)
        equations = [evaluated_constants(e, values, constants) for e in equations]
    return Form(equations, [w.values, matrix_values(step) if matrix_form else {}],
                _piece_definitions(pair_coordinates(step.groupoid), rule),
                [f"where, for {_index_range(w.offsets)},"], _generic_pieces(step.groupoid))


def _generic_pieces(G) -> dict:
    """Coordinates and pieces at j (j−1/2) → the same at k (k−1/2)."""
    out = {v: k for k, v in generic_renaming(G).items()}
    for c in pair_coordinates(G):
        out.update(zip(piece_symbols(c, half_label("j", 0)), piece_symbols(c, half_label("k", 0))))
    return out


def partial_symbol(root: str, label: str | None) -> StepSymbol:
    """(∂_{root} L)_{label}: a partial derivative of the discrete Lagrangian, evaluated at the
    arrow whose pieces carry ``label`` (None: ∂_{root} L itself, a function of the pieces)."""
    name = f"\\partial_{{{root}}} L"
    return StepSymbol(name if label is None else indexed_name(name, label))


def derivative_form(step, rule: PieceRule, matrix_form: bool = False) -> Form | None:
    """The first-order residual on a pair groupoid of Rⁿ, D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1})
    (+ the multiplier terms), through the partial derivatives of L in the midpoint pieces:
    with L(q₀, q₁) = L(q̄, Δq),

        ∂L/∂q₁ = ½ ∂L/∂q̄ + (1/τ) ∂L/∂Δq,    ∂L/∂q₀ = ½ ∂L/∂q̄ − (1/τ) ∂L/∂Δq,

    each partial named and evaluated at q̄_{k∓1/2}, Δq_{k∓1/2}; the "where" list gives each
    partial once, as a function of the pieces (q̄, Δq), then the pieces at j − 1/2.  (The
    coefficients ±½, ±1/τ come from varying the pieces themselves, so the groupoid's sign
    conventions carry over.)"""
    from ..derivation._junction import junction_variation
    from ..derivation._step import tidy

    system = _junction_system(step)
    G, coords = step.groupoid, pair_coordinates(step.groupoid)
    if (matrix_form or rule.kind != "midpoint" or system._arity != 1
            or 2 * len(coords) != G.arrow_dim):
        return None
    fs = system.functions
    w = window_in_pieces(step, rule, fs, False, lagrangian=False)
    dummies = [(sp.Dummy(f"m{i}"), sp.Dummy(f"d{i}")) for i in range(len(coords))]
    on_slot = {}
    for c, (mid, diff) in zip(coords, dummies):
        on_slot[fs.slots[0][c.source]], on_slot[fs.slots[0][c.target]] = rule.coordinates(
            None, None, mid, diff)
    ell = fs.lagrangian.xreplace(on_slot)
    rows = list(w.rows)
    layer: dict = {}
    definitions: list[Definition] = []
    instances = _generic_pieces(G)
    for c, pair in zip(coords, dummies):
        roots = piece_roots(c)
        for which in (0, 1):
            partial = sp.diff(ell, pair[which])
            at = {o: partial_symbol(roots[which], half_label("k", o)) for o in w.offsets}
            for o in w.offsets:
                A = w.slots[o]
                piece = [(A[c.source] + A[c.target]) / 2, (A[c.target] - A[c.source]) / rule.tau]
                X = junction_variation(G, piece[which], w.slots[0], w.slots[1])
                rows = [r + at[o] * x.xreplace(w.substitution) for r, x in zip(rows, X)]
                layer[at[o]] = _in_pieces(partial, coords, dummies, half_label("k", o))
            generic = partial_symbol(roots[which], None)
            definitions.append(Definition(generic, _in_pieces(partial, coords, dummies, None),
                                          frozenset(at.values()), literal=False))
            instances[generic] = at[0]
    for c in coords:
        instances.update(zip(piece_symbols(c, None), piece_symbols(c, half_label("k", 0))))
    equations = [tidy(r) for r in rows + w.constraints]
    intros = [f"where, for {_index_range(w.offsets)}, $(\\cdot)_{{j-1/2}}$ is taken at the "
              f"pieces of index $j - 1/2$:", "with"]
    return Form(equations, [layer, w.values],
                definitions + _piece_definitions(coords, rule, intro=1), intros, instances,
                unindexed=True)


def _in_pieces(expr: sp.Expr, coords, dummies, label: str | None) -> sp.Expr:
    """``expr`` in the piece dummies, written in the named pieces of subscript ``label``."""
    sub = {}
    for c, (mid, diff) in zip(coords, dummies):
        sub[mid], sub[diff] = piece_symbols(c, label)
    return sp.expand(expr.xreplace(sub))


def _piece_definitions(coords: Sequence[PairCoordinate], rule: PieceRule,
                       intro: int = 0) -> list[Definition]:
    """The "where" rows of the pieces at the generic arrow g_j = (q_{j−1}, q_j); each
    defines the pieces of that name at every index (k−3/2 … k+3/2)."""
    out = []
    for c in coords:
        q0 = StepSymbol(indexed_name(latex_name(c.name), "j-1"))
        q1 = StepSymbol(indexed_name(latex_name(c.name), "j"))
        generic = piece_symbols(c, half_label("j", 0))
        at_k = [piece_symbols(c, half_label("k", o)) for o in range(-1, 3)]
        for piece, value in rule.definitions(q0, q1, *generic):
            which = generic.index(piece)
            out.append(Definition(piece, value, frozenset(p[which] for p in at_k),
                                  as_written=True, intro=intro))
    return out


# --- recognised matrix pieces: β(g_k) = W_kᵀΓ_k on action groupoids ----------------------------


def action_pieces(step) -> list[tuple[sp.Expr, sp.Expr, dict]]:
    """(printed entry, explicit value, values of its symbols) for the target β(g_k) of the
    first arrow of the window when G is an action groupoid of a named vector space by a
    matrix group whose action is M p, Mᵀ p or M⁻¹ p (recognised by exact comparison, so
    the printing keeps g_kᵀ as such: (W_{k}^{T} Γ_{k})_{2})."""
    from ..derivation._step import window

    G = step.groupoid
    action = G.named_vector_action()
    if action is None:
        return []
    vector_name, group = action
    offset = window(step.order)[0][0]
    arrow = tuple(G.named_arrow(offset))
    point = sp.Matrix(G.source(arrow))
    target = [sp.expand(t) for t in G.target(arrow)]
    P = sp.MatrixSymbol(indexed_name(latex_name(vector_name), step_label(offset)),
                        len(point), 1)
    M = sp.MatrixSymbol(indexed_name(group.latex, step_label(offset)), group.n, group.n)
    explicit = sp.ImmutableMatrix(group.matrix(arrow[G.base_dim:]))
    values = {P: sp.ImmutableMatrix(point), M: explicit}
    for candidate in (sp.MatMul(M, P), sp.MatMul(sp.Transpose(M), P),
                      sp.MatMul(sp.Inverse(M), P)):
        try:
            entries = sp.Matrix(candidate.xreplace(values).doit())
        except (ValueError, TypeError, NotImplementedError):
            continue
        if all(sp.expand(e - t) == 0 for e, t in zip(entries, target)):
            # as the explicit residuals write it, and as the matrix form does (entries of M)
            in_entries = sp.Matrix(candidate.xreplace({P: values[P]}).doit())
            return [(MatrixElement(candidate, a, 0), value, values)
                    for a in range(len(target))
                    for value in (target[a], sp.expand(in_entries[a]))]
    return []


def with_recognised(form: Form, pieces: Sequence) -> Form:
    """``form`` with each recognised piece's value replaced by its printed entry."""
    equations = list(form.equations)
    layer: dict = {}
    for symbol, value, values in pieces:
        layer.update(values)
        equations = [replace_occurrences(sp.expand(e), value, symbol) for e in equations]
    return Form(equations, [*form.layers, layer], form.definitions, form.intros, form.generic,
                form.unindexed)


# --- abbreviations ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Abbreviation:
    """A user-named piece: its LaTeX name, the symbol it prints as (a :class:`NamedConstant`
    when its value is in the parameters only, so it is ordered with them), and its value:
    an expression, or a callable of an arrow evaluated on each arrow of the window."""

    tex: str
    symbol: sp.Symbol | None
    value: object


def abbreviations_of(abbreviations, step) -> list[Abbreviation]:
    """The checked ``abbreviations`` option: a mapping name → expression or callable; a name
    is a non-empty string (its LaTeX) or a SymPy Symbol, and prints unlike every symbol of
    the step; an expression is a SymPy expression in symbols (not a number, not a string)."""
    if abbreviations is None:
        return []
    if not isinstance(abbreviations, Mapping):
        raise LatexOptionError(f"latex: abbreviations must be a mapping name → expression or "
                               f"callable, got {type(abbreviations).__name__}")
    taken = {latex(s) for s in [*step.knowns, *step.unknowns, *step.fibre_unknowns,
                                *step.parameters]}
    out = []
    for name, value in abbreviations.items():
        if isinstance(name, sp.Symbol):
            tex, symbol = latex(name), name
        elif isinstance(name, str) and name.strip():
            tex, symbol = name, None
        else:
            raise LatexOptionError(f"latex: an abbreviation's name must be a non-empty string "
                                   f"(its LaTeX) or a SymPy Symbol, got {name!r}")
        if tex in taken:
            raise LatexOptionError(f"latex: the abbreviation {tex!r} prints like a symbol of "
                                   f"{step.name}; choose another name")
        taken.add(tex)
        if not callable(value):
            value = _abbreviation_value(tex, value)
            if symbol is None and value.free_symbols <= set(step.parameters):
                symbol = NamedConstant(tex)
        out.append(Abbreviation(tex, symbol, value))
    return out


def _abbreviation_value(tex: str, value) -> sp.Expr:
    try:
        expr = sp.sympify(value, strict=True)
    except sp.SympifyError:
        expr = None
    if not isinstance(expr, sp.Expr) or not expr.free_symbols:
        raise LatexOptionError(f"latex: the abbreviation {tex!r} must stand for a SymPy "
                               f"expression in the step's symbols, or a callable of an arrow; "
                               f"got {value!r}")
    return expr


def abbreviate(form: Form, step, abbreviations: Sequence[Abbreviation],
               rule: PieceRule | None) -> Form:
    """``form`` with each abbreviation recognised in the equations and the "where" rows.

    ``name → expression``: the expression (in the step's symbols or the printed pieces) is
    replaced by the name wherever it occurs, also inside sums with a common factor.
    ``name → callable``: the callable is evaluated, like the Lagrangian, on each arrow of the
    window (written in the pieces) and named with the arrow's index.
    """
    layer: dict = {}
    definitions: list[Definition] = []
    equations = list(form.equations)
    generic = dict(form.generic)
    rows = list(form.definitions)
    for a in abbreviations:
        if callable(a.value):
            pairs, (g_symbol, g_value) = _per_arrow(step, a.tex, a.value, rule, form.unindexed)
            definitions.append(Definition(g_symbol, g_value, frozenset(p for p, _ in pairs),
                                          abbreviation=a.tex))
            generic[g_symbol] = pairs[0][0]
        else:
            symbol = a.symbol if a.symbol is not None else StepSymbol(a.tex)
            g_symbol, g_value = symbol, a.value
            pairs = [(symbol, g_value)]
            definitions.append(Definition(symbol, g_value, frozenset([symbol]),
                                          abbreviation=a.tex))
        for s, v in pairs:
            layer[s] = v
            equations = [replace_occurrences(e, v, s) for e in equations]
        rows = [d if d.literal else dataclasses.replace(
            d, rhs=replace_occurrences(d.rhs, g_value, g_symbol)) for d in rows]
    # the rows defining the equations' names, then the abbreviations they use, then the rest
    ordered = ([d for d in rows if not d.literal] + definitions
               + [d for d in rows if d.literal])
    return Form(equations, [layer, *form.layers], ordered, form.intros, generic, form.unindexed)


def _arrow_in_pieces(step, offset: int, index: str, rule: PieceRule | None,
                     unindexed: bool = False) -> tuple:
    """The coordinates of g_{index+offset} with its pair coordinates written in the pieces
    (``unindexed``: in the pieces without index)."""
    G = step.groupoid
    coords = list(G.named_arrow(offset)) if index == "k" else list(_generic_arrow(G))
    if rule is None:
        return tuple(coords)
    for c in pair_coordinates(G):
        mid, diff = piece_symbols(c, None if unindexed else half_label(index, offset))
        coords[c.source], coords[c.target] = rule.coordinates(coords[c.source],
                                                              coords[c.target], mid, diff)
    return tuple(coords)


def _generic_arrow(G) -> tuple:
    """g_j: the named arrow g_k with the index k renamed j (every coordinate)."""
    return tuple(sp.sympify(c).xreplace(generic_renaming(G)) for c in G.named_arrow(0))


def generic_renaming(G) -> dict:
    """The named coordinates at k−1 and k → the same names at j−1 and j (scalars by name,
    matrix parts entry by entry: (W_{k})_{12} → (W_{j})_{12})."""
    rename: dict = {}
    for offset in (-1, 0):
        label = arrow_label("j", offset)
        for name, s in G.symbols_by_name(offset).items():
            if isinstance(s, sp.Symbol):
                rename[s] = StepSymbol(indexed_name(latex_name(name), label))
            elif isinstance(s, sp.MatrixBase) and s.shape[1] > 1:
                base = indexed_name(latex_name(name), label)
                for (i, j), entry in zip(((i, j) for i in range(s.rows) for j in range(s.cols)),
                                         s):
                    rename[entry] = StepSymbol(f"({base})_{{{i + 1}{j + 1}}}")
    return rename


def _per_arrow(step, tex: str, fn: Callable, rule: PieceRule | None, unindexed: bool = False):
    """(symbol, value) at each window arrow, and the generic (symbol, value) at g_j (with
    ``unindexed``, in the pieces without index, named without index)."""
    from ..derivation._callables import as_scalar, call_user
    from ..derivation._step import window

    G = step.groupoid
    label = half_label if pair_coordinates(G) else arrow_label

    def at(index: str, offset: int):
        arrow = G.view(_arrow_in_pieces(step, offset, index, rule))
        value = as_scalar(step.name, f"abbreviation {tex}", call_user(
            step.name, f"abbreviation {tex}", fn, arrow))
        return StepSymbol(indexed_name(tex, label(index, offset))), value

    pairs = [at("k", o) for o in window(step.order)[0]]
    if unindexed:
        arrow = G.view(_arrow_in_pieces(step, 0, "j", rule, unindexed=True))
        value = as_scalar(step.name, f"abbreviation {tex}", call_user(
            step.name, f"abbreviation {tex}", fn, arrow))
        return pairs, (StepSymbol(tex), value)
    return pairs, at("j", 0)


def replace_occurrences(expr: sp.Expr, value: sp.Expr, symbol: sp.Expr) -> sp.Expr:
    """``expr`` with ``value`` replaced by ``symbol``: exact subexpressions, and sums that
    contain a multiple c·value of a sum (c any common factor of those terms) — of the value
    as given and of its expanded form (a value (a − b)/(2h) is found in terms a/(2h) −
    b/(2h) of an expanded equation)."""
    expr = _replaced(expr, value, symbol)
    expanded = sp.expand(value)
    if expanded != value and isinstance(expanded, sp.Add):
        expr = _replaced(expr, expanded, symbol)
    return expr


def _replaced(expr: sp.Expr, value: sp.Expr, symbol: sp.Expr) -> sp.Expr:
    if expr == value:
        return symbol
    if not expr.args or isinstance(expr, sp.MatrixExpr):
        return expr
    if isinstance(expr, sp.Add) and isinstance(value, sp.Add):
        matched = _match_sum(expr, value, symbol)
        if matched is not None:
            return _replaced(matched, value, symbol)
    args = [_replaced(a, value, symbol) for a in expr.args]
    if all(a is b for a, b in zip(args, expr.args)):
        return expr
    return expr.func(*args)


def _match_sum(expr: sp.Add, value: sp.Add, symbol: sp.Expr) -> sp.Expr | None:
    """expr − c·value + c·symbol if every term of c·value is a term of expr, else None."""
    terms = list(expr.args)
    present = set(terms)
    lead, rest = value.args[0], value.args[1:]
    for t in terms:
        c = t / lead
        scaled = [c * v for v in rest]
        if all(s in present for s in scaled):
            remaining = list(terms)
            for s in [t, *scaled]:
                remaining.remove(s)
            return sp.Add(*remaining) + c * symbol
    return None


# --- collecting ----------------------------------------------------------------------------------


def collect_terms(expr: sp.Expr, multipliers: Sequence, parameters: Sequence,
                  printer: GroupoidLatexPrinter, variables: bool = False) -> list[Term]:
    """The terms of ``expr`` collected by multipliers and parameters (as SymPy's ``collect``
    does, one symbol after the other: λ·(…), h·(…), (Ω h/2)·(…)), then by common numeric
    coefficients (½·(a + b)); factors common to all the terms of a collected sum are taken
    out in front.  Both orders — multipliers first, parameters first — are tried (and, with
    ``variables``, the step variables before the parameters: for a "where" row, which is at
    one index); the shortest printing is kept.  Single terms stay as they are."""
    from ._layout import signed_terms

    ordered = [t.sign * t.expr for t in signed_terms(sp.expand(expr), printer)]
    orders = [[*multipliers, *parameters], [*parameters, *multipliers]]
    if variables:
        steps = sorted((s for s in expr.free_symbols
                        if isinstance(s, StepSymbol) and s not in set(multipliers)),
                       key=sp.default_sort_key)
        orders.append([*multipliers, *steps, *parameters])
    best: list[Term] | None = None
    for symbols in orders:
        grouped = _by_coefficient(_by_cofactor(_by_symbols(ordered, list(symbols)),
                                               multipliers))
        if len(grouped) > 1 and common_monomial(grouped) != 1:
            grouped = [_collected(sp.S.One, grouped)]
        terms = [_as_term(g) for g in grouped]
        if best is None or _printed_length(terms, printer) < _printed_length(best, printer):
            best = terms
    return best


def _printed_length(terms: list[Term], printer: GroupoidLatexPrinter) -> int:
    return sum(len(printer.doprint(t.expr)) + 3 for t in terms)


def _by_symbols(terms: list, symbols: list) -> list:
    """Terms with the same power pᵉ of the first symbol p collected as pᵉ·(…), the rest
    (inside and outside) by the following symbols; order of first appearance."""
    if len(terms) < 2 or not symbols:
        return list(terms)
    p, later = symbols[0], symbols[1:]
    groups: dict = {}
    order: list = []
    others: list = []
    for t in terms:
        c, e = _power_of(t, p)
        if e != 0 and not c.has(p):
            if e not in groups:
                groups[e] = []
                order.append(("power", e))
            groups[e].append(c)
        else:
            if not others:
                order.append(("others", None))
            others.append(t)
    out: list = []
    for kind, e in order:
        if kind == "others":
            out += _by_symbols(others, later)
        elif len(groups[e]) == 1:
            out.append(p**e * groups[e][0])
        else:
            out.append(_collected(p**e, _by_symbols(groups[e], later)))
    return out


def _power_of(term: sp.Expr, p: sp.Symbol) -> tuple[sp.Expr, sp.Expr]:
    """(c, e) with term = c·pᵉ, e the exponent of p as a factor of the product ``term``
    (0 when p is not a factor; c may still contain p, e.g. inside sin(p))."""
    if isinstance(term, Collected):
        return term, sp.S.Zero
    e = term.as_powers_dict().get(p, sp.S.Zero) if isinstance(term, (sp.Mul, sp.Pow)) \
        else (sp.S.One if term == p else sp.S.Zero)
    return (term / p**e if e != 0 else term), e


def _by_cofactor(items: list, multipliers: Sequence) -> list:
    """Plain terms c·λ (λ a multiplier, c a non-constant factor free of multipliers) with the
    same c up to sign collected as c·(±λ ± λ′): x_k ((λ_{k+1})₁ + (λ_k)₁),
    (Ω h/2)((λ_{k+1})₂ + (λ_k)₂)."""
    lam = set(multipliers)
    keys: list = []
    for item in items:
        key = None
        if not isinstance(_unsigned(item)[1], Collected):
            factors = [f for f in sp.Mul.make_args(item) if f in lam]
            if len(factors) == 1:
                c = item / factors[0]
                if c.free_symbols and not c.free_symbols & lam:
                    sign = -1 if c.as_coeff_Mul()[0].is_negative else 1
                    key = (sign * c, sign * factors[0])
        keys.append(key)
    groups: dict = {}
    for key in keys:
        if key is not None:
            groups.setdefault(key[0], []).append(key[1])
    out: list = []
    done: set = set()
    for item, key in zip(items, keys):
        if key is None or len(groups[key[0]]) == 1:
            out.append(item)
        elif key[0] not in done:
            out.append(_collected(key[0], groups[key[0]]))
            done.add(key[0])
    return out


def _by_coefficient(items: list) -> list:
    """Plain terms sharing a numeric coefficient |c| ≠ 1 collected as c·(…)."""
    groups: dict = {}
    for item in items:
        sign, inner = _unsigned(item)
        coeff = inner.as_coeff_Mul()[0] if not isinstance(inner, Collected) else None
        if coeff is not None and abs(coeff) != 1:
            groups.setdefault(abs(coeff), []).append(item)
    shared = {c: members for c, members in groups.items() if len(members) > 1}
    out: list = []
    for item in items:
        hit = next((c for c, members in shared.items() if item in members), None)
        if hit is None:
            out.append(item)
        elif item is shared[hit][0]:
            out.append(_collected(sp.S.One, shared[hit]))
    return out


def _unsigned(item: sp.Expr) -> tuple[int, sp.Expr]:
    """(−1, C) for −C with C collected; (1, item) otherwise."""
    if (isinstance(item, sp.Mul) and len(item.args) == 2 and item.args[0] == -1
            and isinstance(item.args[1], Collected)):
        return -1, item.args[1]
    return 1, item


def _leading_coefficient(part: sp.Expr) -> sp.Rational:
    sign, inner = _unsigned(part)
    if isinstance(inner, Collected):
        return sign * inner.factor.as_coeff_Mul()[0]
    return part.as_coeff_Mul()[0]


def _signed_collected(factor: sp.Expr, total: sp.Expr) -> sp.Expr:
    """factor·(total) with the sign of the factor's coefficient in front."""
    if factor.as_coeff_Mul()[0].is_negative:
        return -Collected(-factor, total)
    return Collected(factor, total)


def _collected(key: sp.Expr, parts: list) -> sp.Expr:
    """key · Σ parts, with the parts' common rational factor (and the sign of the first
    part) taken out in front; one collected part merges with the key."""
    if len(parts) == 1:
        sign, inner = _unsigned(parts[0])
        if isinstance(inner, Collected):
            return _signed_collected(sign * key * inner.factor, inner.total)
        return key * parts[0]
    coeffs = [_leading_coefficient(p) for p in parts]
    denominator = sp.ilcm(1, *[c.q for c in coeffs])
    factor = sp.Rational(sp.igcd(*[int(abs(c) * denominator) for c in coeffs]), denominator)
    if coeffs[0].is_negative:
        factor = -factor
    common = common_monomial(parts)
    total = sp.Add(*[_divided(_scaled(p, 1 / factor), common) for p in parts])
    return _signed_collected(factor * key * common, total)


def _monomial(part: sp.Expr) -> sp.Expr:
    """What multiplies a part: itself, or the factor of a collected part."""
    sign, inner = _unsigned(part)
    return inner.factor if isinstance(inner, Collected) else part


def _divided(part: sp.Expr, m: sp.Expr) -> sp.Expr:
    """``part / m`` (a collected part divides its factor)."""
    sign, inner = _unsigned(part)
    if isinstance(inner, Collected):
        return _signed_collected(sign * inner.factor / m, inner.total)
    return part / m


def common_monomial(parts: Sequence[sp.Expr]) -> sp.Expr:
    """The symbolic factors every one of ``parts`` has (of a collected part: its factor):
    Ω h λ₁/2 and Ω h λ₂/2 share Ω h; x/h and y/h share 1/h.  Each base is taken to the
    power closest to 0 among the parts, when the parts' powers all have one sign."""
    powers = [_monomial(p).as_coeff_Mul()[1].as_powers_dict() for p in parts]
    common = sp.S.One
    for base in powers[0]:
        exponents = [d.get(base, 0) for d in powers]
        if not all(isinstance(e, sp.Integer) for e in exponents):
            continue
        if all(e > 0 for e in exponents):
            common *= base ** min(exponents)
        elif all(e < 0 for e in exponents):
            common *= base ** max(exponents)
    return common


def _scaled(part: sp.Expr, c: sp.Rational) -> sp.Expr:
    sign, inner = _unsigned(part)
    if isinstance(inner, Collected):
        return _signed_collected(c * sign * inner.factor, inner.total)
    return c * part


def _as_term(expr: sp.Expr) -> Term:
    sign, inner = _unsigned(expr)
    if isinstance(inner, Collected):
        return Term(sign, inner)
    if expr.as_coeff_Mul()[0].is_negative:
        return Term(-1, -expr)
    return Term(1, expr)


# --- the printed step ----------------------------------------------------------------------------


@dataclass
class Printed:
    """A verified form: the collected terms of each equation and the "where" rows used."""

    equations: list  # list of list[Term]
    definitions: list  # Definition rows whose names occur
    intros: list  # words before each group of "where" rows
    length: int  # characters of the unbroken printing (what the forms are compared by)
    parameters: list = field(default_factory=list)
    layers: list = field(default_factory=list)  # what writes the printed names out (Form)
    generic: dict = field(default_factory=dict)  # "where" names at j → the same at k (Form)
    keeps: bool = False  # a matrix by name (tr(g_k E_1 E_2)): the papers' notation
    form: Form | None = None  # what the terms were collected from


def _multipliers(step) -> list:
    lam = set()
    for offset in range(-2, 3):
        lam.update(multiplier_symbols(step.n_constraints, offset))
    return [s for s in [*step.knowns, *step.unknowns] if s in lam]


def collected_form(form: Form, step, printer: GroupoidLatexPrinter) -> Printed:
    """The collected terms of a form and the "where" rows they use, with the length of their
    printing; not yet checked (:func:`checked_form`)."""
    multipliers = _multipliers(step)
    equations: list = []
    used: set = set()
    length = 0
    for equation in form.equations:
        terms = collect_terms(equation, multipliers, step.parameters, printer)
        used |= set().union(*[uncollected(t.expr).free_symbols for t in terms])
        length += sum(len(printer.doprint(t.expr)) + 3 for t in terms)
        equations.append(terms)
    for layer in form.layers:  # what the used names are written in is used too
        for name in list(used):
            if name in layer:
                used |= sp.sympify(layer[name]).free_symbols
    definitions = used_definitions(form.definitions, used)
    length += sum(_definition_length(d, step.parameters, printer) for d in definitions)
    return Printed(equations, definitions, form.intros, length, list(step.parameters),
                   list(form.layers), dict(form.generic), keeps_matrices(form.equations), form)


def checked_form(printed: Printed, step, printer: GroupoidLatexPrinter,
                 explicit: Sequence) -> Printed | None:
    """``printed`` if each of its equations, written out, is the explicit residual (an
    equation whose collected terms are not is printed uncollected, if that one is) and each
    "where" row holds; else None."""
    form = printed.form
    for i, (terms, residual) in enumerate(zip(printed.equations, explicit)):
        if not equals_explicit(sp.Add(*[t.value() for t in terms]), residual, form.layers):
            terms = collect_terms(form.equations[i], (), (), printer)
            if not equals_explicit(sp.Add(*[t.value() for t in terms]), residual,
                                   form.layers):
                return None
            printed.equations[i] = terms
    if not all(_definition_holds(d, form) for d in printed.definitions):
        return None
    return printed


def printed_form(form: Form, step, printer: GroupoidLatexPrinter,
                 explicit: Sequence) -> Printed | None:
    """The collected terms of a form, or None when a printed equation is not the explicit
    residual (collected or not)."""
    return checked_form(collected_form(form, step, printer), step, printer, explicit)


def used_definitions(definitions: Sequence[Definition], used: set) -> list[Definition]:
    """The "where" rows the printing needs, in their order: those defining a symbol of the
    equations (``used``), then, until nothing changes, those whose symbol a needed row's
    right-hand side uses (an abbreviation inside a partial derivative's row)."""
    needed: set = set()
    referenced: set = set()
    changed = True
    while changed:
        changed = False
        for i, d in enumerate(definitions):
            if i not in needed and (d.names & used or d.lhs in referenced):
                needed.add(i)
                referenced |= d.rhs.free_symbols
                changed = True
    return [d for i, d in enumerate(definitions) if i in needed]


def _definition_holds(d: Definition, form: Form) -> bool:
    """A "where" row, at j = k (through ``form.generic``), is its defined symbol written out."""
    at_k = form.generic
    return equals_explicit(d.rhs.xreplace(at_k), explicit_value(d.lhs.xreplace(at_k),
                                                                form.layers), form.layers)


def _definition_length(d: Definition, parameters: Sequence, printer) -> int:
    if d.literal:
        chosen = GroupoidLatexPrinter({"order": "none"}) if d.as_written else printer
        return len(chosen.doprint(d.lhs)) + len(chosen.doprint(d.rhs)) + 5
    terms = collect_terms(d.rhs, (), parameters, printer, variables=True)
    return len(printer.doprint(d.lhs)) + sum(len(printer.doprint(t.expr)) + 3 for t in terms)


def definition_rows(definitions: Sequence[Definition], parameters: Sequence,
                    printer: GroupoidLatexPrinter) -> list:
    """The "where" rows: literal ones as :class:`~._layout.Definitions` (packed several to a
    line), the others collected by variables and parameters, checked, and broken like
    equations."""
    rows: list = []
    for d in definitions:
        if not d.literal:
            lhs = printer.doprint(d.lhs)
            terms = verified_terms(d.rhs, (), parameters, printer, lhs)
            rows.append(Row(lhs, terms, numbered=False))
            continue
        pair = (d.lhs, d.rhs, d.as_written)
        if rows and isinstance(rows[-1], Definitions):
            rows[-1].pairs.append(pair)
        else:
            rows.append(Definitions([pair]))
    return rows


def printed_rows(printed: Printed, width: float, printer: GroupoidLatexPrinter) -> PrintedRows:
    """Equation rows (broken to ``width`` when laid out), then the "where" list, each group
    of its rows after its words."""
    items: list = [Row("0", terms) for terms in printed.equations]
    intro = None
    for d in printed.definitions:
        if d.intro != intro:
            intro = d.intro
            items.append(Text(printed.intros[intro]))
        items += definition_rows([d], printed.parameters, printer)
    return PrintedRows(_merged(items), width, printer)


def _merged(items: list) -> list:
    """Consecutive :class:`~._layout.Definitions` as one (packed together)."""
    out: list = []
    for item in items:
        if isinstance(item, Definitions) and out and isinstance(out[-1], Definitions):
            out[-1] = Definitions([*out[-1].pairs, *item.pairs])
        else:
            out.append(item)
    return out


class LatexOptionError(SymgroupoidError, ValueError):
    """An option of the LaTeX printing is invalid: a page width that is not a positive
    number of points, abbreviations that are not a mapping of names to expressions or
    callables, or an abbreviation name that is not a string or a SymPy Symbol."""


def _check_width(width) -> float:
    if width is None:
        return PAGE_WIDTH
    try:
        value = float(width)
    except (TypeError, ValueError):
        value = float("nan")
    if not 0 < value < float("inf"):
        raise LatexOptionError(f"latex: width must be a positive number of points, got "
                               f"{width!r}")
    return value


class UnusedAbbreviationWarning(UserWarning):
    """Abbreviations given to the printing that do not occur in the printed equations (their
    value is not a part of the printed form); ``names``: their LaTeX names."""

    def __init__(self, message: str, names: Sequence[str] = ()):
        super().__init__(message)
        self.names = list(names)


#: the chosen verified form of each printed step, by its abbreviations (a step printed
#: again — as LaTeX, as a document, in Jupyter — is not derived and checked again)
_PRINTED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def printed_step(step, abbreviations: Mapping | None = None,
                 width: float | None = None) -> PrintedRows:
    """The rows of the step's equations in their chosen verified printed form
    (:func:`chosen_form`); abbreviations that do not occur in it are reported with an
    :class:`UnusedAbbreviationWarning`."""
    width = _check_width(width)
    checked = abbreviations_of(abbreviations, step)
    printed = chosen_printed(step, abbreviations)
    unused = unused_abbreviations(printed, checked)
    if unused:
        which = (f"abbreviation {unused[0]} does" if len(unused) == 1 else
                 f"abbreviations {', '.join(unused)} do")
        warnings.warn(UnusedAbbreviationWarning(
            f"{step.name}: the {which} not occur in the printed equations (not a part of "
            f"them, or only of longer forms) and {'is' if len(unused) == 1 else 'are'} left "
            f"out of the \"where\" list", unused), stacklevel=4)
    return printed_rows(printed, width, MemoLatexPrinter())


def chosen_printed(step, abbreviations: Mapping | None = None) -> Printed:
    """The step's :func:`chosen_form`, remembered for the step and its abbreviations."""
    key = tuple(abbreviations_of(abbreviations, step))
    try:
        known = _PRINTED.setdefault(step, {})
        hash(key)
    except TypeError:  # unhashable abbreviations: printed afresh
        known = {}
    if key not in known:
        known[key] = chosen_form(step, abbreviations, MemoLatexPrinter())
    return known[key]


def unused_abbreviations(printed: Printed, abbreviations: Sequence[Abbreviation]) -> list[str]:
    """The LaTeX names of ``abbreviations`` that no "where" row of ``printed`` defines."""
    used = {d.abbreviation for d in printed.definitions}
    return [a.tex for a in abbreviations if a.tex not in used]


def plain_length(step) -> int:
    """Characters of ``sympy.latex`` of the step's residuals, one after the other."""
    return sum(len(sp.latex(r)) for r in step.residuals)


def chosen_form(step, abbreviations: Mapping | None = None,
                printer: GroupoidLatexPrinter | None = None) -> Printed:
    """The printed form of the step: of the forms that keep a matrix by name (the papers'
    tr(g_k E_i E_j); :func:`candidate_forms` in matrix form), the shortest, when it is not
    longer than SymPy's plain printing of the residuals (:func:`plain_length`); otherwise
    the shortest form of all.  Forms are collected first and checked
    (:func:`checked_form`) in that order until one passes (the explicit residuals always
    do); the explicit forms are built only when no matrix form is chosen."""
    printer = printer or MemoLatexPrinter()
    explicit = step.residuals
    kept = [collected_form(form, step, printer)
            for form, _ in candidate_forms(step, abbreviations, matrix_form=True)]
    if kept:
        plain = plain_length(step)
        for candidate in sorted((c for c in kept if c.length <= plain),
                                key=lambda c: c.length):
            printed = checked_form(candidate, step, printer, explicit)
            if printed is not None:
                return printed
    rest = [c for c in kept if c.length > plain] if kept else []
    rest += [collected_form(form, step, printer)
             for form, _ in candidate_forms(step, abbreviations, matrix_form=False)]
    for candidate in sorted(rest, key=lambda c: c.length):
        printed = checked_form(candidate, step, printer, explicit)
        if printed is not None:
            return printed
    raise LatexVerificationError(f"{step.name}: the printed equations differ from the "
                                 f"residuals")


def candidate_forms(step, abbreviations: Mapping | None = None,
                    matrix_form: bool = False) -> list[tuple[Form, object]]:
    """The forms of the step, each with the rule of its pieces (None: no pieces), in matrix
    form (none when the matrix form keeps no matrix by name) or explicit: the derived form
    (:func:`base_form`), the window in named pieces, the partial derivatives of L in them,
    each with recognised matrix pieces (W_kᵀΓ_k) and the ``abbreviations``."""
    abbreviations = abbreviations_of(abbreviations, step)
    base = base_form(step, matrix_form)
    if base is None:
        return []
    forms: list = [(base, None)]
    for pieces, rule in _piece_forms(step, matrix_form):
        if _no_clash(pieces, step):
            forms.append((pieces, rule))
    recognised = action_pieces(step)
    if recognised:
        forms += [(with_recognised(form, recognised), rule) for form, rule in forms]
    if abbreviations:
        forms = [(abbreviate(form, step, abbreviations, rule), rule) for form, rule in forms]
    return forms


def verified_forms(step, abbreviations: Mapping | None = None,
                   printer: GroupoidLatexPrinter | None = None) -> list[Printed]:
    """Every printed form of the step (:func:`candidate_forms`) that equals its residuals."""
    printer = printer or MemoLatexPrinter()
    explicit = step.residuals
    printed = []
    forms = [*candidate_forms(step, abbreviations, matrix_form=True),
             *candidate_forms(step, abbreviations, matrix_form=False)]
    for form, _ in forms:
        result = printed_form(form, step, printer, explicit)
        if result is not None:
            printed.append(result)
    if not printed:  # the base form is the residual itself: only a failed check gets here
        raise LatexVerificationError(f"{step.name}: the printed equations differ from the "
                                     f"residuals")
    return printed


#: what building a form in named pieces may raise for a system it does not fit (a Lagrangian
#: that does not take pieces, a groupoid without pair coordinates): that form is not offered
_NOT_IN_PIECES = (SymgroupoidError, AttributeError, TypeError, ValueError, NotImplementedError)


def _piece_forms(step, matrix_form: bool = False) -> list[tuple[Form, PieceRule]]:
    """The forms of the step in the named pieces of the rule L is shortest in (none when L
    is not written in pieces or the step is not a junction variation of L), in matrix form
    or explicit."""
    system = _junction_system(step)
    if system is None:
        return []
    try:
        rule = best_rule(system.functions, pair_coordinates(step.groupoid), step.parameters)
    except _NOT_IN_PIECES:
        return []
    out = []
    for build in (piece_form, derivative_form):
        try:
            form = build(step, rule, matrix_form) if rule is not None else None
        except _NOT_IN_PIECES:
            form = None
        if form is not None:
            out.append((form, rule))
    return out


def _no_clash(form: Form, step) -> bool:
    """The piece names are not names the step already uses."""
    names = {str(s) for s in [*step.knowns, *step.unknowns, *step.fibre_unknowns,
                              *step.parameters]}
    return not any(str(p) in names for layer in form.layers[:2] for p in layer)


# --- Legendre transforms (seed 000 §3.3) ---------------------------------------------------------


def verified_terms(expr: sp.Expr, multipliers: Sequence, parameters: Sequence,
                   printer: GroupoidLatexPrinter, what: str) -> list[Term]:
    """``expr`` collected (:func:`collect_terms`, step variables too: it is at one arrow),
    checked to be ``expr``."""
    from ._layout import same_sum

    terms = collect_terms(expr, multipliers, parameters, printer, variables=True)
    same_sum(terms, [Term(1, sp.sympify(expr))], what)
    return terms


def inline_latex(expr: sp.Expr, multipliers: Sequence, parameters: Sequence) -> str:
    """``expr`` collected and verified (:func:`verified_terms`), on one line."""
    from ._layout import term_text

    printer = MemoLatexPrinter()
    terms = verified_terms(expr, multipliers, parameters, printer, "the expression")
    return " ".join(term_text(t, i == 0, printer) for i, t in enumerate(terms))


def legendre_rows(lt, width: float | None = None) -> PrintedRows:
    """(𝔽⁻L)_a = X⃗_a[L + λ·φ](g_k), then (𝔽⁺L)_a = X⃖_a[L + λ·φ](g_k): each collected by
    multipliers, variables and parameters, verified, and broken to ``width`` pt."""
    width = _check_width(width)
    printer = MemoLatexPrinter()
    items: list = []
    for sign, forms in (("-", lt.minus), ("+", lt.plus)):
        for a, e in enumerate(forms):
            lhs = printer.doprint(StepSymbol(f"(\\mathbb{{F}}^{{{sign}}}L)_{{{a + 1}}}"))
            items.append(Row(lhs, verified_terms(e, lt.multipliers, lt.parameters, printer,
                                                 lhs)))
    return PrintedRows(items, width, printer)


# --- Lie–Poisson equations (seed 000 §6.1) ------------------------------------------------------


def lie_poisson_rows(lp, width: float | None = None) -> PrintedRows:
    """μ_{k+1} = Ad*_{g_k} μ_k, then 0 = 𝔽⁻L_{k+1} − Ad*_{g_k} 𝔽⁻L_k (componentwise) and the
    constraints, with Ad* printed as a named operator and 𝔽⁻L_j = μ(g_j) + λ_j·Φ(g_j) in a
    "where" list.  Each printed row is verified against the explicit update and residuals,
    with Ad*_{g_k} written out; rows that fail print explicitly (collected, verified)."""
    from ..derivation._momenta import momentum_symbols

    width = _check_width(width)
    printer = MemoLatexPrinter()
    step = lp.reconstruction
    G, rank, m = step.groupoid, len(lp.momentum_symbols), step.n_constraints
    multipliers = _multipliers(step)

    def explicit_row(lhs: str, expr: sp.Expr) -> Row:
        return Row(lhs, verified_terms(expr, multipliers, step.parameters, printer, lhs))

    g0, g1 = tuple(G.named_arrow(0)), tuple(G.named_arrow(1))
    ad = NamedOperator(f"\\operatorname{{Ad}}^{{*}}_{{{indexed_name(G.latex, 'k')}}}", rank, rank)
    ad_value = sp.ImmutableMatrix(G.Ad_star(G.matrix(g0)))
    mu0 = sp.MatrixSymbol(indexed_name("\\mu", "k"), rank, 1)
    mu1 = sp.MatrixSymbol(indexed_name("\\mu", "k+1"), rank, 1)
    items: list = []
    update = sp.MatMul(ad, mu0)
    values = {ad: ad_value, mu0: sp.ImmutableMatrix(lp.momentum_symbols)}
    if all(equals_explicit(MatrixElement(update, a, 0), u, [values])
           for a, u in enumerate(lp.update)):
        items.append(Row(printer.doprint(mu1), [Term(1, update)]))
    else:
        items += [explicit_row(printer.doprint(s), u)
                  for s, u in zip(momentum_symbols(rank, 1), lp.update)]
    F = {o: sp.MatrixSymbol(indexed_name("\\mathbb{F}^{-}L", label), rank, 1)
         for o, label in ((0, "k"), (1, "k+1"))}
    shift = dict(zip(g0, g1))
    shift.update(zip(multiplier_symbols(m, 0), multiplier_symbols(m, 1)))
    momentum = [sp.expand(e) for e in lp.momentum]
    layer = {ad: ad_value, F[0]: sp.ImmutableMatrix(momentum),
             F[1]: sp.ImmutableMatrix([e.xreplace(shift) for e in momentum])}
    residual = sp.MatAdd(F[1], sp.MatMul(-1, ad, F[0]))
    if all(equals_explicit(MatrixElement(residual, a, 0), r, [layer])
           for a, r in enumerate(lp.residuals[:rank])):
        items.append(Row("0", [Term(1, F[1]), Term(-1, sp.MatMul(ad, F[0]))]))
        where = _momentum_definitions(G, momentum, m, printer)
    else:
        where = []
        items += [explicit_row("0", r) for r in lp.residuals[:rank]]
    items += [explicit_row("0", r) for r in lp.residuals[rank:]]
    if where:
        items.append(Text("where, for $j = k, k+1$,"))
        items += definition_rows(where, step.parameters, printer)
    return PrintedRows(items, width, printer)


def _momentum_definitions(G, momentum: Sequence, m: int, printer) -> list[Definition]:
    """(𝔽⁻L_j)_a = X⃗_a[L + λ_j·φ](g_j) at the generic index j."""
    rename = generic_renaming(G)
    rename.update({lam: StepSymbol(f"({indexed_name(chr(92) + 'lambda', 'j')})_{{{b + 1}}}")
                   for b, lam in enumerate(multiplier_symbols(m, 0))})
    out = []
    for a, e in enumerate(momentum):
        lhs = StepSymbol(f"({indexed_name(chr(92) + 'mathbb{F}^{-}L', 'j')})_{{{a + 1}}}")
        out.append(Definition(lhs, e.xreplace(rename), frozenset([lhs]), literal=False))
    return out
