"""The Newton iterations of the initial-state solves, shared by every solve of that kind.

- :func:`newton` — a square system F(z) = 0 with its exact Jacobian (from a momentum, first
  and second order): z ← z − J⁻¹F, stopped by :func:`converged`;
- :func:`continued_newton` — the same root, and where Newton from the guess fails, followed
  from the guess along the homotopy F(z) = (1 − t) F(z₀), t from 0 to 1;
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


#: the least step in t of :func:`continued_newton` before it gives up
CONTINUATION_MIN_STEP = 1.0 / 4096
#: Newton iterations per point of the path (the path's points are near each other)
CONTINUATION_ITERATIONS = 25
#: the most Newton solves along the path (a bound on the time a hopeless case takes)
CONTINUATION_SOLVES = 200


def continued_newton(residual: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                     z: np.ndarray, tol: float, max_iterations: int, owner: str, what: str,
                     singular: str, exhausted: str) -> np.ndarray:
    """:func:`newton`, and where it fails from ``z``, the root followed from ``z`` along

        H(z, t) = F(z) − (1 − t)·F(z₀) = 0,   t from 0 (z₀ is its root) to 1 (F(z) = 0),

    in steps of t that halve when Newton fails from the last point and double when it
    succeeds (at most CONTINUATION_SOLVES solves, steps down to CONTINUATION_MIN_STEP).
    For F = F⁻L(g) − p (an initial state from a momentum) the path's points are the arrows
    of the momenta between the guess's own and p: the first Newton update from zero
    velocity jumps to a velocity of the size of p, which may lie outside the Lagrangian's
    domain (|v| < 1 in L = −√(1 − v²)), where the path moves there in steps.
    The root returned is the end of that path (its last step is a Newton solve of F = 0 at
    ``tol``, as :func:`newton`'s); when both fail, the error of the plain solve is raised,
    its message saying that the continuation failed too."""
    try:
        return newton(residual, z, tol, max_iterations, owner, what, singular, exhausted)
    except (NewtonDivergenceError, SingularJacobianError) as error:
        failure = error
    F0, _ = residual(z)
    if not np.isfinite(F0).all():
        raise failure
    t, dt, point = 0.0, 0.25, np.asarray(z, float).copy()
    for _ in range(CONTINUATION_SOLVES):
        if t >= 1.0:
            return point
        target = min(1.0, t + dt)

        def homotopy(x, shift=(1.0 - target) * F0):
            F, J = residual(x)
            return F - shift, J

        try:
            point = newton(homotopy, point, tol if target == 1.0 else max(tol, 1e-10),
                           CONTINUATION_ITERATIONS, owner, what, singular, exhausted)
            t, dt = target, 2.0 * dt
        except (NewtonDivergenceError, SingularJacobianError):
            dt /= 2.0
            if dt < CONTINUATION_MIN_STEP:
                break
    if t >= 1.0:
        return point
    raise type(failure)(
        f"{failure}; following the root from the guess (t = {t:.4g} of the way) failed too: "
        f"no solution is connected to the guess (the equations may have none here, e.g. a "
        f"momentum outside the range of the Legendre transform)",
        step=failure.step, residual_norm=failure.residual_norm, iterate=failure.iterate)


def _norm(F: np.ndarray) -> float:
    return float(np.abs(F).max()) if F.size else 0.0
