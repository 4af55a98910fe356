"""The Newton iterations of the initial-state solves, shared by every solve of that kind.

- :func:`newton` — a square system F(z) = 0 with its exact Jacobian (from a momentum, first
  and second order): z ← z − J⁻¹F, stopped by :func:`converged`;
- the projections of an initial state onto the constraints use the minimum-norm Gauss–Newton
  :func:`symgroupoid.equations.gauss_newton` of the equations layer, which also builds
  random arrows on a holonomic constraint set (the Noether check of docs/conventions.md §22).

The step kernel's Newton (C and its NumPy twin) and the boundary-value solver's are other
algorithms (a rounding-floor test per equation, trust regions, line searches on a merit
function) and keep their own loops.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import NewtonDivergenceError, SingularJacobianError
from ..equations import ROUNDING_UPDATE


def converged(dz: np.ndarray, before: float, z: np.ndarray, tol: float) -> bool:
    """Whether Newton has converged after the update ``dz`` (the one before it had size
    ``before``): the update is below ``tol`` relative to the iterate, or it is rounding —
    below ROUNDING_UPDATE relative and no longer shrinking (a badly scaled system, e.g.
    rows of size 1/h³ next to constraint rows of size 1, stalls above ``tol``)."""
    size, scale = float(np.abs(dz).max()), 1.0 + float(np.abs(z).max())
    return size <= tol * scale or (size <= ROUNDING_UPDATE * scale and size > 0.1 * before)


def newton(residual: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]], z: np.ndarray,
           tol: float, max_iterations: int, owner: str, what: str, singular: str,
           exhausted: str) -> np.ndarray:
    """The root of F near ``z`` (``residual(z) -> (F, J)``, J square), by Newton's method.

    Non-finite values are a :class:`NewtonDivergenceError` (``what``: the solve, e.g.
    "solving for the initial state from the momentum"), a singular J a
    :class:`SingularJacobianError` with the message ``singular``, no convergence in
    ``max_iterations`` a :class:`NewtonDivergenceError` (``exhausted``: what was not found);
    each carries the last iterate."""
    previous, F = np.inf, np.zeros(0)
    for _ in range(max_iterations):
        F, J = residual(z)
        if not (np.isfinite(F).all() and np.isfinite(J).all()):
            raise NewtonDivergenceError(f"{owner}: non-finite values {what}", step=0,
                                        residual_norm=_norm(F), iterate=z)
        try:
            dz = np.linalg.solve(J, F)
        except np.linalg.LinAlgError:
            raise SingularJacobianError(f"{owner}: {singular}", step=0,
                                        residual_norm=_norm(F), iterate=z) from None
        z = z - dz
        if converged(dz, previous, z, tol):
            return z
        previous = float(np.abs(dz).max())
    raise NewtonDivergenceError(f"{owner}: {exhausted} in {max_iterations} Newton iterations",
                                step=0, residual_norm=_norm(F), iterate=z)


def _norm(F: np.ndarray) -> float:
    return float(np.abs(F).max()) if F.size else 0.0
