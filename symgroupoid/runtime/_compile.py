"""compile_step: a step compiled into a :class:`Simulator`, on its C kernel (built and cached
by :mod:`symgroupoid.runtime.toolchain`) or on the NumPy backend."""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Sequence
from pathlib import Path

from .._arguments import (
    caller_level,
    checked_call,
    choice_argument,
    instance_argument,
    name_argument,
    path_argument,
    sequence_argument,
)
from .._collector import collector_paused
from .._errors import InputTypeError, ShapeError
from .._progress import reported
from ..codegen import KernelSource
from ._backends import NumpyKernel
from ._ckernel import CKernel
from ._options import BACKENDS, NewtonOptions, environment_backend
from ._simulator import Simulator
from .toolchain import (
    STATS,
    CompilerNotFoundError,
    KernelCache,
    VectorISAError,
    absolute_root,
    build_cached,
    load_cached,
    load_step,
    missing_instructions,
    rebuild_step,
    start_openmp_probe,
    step_flags,
    step_kernel,
)


def load_c_kernel(step, flags: Sequence[str] | None = None,
                  cache_dir: str | os.PathLike | None = None, *,
                  source: KernelSource | None = None,
                  block_units: bool | None = None) -> tuple[CKernel, Path]:
    """The compiled kernel of ``step`` from the cache, building it on a miss (from
    ``source``, the step's :func:`step_kernel` when already generated).

    ``block_units`` (default: whether ``flags`` is None, the library's default flags): the
    kernel's straight-line arithmetic in block units, compiled at a cheaper level
    (:func:`~.toolchain.unit_flags`); without, every unit but the cold one is compiled at
    ``flags``.  Raises :class:`CompilerNotFoundError` when a build is needed and no
    compiler exists, :class:`CompilationError` when the compiler fails (the cache is left
    unchanged), :class:`CacheError` when the cache cannot serve the kernel (see
    :mod:`.toolchain`).
    """
    if block_units is None:
        block_units = flags is None
    flags = tuple(step_flags(step, cache_dir) if flags is None else flags)
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    module, manifest, source_key = load_step(step, flags, cache, source=source,
                                             block_units=block_units)
    try:
        kernel = CKernel(module, manifest["prefix"], len(step.unknowns), len(step.knowns))
    except (ShapeError, AttributeError):  # the index named a kernel of another step
        module, manifest, source_key = rebuild_step(step, flags, cache, source=source,
                                                    block_units=block_units)
        kernel = CKernel(module, manifest["prefix"], len(step.unknowns), len(step.knowns))
    entry = cache.entry(source_key)
    kernel.source_key, kernel.flags, kernel.block_units = source_key, flags, block_units
    return kernel, entry


#: a flag that defines or undefines _OPENMP, which the compiler sets with -fopenmp alone
_OPENMP_MACRO = re.compile(r"-[DU]\s*_OPENMP(=.*)?", re.S)


def compiler_flags(flags, owner: str = "") -> tuple[str, ...] | None:
    """``flags`` as a tuple of compiler arguments, or None (the step's
    :func:`default_flags`, chosen when it is built): a list of strings without NUL
    characters.  A single string is refused: it would be taken letter by letter (``"-O2"``
    as ``"-"``, ``"O"``, ``"2"``); pass ``["-O2"]``.  So are flags that ask for an
    instruction set this processor lacks (``-mavx512f`` on a processor without AVX-512:
    :class:`~.toolchain.VectorISAError`)."""
    if flags is None:
        return None
    if isinstance(flags, str):
        raise InputTypeError(f"{owner}: flags must be a list of compiler arguments, got the "
                             f"string {flags!r}; pass [{flags!r}]")
    items = sequence_argument(flags, "flags", owner=owner)
    flags = tuple(name_argument(f, f"flags[{i}]", owner=owner) for i, f in enumerate(items))
    defined = next((f for f in flags if _OPENMP_MACRO.fullmatch(f)), None)
    if defined is not None:
        raise ShapeError(f"{owner}: flags: {defined!r} sets OpenMP's own macro without its "
                         f"runtime, so the kernel could not be loaded; pass '-fopenmp' to "
                         f"build with OpenMP (batches share their runs among threads), or "
                         f"leave it out")
    missing = missing_instructions(flags)
    if missing:
        raise VectorISAError(f"{owner}: flags ask for {', '.join(missing)}, whose instructions "
                             f"this processor does not have; the kernel would stop at the "
                             f"first of them")
    return flags


def load_kernel_source(kernel: KernelSource, flags: Sequence[str], label: str,
                       n_unknowns: int, n_knowns: int,
                       cache_dir: str | os.PathLike | None = None) -> tuple[CKernel, Path]:
    """The compiled kernel of generated C ``kernel``: loaded from the cache by its source
    key (a hash of the C, the flags and the ABI), built there on a miss (see
    :func:`build_cached`).  What a process that never saw the step needs to run it."""
    flags = tuple(flags)
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    source_key, manifest = build_cached(kernel, flags, cache, label)
    module = load_cached(source_key, manifest, cache)
    loaded = CKernel(module, manifest["prefix"], n_unknowns, n_knowns)
    loaded.source_key, loaded.flags = source_key, flags
    loaded.block_units = bool(kernel.blocks)
    return loaded, cache.entry(source_key)


