"""Banded linear algebra of the boundary-value system.

The Jacobian of the necessary conditions is block-banded (every equation depends on a
window of neighbouring unknowns), so its systems are solved in time linear in their size:
LAPACK's banded LU (``gbsv``) on a fixed sparsity pattern stored once (:class:`_Band`), or
a block-tridiagonal elimination in NumPy.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import _lapack


class _Band(NamedTuple):
    """LAPACK's general banded storage of a fixed sparsity pattern: the lower and upper
    bandwidths and, per triplet, its flat position in the (2·kl + ku + 1, n) array that
    ``gbsv`` factorises in place (the first kl rows are its workspace)."""

    kl: int
    ku: int
    index: np.ndarray
    n: int

    @classmethod
    def of(cls, rows: np.ndarray, cols: np.ndarray, n: int) -> _Band:
        kl = int(np.max(rows - cols, initial=0))
        ku = int(np.max(cols - rows, initial=0))
        return cls(kl, ku, (kl + ku + rows - cols) * n + cols, n)

    def matrix(self, vals: np.ndarray) -> np.ndarray:
        """The banded storage of the matrix with these triplet values (duplicates summed)."""
        size = (2 * self.kl + self.ku + 1) * self.n
        return np.bincount(self.index, weights=vals, minlength=size).reshape(-1, self.n)



def _solve_banded(rows, cols, vals, n, rhs, band: _Band | None = None) -> np.ndarray:
    """Solve the sparse banded system (COO triplets) in time linear in its size: LAPACK's
    ``gbsv`` (LU with partial pivoting in banded storage) — NumPy's own LAPACK
    (:mod:`._lapack`), else SciPy's, else block elimination in NumPy; ``band``, the
    triplets' :class:`_Band` when known (a solve's every Jacobian shares one)."""
    band = _Band.of(rows, cols, n) if band is None else band
    ab = band.matrix(vals)
    solved = _lapack.dgbsv(band.kl, band.ku, ab, np.asarray(rhs, float))
    if solved is None:
        try:
            from scipy.linalg import lapack
        except ImportError:  # pragma: no cover - exercised by forcing the fallback in tests
            return _block_tridiagonal(rows, cols, vals, n, rhs, max(band.kl, band.ku))
        _, _, x, info = lapack.dgbsv(band.kl, band.ku, ab, np.array(rhs, float),
                                     overwrite_ab=True, overwrite_b=True)
    else:
        x, info = solved
    if info > 0:
        raise np.linalg.LinAlgError(f"singular banded matrix (zero pivot {info})")
    if info < 0:  # pragma: no cover - the arguments are built above
        raise ValueError(f"gbsv: illegal argument {-info}")
    return x


def _block_tridiagonal(rows, cols, vals, n, rhs, band) -> np.ndarray:
    """Block elimination with blocks of size ``band`` (≥ the bandwidth), so the matrix is
    block tridiagonal; each diagonal block is LU-factorised with pivoting by NumPy."""
    b = max(band, 1)
    nb = -(-n // b)
    size = nb * b
    D = np.zeros((nb, b, b))
    L = np.zeros((nb, b, b))
    U = np.zeros((nb, b, b))
    bi, bj = rows // b, cols // b
    for arr, mask in ((D, bi == bj), (L, bi == bj + 1), (U, bi + 1 == bj)):
        np.add.at(arr, (bi[mask], rows[mask] % b, cols[mask] % b), vals[mask])
    pad = np.arange(n, size)
    D[pad // b, pad % b, pad % b] = 1.0
    y = np.zeros(size)
    y[:n] = rhs
    y = y.reshape(nb, b)
    for k in range(1, nb):
        F = np.linalg.solve(D[k - 1].T, L[k].T).T
        D[k] -= F @ U[k - 1]
        y[k] -= F @ y[k - 1]
    x = np.zeros_like(y)
    x[-1] = np.linalg.solve(D[-1], y[-1])
    for k in range(nb - 2, -1, -1):
        x[k] = np.linalg.solve(D[k], y[k] - U[k] @ x[k + 1])
    return x.ravel()[:n]


def _apply(rows, cols, vals, z, n) -> np.ndarray:
    """A·z for A given by COO triplets."""
    out = np.zeros(n)
    np.add.at(out, rows, vals * z[cols])
    return out

