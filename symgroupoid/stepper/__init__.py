"""The Newton stepper of a step kernel: its C library and the NumPy twin beside it.

The C sources in this directory (``stepper.h``, ``stepper.c``, ``batch.c``, ...) are the
fixed part of every generated kernel — LU with row scaling and partial pivoting, the rounding
floors, Newton with chord updates and polishing, the warm start, the trust region,
``simulate`` and the batched entry points — behind a name-prefix macro (``sg_prefix.h``),
compilable and testable on their own; the code generator writes them into each kernel with
its prefix (:class:`Inliner`).  :mod:`._numpy` is the same library in NumPy, operation for
operation (the same bits), and :class:`Status` the one enum of the statuses every run
reports.  Depends on nothing of the package but its errors.
"""

from ._library import SOURCES, Inliner, library_digest, library_dir, library_source, spelt
from ._numpy import (
    C_INT_MAX,
    DEFAULT_OPTIONS,
    EPSILON,
    MAX_THREADS,
    TRUST_FLOOR,
    LUFactors,
    NumpyStepper,
    NumpyWarmStart,
    StepFunctions,
    above_rounding,
    coordinate_floor,
    explained_by_rounding,
    lu_apply,
    lu_factor,
    lu_solve,
    norm_inf,
    pivot_ratio,
    relative_norm,
)
from ._status import STATUS_MESSAGES, Status, c_defines, c_status_message

__all__ = ["C_INT_MAX", "DEFAULT_OPTIONS", "EPSILON", "Inliner", "LUFactors", "MAX_THREADS",
           "NumpyStepper", "NumpyWarmStart", "SOURCES", "STATUS_MESSAGES", "Status",
           "StepFunctions", "TRUST_FLOOR", "above_rounding", "c_defines", "c_status_message",
           "coordinate_floor", "explained_by_rounding", "library_digest", "library_dir",
           "library_source", "lu_apply", "lu_factor", "lu_solve", "norm_inf", "pivot_ratio",
           "relative_norm", "spelt"]
