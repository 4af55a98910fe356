"""NumPy functions from SymPy expressions: the ``modules`` argument of :func:`sympy.lambdify`.

The module object gives lambdify the same printer as the string ``"numpy"`` (NumPyPrinter,
fully qualified ``numpy.*`` names) without the string's ``from numpy import *``, which imports
``numpy.f2py``, ``numpy.testing`` and ``numpy.ma`` — 0.13 s once per process, a third of
building a small system's kernel.
"""

from __future__ import annotations

import numpy as np

#: ``sympy.lambdify(args, exprs, NUMPY_MODULES)``; the name ``numpy`` itself is bound too, for
#: printers of the library's own functions that write ``numpy.…`` (ir/_smooth.py)
NUMPY_MODULES = [{"numpy": np}, np]
