"""The junction variation on the expression graph: the step equations as a program.

The window action and its junction variation of :class:`~symgroupoid.derivation.WindowAction`
(docs/conventions.md §2, §4, §8), on a hash-consed graph instead of SymPy trees:

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
from dataclasses import dataclass, field

import sympy as sp

from .._symbols import multiplier_symbols, stage_symbols
from ..groupoids import Groupoid
from ..ir import Graph, domain_kind, forward, from_sympy, to_sympy
from ._assembly import WindowAction
from ._forces import input_symbols
from ._step import SystemFunctions, chart_of, window_arrows


@dataclass
class WindowGraph:
    """The graph of one step's residuals and what its program needs."""

    graph: Graph
    residuals: list  # node ids: one per basis section, the stage rows, then the constraints
    del_rows: list  # node ids of the junction residuals alone (before constraints)
    left_rows: list  # X⃖_b[S](g_k) (the g_k half of each junction residual)
    right_rows: list  # X⃗_b[S](g_{k+1}) (the g_{k+1} half: del = left − right)
    constraint_rows: list  # node ids of φ on the newest term
    symbols: dict  # named symbol -> node (knowns, unknowns, parameters)
    arrows: dict  # offset -> named arrow (SymPy coordinates, fibre variables of the unknown)
    memo: dict  # SymPy subexpression -> node (reuse when converting more expressions)
    #: the nodes of every term of the window defined on part of the real line only (log, √,
    #: acos, …): finite exactly where the window's terms are defined (docs/conventions.md §11)
    domain: list = field(default_factory=list)
    #: for each domain node, what it needs and on which term ("the new arrow", …)
    domain_kinds: list = field(default_factory=list)


def window_graph(name: str, G: Groupoid, fs: SystemFunctions, parameters: Sequence,
                 multipliers: bool = True) -> WindowGraph:
    """The residual nodes of the step of order ``len(fs.slots)`` (see the module docstring).

    With ``multipliers=False`` the constraints are not added to the action (nonholonomic
    steps); they still give the last rows.
    """
    action = WindowAction(G, fs)
    m, offsets, starts = action.m, action.offsets, action.starts
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
    inputs = {s: [node_of(u) for u in input_symbols(fs.inputs, s)] for s in starts}
    stages = ({s: [node_of(z) for z in stage_symbols(len(fs.stages), s)] for s in starts}
              if fs.stages else None)
    jn = action.junction_nodes(g, {p: symbols[p] for p in parameters}, arrow_nodes,
                               lam_nodes, inputs, stages, name)
    dels = jn.residuals
    stage_rows = [r for s in starts for r in jn.stage_rows[s]]
    constraint_rows = jn.rows[starts[-1]]
    domain, kinds = _domain(g, jn.domain, starts)
    return WindowGraph(g, dels + stage_rows + constraint_rows, dels, jn.left, jn.right,
                       constraint_rows, symbols, arrows, memo, domain, kinds)


def _domain(g: Graph, nodes: dict, starts: Sequence[int]) -> tuple[list, list]:
    """The window's domain nodes (each once, newest term first) and their descriptions: what
    each needs, the expression (when short) and the terms it belongs to."""
    terms: dict = {}
    for s in reversed(starts):
        term = "the new arrow's term" if s == starts[-1] else "a known arrow's term"
        for n in nodes.get(s, []):
            if domain_kind(g, n) is not None:  # (a constant folded away is no node)
                terms.setdefault(n, []).append(term)
    domain = list(terms)
    return domain, [f"{_shown(g, n)}{domain_kind(g, n)} ({' and '.join(terms[n])})"
                    for n in domain]


#: the largest expression a domain value's description prints
SHOWN_NODES, SHOWN_CHARACTERS = 60, 90


def _shown(g: Graph, node: int) -> str:
    """``node`` as SymPy text and a colon, when it is short; else empty."""
    if len(g.reachable([node])) > SHOWN_NODES:
        return ""
    text = str(to_sympy(g, [node])[0])
    return f"{text}: " if len(text) <= SHOWN_CHARACTERS else ""


def step_jacobian(g: Graph, residuals: Sequence[int], unknowns: Sequence[int]
                  ) -> list[list[int]]:
    """∂residuals/∂unknowns (rows × columns of nodes), one forward sweep per unknown; the
    unknowns are input nodes, and the fibre chart is part of the graph."""
    order = g.reachable(residuals)
    columns = [forward(g, residuals, {u: g.one}, order) for u in unknowns]
    return [[col[i] for col in columns] for i in range(len(residuals))]
