"""The programs of a boundary-value solve: window residuals and blocks, the cost, and the
structure maps a solve applies to rows of arrows.

A discrete two-point problem (seed 000 §6.1–6.2, seed 001 §3.3) moves every free junction j
by a variation δ_j ∈ R^rank, g_j ↦ g_j · h(δ_j), g_{j+1} ↦ h(δ_j)⁻¹ · g_{j+1}.  Its equations
are the junction residuals and the constraints of every term; its Jacobian's blocks are the
derivatives of a window's residuals along the section fields on each of its arrows.  All
come from the window action of :class:`~symgroupoid.derivation.WindowAction` — the same
junction variation as a step's — on the expression graph:

- the *junction* program: for one window (arrows A_o, multipliers λ_s, and for a forced
  system the inputs u_s of each term), the junction residual
  r_b = X⃖_b[S](A_0) − X⃗_b[S](A_1) (docs/conventions.md §2) — with the forces of the
  window's terms at the junction node, f⁺_b(A_0) + f⁻_b(A_1) for a forced system of first
  order (the discrete Lagrange–d'Alembert principle, §20) —, then for each slot o the blocks
  X⃖_c[r_b] and X⃗_c[r_b] on A_o, then ∂r/∂λ_s, then the running-error bound of each r_b
  (:func:`symgroupoid.ir.rounding_error`, the coordinates and multipliers counted as rounded
  values);
- with internal stages ζ (docs/conventions.md §22), the *stage* program: the stage rows
  ∂L/∂ζ(A, ζ) (+ f_ζ) of one term, their blocks along the fields on its arrow and ∂/∂ζ (the
  junction program then also reads the stages of its terms, and gives ∂r/∂ζ_s);
- the *term* program (with constraints): φ on one term, its blocks along the fields on each
  of its arrows, and its rounding bounds;
- the *cost* program: L on one term (the discrete cost Σ_k L);
- the *structure* program: the product m(a, b), the inverse of a, the target β(a), the section
  flow h(δ) ⊂ α⁻¹(β(a)) and the flow from a base point q.

The inputs are plain, position-named symbols, so the generated code depends on nothing else.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from ...derivation import WindowAction, field_derivatives, slot_derivatives
from ...ir import Graph, Program, forward, from_sympy, rounding_error


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows)."""
    return system._fs


@dataclass
class WindowPrograms:
    """The junction and term programs of a system's window (see the module docstring) and
    the shape of their outputs.

    ``junction``: input ``a`` = the window's arrow coordinates (offset by offset), its
    multipliers (term by term), the inputs of a forced system (term by term: ``n_inputs``
    values u_s of the term starting at offset s, docs/conventions.md §20), the parameters;
    output ``junction`` = [r (rank), per offset o:
    (rank × 2 × rank) blocks X⃖_c[r_b], X⃗_c[r_b] (row b, side, section c), per start s:
    ∂r_b/∂λ_s (rank × m), per start s: ∂r_b/∂ζ_s (rank × n_stages), rounding bounds (rank)];
    with internal stages (docs/conventions.md §22) ``a`` holds the stages ζ_s of every term
    after the multipliers, and ``stage`` is the program of one term's stage rows: input
    ``a`` = its arrow, ζ, its inputs, the parameters; output ``stage`` = [the rows
    (n_stages), per row: the blocks along X⃖_c, X⃗_c on the arrow (2 × rank), ∂/∂ζ
    (n_stages × n_stages), rounding bounds (n_stages)].  ``term`` (None without constraints):
    input ``a`` = the arrows of one term, the parameters; output ``term`` = [φ (m), per slot o:
    (m × 2 × rank) blocks, rounding bounds (m)].  ``forced``: the junction residual carries
    the forces (``n_inputs`` may be 0: forces without inputs, such as damping).
    """

    name: str
    rank: int
    m: int
    held: int  # the last ``held`` multipliers are holonomic (docs/conventions.md §15)
    arity: int
    offsets: list
    starts: list
    parameters: list
    junction: Program
    term: Program | None
    forced: bool = False
    n_inputs: int = 0
    n_stages: int = 0
    stage: Program | None = None


