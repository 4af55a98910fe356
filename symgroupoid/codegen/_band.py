"""The band order of a step's Jacobian: a reordering of its unknowns (and equations) that
makes the Jacobian banded, found from the program's sparsity, for the stepper's band LU.

A chain written in maximal coordinates with holonomic joint constraints has a Jacobian in
KKT form, [[H, Aᵀ], [A, 0]], whose couplings run between neighbouring bodies only; in the
order (x₁, y₁, λ₁, x₂, y₂, λ₂, …) it is banded with a small bandwidth, and its LU costs
O(n·kl·(kl + ku)) instead of O(n³).  :func:`band_order` finds such an order with the reverse
Cuthill–McKee ordering (Cuthill & McKee 1969; George & Liu, *Computer Solution of Large
Sparse Positive Definite Systems*, 1981, §4.3) of the symmetrised sparsity pattern, started
from a pseudo-peripheral node (George & Liu's algorithm), and keeps it only where the band
is narrow enough to win (:data:`BAND_WIDTH_FRACTION`).  The same order permutes rows and
columns, so the diagonal stays on the diagonal.  Deterministic: ties are broken by index.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from ..stepper import LU_PANEL_FROM, BandOrder
from ._checks import step_argument
from ._time import time_layout

#: a band order is used when the band storage's row, 2·kl + ku + 1, is at most this
#: fraction of the unknowns (the band LU then does less than a tenth of the dense work)
BAND_WIDTH_FRACTION = 1 / 4


def jacobian_pattern(step) -> np.ndarray:
    """The structural nonzeros of the step's Jacobian (n × n booleans): entry (i, j) is
    False where the program's ``J`` output is the graph's constant zero."""
    program = step_argument(step, "jacobian_pattern").program
    n = len(step.unknowns)
    zero = program.graph.zero
    return np.array([node != zero for node in program.outputs["J"]], dtype=bool).reshape(n, n)


def _pseudo_peripheral(adjacency: list[list[int]], start: int, allowed: set[int]) -> int:
    """A node of large eccentricity in ``start``'s component (George & Liu): from ``start``,
    repeatedly move to a node of least degree in the last BFS level while the number of
    levels grows."""
    node, depth = start, -1
    while True:
        levels = _levels(adjacency, node, allowed)
        if len(levels) <= depth:
            return node
        depth = len(levels)
        node = min(levels[-1], key=lambda v: (len(adjacency[v]), v))


def _levels(adjacency: list[list[int]], root: int, allowed: set[int]) -> list[list[int]]:
    seen, levels, frontier = {root}, [], [root]
    while frontier:
        levels.append(frontier)
        following = []
        for v in frontier:
            for w in adjacency[v]:
                if w in allowed and w not in seen:
                    seen.add(w)
                    following.append(w)
        frontier = following
    return levels


def reverse_cuthill_mckee(pattern: np.ndarray) -> list[int]:
    """The reverse Cuthill–McKee order of the symmetrised ``pattern`` (every component,
    each from a pseudo-peripheral node; neighbours by increasing degree, then index)."""
    n = len(pattern)
    symmetric = pattern | pattern.T
    np.fill_diagonal(symmetric, False)
    adjacency = [sorted(np.flatnonzero(row).tolist()) for row in symmetric]
    degree = [len(a) for a in adjacency]
    order: list[int] = []
    placed = [False] * n
    for first in sorted(range(n), key=lambda v: (degree[v], v)):
        if placed[first]:
            continue
        component = {v for level in _levels(adjacency, first, set(range(n))) for v in level}
        root = _pseudo_peripheral(adjacency, first, component)
        placed[root] = True
        queue = deque([root])
        while queue:
            v = queue.popleft()
            order.append(v)
            for w in sorted((w for w in adjacency[v] if not placed[w]),
                            key=lambda w: (degree[w], w)):
                placed[w] = True
                queue.append(w)
    return order[::-1]


def bandwidths(pattern: np.ndarray, order: list[int]) -> tuple[int, int]:
    """(kl, ku) of the pattern reordered by ``order`` (rows and columns)."""
    rows, cols = np.nonzero(pattern[np.ix_(order, order)])
    if not len(rows):
        return 0, 0
    offsets = cols - rows
    return int(max(0, -offsets.min())), int(max(0, offsets.max()))


def band_order(step) -> BandOrder | None:
    """The :class:`~symgroupoid.stepper.BandOrder` the stepper factors ``step``'s Jacobian
    in, or None (dense factors): from ``LU_PANEL_FROM`` unknowns, for a step not on a time
    groupoid (whose fixed-step phase replaces a row of J), when the reverse Cuthill–McKee
    order's band storage is at most :data:`BAND_WIDTH_FRACTION` of the unknowns wide."""
    n = len(step_argument(step, "band_order").unknowns)
    if n < LU_PANEL_FROM or time_layout(step).unknown >= 0:
        return None
    pattern = jacobian_pattern(step)
    order = reverse_cuthill_mckee(pattern)
    kl, ku = bandwidths(pattern, order)
    if 2 * kl + ku + 1 > BAND_WIDTH_FRACTION * n:
        return None
    return BandOrder(kl, ku, tuple(order))


def band_defines(step) -> tuple[dict[str, str], str | None]:
    """The kernel header's band macros: the numbers (``BANDED``, ``BAND_KL``, ``BAND_KU``,
    also declared to cffi) and the initialiser of ``BAND_ORDER`` (C only); none for dense
    factors."""
    band = band_order(step)
    if band is None:
        return {}, None
    return ({"BANDED": "1", "BAND_KL": str(band.kl), "BAND_KU": str(band.ku)},
            "{" + ", ".join(map(str, band.order)) + "}")


__all__ = ["BAND_WIDTH_FRACTION", "band_defines", "band_order", "bandwidths",
           "jacobian_pattern", "reverse_cuthill_mckee"]
