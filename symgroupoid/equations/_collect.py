"""Terms collected by multipliers, parameters and common coefficients, as the papers write
them: λ·(…), h·(…), (Ω h/2)·(…), ½·(a + b); the shortest printing of the orders tried is
kept.  A collected sum is a :class:`~._latex.Collected` (printed by type, never by editing
strings), and what it stands for is checked where it is printed.  A value (an abbreviation,
a recognised matrix piece) is recognised in a sum by :func:`replace_occurrences`.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from .._symbols import StepSymbol
from ._latex import Collected, GroupoidLatexPrinter
from ._layout import Term


def collect_terms(expr: sp.Expr, multipliers: Sequence, parameters: Sequence,
                  printer: GroupoidLatexPrinter, variables: bool = False,
                  expand: bool = True) -> list[Term]:
    """The terms of ``expr`` collected by multipliers and parameters (as SymPy's ``collect``
    does, one symbol after the other: λ·(…), h·(…), (Ω h/2)·(…)), then by common numeric
    coefficients (½·(a + b)); factors common to all the terms of a collected sum are taken
    out in front.  Both orders — multipliers first, parameters first — are tried (and, with
    ``variables``, the step variables before the parameters: for a "where" row, which is at
    one index); the shortest printing is kept.  Single terms stay as they are.  With
    ``expand`` false the terms are those of ``expr`` as it is (an equation as derived)."""
    from ._layout import signed_terms

    ordered = _by_number(
        [t.sign * t.expr for t in signed_terms(sp.expand(expr) if expand else expr, printer)])
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


def _by_number(terms: list) -> list:
    """Terms that differ only in their numeric coefficients, which expanding leaves apart
    when one is irrational (√3·sin Q and 3·sin Q: the Gauss nodes' surds), as one term
    (3 + √3)·sin Q, its coefficient over a common denominator, in the place of the first;
    terms whose coefficients cancel are left out."""
    groups: dict = {}
    for t in terms:
        number, rest = t.as_independent(*t.free_symbols, as_Add=False)
        groups.setdefault(rest, []).append(number)
    out = []
    for rest, numbers in groups.items():
        if len(numbers) == 1:
            out.append(numbers[0] * rest)
            continue
        total = sp.factor_terms(sp.Add(*numbers))  # −(3 + √3)/12, not −1/4 − √3/12
        if total != 0:
            out.append(total * rest)
    return out


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
    if all(c.is_Rational for c in coeffs):
        denominator = sp.ilcm(1, *[c.q for c in coeffs])
        factor = sp.Rational(sp.igcd(*[int(abs(c) * denominator) for c in coeffs]),
                             denominator)
    else:  # a coefficient written as a float (0.5): no common rational factor to take out
        factor = sp.S.One
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


# --- recognising a value ----------------------------------------------------------------------


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
    if isinstance(expr, sp.Mul) and isinstance(value, sp.Mul):
        matched = _match_product(expr, value, symbol)
        if matched is not None:
            return _replaced(matched, value, symbol)
    args = [_replaced(a, value, symbol) for a in expr.args]
    if all(a is b for a, b in zip(args, expr.args)):
        return expr
    return expr.func(*args)


def _match_product(expr: sp.Mul, value: sp.Mul, symbol: sp.Expr) -> sp.Expr | None:
    """expr / value · symbol if every factor of the product ``value`` (its numeric
    coefficient aside) is a factor of ``expr`` to at least its positive integer power, else
    None: a value m₂·l found in the term −l·m₂·Δθ."""
    _, factors = value.as_coeff_Mul()
    wanted = factors.as_powers_dict()
    if len(wanted) < 2:
        return None
    have = expr.as_powers_dict()
    for base, power in wanted.items():
        held = sp.sympify(have.get(base, 0))
        if not (power.is_Integer and power > 0 and held.is_Integer and held >= power):
            return None
    return expr / value * symbol


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
