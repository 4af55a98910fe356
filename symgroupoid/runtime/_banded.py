"""The inertia of a symmetric banded matrix in time linear in its size.

A symmetric matrix K with half-bandwidth w, cut into blocks of size b ≥ w, is block
tridiagonal: diagonal blocks D_k, sub-diagonal blocks B_k.  Block LDLᵀ elimination

    P₁ = D₁,   P_k = D_k − B_k P_{k−1}⁻¹ B_kᵀ

gives K = L·diag(P_k)·Lᵀ with L unit block lower triangular, so by Sylvester's law of inertia
(and the Haynsworth additivity of the inertia over Schur complements) the numbers of
positive, negative and zero eigenvalues of K are the sums of those of the pivot blocks P_k,
each read off a small symmetric eigendecomposition.

A pivot block with an eigenvalue near zero (|μ| ≤ PIVOT_TOLERANCE after the symmetric
equilibration below) is not inverted: it is merged with the next block (a delayed pivot, the
block analogue of Bunch–Kaufman's 2×2 pivots), which is exact because the merged block
couples to the block after it only through its last b rows.  A singular K keeps a zero
eigenvalue in a pivot and is reported with ``zero > 0`` (a pivot's null vectors that do not
reach its coupling rows are null vectors of K, counted and deflated); a near-singular pivot
that MAX_MERGED merges do not resolve makes the inertia undetermined (None), never a guess.

Before elimination K is equilibrated symmetrically, K ↦ SKS with S = diag(1/√max_j|K_ij|)
(a congruence: the inertia is unchanged), so the tolerance is relative to each row's scale —
the boundary-value Hessians mix rows scaled like 1/h³ and like h.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: a pivot block eigenvalue at most this (after equilibration: entries ≤ 1) counts as zero
PIVOT_TOLERANCE = 1e-10

#: at most this many blocks merged into one delayed pivot
MAX_MERGED = 24

#: the smallest block size (a multiple of the bandwidth): fewer, larger blocks cost less
#: per row in the elimination loop
MIN_BLOCK = 16


class Inertia(NamedTuple):
    """Numbers of positive, negative and zero eigenvalues of a symmetric matrix."""

    positive: int
    negative: int
    zero: int


def _symmetric_blocks(rows, cols, vals, n: int):
    """Diagonal and sub-diagonal blocks (nb, b, b) of SKS, K = (A + Aᵀ)/2 from COO triplets
    of A (duplicates summed), padded with an identity to nb·b rows; returns (D, B, pad)."""
    w = max(int(np.max(np.abs(rows - cols), initial=0)), 1)
    b = w * max(1, -(-MIN_BLOCK // w))
    nb = -(-n // b)
    bi, bj = rows // b, cols // b
    flat = (rows % b) * b + cols % b

    def gather(mask: np.ndarray, shift: int = 0) -> np.ndarray:
        index = (bi[mask] + shift) * b * b + flat[mask]
        out = np.bincount(index, weights=vals[mask], minlength=(nb + 1) * b * b)
        return out[:nb * b * b].astype(float).reshape(nb, b, b)

    A_diag = gather(bi == bj)
    A_below = gather(bi == bj + 1)  # A[block k, block k − 1] at k
    A_above = gather(bi + 1 == bj, shift=1)  # A[block k − 1, block k] at k
    D = (A_diag + np.swapaxes(A_diag, 1, 2)) / 2
    B = (A_below + np.swapaxes(A_above, 1, 2)) / 2
    _equilibrate(D, B)
    pad = np.arange(n, nb * b)
    D[pad // b, pad % b, pad % b] = 1.0
    return D, B, len(pad)


def _equilibrate(D: np.ndarray, B: np.ndarray) -> None:
    """K ↦ SKS in place, S = diag(1/√max_j|K_ij|) (a congruence: the inertia is kept)."""
    big = np.maximum(np.abs(D).max(axis=2), np.abs(B).max(axis=2))  # row maxima (nb, b)
    big[:-1] = np.maximum(big[:-1], np.abs(B[1:]).max(axis=1))  # the blocks above: B_{k+1}ᵀ
    scale = 1.0 / np.sqrt(np.where(big > 0, big, 1.0))
    D *= scale[:, :, None] * scale[:, None, :]
    B[1:] *= scale[1:, :, None] * scale[:-1, None, :]


def banded_inertia(rows, cols, vals, n: int) -> Inertia | None:
    """The inertia of the symmetric part (A + Aᵀ)/2 of the banded matrix A given by COO
    triplets (``n`` × ``n``), by block LDLᵀ with delayed pivots; None when a near-singular
    pivot cannot be resolved within MAX_MERGED blocks, or when the eigenvalues of a block
    cannot be computed (entries near the largest doubles: LAPACK does not converge; or not
    finite after an elimination, on which LAPACK ran for minutes)."""
    if n == 0:
        return Inertia(0, 0, 0)
    try:
        with np.errstate(all="ignore"):
            return _inertia(rows, cols, vals, n)
    except np.linalg.LinAlgError:
        return None


def _inertia(rows, cols, vals, n: int) -> Inertia | None:
    """:func:`banded_inertia` of a nonempty matrix (LinAlgError from LAPACK passes)."""
    D, B, pad = _symmetric_blocks(np.asarray(rows), np.asarray(cols), np.asarray(vals, float),
                                  n)
    nb, b = D.shape[0], D.shape[1]
    positive = negative = zero = 0
    P = D[0]
    for k in range(1, nb):
        if not np.isfinite(P).all():  # (an elimination overflowed: LAPACK may not return)
            return None
        mu, Q = np.linalg.eigh(P)
        tiny = np.abs(mu) <= PIVOT_TOLERANCE
        Qb = Q[-b:]
        # eigenvectors of a zero eigenvalue that do not reach the coupling rows are null
        # vectors of K itself: counted and deflated, the rest is eliminated exactly
        if not tiny.any() or np.abs(Qb[:, tiny]).max() <= np.sqrt(PIVOT_TOLERANCE):
            positive += int((mu[~tiny] > 0).sum())
            negative += int((mu[~tiny] < 0).sum())
            zero += int(tiny.sum())
            Qb = Qb[:, ~tiny]
            P = D[k] - B[k] @ ((Qb / mu[~tiny]) @ Qb.T) @ B[k].T
        elif P.shape[0] >= MAX_MERGED * b:
            return None
        else:  # a delayed pivot: merge with block k, coupled through the last b rows
            C = np.zeros((b, P.shape[0]))
            C[:, -b:] = B[k]
            P = np.block([[P, C.T], [C, D[k]]])
    if not np.isfinite(P).all():
        return None
    mu = np.linalg.eigvalsh(P)
    zero += int((np.abs(mu) <= PIVOT_TOLERANCE).sum())
    positive += int((mu > PIVOT_TOLERANCE).sum())
    negative += int((mu < -PIVOT_TOLERANCE).sum())
    return Inertia(positive - pad, negative, zero)

