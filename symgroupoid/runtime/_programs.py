"""Batched programs compiled to C through the kernel build cache.

The boundary-value solver evaluates, for every window of a trajectory, a program over the
expression graph (the window residual, its slot derivatives and its rounding bound).
:func:`compile_program` prints it to C (``codegen.generate_program_c``: one function applied
to W items in a loop), builds it with cffi through the same cache as the step kernels (keyed
by a hash of the source and flags, built in a temporary directory, verified on load) and
returns a function of a (W, n_in) array.  Without a compiler it returns None and the caller
evaluates the program with NumPy.

:class:`ProgramEvaluator` never waits for the compiler: a program whose kernel is not in the
cache is evaluated with its NumPy form while the kernel is built in a background thread,
and with the kernel from the first call after it is loaded.  The NumPy form computes the
same bits as the kernel (the same operations in the same order, and the C library's own
elementary functions: :mod:`symgroupoid.ir._libm`), so which of the two evaluated a call
never shows in a result.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable

import numpy as np

from .._arguments import caller_level
from .._errors import ShapeError
from ..codegen import generate_program_c
from ..stepper import C_INT_MAX
from ._backends import c_buffer
from ._options import environment_backend
from .toolchain import (
    CompilationError,
    CompilerNotFoundError,
    KernelCache,
    build_cached,
    load_cached,
    optimisation_flags,
    source_key_of,
)

#: rows (windows) per NumPy evaluation: the NumPy form holds one array per named node of the
#: program at once (the rigid body's window program: about 3000), so the memory of a call is
#: bounded by evaluating it this many rows at a time (the same bits: every row is evaluated
#: alone); measured at N = 16000, 520 MB peak unchunked, and per-operation overhead of NumPy
#: starts to dominate below about 1000 rows
NUMPY_ROWS = 2048

#: the background builds this process has started
_THREADS: list[threading.Thread] = []
_THREADS_LOCK = threading.Lock()


def compile_program(label: str, program, inputs: str, outputs: str
                    ) -> Callable[[np.ndarray], np.ndarray] | None:
    """``program``'s output ``outputs`` as a compiled ``f(values (W, n_in)) -> (W, n_out)``
    (each row the input array ``inputs``), or None (no compiler, or the backend forced to
    NumPy with ``SYMGROUPOID_BACKEND=numpy``)."""

    if environment_backend(label) == "numpy":
        return None
    kernel, flags = _source(label, program, inputs, outputs)
    cache = KernelCache()
    try:
        key, manifest = build_cached(kernel, flags, cache, label)
    except (CompilerNotFoundError, CompilationError) as exc:
        warnings.warn(f"{label}: window kernels stay in NumPy ({exc})", RuntimeWarning,
                      stacklevel=caller_level())
        return None
    return _evaluator(label, program, inputs, outputs, kernel.prefix,
                      load_cached(key, manifest, cache))


def _source(label: str, program, inputs: str, outputs: str) -> tuple:
    """The generated C of a program's output and the flags it is built with."""
    return (generate_program_c(label, program, inputs, outputs),
            optimisation_flags(program.size([outputs])))


def _evaluator(label: str, program, inputs: str, outputs: str, prefix: str, module):
    """The (W, n_in) → (W, n_out) function of a loaded program kernel (arguments checked)."""
    fn, ffi = getattr(module.lib, f"{prefix}_eval"), module.ffi
    n_in, n_out = len(program.inputs[inputs]), len(program.outputs[outputs])

    def evaluate(values: np.ndarray) -> np.ndarray:
        arr = _checked(label, values, n_in)
        W = arr.shape[0]
        out = np.empty((W, n_out))
        fn(W, n_in, n_out, c_buffer(ffi, arr, W * n_in, f"{label}: in"),
           c_buffer(ffi, out, W * n_out, f"{label}: out"))
        return out

    return evaluate


def _checked(label: str, values, n_in: int) -> np.ndarray:
    arr = np.asarray(values)
    if arr.ndim != 2 or arr.shape[1] != n_in or arr.dtype.kind not in "iuf":
        raise ShapeError(f"{label}: the window program takes a real (W, {n_in}) array, "
                         f"got shape {arr.shape} and dtype {arr.dtype}")
    if arr.shape[0] > C_INT_MAX:
        raise ShapeError(f"{label}: at most {C_INT_MAX} windows per call, got {arr.shape[0]}")
    return np.ascontiguousarray(arr, dtype=np.float64)


