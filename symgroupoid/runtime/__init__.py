"""Layer 5: compiled (cffi) or NumPy kernels, simulation and trajectories.

The trajectory files (:mod:`._files`: ``read_trajectory``, ``save_trajectory``, ...) load on
first use, so that ``import symgroupoid`` does not import what only writing and reading files
needs (csv, zipfile, tempfile).
"""

from .._errors import CacheError
from ._backends import c_buffer, real_vector
from ._batch import TrajectoryBatch
from ._bvp import BoundaryValueSolution, interpolate_arrows, solve_boundary_value
from ._compile import compile_step
from ._diagnostics import (
    ConservationSummary,
    Drift,
    Momenta,
    conservation_summary,
    constraint_residuals,
    energy,
    energy_changes,
    energy_drift,
    energy_label,
    energy_magnitude,
    has_energy,
    momenta,
    noether_drifts,
    noether_quantities,
    rounding_floor,
    trajectory_programs,
)
from ._executors import ClusterLostError
from ._options import NewtonOptions
from ._pickle import DetachedStepError, NotPortableError
from ._programs import ProgramEvaluator, compile_program, wait_for_kernels
from ._projection import ProjectionError
from ._simulator import Simulator
from ._sweep import sweep
from ._sweep_boundary import sweep_boundary_value
from ._sweep_result import SweepResult
from ._sweep_tasks import ReduceError
from ._trajectory import Trajectory
from ._validate import constraint_check, parameter_vector, system_argument
from .toolchain import CompilationError, CompilerNotFoundError, VectorISAError, cache_root

#: names of :mod:`._files`, imported when first asked for (:func:`__getattr__`)
_FILE_NAMES = frozenset({"TRAJECTORY_FORMATS", "atomic_write", "number_text", "output_problem",
                         "read_trajectory", "save_trajectory", "claimed_bytes",
                         "check_claimed_size"})

__all__ = ["TRAJECTORY_FORMATS", "BoundaryValueSolution", "CacheError", "ClusterLostError",
           "CompilationError",
           "CompilerNotFoundError", "ConservationSummary", "DetachedStepError", "Drift", "Momenta",
           "VectorISAError",
           "NewtonOptions", "NotPortableError", "ProgramEvaluator", "ProjectionError",
           "ReduceError", "Simulator", "SweepResult", "Trajectory", "TrajectoryBatch",
           "atomic_write", "cache_root", "check_claimed_size", "claimed_bytes",
           "compile_program", "compile_step", "conservation_summary",
           "constraint_check", "constraint_residuals", "energy", "energy_changes",
           "energy_drift", "energy_label", "energy_magnitude",
           "has_energy",
           "momenta", "noether_drifts", "noether_quantities", "number_text",
           "output_problem", "parameter_vector",
           "read_trajectory",
           "rounding_floor", "save_trajectory", "solve_boundary_value", "sweep",
           "sweep_boundary_value", "system_argument", "trajectory_programs", "wait_for_kernels",
           # the checks of every buffer handed to C (for code that calls a kernel's C itself)
           "c_buffer", "real_vector",
           # the default initial path of a boundary-value solve (to start a guess from)
           "interpolate_arrows"]


def __getattr__(name: str):
    """The trajectory-file names, imported on first use (PEP 562)."""
    if name in _FILE_NAMES:
        from . import _files

        return getattr(_files, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
