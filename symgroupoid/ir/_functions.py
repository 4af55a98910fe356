"""Elementary functions of the expression graph: evaluation, derivatives, C and NumPy forms.

Each function the graph can hold is a :class:`FunctionSpec`: how to fold it on exact
constants, its partial derivatives (as graph nodes, built from the argument nodes), its C
expression and its NumPy expression.  Three kinds:

- the elementary functions of ``math.h`` (sin, cos, exp, log, atan2, …);
- the smooth special functions of the exponential retraction
  (:mod:`symgroupoid.ir._smooth`), printed as small C helper functions;
- any other SymPy function of the arguments (``Piecewise``, ``Max``, …): an *opaque* spec
  holding a SymPy expression in placeholder symbols, printed by SymPy's printers and
  differentiated by SymPy — exact, and rare in mechanics.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .._lambdify import NUMPY_MODULES
from ._graph import Graph
from ._libm import LIBM, SCALAR, numpy_name


class FunctionSpec:
    """An elementary function of the graph (see the module docstring)."""

    #: hashable identity of the function (part of the node key)
    key: tuple = ()
    #: the same as deterministic text (cache keys)
    key_text: str = ""
    nargs: int = 1
    #: whether its C calls a library function (``sin``, a helper): the C compiler's level
    #: then matters beyond arithmetic (at -O1, gcc pairs ``sin(x)`` and ``cos(x)`` into one
    #: ``sincos`` call; at -Og it does not)
    calls: bool = True

    def fold(self, values: Sequence[sp.Expr]) -> sp.Expr | None:
        """The exact value on constant arguments, or None when it is not a plain number."""
        return None

    def partial(self, g: Graph, node: int, k: int) -> int:
        """∂f/∂x_k at the arguments of ``node`` (a graph node)."""
        raise NotImplementedError

    def c_expression(self, args: Sequence[str]) -> str:
        raise NotImplementedError

    def numpy_expression(self, args: Sequence[str]) -> str:
        raise NotImplementedError

    def sympy(self, args: Sequence[sp.Expr]) -> sp.Expr:
        raise NotImplementedError

    #: C helper definitions this function needs (name -> source), emitted once per kernel
    def c_helpers(self) -> dict:
        return {}

    #: Python objects the NumPy expression refers to (name -> object)
    def numpy_namespace(self) -> dict:
        return {}

    def __repr__(self) -> str:
        return f"<function {self.key_text}>"


# --- elementary functions -------------------------------------------------------------------

class Elementary(FunctionSpec):
    """A function of ``math.h`` with a SymPy counterpart and derivative rules."""

    def __init__(self, name: str, sympy_func, c_name: str, numpy_name: str,
                 derivatives: Callable[[Graph, tuple], list[int]], nargs: int = 1):
        self.name, self.sympy_func = name, sympy_func
        self.c_name, self.numpy_name = c_name, numpy_name
        self._derivatives = derivatives
        self.nargs = nargs
        self.key = ("elementary", name)
        self.key_text = name

    def fold(self, values):
        value = self.sympy_func(*values)
        return value if value.is_number and not value.has(sp.zoo, sp.nan, sp.oo, -sp.oo) \
            and value.is_real else None

    def partial(self, g, node, k):
        return self._derivatives(g, g.args[node], node)[k]

    def c_expression(self, args):
        return f"{self.c_name}({', '.join(args)})"

    def numpy_expression(self, args):
        name = numpy_name(self.c_name) if self.c_name in LIBM else self.numpy_name
        return f"{name}({', '.join(args)})"

    def numpy_namespace(self):
        """C's function itself where NumPy's may round differently (:mod:`._libm`)."""
        return {numpy_name(self.c_name): LIBM[self.c_name]} if self.c_name in LIBM else {}

    def sympy(self, args):
        return self.sympy_func(*args)


def _one_over(g: Graph, x: int) -> int:
    return g.pow(x, -1)


def _d_atan2(g, a, node):
    y, x = a
    r2 = g.pow(g.add(g.pow(x, 2), g.pow(y, 2)), -1)
    return [g.mul(x, r2), g.neg(g.mul(y, r2))]


def _d_tan(g, a, node):
    return [g.add(g.one, g.pow(node, 2))]


def _d_tanh(g, a, node):
    return [g.sub(g.one, g.pow(node, 2))]


ELEMENTARY: dict = {}


def _register(spec: Elementary) -> None:
    ELEMENTARY[spec.sympy_func] = spec


_register(Elementary("sin", sp.sin, "sin", "np.sin",
                     lambda g, a, n: [g.func(ELEMENTARY[sp.cos], a[0])]))
_register(Elementary("cos", sp.cos, "cos", "np.cos",
                     lambda g, a, n: [g.neg(g.func(ELEMENTARY[sp.sin], a[0]))]))
_register(Elementary("tan", sp.tan, "tan", "np.tan", _d_tan))
_register(Elementary("exp", sp.exp, "exp", "np.exp", lambda g, a, n: [n]))
_register(Elementary("log", sp.log, "log", "np.log", lambda g, a, n: [_one_over(g, a[0])]))
_register(Elementary("asin", sp.asin, "asin", "np.arcsin", lambda g, a, n: [
    g.pow(g.sub(g.one, g.pow(a[0], 2)), sp.Rational(-1, 2))]))
_register(Elementary("acos", sp.acos, "acos", "np.arccos", lambda g, a, n: [
    g.neg(g.pow(g.sub(g.one, g.pow(a[0], 2)), sp.Rational(-1, 2)))]))
_register(Elementary("atan", sp.atan, "atan", "np.arctan", lambda g, a, n: [
    g.pow(g.add(g.one, g.pow(a[0], 2)), -1)]))
_register(Elementary("sinh", sp.sinh, "sinh", "np.sinh",
                     lambda g, a, n: [g.func(ELEMENTARY[sp.cosh], a[0])]))
_register(Elementary("cosh", sp.cosh, "cosh", "np.cosh",
                     lambda g, a, n: [g.func(ELEMENTARY[sp.sinh], a[0])]))
_register(Elementary("tanh", sp.tanh, "tanh", "np.tanh", _d_tanh))
_register(Elementary("atan2", sp.atan2, "atan2", "np.arctan2", _d_atan2, nargs=2))


class _Abs(Elementary):
    calls = False  # fabs: one instruction

    def __init__(self):
        super().__init__("fabs", sp.Abs, "fabs", "np.abs",
                         lambda g, a, n: [g.func(SIGN, a[0])])


class _Sign(Elementary):
    calls = False  # comparisons

    def __init__(self):
        super().__init__("sign", sp.sign, "", "np.sign", lambda g, a, n: [g.zero])

    def c_expression(self, args):
        x = args[0]
        return f"(({x} > 0.0) ? 1.0 : (({x} < 0.0) ? -1.0 : 0.0))"


SIGN = _Sign()
ELEMENTARY[sp.sign] = SIGN
ELEMENTARY[sp.Abs] = _Abs()


# --- smooth special functions (exponential retraction) ------------------------------------------

class Smooth(FunctionSpec):
    """A :class:`~symgroupoid.ir._smooth.SmoothFunction` f(s): Taylor polynomial near
    its singular point, closed form elsewhere; a C helper ``sg_<name>``."""

    def __init__(self, cls):
        self.cls = cls
        self.key = ("smooth", cls.__name__)
        self.key_text = f"smooth:{cls.__name__}"
        self.c_name = f"sg_{cls.__name__}"

    def fold(self, values):
        value = self.cls(*values)
        return value if value.is_number and not isinstance(value, self.cls) else None

    def partial(self, g, node, k):
        from ._smooth import derivative_of

        return g.func(smooth_spec(derivative_of(self.cls)), *g.args[node])

    def c_expression(self, args):
        return f"{self.c_name}({args[0]})"

    def c_helpers(self):
        from ._c import c_of_sympy
        from ._smooth import THRESHOLD

        s = sp.Symbol("s", real=True)
        d = sp.Symbol("d", real=True)
        poly = sp.horner(sp.Add(*[sp.Float(c, 17) * d ** k
                                  for k, c in enumerate(self.cls.taylor())]), d)
        closed = self.cls.closed_form.xreplace({self.cls.closed_form.free_symbols.pop(): s}) \
            if self.cls.closed_form.free_symbols else self.cls.closed_form
        body = (f"static double {self.c_name}(double s)\n{{\n"
                f"    const double d = s - ({c_of_sympy(self.cls.point, {})});\n"
                f"    if (fabs(d) < {THRESHOLD!r}) {{\n"
                f"        return {c_of_sympy(poly, {d: 'd'})};\n    }}\n"
                f"    return {c_of_sympy(closed, {s: 's'})};\n}}\n")
        return {self.c_name: body}

    def numpy_expression(self, args):
        return f"{self.c_name}({args[0]})"

    def numpy_namespace(self):
        return {self.c_name: _numpy_smooth(self.cls)}

    def sympy(self, args):
        return self.cls(*args)


@functools.cache
def smooth_spec(cls) -> Smooth:
    return Smooth(cls)


@functools.cache
def _numpy_smooth(cls):
    """f(s) on arrays: the Taylor polynomial near s₀, the closed form (at a safe point
    substituted near s₀, so no 0/0 is ever evaluated) elsewhere — the same operations as the
    C helper of :class:`Smooth` (its Horner polynomial, its closed form with C's functions),
    so that both give the same bits."""
    import numpy as np

    from ._smooth import THRESHOLD

    coeffs = [float(sp.Float(c, 17)) for c in cls.taylor()][::-1]  # the C helper's literals
    point = float(cls.point)
    away = point + cls.inside * 2 * THRESHOLD
    closed = _closed_form_elementwise(cls, away)

    def f(x):
        x = np.asarray(x, dtype=float)
        d = x - point
        near = np.abs(d) < THRESHOLD
        out = np.empty(x.shape)
        with np.errstate(all="ignore"):
            out[near] = np.polyval(coeffs, d[near])
            out[~near] = closed(x[~near])
        return out if out.ndim else float(out)

    return f


def _closed_form_elementwise(cls, point: float):
    """The closed form of a smooth function on arrays, computed as its C helper computes it.

    The C text of the closed form (:func:`~._c.c_of_sympy`: literals as doubles, C's
    function names, ``pow`` for general powers) is also a Python expression with the same
    operations in the same order — C's arithmetic operators have Python's precedence and
    associativity, both in IEEE double — so it is evaluated element by element with C's own
    functions (:data:`~._libm.SCALAR`).  A closed form whose C text is not such an
    expression (checked at ``point``) falls back to NumPy's functions (same values, possibly
    different last bits)."""
    import numpy as np

    from ._c import c_of_sympy

    s = cls.closed_form.free_symbols.pop()
    text = c_of_sympy(cls.closed_form, {s: "s"})
    try:
        scalar = eval(compile(f"lambda s: {text}", f"<{cls.__name__}>", "eval"),  # noqa: S307
                      {"__builtins__": {}, **SCALAR})
        float(scalar(point))
    except Exception:  # noqa: BLE001 - not Python: NumPy's own forms
        return sp.lambdify([s], cls.closed_form, NUMPY_MODULES)
    ufunc = np.frompyfunc(scalar, 1, 1)
    special = sp.lambdify([s], cls.closed_form, NUMPY_MODULES)

    def ieee(v):
        """An element where Python's float arithmetic raises (x/0, an overflow) gets C's
        IEEE value (±inf, NaN) from NumPy's doubles; the others keep Python's bits."""
        try:
            return scalar(v)
        except (ZeroDivisionError, OverflowError):
            with np.errstate(all="ignore"):
                return float(special(np.float64(v)))

    elementwise = np.frompyfunc(ieee, 1, 1)

    def closed(x):
        try:
            return np.asarray(ufunc(x), dtype=float)
        except (ZeroDivisionError, OverflowError):
            return np.asarray(elementwise(x), dtype=float)

    return closed


# --- anything else SymPy can differentiate and print: opaque functions -------------------------

class Opaque(FunctionSpec):
    """f(x₀, …, x_{n−1}) given as a SymPy expression in placeholder symbols."""

    def __init__(self, expr: sp.Expr, placeholders: tuple):
        self.expr, self.placeholders = expr, placeholders
        self.nargs = len(placeholders)
        self.key = ("opaque", expr, placeholders)
        self.key_text = f"opaque:{sp.srepr(expr)}"

    def fold(self, values):
        value = self.expr.xreplace(dict(zip(self.placeholders, values)))
        return value if value.is_number and value.is_real else None

    def partial(self, g, node, k):
        from ._sympy import from_sympy

        d = sp.diff(self.expr, self.placeholders[k])
        return from_sympy(g, d, dict(zip(self.placeholders, g.args[node])))

    def c_expression(self, args):
        from ._c import c_of_sympy

        return c_of_sympy(self.expr, dict(zip(self.placeholders, args)))

    def numpy_expression(self, args):
        return f"{self._name}({', '.join(args)})"

    @functools.cached_property
    def _name(self) -> str:
        import hashlib

        return "sg_opaque_" + hashlib.sha256(self.key_text.encode()).hexdigest()[:12]

    def numpy_namespace(self):
        """The function, element by element on arrays: SymPy prints functions NumPy lacks
        (``erf``, ``gamma``, …) as the :mod:`math` module's, which take scalars only (and call
        the C library, as the kernels do)."""
        scalar = sp.lambdify(list(self.placeholders), self.expr, NUMPY_MODULES)
        elementwise = np.frompyfunc(scalar, self.nargs, 1)

        def call(*args):
            if all(np.ndim(a) == 0 for a in args):
                return scalar(*args)
            return np.asarray(elementwise(*args), dtype=float)

        return {self._name: call}

    def sympy(self, args):
        return self.expr.xreplace(dict(zip(self.placeholders, args)))


@functools.cache
def placeholders(n: int) -> tuple:
    return tuple(sp.Symbol(f"_x{i}", real=True) for i in range(n))
