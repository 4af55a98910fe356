"""Readable printed equations: named pieces, collected terms, a "where" list — each verified.

The printers print what the derivation gives; they derive nothing.  The step's residuals
come from the derivation in three forms (:mod:`._forms`): as derived (explicit, or in matrix
form with its matrix parts kept by name, :mod:`._matrix_parts`), with the window's pair
arrows in named pieces, and through the partial derivatives of L in them — the pieces of the
rule L and the constraints are shortest in (:mod:`._pieces`).  User abbreviations are
recognised next (:mod:`._abbreviations`), then the terms are collected by multipliers and
parameters (:mod:`._collect`), and the rows broken to the page width (:mod:`._rows`,
:mod:`._layout`).

Every printed equation, written out, is checked to equal the explicit residual, and so is
every "where" row; a form that fails is not printed.  The explicit residuals always pass.
Of the verified forms, the shortest one that keeps a matrix by name is printed when it is
not longer than ``sympy.latex`` of the residuals, else the shortest in total (equations and
"where" list); the choice is remembered for the step.

Nothing here runs unless LaTeX is asked for.
"""

from __future__ import annotations

import warnings
import weakref
from collections.abc import Mapping, Sequence

import sympy as sp

from .._arguments import caller_level
from .._errors import UnsupportedExpressionError, UnsupportedFeatureError
from ..derivation import PieceRule, window
from ..ir import TERMS_CAP, power_terms, product_terms
from ._abbreviations import (
    Abbreviation,
    UnusedAbbreviationWarning,
    abbreviate,
    abbreviations_of,
    constant_names,
    printed_pieces,
    printed_symbols,
    rendered,
)
from ._denominators import free_name, shared_denominator
from ._forms import (
    Form,
    action_pieces,
    base_form,
    derivative_form,
    forced_form,
    piece_form,
    with_recognised,
)
from ._group_stage_forms import group_rule_refusal, group_stage_form
from ._latex import (
    EXPANSION_LIMIT,
    PRINT_LIMIT,
    GroupoidLatexPrinter,
    LatexVerificationError,
    MemoLatexPrinter,
    latex,
)
from ._layout import PrintedRows
from ._matrix_parts import NOT_IN_PIECES, junction_system
from ._pieces import best_rule, pair_coordinates
from ._rows import Printed, check_width, checked_form, collected_form, printed_form, printed_rows
from ._stage_forms import stage_clash, stage_form

#: the chosen verified form of each printed step, by its abbreviations (a step printed
#: again — as LaTeX, as a document, in Jupyter — is not derived and checked again)
_PRINTED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def check_printable(step) -> None:
    """An :class:`~symgroupoid.UnsupportedFeatureError`, at once, for a step whose residuals
    written out exceed :data:`PRINT_LIMIT` operations, or expanded could exceed
    :data:`EXPANSION_LIMIT` terms (:func:`expanded_terms`): printing them would not finish.
    A step of an undefined function (an arbitrary L) has no program; its expansion is
    bounded all the same."""
    unaffected = ("LaTeX is not produced for it.  Its kernels, diagnostics and verification "
                  "do not write them out and are unaffected")
    try:
        program = step.program
    except UnsupportedExpressionError:
        program = None
    size = 0 if program is None else program.expanded_size(["F"])
    if size > PRINT_LIMIT:
        raise UnsupportedFeatureError(
            f"{step.name}: its equations written out as formulas have {size:.2e} operations "
            f"({program.size(['F'])} in the shared graph its kernels evaluate), more "
            f"than the {PRINT_LIMIT:.0e} that can be printed and checked: {unaffected}")
    terms = expanded_terms(step.residuals)
    if terms > EXPANSION_LIMIT:
        raise UnsupportedFeatureError(
            f"{step.name}: its equations expanded (products multiplied out over sums, as "
            f"printing collects and checks them) could have {terms:.2e} terms, more than the "
            f"{EXPANSION_LIMIT:.0e} that can be printed and checked in minutes: {unaffected}")


def expanded_terms(exprs: Sequence[sp.Expr]) -> int:
    """A bound on the number of terms of ``sympy.expand`` of the expressions, without
    cancellation: a sum has its terms' sum, a product their product, a positive integer
    power pⁿ of a sum of t terms at most C(t + n − 1, n); a negative or fractional power, a
    function or an atom is one term.  Each distinct subexpression is counted once (linear
    in the expressions' size); values past 10³⁰ are 10³⁰."""
    memo: dict = {}
    for root in exprs:  # children before parents, with an explicit stack (no recursion)
        stack = [(sp.sympify(root), False)]
        while stack:
            e, ready = stack.pop()
            if e in memo:
                continue
            if not ready:
                stack.append((e, True))
                stack.extend((a, False) for a in e.args if a not in memo)
                continue
            memo[e] = min(_node_terms(e, [memo[a] for a in e.args]), TERMS_CAP)
    return sum(memo[sp.sympify(e)] for e in exprs)


