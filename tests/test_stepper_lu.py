"""The stepper's LU (``stepper.c``: ``lu_factor``, ``eliminate``, ``lu_apply``) against its
NumPy twin, bit for bit, on both sides of ``SG_LU_PANEL_FROM``: below it the elimination
goes column by column, from it on in panels of ``SG_LU_PANEL`` columns and the back
substitution column by column (the same operations in the same order for every entry).

The kernel is linear, F(u) = A u − b (A in the parameters, b the known state, each sum in
the order j = 0, 1, …; the next state is the solution u), so a step is one solve A u = b
refined by Newton's updates: every update goes through ``lu_factor`` and ``lu_apply``.
The matrices are random, or random with many exact zeros (skipped multipliers: the panel's
fused update is not taken), or block banded as a chain's Jacobian is, or singular (two
equal rows: both sides must say ``SINGULAR_JACOBIAN`` at the same step).
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess

import numpy as np
import pytest
from kernel_support import needs_cc

from symgroupoid.runtime import NewtonOptions
from symgroupoid.stepper import (
    LU_PANEL_FROM,
    BandOrder,
    NumpyStepper,
    Status,
    StepFunctions,
    library_dir,
)

#: the linear kernel's functions; N_UNKNOWNS etc. come from the sizes header
LINEAR_C = r"""
#include <math.h>
#include "stepper.h"

void lin_reconstruct(const double *u, const double *known, const double *p, double *fibre)
{
    int i;
    (void)known;
    (void)p;
    for (i = 0; i < LIN_N_UNKNOWNS; ++i) {
        fibre[i] = u[i];
    }
}

void lin_residual(const double *u, const double *known, const double *p, double *F)
{
    int i, j;
    for (i = 0; i < LIN_N_UNKNOWNS; ++i) {
        double t = 0.0;
        for (j = 0; j < LIN_N_UNKNOWNS; ++j) {
            t += p[i * LIN_N_UNKNOWNS + j] * u[j];
        }
        F[i] = t - known[i];
    }
}

#if LIN_BANDED
/* the band form the stepper reads: entry (i, j) of B = A[order[i]][order[j]] */
void lin_residual_jacobian_band(const double *u, const double *known, const double *p,
                                double *F, double *J)
{
    static const int order[LIN_N_UNKNOWNS] = LIN_BAND_ORDER;
    const int n = LIN_N_UNKNOWNS, width = LIN_BAND_KL + LIN_BAND_KU + 1;
    int i, j;
    lin_residual(u, known, p, F);
    for (i = 0; i < n; ++i) {
        for (j = i - LIN_BAND_KL; j <= i + LIN_BAND_KU; ++j) {
            if (j >= 0 && j < n) {
                J[i * width + j - i + LIN_BAND_KL] = p[order[i] * n + order[j]];
            }
        }
    }
}
#else
void lin_residual_jacobian(const double *u, const double *known, const double *p, double *F,
                           double *J)
{
    int i;
    lin_residual(u, known, p, F);
    for (i = 0; i < LIN_N_UNKNOWNS * LIN_N_UNKNOWNS; ++i) {
        J[i] = p[i];
    }
}
#endif

/* nothing is hoisted (LIN_N_HOISTED 0): the stepper's entry points of the hoisted form */
void lin_hoist(const double *known, const double *p, double *h)
{
    (void)known;
    (void)p;
    (void)h;
}

void lin_residual_hoisted(const double *u, const double *known, const double *p,
                          const double *h, double *F)
{
    (void)h;
    lin_residual(u, known, p, F);
}

#if LIN_BANDED
void lin_residual_jacobian_band_hoisted(const double *u, const double *known, const double *p,
                                        const double *h, double *F, double *J)
{
    (void)h;
    lin_residual_jacobian_band(u, known, p, F, J);
}
#else
void lin_residual_jacobian_hoisted(const double *u, const double *known, const double *p,
                                   const double *h, double *F, double *J)
{
    (void)h;
    lin_residual_jacobian(u, known, p, F, J);
}
#endif

