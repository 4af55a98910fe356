"""Programs of the constraint checks: the system's own constraints and the size of their
terms, evaluated on known arrows (initial states, boundary data).

Each constraint c comes with M(c), the size of the terms that cancel in it (:func:`magnitude`):
evaluating c in floating point rounds it by about ε·M(c), so a check accepts |c| up to a
modest multiple of that (docs/conventions.md §15 for the holonomic constraints ψ, checked at
the nodes of arrows).
"""

from __future__ import annotations

import sympy as sp

from ...ir import Graph, Program, from_sympy


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows), or None."""
    return getattr(system, "_fs", None)


def magnitude(expr: sp.Expr) -> sp.Expr:
    """An expression for the size of the terms that cancel in ``expr``: every sum replaced
    by the sum of the magnitudes of its terms, recursively through products and positive
    integer powers; a function f(u) or another power contributes |f(u)| + |f′(u)|·M(u) (the
    rounding of its argument, carried through).  ε·M(expr) estimates the rounding error of
    evaluating ``expr`` in floating point (up to a modest factor)."""
    memo: dict = {}

    def size(e: sp.Expr) -> sp.Expr:
        hit = memo.get(e)
        if hit is None:
            hit = memo[e] = _size(e, size)
        return hit

    return size(sp.sympify(expr))


def _size(e: sp.Expr, size) -> sp.Expr:
    if e.is_Number:
        return abs(e)
    if e.is_Symbol:
        return sp.Abs(e)
    if e.is_Add or e.is_Mul:
        return e.func(*[size(a) for a in e.args])
    if e.is_Pow and e.exp.is_Integer and e.exp > 0:
        return size(e.base) ** e.exp
    if e.is_Pow:  # b^n, n not a positive integer: |b^n| + |n b^(n−1)|·M(b)
        return sp.Abs(e) + sp.Abs(e.exp * e.base ** (e.exp - 1)) * size(e.base)
    if isinstance(e, sp.Function) and len(e.args) == 1 and not isinstance(e, sp.Piecewise):
        u = sp.Dummy("u", real=True)  # f(u): |f(u)| + |f′(u)|·M(u)
        slope = sp.diff(e.func(u), u).xreplace({u: e.args[0]})
        return sp.Abs(e) + sp.Abs(slope) * size(e.args[0])
    return sp.Abs(e)


def _checked(name: str, inputs: dict, functions: list, what: str) -> Program:
    """``values`` = the functions and ``sizes`` = their magnitudes, over ``inputs``."""
    g = Graph()
    symbols = {s: g.input(s) for v in inputs.values() for s in v}
    memo: dict = {}
    values = [from_sympy(g, sp.sympify(c), symbols, f"{name}: {what} {i + 1}", memo)
              for i, c in enumerate(functions)]
    sizes = [from_sympy(g, magnitude(c), symbols, f"{name}: the size of {what} {i + 1}", memo)
             for i, c in enumerate(functions)]
    return Program(g, inputs, {"values": values, "sizes": sizes})


def constraint_program(step) -> Program | None:
    """The constraints a step's known state must satisfy, on one window of its known arrows
    (the system's slots): φ, then the holonomic ψ at the first node, then ψ at the last node
    (docs/conventions.md §15).  Inputs ``a`` (the slots' coordinates), ``p``; outputs
    ``values`` and ``sizes`` (their :func:`magnitude`).  None without constraints."""
    fs = _functions(getattr(step, "system", None))
    if fs is None or not fs.constraints:
        return None
    plain = len(fs.constraints) - fs.n_holonomic
    functions = list(fs.constraints) + list(fs.rows[plain:])
    coords = [c for s in fs.slots for c in s]
    return _checked(step.name, {"a": coords, "p": list(step.parameters)}, functions,
                    "constraint")


def holonomic_program(system) -> Program | None:
    """The holonomic constraints ψ(q) at a base point: inputs ``q``, ``p``; outputs
    ``values`` and ``sizes``.  None without holonomic constraints."""
    fs = _functions(system)
    if fs is None or not fs.n_holonomic:
        return None
    return _checked(system.name, {"q": list(fs.base), "p": list(system.parameters)},
                    list(fs.holonomic), "holonomic constraint")
