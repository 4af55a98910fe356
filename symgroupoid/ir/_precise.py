"""A program's outputs at many digits: the graph walked node by node in mpmath.

The C kernels and the NumPy twin evaluate a program in binary64.  Checking an identity that
holds only on a submanifold — a printed form of a step on a Lie group, whose rows equal the
residual on the group and not in the free entries of the attitudes (docs/conventions.md
§22) — needs the residual at a point of the group to far more digits than the identity's
own rounding: :func:`interpret_precise` evaluates the same nodes with mpmath at ``dps``
decimal digits, the graph's exact constants (√3/6 of a Gauss node) rounded at that
precision, so that at 50 digits two sides of a true identity agree to their rounding
(3–8·10⁻⁵¹ of their size, measured on the group stage notation of a heavy top).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import mpmath
import sympy as sp

from ._functions import Smooth
from ._graph import ADD, CONST, FUNC, INPUT, MUL, POW
from ._program import Program
from ._smooth import precise_number


def interpret_precise(program: Program, outputs: Sequence[str],
                      values: Mapping[sp.Symbol, object], dps: int = 50) -> dict:
    """The named outputs at ``values`` (every input symbol the outputs read → a number,
    converted with :func:`mpmath.mpf`), each a list of :class:`mpmath.mpf` at ``dps``
    digits.  An input the outputs read and ``values`` lacks raises KeyError."""
    g = program.graph
    outs = [n for name in outputs for n in program.outputs[name]]
    value: dict = {}
    with mpmath.workdps(dps):
        for n in g.reachable(outs):
            value[n] = _node_value(g, n, value, values, dps)
        results, k = {}, 0
        for name in outputs:
            m = len(program.outputs[name])
            results[name] = [+value[x] for x in outs[k:k + m]]
            k += m
    return results


def _node_value(g, n: int, value: dict, values: Mapping, dps: int):
    o, a = g.op[n], g.args[n]
    if o == CONST:
        return precise_number(g.data[n], dps + 10)
    if o == INPUT:
        return mpmath.mpf(values[g.data[n]])
    if o == ADD:
        return mpmath.fsum(value[x] for x in a)
    if o == MUL:
        product = value[a[0]]
        for x in a[1:]:
            product = product * value[x]
        return product
    if o == POW:
        e = g.data[n]
        base = value[a[0]]
        return base ** int(e) if e.is_Integer else base ** precise_number(e, dps + 10)
    if o == FUNC:
        spec = g.data[n]
        if isinstance(spec, Smooth):  # its closed form, exactly (not binary64's polynomial)
            return spec.cls.precise(value[a[0]])
        args = [sp.Float(value[x], dps) for x in a]
        return precise_number(spec.sympy(args), dps + 10)
    raise ValueError(f"node {n}: unknown operation {o}")



__all__ = ["interpret_precise"]