def _node_terms(e: sp.Basic, inner: list[int]) -> int:
    """:func:`expanded_terms` of ``e`` from those of its arguments."""
    if e.is_Add:
        return sum(inner)
    if e.is_Mul:
        return product_terms(inner)
    if e.is_Pow and e.exp.is_Integer and e.exp > 0:
        return power_terms(inner[0], int(e.exp))
    return 1


def _check_printable_staged(step) -> None:
    """:func:`check_printable`, whose refusal of a Galerkin step names the system's names
    that kept its stage notation from printing it (:func:`~._stage_forms.stage_clash`)."""
    try:
        check_printable(step)
    except UnsupportedFeatureError as refused:
        clash = stage_clash(step)
        if not clash:
            raise
        raise UnsupportedFeatureError(
            f"{refused}.  The stage notation (docs/conventions.md §22) prints such a step, "
            f"but the system's names {', '.join(clash)} read as its symbols: rename them "
            f"(e.g. a group named R, coordinates x, y, inputs u1, u2) to print it") from None


#: the group stage notation of each printed step (None: not offered), checked once
_GROUPED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def group_stage_printed(step, width: float) -> PrintedRows | None:
    """A Galerkin or rule's step on Lie-group factors in the group stage notation
    (:func:`~._group_stage_forms.group_stage_form`, checked at points of the group), laid
    out for ``width``, or None; the checked form is remembered for the step.  (Written out,
    a rule's step on a group is too large to print, a free body on SE(3), or to check in
    minutes, a pendulum on SO(2).)"""
    try:
        if step not in _GROUPED:
            _GROUPED[step] = group_stage_form(step)
        form = _GROUPED[step]
    except TypeError:  # not weakly referenceable: checked afresh
        form = group_stage_form(step)
    return None if form is None else form.rows(width, MemoLatexPrinter())


#: why abbreviations do not occur in a step printed in the stage notation
_STAGE_REASON = ("the stage notation names its own parts: abbreviations apply to the other "
                 "printed forms")


def printed_step(step, abbreviations: Mapping | None = None,
                 width: float | None = None) -> PrintedRows:
    """The rows of the step's equations in their chosen verified printed form
    (:func:`chosen_form`); abbreviations that do not occur in it are reported with an
    :class:`UnusedAbbreviationWarning`."""
    width = check_width(width)
    checked = abbreviations_of(abbreviations, step)
    grouped = group_stage_printed(step, width)  # a Galerkin or rule step on a group
    if grouped is not None:
        _warn_unused(step, [a.tex for a in checked], _STAGE_REASON)
        return grouped
    refusal = group_rule_refusal(step)
    if refusal is not None:  # written out it would not finish
        raise UnsupportedFeatureError(
            f"{step.name}: a rule's step on a group prints in the group stage notation "
            f"(docs/latex.md), which is not offered here: {refusal}; written out, its "
            f"equations take too long to print and check: LaTeX is not produced for it.  Its "
            f"kernels, diagnostics and verification are unaffected")
    _check_printable_staged(step)
    printed = chosen_printed(step, abbreviations)
    _warn_unused(step, unused_abbreviations(printed, checked),
                 _STAGE_REASON if printed.stage_notation
                 else "not a part of them, or only of longer forms")
    return printed_rows(printed, width, MemoLatexPrinter())


