"""An exact zero test for rational expressions, without bringing them over one denominator
by SymPy's ``together`` (whose pairwise gcds take seconds on the printed equations of a
Lie group in Cayley coordinates, whose denominators are powers of 1 + tr g in several
expanded forms).

:func:`vanishes` factors each distinct denominator once (``factor_list`` over Q), writes
every term over the least common multiple of the irreducible factors, and adds the
numerators as sparse polynomials: the expression is the zero rational function exactly
when that numerator is the zero polynomial.  Square roots of integers (the nodes of the
Gauss–Legendre schemes) stand for symbols s_p, one per prime p, with s_p² = p, by which the
numerator is reduced at the end.  Expressions that are not rational in their symbols over
Q(√p, …) (functions, other roots) are left to the caller (``None``)."""

from __future__ import annotations

import random

import sympy as sp
from sympy.polys.domains import QQ
from sympy.polys.polyerrors import CoercionFailed, GeneratorsNeeded, PolynomialError
from sympy.polys.rings import PolyRing


def vanishes(expr: sp.Expr) -> bool | None:
    """Whether ``expr`` (a sum of products, as ``expand`` leaves it) is identically zero as
    a rational function of its symbols; None when it is not a rational function over Q and
    square roots of integers (the caller then decides otherwise)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    primes = _surds(expr)
    if primes is None:
        return None
    expr = expr.xreplace({sp.sqrt(n): sp.Mul(*[primes[q] for q in sp.primefactors(n)])
                          for n in _square_roots(expr)})
    gens = sorted(expr.free_symbols, key=sp.default_sort_key)
    if not gens:
        return None
    try:
        total = _numerator(expr, gens)
        for q, s in primes.items():  # s² = q: what remains is Σ c_e Π s^e, e ∈ {0, 1}
            total = total.rem(_polynomial(total.ring, s ** 2 - q))
        return total == 0
    except (CoercionFailed, GeneratorsNeeded, PolynomialError):
        return None


def _square_roots(expr: sp.Expr) -> set[int]:
    """The integers n whose square roots √n appear in ``expr``."""
    return {int(p.base) for p in expr.atoms(sp.Pow)
            if p.base.is_Integer and p.exp == sp.S.Half}


def _surds(expr: sp.Expr) -> dict | None:
    """{p: a symbol standing for √p} for the primes p of the square roots √n in ``expr``,
    each √n to be written as Π √p over the primes of n: the products Π √p^{e_p},
    e_p ∈ {0, 1}, of distinct primes are linearly independent over Q, which the reduction
    modulo s_p² − p relies on.  None for the square root of an integer that is not
    square-free or not above 1 (SymPy leaves none)."""
    out: dict = {}
    for n in sorted(_square_roots(expr)):
        factors = sp.factorint(n)
        if n <= 1 or any(e > 1 for e in factors.values()):
            return None
        for q in factors:
            out.setdefault(q, sp.Dummy(f"sqrt{q}"))
    return out


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


def _polynomial(R: PolyRing, expr: sp.Expr):
    """``expr`` as an element of R; CoercionFailed when it is not a polynomial over Q."""
    try:
        return R.from_expr(expr)
    except ValueError as exc:  # from_expr's "expected an expression convertible to …"
        raise CoercionFailed(str(exc)) from None


def _numerator(expr: sp.Expr, gens: list):
    """Σ_t n_t·Π_a a^(m_a − m_{t,a}): the numerator of ``expr`` over the common multiple
    Π_a a^(m_a) of its terms' denominators Π_a a^(m_{t,a}), the atoms a being its distinct
    denominator polynomials, each made primitive (its content moved to the numerator) and
    written as a power of an atom already met where it is one (1 + tr g and its expanded
    square and cube: :func:`_atoms`), as a polynomial of the ring Q[gens]."""
    R = PolyRing(gens, QQ)
    atoms: list = []  # (polynomial, its total degree)
    known: dict = {}  # base expression -> (constant, atom index, power)
    groups: dict = {}
    for term in sp.Add.make_args(expr):
        numerator, denominator = _split(term)
        part, own = _polynomial(R, numerator), {}
        for base, n in denominator.items():
            if base not in known:
                known[base] = _atom(_polynomial(R, base), atoms)
            constant, index, power = known[base]
            part = part.quo_ground(constant ** n)
            own[index] = own.get(index, 0) + power * n
        key = frozenset(own.items())
        groups[key] = groups.get(key, R.zero) + part
    most: dict = {}
    for key in groups:
        for index, m in key:
            most[index] = max(most.get(index, 0), m)
    total = R.zero
    for key, part in groups.items():
        if not part:
            continue
        own = dict(key)
        for index, m in most.items():
            if m > own.get(index, 0):
                part = part * atoms[index][0] ** (m - own.get(index, 0))
        total += part
    return total


def _atom(base, atoms: list) -> tuple:
    """(c, i, k) with base = c·atoms[i]^k: the base made primitive with a positive leading
    coefficient, matched as a power of an atom of lower degree, else a new atom."""
    if not base:
        raise CoercionFailed("a denominator is zero")
    constant, primitive = base.primitive()
    if primitive.LC < 0:
        constant, primitive = -constant, -primitive
    degree = _total_degree(primitive)
    for i, (atom, d) in enumerate(atoms):
        if d and degree % d == 0 and atom ** (degree // d) == primitive:
            return constant, i, degree // d
    atoms.append((primitive, degree))
    return constant, len(atoms) - 1, 1


def _total_degree(p) -> int:
    return max((sum(monomial) for monomial in p.itermonoms()), default=0)


__all__ = ["vanishes"]


#: the expanded size (terms) from which :func:`vanishes_at_points` stands in for
#: :func:`vanishes`: bringing a few thousand terms with powers of several Cayley
#: denominators over their common multiple takes hours (a heavy top with rotors, seed 001
#: §3.3.5), where evaluating them at a point takes a second
LARGE_TERMS = 400

#: the random points of :func:`vanishes_at_points` and the range of their coordinates'
#: numerators and denominators (from a fixed seed: the same decision on every run)
POINTS, SPREAD, SEED = 3, 2**31, 0x5EED


def is_rational_expression(expr: sp.Expr) -> bool:
    """Whether ``expr`` is built from symbols and rational numbers by sums, products and
    integer powers only (a rational function over Q)."""
    for node in sp.preorder_traversal(expr):
        if node.is_Symbol or node.is_Rational or node.is_Add or node.is_Mul:
            continue
        if node.is_Pow and node.exp.is_Integer:
            continue
        return False
    return True


def expanded_vanishes(difference: sp.Expr) -> bool:
    """Whether an expanded difference of two forms of an equation is identically zero: as
    expanded; beyond :data:`LARGE_TERMS` terms at random points (:func:`vanishes_at_points`);
    over the lcm of its factored denominators (:func:`vanishes`: 2X/(2t₁² − 4t₁t₀ + 2t₀²)
    − X/(t₁ − t₀)², which ``expand`` leaves apart); else over a common denominator, with
    functions (sin, cos) as generators (``cancel``)."""
    if difference == 0:
        return True
    if len(sp.Add.make_args(difference)) > LARGE_TERMS:  # (the common denominator: hours)
        zero = vanishes_at_points(difference)
        if zero is not None:
            return zero
    zero = vanishes(difference)
    if zero is not None:
        return zero
    return sp.cancel(sp.together(difference)) == 0


def vanishes_at_points(expr: sp.Expr) -> bool | None:
    """Whether the rational function ``expr`` of its symbols is zero, by exact evaluation at
    :data:`POINTS` random rational points (Schwartz–Zippel: a nonzero numerator of degree d
    vanishes at a point drawn from a set of N values per coordinate with probability at
    most d/N; here N is about 2⁶¹, so for every degree these equations reach the chance of
    a false "zero" at three points is below 10⁻⁴⁵).  A nonzero value proves the expression
    nonzero.  Points where a denominator vanishes are drawn again.  None when ``expr`` is
    not a rational function over Q (:func:`is_rational_expression`)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    if not is_rational_expression(expr):
        return None
    gens = sorted(expr.free_symbols, key=sp.default_sort_key)
    draw = random.Random(SEED)
    found = 0
    for _ in range(20 * POINTS):
        point = {s: sp.Rational(draw.randint(1, SPREAD), draw.randint(1, SPREAD)) for s in gens}
        value = expr.xreplace(point)
        if not value.is_Rational:  # a denominator vanished there (zoo, nan): another point
            continue
        if value != 0:
            return False
        found += 1
        if found == POINTS:
            return True
    return None
