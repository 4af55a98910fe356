"""Smooth special functions for the exponential retraction, safe at and near 0.

The closed forms of exp and log on SO(3), SE(2), SE(3) contain sin θ/θ, (1 − cos θ)/θ²,
θ/(2 sin θ), … — smooth functions of s = θ² (or of cos θ) whose closed forms are 0/0 at the
identity and lose precision close to it, as do all their derivatives.  A
:class:`SmoothFunction` is such a function f(s): symbolically it is differentiable (its
derivative is another SmoothFunction, from the closed form), numerically it evaluates its
Taylor polynomial at the expansion point when |s − s₀| is small and the closed form
otherwise — in SymPy (evalf), in NumPy (lambdify) and in C (a conditional expression).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import sympy as sp

_S = sp.Symbol("s", real=True)

#: |s − s₀| below which the Taylor polynomial is used; its error there is < 1e-17 relative
#: for the functions below (degree 6 in s, |s| < 1e-2 ⇒ remainder ~ s⁷/15! scale)
THRESHOLD = 1e-2
DEGREE = 8


class SmoothFunction(sp.Function):
    """Base class: subclasses are made by :func:`smooth_function`."""

    closed_form: sp.Expr  # in the symbol _S
    point: sp.Expr  # expansion point s₀
    inside: int = 1  # the side of s₀ where the closed form's domain lies
    nargs = 1

    @classmethod
    def eval(cls, arg):
        if arg == cls.point:
            return cls.taylor()[0]
        return None

    #: the function this one is the derivative of (set by :func:`derivative_of`)
    parent: type | None = None
    #: k ↦ the k-th Taylor coefficient at s₀ in closed form, for the functions below whose
    #: series is known (None: computed by SymPy's ``series``)
    coefficient: Callable[[int], sp.Rational] | None = None

    @classmethod
    def taylor(cls) -> tuple:
        """Taylor coefficients at s₀ (exact), degree :data:`DEGREE`."""
        return taylor_coefficients(cls, DEGREE)

    def fdiff(self, argindex=1):
        return derivative_of(type(self))(self.args[0])

    def _eval_evalf(self, prec):
        x = self.args[0].evalf(prec)
        if not x.is_Number:
            return None
        d = x - self.point
        if abs(d) < THRESHOLD:
            return sp.Add(*[c * d ** k for k, c in enumerate(self.taylor())]).evalf(prec)
        return self.closed_form.subs(_S, x).evalf(prec)

    @classmethod
    def precise(cls, s):
        """f(s) at mpmath's working precision, exactly: the closed form away from s₀ (which at
        50 digits loses only the digits |s − s₀| cancels), the exact value at s₀ — not the
        Taylor polynomial, whose error (< 1e-17) is binary64's, not the working precision's."""
        import mpmath

        if s == cls.point:
            return precise_number(cls.taylor()[0], mpmath.mp.dps + 10)
        return _precise_closed_form(cls)(s)

    # --- printing -----------------------------------------------------------------------------
    def _numpycode(self, printer):
        """where(|s − s₀| < T, Taylor(s), closed(s′)) with s′ = s away from s₀ only, so the
        closed form is never evaluated at its 0/0 point."""
        np_ = printer._module_format("numpy")
        arg = printer._print(self.args[0])
        d = f"({arg} - ({printer._print(self.point)}))"
        near = f"{np_}.abs({d}) < {THRESHOLD}"
        poly = " + ".join(f"({printer._print(sp.Float(c, 17))})*{d}**{k}"
                          for k, c in enumerate(self.taylor()))
        x = sp.Dummy("x")
        closed = printer._print(self.closed_form.subs(_S, x))
        away = self.point + self.inside * 2 * THRESHOLD  # a point of the domain, not s₀
        safe = f"{np_}.where({near}, {printer._print(away)}, {arg})"
        closed = f"(lambda {printer._print(x)}: {closed})({safe})"
        return f"{np_}.where({near}, {poly}, {closed})"

    _lambdacode = _numpycode

    def _ccode(self, printer):
        d = printer._print(self.args[0] - self.point)
        closed = printer._print(self.closed_form.subs(_S, self.args[0]))
        return f"((fabs({d}) < {THRESHOLD}) ? ({self._c_poly(printer)}) : ({closed}))"

    def _c_poly(self, printer) -> str:
        x = sp.Symbol("_smooth_arg")
        d = self.args[0] - self.point
        horner = sp.horner(sp.Add(*[sp.Float(c, 17) * x ** k
                                    for k, c in enumerate(self.taylor())]), x)
        return printer._print(horner.subs(x, d))


def precise_number(number, digits: int):
    """An exact SymPy number (√3/6, a function at Floats) as an mpmath number rounded at
    ``digits`` decimal digits."""
    import mpmath

    return mpmath.mpf(sp.Float(sp.N(number, digits), digits)._mpf_)


@functools.cache
def _precise_closed_form(cls: type):
    return sp.lambdify(_S, cls.closed_form, "mpmath")


def precise_namespace(expr) -> dict:
    """The :meth:`SmoothFunction.precise` of every smooth function in ``expr`` by its name:
    a namespace for ``sympy.lambdify(..., [namespace, "mpmath"])``."""
    return {type(f).__name__: type(f).precise for f in expr.atoms(SmoothFunction)}


@functools.cache
def smooth_function(name: str, closed_form: sp.Expr, point=0, inside: int = 1) -> type:
    """A :class:`SmoothFunction` class for ``closed_form`` (an expression in ``_S``)."""
    return type(name, (SmoothFunction,), {"closed_form": closed_form,
                                           "point": sp.sympify(point), "inside": inside})


@functools.cache
def derivative_of(cls: type) -> type:
    """The SmoothFunction class of d/ds of ``cls``."""
    derivative = smooth_function(f"{cls.__name__}_d", sp.diff(cls.closed_form, _S), cls.point,
                                 cls.inside)
    derivative.parent = cls
    return derivative


@functools.cache
def taylor_coefficients(cls: type, degree: int) -> tuple:
    """The Taylor coefficients c₀ … c_degree of ``cls`` at its point s₀ (exact).

    A derivative's are those of its parent's series differentiated term by term,
    c′_k = (k + 1) c_{k+1}; a function with a closed-form :attr:`~SmoothFunction.coefficient`
    uses it; any other is expanded by SymPy's ``series`` (slow: about 0.1–0.4 s each).
    """
    if cls.parent is not None:
        c = taylor_coefficients(cls.parent, degree + 1)
        return tuple((k + 1) * c[k + 1] for k in range(degree + 1))
    if cls.coefficient is not None:
        return tuple(sp.Rational(cls.coefficient(k)) for k in range(degree + 1))
    series = sp.series(cls.closed_form, _S, cls.point, degree + 1).removeO()
    poly = sp.Poly(sp.expand(series.subs(_S, _S + cls.point)), _S)
    return tuple(poly.coeff_monomial(_S ** k) for k in range(degree + 1))


_R = sp.sqrt(_S)
#: sin θ/θ as a function of s = θ²
SinOverTheta = smooth_function("SinOverTheta", sp.sin(_R) / _R)
#: (1 − cos θ)/θ² as a function of s = θ²
OneMinusCosOverTheta2 = smooth_function("OneMinusCosOverTheta2", (1 - sp.cos(_R)) / _S)
#: (θ − sin θ)/θ³ as a function of s = θ²
ThetaMinusSinOverTheta3 = smooth_function("ThetaMinusSinOverTheta3",
                                          (_R - sp.sin(_R)) / (_S * _R))
#: (θ/2)·cot(θ/2) as a function of s = θ²
HalfThetaCotHalfTheta = smooth_function("HalfThetaCotHalfTheta",
                                        _R / 2 * sp.cos(_R / 2) / sp.sin(_R / 2))
#: (1 − (θ/2)cot(θ/2))/θ² as a function of s = θ² (SE(3)'s V⁻¹ coefficient)
SE3LogCoefficient = smooth_function("SE3LogCoefficient",
                                    (1 - _R / 2 * sp.cos(_R / 2) / sp.sin(_R / 2)) / _S)
#: θ/(2 sin θ) as a function of c = cos θ, expanded at c = 1 (the SO(3) logarithm)
ThetaOverTwoSin = smooth_function("ThetaOverTwoSin",
                                  sp.acos(_S) / (2 * sp.sqrt(1 - _S ** 2)), point=1,
                                  inside=-1)


# --- closed-form Taylor coefficients (checked against SymPy's series in the tests) ------------

def _sign(k: int) -> int:
    return -1 if k % 2 else 1


SinOverTheta.coefficient = staticmethod(
    lambda k: sp.Rational(_sign(k), sp.factorial(2 * k + 1)))  # Σ (−s)^k/(2k+1)!
OneMinusCosOverTheta2.coefficient = staticmethod(
    lambda k: sp.Rational(_sign(k), sp.factorial(2 * k + 2)))  # Σ (−s)^k/(2k+2)!
ThetaMinusSinOverTheta3.coefficient = staticmethod(
    lambda k: sp.Rational(_sign(k), sp.factorial(2 * k + 3)))  # Σ (−s)^k/(2k+3)!
#: x cot x = Σ (−1)^k 2^{2k} B_{2k} x^{2k}/(2k)!, at x = θ/2: Σ (−1)^k B_{2k} s^k/(2k)!
HalfThetaCotHalfTheta.coefficient = staticmethod(
    lambda k: _sign(k) * sp.bernoulli(2 * k) / sp.factorial(2 * k))
#: (1 − (θ/2)cot(θ/2))/s = Σ (−1)^k B_{2k+2} s^k/(2k+2)!
SE3LogCoefficient.coefficient = staticmethod(
    lambda k: _sign(k) * sp.bernoulli(2 * k + 2) / sp.factorial(2 * k + 2))


def _theta_over_two_sin(k: int) -> sp.Rational:
    """θ/(2 sin θ) in powers of c − 1 (c = cos θ, u = 1 − c): with x = u/2,
    acos(1 − u) = 2√x Σ a_j x^j, a_j = (2j)!/(4^j (j!)² (2j + 1)), and
    2 sin θ = 2√(2u − u²) = 4√x √(1 − x), so θ/(2 sin θ) = ½ Σ a_j x^j · Σ b_i x^i with
    (1 − x)^{−1/2} = Σ b_i x^i, b_i = (2i)!/(4^i (i!)²); the coefficient of (c − 1)^k is
    (−1)^k 2^{−k} times that of x^k."""
    def central(j: int) -> sp.Rational:
        return sp.Rational(sp.factorial(2 * j), 4 ** j * sp.factorial(j) ** 2)

    x_k = sum(central(j) / (2 * j + 1) * central(k - j) for j in range(k + 1)) / 2
    return _sign(k) * x_k / 2 ** k


ThetaOverTwoSin.coefficient = staticmethod(_theta_over_two_sin)
