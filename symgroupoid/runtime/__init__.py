"""Layer 5: compiled (cffi) or NumPy kernels, simulation and trajectories."""

from .._errors import CacheError
from ._backends import NewtonOptions
from ._build import CompilationError, CompilerNotFoundError
from ._cache import cache_root
from ._compile import compile_step
from ._simulator import Simulator
from ._trajectory import Trajectory

__all__ = ["CacheError", "CompilationError", "CompilerNotFoundError", "NewtonOptions",
           "Simulator", "Trajectory", "cache_root", "compile_step"]
