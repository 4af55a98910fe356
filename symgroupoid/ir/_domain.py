"""The nodes of a graph that are defined on part of the real line only.

A Lagrangian such as v²/2 − log x is defined for x > 0; its step equations hold 1/x and
never log x, so they have roots on both sides of x = 0 and Newton finds them.  Where such a
root leaves the domain, the value of the partial function itself is not finite in IEEE
arithmetic (log of a non-positive number, a square root or other non-integer power of a
negative one, asin or acos beyond ±1, an opaque SymPy function outside its domain: NaN or
±inf), so the finiteness of these nodes at a step's solution tells whether the step stays
where L is defined (docs/conventions.md §11, "Staying in the domain of L").
"""

from __future__ import annotations

from collections.abc import Iterable

import sympy as sp

from ._functions import Opaque
from ._graph import FUNC, POW, Graph

#: elementary functions defined on part of the real line, by name → what their argument must be
_PARTIAL = {"log": "> 0", "asin": "in [-1, 1]", "acos": "in [-1, 1]"}


def _integral(e: sp.Expr) -> bool:
    """Whether a constant exponent is an integer (2 and 2.0 alike: C's pow of a negative base
    to 2.0 is finite)."""
    return bool(e.is_Integer or (e.is_Float and float(e).is_integer()))


def _total(spec: Opaque) -> bool:
    """Whether SymPy knows an opaque function to be real for every real argument (asinh,
    atan of a sum, …): no domain to leave."""
    real = {x: sp.Dummy(real=True) for x in spec.placeholders}
    return spec.expr.xreplace(real).is_real is True


def domain_kind(g: Graph, node: int) -> str | None:
    """What ``node`` needs of its argument to be finite, in words (``"log needs a positive
    argument"``), or None for a node defined on the whole real line (given finite
    arguments)."""
    op = g.op[node]
    if op == POW:
        e = g.data[node]
        if _integral(e):
            return None
        return f"the power {e} needs a base {'> 0' if e.is_negative else '>= 0'}"
    if op != FUNC:
        return None
    spec = g.data[node]
    if isinstance(spec, Opaque):
        return None if _total(spec) else f"{type(spec.expr).__name__} needs a finite value"
    need = _PARTIAL.get(getattr(spec, "name", None))
    return f"{spec.name} needs an argument {need}" if need else None


def domain_nodes(g: Graph, outputs: Iterable[int], varying: Iterable[int] | None = None
                 ) -> list[int]:
    """The nodes the ``outputs`` depend on that are defined on part of the real line only
    (:func:`domain_kind`), ascending; with ``varying`` (input nodes), only those that depend
    on one of them (a square root of a parameter is checked with the parameters, not at
    every step)."""
    order = g.reachable(list(outputs))
    moving = None if varying is None else g.dependents(varying, order)
    return [i for i in order if domain_kind(g, i) is not None
            and (moving is None or i in moving)]


__all__ = ["domain_kind", "domain_nodes"]