def _warn_unused(step, unused: list[str], why: str) -> None:
    """An :class:`UnusedAbbreviationWarning` for the abbreviations ``unused`` (none: none)."""
    if not unused:
        return
    which = (f"abbreviation {unused[0]} does" if len(unused) == 1 else
             f"abbreviations {', '.join(unused)} do")
    warnings.warn(UnusedAbbreviationWarning(
        f"{step.name}: the {which} not occur in the printed equations ({why}) and "
        f"{'is' if len(unused) == 1 else 'are'} left out of the \"where\" list", unused),
        stacklevel=caller_level())


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
    do); the explicit forms are built only when no matrix form is chosen.  A Galerkin step
    with internal stages prints in the papers' stage notation when that form holds
    (:func:`~._stage_forms.stage_form`, docs/conventions.md §22)."""
    printer = printer or MemoLatexPrinter()
    explicit = step.residuals
    staged = stage_form(step)  # a Galerkin step: the papers' stage notation, when it holds
    if staged is not None:  # (it names its own parts: abbreviations are for the others)
        printed = printed_form(staged, step, printer, explicit)
        if printed is not None:
            printed.stage_notation = True
            return printed
    abbreviations = with_named_denominator(step, abbreviations)
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
            return _as_derived_if_shorter(printed, step, printer)
    raise LatexVerificationError(f"{step.name}: the printed equations differ from the "
                                 f"residuals")


def _as_derived_if_shorter(printed: Printed, step, printer: GroupoidLatexPrinter) -> Printed:
    """``printed``, or the residuals as derived, not expanded (their terms collected), when
    ``printed`` names nothing (no "where" list: the forces, pieces and abbreviations it
    names are kept) and the residuals as derived are shorter by more than a third:
    expanding a quotient by a sum spreads it over the sum's terms,
    (q_{k+1} − q_k)²/(2(t_{k+1} − t_k)²) into three quotients by 2t_{k+1}² − 4t_{k+1}t_k +
    2t_k²."""
    if printed.definitions:
        return printed
    derived = collected_form(Form(list(step.residuals), expanded=False), step, printer)
    if 3 * derived.length >= 2 * printed.length:
        return printed
    return checked_form(derived, step, printer, step.residuals) or printed


def with_named_denominator(step, abbreviations: Mapping | None) -> Mapping | None:
    """``abbreviations`` and, when a polynomial of one arrow divides terms of the residuals
    more than once (:func:`~._denominators.shared_denominator`), that polynomial named per
    arrow, under the first name of :data:`~._denominators.NAMES` that neither the step's
    symbols nor the user's abbreviations print as.  It is not the user's: never reported
    unused."""
    arrows = {o: tuple(step.groupoid.named_arrow(o)) for o in window(step.order)[0]}
    found = shared_denominator(step.residuals, arrows, step.parameters)
    if found is None:
        return abbreviations
    given = dict(abbreviations or {})
    taken = {a.tex for a in abbreviations_of(given, step)}
    name = free_name(taken | {latex(s) for s in printed_symbols(step)})
    return given if name is None else {**given, name: found}


def candidate_forms(step, abbreviations: Mapping | None = None,
                    matrix_form: bool = False) -> list[tuple[Form, object]]:
    """The forms of the step, each with the rule of its pieces (None: no pieces), in matrix
    form (none when the matrix form keeps no matrix by name) or explicit: the derived form
    (:func:`base_form`), the window in named pieces, the partial derivatives of L in them,
    each with recognised matrix pieces (W_kᵀΓ_k) and the ``abbreviations``."""
    abbreviations = abbreviations_of(abbreviations, step)
    base = base_form(step, matrix_form)
    if base is None or matrix_form and _constants_clash(step):
        return []
    # a forced step: its forces named, always (with internal stages the forces also enter
    # the stage rows, which that form does not name: such a step prints as derived, or in
    # the stage notation)
    forced = None if step.stages else forced_form(step, matrix_form)
    forms: list = [(base if forced is None else forced, None)]
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


def _piece_forms(step, matrix_form: bool = False) -> list[tuple[Form, PieceRule]]:
    """The forms of the step in the named pieces of the rule L is shortest in (none when L
    is not written in pieces or the step is not a junction variation of L), in matrix form
    or explicit."""
    system = junction_system(step)
    if system is None:
        return []
    try:
        rule = best_rule(system.functions, pair_coordinates(step.groupoid), step.parameters)
    except NOT_IN_PIECES:
        return []
    out = []
    for build in (piece_form, derivative_form):
        try:
            form = build(step, rule, matrix_form) if rule is not None else None
        except NOT_IN_PIECES:
            form = None
        if form is not None:
            out.append((form, rule))
    return out


def _constants_clash(step) -> bool:
    """Whether a constant matrix that the step's matrix form keeps by name (a Lie algebra's
    basis E_a, a user's J_d), or a unit vector e_i the "where" list writes a basis in,
    prints as one of the step's symbols (a parameter E1, written E_{1}): the printed
    equations would use one name for two things, and the "where" list would define the
    parameter as a matrix, so the matrix form is not offered (the step prints with the
    matrices' entries)."""
    names = {latex(s) for s in printed_symbols(step)}
    return not names.isdisjoint(constant_names(step))


def _no_clash(form: Form, step) -> bool:
    """The piece names print unlike every name the step already uses: no symbol of the
    step prints as a piece at any subscript (a parameter xbar as the midpoint x̄, which
    sits beside x̄_{k+1/2}), and, in the form with L's partial derivatives, none as L (a
    length L beside ∂_{Δx} L).  Compared as they typeset (:func:`rendered`)."""
    names = {rendered(latex(s)) for s in [*step.knowns, *step.unknowns, *step.fibre_unknowns,
                                          *step.parameters]}
    pieces = [*printed_pieces(step), *(p for layer in form.layers[:2] for p in layer)]
    if form.unindexed and "L" in names:
        return False
    return names.isdisjoint(rendered(latex(p)) for p in pieces)


