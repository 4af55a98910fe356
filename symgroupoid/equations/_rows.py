"""A form's collected, checked terms, and the rows they print in.

Every printed equation — the pieces and abbreviations written out, matrices and named
operators by their values — is checked to equal the explicit residual (the expanded
difference is 0), and so is every "where" row; a form that fails is not printed.  The rows
(equations, then the "where" list, each group after its words) are broken to the page width
by :mod:`._layout`, which checks each break too (:func:`._layout.same_sum`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .._symbols import multiplier_symbols
from ..groupoids import is_constant_matrix
from ._abbreviations import LatexOptionError
from ._collect import collect_terms
from ._forms import Definition, Form, equals_explicit, explicit_value
from ._latex import GroupoidLatexPrinter, uncollected, unit_vector_dimension
from ._layout import PAGE_WIDTH, Definitions, PrintedRows, Row, Term, Text
from ._matrix_parts import keeps_matrices

#: the smallest scale a whole literal definition is meant to be set at
READABLE_SCALE = 0.75


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
    stage_notation: bool = False  # the papers' stage notation, which names its own parts
    staged: bool = False  # the step has internal stages ζ (docs/conventions.md §22)


def multipliers_of(step) -> list:
    lam = set()
    for offset in range(-2, 3):
        lam.update(multiplier_symbols(step.n_constraints, offset))
    return [s for s in [*step.knowns, *step.unknowns] if s in lam]


def collected_form(form: Form, step, printer: GroupoidLatexPrinter) -> Printed:
    """The collected terms of a form and the "where" rows they use, with the length of their
    printing; not yet checked (:func:`checked_form`)."""
    multipliers = multipliers_of(step)
    equations: list = []
    used: set = set()
    length = 0
    for equation in form.equations:
        terms = collect_terms(equation, multipliers, step.parameters, printer,
                              expand=form.expanded)
        used |= set().union(*[uncollected(t.expr).free_symbols for t in terms])
        length += sum(len(printer.doprint(t.expr)) + 3 for t in terms)
        equations.append(terms)
    for layer in form.layers:  # what the used names are written in is used too
        for name in list(used):
            if name in layer:
                used |= sp.sympify(layer[name]).free_symbols
    definitions = used_definitions(form.definitions, used)
    length += sum(_definition_length(d, step.parameters, printer) for d in definitions)
    # (the constants' values are stated once, whichever form: not counted against it)
    definitions = constant_definitions(used) + definitions
    return Printed(equations, definitions, form.intros, length, list(step.parameters),
                   list(form.layers), dict(form.generic), keeps_matrices(form.equations), form,
                   staged=bool(getattr(step, "stages", None)))


def checked_form(printed: Printed, step, printer: GroupoidLatexPrinter,
                 explicit: Sequence) -> Printed | None:
    """``printed`` if each of its equations, written out, is the explicit residual (an
    equation whose collected terms are not is printed uncollected, if that one is) and each
    "where" row holds; else None.  A form that prints fewer or more equations than there
    are residuals (e.g. pieces of the junction rows alone, without the stage rows of
    docs/conventions.md §22) is not the step."""
    form = printed.form
    if len(printed.equations) != len(explicit):
        return None
    for i, (terms, residual) in enumerate(zip(printed.equations, explicit)):
        if not equals_explicit(sp.Add(*[t.value() for t in terms]), residual, form.layers):
            terms = collect_terms(form.equations[i], (), (), printer)
            if not equals_explicit(sp.Add(*[t.value() for t in terms]), residual,
                                   form.layers):
                return None
            printed.equations[i] = terms
    if not all(is_constant_matrix(d.lhs) or _definition_holds(d, form)
               for d in printed.definitions):
        return None
    return printed


def printed_form(form: Form, step, printer: GroupoidLatexPrinter,
                 explicit: Sequence) -> Printed | None:
    """The collected terms of a form, or None when a printed equation is not the explicit
    residual (collected or not)."""
    return checked_form(collected_form(form, step, printer), step, printer, explicit)


def constant_definitions(used: set) -> list[Definition]:
    """A "where" row for each named constant matrix the equations print by name (``J_d`` of
    ``systems.rigid_body``, whose value the document would otherwise leave undefined), in the
    order of their names; each holds by construction (its value is what the name stands
    for)."""
    constants = sorted((s for s in used if is_constant_matrix(s)), key=str)
    return [Definition(c, c.value, frozenset({c})) for c in constants]


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


#: LaTeX characters of a literal definition's right-hand side beyond which it would be set
#: below three quarters of its size to fit a line (about 2.5 pt a character, the page's
#: width), or not fit at all: it is collected and broken like an equation instead
LONG_LITERAL = int(PAGE_WIDTH / 2.5 / READABLE_SCALE)


def definition_rows(definitions: Sequence[Definition], parameters: Sequence,
                    printer: GroupoidLatexPrinter) -> list:
    """The "where" rows: literal ones as :class:`~._layout.Definitions` (packed several to a
    line), the others — and the literal ones too long for any line (:data:`LONG_LITERAL`:
    a force's f^±_a written as one fraction ran off the page at half size) — collected by
    variables and parameters, checked, and broken like equations."""
    rows: list = []
    for d in definitions:
        if not d.literal or len(printer.doprint(d.rhs)) > LONG_LITERAL:
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
            items.append(Text(first_words(printed) if intro == 0 else printed.intros[intro]))
        items += definition_rows([d], printed.parameters, printer)
    return PrintedRows(_merged(items), width, printer)


#: what the words before the "where" rows say of a step's internal stages
STAGES_SAID = (r"$\zeta_{k}$ and $\zeta_{k+1}$ the internal stages of the known and the new "
               r"arrow (unknowns of the step)")


def first_words(printed: Printed) -> str:
    """The words before the first group of "where" rows, saying what the rows use but do
    not define: the internal stages ζ of a Galerkin step, and the unit vectors e_i when a
    named constant's row writes a matrix in them (E_1 = − e_2 e_3ᵀ + e_3 e_2ᵀ of so(3))."""
    said = [STAGES_SAID] if printed.staged else []
    sizes = sorted({n for d in printed.definitions if is_constant_matrix(d.lhs)
                    for n in [unit_vector_dimension(d.rhs)] if n is not None})
    if sizes:
        spaces = " and ".join(f"$\\mathbb{{R}}^{{{n}}}$" for n in sizes)
        said.append(f"$e_{{i}}$ the $i$-th standard unit vector of {spaces}")
    words = printed.intros[0]
    if not said:
        return words
    return f"{words}{'' if words.endswith(',') else ','} with {', and '.join(said)},"


def _merged(items: list) -> list:
    """Consecutive :class:`~._layout.Definitions` as one (packed together)."""
    out: list = []
    for item in items:
        if isinstance(item, Definitions) and out and isinstance(out[-1], Definitions):
            out[-1] = Definitions([*out[-1].pairs, *item.pairs])
        else:
            out.append(item)
    return out


#: the text widths a document may have (points): narrower than a few symbols prints nothing
#: readable, and TeX's dimensions end below 16384 pt
MIN_WIDTH, MAX_WIDTH = 20.0, 16000.0


def check_width(width) -> float:
    """The text width in points: None for the page's, else a real number from
    :data:`MIN_WIDTH` to :data:`MAX_WIDTH` (not a boolean, not a string); a
    :class:`LatexOptionError` otherwise."""
    if width is None:
        return PAGE_WIDTH
    value = float("nan")
    if not isinstance(width, (bool, np.bool_, str, bytes)):  # ("450": float would read it)
        try:
            value = float(width)
        except (TypeError, ValueError, OverflowError):  # (10**400: beyond a double)
            pass
    if not MIN_WIDTH <= value <= MAX_WIDTH:
        raise LatexOptionError(f"latex: width must be a number of points from "
                               f"{MIN_WIDTH:g} to {MAX_WIDTH:g}, got {width!r}")
    return value


def verified_terms(expr: sp.Expr, multipliers: Sequence, parameters: Sequence,
                   printer: GroupoidLatexPrinter, what: str) -> list[Term]:
    """``expr`` collected (:func:`collect_terms`, step variables too: it is at one arrow),
    checked to be ``expr``."""
    from ._layout import same_sum

    terms = collect_terms(expr, multipliers, parameters, printer, variables=True)
    same_sum(terms, [Term(1, sp.sympify(expr))], what)
    return terms


