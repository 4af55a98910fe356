"""Programs of the initial-state solves: a state from a configuration and a momentum, and
the source of an arrow moved onto the holonomic constraint set.

From a momentum (docs/conventions.md §3, §4): given the base point q₀ and a momentum p₀ in
the dual of the section basis, the first arrow g₁ ∈ α⁻¹(q₀) and its multipliers λ₁ solve

    F⁻[L + λ₁·φ](g₁) = p₀,      φ(g₁) = 0

(holonomic constraints ψ: the condition is ψ(β(g₁)) = 0, docs/conventions.md §15), with
⟨F⁻[L + λ·φ](g), X⟩ = X⃗[L + λ·φ](g) (``system.legendre().minus``), in the α-fibre chart
g₁ = arrow_from(q₀, τ(x)); with internal stages ζ (docs/conventions.md §22) the unknowns are
(x, ζ, λ₁) and the rows ∂L/∂ζ(g₁, ζ) = 0 follow F⁻.  Second order (seed 001 §4): on the
window (g₀, g₁, g₂), the 2·rank components of F⁻[L + λ·Φ](g₀, g₁, g₂) = p₀ and Φ on both
terms, in the fibre charts of g₁ and g₂.  The Jacobian ∂F/∂(x, λ) is forward-mode
differentiation on the graph, through the fibre chart as for a step (docs/conventions.md
§2).

Onto M = {ψ = 0}: with e(x) = arrow_from(q, τ_q(x)), ψ(β(e(x))) and its Jacobian in x, and
the arrow e(x)⁻¹·a (the groupoid's own multiplication: on a pair groupoid (q, q₁) ↦ (q′, q₁)).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ..._symbols import multiplier_symbols
from ...derivation import (
    WindowAction,
    chart_of,
    named,
    next_arrow,
    second_order_legendre_forms,
    step_jacobian,
)
from ...ir import Graph, Program, from_sympy


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows)."""
    return system._fs


def _nodes(g: Graph, exprs, symbols: dict, what: str, memo: dict) -> list[int]:
    return [from_sympy(g, sp.sympify(e), symbols, what, memo) for e in exprs]


@dataclass
class MomentumProgram:
    """The program of a from-momentum solve and the symbols its inputs stand for.

    First order: inputs ``z`` (the fibre chart coordinates x of g₁, then λ₁), ``q`` (the
    base point α(g₁): ``source``), ``p`` (the momentum), ``params``; outputs ``F``, ``J``
    (∂F/∂z, row-major), ``arrow`` (g₁ = arrow_from(q, τ(x)), from ``z``, ``q``) and ``guess``
    (the chart coordinates of the identity ε(q), from ``q``).  Second order: ``q`` is g₀ (the
    first arrow), ``z`` the charts of g₁, g₂ then λ₀, λ₁; outputs ``F``, ``J``, ``fibres``
    (the fibre variables of g₁, g₂ from their charts) and ``guess`` (the predicted chart of
    the next arrow, from ``q``)."""

    program: Program
    rank: int
    m: int
    source: list  # the symbols of q
    arrow: list  # first order: the symbols of g₁ in the step's known state
    multipliers: list  # the symbols of λ in the step's known state
    n_chart: int = 0  # second order: chart coordinates of g₁, g₂
    n_stages: int = 0  # internal stages ζ of g₁ among the unknowns z (after the chart)


