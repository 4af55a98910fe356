"""Closed-form Taylor coefficients of the retraction's smooth functions (ir/_smooth.py).

Each built-in smooth function carries its series in closed form (factorials, Bernoulli
numbers, central binomial coefficients), and a derivative's series is its parent's
differentiated term by term.  Both must be exactly what SymPy's ``series`` expands.
"""

from __future__ import annotations

import pytest
import sympy as sp

# the Taylor coefficients and derivatives of the smooth functions are the subject
from symgroupoid.ir import _smooth

BUILT_IN = [_smooth.SinOverTheta, _smooth.OneMinusCosOverTheta2,
            _smooth.ThetaMinusSinOverTheta3, _smooth.HalfThetaCotHalfTheta,
            _smooth.SE3LogCoefficient, _smooth.ThetaOverTwoSin]


def _series(closed: sp.Expr, point, degree: int) -> tuple:
    s = _smooth._S
    series = sp.series(closed, s, point, degree + 1).removeO()
    poly = sp.Poly(sp.expand(series.subs(s, s + point)), s)
    return tuple(poly.coeff_monomial(s ** k) for k in range(degree + 1))


@pytest.mark.parametrize("cls", BUILT_IN, ids=lambda c: c.__name__)
def test_closed_form_coefficients_are_the_series(cls):
    assert cls.coefficient is not None
    assert _smooth.taylor_coefficients(cls, _smooth.DEGREE + 2) == \
        _series(cls.closed_form, cls.point, _smooth.DEGREE + 2)


@pytest.mark.parametrize("cls", [_smooth.SinOverTheta, _smooth.ThetaOverTwoSin],
                         ids=lambda c: c.__name__)
def test_derivative_series_is_the_series_of_the_derivative(cls):
    second = _smooth.derivative_of(_smooth.derivative_of(cls))
    assert second.parent is _smooth.derivative_of(cls)
    assert second.taylor() == _series(second.closed_form, cls.point, _smooth.DEGREE)


def test_a_function_without_closed_form_coefficients_is_expanded_by_sympy():
    s = _smooth._S
    cls = _smooth.smooth_function("ExpMinusOneOverS", (sp.exp(s) - 1) / s)
    assert cls.coefficient is None and cls.parent is None
    assert cls.taylor() == tuple(sp.Rational(1, sp.factorial(k + 1))
                                 for k in range(_smooth.DEGREE + 1))
