"""Cheap bounds on the size of SymPy expressions.

``sympy.count_ops`` walks a tree with its repetitions: on the Legendre transforms of a
midpoint step on SO(3) with a potential it takes a minute, to answer a question (at most a
few hundred operations?) that the first thousand nodes already decide.
"""

from __future__ import annotations

import sympy as sp

#: every node of a SymPy tree with k arguments carries at least one of ``count_ops``'
#: operations, or is merged into its parent's (−1 into a subtraction, ``Pow(y, −1)`` into a
#: division): at most this many nodes per operation (measured worst case 4, on random
#: trees of sums, products, powers and functions)
NODES_PER_OPERATION = 8


def nodes_at_most(expr: sp.Basic, limit: int) -> bool:
    """Whether ``expr``'s tree, with its repetitions, has at most ``limit`` nodes (walking
    at most ``limit`` + 1 of them)."""
    for n, _ in enumerate(sp.preorder_traversal(expr)):
        if n >= limit:
            return False
    return True


def ops_at_most(expr: sp.Basic, limit: int) -> bool:
    """``sympy.count_ops(expr) <= limit``, counting the operations only of a tree of at most
    :data:`NODES_PER_OPERATION` · (limit + 1) nodes; a larger tree is taken to have more
    than ``limit`` (twice the worst ratio measured).  Where that bound were wrong, a small
    defect would be decided numerically instead of symbolically: never a wrong verdict."""
    return (nodes_at_most(expr, NODES_PER_OPERATION * (limit + 1))
            and sp.count_ops(expr) <= limit)


__all__ = ["NODES_PER_OPERATION", "nodes_at_most", "ops_at_most"]
