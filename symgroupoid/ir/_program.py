"""Programs: named input arrays and named output arrays over one expression graph.

A :class:`Program` is what every kernel is — the step residual and Jacobian, the chart, the
prediction, a boundary-value window — in the manner of a CasADi ``Function``: inputs are
named arrays of symbols (``u``, ``known``, ``p``), outputs are named arrays of graph nodes
(``F``, ``J``, …).  It can be evaluated with NumPy (straight-line Python generated from the
graph, vectorised over a trailing batch axis) and printed to C (:mod:`symgroupoid.codegen`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from ._graph import CONST, FUNC, INPUT, POW, Graph


@dataclass
class Program:
    """Outputs over a graph, with the inputs they read (see the module docstring)."""

    graph: Graph
    inputs: dict  # name -> list of symbols (the array's entries, in order)
    outputs: dict  # name -> list of node ids
    _numpy: dict = field(default_factory=dict, repr=False)

    def input_positions(self) -> dict:
        """Input node id → (array name, index)."""
        out = {}
        for name, symbols in self.inputs.items():
            for i, s in enumerate(symbols):
                node = self.graph.inputs.get(s)
                if node is not None:
                    out[node] = (name, i)
        return out

    def nodes(self, names: Sequence[str] | None = None) -> list[int]:
        """Every node the named outputs need, ascending."""
        names = list(self.outputs) if names is None else names
        return self.graph.reachable([n for k in names for n in self.outputs[k]])

    def size(self, names: Sequence[str] | None = None) -> int:
        """Number of operations (non-leaf nodes) the named outputs need."""
        return sum(1 for n in self.nodes(names) if self.graph.args[n])

    def compacted(self) -> Program:
        """The same outputs over a new graph with fewer operations
        (:func:`~symgroupoid.ir.compact`: one node for S and −S, shared prefixes of products
        and sums); every input symbol keeps an input node."""
        from ._compact import compact

        names = list(self.outputs)
        flat = [n for k in names for n in self.outputs[k]]
        graph, nodes = compact(self.graph, flat)
        for symbols in self.inputs.values():
            for s in symbols:
                graph.input(s)
        outputs, k = {}, 0
        for name in names:
            m = len(self.outputs[name])
            outputs[name] = nodes[k:k + m]
            k += m
        return Program(graph, {k: list(v) for k, v in self.inputs.items()}, outputs)

    def check_inputs(self, names: Sequence[str] | None = None) -> None:
        """Every input node the outputs read is an entry of an input array."""
        known = self.input_positions()
        g = self.graph
        stray = [g.data[n] for n in self.nodes(names) if g.op[n] == INPUT and n not in known]
        if stray:
            raise ValueError(f"program reads symbols that are not inputs: "
                             f"{', '.join(sorted(str(s) for s in stray))}")

    def fingerprint(self) -> str:
        """Exact deterministic text of the program (inputs by position)."""
        g = self.graph
        outs = [n for k in self.outputs for n in self.outputs[k]]
        pos = self.input_positions()
        order = g.reachable(outs)
        local = {n: k for k, n in enumerate(order)}
        parts = [",".join(f"{k}:{len(v)}" for k, v in self.inputs.items())]
        for n in order:
            o = g.op[n]
            d = g.data[n]
            if o == INPUT:
                name, i = pos.get(n, ("?", d.name))
                payload = f"{name}[{i}]"
            elif o == CONST:
                payload = sp.srepr(d)
            elif o == POW:
                payload = sp.srepr(d)
            elif o == FUNC:
                payload = d.key_text
            else:
                payload = ""
            parts.append(f"{o}({','.join(str(local[a]) for a in g.args[n])}){payload}")
        for k, v in self.outputs.items():
            parts.append(f"{k}=" + ",".join(str(local[n]) for n in v))
        return ";".join(parts)

    # --- NumPy evaluation ---------------------------------------------------------------------
    def numpy_function(self, outputs: Sequence[str], inputs: Sequence[str]):
        """``f(*arrays) -> tuple of arrays`` for the named outputs.

        Input arrays have shape (n,) or (n, B) (a batch of B points); each output is returned
        with shape (m,) or (m, B).
        """
        key = (tuple(outputs), tuple(inputs))
        f = self._numpy.get(key)
        if f is None:
            f = _compile_numpy(self, list(outputs), list(inputs))
            self._numpy[key] = f
        return f


def _compile_numpy(program: Program, outputs: list[str], inputs: list[str]):
    from ._format import NUMPY, functions_used, listing
    from ._libm import namespace as libm_namespace

    g = program.graph
    pos = program.input_positions()
    outs = [n for k in outputs for n in program.outputs[k]]
    arrays = {k: i for i, k in enumerate(inputs)}
    names: dict = {}
    for n in g.reachable(outs):
        if g.op[n] == INPUT:
            array, i = pos.get(n, (None, None))
            if array not in arrays:
                raise ValueError(f"the outputs {outputs} read {g.data[n]}, which is not in "
                                 f"the inputs {inputs}")
            names[n] = f"_in{arrays[array]}[{i}]"
    code = listing(g, outs, names, NUMPY)
    namespace: dict = {"np": np, **libm_namespace()}
    for spec in functions_used(g, outs):
        namespace.update(spec.numpy_namespace())
    lines = [f"def _f({', '.join('_in' + str(i) for i in range(len(inputs)))}):"]
    lines += [f"    {t} = {e}" for t, e in code.statements]
    k = 0
    for name in outputs:
        m = len(program.outputs[name])
        lines.append(f"    _o_{name} = [{', '.join(code.outputs[k:k + m])}]")
        k += m
    lines.append("    return (" + "".join(f"_o_{name}, " for name in outputs) + ")")
    source = "\n".join(lines) + "\n"
    exec(compile(source, f"<program {'/'.join(outputs)}>", "exec"), namespace)  # noqa: S102
    raw = namespace["_f"]

    def evaluate(*arrays):
        values = [np.asarray(a, dtype=float) for a in arrays]
        batch = next((v.shape[1:] for v in values if v.ndim > 1), ())
        with np.errstate(all="ignore"):
            results = raw(*values)
        return tuple(np.array([np.broadcast_to(np.asarray(x, dtype=float), batch) for x in r],
                              dtype=float).reshape((len(r),) + batch) for r in results)

    return evaluate
