"""Structural findings: residuals that are exactly zero, residuals free of every unknown,
unknowns that enter no residual — read off the step's program graph, or off its SymPy
residuals for a step known only symbolically.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from ._findings import Finding, Layout, compose
from ._sampling import POINTS, program_of, sample, small_residuals, zero_residuals

_SIMPLIFY_NODES = 400  # rows of at most this many graph nodes are checked for zero exactly


def _unknown_symbols(step) -> list[set] | None:
    """For each unknown, the symbols of the residuals through which it enters: itself and
    the fibre variables whose chart expression (``step.reconstruction``) involves it; None
    when the step does not expose its chart."""
    reconstruction = getattr(step, "reconstruction", None)
    if reconstruction is None:
        return None
    out = []
    for u in step.unknowns:
        syms = {u}
        syms |= {f for f, e in reconstruction.items() if u in sp.sympify(e).free_symbols}
        out.append(syms)
    return out



def structural_findings(step, layout: Layout) -> list[Finding]:
    """Residuals that are exactly 0, residuals free of every unknown, unknowns in no
    residual — read off the program's graph (which unknown inputs each residual node
    depends on); for a symbolic-only step, off its SymPy residuals."""
    program = program_of(step)
    if program is not None:
        return _graph_findings(step, program, layout)
    return _sympy_findings(step, layout)


def _graph_findings(step, program, layout: Layout) -> list[Finding]:
    from ..ir import to_sympy

    g = program.graph
    F = program.outputs["F"]
    unknown_nodes = [g.inputs.get(u) for u in step.unknowns]
    reached = [set(g.reachable([r])) for r in F]
    samples = sample(step, POINTS, 0)
    numeric = len(samples) == POINTS
    small = (np.all([small_residuals(s_) for s_ in samples], axis=0) if numeric
             else np.ones(len(F), dtype=bool))
    vanish = (np.all([zero_residuals(s_) for s_ in samples], axis=0) if numeric
              else np.zeros(len(F), dtype=bool))

    def is_zero(i: int) -> bool:
        """Exactly zero: structurally; or, for a row that is numerically small everywhere
        sampled, as a SymPy expression when it is small enough to simplify (tr(S E) = 0
        for a symmetric S and a skew E, which the graph does not cancel), else by the
        numeric test that tells rounding noise from a small value."""
        if F[i] == g.zero:
            return True
        if not small[i]:
            return False
        if len(reached[i]) <= _SIMPLIFY_NODES:
            return sp.expand(to_sympy(g, [F[i]])[0]) == 0
        return bool(vanish[i])

    zero = [i for i in range(len(F)) if is_zero(i)]
    idle = [i for i in range(len(F)) if i not in zero
            and not any(n is not None and n in reached[i] for n in unknown_nodes)]
    unused = [j for j, n in enumerate(unknown_nodes)
              if n is None or not any(n in r for r in reached)]
    shown = {}
    for i in idle:
        if len(reached[i]) <= 200:
            shown[i] = to_sympy(g, [F[i]])[0]
    return compose(layout, zero, idle, unused, shown)


def _sympy_findings(step, layout: Layout) -> list[Finding]:
    residuals = [sp.sympify(r) for r in step.residuals]
    zero = [i for i, r in enumerate(residuals) if r == 0]
    through = _unknown_symbols(step)
    if through is None:
        return compose(layout, zero, [], [])
    every = set().union(*through)
    free = [r.free_symbols for r in residuals]
    idle = [i for i in range(len(residuals)) if i not in zero and not free[i] & every]
    unused = [j for j, syms in enumerate(through) if not any(f & syms for f in free)]
    return compose(layout, zero, idle, unused, {i: residuals[i] for i in idle})


