"""Batched programs compiled to C through the kernel build cache.

The boundary-value solver evaluates, for every window of a trajectory, a program over the
expression graph (the window residual, its slot derivatives and its rounding bound).
:func:`compile_program` prints it to C (``codegen.generate_program_c``: one function applied
to W items in a loop), builds it with cffi through the same cache as the step kernels (keyed
by a hash of the source and flags, built in a temporary directory, verified on load) and
returns a function of a (W, n_in) array.  Without a compiler it returns None and the caller
evaluates the program with NumPy.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable

import numpy as np

from .._errors import ShapeError
from ..codegen._emit import generate_program_c
from ._backends import C_INT_MAX, c_buffer
from ._build import CompilationError, CompilerNotFoundError, optimisation_flags
from ._cache import KernelCache


def compile_program(label: str, program, inputs: str, outputs: str
                    ) -> Callable[[np.ndarray], np.ndarray] | None:
    """``program``'s output ``outputs`` as a compiled ``f(values (W, n_in)) -> (W, n_out)``
    (each row the input array ``inputs``), or None (no compiler, or the backend forced to
    NumPy with ``SYMGROUPOID_BACKEND=numpy``)."""
    from ._compile import build_cached, load_cached

    if os.environ.get("SYMGROUPOID_BACKEND", "auto") == "numpy":
        return None
    kernel = generate_program_c(label, program, inputs, outputs)
    cache = KernelCache()
    try:
        key, manifest = build_cached(kernel, optimisation_flags(program.size([outputs])), cache,
                                     label)
    except (CompilerNotFoundError, CompilationError) as exc:
        warnings.warn(f"{label}: window kernels stay in NumPy ({exc})", RuntimeWarning,
                      stacklevel=3)
        return None
    module = load_cached(key, manifest, cache)
    fn, ffi = getattr(module.lib, f"{kernel.prefix}_eval"), module.ffi
    n_in, n_out = len(program.inputs[inputs]), len(program.outputs[outputs])

    def evaluate(values: np.ndarray) -> np.ndarray:
        arr = np.asarray(values)
        if arr.ndim != 2 or arr.shape[1] != n_in or arr.dtype.kind not in "iuf":
            raise ShapeError(f"{label}: the window program takes a real (W, {n_in}) array, "
                             f"got shape {arr.shape} and dtype {arr.dtype}")
        W = arr.shape[0]
        if W > C_INT_MAX:
            raise ShapeError(f"{label}: at most {C_INT_MAX} windows per call, got {W}")
        arr = np.ascontiguousarray(arr, dtype=np.float64)
        out = np.empty((W, n_out))
        fn(W, n_in, n_out, c_buffer(ffi, arr, W * n_in, f"{label}: in"),
           c_buffer(ffi, out, W * n_out, f"{label}: out"))
        return out

    return evaluate
