"""The expression graph: hash-consed nodes of elementary operations.

A :class:`Graph` is a growing list of nodes; node ``i`` is an operation applied to earlier
nodes, so node ids are a topological order and any set of outputs is a straight-line
program.  Structurally equal nodes are created once (hash-consing, with commutative
arguments sorted), so shared subexpressions are shared by construction — the representation
CasADi's SX graphs use, and what makes differentiation cheap: a derivative is a few new
nodes per node, never an expanded tree.

Operations:

- ``CONST`` — an exact SymPy number (``Integer``, ``Rational``, ``Float``, or a number such
  as ``pi``);
- ``INPUT`` — a SymPy symbol (an unknown, a known coordinate, a parameter, a slot variable);
- ``ADD``, ``MUL`` — n-ary sum and product (constants folded into one leading argument);
- ``POW`` — a node to a constant exponent (integer or rational);
- ``FUNC`` — an elementary function given by a :class:`~symgroupoid.ir.FunctionSpec`.

Construction applies only local, exact rewrites (constant folding, neutral elements,
``(x^a)^n = x^(an)`` for integer n), so the graph denotes exactly the expression it was built
from.
"""

from __future__ import annotations

import operator
from collections.abc import Collection, Iterable, Sequence

import mpmath
import sympy as sp

CONST, INPUT, ADD, MUL, POW, FUNC = range(6)
OP_NAMES = ("const", "input", "add", "mul", "pow", "func")

_ZERO, _ONE = sp.Integer(0), sp.Integer(1)


def is_zero(c: sp.Expr) -> bool:
    """``c == 0`` for a SymPy number, by identity for rationals (SymPy keeps one zero)."""
    return c is _ZERO if c.is_Rational else bool(c == 0)


def is_one(c: sp.Expr) -> bool:
    """``c == 1`` for a SymPy number, by identity for rationals (SymPy keeps one one)."""
    return c is _ONE if c.is_Rational else bool(c == 1)


def is_negative(c: sp.Expr) -> bool:
    """``c < 0`` for a SymPy number (its cached sign when SymPy knows it; else its value to
    :data:`SIGN_DIGITS` digits, for a constant SymPy cannot order exactly)."""
    sign = c.is_negative
    if sign is not None:
        return sign
    try:
        return bool(c < 0)
    except TypeError:  # an unevaluated relational: decide on the value
        return bool(sp.N(c, SIGN_DIGITS) < 0)


#: digits to which the sign of a constant SymPy cannot order exactly is decided
SIGN_DIGITS = 50


def folded_float(value: sp.Expr) -> sp.Expr:
    """A constant that holds floating-point numbers (a user's mass 1.0 times the Gauss
    nodes' √3) as one Float, at the finest precision among them: its exactness is gone
    already, and SymPy leaves such sums unevaluated, so that it could not even order them
    (0.5 + √3/3 − …).  Other constants unchanged."""
    if isinstance(value, sp.Number) or not value.has(sp.Float):
        return value
    bits = max(f._prec for f in value.atoms(sp.Float))
    return sp.Float(sp.N(value, mpmath.libmp.prec_to_dps(bits)), precision=bits)


def _number_key(value: sp.Expr) -> tuple:
    """A hash key that distinguishes 2 from 2.0 (SymPy may call them equal)."""
    return (type(value).__name__, value)


