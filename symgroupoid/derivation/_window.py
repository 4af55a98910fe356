"""The junction variation on the expression graph: the step equations as a program.

The same mechanism as :func:`~symgroupoid.derivation.junction_variation` (docs/conventions.md
§2, §4, §8), executed on a hash-consed graph instead of SymPy trees:

1. one *term* of the action, T(A₁, …, A_arity; λ) = L(A) + λ·φ(A), is captured as a graph in
   independent slot coordinates, and its gradient with respect to every slot coordinate is
   taken once by reverse-mode differentiation;
2. the window's arrows g_{k+o} (named knowns, and the unknown arrow through its fibre chart
   τ(x)) are graph nodes; each term's gradient is instantiated at its arrows by substitution;
3. residual b = Σ ⟨∇_{g_k} T_s, X⃖_b(g_k)⟩ − Σ ⟨∇_{g_{k+1}} T_s, X⃗_b(g_{k+1})⟩ over the terms
   containing g_k and g_{k+1} (both halves are kept: ``left_rows``, ``right_rows``) — the
   derivative of the action sum along the junction variation of section b — then the
   constraints on the newest term (holonomic ones at the target of the newest arrow);
4. the step Jacobian ∂F/∂(x, λ) is forward-mode differentiation of those nodes along the
   unknowns (through the chart), one sweep per unknown.

Nothing is expanded; shared subexpressions stay shared, so the residual costs a small
multiple of L and the Jacobian a small multiple of the residual per unknown.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from .._symbols import multiplier_symbols
from ..groupoids import Groupoid
from ..ir import Graph, forward, from_sympy, gradient
from ._step import SystemFunctions, chart_of, window, window_arrows


@dataclass
class WindowGraph:
    """The graph of one step's residuals and what its program needs."""

    graph: Graph
    residuals: list  # node ids: one per basis section, then the constraints
    del_rows: list  # node ids of the junction residuals alone (before constraints)
    left_rows: list  # X⃖_b[S](g_k) (the g_k half of each junction residual)
    right_rows: list  # X⃗_b[S](g_{k+1}) (the g_{k+1} half: del = left − right)
    constraint_rows: list  # node ids of φ on the newest term
    symbols: dict  # named symbol -> node (knowns, unknowns, parameters)
    arrows: dict  # offset -> named arrow (SymPy coordinates, fibre variables of the unknown)
    memo: dict  # SymPy subexpression -> node (reuse when converting more expressions)


def _term(g: Graph, fs: SystemFunctions, parameters: Sequence, m: int,
          with_multipliers: bool):
    """T = L + λ·φ on the generic slots, its gradient in the slot coordinates, φ, and the
    rows a step imposes on the term (φ, then ψ at the target of its last arrow)."""
    smap = {c: g.input(c) for s in fs.slots for c in s}
    smap.update({p: g.input(p) for p in parameters})
    memo: dict = {}
    L = from_sympy(g, fs.lagrangian, smap, "the Lagrangian", memo)
    phis = [from_sympy(g, phi, smap, f"constraint {a + 1}", memo)
            for a, phi in enumerate(fs.constraints)]
    held = len(fs.constraints) - fs.n_holonomic
    rows = phis[:held] + [from_sympy(g, psi, smap, f"holonomic constraint {a + 1}", memo)
                          for a, psi in enumerate(fs.rows[held:])]
    generic_lam = [g.input(sp.Dummy(f"lam{a}", real=True)) for a in range(m)]
    T = L
    if with_multipliers and m:
        T = g.add(L, *[g.mul(lam, phi) for lam, phi in zip(generic_lam, phis)])
    slot_nodes = [[smap[c] for c in s] for s in fs.slots]
    grad = gradient(g, T, [n for s in slot_nodes for n in s])
    return slot_nodes, generic_lam, grad, phis, rows


def _fields(g: Graph, G: Groupoid, side: str, coords: Sequence[int],
            parameters: dict | None = None) -> list[list[int]]:
    """X⃖_b(a) (``side="left"``) or X⃗_b(a) at an arrow given by nodes: the groupoid's
    :meth:`~symgroupoid.groupoids.Groupoid.field_nodes` (seed 000 eqs. (1)–(2))."""
    return G.field_nodes(g, side, coords, parameters)


@dataclass
class JunctionNodes:
    """The junction variation of a window's action at given arrows (graph nodes)."""

    left: list  # X⃖_b[S](g_0), one per basis section
    right: list  # X⃗_b[S](g_1)
    residuals: list  # left − right: the junction residuals (docs/conventions.md §2)
    constraints: dict  # start offset s -> φ on the term starting at s (as in the action)
    rows: dict  # start offset s -> a step's rows on that term: φ, then ψ(β(its last arrow))


