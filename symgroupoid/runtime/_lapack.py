"""LAPACK's banded LU solver ``dgbsv`` from the LAPACK that NumPy itself loads, when it has one.

NumPy's binary wheels bundle OpenBLAS with all of LAPACK (the 64-bit integer interface, its
symbols named ``scipy_<routine>_64_``), already loaded by ``import numpy``.  Calling its
``dgbsv`` through cffi's ABI mode (no compiler involved) spares a cold boundary-value solve
``import scipy.linalg``, which takes 0.14 s per process — about a third of a cold solve at
N = 1000 — because it touches every lazily imported NumPy submodule.

:func:`dgbsv` returns None when NumPy has no such library (another build of NumPy), and the
caller uses SciPy's ``dgbsv`` instead.  Either is LAPACK's partial-pivoting banded LU.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

_CDEF = """
void {name}(int64_t *n, int64_t *kl, int64_t *ku, int64_t *nrhs, double *ab, int64_t *ldab,
            int64_t *ipiv, double *b, int64_t *ldb, int64_t *info);
"""
#: the bundled library's routine (NumPy ≥ 2 wheels: scipy-openblas64)
_SYMBOL = "scipy_dgbsv_64_"


@functools.cache
def _routine():
    """(ffi, function) of the bundled ``dgbsv``, or None."""
    libs = Path(np.__file__).resolve().parent.parent / "numpy.libs"
    candidates = sorted(libs.glob("libscipy_openblas64_*.so*")) if libs.is_dir() else []
    if not candidates:
        return None
    try:
        import cffi

        ffi = cffi.FFI()
        ffi.cdef(_CDEF.format(name=_SYMBOL))
        lib = ffi.dlopen(str(candidates[0]))
        return ffi, getattr(lib, _SYMBOL)
    except (ImportError, OSError, AttributeError, cffi.FFIError):
        return None


def available() -> bool:
    """Whether NumPy's own LAPACK provides ``dgbsv``."""
    return _routine() is not None


def dgbsv(kl: int, ku: int, ab: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, int] | None:
    """Solve A x = b, A (n × n) with ``kl`` sub- and ``ku`` superdiagonals given in LAPACK's
    banded storage ``ab`` (shape (2·kl + ku + 1, n), row-major as NumPy holds it: entry
    A[i, j] at ab[kl + ku + i − j, j]; the first kl rows are workspace).  Returns
    (x, info) — info > 0: U[info−1, info−1] is exactly zero (singular) — or None when NumPy
    has no LAPACK of its own.  ``ab`` and ``b`` are not modified."""
    routine = _routine()
    if routine is None:
        return None
    ffi, fn = routine
    ldab, n = ab.shape
    if ldab != 2 * kl + ku + 1 or b.shape != (n,):
        raise ValueError(f"dgbsv: banded storage of shape {ab.shape} and right-hand side "
                         f"of shape {b.shape} do not fit kl = {kl}, ku = {ku}")
    work = np.ascontiguousarray(ab.T, dtype=np.float64)  # column-major (ldab, n)
    x = np.array(b, dtype=np.float64)
    ipiv = np.empty(max(n, 1), dtype=np.int64)
    info = ffi.new("int64_t *")
    args = [ffi.new("int64_t *", v) for v in (n, kl, ku, 1)]
    fn(*args, ffi.from_buffer("double[]", work), ffi.new("int64_t *", ldab),
       ffi.from_buffer("int64_t[]", ipiv), ffi.from_buffer("double[]", x),
       ffi.new("int64_t *", max(n, 1)), info)
    return x, int(info[0])


__all__ = ["available", "dgbsv"]