def window_programs(system) -> WindowPrograms:
    """The :class:`WindowPrograms` of a system (see the module docstring)."""
    G, fs = system.groupoid, _functions(system)
    action = WindowAction(G, fs)
    r, m, arity = G.rank, action.m, action.arity
    offsets, starts = action.offsets, action.starts
    parameters = list(system.parameters)
    g = Graph()
    A = {o: [sp.Symbol(f"a{o + 2}_{i}", real=True) for i in range(G.arrow_dim)] for o in offsets}
    lam = {s: [sp.Symbol(f"l{s + 2}_{a}", real=True) for a in range(m)] for s in starts}
    nodes = {x: g.input(x) for o in offsets for x in A[o]}
    nodes.update({x: g.input(x) for s in starts for x in lam[s]})
    forced = fs.forces is not None
    n_inputs = len(fs.forces.inputs) if forced else 0
    U = {s: [sp.Symbol(f"u{s + 2}_{j}", real=True) for j in range(n_inputs)] for s in starts}
    nodes.update({x: g.input(x) for s in starts for x in U[s]})
    n_stages = len(fs.stages)
    Z = {s: [sp.Symbol(f"z{s + 2}_{a}", real=True) for a in range(n_stages)] for s in starts}
    nodes.update({x: g.input(x) for s in starts for x in Z[s]})
    pnodes = {p: g.input(p) for p in parameters}
    arrows = {o: [nodes[x] for x in A[o]] for o in offsets}
    inputs = {s: [nodes[x] for x in U[s]] for s in starts} if forced else None
    stages = {s: [nodes[x] for x in Z[s]] for s in starts} if n_stages else None
    jn = action.junction_nodes(g, pnodes, arrows, {s: [nodes[x] for x in lam[s]] for s in starts},
                               inputs, stages)
    fields = {o: (action.fields(g, "left", arrows[o], pnodes),
                  action.fields(g, "right", arrows[o], pnodes)) for o in offsets}
    res = jn.residuals
    order = g.reachable(res)
    blocks = list(res)
    along = field_derivatives(g, res, arrows, fields)
    for o in offsets:
        for b in range(r):
            blocks += [along[o][side][c][b] for side in (0, 1) for c in range(r)]
    for s in starts:
        d = [forward(g, res, {nodes[x]: g.one}, order) for x in lam[s]]
        blocks += [d[a][b] for b in range(r) for a in range(m)]
    for s in starts:  # ∂r/∂ζ_s (docs/conventions.md §22; none without internal stages)
        d = [forward(g, res, {nodes[x]: g.one}, order) for x in Z[s]]
        blocks += [d[a][b] for b in range(r) for a in range(n_stages)]
    coords = [x for o in offsets for x in A[o]]
    lams = [x for s in starts for x in lam[s]]
    zs = [x for s in starts for x in Z[s]]
    # the rounding bound of each junction residual, the coordinates, multipliers and stages
    # counted as rounded values
    blocks += rounding_error(g, res, [nodes[x] for x in coords + lams + zs])
    # the inputs are data of the problem, exact as given: not counted as rounded values
    us = [x for s in starts for x in U[s]]
    junction = Program(g, {"a": coords + lams + zs + us + parameters}, {"junction": blocks})
    stage = (_stage_program(g, jn.stage_rows[0], arrows[0], fields[0], A[0],
                            [nodes[x] for x in Z[0]], Z[0] + U[0] + parameters)
             if n_stages else None)
    term = None
    if m:
        values = jn.constraints[0]
        corder = g.reachable(values)
        cblocks = list(values)
        for o in range(arity):
            d = [slot_derivatives(g, values, arrows[o], fields[o][side], corder)
                 for side in (0, 1)]
            for e in range(m):
                cblocks += [d[side][c][e] for side in (0, 1) for c in range(r)]
        ccoords = [x for o in range(arity) for x in A[o]]
        cblocks += rounding_error(g, values, [nodes[x] for x in ccoords])
        term = Program(g, {"a": ccoords + parameters}, {"term": cblocks})
    return WindowPrograms(system.name, r, m, fs.n_holonomic, arity, offsets, starts,
                          parameters, junction, term, forced, n_inputs, n_stages, stage)


def _stage_program(g: Graph, values: list, arrow: list, fields: tuple, coords: list,
                   zeta: list, rest: list) -> Program:
    """The *stage* program of one term (docs/conventions.md §22): its stage rows
    ∂L/∂ζ(g, ζ) (+ f_ζ(g, ζ, u) when forced), their blocks along the fields X⃖_c, X⃗_c on
    the term's arrow, ∂/∂ζ, and their rounding bounds (the coordinates and the stages
    counted as rounded values).  Input ``a`` = the arrow's coordinates, ζ, the inputs, the
    parameters (``rest``: ζ's symbols, the inputs', the parameters')."""
    order = g.reachable(values)
    n = len(values)
    d = [slot_derivatives(g, values, arrow, fields[side], order) for side in (0, 1)]
    dz = [forward(g, values, {z: g.one}, order) for z in zeta]
    out = list(values)
    for e in range(n):
        out += [d[side][c][e] for side in (0, 1) for c in range(len(fields[side]))]
    out += [dz[a][e] for e in range(n) for a in range(len(zeta))]
    out += rounding_error(g, values, arrow + zeta)
    return Program(g, {"a": list(coords) + list(rest)}, {"stage": out})