void lin_residual_scale(const double *u, const double *known, const double *p, double *S)
{
    int i, j;
    for (i = 0; i < LIN_N_UNKNOWNS; ++i) {
        double t = 0.0;
        for (j = 0; j < LIN_N_UNKNOWNS; ++j) {
            t += fabs(p[i * LIN_N_UNKNOWNS + j] * u[j]);
        }
        S[i] = t + fabs(known[i]);
    }
}

void lin_predict(const double *known, const double *p, double *u)
{
    int i;
    (void)known;
    (void)p;
    for (i = 0; i < LIN_N_UNKNOWNS; ++i) {
        u[i] = 0.0;
    }
}

void lin_next_knowns(const double *u, const double *known, const double *p,
                     double *known_next)
{
    int i;
    (void)known;
    (void)p;
    for (i = 0; i < LIN_N_UNKNOWNS; ++i) {
        known_next[i] = u[i];
    }
}
"""

FLAGS = ["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-pedantic", "-Werror",
         "-fPIC", "-DSG_PREFIX=lin", "-DSG_PREFIX_UPPER=LIN"]

#: sizes on both sides of the panel threshold, with and without a last partial panel
SIZES = (5, 23, 24, 26, 27, 61, 100)


#: band kernels: (n, kl, ku), their order a fixed random permutation
BANDS = ((7, 1, 1), (30, 2, 3), (61, 4, 2))


def _band(n: int, kl: int, ku: int) -> BandOrder:
    order = np.random.default_rng(n).permutation(n)
    return BandOrder(kl, ku, tuple(int(i) for i in order))


def _sizes_header(n: int, band: BandOrder | None = None) -> str:
    defines = {"N_EQUATIONS": n, "N_UNKNOWNS": n, "N_KNOWNS": n, "N_PARAMETERS": n * n,
               "N_INPUTS": 0, "N_HOISTED": 0, "TIME_ROW": -1, "TIME_UNKNOWN": -1, "TIME_KNOWN": -1,
               "TIME_BEFORE": -1}
    if band is not None:
        defines.update(BANDED=1, BAND_KL=band.kl, BAND_KU=band.ku,
                       BAND_ORDER="{" + ", ".join(map(str, band.order)) + "}")
    return "".join(f"#define LIN_{k} {v}\n" for k, v in defines.items())


def _build(cc: str, where, n: int, band: BandOrder | None = None):
    (where / "sizes.h").write_text(_sizes_header(n, band))
    (where / "lin.c").write_text(LINEAR_C)
    objects = []
    for source in (library_dir() / "stepper.c", library_dir() / "batch.c", where / "lin.c"):
        obj = where / (source.stem + ".o")
        subprocess.run([cc, *FLAGS, f"-I{library_dir()}", "-include",
                        str(where / "sizes.h"), "-c", str(source), "-o", str(obj)],
                       check=True, capture_output=True, text=True)
        objects.append(str(obj))
    library = where / "liblin.so"
    subprocess.run([cc, "-shared", *objects, "-lm", "-o", str(library)], check=True)
    return ctypes.CDLL(str(library))


@pytest.fixture(scope="module")
def linear_kernels(tmp_path_factory):
    """The library compiled with the linear kernel at every size of :data:`SIZES`."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH")
    return {n: _build(cc, tmp_path_factory.mktemp(f"lu{n}"), n) for n in SIZES}


