"""The printed forms of a step's residuals, each with the "where" rows it needs.

The residual of a step is the junction variation of the window action (seed 000 Thm 2.13;
docs/conventions.md §2): on the pair groupoid Q × Q, D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}).
The derivation gives it in three ways (:mod:`symgroupoid.derivation`): as derived (explicit,
or in matrix form), with the window's pair arrows in named pieces
(:func:`~symgroupoid.derivation.piece_residuals`), and through the named partial
derivatives of L(q̄, Δq) (:func:`~symgroupoid.derivation.partial_residuals`): the step reads
½(∂_q̄L_{k−1/2} + ∂_q̄L_{k+1/2}) − (∂_ΔqL_{k+1/2} − ∂_ΔqL_{k−1/2})/h = 0 and the "where"
list gives each partial once.  A :class:`Form` holds one of them with what its printed names
stand for, layer by layer, so that every printed equation can be checked to equal the
explicit residual (:func:`equals_explicit`).  On action groupoids β(g_k) = W_kᵀΓ_k is
recognised and kept by name (:func:`action_pieces`).
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import sympy as sp
from sympy.matrices.expressions.matexpr import MatrixElement

from .._errors import CallableError
from .._rational import expanded_vanishes, vanishes_at_points
from .._sizes import nodes_at_most
from .._symbols import StepSymbol, latex_name, step_label
from ..derivation import (
    PieceRule,
    WindowAction,
    distribution_coefficients,
    matrix_form_residuals,
    matrix_form_values,
    partial_residuals,
    piece_residuals,
    window,
)
from ..groupoids import PairCoordinate
from ._collect import replace_occurrences
from ._latex import uncollected
from ._matrix_parts import (
    _matrix_form_keeps,
    constant_matrices,
    evaluated_constants,
    junction_system,
    keeps_matrices,
    kept_matrix_form,
    matrix_values,
    system_functions,
)
from ._pieces import (
    generic_renaming,
    half_label,
    indexed_name,
    pair_coordinates,
    partial_symbol,
    piece_roots,
    piece_symbols,
    window_partial_symbol,
    window_piece_symbols,
)


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
    expanded: bool = True  # terms collected from the equations expanded (else as they are)


def written_out(expr: sp.Expr, layers: Sequence[Mapping]) -> sp.Expr:
    """``expr`` with every layer substituted in order, named constants (J_d) by their
    values, matrices evaluated."""
    from ..groupoids import named_constants

    out = uncollected(sp.sympify(expr))
    for layer in layers:
        if layer:
            out = out.xreplace(dict(layer))
    return out.xreplace(named_constants(out)).doit()


def explicit_value(expr: sp.Expr, layers: Sequence[Mapping]) -> sp.Expr:
    """:func:`written_out`, expanded."""
    return sp.expand(written_out(expr, layers))


#: the size (nodes of the tree, with repetitions) of a printed equation's difference from
#: the explicit residual, written out but not expanded, from which random rational points
#: decide it (:func:`vanishes_at_points`) before any expansion: the three junction rows of
#: the heavy top with rotors (seed 001 §3.3.5), 31,000 nodes each, took 13–16 s each to
#: expand, 0.3–0.4 s at the points
LARGE_NODES = 4000


def equals_explicit(printed: sp.Expr, explicit: sp.Expr, layers: Sequence[Mapping]) -> bool:
    """Whether the printed equation, written out, is the explicit residual: their
    difference is zero over the factored common denominator (:func:`vanishes`), or, with
    more than :data:`LARGE_NODES` nodes unexpanded or :data:`LARGE_TERMS` terms expanded,
    at random rational points, exactly evaluated (:func:`vanishes_at_points`: a nonzero
    value there refutes the form for certain; zero at three points is wrong with a chance
    below 10⁻⁴⁵)."""
    written, explicit = written_out(printed, layers), sp.sympify(explicit)
    unexpanded = written - explicit
    if not nodes_at_most(unexpanded, LARGE_NODES):
        zero = vanishes_at_points(unexpanded)
        if zero is not None:
            return zero
    return expanded_vanishes(sp.expand(sp.expand(written) - sp.expand(explicit)))


def base_form(step, matrix_form: bool = False) -> Form | None:
    """The residuals as derived: in matrix form, when it keeps a matrix by name (else None),
    or explicit.  A forced step's matrix form is the unforced one with its forces named
    (:func:`forced_form`)."""
    if not matrix_form:
        return Form(list(step.residuals))
    structured = kept_matrix_form(step)
    if structured is None:
        return forced_form(step, matrix_form=True)
    return Form(structured, [matrix_values(step)])


def forced_form(step, matrix_form: bool = False) -> Form | None:
    """A forced step with its forces named (docs/conventions.md §20): the junction residual
    of L (+ λ·φ) followed by f⁺_b(g_k) + f⁻_b(g_{k+1}) (second order: f²_b(g_{k−1}, g_k) +
    f¹_b(g_k, g_{k+1}) + f⁰_b(g_{k+1}, g_{k+2})), the discrete forces given in the "where"
    list; for the nonholonomic Hölder step, those rows combined along D_c,
    Σ_b c_a^b(β(g_k))·(…) (docs/conventions.md §10).  With ``matrix_form`` the residual of
    L is its matrix form (tr(J_d W_k E_a), as the unforced step prints it:
    :func:`unforced_matrix_form`).  None for a step without forces, and in matrix form for
    a step whose L keeps no matrix by name (or a Hölder step, which has no matrix form)."""
    system, holder = junction_system(step), _holder_system(step)
    if (system or holder) is None or (matrix_form and system is None):
        return None
    fs, rank = (system or holder).functions, step.groupoid.rank
    if fs.forces is None:
        return None
    action = WindowAction(step.groupoid, replace(fs, forces=None))
    unforced, arrows = action.residuals(multipliers=holder is None)
    matrices: dict = {}
    if matrix_form:
        kept = unforced_matrix_form(step, unforced)
        if kept is None:
            return None
        unforced, matrices = kept
    layer = _force_layer(fs, action, arrows, rank)
    names = list(layer)
    equations = [unforced[b] + sum(names[b::rank], sp.S.Zero) for b in range(rank)]
    if holder is not None:
        rows = distribution_coefficients(step.name, step.groupoid, holder.distribution,
                                         step.groupoid.target(arrows[0]))
        equations = [sum((c * e for c, e in zip(row, equations)), sp.S.Zero) for row in rows]
    definitions = [Definition(name, value, frozenset({name})) for name, value in layer.items()]
    layers = [layer, matrices] if matrix_form else [layer]
    return Form(equations + list(unforced[rank:]), layers, definitions)


def _force_layer(fs, action: WindowAction, arrows: Mapping, rank: int) -> dict:
    """The named discrete forces at the junction — f⁺_b(g_k), f⁻_b(g_{k+1}) (second order:
    f², f¹, f⁰) as :class:`StepSymbol` s — with their values at the window's named arrows."""
    arity, layer = len(fs.slots), {}
    for s in action.starts:  # the term starting at s meets the junction at its point 1 − s
        values = fs.forces.on([arrows[s + i] for i in range(arity)], s)[1 - s]
        mark = ("+" if s == 0 else "-") if arity == 1 else str(1 - s)
        where = ", ".join(f"g_{{{step_label(s + i)}}}" for i in range(arity))
        layer.update({StepSymbol(f"f^{{{mark}}}_{{{b + 1}}}({where})"): values[b]
                      for b in range(rank)})
    return layer