def momentum_program(step, forced: bool = False) -> MomentumProgram:
    """The from-momentum program of a first-order step (see the module docstring), built on
    the expression graph: one term T = L + λ·φ on generic slots and its gradient (reverse
    mode, once), instantiated at the arrow g₁ = arrow_from(q, τ(x)) and contracted with the
    fields X⃗_b there (:meth:`WindowAction.derivation_nodes`, as the momenta of a state are);
    no SymPy derivative of L is taken.  ``forced`` (a forced system): the forced discrete
    Legendre transform X⃗[L](g₁) − f⁻(g₁) = p₀ (Marsden–West eq. (3.2.4); the junction row of
    docs/conventions.md §20 read at g₁) and the forced stage rows ∂L/∂ζ + f_ζ (§22), with a
    further input ``u``, the inputs of g₁."""
    system, G = step.system, step.groupoid
    fs = _functions(system)
    action = WindowAction(G, fs)
    rank, m = G.rank, len(fs.constraints)
    arrow = tuple(named(G, 0, False))
    lam = list(multiplier_symbols(m, 0))
    source = tuple(G.source(arrow))
    x = [sp.Dummy(f"x{a}", real=True) for a in range(rank)]
    zeta = [sp.Dummy(f"zeta{a}", real=True) for a in range(len(fs.stages))]
    p = [sp.Dummy(f"p{a}", real=True) for a in range(rank)]
    params = list(step.parameters)
    on_fibre = tuple(G.arrow_from(source, G.fibre_chart(x, source)))
    g = Graph()
    symbols = {s: g.input(s) for s in (*x, *zeta, *lam, *source, *p, *params)}
    memo: dict = {}
    pnodes = {q: symbols[q] for q in params}
    arrow_nodes = _nodes(g, on_fibre, symbols, f"{step.name}: the fibre chart", memo)
    term = action.term_nodes(g, params, bool(m), step.name)
    lam_nodes = [symbols[a] for a in lam]
    stages = {0: [symbols[z] for z in zeta]}
    minus = action.derivation_nodes(g, term, action.fields(g, "right", arrow_nodes, pnodes),
                                    0, [0], {0: arrow_nodes}, {0: lam_nodes}, stages=stages)
    stage_rows = (action.instantiate(g, term, term.stage_gradient, [arrow_nodes], lam_nodes,
                                     stages=stages[0]) if zeta else [])
    rows = action.instantiate(g, term, term.rows, [arrow_nodes], lam_nodes) if m else []
    u: list = []
    if forced and fs.forces is not None:
        u = [sp.Dummy(f"u{a}", real=True) for a in range(len(fs.forces.inputs))]
        symbols.update({s: g.input(s) for s in u})
        f_minus, f_stages = _force_nodes(g, fs.forces, arrow_nodes, zeta, u, symbols, memo)
        minus = [g.sub(mi, fi) for mi, fi in zip(minus, f_minus)]
        stage_rows = [g.add(r, fz) for r, fz in zip(stage_rows, f_stages)]
    F = [g.sub(mi, symbols[pi]) for mi, pi in zip(minus, p)] + stage_rows + list(rows)
    J = step_jacobian(g, F, [symbols[s] for s in (*x, *zeta, *lam)])
    identity = G.identity(source)
    outputs = {"F": F, "J": [c for row in J for c in row],
               "arrow": arrow_nodes,
               "guess": _nodes(g, G.chart_of_fibre(G.fibre_of(identity), source), symbols,
                               f"{step.name}: the chart of the identity", memo)}
    inputs = {"z": x + zeta + lam, "q": list(source), "p": p, "params": params}
    if forced:
        inputs["u"] = u
    program = Program(g, inputs, outputs)
    return MomentumProgram(program, rank, m, list(source), list(arrow), lam,
                           n_stages=len(zeta))


def _force_nodes(g: Graph, forces, arrow_nodes: list, zeta: list, u: list, symbols: dict,
                 memo: dict) -> tuple[list[int], list[int]]:
    """f⁻ and f_ζ of the arrow whose coordinates are ``arrow_nodes``, with stages ``zeta``
    and inputs ``u`` (symbols with nodes in ``symbols``)."""
    mapping = dict(symbols)
    mapping.update(zip(forces.slot, arrow_nodes))
    mapping.update({s: symbols[z] for s, z in zip(forces.stages, zeta)})
    mapping.update({s: symbols[v] for s, v in zip(forces.inputs, u)})
    minus = [from_sympy(g, e, mapping, "the forces (f⁻)", memo) for e in forces.minus]
    staged = [from_sympy(g, e, mapping, "the stage forces", memo) for e in forces.stage_forces]
    return minus, staged


