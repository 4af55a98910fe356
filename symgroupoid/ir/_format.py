"""Straight-line code from a program's nodes, in C or NumPy.

One formatter serves both languages so that the compiled kernels and the NumPy backend
perform the same floating-point operations in the same order: sums and products left to
right in node order (a later factor or term that is itself a product or a sum in
parentheses), integer powers as repeated products, a reciprocal as ``1.0/c``.  A small node
used once, and not an output, is written inline into its single user (evaluation order and
rounding are unchanged: kernels are compiled with ``-ffp-contract=off``); every other node is
*named* (a temporary).

The plan — which nodes are named, in which order — is structural (:func:`plan`), so that a
caller can assign names (locals, or slots of a work array shared between the parts of a
split kernel) before any text is produced (:func:`write`).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field

import sympy as sp

from ._graph import ADD, CONST, INPUT, MUL, POW, Graph
from ._libm import numpy_name

#: precedence levels of printed expressions
ATOM, PRODUCT, SUM = 3, 2, 1
#: integer powers up to this size are written as products
MAX_UNROLLED_POWER = 4
#: a node is inlined into its single user only while its inlined subtree has at most this
#: many operations
MAX_INLINE_OPS = 6


@dataclass
class Dialect:
    """What differs between the languages: constants and function calls."""

    name: str
    constant: Callable[[sp.Expr], str]
    function: Callable[[object, Sequence[str]], str]
    sqrt: str
    pow: str


def c_constant(value: sp.Expr) -> str:
    """A double literal (exact integers and rationals as such, others correctly rounded)."""
    if value.is_Integer:
        return f"{int(value)}.0"
    if value.is_Rational:
        q = int(value.q)
        if q & (q - 1) == 0 and abs(int(value.p)) < 2**53:  # dyadic: exact as a double
            return repr(float(value))
        return f"({int(value.p)}.0/{int(value.q)}.0)"
    return repr(float(value))


C = Dialect("c", c_constant, lambda spec, args: spec.c_expression(args), "sqrt", "pow")
#: C's pow in NumPy code is C's own (:mod:`._libm`), bound by the code's namespace
NUMPY = Dialect("numpy", c_constant, lambda spec, args: spec.numpy_expression(args),
                "np.sqrt", numpy_name("pow"))


@dataclass
class Plan:
    """Which operation nodes are named (in evaluation order) and which are inlined."""

    named: list = field(default_factory=list)
    inlined: set = field(default_factory=set)
    refs: dict = field(default_factory=dict)  # named node -> named nodes its text reads


def plan(g: Graph, outputs: Sequence[int], inline: bool = True,
         given: Collection[int] = ()) -> Plan:
    """Decide named and inlined nodes for computing ``outputs``.

    ``given``: operation nodes whose values are computed elsewhere (and named by the
    caller, as inputs are): they are read, never computed, and nothing below them is
    planned unless another node needs it."""
    given = frozenset(given)
    order = [n for n in g.reachable(outputs, stop=given) if g.args[n] and n not in given]
    uses = g.uses(order)
    outs = set(outputs)
    summed = _only_in_sums(g, order)
    size: dict = {}
    reads: dict = {}  # node -> frozenset of named nodes its (possibly inlined) text reads
    p = Plan()
    for n in order:
        s = 1
        r: set = set()
        for a in g.args[n]:
            if a in p.inlined:
                s += size[a]
                r |= reads[a]
            elif g.args[a] and a not in given:
                r.add(a)
        single = uses.get(n, 0) == 1 and s <= MAX_INLINE_OPS
        if inline and n not in outs and (single or (n in summed and s == 1)):
            p.inlined.add(n)
            size[n], reads[n] = s, frozenset(r)
        else:
            p.named.append(n)
            p.refs[n] = r
            size[n], reads[n] = 1, frozenset()
    return p


def _only_in_sums(g: Graph, order: Sequence[int]) -> set:
    """The negations −x (``MUL(-1, x)``) among ``order`` whose every user is a sum: written
    into each sum as a subtraction (``a - x``, exact: a + (−x) = a − x), never named."""
    minus_one = g.minus_one
    negations = {n for n in order if g.op[n] == MUL and len(g.args[n]) == 2
                 and g.args[n][0] == minus_one}
    other: set = set()
    for n in order:
        if g.op[n] != ADD:
            other.update(a for a in g.args[n] if a in negations)
    return negations - other


@dataclass
class Listing:
    """Statements ``(name, expression)`` in order, then the output expressions."""

    statements: list = field(default_factory=list)
    outputs: list = field(default_factory=list)


def _wrap(text: str, level: int, needed: int) -> str:
    return f"({text})" if level < needed else text


class _Writer:
    def __init__(self, g: Graph, names: Mapping[int, str], dialect: Dialect, inlined: set):
        self.g, self.names, self.d, self.inlined = g, names, dialect, inlined
        self.text: dict = {}
        self.level: dict = {}

    def atom(self, n: int) -> tuple[str, int]:
        g = self.g
        if n in self.text:
            return self.text[n], self.level[n]
        if n in self.names:
            return self.names[n], ATOM
        if g.op[n] == CONST:
            text = self.d.constant(g.data[n])
            return text, (ATOM if not text.startswith("-") else PRODUCT)
        raise KeyError(f"node {n} ({g.op[n]}) has no name")

    def expression(self, n: int) -> tuple[str, int]:
        g = self.g
        o, a = g.op[n], g.args[n]
        if o == ADD:
            parts = []
            for k, x in enumerate(a):
                t, lvl = self.atom(x)
                if k and t.startswith("-") and lvl >= PRODUCT:
                    parts.append(f" - {t[1:]}")
                elif k:  # a sum as a later term keeps its parentheses (evaluation order)
                    parts.append(" + " + _wrap(t, lvl, PRODUCT))
                else:
                    parts.append(t)
            return "".join(parts), SUM
        if o == MUL:
            return self._product(a)
        if o == POW:
            return self._power(a[0], g.data[n])
        args = [self.atom(x)[0] for x in a]
        return self.d.function(g.data[n], args), ATOM

    def _product(self, a) -> tuple[str, int]:
        """The factors left to right in node order, each later one that is itself a
        product, a quotient or a sum in parentheses: ((a·b)·c) is computed whatever was
        inlined, so a value rounds the same whether its factors are named or written in
        place (an inlined reciprocal is the factor (1.0/c), never a division by c)."""
        g = self.g
        factors, negative = [], False
        for x in a:
            if g.op[x] == CONST and g.data[x].is_negative and g.data[x].is_Rational:
                negative = True
                if g.data[x] != -1:
                    factors.append((self.d.constant(-g.data[x]), ATOM))
            else:
                factors.append(self.atom(x))
        text = "*".join(_wrap(t, lvl, ATOM if k else PRODUCT + (1 if t.startswith("-") else 0))
                        for k, (t, lvl) in enumerate(factors)) or "1.0"
        return ("-" + text if negative else text), PRODUCT

    def _power(self, base: int, e: sp.Expr) -> tuple[str, int]:
        b, lvl = self.atom(base)
        b = _wrap(b, lvl, ATOM)
        if e.is_Integer and 1 <= abs(int(e)) <= MAX_UNROLLED_POWER:
            prod = "*".join([b] * abs(int(e)))
            if e > 0:
                return prod, PRODUCT if int(e) > 1 else ATOM
            return f"1.0/{_wrap(prod, PRODUCT if abs(int(e)) > 1 else ATOM, ATOM)}", PRODUCT
        if e == sp.Rational(1, 2):
            return f"{self.d.sqrt}({b})", ATOM
        if e == sp.Rational(-1, 2):
            return f"1.0/{self.d.sqrt}({b})", PRODUCT
        return f"{self.d.pow}({b}, {self.d.constant(e)})", ATOM


def write(g: Graph, p: Plan, nodes: Sequence[int], names: Mapping[int, str],
          dialect: Dialect, writer: _Writer | None = None) -> tuple[list, _Writer]:
    """``(name, expression)`` for the named ``nodes`` (a contiguous run of ``p.named``), with
    every input and named node given a name in ``names``; inlined nodes they read are
    written into them.  Returns the statements and the writer (pass it on to continue)."""
    w = writer or _Writer(g, names, dialect, p.inlined)
    out = []
    pending = [n for n in nodes]
    for n in pending:
        _write_inlined(g, w, n)
        text, _ = w.expression(n)
        out.append((names[n], text))
    return out, w


def _write_inlined(g: Graph, w: _Writer, n: int) -> None:
    """Texts of the inlined nodes under n (each written once, before its user)."""
    stack = [a for a in g.args[n] if a in w.inlined and a not in w.text]
    todo = []
    while stack:
        a = stack.pop()
        todo.append(a)
        stack.extend(b for b in g.args[a] if b in w.inlined and b not in w.text)
    for a in sorted(set(todo)):
        if a not in w.text:
            w.text[a], w.level[a] = w.expression(a)


def listing(g: Graph, outputs: Sequence[int], inputs: Mapping[int, str], dialect: Dialect,
            temporaries: Callable[[], str] | None = None, inline: bool = True) -> Listing:
    """Straight-line code for ``outputs`` in one piece (see the module docstring)."""
    p = plan(g, outputs, inline)
    if temporaries is None:
        counter = itertools.count()
        temporaries = lambda: f"t{next(counter)}"  # noqa: E731
    names = dict(inputs)
    for n in p.named:
        names[n] = temporaries()
    statements, w = write(g, p, p.named, names, dialect)
    out = Listing(statements)
    for o in outputs:
        if o in p.inlined:  # pragma: no cover - outputs are never inlined
            raise AssertionError
        out.outputs.append(w.atom(o)[0])
    return out


def functions_used(g: Graph, outputs: Sequence[int]) -> list:
    """The function specs the outputs need, in first-use order (deterministic)."""
    from ._graph import FUNC

    seen: dict = {}
    for n in g.reachable(outputs):
        if g.op[n] == FUNC and g.data[n].key not in seen:
            seen[g.data[n].key] = g.data[n]
    return list(seen.values())


__all__ = ["C", "NUMPY", "Dialect", "Listing", "Plan", "functions_used", "listing", "plan",
           "write", "INPUT"]
