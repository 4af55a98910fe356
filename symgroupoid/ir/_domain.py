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

from ._functions import Opaque
from ._graph import FUNC, POW, Graph

#: elementary functions defined on part of the real line, by name → what their argument must be
_PARTIAL = {"log": "positive", "asin": "in [-1, 1]", "acos": "in [-1, 1]"}


def domain_kind(g: Graph, node: int) -> str | None:
    """What ``node`` needs of its argument to be finite, in words (``"log: its argument
    positive"``), or None for a node defined on the whole real line (given finite
    arguments)."""
    op = g.op[node]
    if op == POW:
        e = g.data[node]
        if not e.is_Integer:
            need = "positive" if e.is_negative else "non-negative"
            return f"the power {e} of a number: the number {need}"
        return None
    if op != FUNC:
        return None
    spec = g.data[node]
    if isinstance(spec, Opaque):
        return f"the function {str(spec.expr)[:60]} of {spec.nargs} argument(s): a finite value"
    need = _PARTIAL.get(getattr(spec, "name", None))
    return f"{spec.name}: its argument {need}" if need else None


def domain_nodes(g: Graph, outputs: Iterable[int]) -> list[int]:
    """The nodes the ``outputs`` depend on that are defined on part of the real line only
    (:func:`domain_kind`), ascending."""
    return [i for i in g.reachable(list(outputs)) if domain_kind(g, i) is not None]


__all__ = ["domain_kind", "domain_nodes"]