@reported(lambda step, **options: f"{step.name}: building the kernel")
@collector_paused
@checked_call
def compile_step(step, *, backend: str = "auto", flags: Sequence[str] | None = None,
                 cache_dir: str | os.PathLike | None = None, tol_residual: float | None = None,
                 tol_step: float | None = None, max_iterations: int | None = None,
                 floor_factor: float | None = None, trust_factor: float | None = None,
                 extrapolate: bool | None = None) -> Simulator:
    """A :class:`Simulator` for ``step``: its C kernel (cffi, cached) or the NumPy backend.

    Every argument is checked before anything is built, whichever backend is used
    (:class:`~symgroupoid.DomainError` for a backend that is not one of ``BACKENDS``,
    :class:`~symgroupoid.InputTypeError` or :class:`~symgroupoid.ShapeError` for malformed
    flags or paths).

    Parameters
    ----------
    backend : ``"auto"`` (C if a compiler is available, else NumPy with a warning), ``"c"``
        or ``"numpy"``.  The environment variable ``SYMGROUPOID_BACKEND`` overrides
        ``"auto"``.
    flags : compiler flags, a list of strings (default :func:`default_flags`:
        ``DEFAULT_FLAGS``, at -O2 above ``LARGE_PROGRAM`` operations and at -O1 up to
        ``SMALL_STEP``, which compile in half to three quarters of the time and step at
        most 13 % slower, above it without SLP vectorisation (``LARGE_STEP_FLAGS``), plus
        ``-fopenmp`` when the compiler supports it; the straight-line
        functions of a kernel that calls no library function at -Og,
        ``runtime.toolchain.BLOCK_LEVEL``); part of the cache key.  Explicit ``flags`` apply to
        every unit but the cold one.  Builds carry no debug information unless ``flags``
        ask for it (``-g``).  On x86-64 with GCC or Clang every unit is also compiled for
        the processor's widest vector extension (``runtime.toolchain.vector_flags``: the
        same bits, faster; ``SYMGROUPOID_VECTOR_ISA`` overrides it), unless ``flags`` choose
        a target themselves (``-march=…``, ``-mavx…``).
    cache_dir : cache root, a path (default ``$SYMGROUPOID_CACHE``,
        ``$XDG_CACHE_HOME/symgroupoid`` or ``~/.cache/symgroupoid``); a relative path is
        taken relative to the working directory of this call.  If it cannot be written,
        kernels are built in a private temporary directory for this process (with a
        ``RuntimeWarning``).
    tol_residual, tol_step, max_iterations, floor_factor, trust_factor, extrapolate : Newton
        options (see :class:`NewtonOptions`).
    progress : report code generation and compilation taking longer than 2 s (see
        :mod:`symgroupoid._progress`; a cached kernel loads in milliseconds).
    """
    from ..equations import StepEquations

    instance_argument(step, StepEquations, "step", "the StepEquations of a system (from "
                      "system.euler_lagrange())", owner="compile_step")
    owner = step.name
    backend = choice_argument(backend, BACKENDS, "backend", owner=owner)
    if backend == "auto":
        backend = environment_backend(owner)
    flags = compiler_flags(flags, owner)
    if cache_dir is not None:  # resolved now: a later chdir cannot move the cache
        cache_dir = absolute_root(path_argument(cache_dir, "cache_dir", owner=owner))
    given = {"tol_residual": tol_residual, "tol_step": tol_step,
             "max_iterations": max_iterations, "floor_factor": floor_factor,
             "trust_factor": trust_factor, "extrapolate": extrapolate}
    options = NewtonOptions(**{k: v for k, v in given.items() if v is not None})
    if backend == "numpy":
        return Simulator(step, NumpyKernel(step), options)
    try:
        source = None
        if flags is None and start_openmp_probe(cache_dir):
            # a first build here (the compiler's OpenMP support is not known yet): the C is
            # generated while the probe runs, instead of after it
            source = step_kernel(step, KernelCache(
                Path(cache_dir) if cache_dir is not None else None))
            STATS["codegen"] += 1
        chosen = step_flags(step, cache_dir) if flags is None else flags
        kernel, entry = load_c_kernel(step, chosen, cache_dir, source=source,
                                      block_units=flags is None)
    except CompilerNotFoundError as exc:
        if backend == "c":
            raise
        warnings.warn(f"{step.name}: {exc}; using the NumPy backend (same results, slower)",
                      RuntimeWarning, stacklevel=caller_level())  # (the user's line)
        return Simulator(step, NumpyKernel(step), options)
    return Simulator(step, kernel, options, cache_entry=entry)
