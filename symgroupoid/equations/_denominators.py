"""A polynomial of one arrow that divides many terms of the printed equations, named.

A Lagrangian written in a retraction's coordinates reads each arrow through a rational map:
on SO(3) with the Cayley retraction, τ⁻¹(g) = 2 vee(g − gᵀ)/(1 + tr g) (seed 000 §6.1,
docs/conventions.md §1).  Its derivatives divide by powers of D(g) = 1 + tr g, and expanded,
every such term carries the whole polynomial, (g₁₁ + g₂₂ + g₃₃ + 1)² written out as ten
monomials: the optimal-control equations of seed 000 §6.1 on SO(3) printed lines of 1,855 pt
where a page has 450.  A paper names that polynomial; so does the printing: the base of a
negative power that occurs most often, in the coordinates of a single arrow of the window,
is printed as D_j (D_k, D_{k+1}, …) and defined in the "where" list.  It is an
abbreviation like the user's (:mod:`._abbreviations`), checked with the printed form.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import sympy as sp

#: the names tried, in order, for the named denominator (the first that no symbol of the
#: equations and no abbreviation of the user's prints as)
NAMES = ("D", r"\mathcal{D}", r"\Delta_{D}")

#: a base with fewer terms than this is printed as it is
MIN_TERMS = 3


@dataclass(frozen=True)
class NamedDenominator:
    """The polynomial ``polynomial`` (in ``coordinates``, the coordinates of one arrow) as a
    function of an arrow: what a callable abbreviation is (:mod:`._abbreviations`)."""

    polynomial: sp.Expr
    coordinates: tuple

    def __call__(self, arrow) -> sp.Expr:
        return self.polynomial.xreplace(dict(zip(self.coordinates, arrow.coords)))

    def at(self, coordinates: Sequence) -> sp.Expr:
        """The polynomial on the arrow with these coordinates."""
        return self.polynomial.xreplace(dict(zip(self.coordinates, coordinates)))


def shared_denominator(expressions: Iterable[sp.Expr], arrows: Mapping[object, Sequence],
                       parameters: Sequence = ()) -> NamedDenominator | None:
    """The base of a negative power (a sum of at least :data:`MIN_TERMS` terms) that occurs
    most often in ``expressions``, counted over the arrows ``arrows`` (key → coordinates)
    it can be read on — the same polynomial on g_k and g_{k+1} counts once for both —
    written on the first arrow; None when no base occurs twice.  A base counts only when its
    symbols other than ``parameters`` are the coordinates of exactly one arrow."""
    keys = list(arrows)
    if not keys:
        return None
    first = tuple(arrows[keys[0]])
    owners = _owners(arrows)
    counts: Counter = Counter()
    for expr in expressions:
        for node in sp.preorder_traversal(sp.sympify(expr)):
            if not (isinstance(node, sp.Pow) and isinstance(node.base, sp.Add)
                    and node.exp.is_negative and len(node.base.args) >= MIN_TERMS):
                continue
            key = _single_arrow(node.base, owners, set(parameters))
            if key is not None:
                counts[node.base.xreplace(dict(zip(arrows[key], first)))] += 1
    if not counts:
        return None
    polynomial, n = max(counts.items(), key=lambda item: (item[1], -len(str(item[0])),
                                                          str(item[0])))
    return NamedDenominator(polynomial, first) if n >= 2 else None


def free_name(taken: Iterable[str]) -> str | None:
    """The first of :data:`NAMES` not in ``taken`` (LaTeX names)."""
    taken = set(taken)
    return next((name for name in NAMES if name not in taken), None)


def _owners(arrows: Mapping[object, Sequence]) -> dict:
    """Each coordinate symbol → the arrows it is a coordinate of."""
    out: dict = {}
    for key, coords in arrows.items():
        for c in coords:
            if isinstance(c, sp.Symbol):
                out.setdefault(c, set()).add(key)
    return out


def _single_arrow(base: sp.Expr, owners: dict, parameters: set):
    """The one arrow whose coordinates (with the parameters) hold all of ``base``'s symbols,
    or None (none does, or several do: on a pair groupoid q_k is a coordinate of g_k and of
    g_{k+1}, so a polynomial in q_k alone is not one arrow's, one in q_{k−1} and q_k is)."""
    found: set | None = None
    for s in base.free_symbols - parameters:
        keys = owners.get(s)
        if keys is None:
            return None
        found = set(keys) if found is None else found & keys
        if not found:
            return None
    return next(iter(found)) if found is not None and len(found) == 1 else None


class NamedDenominators:
    """The shared denominator of ``expressions`` (:func:`shared_denominator`) on the arrows
    ``arrows`` (offset → coordinates), named D_{k+offset} (subscript ``label(index,
    offset)``) under the first name of :data:`NAMES` that none of the ``printed`` symbols
    prints as; calling it names the polynomial in an expression (the expression unchanged
    where that would change its value, or when nothing is shared)."""

    def __init__(self, arrows: Mapping[int, Sequence], expressions: Iterable[sp.Expr],
                 parameters: Sequence, printed: Iterable[sp.Expr],
                 label: Callable[[str, int], str] | None = None):
        from ._latex import latex
        from ._pieces import arrow_label

        self.found = shared_denominator(expressions, arrows, parameters)
        self.name = free_name(latex(s) for s in printed)
        self.label = label or arrow_label
        self.symbols: dict = {}
        self.values: dict = {}
        if self.found is not None and self.name is not None:
            for o, coords in arrows.items():
                self.symbols[o] = self.symbol("k", o)
                self.values[self.symbols[o]] = self.found.at(coords)

    def symbol(self, index: str, offset: int) -> sp.Symbol:
        """D_{index+offset}."""
        from .._symbols import StepSymbol
        from ._pieces import indexed_name

        return StepSymbol(indexed_name(self.name, self.label(index, offset)))

    def __call__(self, expr: sp.Expr) -> sp.Expr:
        from ._collect import replace_occurrences
        from ._forms import equals_explicit

        out = expr
        for symbol, value in self.values.items():
            out = replace_occurrences(out, value, symbol)
        if out is expr or not equals_explicit(out, expr, [self.values]):
            return expr
        return out

    def shift(self, source: int, target: int) -> dict:
        """D at ``source`` → D at ``target`` (what shifts an expression along the window)."""
        if source not in self.symbols or target not in self.symbols:
            return {}
        return {self.symbols[source]: self.symbols[target]}

    def generic(self, offset: int) -> dict:
        """D at ``offset`` → D_j, the name its "where" row is printed with."""
        if offset not in self.symbols:
            return {}
        return {self.symbols[offset]: self.symbol("j", 0)}

    def used_in(self, expressions: Iterable[sp.Expr]) -> bool:
        """Whether a named D occurs in ``expressions``."""
        names = set(self.symbols.values()) | {self.symbol("j", 0)} if self.symbols else set()
        return any(s in names for e in expressions for s in sp.sympify(e).free_symbols)

    def definition(self, coordinates: Sequence, index: str = "j", offset: int = 0):
        """The "where" row D_{index+offset} = p(coordinates)."""
        from ._forms import Definition

        lhs = self.symbol(index, offset)
        return Definition(lhs, self.found.at(coordinates), frozenset([lhs]))