def _with_forces(step, form: Form, fs) -> Form:
    """A form of a forced step's residual of L alone (+ λ·φ) with its forces named, as
    :func:`forced_form` names them: each junction row plus its f⁺ + f⁻, their values
    (written in the arrows' coordinates) after the form's own "where" rows."""
    rank = step.groupoid.rank
    action = WindowAction(step.groupoid, replace(fs, forces=None))
    layer = _force_layer(fs, action, action.named_arrows(), rank)
    names = list(layer)
    equations = [form.equations[b] + sum(names[b::rank], sp.S.Zero) for b in range(rank)]
    intro = len(form.intros)
    forces = [Definition(name, value, frozenset({name}), intro=intro)
              for name, value in layer.items()]
    return Form(equations + list(form.equations[rank:]), [layer, *form.layers],
                form.definitions + forces, [*form.intros, "and the discrete forces"],
                form.generic, form.unindexed)


#: each forced step's :func:`unforced_matrix_form` (None too), built once
_UNFORCED_KEPT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def unforced_matrix_form(step, unforced: Sequence[sp.Expr]) -> tuple[list, dict] | None:
    """The matrix form of a forced step's residuals of L (+ λ·φ) alone — ``unforced``, the
    explicit rows the forces are added to — with its constant parts evaluated, as
    :func:`~symgroupoid.equations._matrix_parts.kept_matrix_form` gives an unforced step's;
    and the values of its matrix symbols.  None when it keeps no matrix by name (or has no
    matrix form)."""
    if step not in _UNFORCED_KEPT:
        _UNFORCED_KEPT[step] = _unforced_matrix_form(step, unforced)
    return _UNFORCED_KEPT[step]


