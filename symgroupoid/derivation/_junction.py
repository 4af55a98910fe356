"""The one derivation mechanism: vary a composable sequence at a junction, differentiate at 0.

For a discrete action ``S(g_1, …, g_n)`` written in *independent* arrow slots, the variation
at the junction between ``g_j`` and ``g_{j+1}`` is

    g_j ↦ g_j · h(t),    g_{j+1} ↦ h(t)⁻¹ · g_{j+1},    h(t) ⊂ α⁻¹(β(g_j)),  h(0) = ε,

which keeps the sequence composable and its product fixed (seed 000 §5.1, seed 001 eq. (11)).
For the basis section X its derivative at t = 0 is

    d/dt S = X⃖[S|_{g_j}](g_j) − X⃗[S|_{g_{j+1}}](g_{j+1})

(docs/conventions.md §2).  First-order, constrained (λ·φ added to S, §4), time-dependent (§7) and
second-order (S = Σ L(g_j, g_{j+1}), §8) equations all come from this one function.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import sympy as sp
from sympy.matrices.expressions.matexpr import MatrixElement

from ..groupoids import Groupoid


def junction_variation(groupoid: Groupoid, action: sp.Expr, left: Sequence,
                       right: Sequence) -> list[sp.Expr]:
    """d/dt S(…, g_j·h(t), h(t)⁻¹·g_{j+1}, …) at t = 0, one entry per basis section.

    ``action`` is an expression in independent slot coordinates; ``left``/``right`` are the
    coordinate tuples (of Dummy symbols) of the slots g_j and g_{j+1}.
    """
    lhs, rhs = junction_halves(groupoid, action, left, right)
    return [a - b for a, b in zip(lhs, rhs)]


def junction_halves(groupoid: Groupoid, action: sp.Expr, left: Sequence,
                    right: Sequence) -> tuple[list, list]:
    """The two halves of :func:`junction_variation`: (X⃖_b[S](g_j), X⃗_b[S](g_{j+1}))."""
    return (groupoid.apply_left(action, tuple(left)),
            groupoid.apply_right(action, tuple(right)))


_counter = itertools.count()


def slot(groupoid: Groupoid, name: str, matrix_form: bool = False) -> tuple:
    """A fresh arrow slot: independent real Dummy coordinates (matrix parts as fresh
    MatrixSymbols when ``matrix_form``)."""
    coords = tuple(sp.Dummy(f"{name}{i}", real=True) for i in range(groupoid.arrow_dim))
    if not matrix_form:
        return coords
    return groupoid.in_matrix_form(coords, lambda g: f"_{name}{next(_counter)}")


def slot_substitution(old: Sequence, new: Sequence) -> dict:
    """xreplace map taking slot ``old`` to ``new`` (matrix parts map symbol to symbol)."""
    sub = {}
    for a, b in zip(old, new):
        if isinstance(a, MatrixElement) and isinstance(b, MatrixElement):
            sub[a.parent] = b.parent
        sub[a] = b
    return sub
