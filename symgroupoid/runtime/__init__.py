"""Layer 5: compiled (cffi) or NumPy kernels, simulation and trajectories."""

from .._errors import CacheError
from ._batch import TrajectoryBatch
from ._compile import compile_step
from ._options import NewtonOptions
from ._pickle import DetachedStepError, NotPortableError
from ._simulator import Simulator
from ._sweep import sweep
from ._sweep_boundary import sweep_boundary_value
from ._sweep_result import SweepResult
from ._sweep_tasks import ReduceError
from ._trajectory import Trajectory
from .toolchain import CompilationError, CompilerNotFoundError, cache_root

__all__ = ["CacheError", "CompilationError", "CompilerNotFoundError", "DetachedStepError",
           "NewtonOptions", "NotPortableError", "ReduceError", "Simulator", "SweepResult",
           "Trajectory", "TrajectoryBatch", "cache_root", "compile_step", "sweep",
           "sweep_boundary_value"]