@pytest.fixture(scope="module")
def band_kernels(tmp_path_factory):
    """The library compiled with the linear kernel in band form for every case of BANDS."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH")
    return {case: _build(cc, tmp_path_factory.mktemp(f"band{case[0]}"), case[0], _band(*case))
            for case in BANDS}


class _Options(ctypes.Structure):
    _fields_ = [("tol_residual", ctypes.c_double), ("floor_factor", ctypes.c_double),
                ("tol_step", ctypes.c_double), ("max_iterations", ctypes.c_int),
                ("extrapolate", ctypes.c_int), ("trust_factor", ctypes.c_double)]


def _twin_functions(n: int) -> StepFunctions:
    """The linear kernel in NumPy, each sum in the C's order (a Python loop)."""

    def residual(u, known, p):
        A = p.reshape(n, n)
        F = np.empty(n)
        for i in range(n):
            t = 0.0
            for j in range(n):
                t += A[i, j] * u[j]
            F[i] = t - known[i]
        return F

    def scale(u, known, p):
        A = p.reshape(n, n)
        S = np.empty(n)
        for i in range(n):
            t = 0.0
            for j in range(n):
                t += abs(A[i, j] * u[j])
            S[i] = t + abs(known[i])
        return S

    return StepFunctions(
        residual=residual,
        residual_jacobian=lambda u, known, p: (residual(u, known, p), p.reshape(n, n).copy()),
        residual_scale=scale, predict=lambda known, p: np.zeros(n),
        next_knowns=lambda u, known, p: np.array(u, dtype=float))


def _c_step(lib, n: int, A: np.ndarray, b: np.ndarray):
    """(status, u) of the library's one-step entry point from the prediction u = 0."""
    options = _Options()
    lib.lin_default_options(ctypes.byref(options))
    states = np.zeros((2, n))
    iterations = np.zeros(1, dtype=np.intc)
    norms = np.zeros(1)
    failed = ctypes.c_long(-2)
    last = np.zeros(n)
    warm = (ctypes.c_byte * (8 + 3 * 8 * n + 64))()
    p, known = np.ascontiguousarray(A.ravel()), np.ascontiguousarray(b)
    as_double = ctypes.POINTER(ctypes.c_double)
    status = lib.lin_simulate(
        known.ctypes.data_as(as_double), p.ctypes.data_as(as_double), None, ctypes.c_long(1),
        ctypes.byref(options), ctypes.byref(warm), states.ctypes.data_as(as_double),
        ctypes.c_long(2), iterations.ctypes.data_as(ctypes.POINTER(ctypes.c_int)),
        norms.ctypes.data_as(as_double), ctypes.byref(failed), last.ctypes.data_as(as_double))
    return status, (states[1] if status == Status.OK else last), int(iterations[0]), norms[0]


def _matrix(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(n, n)) * np.exp(rng.uniform(-3, 3, size=(n, 1)))
    if kind == "zeros":  # many exact zeros: multipliers are skipped, panels not fused
        A[rng.uniform(size=(n, n)) < 0.4] = 0.0
        A += np.diag(rng.uniform(0.5, 1.0, n))
    elif kind == "banded":  # a chain's Jacobian: blocks of 3 coupled to their neighbours
        blocks = np.arange(n) // 3
        A[np.abs(blocks[:, None] - blocks[None, :]) > 1] = 0.0
        A += np.diag(rng.uniform(0.1, 0.2, n))
    elif kind == "singular":
        A[n - 2] = A[1]
    return A


@needs_cc
@pytest.mark.parametrize("kind", ["dense", "zeros", "banded", "singular"])
@pytest.mark.parametrize("n", SIZES)
def test_lu_and_its_numpy_twin_agree_bit_for_bit(linear_kernels, n, kind):
    rng = np.random.default_rng(1000 * n + len(kind))
    A = _matrix(kind, n, rng)
    _solve_both(linear_kernels[n], A, rng.normal(size=n), kind)


def _solve_both(lib, A: np.ndarray, b: np.ndarray, kind: str, band: BandOrder | None = None):
    """One step of the C library ``lib`` and of its twin on A u = b: the same status and
    bits; ``SINGULAR_JACOBIAN`` for a singular A, else a u that solves A u = b.  Returns u."""
    n = len(b)
    status, u, iterations, norm = _c_step(lib, n, A, b)
    twin = NumpyStepper(_twin_functions(n), n, band=band)
    t_states, t_iterations, t_norms, t_status, _, t_last = twin.simulate(
        b, A.ravel(), 1, NewtonOptions(), twin.warm_start())
    assert status == t_status
    t_u = t_states[1] if t_status == Status.OK else np.asarray(t_last, dtype=float)
    assert u.tobytes() == t_u.tobytes()
    assert (iterations, norm) == (int(t_iterations[0]), t_norms[0])
    if kind == "singular":
        assert status == Status.SINGULAR_JACOBIAN
    else:
        assert status == Status.OK
        np.testing.assert_allclose(A @ u, b, atol=1e-12 * np.abs(A).sum(axis=1).max())
    return u