def cost_program(system) -> Program:
    """L on one term of ``arity`` consecutive arrows: input ``a`` (the term's arrow
    coordinates, then the parameters), output ``cost`` (one value): the discrete cost
    S = Σ_k L(g_k, …, g_{k+arity−1}) of an arrow sequence is its sum over the terms.  With
    internal stages ζ (docs/conventions.md §22) the term's stages follow its arrows in ``a``:
    L(g_k, ζ_k), which is L_d(g_k) where ζ_k solves the stage rows."""
    fs = _functions(system)
    g = Graph()
    coords = [c for slot in fs.slots for c in slot] + list(fs.stages)
    symbols = {c: g.input(c) for c in coords}
    symbols.update({q: g.input(q) for q in system.parameters})
    lagrangian = from_sympy(g, fs.lagrangian, symbols, f"{system.name}: the Lagrangian")
    return Program(g, {"a": coords + list(system.parameters)}, {"cost": [lagrangian]})


def action_program(system) -> Program:
    """L and φ (as in the action: holonomic ones as ψ at the term's source node,
    docs/conventions.md §15) on one term: input ``a`` (the term's arrow coordinates),
    ``p`` (the parameters), with internal stages ``z`` (the term's ζ, docs/conventions.md
    §22); outputs ``L`` (one value) and ``phi`` (m values)."""
    fs = _functions(system)
    g = Graph()
    coords = [c for slot in fs.slots for c in slot]
    symbols = {c: g.input(c) for c in (*coords, *fs.stages, *system.parameters)}
    memo: dict = {}
    L = from_sympy(g, fs.lagrangian, symbols, f"{system.name}: the Lagrangian", memo)
    phi = [from_sympy(g, c, symbols, f"{system.name}: constraint {a + 1}", memo)
           for a, c in enumerate(fs.constraints)]
    inputs = {"a": coords, "p": list(system.parameters)}
    if fs.stages:
        inputs["z"] = list(fs.stages)
    return Program(g, inputs, {"L": [L], "phi": phi})


@functools.lru_cache(maxsize=16)
def structure_program(G, parameters: Sequence = ()) -> Program:
    """The structure maps a solve applies to rows of arrows, on the expression graph:
    inputs ``a``, ``b`` (arrows), ``d`` (section coordinates, rank), ``q`` (a base point),
    ``p`` (the system's ``parameters``, which a groupoid's maps may use: an Atiyah
    groupoid's connection with the inertias in it);
    outputs ``multiply`` = m(a, b), ``inverse`` = a⁻¹, ``target`` = β(a), ``flow`` = the
    section flow h(δ) ⊂ α⁻¹(β(a)) (:meth:`~symgroupoid.groupoids.Groupoid.section_flow_nodes`:
    the section curves h_c(δ_c) composed, each at the target of the product so far) and
    ``flow_from`` = the same flow from the base point q (at the identity ε(q))."""
    a = tuple(sp.Dummy(f"a{i}", real=True) for i in range(G.arrow_dim))
    b = tuple(sp.Dummy(f"b{i}") for i in range(G.arrow_dim))
    d = tuple(sp.Dummy(f"d{i}") for i in range(G.rank))
    q = tuple(sp.Dummy(f"q{i}", real=True) for i in range(G.base_dim))
    g = Graph()
    nodes = {x: g.input(x) for x in (*a, *b, *d, *parameters)}
    memo: dict = {}

    def build(exprs, what: str) -> list[int]:
        return [from_sympy(g, sp.sympify(e), nodes, f"{G.name}: {what}", memo) for e in exprs]

    outputs = {"multiply": build(G.multiply(a, b), "the multiplication"),
               "inverse": build(G.inverse(a), "the inverse"),
               "flow": G.section_flow_nodes(g, [nodes[x] for x in a], [nodes[x] for x in d])}
    outputs["target"] = build(G.target(a), "the target")
    nodes.update({x: g.input(x) for x in q})
    identity = build(G.identity(q), "the identity")
    outputs["flow_from"] = G.section_flow_nodes(g, identity, [nodes[x] for x in d])
    return Program(g, {"a": list(a), "b": list(b), "d": list(d), "q": list(q),
                       "p": list(parameters)}, outputs)
