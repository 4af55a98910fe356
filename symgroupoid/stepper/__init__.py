"""The Newton stepper of a step kernel: its C library and the NumPy twin beside it.

The C sources in this directory (``stepper.h``, ``stepper.c``, ``batch.c``, ...) are the
fixed part of every generated kernel — LU with row scaling and partial pivoting (in panels
of columns for large kernels, the same bits), the rounding
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
    LU_PANEL_FROM,
    MAX_THREADS,
    TRUST_FLOOR,
    BandOrder,
    LUFactors,
    NumpyStepper,
    NumpyWarmStart,
    StepFunctions,
    above_rounding,
    band_factor,
    coordinate_floor,
    explained_by_rounding,
    hold_time,
    lu_apply,
    lu_factor,
    lu_solve,
    norm_inf,
    pivot_ratio,
    relative_norm,
    time_step_kept,
)
from ._status import STATUS_MESSAGES, Status, c_defines, c_status_message
from ._time import HOLD_ITERATIONS, HOLD_TOLERANCE, NO_TIME, STEP_RATIO, TimeLayout

__all__ = ["BandOrder", "C_INT_MAX", "DEFAULT_OPTIONS", "EPSILON", "HOLD_ITERATIONS",
           "HOLD_TOLERANCE", "Inliner", "LU_PANEL_FROM", "LUFactors", "MAX_THREADS", "NO_TIME",
           "NumpyStepper", "NumpyWarmStart", "SOURCES", "STATUS_MESSAGES", "STEP_RATIO", "Status",
           "StepFunctions", "TRUST_FLOOR", "TimeLayout", "above_rounding", "band_factor",
           "c_defines", "c_status_message", "coordinate_floor", "explained_by_rounding",
           "hold_time", "library_digest", "library_dir", "library_source", "lu_apply", "lu_factor",
           "lu_solve", "norm_inf", "pivot_ratio", "relative_norm", "spelt", "time_step_kept"]