class ProgramEvaluator:
    """``f(values (W, n_in)) -> (W, n_out)`` for a program's output: its compiled kernel
    when that is loaded, else its NumPy form (the same bits) while the kernel is built in the
    background.

    ``backend`` is ``"auto"`` (this behaviour), ``"c"`` (build now and wait; without a
    compiler, NumPy with a warning, as :func:`compile_program`) or ``"numpy"``.  A kernel
    that cannot be built or loaded in the background leaves the NumPy form in use, with a
    ``RuntimeWarning`` on the next call.
    """

    def __init__(self, label: str, program, inputs: str, outputs: str, backend: str = "auto"):
        self.label, self.program = label, program
        self.inputs, self.outputs = inputs, outputs
        self._n_in = len(program.inputs[inputs])
        self._compiled: Callable | None = None
        self._numpy: Callable | None = None
        self._failure: BaseException | None = None
        self._thread: threading.Thread | None = None
        if backend == "numpy":
            return
        if backend == "c":
            self._compiled = compile_program(label, program, inputs, outputs)
            return
        self._start()

    @property
    def backend(self) -> str:
        """``"c"`` once the compiled kernel is in use, else ``"numpy"``."""
        return "c" if self._compiled is not None else "numpy"

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the background build (at most ``timeout`` seconds); whether the compiled
        kernel is now in use."""
        thread = self._thread
        if thread is not None:
            thread.join(timeout)
        return self._compiled is not None

    def __call__(self, values: np.ndarray) -> np.ndarray:
        compiled = self._compiled
        if compiled is not None:
            with np.errstate(all="ignore"):
                return compiled(values)
        self._report_failure()
        arr = _checked(self.label, values, self._n_in)
        if self._numpy is None:
            self._numpy = self.program.numpy_function([self.outputs], [self.inputs])
        n_out = len(self.program.outputs[self.outputs])
        out = np.empty((arr.shape[0], n_out))
        for start in range(0, arr.shape[0], NUMPY_ROWS):  # every node's array stays small
            rows = slice(start, start + NUMPY_ROWS)
            out[rows] = self._numpy(arr[rows].T)[0].T
        return out

    # --- the background build -------------------------------------------------------------
    def _start(self) -> None:

        kernel, flags = _source(self.label, self.program, self.inputs, self.outputs)
        cache = KernelCache()
        key = source_key_of(kernel, flags)
        manifest = cache.verified_manifest(key)
        if manifest is not None:  # cached: load now
            try:
                self._compiled = self._loaded(kernel, load_cached(key, manifest, cache))
                return
            except Exception:  # noqa: BLE001 - rebuilt in the background, as a miss
                pass
        # built in the background; another evaluator building the same kernel holds its
        # cache lock, so this one waits for that build and loads it (build_cached)
        self._thread = threading.Thread(target=self._build, args=(kernel, flags, cache),
                                        name=f"symgroupoid build {self.label}")
        with _THREADS_LOCK:
            _THREADS.append(self._thread)
        self._thread.start()

    def _build(self, kernel, flags, cache) -> None:

        try:
            key, manifest = build_cached(kernel, flags, cache, self.label)
            self._compiled = self._loaded(kernel, load_cached(key, manifest, cache))
        except BaseException as exc:  # noqa: BLE001 - reported on the next call
            self._failure = exc

    def _loaded(self, kernel, module) -> Callable:
        return _evaluator(self.label, self.program, self.inputs, self.outputs, kernel.prefix,
                          module)

    def _report_failure(self) -> None:
        failure, self._failure = self._failure, None
        if failure is not None:
            warnings.warn(f"{self.label}: the window kernel could not be built or loaded; "
                          f"it stays in NumPy (same results, slower): {failure}",
                          RuntimeWarning, stacklevel=caller_level())


def wait_for_kernels(timeout: float | None = None) -> bool:
    """Wait until every program kernel this process is building in the background is built
    (at most ``timeout`` seconds in all); whether none is still being built.  Evaluators
    switch to their kernels by themselves; this is for a caller that wants the compiled
    speed from then on (or the kernels in the cache before it goes on)."""
    import time

    deadline = None if timeout is None else time.monotonic() + timeout
    with _THREADS_LOCK:
        _THREADS[:] = [t for t in _THREADS if t.is_alive()]
        threads = list(_THREADS)
    for thread in threads:
        thread.join(None if deadline is None else max(0.0, deadline - time.monotonic()))
    return not any(thread.is_alive() for thread in threads)