class Graph:
    """A hash-consed expression DAG (see the module docstring)."""

    def __init__(self) -> None:
        self.op: list[int] = []
        self.args: list[tuple[int, ...]] = []
        self.data: list = []
        self._table: dict = {}
        self._partials: dict = {}
        self._sums: dict = {}  # (constant node, constant node) -> their sum's node
        self._products: dict = {}  # ... -> their product's node
        self.inputs: dict = {}  # symbol -> node id
        self.zero = self.const(_ZERO)
        self.one = self.const(_ONE)
        self.minus_one = self.const(sp.Integer(-1))

    def __len__(self) -> int:
        return len(self.op)

    # --- node creation ----------------------------------------------------------------------
    def _node(self, op: int, args: tuple, data, key) -> int:
        hit = self._table.get(key)
        if hit is not None:
            return hit
        i = len(self.op)
        self.op.append(op)
        self.args.append(args)
        self.data.append(data)
        self._table[key] = i
        return i

    def const(self, value) -> int:
        """The constant ``value`` (a SymPy number, or anything SymPy turns into one)."""
        if not isinstance(value, sp.Number):  # Numbers (most calls) need no checks
            value = sp.sympify(value)
            if not value.is_number or value.free_symbols:
                raise ValueError(f"not a constant: {value!r}")
            value = folded_float(value)
        return self._node(CONST, (), value, (CONST, _number_key(value)))

    def input(self, symbol: sp.Symbol) -> int:
        """The input node of ``symbol``."""
        i = self._node(INPUT, (), symbol, (INPUT, symbol))
        self.inputs.setdefault(symbol, i)
        return i

    def is_const(self, i: int) -> bool:
        return self.op[i] == CONST

    def value(self, i: int):
        """The SymPy value of a constant node (None for other nodes)."""
        return self.data[i] if self.op[i] == CONST else None

    def _folded(self, memo: dict, a: int, b: int, combine) -> int:
        """The constant node ``combine(a, b)`` of two constant nodes, computed once per
        graph (SymPy's arithmetic on numbers is slow; a graph uses few constants)."""
        key = (a, b) if a <= b else (b, a)
        hit = memo.get(key)
        if hit is None:
            hit = memo[key] = self.const(combine(self.data[a], self.data[b]))
        return hit

    def _plus(self, a: int, b: int) -> int:
        return self._folded(self._sums, a, b, operator.add)

    def _times(self, a: int, b: int) -> int:
        return self._folded(self._products, a, b, operator.mul)

    def add(self, *ids: int) -> int:
        """Σ ids: constants folded, like terms c₁·t + c₂·t combined (exactly), zeros dropped,
        arguments in canonical order."""
        op, data, args_of = self.op, self.data, self.args
        total = None  # the constant node of the folded constants
        terms: dict = {}  # term without its coefficient -> [coefficient node, node, count]
        for i in ids:
            o = op[i]
            if o == CONST:
                total = i if total is None else self._plus(total, i)
                continue
            if o == MUL and op[args_of[i][0]] == CONST:
                key, c = args_of[i][1:], args_of[i][0]
            else:
                key, c = (i,), self.one
            hit = terms.get(key)
            if hit is None:
                terms[key] = [c, i, 1]
            else:
                hit[0] = self._plus(hit[0], c)
                hit[2] += 1
        rest = []
        for key, (c, node, count) in terms.items():
            if count > 1:
                if is_zero(data[c]):
                    continue
                node = self.mul(c, *key) if not is_one(data[c]) or len(key) > 1 else key[0]
            rest.append(node)
        if total is not None and not is_zero(data[total]):
            rest.append(total)
        if not rest:
            return self.zero
        if len(rest) == 1:
            return rest[0]
        rest.sort()
        args = tuple(rest)
        return self._node(ADD, args, None, (ADD, args))

    def mul(self, *ids: int) -> int:
        """Π ids, constants folded into one factor, ones dropped, zero absorbing."""
        op, data, args_of = self.op, self.data, self.args
        c = None  # the constant node of the folded constants
        rest = []
        for i in ids:
            o = op[i]
            if o == CONST:
                c = i if c is None else self._times(c, i)
            elif o == MUL and op[args_of[i][0]] == CONST:
                k = args_of[i][0]
                c = k if c is None else self._times(c, k)
                rest.extend(args_of[i][1:])
            else:
                rest.append(i)
        unit = c is None or c == self.one
        if not unit and is_zero(data[c]):
            return self.zero
        if not rest:
            return self.one if c is None else c
        unit = unit or is_one(data[c])
        if unit and len(rest) == 1:
            return rest[0]
        rest.sort()
        if not unit:
            rest.insert(0, c)
        args = tuple(rest)
        return self._node(MUL, args, None, (MUL, args))

    def neg(self, i: int) -> int:
        return self.mul(self.minus_one, i)

    def sub(self, a: int, b: int) -> int:
        return self.add(a, self.neg(b))

    def pow(self, base: int, exponent) -> int:
        """base**exponent for a constant (integer or rational) exponent."""
        e = sp.sympify(exponent)
        if not e.is_number:
            raise ValueError(f"pow needs a constant exponent, got {e!r}")
        if e == 0:
            return self.one
        if e == 1:
            return base
        if self.op[base] == CONST:
            return self.const(self.data[base] ** e)
        if self.op[base] == POW and e.is_Integer:
            inner = self.data[base]
            return self.pow(self.args[base][0], inner * e)
        return self._node(POW, (base,), e, (POW, base, _number_key(e)))

    def div(self, a: int, b: int) -> int:
        return self.mul(a, self.pow(b, -1))

    def func(self, spec, *args: int) -> int:
        """The elementary function ``spec`` applied to ``args`` (folded on constants when
        the result is an exact number)."""
        if all(self.op[a] == CONST for a in args):
            folded = spec.fold([self.data[a] for a in args])
            if folded is not None:
                return self.const(folded)
        args = tuple(args)
        return self._node(FUNC, args, spec, (FUNC, spec.key, args))

    # --- structure ---------------------------------------------------------------------------
    def reachable(self, outputs: Iterable[int], stop: Collection[int] = ()) -> list[int]:
        """Ids of every node the outputs depend on (outputs included), ascending; the
        arguments of the nodes in ``stop`` are not followed (they are reached, not what
        they depend on)."""
        seen = set()
        stack = [o for o in outputs]
        args = self.args
        while stack:
            i = stack.pop()
            if i in seen:
                continue
            seen.add(i)
            if i not in stop:
                stack.extend(a for a in args[i] if a not in seen)
        return sorted(seen)

    def dependents(self, sources: Iterable[int], nodes: Sequence[int]) -> set:
        """The nodes among ``nodes`` (ascending) that depend on any of ``sources``."""
        hit = set(sources)
        args = self.args
        for i in nodes:
            if i not in hit and any(a in hit for a in args[i]):
                hit.add(i)
        return hit

    def free_inputs(self, outputs: Iterable[int]) -> list:
        """The symbols the outputs depend on, in node order."""
        return [self.data[i] for i in self.reachable(outputs) if self.op[i] == INPUT]

    def uses(self, nodes: Sequence[int]) -> dict:
        """How many times each node is an argument of a node in ``nodes``."""
        count: dict = {}
        args = self.args
        for i in nodes:
            for a in args[i]:
                count[a] = count.get(a, 0) + 1
        return count

    def substitute(self, outputs: Sequence[int], mapping: dict) -> list[int]:
        """The outputs with nodes replaced per ``mapping`` (node id → node id), rebuilt
        bottom-up (one pass over the nodes the outputs depend on)."""
        new = dict(mapping)
        op, args, data = self.op, self.args, self.data
        for i in self.reachable(outputs):
            if i in new:
                continue
            a = args[i]
            if not a:
                new[i] = i
                continue
            b = tuple(new[x] for x in a)
            if b == a:
                new[i] = i
                continue
            o = op[i]
            if o == ADD:
                new[i] = self.add(*b)
            elif o == MUL:
                new[i] = self.mul(*b)
            elif o == POW:
                new[i] = self.pow(b[0], data[i])
            else:
                new[i] = self.func(data[i], *b)
        return [new[o] for o in outputs]

    def fingerprint(self, outputs: Sequence[int]) -> str:
        """An exact, deterministic text of the program computing ``outputs`` (for cache keys):
        every node they need, in order, with its operation, arguments and payload."""
        order = self.reachable(outputs)
        local = {n: k for k, n in enumerate(order)}
        parts = []
        for n in order:
            o, d = self.op[n], self.data[n]
            if o == CONST:
                payload = f"{type(d).__name__}:{sp.srepr(d)}"
            elif o == INPUT:
                payload = f"{type(d).__name__}:{d.name}"
            elif o == POW:
                payload = sp.srepr(d)
            elif o == FUNC:
                payload = d.key_text
            else:
                payload = ""
            parts.append(f"{OP_NAMES[o]}({','.join(str(local[a]) for a in self.args[n])})"
                         f"{payload}")
        parts.append("->" + ",".join(str(local[o]) for o in outputs))
        return ";".join(parts)
