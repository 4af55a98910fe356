"""Counts given to any entry point (steps, samples, iterations, seeds): one rule everywhere.

It lives below every layer, so the groupoid checks (layer 1), the runtime (layer 5) and the
command line all read ``steps=1e7``, ``steps=-5`` or ``samples=2.5`` the same way.
"""

from __future__ import annotations

import numbers

import numpy as np

from ._errors import ShapeError

#: the largest count accepted for steps, iterations and similar arguments (C ``long`` safe,
#: and far beyond what fits in memory or time)
MAX_COUNT = 2**53


def integer_argument(value, name: str, *, minimum: int = 0, maximum: int = MAX_COUNT,
                     owner: str = "") -> int:
    """``value`` as an int, or a :class:`ShapeError` naming ``name``.

    Accepted: Python and NumPy integers, and real numbers with an integral value
    (``1e7``, ``np.float64(100.0)``) — one rule everywhere.  Rejected: booleans, NaN,
    infinities, non-integral values, values below ``minimum`` or above ``maximum``, and
    anything that is not a real number.
    """
    where = f"{owner}: " if owner else ""
    if isinstance(value, (bool, np.bool_)):
        raise ShapeError(f"{where}{name} must be an integer, got the boolean {value!r}")
    if isinstance(value, numbers.Integral):
        number = int(value)
    elif isinstance(value, numbers.Real):
        real = float(value)
        if not np.isfinite(real):
            raise ShapeError(f"{where}{name} must be a finite integer, got {value!r}")
        if real != int(real):
            raise ShapeError(f"{where}{name} must be an integer, got {value!r}")
        number = int(real)
    else:
        raise ShapeError(f"{where}{name} must be an integer, got {type(value).__name__} "
                         f"{value!r}")
    if number < minimum:
        raise ShapeError(f"{where}{name} must be at least {minimum}, got {number}")
    if number > maximum:
        raise ShapeError(f"{where}{name} must be at most {maximum}, got {number}")
    return number