def second_order_momentum_program(step) -> MomentumProgram:
    """The from-momentum program of a second-order step (see the module docstring)."""
    system, G = step.system, step.groupoid
    fs = _functions(system)
    m = len(fs.constraints)
    forms = second_order_legendre_forms(G, fs, offset=-1)
    g0 = named(G, -1, False)
    g1 = next_arrow(G, g0, 0, False)
    g2 = next_arrow(G, g1, 1, False)
    fib1, chart1, cmap1 = chart_of(G, 0, G.target(g0))
    fib2, chart2, cmap2 = chart_of(G, 1, G.target(g1))
    lam = list(forms.multipliers)
    p = [sp.Dummy(f"p{a}") for a in range(2 * G.rank)]
    params = list(step.parameters)
    eqs = [e - pi for e, pi in zip(forms.minus, p)]
    for a, b in ((g0, g1), (g1, g2)):
        eqs += fs.rows_on(G, [a, b])
    fibres, charts = list(fib1) + list(fib2), list(chart1) + list(chart2)
    sub = {**cmap1, **cmap2}
    n_inputs = 3 * len(getattr(step, "inputs", ()))  # u_{k-1}, u_k, u_{k+1} after them
    knowns = step.knowns[:len(step.knowns) - n_inputs]
    if [str(s) for s in knowns] != [str(s) for s in (*g0, *fibres, *lam)]:
        raise RuntimeError(f"{step.name}: second-order state layout mismatch")
    g = Graph()
    symbols = {s: g.input(s) for s in (*charts, *lam, *g0, *p, *params)}
    memo: dict = {}
    # the fibre variables as intermediates: differentiated through the charts
    fibre_nodes = [symbols[f] if f in symbols else
                   from_sympy(g, sp.sympify(sub.get(f, f)), symbols,
                              f"{step.name}: the fibre chart", memo) for f in fibres]
    symbols.update({f: n for f, n in zip(fibres, fibre_nodes)})
    F = _nodes(g, eqs, symbols, f"{step.name}: the momentum equations", memo)
    J = step_jacobian(g, F, [symbols[s] for s in (*charts, *lam)])
    outputs = {"F": F, "J": [c for row in J for c in row], "fibres": fibre_nodes,
               "guess": _nodes(g, G.predict_chart(g0), symbols,
                               f"{step.name}: the predicted chart", memo)}
    program = Program(g, {"z": charts + lam, "q": list(g0), "p": p, "params": params},
                      outputs)
    return MomentumProgram(program, G.rank, m, list(g0), [], lam, len(charts))


def source_projection_program(step) -> Program:
    """ψ(β(e(x))) and the arrow e(x)⁻¹·a (see the module docstring) of a step's system: see
    :func:`holonomic_projection_program`."""
    return holonomic_projection_program(step.name, step.groupoid, _functions(step.system),
                                        step.parameters)


def holonomic_projection_program(name: str, G, fs, parameters) -> Program:
    """ψ(β(e(x))) and the arrow e(x)⁻¹·a (see the module docstring) of the system ``name``
    on ``G`` with the evaluated functions ``fs``: inputs ``x`` (fibre chart coordinates,
    rank), ``q`` (the source point), ``p`` (the parameters), ``a`` (an arrow); outputs
    ``psi``, ``J`` (∂ψ/∂x, row-major; from ``x``, ``q``, ``p``) and ``moved`` (the arrow
    e(x)⁻¹·a from its own source α(a), from ``x``, ``a``)."""
    q = list(fs.base)
    x = [sp.Dummy(f"x{i}", real=True) for i in range(G.rank)]
    params = list(parameters)
    e = G.arrow_from(tuple(q), G.fibre_chart(tuple(x), tuple(q)))
    psi = [c.xreplace(dict(zip(q, G.target(e)))) for c in fs.holonomic]
    a = [sp.Dummy(f"a{i}", real=True) for i in range(G.arrow_dim)]
    source = tuple(G.source(tuple(a)))
    moved_e = G.arrow_from(source, G.fibre_chart(tuple(x), source))
    moved = G.multiply(G.inverse(moved_e), tuple(a))
    g = Graph()
    symbols = {s: g.input(s) for s in (*x, *q, *params, *a)}
    memo: dict = {}
    psi_nodes = _nodes(g, psi, symbols, f"{name}: the holonomic constraints", memo)
    J = step_jacobian(g, psi_nodes, [symbols[s] for s in x])
    outputs = {"psi": psi_nodes, "J": [c for row in J for c in row],
               "moved": _nodes(g, moved, symbols, f"{name}: the moved arrow", memo)}
    return Program(g, {"x": x, "q": q, "p": params, "a": a}, outputs)

