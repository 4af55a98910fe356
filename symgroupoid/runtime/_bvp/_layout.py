"""Where the unknowns and the equations of a boundary-value problem sit.

The unknowns are the junction variations δ_j ∈ R^rank of the free junctions, the
multipliers λ_t ∈ R^m of every term and, with internal stages (docs/conventions.md §22), the
stages ζ_t of every term; the equations are the junction residuals DEL_j, the constraints Φ_t
and the stage rows ∂L/∂ζ(g_t, ζ_t) (+ f_ζ).  Both are interleaved by position along the
trajectory (λ_p, ζ_p, then δ_p), so that every equation's window of unknowns is a band
around the diagonal.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np


@dataclass
class _Layout:
    """Positions of the unknowns (δ_j, λ_t) and equations (DEL_j, Φ_t) in the banded system."""

    junctions: np.ndarray
    terms: np.ndarray
    delta_index: dict
    lam_index: dict
    size: int
    zeta_index: dict = None  # term t -> the position of ζ_t (empty without stages)

    @functools.cached_property
    def delta_at(self) -> np.ndarray:
        """delta_index as an array over positions 0 … n (−1: not an unknown)."""
        return _index_array(self.delta_index, len(self.terms) + len(self.junctions) + 2)

    @functools.cached_property
    def lam_at(self) -> np.ndarray:
        return _index_array(self.lam_index, len(self.terms) + len(self.junctions) + 2)

    @functools.cached_property
    def zeta_at(self) -> np.ndarray:
        return _index_array(self.zeta_index or {}, len(self.terms) + len(self.junctions) + 2)

    @functools.cached_property
    def staged(self) -> np.ndarray:
        """The terms t with stages ζ_t, increasing."""
        return np.array(sorted(self.zeta_index or {}), dtype=np.int64)

    @functools.cached_property
    def moved(self) -> np.ndarray:
        """The positions j with a variation δ_j, increasing."""
        return np.array(sorted(self.delta_index), dtype=np.int64)

    @functools.cached_property
    def multiplied(self) -> np.ndarray:
        """The terms t with multipliers λ_t, increasing."""
        return np.array(sorted(self.lam_index), dtype=np.int64)


def _index_array(index: dict, n: int) -> np.ndarray:
    out = np.full(max(n, max(index, default=-1) + 2), -1, dtype=np.int64)
    for position, k in index.items():
        out[position] = k
    return out


@functools.lru_cache(maxsize=16)
def _layout(n: int, arity: int, rank: int, m: int, n_stages: int = 0) -> _Layout:
    """The positions of the unknowns and equations of N = ``n`` steps (cached: the layout
    and its index arrays are read-only and shared by the solves of one size)."""
    junctions = np.arange(arity - 1, n - arity)
    terms = np.arange(0, n - arity + 1)
    junctions.flags.writeable = terms.flags.writeable = False
    delta_index, lam_index, zeta_index, k = {}, {}, {}, 0
    term_set = set(terms.tolist())
    for p in range(n + 1):  # interleave by position: λ_p, ζ_p, then δ_p
        if m and p in term_set:
            lam_index[p] = k
            k += m
        if n_stages and p in term_set:
            zeta_index[p] = k
            k += n_stages
        if arity - 1 <= p < n - arity:
            delta_index[p] = k
            k += rank
    return _Layout(junctions, terms, delta_index, lam_index, k, zeta_index)


def _multiplier_rows(lay: _Layout, m: int) -> np.ndarray:
    """The rows of the multipliers λ (and of the constraints Φ), in layout order."""
    if not m or not lay.lam_index:
        return np.zeros(0, int)
    return (np.array(list(lay.lam_index.values()))[:, None] + np.arange(m)).ravel()


def _variation_rows(lay: _Layout, r: int) -> np.ndarray:
    """The rows of the variations δ (and of the junction residuals), in layout order."""
    if not lay.delta_index:
        return np.zeros(0, int)
    return (np.array(list(lay.delta_index.values()))[:, None] + np.arange(r)).ravel()