def test_the_panel_threshold_is_the_twins():
    """``SG_LU_PANEL_FROM`` of ``stepper.c`` is :data:`LU_PANEL_FROM` of the NumPy twin, and
    the fused panel update spells out ``SG_LU_PANEL`` multipliers."""
    text = (library_dir() / "stepper.c").read_text(encoding="ascii")
    threshold = int(re.search(r"#define SG_LU_PANEL_FROM (\d+)", text).group(1))
    panel = int(re.search(r"#define SG_LU_PANEL (\d+)", text).group(1))
    assert threshold == LU_PANEL_FROM
    fused = re.search(r"void SG_NAME\(panel_row_update\)\(.*?\n}\n", text, re.S).group(0)
    assert len(re.findall(r"t -= l\d \* u\d\[j\];", fused)) == panel


def _banded_matrix(band: BandOrder, kind: str, rng: np.random.Generator) -> np.ndarray:
    """A random J whose reordering by ``band.order`` is banded (kl, ku); "zeros": a third
    of the band's entries exactly zero; "singular": two rows equal (both in the band)."""
    n = len(band.order)
    B = rng.normal(size=(n, n)) * np.exp(rng.uniform(-3, 3, size=(n, 1)))
    i, j = np.indices((n, n))
    B[(j - i < -band.kl) | (j - i > band.ku)] = 0.0
    if kind == "zeros":
        B[rng.uniform(size=(n, n)) < 0.33] = 0.0
        B += np.diag(rng.uniform(0.5, 1.0, n))
    if kind == "singular":  # rows m and m + 1 equal, inside the band (kl, ku >= 1)
        m = n // 2
        B[m:m + 2] = 0.0
        B[m, m:m + 2] = B[m + 1, m:m + 2] = [1.0, 2.0]
    order = np.asarray(band.order)
    J = np.empty((n, n))
    J[np.ix_(order, order)] = B
    return J


@needs_cc
@pytest.mark.parametrize("kind", ["dense", "zeros", "singular"])
@pytest.mark.parametrize("case", BANDS)
def test_band_lu_and_its_numpy_twin_agree_bit_for_bit(band_kernels, case, kind):
    """The band factors (``SG_BANDED``) against the twin's band_factor: the same
    bits, the same status; the solution solves J u = b."""
    n = case[0]
    band = _band(*case)
    rng = np.random.default_rng(7 * n + len(kind))
    A = _banded_matrix(band, kind, rng)
    b = rng.normal(size=n)
    u = _solve_both(band_kernels[case], A, b, kind, band)
    if kind != "singular":
        dense = NumpyStepper(_twin_functions(n), n)  # the dense factors: the same solution
        d_states = dense.simulate(b, A.ravel(), 1, NewtonOptions(), dense.warm_start())[0]
        np.testing.assert_allclose(u, d_states[1], rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize(("kl", "ku", "order"), [
    (-1, 1, (0, 1, 2)), (1, 1.5, (0, 1, 2)), (True, 1, (0, 1, 2)), (1, 1, (0, 0, 2)),
    (1, 1, (0, 1, 3)), (1, 1, (0.0, 1, 2))])
def test_a_malformed_band_order_is_refused_by_name(kl, ku, order):
    import symgroupoid as sg

    with pytest.raises(sg.ShapeError, match="BandOrder"):
        BandOrder(kl, ku, order)


def test_a_band_order_of_another_size_is_refused_by_name():
    import symgroupoid as sg
    from symgroupoid.stepper import lu_factor

    with pytest.raises(sg.ShapeError, match="band order of 3 unknowns for a matrix of 4"):
        lu_factor(np.eye(4), BandOrder(1, 1, (0, 1, 2)))
