"""The program of a step: residual, exact Jacobian, chart, prediction and state update as
outputs of one expression graph (:class:`symgroupoid.ir.Program`).

Steps derived on the graph (``DerivedStep.window``) reuse its residual nodes; steps known only
as SymPy expressions (e.g. the Lie–Poisson reconstruction) are captured into a graph here.
Either way the Jacobian ∂F/∂(x, λ) is forward-mode differentiation through the fibre chart
f = τ(x) (docs/conventions.md §2), never a SymPy ``jacobian`` of expanded trees.  The
finished program is compacted (:func:`symgroupoid.ir.compact`): the same values in fewer
floating-point operations, the form the C kernels and the NumPy backend both evaluate.
The output ``domain`` holds the values of the window's terms that are defined on part of
the real line only (log, square roots, acos, …): a solution of the step is accepted only
where they are finite (docs/conventions.md §11, "Staying in the domain of L").
Beside the residual it carries ``F_scale``, the size of the terms each residual is computed
from (:func:`symgroupoid.ir.term_magnitude`, on the compacted graph): Newton's rounding-floor
tests read it (docs/conventions.md, "Newton's stopping rule").
"""

from __future__ import annotations

from ...derivation import step_jacobian
from ...ir import Graph, Program, from_sympy, term_magnitude


def _symbol_table(g: Graph, step, symbols: dict, memo: dict) -> dict:
    """Inputs for the knowns, unknowns and parameters; the unknown arrow's fibre variables
    as chart nodes."""
    for s in (*step.knowns, *step.unknowns, *step.parameters):
        if s not in symbols:
            symbols[s] = g.input(s)
    for f, value in step.reconstruction.items():
        if f not in symbols:
            symbols[f] = from_sympy(g, value, symbols, f"{step.name}: the fibre chart", memo)
    return symbols


def step_program(step, compacted: bool = True) -> Program:
    """The :class:`Program` of a :class:`StepEquations` (see the module docstring), compacted
    (:meth:`Program.compacted`: fewer operations for the same values) unless ``compacted``
    is False."""
    d = step._d
    if d.window is not None:
        g, symbols, memo = d.window.graph, d.window.symbols, d.window.memo
        _symbol_table(g, step, symbols, memo)
        F = list(d.window.residuals)
    else:
        g, symbols, memo = Graph(), {}, {}
        _symbol_table(g, step, symbols, memo)
        F = [from_sympy(g, r, symbols, f"{step.name}: residual {i}", memo)
             for i, r in enumerate(d.sympy_residuals())]
    unknowns = [symbols[u] for u in step.unknowns]
    J = step_jacobian(g, F, unknowns)

    def nodes(exprs, what):
        return [from_sympy(g, e, symbols, f"{step.name}: the {what}", memo) for e in exprs]

    fibre = [symbols[f] for f in step.fibre_unknowns if f in step.reconstruction]
    outputs = {"F": F, "J": [c for row in J for c in row], "fibre": fibre,
               "predict": nodes(step.prediction, "prediction"),
               "next_knowns": nodes(step.next_knowns, "state update"),
               "domain": list(d.window.domain) if d.window is not None else []}
    inputs = {"u": list(step.unknowns), "known": list(step.knowns),
              "p": list(step.parameters)}
    program = Program(graph=g, inputs=inputs, outputs=outputs)
    program.check_inputs()
    return with_residual_scale(program.compacted() if compacted else program)


def input_jacobian_program(step) -> Program:
    """∂F/∂(u_k, u_{k+1}) of a forced step (docs/conventions.md §20): the residual's exact
    derivative with respect to the inputs of the window's terms (the last (r + 1)·m
    knowns, r the order: u_k, u_{k+1}; second order u_{k−1}, u_k, u_{k+1}), by forward mode
    on the step's graph — what a controller or an optimiser linearises.  Inputs ``u``
    (unknowns), ``known``, ``p``; outputs ``F`` and ``J_inputs`` (row-major,
    n × (r + 1)·m)."""
    program = step.program
    g = program.graph
    m = (step.order + 1) * len(step.inputs)
    columns = [g.inputs[s] for s in step.knowns[len(step.knowns) - m:]]
    F = list(program.outputs["F"])
    J = step_jacobian(g, F, columns)
    return Program(graph=g, inputs=program.inputs,
                   outputs={"F": F, "J_inputs": [c for row in J for c in row]})


def with_residual_scale(program: Program) -> Program:
    """``program`` with the output ``F_scale``: S_i, the size of the terms F_i is built from
    (the unknowns ``u`` varying; :func:`symgroupoid.ir.term_magnitude`)."""
    g = program.graph
    varying = [g.inputs[s] for s in program.inputs["u"] if s in g.inputs]
    scale = term_magnitude(g, program.outputs["F"], varying)
    return Program(graph=g, inputs=program.inputs, outputs={**program.outputs, "F_scale": scale})
