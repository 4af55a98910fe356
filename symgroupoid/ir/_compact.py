"""Compaction of a finished program: fewer floating-point operations for the same values.

The graph's constructors keep sums and products n-ary and flat (constants folded into one
coefficient, like terms combined), which is what differentiation wants; printed as it is, an
n-ary node costs one operation per argument, and products that share all but one factor —
``2·t₁·t₅·a``, ``2·t₁·t₅·b`` (a Cayley entry times every row of an attitude), or the terms
∂node/∂arg · tangent of a Jacobian column — recompute the shared part each time: the C
compiler may not reassociate floating-point products to share them (no ``-ffast-math``).

:func:`compact` rebuilds the nodes a program's outputs need, in two linear passes:

1. *signs*: a sum whose leading term (in an order that ignores signs) has a negative
   coefficient is stored as the negation of the opposite sum, so that S and −S are one node
   (``a − b`` and ``b − a``), and a sum's terms c·S + c'·(−S) combine;
2. *sharing*: the arguments of every n-ary product (and sum) are ordered by how many products
   (sums) of the program use them, most used first (ties: older node first), and the
   products are evaluated left to right along a prefix tree of those orders: a prefix that
   several products share is one node, computed once.  Signs stay outside: a product with a
   negative coefficient is the negation of a positive one, which its sum prints as a
   subtraction.

Every node denotes the same exact expression as before (the rewrites are the associativity
and commutativity of + and ·, and x − y = −(y − x)); floating-point results may differ in
the last bits, as any other evaluation order would.  The passes are deterministic: no set
or hash-order iteration, ties broken by node id.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ._graph import ADD, CONST, FUNC, INPUT, MUL, POW, Graph, is_negative, is_one

_ONE = sp.Integer(1)


def compact(g: Graph, outputs: Sequence[int]) -> tuple[Graph, list[int]]:
    """A new graph computing ``outputs`` of ``g`` with fewer operations (see the module
    docstring); returns it and the outputs' nodes in it."""
    signed, outs = _canonical_signs(g, outputs)
    return _shared(signed, outs)


# --- pass 1: one node for S and −S ----------------------------------------------------------

def _term_parts(g: Graph, t: int) -> tuple[sp.Expr, tuple]:
    """(coefficient, the term without it) of an argument of a sum: c·x·y → (c, (x, y))."""
    if g.op[t] == CONST:
        return g.data[t], ()
    a = g.args[t]
    if g.op[t] == MUL and g.op[a[0]] == CONST:
        return g.data[a[0]], a[1:]
    return _ONE, (t,)


def _signed_add(g: Graph, terms: Sequence[int]) -> int:
    """Σ terms, as −(−Σ terms) when the leading term (smallest term-without-coefficient)
    has a negative coefficient."""
    s = g.add(*terms)
    if g.op[s] != ADD:
        return s
    parts = [_term_parts(g, t) for t in g.args[s]]
    coefficient = min(parts, key=lambda p: p[1])[0]
    if not is_negative(coefficient):
        return s
    return g.neg(g.add(*[g.neg(t) for t in g.args[s]]))


def _canonical_signs(g: Graph, outputs: Sequence[int]) -> tuple[Graph, list[int]]:
    """Pass 1: the outputs rebuilt in a new graph with canonical signs of sums."""
    h = Graph()
    new: dict = {}
    op, args, data = g.op, g.args, g.data
    for i in g.reachable(outputs):
        o = op[i]
        if o == CONST:
            new[i] = h.const(data[i])
        elif o == INPUT:
            new[i] = h.input(data[i])
        elif o == ADD:
            new[i] = _signed_add(h, [new[a] for a in args[i]])
        elif o == MUL:
            new[i] = h.mul(*[new[a] for a in args[i]])
        elif o == POW:
            new[i] = h.pow(new[args[i][0]], data[i])
        else:
            new[i] = h.func(data[i], *[new[a] for a in args[i]])
    return h, [new[o] for o in outputs]


# --- pass 2: shared prefixes of products and sums -----------------------------------------------

