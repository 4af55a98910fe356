"""Algorithmic differentiation on the expression graph.

Both modes build new graph nodes (the derivative is again a straight-line program, exact):

- :func:`forward` — directional derivatives (Jacobian–vector products): one pass over the
  nodes between the seeds and the outputs, tangent(node) = Σ_k ∂node/∂arg_k · tangent(arg_k);
- :func:`gradient` — reverse mode: one backward pass from a scalar output,
  adjoint(arg_k) += adjoint(node) · ∂node/∂arg_k, giving the derivative with respect to
  every input at a cost proportional to the output's program.

Local partial derivatives ∂node/∂arg_k are built once per node and argument position and
cached in the graph, so repeated sweeps (the columns of a Jacobian) share them.  A product of
many factors gets its partials from prefix and suffix products (linear, not quadratic).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ._graph import ADD, CONST, FUNC, MUL, POW, Graph


def partial(g: Graph, node: int, k: int) -> int:
    """∂node/∂(argument k of node), cached."""
    key = (node, k)
    hit = g._partials.get(key)
    if hit is not None:
        return hit
    o = g.op[node]
    if o == ADD:
        d = g.one
    elif o == MUL:
        d = _product_partials(g, node)[k]
    elif o == POW:
        e = g.data[node]
        d = g.mul(g.const(e), g.pow(g.args[node][0], e - 1))
    elif o == FUNC:
        d = g.data[node].partial(g, node, k)
    else:
        raise ValueError(f"node {node} has no arguments")
    g._partials[key] = d
    return d


def _product_partials(g: Graph, node: int) -> list[int]:
    """Π_{j≠k} a_j for every k, by prefix and suffix products (cached with the node)."""
    key = (node, "product")
    hit = g._partials.get(key)
    if hit is not None:
        return hit
    a = g.args[node]
    n = len(a)
    if n == 2:
        out = [a[1], a[0]]
    else:
        prefix = [g.one]
        for x in a[:-1]:
            prefix.append(g.mul(prefix[-1], x))
        suffix = [g.one] * n
        for k in range(n - 2, -1, -1):
            suffix[k] = g.mul(a[k + 1], suffix[k + 1])
        out = [g.mul(prefix[k], suffix[k]) for k in range(n)]
    g._partials[key] = out
    return out


def forward(g: Graph, outputs: Sequence[int], seeds: Mapping[int, int],
            order: Sequence[int] | None = None) -> list[int]:
    """d/dt of ``outputs`` when each seed node s moves with velocity ``seeds[s]`` (a node).

    ``order``: the nodes to sweep, ascending (default: everything the outputs depend on);
    pass it when sweeping the same outputs along many directions.
    """
    if order is None:
        order = g.reachable(outputs)
    tan = {s: v for s, v in seeds.items() if v != g.zero}
    if not tan:
        return [g.zero] * len(outputs)
    args, op = g.args, g.op
    for n in order:
        a = args[n]
        if not a or n in tan:
            continue
        terms = []
        for k, x in enumerate(a):
            t = tan.get(x)
            if t is not None:
                terms.append(t if op[n] == ADD else g.mul(partial(g, n, k), t))
        if terms:
            d = g.add(*terms)
            if d != g.zero:
                tan[n] = d
    return [tan.get(o, g.zero) for o in outputs]


def gradient(g: Graph, output: int, wrt: Sequence[int]) -> list[int]:
    """∂output/∂w for every node w in ``wrt`` (reverse mode)."""
    order = g.reachable([output])
    contrib: dict = {output: [g.one]}
    done: dict = {}
    args, op = g.args, g.op
    targets = set(wrt)
    for n in reversed(order):
        parts = contrib.pop(n, None)
        if parts is None:
            continue
        adj = g.add(*parts)
        if adj == g.zero:
            continue
        if n in targets:
            done[n] = adj
        a = args[n]
        for k, x in enumerate(a):
            if op[x] == CONST:
                continue
            d = adj if op[n] == ADD else g.mul(adj, partial(g, n, k))
            contrib.setdefault(x, []).append(d)
    return [done.get(w, g.zero) for w in wrt]


def jacobian(g: Graph, outputs: Sequence[int], wrt: Sequence[int],
             tangents: Sequence[Mapping[int, int]] | None = None) -> list[list[int]]:
    """J[i][j] = ∂outputs[i]/∂wrt[j] by forward sweeps (one per column).

    ``tangents[j]`` optionally replaces the unit seed of column j by a map node → velocity
    (a chain rule through an intermediate map, e.g. the fibre chart).
    """
    order = g.reachable(outputs)
    columns = []
    for j, w in enumerate(wrt):
        seeds = tangents[j] if tangents is not None else {w: g.one}
        columns.append(forward(g, outputs, seeds, order))
    return [[columns[j][i] for j in range(len(wrt))] for i in range(len(outputs))]


__all__ = ["forward", "gradient", "jacobian", "partial", "FUNC"]
