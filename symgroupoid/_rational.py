"""An exact zero test for rational expressions, without bringing them over one denominator
by SymPy's ``together`` (whose pairwise gcds take seconds on the printed equations of a
Lie group in Cayley coordinates, whose denominators are powers of 1 + tr g in several
expanded forms).

:func:`vanishes` factors each distinct denominator once (``factor_list`` over Q), writes
every term over the least common multiple of the irreducible factors, and adds the
numerators as sparse polynomials: the expression is the zero rational function exactly
when that numerator is the zero polynomial.  Expressions that are not rational in their
symbols over Q (square roots, functions) are left to the caller (``None``)."""

from __future__ import annotations

import sympy as sp
from sympy.polys.domains import QQ
from sympy.polys.polyerrors import CoercionFailed, GeneratorsNeeded, PolynomialError
from sympy.polys.rings import PolyRing


def _split(term: sp.Expr) -> tuple[sp.Expr, dict]:
    """(numerator, {base: multiplicity}) of a product: its factors b**(−n), n a positive
    integer and b not a number, form the denominator."""
    numerator, denominator = [], {}
    for f in sp.Mul.make_args(term):
        if f.is_Pow and f.exp.is_Integer and f.exp < 0 and not f.base.is_number:
            denominator[f.base] = denominator.get(f.base, 0) - int(f.exp)
        else:
            numerator.append(f)
    return sp.Mul(*numerator), denominator


def vanishes(expr: sp.Expr) -> bool | None:
    """Whether ``expr`` (a sum of products, as ``expand`` leaves it) is identically zero as
    a rational function of its symbols; None when it is not a rational function over Q
    (the caller then decides otherwise)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    gens = sorted(expr.free_symbols, key=sp.default_sort_key)
    if not gens:
        return None
    try:
        return _numerator(expr, gens) == 0
    except (CoercionFailed, GeneratorsNeeded, PolynomialError):
        return None


def _polynomial(R: PolyRing, expr: sp.Expr):
    """``expr`` as an element of R; CoercionFailed when it is not a polynomial over Q."""
    try:
        return R.from_expr(expr)
    except ValueError as exc:  # from_expr's "expected an expression convertible to …"
        raise CoercionFailed(str(exc)) from None


def _numerator(expr: sp.Expr, gens: list):
    """Σ_t (n_t / c_t)·Π_f f^(m_f − m_{t,f}): the numerator of ``expr`` over the least common
    multiple Π_f f^(m_f) of its terms' denominators c_t·Π_f f^(m_{t,f}) (f irreducible over
    Q), as a polynomial of the ring Q[gens]."""
    R = PolyRing(gens, QQ)
    factored: dict = {}
    groups: dict = {}
    for term in sp.Add.make_args(expr):
        numerator, denominator = _split(term)
        constant, own = sp.S.One, {}
        for base, n in denominator.items():
            if base not in factored:
                factored[base] = sp.factor_list(base, *gens)
            c, factors = factored[base]
            constant *= c ** n
            for f, m in factors:
                own[f] = own.get(f, 0) + m * n
        if not constant.is_Rational:
            raise CoercionFailed(f"a denominator's constant {constant} is not rational")
        key = frozenset(own.items())
        groups[key] = groups.get(key, R.zero) + _polynomial(R, numerator) * QQ.convert(1 / constant)
    lcm: dict = {}
    for key in groups:
        for f, m in key:
            lcm[f] = max(lcm.get(f, 0), m)
    polys = {f: _polynomial(R, f) for f in lcm}
    total = R.zero
    for key, part in groups.items():
        if not part:
            continue
        own = dict(key)
        for f, m in lcm.items():
            if m > own.get(f, 0):
                part = part * polys[f] ** (m - own.get(f, 0))
        total += part
    return total


__all__ = ["vanishes"]