def _unforced_matrix_form(step, unforced: Sequence[sp.Expr]) -> tuple[list, dict] | None:
    from ..groupoids import named_constants

    system, G = junction_system(step), step.groupoid
    if not G.matrix_parts() or not _matrix_form_keeps(step):
        return None
    try:
        structured = matrix_form_residuals(
            system.name, G, system.lagrangian, system.constraints, system.parameters,
            unforced, arity=system._arity, holonomic=system.holonomic)
    except CallableError:
        return None  # user code needs explicit matrices: print entries
    if structured is None:
        return None
    values = matrix_form_values(G, window(step.order)[0])
    for e in structured:
        values.update(named_constants(e))
    constants = constant_matrices(G)
    equations = [evaluated_constants(e, values, constants) for e in structured]
    return (equations, values) if keeps_matrices(equations) else None


def _holder_system(step):
    """The nonholonomic system of a Hölder step (docs/conventions.md §10), else None."""
    from ._system import NonholonomicSystem

    system = step.system
    if isinstance(system, NonholonomicSystem) and system.method == "holder":
        return system
    return None


def index_range(offsets: Sequence[int]) -> str:
    return "$j = " + ", ".join(step_label(o) for o in offsets) + "$"


def piece_form(step, rule: PieceRule, matrix_form: bool = False) -> Form | None:
    """The residuals with every pair arrow of the window written in the pieces of ``rule``
    before the variation meets the named arrows (so L's derivative comes out in them;
    :func:`~symgroupoid.derivation.piece_residuals`); in matrix form (constant parts
    evaluated) or explicitly."""
    system = junction_system(step)
    fs = system_functions(system, matrix_form)
    forces = fs.forces  # the pieces are those of L alone: a forced step adds f⁺ + f⁻
    equations, w = piece_residuals(step.groupoid, replace(fs, forces=None), rule,
                                   window_piece_symbols, matrix_form)
    if matrix_form:
        values, constants = matrix_values(step), constant_matrices(step.groupoid)
        equations = [evaluated_constants(e, values, constants) for e in equations]
    form = Form(equations, [w.values, matrix_values(step) if matrix_form else {}],
                _piece_definitions(pair_coordinates(step.groupoid), rule),
                [f"where, for {index_range(w.offsets)},"], _generic_pieces(step.groupoid))
    return form if forces is None else _with_forces(step, form, fs)


def _generic_pieces(G) -> dict:
    """Coordinates and pieces at j (j−1/2) → the same at k (k−1/2)."""
    out = {v: k for k, v in generic_renaming(G).items()}
    for c in pair_coordinates(G):
        out.update(zip(piece_symbols(c, half_label("j", 0)), piece_symbols(c, half_label("k", 0))))
    return out


def derivative_form(step, rule: PieceRule, matrix_form: bool = False) -> Form | None:
    """The first-order residual on a pair groupoid of Rⁿ, D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1})
    (+ the multiplier terms), through the partial derivatives of L in the midpoint pieces
    (:func:`~symgroupoid.derivation.partial_residuals`), each partial named and evaluated at
    q̄_{k∓1/2}, Δq_{k∓1/2}; the "where" list gives each partial once, as a function of the
    pieces (q̄, Δq), then the pieces at j − 1/2."""
    system = junction_system(step)
    G, coords = step.groupoid, pair_coordinates(step.groupoid)
    if (matrix_form or rule.kind != "midpoint" or system._arity != 1
            or 2 * len(coords) != G.arrow_dim):
        return None
    fs = system.functions
    equations, partials, w = partial_residuals(G, replace(fs, forces=None), rule,
                                               window_piece_symbols, window_partial_symbol)
    layer: dict = {}
    definitions: list[Definition] = []
    instances = _generic_pieces(G)
    for p in partials:
        layer.update(p.values)
        generic = partial_symbol(piece_roots(p.coordinate)[p.which], None)
        definitions.append(Definition(generic, p.value, frozenset(p.at.values()),
                                      literal=False))
        instances[generic] = p.at[0]
    for c in coords:
        instances.update(zip(piece_symbols(c, None), piece_symbols(c, half_label("k", 0))))
    intros = [f"where, for {index_range(w.offsets)}, $(\\cdot)_{{j-1/2}}$ is taken at the "
              f"pieces of index $j - 1/2$:", "with"]
    form = Form(equations, [layer, w.values],
                definitions + _piece_definitions(coords, rule, intro=1), intros, instances,
                unindexed=True)
    return form if fs.forces is None else _with_forces(step, form, fs)


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


