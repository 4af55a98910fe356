"""Between SymPy expressions and the expression graph.

:func:`from_sympy` walks a SymPy expression once (memoised on subexpressions, so a DAG-shaped
expression costs its number of *distinct* subexpressions) and builds graph nodes;
:func:`to_sympy` rebuilds SymPy expressions from nodes (for printing and checking small
systems).  Expressions the generated code cannot evaluate — complex or infinite values,
undefined functions, unevaluated derivatives and integrals — are refused here, by name, so
the error appears when the equations are built rather than in a C compiler.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import sympy as sp
from sympy.core.function import AppliedUndef

from .._errors import UnsupportedExpressionError
from ._functions import ELEMENTARY, Opaque, placeholders, smooth_spec
from ._graph import ADD, CONST, FUNC, INPUT, MUL, POW, Graph

_REFUSED = (sp.Derivative, sp.Integral, sp.Subs, sp.Sum, sp.Product, sp.Limit, sp.Order)


class Context(str):
    """What an expression is, for messages (``"pendulum: the Lagrangian"``), with the names
    its symbols are shown by: an expression built on internal symbols (a term's slot
    coordinates) is refused in the names the user knows (the arrow's coordinates)."""

    def __new__(cls, text: str, shown: Mapping | None = None):
        out = super().__new__(cls, text)
        out.shown = dict(shown or {})
        return out


def _refuse(expr: sp.Expr, why: str, context: str) -> UnsupportedExpressionError:
    where = f"{context}: " if context else ""
    shown = str(expr.xreplace(getattr(context, "shown", {})))
    if len(shown) > 120:
        shown = shown[:117] + "..."
    return UnsupportedExpressionError(f"{where}the subexpression {shown} {why}")


def _check_number(expr: sp.Expr, context: str) -> None:
    if expr.has(sp.zoo, sp.nan) or expr is sp.nan:
        raise _refuse(expr, "is undefined (zoo or nan: a division by zero or 0/0 in the "
                      "expression)", context)
    if expr.has(sp.oo, -sp.oo):
        raise _refuse(expr, "is infinite", context)
    if expr.has(sp.I) or expr.is_real is False:
        raise _refuse(expr, "is not real (the equations must be real-valued)", context)


def from_sympy(g: Graph, expr, symbols: Mapping, context: str = "",
               memo: dict | None = None) -> int:
    """The graph node of ``expr``; ``symbols`` maps each free symbol to a node id.

    Raises :class:`UnsupportedExpressionError` naming the first subexpression that compiled
    code cannot evaluate.
    """
    memo = {} if memo is None else memo
    root = sp.sympify(expr)
    stack = [(root, False)]
    while stack:
        e, ready = stack.pop()
        if e in memo:
            continue
        if not ready:
            children = _children(e, symbols, context)
            if children:
                stack.append((e, True))
                stack.extend((c, False) for c in children if c not in memo)
                continue
        memo[e] = _build(g, e, symbols, memo, context)
    return memo[root]


def _children(e, symbols, context) -> tuple:
    if e.is_Atom:
        return ()
    if isinstance(e, (sp.Add, sp.Mul)):
        return e.args
    if isinstance(e, sp.Pow):
        return e.args if not e.exp.is_number else (e.base,)
    if _function_spec(e) is not None:
        return e.args
    return ()


def _function_spec(e):
    from ._smooth import SmoothFunction

    if isinstance(e, SmoothFunction):
        return smooth_spec(type(e))
    return ELEMENTARY.get(type(e))


def _build(g: Graph, e, symbols, memo, context) -> int:
    if isinstance(e, sp.Symbol):
        try:
            return symbols[e]
        except KeyError:
            raise _refuse(e, "is a symbol with no value in this program (not an unknown, "
                          "known coordinate or parameter)", context) from None
    if e.is_number and not e.free_symbols and not isinstance(e, sp.Function):
        _check_number(e, context)
        return g.const(e)
    if isinstance(e, sp.Add):
        return g.add(*[memo[a] for a in e.args])
    if isinstance(e, sp.Mul):
        return g.mul(*[memo[a] for a in e.args])
    if isinstance(e, sp.Pow):
        b, x = e.args
        if x.is_number:
            _check_number(x, context)
            if b is sp.E:
                return g.func(ELEMENTARY[sp.exp], g.const(x))
            return g.pow(memo[b], x)
        if b is sp.E:
            return g.func(ELEMENTARY[sp.exp], memo[x])
        if b.is_number and b.is_negative and x.is_integer:
            return _negative_base_power(g, b, memo[x])
        log_b = g.func(ELEMENTARY[sp.log], memo[b])
        return g.func(ELEMENTARY[sp.exp], g.mul(memo[x], log_b))
    spec = _function_spec(e)
    if spec is not None:
        return g.func(spec, *[memo[a] for a in e.args])
    return _opaque(g, e, symbols, context)


def _negative_base_power(g: Graph, b: sp.Expr, x: int) -> int:
    """bⁿ for a negative constant b and an exponent n declared integer (SymPy writes cos(nπ)
    as (−1)ⁿ): cos(πn)·|b|ⁿ, exact at every integer n (exp(n·log b) would be NaN there)."""
    sign = g.func(ELEMENTARY[sp.cos], g.mul(g.const(sp.pi), x))
    if b == -1:
        return sign
    size = g.func(ELEMENTARY[sp.exp], g.mul(x, g.const(sp.log(-b))))
    return g.mul(sign, size)


def _opaque(g: Graph, e, symbols, context) -> int:
    """A subexpression that is not elementary: kept whole as an opaque function of its free
    symbols, if SymPy can print it to C and differentiate it."""
    if isinstance(e, AppliedUndef):
        raise _refuse(e, "is an undefined function (give it an explicit formula)", context)
    if isinstance(e, _REFUSED) or e.has(*_REFUSED):
        raise _refuse(e, f"is an unevaluated {type(e).__name__} (evaluate it, e.g. with "
                      ".doit(), before building the system)", context)
    if e.has(AppliedUndef):
        bad = next(iter(sorted(e.atoms(AppliedUndef), key=str)))
        raise _refuse(bad, "is an undefined function (give it an explicit formula)", context)
    if isinstance(e, (sp.MatrixBase, sp.MatrixExpr)) or not isinstance(e, sp.Expr):
        raise _refuse(e, "is not a scalar expression", context)
    _check_number(e, context) if e.is_number else None
    free = sorted(e.free_symbols, key=lambda s: s.name)
    ph = placeholders(len(free))
    local = e.xreplace(dict(zip(free, ph)))
    from ._c import c_of_sympy

    try:
        c_of_sympy(local, {p: f"x{i}" for i, p in enumerate(ph)})
    except Exception as exc:  # noqa: BLE001 - the printer raises several types
        raise _refuse(e, f"cannot be written in C ({type(exc).__name__})", context) from None
    ids = [_symbol_node(s, symbols, context) for s in free]
    return g.func(Opaque(local, ph), *ids)


def _symbol_node(s, symbols, context) -> int:
    try:
        return symbols[s]
    except KeyError:
        raise _refuse(s, "is a symbol with no value in this program", context) from None


def to_sympy(g: Graph, nodes: Sequence[int], symbols: Mapping | None = None) -> list:
    """SymPy expressions of ``nodes`` (inputs become their symbols, or ``symbols[node]``)."""
    symbols = symbols or {}
    out: dict = {}
    op, args, data = g.op, g.args, g.data
    for i in g.reachable(nodes):
        o = op[i]
        if i in symbols:
            out[i] = symbols[i]
        elif o == CONST or o == INPUT:
            out[i] = data[i]
        elif o == ADD:
            out[i] = sp.Add(*[out[a] for a in args[i]])
        elif o == MUL:
            out[i] = sp.Mul(*[out[a] for a in args[i]])
        elif o == POW:
            out[i] = sp.Pow(out[args[i][0]], data[i])
        elif o == FUNC:
            out[i] = data[i].sympy([out[a] for a in args[i]])
    return [out[n] for n in nodes]
