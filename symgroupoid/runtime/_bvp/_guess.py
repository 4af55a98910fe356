"""Boundary data, the initial path and its checks.

The boundary data are checked as states are (runtime/_validate.py) before anything is
assembled.  The default initial path follows geodesics (exp(s·log g) on a Lie group), so a
half-turn between the ends is split into N small turns instead of meeting the cut locus of
the Cayley chart; a guess is checked to be composable, to join the boundary configurations
and (second order) to keep the fixed first and last arrows; an initial path with a
half-turn raises a :class:`CutLocusError`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..._arguments import ndim, real_array
from ..._errors import CutLocusError, DomainError, InputTypeError, NotComposableError, ShapeError
from .._validate import arrow as checked_arrow
from .._validate import configuration
from ._kernels import _maps

#: an arrow with cos²(θ/2) ≤ this for a rotation block (θ its largest rotation angle) is a
#: half-turn to rounding, on the cut locus of the Cayley chart and of the logarithm
CUT_LOCUS_TOLERANCE = 1e-12


def interpolate_arrows(G, total: Sequence, steps: int, maps=None) -> np.ndarray:
    """N arrows g_k = P_{k−1}⁻¹ P_k whose product is ``total``: P_k = P(k/N) on the geodesic
    (``G.geodesic``) from the identity ε(α(total)) to ``total`` (on a Lie group
    g_k = exp(log(total)/N), so a half-turn is split into N turns by π/N and the guess stays
    off the cut locus of the Cayley chart)."""
    total = np.asarray(total, float)
    P = G.geodesic(total, np.arange(steps + 1) / steps)
    P[0] = np.asarray(G.identity(tuple(G.source(total))), float)
    P[-1] = total
    maps = maps or _maps(G)  # (a groupoid whose maps use parameters: the caller's, bound)
    return maps.multiply(maps.inverse(P[:-1]), P[1:])


# --- boundary data -----------------------------------------------------------------------------

@dataclass
class _Boundary:
    """Validated boundary data: the configurations, the arrow from the first to the last one,
    and (second order) the fixed first and last arrows and the arrow between them."""

    configurations: tuple
    total: np.ndarray
    first: np.ndarray | None = None
    last: np.ndarray | None = None
    inner: np.ndarray | None = None


def _boundary(system, a: int, start, end) -> _Boundary:
    """``start``/``end`` checked as states are (:func:`configuration`), before any solve."""
    G, owner = system.groupoid, system.name
    if a == 1:
        c0 = configuration(G, start, "start", owner=owner)
        cn = configuration(G, end, "end", owner=owner)
        return _Boundary((c0, cn), np.asarray(G.arrow_between(c0, cn), float))
    pairs = []
    for label, value in (("start", start), ("end", end)):
        if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) \
                or (isinstance(value, np.ndarray) and value.ndim == 0) or len(value) != 2:
            raise ShapeError(f"{owner}: second-order boundary data are two configurations at "
                             f"each end: start=(c0, c1), end=(cN-1, cN); {label} is not a pair")
        pairs.append(tuple(configuration(G, c, f"{label}[{i}]", owner=owner)
                           for i, c in enumerate(value)))
    (c0, c1), (cn1, cn) = pairs
    arrow_of = lambda x, y: np.asarray(G.arrow_between(x, y), float)  # noqa: E731
    return _Boundary((c0, c1, cn1, cn), arrow_of(c0, cn), arrow_of(c0, c1), arrow_of(cn1, cn),
                     arrow_of(c1, cn1))


def _boundary_system(step_equations):
    """The system behind the first argument of :func:`solve_boundary_value` (a system, or
    its step equations), or an :class:`InputTypeError` naming what was given."""
    # a system, its step equations, or a simulator of them (its ``equations``)
    system = getattr(step_equations, "equations", step_equations)
    system = getattr(system, "system", system)
    if not all(hasattr(system, a) for a in ("_fs", "groupoid", "name", "parameters")):
        raise InputTypeError(
            f"solve_boundary_value: the first argument must be a system (DiscreteSystem, "
            f"SecondOrderSystem, …) or its step equations (system.euler_lagrange()), got "
            f"{type(step_equations).__name__}")
    return system


def _split_guess(guess, steps: int):
    """(arrows, multipliers or None) of a guess: an (N, arrow_dim) table of arrows, or the
    pair ``(arrows, multipliers)``, a 2-tuple whose first entry is itself a table (a tuple
    of N arrows is arrows)."""
    if isinstance(guess, tuple) and len(guess) == 2 and ndim(guess[0]) == 2:
        return guess
    return guess, None


def _initial(system, a: int, m: int, data: _Boundary, steps: int, guess, maps=None):
    """The initial arrows and multipliers: ``guess`` (checked) or the geodesic
    interpolation with zero multipliers."""
    G, owner = system.groupoid, system.name
    n_terms = steps - a + 1
    if guess is None:
        if a == 1:
            return interpolate_arrows(G, data.total, steps, maps), np.zeros((n_terms, m))
        inner = interpolate_arrows(G, data.inner, steps - 2, maps)
        return np.vstack([data.first, inner, data.last]), np.zeros((n_terms, m))
    arrows, lam = _split_guess(guess, steps)
    arrows = real_array(arrows, "guess", owner=owner)
    if arrows.shape != (steps, G.arrow_dim):
        raise ShapeError(f"{owner}: guess must have shape ({steps}, {G.arrow_dim}) "
                         f"(one arrow per step), got {arrows.shape}")
    for k, row in enumerate(arrows):
        checked_arrow(G, row, f"guess[{k}]", owner=owner)
    if lam is None:
        lam = np.zeros((n_terms, m))
    else:
        lam = real_array(lam, "the multiplier guess", owner=owner)
        if lam.shape != (n_terms, m):
            raise ShapeError(f"{owner}: multiplier guess must have shape "
                             f"({n_terms}, {m}), got {lam.shape}")
        if not np.isfinite(lam).all():
            raise DomainError(f"{owner}: the multiplier guess has non-finite entries")
    _check_guess(system, arrows, data.total, data.first, data.last, maps)
    return arrows, lam


#: how closely (relative to 1 + |value|, per arrow of the path) a guess must compose and
#: join the boundary configurations: to the rounding of its products.  The solver keeps the
#: guess's ends, so a looser match would move the boundary: a guess stored in single
#: precision (0.4 → 0.4000000060) gave a solution starting 6e-9 away from ``start``
GUESS_ROUNDING = 64 * float(np.finfo(float).eps)


def _close(x, y, tolerance: float) -> bool:
    x, y = np.asarray(x, float), np.asarray(y, float)
    return bool(np.all(np.abs(x - y) <= tolerance * (1.0 + np.maximum(np.abs(x), np.abs(y)))))


def _check_guess(system, arrows, total, first, last, maps=None):
    G = system.groupoid
    maps = maps or _maps(G)
    for k in range(1, len(arrows)):
        if not _close(G.target(arrows[k - 1]), G.source(arrows[k]), GUESS_ROUNDING):
            raise NotComposableError(f"{system.name}: guess arrows {k - 1} and {k} are not "
                                     "composable (β(g_{k-1}) ≠ α(g_k))")
    product = arrows[0:1]
    for k in range(1, len(arrows)):
        product = maps.multiply(product, arrows[k:k + 1])
    if not _close(product[0], total, GUESS_ROUNDING * len(arrows)):
        raise NotComposableError(f"{system.name}: the guess does not join the boundary "
                                 "configurations to rounding (its product differs from "
                                 "start⁻¹·end; the solution keeps the guess's ends)")
    if first is not None and not (np.allclose(arrows[0], first) and
                                  np.allclose(arrows[-1], last)):
        raise ShapeError(f"{system.name}: a second-order guess must keep the fixed first and "
                         "last arrows")


# --- the cut locus -----------------------------------------------------------------------------

def _half_turns(G, arrows: np.ndarray) -> list[tuple[int, str, float]]:
    """(arrow index, part name, det(I + R)/2ⁿ) of every matrix part of ``arrows`` whose
    rotation block R is a half-turn to rounding: det(I + R)/2ⁿ = Π cos²(θ_i/2) over the
    rotation angles θ_i (SO(3): cos²(θ/2)) vanishes exactly on the cut locus of the Cayley
    chart cay⁻¹(R) = 2(R − I)(R + I)⁻¹, which is also where the logarithm is not unique."""
    out = []
    for start, group in G.matrix_parts():
        n = group.n - 1 if group.affine else group.n
        R = group.numeric_matrices(arrows[:, start:start + group.arrow_dim])[:, :n, :n]
        closeness = np.abs(np.linalg.det(np.eye(n) + R)) / 2.0 ** n
        out += [(int(k), group.symbol_name, float(closeness[k]))
                for k in np.flatnonzero(closeness <= CUT_LOCUS_TOLERANCE)]
    return sorted(out)


def _check_cut_locus(system, arrows: np.ndarray, what: str) -> None:
    """A :class:`CutLocusError` naming the arrows of ``arrows`` that are half-turns."""
    bad = _half_turns(system.groupoid, arrows)
    if bad:
        listing = ", ".join(f"arrows[{k}] (its {name!r} part, det(I + R)/2ⁿ = {c:.1e})"
                            for k, name, c in bad[:6])
        verb = "is a half-turn" if len(bad) == 1 else "are half-turns"
        raise CutLocusError(
            f"{system.name}: {what} {listing} {verb}, on the cut locus of the Cayley chart "
            f"and of the logarithm, where "
            f"Lagrangians and constraints written in these charts are not defined; use a "
            f"guess that avoids half-turns (the default geodesic guess does) or more steps",
            arrows=tuple(k for k, _, _ in bad), iterate=arrows)

