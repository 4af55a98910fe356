"""Straight-line programs compiled to C through the kernel build cache.

The boundary-value solver evaluates, for every window of a trajectory, a program of
assignments (the window residual and its slot derivatives).  :func:`compile_program` prints
it as one C function applied to W windows in a loop, builds it with cffi through the same
cache as the step kernels (keyed by a hash of the source and flags, built in a temporary
directory, verified on load) and returns a function of a (W, n_in) array.  Without a
compiler it returns None and the caller keeps its NumPy evaluation.
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .._errors import ShapeError
from ..codegen._emit import KernelSource
from ..codegen._printer import KernelCPrinter
from ._backends import C_INT_MAX, c_buffer
from ._build import DEFAULT_FLAGS, CompilationError, CompilerNotFoundError
from ._cache import KernelCache


def program_source(prefix: str, inputs: Sequence[sp.Symbol],
                   assignments: Sequence[tuple[sp.Symbol, sp.Expr]],
                   outputs: Sequence[sp.Expr]) -> KernelSource:
    """C99 source of ``out[k] = outputs[k](in)`` through the assignments, for W windows."""
    names = {x: f"a[{i}]" for i, x in enumerate(inputs)}
    local = sorted({s for s, _ in assignments}, key=lambda s: (len(s.name), s.name))
    names.update({s: s.name for s in local})
    printer = KernelCPrinter(names)
    body = [f"    {s.name} = {printer.doprint(e)};" for s, e in assignments]
    body += [f"    o[{k}] = {printer.doprint(e)};" for k, e in enumerate(outputs)]
    decl = [f"    double {', '.join(s.name for s in local[i:i + 12])};"
            for i in range(0, len(local), 12)]
    signature = (f"void {prefix}_eval(int n, int n_in, int n_out, const double *in, "
                 f"double *out)")
    header = (f"/* window program {prefix}: {len(inputs)} inputs, {len(outputs)} outputs */\n"
              f"{signature};\n")
    source = "\n".join([
        f'#include <math.h>\n#include <stddef.h>\n#include "{prefix}.h"\n',
        f"static void {prefix}_one(const double *a, double *o)\n{{",
        *decl, *body, "}\n",
        f"{signature}\n{{",
        "    for (int w = 0; w < n; ++w)",
        f"        {prefix}_one(in + (size_t)w * (size_t)n_in, out + (size_t)w * (size_t)n_out);",
        "}\n"])
    return KernelSource(prefix=prefix, header_name=f"{prefix}.h", header=header,
                        source=source, cdef=signature + ";")


def compile_program(label: str, inputs: Sequence[sp.Symbol],
                    assignments: Sequence[tuple[sp.Symbol, sp.Expr]],
                    outputs: Sequence[sp.Expr]) -> Callable[[np.ndarray], np.ndarray] | None:
    """The compiled program as ``f(values (W, n_in)) -> (W, n_out)``, or None (no compiler,
    or the backend forced to NumPy with ``SYMGROUPOID_BACKEND=numpy``)."""
    import os

    from ._compile import build_cached, load_cached

    if os.environ.get("SYMGROUPOID_BACKEND", "auto") == "numpy":
        return None
    ident = re.sub(r"[^a-z0-9_]+", "_", label.lower()).strip("_") or "program"
    kernel = program_source(f"sgw_{ident}", inputs, assignments, outputs)
    cache = KernelCache()
    try:
        key, manifest = build_cached(kernel, tuple(DEFAULT_FLAGS), cache, label)
    except (CompilerNotFoundError, CompilationError) as exc:
        warnings.warn(f"{label}: window kernels stay in NumPy ({exc})", RuntimeWarning,
                      stacklevel=3)
        return None
    module = load_cached(key, manifest, cache)
    fn, ffi = getattr(module.lib, f"{kernel.prefix}_eval"), module.ffi
    n_in, n_out = len(inputs), len(outputs)

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
