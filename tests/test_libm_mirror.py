"""The NumPy form of a program computes the compiled program's bits (symgroupoid/ir/_libm.py).

A boundary-value solve may evaluate its window program in NumPy first and in C once the
kernel is built, so both must agree exactly — for every elementary function, general powers
and the smooth functions of the exponential retraction (both branches: Taylor polynomial and
closed form), and their derivatives.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from symgroupoid.ir import (
    LIBM,
    SCALAR,
    SMOOTH_ARGUMENT,
    Graph,
    HalfThetaCotHalfTheta,
    OneMinusCosOverTheta2,
    Program,
    SE3LogCoefficient,
    SinOverTheta,
    ThetaMinusSinOverTheta3,
    ThetaOverTwoSin,
    derivative_of,
    from_sympy,
    smooth_function,
    taylor_coefficients,
)
from symgroupoid.runtime import compile_program

x, y = sp.symbols("x y", real=True)
r = sp.sqrt(x ** 2 + y ** 2 + 1)  # > 1
u = x / r  # in (-1, 1)

ELEMENTARY = [sp.sin(x), sp.cos(x), sp.tan(x), sp.exp(x), sp.log(r), sp.asin(u), sp.acos(u),
              sp.atan(x), sp.sinh(x), sp.cosh(x), sp.tanh(x), sp.atan2(y, x),
              r ** sp.Rational(3, 2), x ** 7, r ** -sp.Rational(5, 3), sp.exp(sp.sin(x) * y) / r]

SMOOTH = [SinOverTheta, OneMinusCosOverTheta2, ThetaMinusSinOverTheta3, HalfThetaCotHalfTheta,
          SE3LogCoefficient]


def _smooth_expressions() -> list[sp.Expr]:
    out = []
    for cls in SMOOTH:
        d1 = derivative_of(cls)
        for f in (cls, d1, derivative_of(d1)):
            out += [f(x ** 2 * sp.Rational(1, 50)), f(y ** 2 * 3)]  # near and far from 0
    c = u * sp.Rational(1, 2) + sp.Rational(1, 2)  # cos θ in (0, 1), near 1 for large x
    out += [ThetaOverTwoSin(c), derivative_of(ThetaOverTwoSin)(c)]
    return out


def _program(exprs: list[sp.Expr]) -> Program:
    g = Graph()
    nodes = {s: g.input(s) for s in (x, y)}
    memo: dict = {}
    return Program(g, {"a": [x, y]}, {"out": [from_sympy(g, e, nodes, memo=memo)
                                               for e in exprs]})


def _points() -> np.ndarray:
    rng = np.random.default_rng(7)
    wide = rng.uniform(-4, 4, (400, 2))
    small = rng.uniform(-0.3, 0.3, (400, 2))  # the smooth functions' Taylor branch
    tiny = rng.uniform(-1e-4, 1e-4, (100, 2))
    return np.vstack([wide, small, tiny])


@pytest.mark.parametrize("kind", ["elementary", "smooth"])
def test_numpy_form_equals_compiled_bits(kind):
    exprs = ELEMENTARY if kind == "elementary" else _smooth_expressions()
    program = _program(exprs)
    compiled = compile_program(f"libm_mirror_{kind}", program, "a", "out")
    if compiled is None:
        pytest.skip("no C compiler")
    values = _points()
    c = compiled(values)
    numpy = program.numpy_function(["out"], ["a"])(values.T)[0].T
    assert np.isfinite(c).all()
    mismatched = np.argwhere(c.view(np.int64) != numpy.view(np.int64))
    assert not len(mismatched), [(exprs[j], values[i], c[i, j], numpy[i, j])
                                 for i, j in mismatched[:5]]


def test_special_values_are_those_of_c():
    """Where ``math`` raises, C (and so the mirror) returns IEEE special values."""
    with np.errstate(all="ignore"):
        assert LIBM["log"](np.array([0.0]))[0] == -np.inf
        assert np.isnan(LIBM["log"](np.array([-1.0]))[0])
        assert LIBM["exp"](np.array([1000.0]))[0] == np.inf
        assert np.isnan(LIBM["acos"](np.array([2.0]))[0])
        assert np.isnan(LIBM["sin"](np.array([np.inf]))[0])
        assert LIBM["pow"](np.array([0.0]), np.array([-1.0]))[0] == np.inf
    assert SCALAR["exp"](1000.0) == np.inf
    assert LIBM["exp"](0.5) == SCALAR["exp"](0.5)  # scalars stay scalars


def test_libm_agrees_with_numpy_to_rounding():
    """The mirror's functions are the usual ones (to a few ulps)."""
    z = np.linspace(-3, 3, 101)
    for name, ref in [("sin", np.sin), ("exp", np.exp), ("atan", np.arctan),
                      ("tanh", np.tanh)]:
        np.testing.assert_allclose(LIBM[name](z), ref(z), rtol=4e-16, atol=0)
    np.testing.assert_allclose(LIBM["atan2"](z, z[::-1] + 0.1), np.arctan2(z, z[::-1] + 0.1),
                               rtol=4e-16, atol=0)


# --- the closed-form Taylor coefficients of the smooth functions (ir/_smooth.py) ----------------
# Each built-in smooth function carries its series in closed form (factorials, Bernoulli
# numbers, central binomial coefficients), and a derivative's series is its parent's
# differentiated term by term.  Both must be exactly what SymPy's ``series`` expands.

BUILT_IN = [SinOverTheta, OneMinusCosOverTheta2, ThetaMinusSinOverTheta3, HalfThetaCotHalfTheta,
            SE3LogCoefficient, ThetaOverTwoSin]
#: the degree of the Taylor polynomials the smooth functions evaluate near their point
DEGREE = len(SinOverTheta.taylor()) - 1


def _series(closed: sp.Expr, point, degree: int) -> tuple:
    s = SMOOTH_ARGUMENT
    series = sp.series(closed, s, point, degree + 1).removeO()
    poly = sp.Poly(sp.expand(series.subs(s, s + point)), s)
    return tuple(poly.coeff_monomial(s ** k) for k in range(degree + 1))


@pytest.mark.parametrize("cls", BUILT_IN, ids=lambda c: c.__name__)
def test_closed_form_coefficients_are_the_series(cls):
    assert cls.coefficient is not None
    assert taylor_coefficients(cls, DEGREE + 2) == \
        _series(cls.closed_form, cls.point, DEGREE + 2)


@pytest.mark.parametrize("cls", [SinOverTheta,
                                 pytest.param(ThetaOverTwoSin, marks=pytest.mark.slow)],
                         ids=lambda c: c.__name__)
def test_derivative_series_is_the_series_of_the_derivative(cls):
    second = derivative_of(derivative_of(cls))
    assert second.parent is derivative_of(cls)
    assert second.taylor() == _series(second.closed_form, cls.point, DEGREE)


def test_a_function_without_closed_form_coefficients_is_expanded_by_sympy():
    s = SMOOTH_ARGUMENT
    cls = smooth_function("ExpMinusOneOverS", (sp.exp(s) - 1) / s)
    assert cls.coefficient is None and cls.parent is None
    assert cls.taylor() == tuple(sp.Rational(1, sp.factorial(k + 1))
                                 for k in range(DEGREE + 1))
