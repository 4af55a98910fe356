"""The printed rows of the discrete Legendre transforms (seed 000 §3.3) and of the
Lie–Poisson equations (seed 000 §6.1): each collected, verified and broken to the page, with
Ad*_{g_k} a named operator where the rows hold with it.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp
from sympy.matrices.expressions.matexpr import MatrixElement

from .._symbols import StepSymbol, multiplier_symbols
from ..derivation import momentum_symbols
from ._abbreviations import printed_symbols
from ._denominators import NamedDenominators
from ._forms import Definition, equals_explicit
from ._latex import MemoLatexPrinter, NamedOperator
from ._layout import PrintedRows, Row, Term, Text
from ._pieces import generic_arrow, generic_renaming, half_label, indexed_name, pair_coordinates
from ._rows import check_width, definition_rows, multipliers_of, verified_terms

# --- Legendre transforms (seed 000 §3.3) ---------------------------------------------------------



def inline_latex(expr: sp.Expr, multipliers: Sequence, parameters: Sequence) -> str:
    """``expr`` collected and verified (:func:`verified_terms`), on one line."""
    from ._layout import term_text

    printer = MemoLatexPrinter()
    terms = verified_terms(expr, multipliers, parameters, printer, "the expression")
    return " ".join(term_text(t, i == 0, printer) for i, t in enumerate(terms))


def quantity_rows(expr: sp.Expr, multipliers: Sequence, parameters: Sequence,
                  width: float | None = None) -> PrintedRows:
    """F_X = ``expr``, collected and verified (:func:`verified_terms`), broken to ``width``
    pt as one row of an ``align``."""
    width = check_width(width)
    printer = MemoLatexPrinter()
    lhs = printer.doprint(StepSymbol("F_{X}"))
    return PrintedRows([Row(lhs, verified_terms(expr, multipliers, parameters, printer, lhs))],
                       width, printer)


def legendre_rows(lt, width: float | None = None) -> PrintedRows:
    """(𝔽⁻L)_a = X⃗_a[L + λ·φ](g_k), then (𝔽⁺L)_a = X⃖_a[L + λ·φ](g_k): each collected by
    multipliers, variables and parameters, verified, and broken to ``width`` pt."""
    width = check_width(width)
    printer = MemoLatexPrinter()
    items: list = []
    named = NamedDenominators({0: lt.arrow}, [*lt.minus, *lt.plus], lt.parameters,
                              [*lt.arrow, *lt.multipliers, *lt.parameters])
    for sign, forms in (("-", lt.minus), ("+", lt.plus)):
        for a, e in enumerate(forms):
            lhs = printer.doprint(StepSymbol(f"(\\mathbb{{F}}^{{{sign}}}L)_{{{a + 1}}}"))
            items.append(Row(lhs, verified_terms(named(e), lt.multipliers, lt.parameters,
                                                 printer, lhs)))
    if named.used_in(t.expr for row in items for t in row.terms):
        items.append(Text("where"))
        items += definition_rows([named.definition(lt.arrow, "k")], lt.parameters, printer)
    return PrintedRows(items, width, printer)


# --- Lie–Poisson equations (seed 000 §6.1) ------------------------------------------------------


def lie_poisson_rows(lp, width: float | None = None) -> PrintedRows:
    """μ_{k+1} = Ad*_{g_k} μ_k, then 0 = 𝔽⁻L_{k+1} − Ad*_{g_k} 𝔽⁻L_k (componentwise) and the
    constraints, with Ad* printed as a named operator and 𝔽⁻L_j = μ(g_j) + λ_j·Φ(g_j) in a
    "where" list.  Each printed row is verified against the explicit update and residuals,
    with Ad*_{g_k} written out; rows that fail print explicitly (collected, verified)."""
    width = check_width(width)
    printer = MemoLatexPrinter()
    step = lp.reconstruction
    G, rank, m = step.groupoid, len(lp.momentum_symbols), step.n_constraints
    multipliers = multipliers_of(step)

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
    named = NamedDenominators({0: g0, 1: g1}, [*lp.momentum, *lp.residuals[rank:]],
                              step.parameters, printed_symbols(step),
                              half_label if pair_coordinates(G) else None)
    shift = dict(zip(g0, g1))
    shift.update(zip(multiplier_symbols(m, 0), multiplier_symbols(m, 1)))
    shift.update(named.shift(0, 1))
    momentum = [sp.expand(named(e)) for e in lp.momentum]
    layer = {ad: ad_value, F[0]: sp.ImmutableMatrix(momentum),
             F[1]: sp.ImmutableMatrix([e.xreplace(shift) for e in momentum])}
    residual = sp.MatAdd(F[1], sp.MatMul(-1, ad, F[0]))
    if all(equals_explicit(MatrixElement(residual, a, 0), r, [layer, named.values])
           for a, r in enumerate(lp.residuals[:rank])):
        items.append(Row("0", [Term(1, F[1]), Term(-1, sp.MatMul(ad, F[0]))]))
        where = _momentum_definitions(G, momentum, m, named)
    else:
        where = []
        items += [explicit_row("0", r) for r in lp.residuals[:rank]]
    constraints = [named(r) for r in lp.residuals[rank:]]
    items += [explicit_row("0", r) for r in constraints]
    if not where and named.used_in(constraints):
        items.append(Text("where, for $j = k+1$,"))
        items += definition_rows([named.definition(generic_arrow(G))], step.parameters,
                                 printer)
    momenta = (r"where $\mu_{j}$ is the momentum the integrator carries from step to step: "
               r"the reconstruction solves $(\mathbb{F}^{-}L)_{k+1} = \mu_{k+1}$ for the new "
               r"arrow")
    if where:  # (an \intertext ends no align)
        items.append(Text(momenta + ", and, for $j = k, k+1$,"))
        items += definition_rows(where, step.parameters, printer)
    return PrintedRows(items, width, printer)


def _momentum_definitions(G, momentum: Sequence, m: int,
                          named: NamedDenominators) -> list[Definition]:
    """(𝔽⁻L_j)_a = X⃗_a[L + λ_j·φ](g_j) at the generic index j, and the named denominator
    D_j when they read it."""
    rename = generic_renaming(G)
    rename.update({lam: StepSymbol(f"({indexed_name(chr(92) + 'lambda', 'j')})_{{{b + 1}}}")
                   for b, lam in enumerate(multiplier_symbols(m, 0))})
    rename.update(named.generic(0))
    out = []
    for a, e in enumerate(momentum):
        lhs = StepSymbol(f"({indexed_name(chr(92) + 'mathbb{F}^{-}L', 'j')})_{{{a + 1}}}")
        out.append(Definition(lhs, e.xreplace(rename), frozenset([lhs]), literal=False))
    if named.used_in(momentum):
        out.append(named.definition(generic_arrow(G)))
    return out
