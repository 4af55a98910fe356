"""The internal stages ζ* of arrows, solved from their rows ∂L/∂ζ = 0 (docs/conventions.md
§22): one vectorised Newton iteration over many arrows at once, for every evaluation of a
quantity of a discrete Lagrangian with internal stages (momenta, energy, Noether
quantities), whose value is that of L(g, ζ) at ζ = ζ*(g) by the envelope theorem."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..._errors import DiagnosticsError

_EPS = float(np.finfo(float).eps)

#: a Newton update at most this size (relative to the iterate) that is not 10 times smaller
#: than the one before it is rounding: quadratic convergence has ended at a solution (the
#: rule of the initial-state solves, runtime/_newton.py, and of the stage solves here)
ROUNDING_UPDATE = 1e-9


def solve_stages(rows: Callable, known: np.ndarray, p: np.ndarray, n_stages: int,
                 name: str, max_iterations: int = 50) -> np.ndarray:
    """ζ* at every arrow, shape (n_stages, R): Newton from ζ = 0 on ``rows(known, zeta, p)
    -> (F, J)`` (F the stage rows (n_stages, R), J their Jacobian ∂F/∂ζ row-major
    (n_stages², R)), all arrows at once (``known`` (n, R)).  An arrow is solved, and kept
    as it is from then on, at an update at the rounding level of ζ, or one that is rounding
    by the rule of the initial-state solves: below :data:`ROUNDING_UPDATE` relative and no
    longer shrinking (the interior multipliers of a constrained Galerkin arrow,
    docs/conventions.md §22, are found from rows of size 1/h and stall some tens of ulps
    from their root); a
    :class:`DiagnosticsError` where it does not converge (a singular Jacobian, a non-finite
    iterate, or no convergence in ``max_iterations``): never values at a non-solution."""
    R = known.shape[1]
    zeta = np.zeros((n_stages, R))
    before = np.full(R, np.inf)
    done = np.zeros(R, dtype=bool)  # arrows whose stages are solved: kept as they are
    for _ in range(max_iterations):
        with np.errstate(all="ignore"):
            F, J = rows(known, zeta, p)
        F = np.broadcast_to(np.asarray(F, float), (n_stages, R))
        J = np.broadcast_to(np.asarray(J, float), (n_stages * n_stages, R))
        try:
            delta = np.linalg.solve(J.reshape(n_stages, n_stages, R).transpose(2, 0, 1),
                                    F.T[..., None])[..., 0].T
        except np.linalg.LinAlgError:
            break
        delta = np.where(done, 0.0, delta)
        zeta = zeta - delta
        if not np.isfinite(zeta).all():
            break
        size = (np.abs(delta) / np.maximum(1.0, np.abs(zeta))).max(axis=0, initial=0.0)
        # each arrow stops on its own: an update at rounding level in one iteration, on
        # every arrow at once, grows ever rarer with the number of arrows (a run of 5,000
        # constrained arrows, whose multipliers stall tens of ulps from their root, never
        # had one)
        done |= (size <= 8 * _EPS) | ((size <= ROUNDING_UPDATE) & (size > 0.1 * before))
        if done.all():
            return zeta
        before = size
    raise DiagnosticsError(f"{name}: the internal stages of some arrow could not be solved "
                           f"(∂L/∂ζ = 0 has no root near ζ = 0 there, docs/conventions.md "
                           f"§22)")


__all__ = ["ROUNDING_UPDATE", "solve_stages"]
