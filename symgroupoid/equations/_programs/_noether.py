"""The Noether quantity of a first-order system on the expression graph (seed 000 Thm 4.9):

    F_X = ⟨F⁺L(g), X(β(g))⟩ + f(β(g)),    defect = ⟨F⁻L(g), X(α(g))⟩ + f(α(g)) − F_X,

with F⁻L = X⃗_b[L + λ·φ](g) and F⁺L = X⃖_b[L + λ·φ](g) contracted on the graph from one
gradient of the term (:meth:`~symgroupoid.derivation.WindowAction.derivation_nodes`, as the
momenta of a state are), at the generic internal stages ζ of a discrete Lagrangian with
stages (docs/conventions.md §22), which the evaluator solves for.  No SymPy derivative of L
is taken: the symbolic Legendre transforms of a Galerkin step on SO(3) take minutes.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ...derivation import WindowAction
from ...ir import Graph, from_sympy


def noether_nodes(system, ends: tuple, arrow: Sequence, multipliers: Sequence, g: Graph,
                  symbols: dict, memo: dict) -> tuple[int, int, list[int]]:
    """(F_X, defect, stage rows ∂L/∂ζ) nodes of ``system`` at the arrow ``arrow`` with
    multipliers ``multipliers`` and the system's generic stages (no stage rows without
    stages); ``ends`` = (X(α), f(α), X(β), f(β))
    (:func:`~symgroupoid.derivation.noether_ends`); ``symbols`` maps the arrow, the
    multipliers, the stages and the parameters to input nodes of ``g``."""
    G, fs = system.groupoid, system._fs
    parameters = list(system.parameters)
    action = WindowAction(G, fs)
    term = action.term_nodes(g, parameters, bool(fs.constraints), system.name)
    pnodes = {p: symbols[p] for p in parameters}
    nodes = {0: [symbols[a] for a in arrow]}
    lam = {0: [symbols[x] for x in multipliers]}
    stages = {0: [symbols[z] for z in fs.stages]} if fs.stages else None

    def momenta(side: str) -> list[int]:
        fields = action.fields(g, side, nodes[0], pnodes)
        return action.derivation_nodes(g, term, fields, 0, [0], nodes, lam, stages=stages)

    def paired(X: list, values: list[int], f: sp.Expr, where: str) -> int:
        out = [from_sympy(g, f, symbols, f"{system.name}: f at {where}", memo)]
        for a, (c, v) in enumerate(zip(X, values)):
            coefficient = from_sympy(g, c, symbols, f"{system.name}: the section at {where} "
                                     f"(coefficient {a})", memo)
            out.append(g.mul(coefficient, v))
        return g.add(*out)

    Xa, fa, Xb, fb = ends
    F = paired(Xb, momenta("left"), fb, "β(g)")
    rows = (action.instantiate(g, term, term.stage_gradient, [nodes[0]], lam[0],
                               stages=stages[0]) if stages else [])
    return F, g.sub(paired(Xa, momenta("right"), fa, "α(g)"), F), rows


__all__ = ["noether_nodes"]
