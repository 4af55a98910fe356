"""The banded LU solve through NumPy's own LAPACK (symgroupoid/runtime/_lapack.py)."""

from __future__ import annotations

import numpy as np
import pytest

# the banded LU through NumPy's LAPACK and its fallback are the subject
from symgroupoid.runtime import _lapack
from symgroupoid.runtime._bvp._linear import _solve_banded

pytestmark = pytest.mark.skipif(not _lapack.available(),
                                reason="this NumPy has no LAPACK of its own")


def _banded(n: int, kl: int, ku: int, rng) -> tuple[np.ndarray, np.ndarray]:
    A = np.zeros((n, n))
    ab = np.zeros((2 * kl + ku + 1, n))
    for i in range(n):
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            A[i, j] = ab[kl + ku + i - j, j] = rng.normal()
    return A, ab


@pytest.mark.parametrize("n,kl,ku", [(1, 0, 0), (7, 2, 1), (200, 5, 9), (64, 0, 3)])
def test_solves_banded_systems(n, kl, ku):
    rng = np.random.default_rng(n + kl + ku)
    A, ab = _banded(n, kl, ku, rng)
    A += np.eye(n) * 4
    ab[kl + ku] += 4
    b = rng.normal(size=n)
    before = ab.copy()
    x, info = _lapack.dgbsv(kl, ku, ab, b)
    assert info == 0
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-12 * np.abs(b).max())
    assert np.array_equal(ab, before), "the caller's storage is not modified"
    scipy_lapack = pytest.importorskip("scipy.linalg.lapack")
    _, _, y, _ = scipy_lapack.dgbsv(kl, ku, ab.copy(), b.copy())
    np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-15)


def test_singular_matrix_reports_its_zero_pivot():
    A, ab = _banded(5, 1, 1, np.random.default_rng(0))
    ab[:, 2] = 0.0  # column 2 is zero
    _, info = _lapack.dgbsv(1, 1, ab, np.ones(5))
    assert info == 3
    rows, cols = np.nonzero(A)
    keep = cols != 2
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        _solve_banded(rows[keep], cols[keep], A[rows[keep], cols[keep]], 5, np.ones(5))


def test_storage_that_does_not_fit_the_bandwidths_is_refused():
    with pytest.raises(ValueError, match="do not fit"):
        _lapack.dgbsv(1, 1, np.zeros((3, 4)), np.zeros(4))


def test_solver_falls_back_when_numpy_has_no_lapack(monkeypatch):
    rng = np.random.default_rng(3)
    A, _ = _banded(30, 2, 2, rng)
    A += np.eye(30) * 4
    rows, cols = np.nonzero(A)
    b = rng.normal(size=30)
    calls = []
    monkeypatch.setattr(_lapack, "dgbsv", lambda *args: calls.append(args))  # returns None
    pytest.importorskip("scipy.linalg")
    x = _solve_banded(rows, cols, A[rows, cols], 30, b)
    assert calls, "NumPy's LAPACK was asked first"
    # SciPy's gbsv (another LAPACK build: equal to rounding, not necessarily bit for bit)
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-13 * np.abs(b).max())
