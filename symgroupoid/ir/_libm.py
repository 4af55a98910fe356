"""The C library's elementary functions on NumPy arrays: the NumPy forms of the C kernels' calls.

A compiled kernel calls ``sin``, ``exp``, ``pow``, … of the platform's C maths library.
NumPy's own implementations of most of them (SIMD, chosen per processor) round differently
in the last bit: on an AVX-512 machine ``np.exp`` differs from the C library's ``exp`` on
about 5 % of arguments, ``np.arccos`` on 9 %.  The NumPy backend must compute what the C
kernels compute, bit for bit (a boundary-value solve may start with the NumPy form of its
window program and continue with the compiled one), so its elementary functions call the C
library too, element by element, through :mod:`math` (whose functions call it directly).

:mod:`math` raises where C returns an IEEE special value (``log(0)``, ``exp(1000)``,
``acos(2)``, ``sin(inf)``); those elements are computed by NumPy instead, which returns the
same special values (±inf, NaN) without raising.

Square roots and absolute values are exact in both (IEEE), so they stay NumPy's.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

#: names of the C library's functions → (the math module's function, NumPy's function)
_FUNCTIONS: dict[str, tuple[Callable, Callable]] = {
    "sin": (math.sin, np.sin), "cos": (math.cos, np.cos), "tan": (math.tan, np.tan),
    "exp": (math.exp, np.exp), "log": (math.log, np.log),
    "asin": (math.asin, np.arcsin), "acos": (math.acos, np.arccos),
    "atan": (math.atan, np.arctan), "sinh": (math.sinh, np.sinh),
    "cosh": (math.cosh, np.cosh), "tanh": (math.tanh, np.tanh),
    "atan2": (math.atan2, np.arctan2), "pow": (math.pow, np.power),
    "cbrt": (math.cbrt, np.cbrt),
}


def _scalar(exact: Callable, special: Callable) -> Callable:
    def f(*args: float) -> float:
        try:
            return exact(*args)
        except (ValueError, OverflowError):  # C returns an IEEE special value here
            with np.errstate(all="ignore"):
                return float(special(*args))

    return f


def _elementwise(name: str) -> Callable:
    exact, special = _FUNCTIONS[name]
    scalar = _scalar(exact, special)
    nargs = 2 if name in ("atan2", "pow") else 1
    ufunc = np.frompyfunc(scalar, nargs, 1)

    def call(*args):
        if all(np.ndim(a) == 0 for a in args):
            return scalar(*(float(a) for a in args))
        out = ufunc(*(np.asarray(a, dtype=float) for a in args))
        return np.asarray(out, dtype=float)

    call.__name__ = f"libm_{name}"
    call.__doc__ = f"C's {name} on every element (see symgroupoid.ir._libm)."
    return call


#: name → elementwise function of arrays (or floats), e.g. ``LIBM["exp"](x)``
LIBM: dict[str, Callable] = {name: _elementwise(name) for name in _FUNCTIONS}

#: the names a C expression of the kernels may use, as functions of floats (C's own
#: functions; square root and absolute value are exact in both languages)
SCALAR: dict[str, object] = {**{name: _scalar(*pair) for name, pair in _FUNCTIONS.items()},
                             "sqrt": _scalar(math.sqrt, np.sqrt), "fabs": math.fabs,
                             "M_PI": math.pi, "M_E": math.e}


def numpy_name(c_name: str) -> str:
    """The name under which generated NumPy code calls C's ``c_name`` (see :data:`LIBM`)."""
    return f"_libm_{c_name}"


def namespace() -> dict:
    """Every :func:`numpy_name` bound to its function (for generated NumPy code)."""
    return {numpy_name(name): f for name, f in LIBM.items()}


__all__ = ["LIBM", "SCALAR", "namespace", "numpy_name"]