def junction_nodes(g: Graph, G: Groupoid, fs: SystemFunctions, parameters: dict,
                   arrows: dict, multipliers: dict | None) -> JunctionNodes:
    """The junction variation between the window's arrows at offsets 0 and 1, at arrows given
    as graph nodes (``arrows[o]``: the coordinate nodes of the arrow at offset o; any nodes —
    named knowns and a chart of the unknown for a step, independent inputs for a
    boundary-value window).  ``parameters``: symbol → node; ``multipliers[s]``: the nodes of
    λ_s of the term starting at s (None: the constraints are not in the action, as for
    nonholonomic steps).  Also φ on every term of the window, and the rows a step imposes
    on each term: φ, then the holonomic constraints at the target of the term's last arrow
    (their action terms, ψ at each term's source node, are among the φ: the junction
    residual gets λ·dψ(β(g_0))(ρ(X)) from X⃗[ψ∘α](g_1), docs/conventions.md §15)."""
    arity, m = len(fs.slots), len(fs.constraints)
    _, starts = window(arity)
    slot_nodes, generic_lam, grad, phis, row_nodes = _term(g, fs, list(parameters), m,
                                                           multipliers is not None)
    flat_slots = [n for s in slot_nodes for n in s]
    pmap = {g.inputs[p]: n for p, n in parameters.items() if p in g.inputs and
            g.inputs[p] != n}
    dim = G.arrow_dim

    def instantiate(nodes: Sequence[int], s: int) -> list[int]:
        mapping = dict(zip(flat_slots, [c for i in range(arity) for c in arrows[s + i]]))
        mapping.update(pmap)
        if multipliers is not None:
            mapping.update(dict(zip(generic_lam, multipliers[s])))
        return g.substitute(nodes, mapping)

    left = _fields(g, G, "left", arrows[0], parameters)
    right = _fields(g, G, "right", arrows[1], parameters)
    halves: dict = {0: [[] for _ in range(G.rank)], 1: [[] for _ in range(G.rank)]}
    for s in starts:
        grads = instantiate(grad, s)
        for i in range(arity):
            o = s + i
            if o not in (0, 1):
                continue
            part = grads[i * dim:(i + 1) * dim]
            fields = left if o == 0 else right
            for b in range(G.rank):
                halves[o][b].extend(g.mul(d, v) for d, v in zip(part, fields[b])
                                    if d != g.zero and v != g.zero)
    lefts = [g.add(*t) for t in halves[0]]
    rights = [g.add(*t) for t in halves[1]]
    constraints = {s: instantiate(phis, s) if m else [] for s in starts}
    rows = {s: instantiate(row_nodes, s) if fs.n_holonomic else constraints[s]
            for s in starts}
    return JunctionNodes(lefts, rights, [g.sub(a, b) for a, b in zip(lefts, rights)],
                         constraints, rows)


def window_graph(name: str, G: Groupoid, fs: SystemFunctions, parameters: Sequence,
                 multipliers: bool = True) -> WindowGraph:
    """The residual nodes of the step of order ``len(fs.slots)`` (see the module docstring).

    With ``multipliers=False`` the constraints are not added to the action (nonholonomic
    steps); they still give the last rows.
    """
    arity, m = len(fs.slots), len(fs.constraints)
    offsets, starts = window(arity)
    g = Graph()
    arrows = window_arrows(G, offsets)
    newest = offsets[-1]
    _, chart, cmap = chart_of(G, newest, G.target(arrows[newest - 1]))
    symbols: dict = {p: g.input(p) for p in parameters}
    symbols.update({x: g.input(x) for x in chart})
    memo: dict = {}
    lam = {s: multiplier_symbols(m, s) for s in starts}
    for s in starts:
        symbols.update({x: g.input(x) for x in lam[s]})

    def node_of(expr, what: str = "the arrows of the step") -> int:
        for s in sorted(sp.sympify(expr).free_symbols, key=str):
            if s not in symbols:
                symbols[s] = g.input(s)
        return from_sympy(g, expr, symbols, f"{name}: {what}", memo)

    for f, value in cmap.items():
        symbols[f] = node_of(value, f"the fibre chart of {G.name}")

    arrow_nodes = {o: [node_of(c) for c in arrows[o]] for o in offsets}
    lam_nodes = {s: [symbols[x] for x in lam[s]] for s in starts} if multipliers else None
    jn = junction_nodes(g, G, fs, {p: symbols[p] for p in parameters}, arrow_nodes,
                        lam_nodes)
    dels = jn.residuals
    constraint_rows = jn.rows[starts[-1]]
    return WindowGraph(g, dels + constraint_rows, dels, jn.left, jn.right, constraint_rows,
                       symbols, arrows, memo)


def step_jacobian(g: Graph, residuals: Sequence[int], unknowns: Sequence[int]
                  ) -> list[list[int]]:
    """∂residuals/∂unknowns (rows × columns of nodes), one forward sweep per unknown; the
    unknowns are input nodes, and the fibre chart is part of the graph."""
    order = g.reachable(residuals)
    columns = [forward(g, residuals, {u: g.one}, order) for u in unknowns]
    return [[col[i] for col in columns] for i in range(len(residuals))]