class _Trie:
    """Prefix tree of argument sequences: node 0 is the root; ``count[t]``: how many
    sequences pass through t; ``depth[t]``; ``parent[t]``; ``label[t]``: the argument."""

    def __init__(self) -> None:
        self.children: list[dict] = [{}]
        self.count, self.depth = [0], [0]
        self.parent, self.label = [-1], [-1]

    def insert(self, sequence: Sequence[int]) -> int:
        t = 0
        self.count[0] += 1
        for x in sequence:
            nxt = self.children[t].get(x)
            if nxt is None:
                nxt = len(self.count)
                self.children[t][x] = nxt
                self.children.append({})
                self.count.append(0)
                self.depth.append(self.depth[t] + 1)
                self.parent.append(t)
                self.label.append(x)
            t = nxt
            self.count[t] += 1
        return t


def _factors(g: Graph, i: int) -> tuple[bool, list[int]]:
    """(negative, the factors of product i with its coefficient's magnitude as one factor
    unless it is 1)."""
    a = list(g.args[i])
    if g.op[a[0]] != CONST:
        return False, a
    c = g.data[a[0]]
    negative = is_negative(c)
    magnitude = -c if negative else c
    rest = a[1:]
    if is_one(magnitude):
        return negative, rest
    return negative, [g.const(magnitude), *rest]


def _shared(g: Graph, outputs: Sequence[int]) -> tuple[Graph, list[int]]:
    """Pass 2: rebuild with shared prefixes (see the module docstring)."""
    order = g.reachable(outputs)
    op, args, data = g.op, g.args, g.data
    factors = {i: _factors(g, i) for i in order if op[i] == MUL}
    uses: dict = {}
    for i in order:
        if op[i] == MUL:
            for x in factors[i][1]:
                uses[(MUL, x)] = uses.get((MUL, x), 0) + 1
        elif op[i] == ADD:
            for x in args[i]:
                uses[(ADD, x)] = uses.get((ADD, x), 0) + 1
    tries = {MUL: _Trie(), ADD: _Trie()}
    path: dict = {}
    for i in order:
        o = op[i]
        if o not in (MUL, ADD):
            continue
        items = factors[i][1] if o == MUL else list(args[i])
        items.sort(key=lambda x: (-uses[(o, x)], x))
        path[i] = (tries[o].insert(items), items)
    h = Graph()
    new: dict = {}
    built: dict = {}  # (op, trie node) -> node of h

    def node_of(x: int) -> int:
        hit = new.get(x)
        if hit is None:  # a coefficient's magnitude, made by _factors
            hit = new[x] = h.const(data[x])
        return hit

    def prefix(o: int, t: int) -> int:
        """The node of h for the product (sum) of the arguments along trie path t: the
        longest proper prefix that more paths share than t, times the arguments after it."""
        key = (o, t)
        hit = built.get(key)
        if hit is not None:
            return hit
        trie = tries[o]
        run = [node_of(trie.label[t])]
        s = trie.parent[t]
        while s > 0 and not (trie.depth[s] >= 2 and trie.count[s] > trie.count[t]):
            run.append(node_of(trie.label[s]))
            s = trie.parent[s]
        if s > 0:
            run.append(prefix(o, s))
        run.reverse()
        node = run[0] if len(run) == 1 else h._node(o, tuple(run), None, (o, tuple(run)))
        built[key] = node
        return node

    for i in order:
        o = op[i]
        if o == CONST:
            new[i] = h.const(data[i])
        elif o == INPUT:
            new[i] = h.input(data[i])
        elif o == POW:
            new[i] = h.pow(new[args[i][0]], data[i])
        elif o == FUNC:
            new[i] = h.func(data[i], *[new[a] for a in args[i]])
        else:
            node = prefix(o, path[i][0])
            if o == MUL and factors[i][0]:
                node = h._node(MUL, (h.minus_one, node), None, (MUL, (h.minus_one, node)))
            new[i] = node
    return h, [new[o] for o in outputs]


__all__ = ["compact"]
