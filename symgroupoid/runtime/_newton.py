"""The Newton iterations of the initial-state solves, shared by every solve of that kind.

- :func:`newton` — a square system F(z) = 0 with its exact Jacobian (from a momentum, first
  and second order): z ← z − J⁻¹F, stopped by :func:`converged`;
- :func:`gauss_newton` — an underdetermined system φ(x) = 0 (m ≤ n unknowns) with minimum-norm
  steps x ← x − J⁺φ (the projections of an initial state onto the constraints): to first
  order the orthogonal projection of the start onto {φ = 0} in the chart, stopped at the
  rounding floor (no further halving of |φ|∞ once it is below 1e-8).

The step kernel's Newton (C and its NumPy twin) and the boundary-value solver's are other
algorithms (a rounding-floor test per equation, trust regions, line searches on a merit
function) and keep their own loops.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .._errors import NewtonDivergenceError, SingularJacobianError

#: a Newton update at most this size (relative to the iterate) that is not 10 times smaller
#: than the one before it is rounding: quadratic convergence has ended at a solution
ROUNDING_UPDATE = 1e-9

#: the residual size (max norm) below which a Gauss–Newton projection has found a zero
PROJECTED = 1e-8


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


def gauss_newton(residual: Callable[[np.ndarray], tuple], x: np.ndarray,
                 max_iterations: int) -> tuple[tuple | None, list[float], np.ndarray]:
    """Minimum-norm Gauss–Newton on φ(x) = 0 from ``x`` (``residual(x) -> (φ, J, *extra)``,
    J of shape (m, n)).  Returns ``(best, history, x)``: ``best`` = (|φ|∞, x, *extra) of
    the iterate with the smallest residual, or None when the first values are not finite,
    the residual sizes seen, and the last iterate.  The caller accepts ``best`` when its
    residual is below :data:`PROJECTED` (otherwise no zero is near the start)."""
    best, history = None, []
    for _ in range(max_iterations):
        phi, J, *extra = residual(x)
        norm = float(np.max(np.abs(phi))) if len(phi) else 0.0
        if not np.isfinite(norm) or not np.isfinite(J).all():
            break
        history.append(norm)
        if best is None or norm < best[0]:
            best = (norm, x, *extra)
        # stop at the rounding floor: no further halving of the residual
        if norm == 0.0 or (len(history) > 2 and norm > 0.5 * min(history[:-1])
                           and norm < PROJECTED):
            break
        x = x - np.linalg.lstsq(J.reshape(len(phi), len(x)), phi, rcond=None)[0]
    return best, history, x
