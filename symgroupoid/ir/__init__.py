"""The expression graph every kernel goes through.

SymPy expressions from the user (Lagrangians, constraints, structure maps) are captured as a
hash-consed DAG (:class:`Graph`) right away; the junction variation and the step Jacobian are
computed on it by algorithmic differentiation (:func:`gradient`, :func:`forward`,
:func:`jacobian`), and kernels are :class:`Program` objects — named inputs and outputs over
the graph — evaluated with NumPy or printed to C.  Exact SymPy expressions are rebuilt from
the graph only on demand (:func:`to_sympy`).
"""

from ._ad import forward, gradient, jacobian, partial
from ._c import KernelCPrinter, UnmappedSymbolError, c_of_sympy, print_c
from ._compact import compact
from ._domain import domain_kind, domain_nodes
from ._format import C, functions_used, plan, write
from ._functions import ELEMENTARY, FunctionSpec, Opaque, Smooth, smooth_spec
from ._graph import ADD, CONST, FUNC, INPUT, MUL, OP_NAMES, POW, Graph
from ._libm import LIBM, SCALAR
from ._precise import interpret_precise
from ._program import TERMS_CAP, Program, interpret, power_terms, product_terms
from ._rounding import rounding_error, term_magnitude
from ._smooth import _S as SMOOTH_ARGUMENT  # s, of the closed forms smooth_function takes
from ._smooth import (
    HalfThetaCotHalfTheta,
    OneMinusCosOverTheta2,
    SE3LogCoefficient,
    SinOverTheta,
    SmoothFunction,
    ThetaMinusSinOverTheta3,
    ThetaOverTwoSin,
    derivative_of,
    precise_namespace,
    precise_number,
    smooth_function,
    taylor_coefficients,
)
from ._sympy import Context, from_sympy, to_sympy

__all__ = [
    "ADD", "CONST", "ELEMENTARY", "FUNC", "INPUT", "MUL", "OP_NAMES", "POW", "FunctionSpec",
    "Graph", "KernelCPrinter", "Opaque", "Program", "Smooth", "UnmappedSymbolError",
    "Context", "c_of_sympy", "compact", "domain_kind", "domain_nodes", "forward",
    "from_sympy", "gradient", "interpret",
    "interpret_precise", "jacobian", "partial", "print_c", "rounding_error", "smooth_spec",
    "term_magnitude", "to_sympy",
    # bounds on the terms of expanded formulas (the printers' and Program.expanded_terms)
    "TERMS_CAP", "power_terms", "product_terms",
    # straight-line code of a graph: the C dialect, the plan of its nodes, the writer
    "C", "functions_used", "plan", "write",
    # smooth functions of θ² (or cos θ) with their Taylor series near the removable point
    "HalfThetaCotHalfTheta", "OneMinusCosOverTheta2", "SE3LogCoefficient", "SinOverTheta",
    "SmoothFunction", "ThetaMinusSinOverTheta3", "ThetaOverTwoSin", "smooth_function",
    "SMOOTH_ARGUMENT", "derivative_of", "precise_namespace", "precise_number",
    "taylor_coefficients",
    # the C library's functions on NumPy arrays (LIBM) and on floats (SCALAR): the same bits
    "LIBM", "SCALAR",
]
