"""Programs: named input arrays and named output arrays over one expression graph.

A :class:`Program` is what every kernel is — the step residual and Jacobian, the chart, the
prediction, a boundary-value window — in the manner of a CasADi ``Function``: inputs are
named arrays of symbols (``u``, ``known``, ``p``), outputs are named arrays of graph nodes
(``F``, ``J``, …).  It can be evaluated with NumPy (straight-line Python generated from the
graph, vectorised over a trailing batch axis) and printed to C (:mod:`symgroupoid.codegen`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from .._errors import DomainError
from ._graph import ADD, CONST, FUNC, INPUT, MUL, POW, Graph

#: the largest count of expanded terms reported (:func:`product_terms`, :func:`power_terms`)
TERMS_CAP = 10**30


def product_terms(inner: Sequence[int]) -> int:
    """Terms of a product of factors of ``inner`` terms each, expanded without
    cancellation: their product, or :data:`TERMS_CAP` past it."""
    value = 1
    for t in inner:
        value = min(value * t, TERMS_CAP)
    return value


def power_terms(t: int, n: int) -> int:
    """Monomials of degree n in t terms, C(t + n − 1, n), or :data:`TERMS_CAP` past it
    (exact below it: with n and t − 1 both at least 64 the count is at least
    C(128, 64) > 10³⁰, and otherwise C(t + n − 1, min(n, t − 1)) takes fewer than 64
    products)."""
    k = min(n, t - 1)
    if k >= 64:
        return TERMS_CAP
    return min(math.comb(t + n - 1, max(k, 0)), TERMS_CAP)


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

    def _known_names(self, names, entry: str) -> list:
        """``names`` if it is a list of this program's outputs, else a DomainError."""
        unknown = [k for k in names if not isinstance(k, str) or k not in self.outputs]
        if isinstance(names, str) or unknown:
            raise DomainError(f"{entry}: names must be a list of the program's outputs "
                              f"({', '.join(map(repr, self.outputs))}), got {names!r}")
        return list(names)

    def expanded_size(self, names: Sequence[str] | None = None) -> int:
        """Number of operations of the named outputs written out as expression trees, a
        node counted at every use (what printing them as formulas costs; :meth:`size`
        counts each once).  Exact, in integers, however large.  A name the program does not
        output is a :class:`~symgroupoid.DomainError`."""
        g = self.graph
        names = list(self.outputs) if names is None else names
        outputs = [n for k in self._known_names(names, "expanded_size") for n in self.outputs[k]]
        size: dict = {}
        for n in g.reachable(outputs):
            size[n] = 1 + sum(size[a] for a in g.args[n]) if g.args[n] else 0
        return sum(size[n] for n in outputs)

    def expanded_terms(self, names: Sequence[str]) -> int:
        """A bound on the number of terms of the named outputs written out as formulas and
        expanded, without cancellation, by the rules the printers bound a SymPy
        expression's with: a sum has its terms' sum, a product their product
        (:func:`product_terms`), a positive integer power pⁿ of t terms at most
        C(t + n − 1, n) (:func:`power_terms`); a negative or fractional power, a function,
        an input or a constant is one term.  Values past 10³⁰ are 10³⁰.  A name the
        program does not output is a :class:`~symgroupoid.DomainError`."""
        g = self.graph
        outputs = [n for k in self._known_names(names, "expanded_terms") for n in self.outputs[k]]
        terms: dict = {}
        for n in g.reachable(outputs):
            inner = [terms[a] for a in g.args[n]]
            if g.op[n] == ADD:
                value = min(sum(inner), TERMS_CAP)
            elif g.op[n] == MUL:
                value = product_terms(inner)
            elif g.op[n] == POW and g.data[n].is_Integer and g.data[n] > 0:
                value = power_terms(inner[0], int(g.data[n]))
            else:
                value = 1
            terms[n] = value
        return min(sum(terms[n] for n in outputs), TERMS_CAP)

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


def interpret(program: Program, outputs: Sequence[str], inputs: Sequence[str], *arrays):
    """The named outputs at input arrays of shape (n,) or (n, B), evaluated by walking the
    graph node by node with NumPy — the operations of :meth:`Program.numpy_function`, bit for
    bit (``tests/test_format_inlining.py``), without printing and compiling code first.  For
    a few evaluations of a large program (a derivation's regularity samples) this is the
    cheaper way; for many, the compiled function is.  Returns a tuple of arrays of shape
    (m,) or (m, B)."""
    from ._format import NUMPY
    from ._libm import namespace as libm_namespace

    g = program.graph
    pos = program.input_positions()
    values_in = [np.asarray(a, dtype=float) for a in arrays]
    batch = next((v.shape[1:] for v in values_in if v.ndim > 1), ())
    index = {name: i for i, name in enumerate(inputs)}
    outs = [n for k in outputs for n in program.outputs[k]]
    namespace: dict = {"np": np, **libm_namespace()}
    functions: dict = {}
    value: dict = {}
    with np.errstate(all="ignore"):
        for n in g.reachable(outs):
            o, a = g.op[n], g.args[n]
            if o == CONST:
                value[n] = float(g.data[n])
            elif o == INPUT:
                array, i = pos.get(n, (None, None))
                if array not in index:
                    raise ValueError(f"the outputs {list(outputs)} read {g.data[n]}, which "
                                     f"is not in the inputs {list(inputs)}")
                value[n] = values_in[index[array]][i]
            elif o == ADD:
                total = value[a[0]]
                for x in a[1:]:
                    total = total + value[x]
                value[n] = total
            elif o == MUL:
                product = value[a[0]]
                for x in a[1:]:
                    product = product * value[x]
                value[n] = product
            elif o == POW:
                value[n] = _power(value[a[0]], g.data[n], namespace[NUMPY.pow])
            else:
                spec = g.data[n]
                f = functions.get(spec.key)
                if f is None:
                    names = [f"_a{k}" for k in range(len(a))]
                    scope = {**namespace, **spec.numpy_namespace()}
                    f = eval(f"lambda {', '.join(names)}: "  # noqa: S307 - our own text
                             f"{spec.numpy_expression(names)}", scope)
                    functions[spec.key] = f
                value[n] = f(*[value[x] for x in a])
    results, k = [], 0
    for name in outputs:
        m = len(program.outputs[name])
        rows = [np.broadcast_to(np.asarray(value[x], dtype=float), batch)
                for x in outs[k:k + m]]
        results.append(np.array(rows, dtype=float).reshape((m,) + batch))
        k += m
    return tuple(results)


def _power(base, e: sp.Expr, pow_function):
    """base**e as the formatter writes it: small integer powers as products, square roots
    with sqrt, others with the C library's pow."""
    from ._format import MAX_UNROLLED_POWER

    if e.is_Integer and 1 <= abs(int(e)) <= MAX_UNROLLED_POWER:
        product = base
        for _ in range(abs(int(e)) - 1):
            product = product * base
        return product if e > 0 else 1.0 / product
    if e == sp.Rational(1, 2):
        return np.sqrt(base)
    if e == sp.Rational(-1, 2):
        return 1.0 / np.sqrt(base)
    return pow_function(base, float(e))


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
