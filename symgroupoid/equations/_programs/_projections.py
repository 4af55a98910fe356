"""Points of a holonomic constraint set M = {ψ = 0} found numerically (docs/conventions.md
§15): the minimum-norm Gauss–Newton that projects an initial state onto the constraints
(:meth:`Simulator.project_initial`), and the arrows of N = G|_M near a given arrow at which
the Noether quantity of a system with internal stages is checked (docs/conventions.md §22).

In the α-fibre chart of a base point q, e(x) = arrow_from(q, τ_q(x)), the residual
ψ(β(e(x))) and its Jacobian in x are those of :func:`source_projection_program`; Gauss–Newton
with minimum-norm steps x ← x − J⁺ψ converges, to first order, to the orthogonal projection
of the start onto {ψ(β(e(x))) = 0} in the chart.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

#: the residual size (max norm) below which a Gauss–Newton projection has found a zero
PROJECTED = 1e-8


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


class RestrictedArrows:
    """Arrows of N = G|_M = {g : ψ(α(g)) = 0 = ψ(β(g))} near given arrows.

    ``residual(x, q, p) -> (ψ(β(e(x))), ∂ψ/∂x)`` with e(x) = arrow_from(q, τ_q(x)) (the
    ``psi`` and ``J`` outputs of :func:`source_projection_program`).  An arrow a is moved in
    two projections: its source onto M along the α-fibre of α(a), from the chart of the
    identity (q′ = β(e(x)), as :meth:`Simulator.project_initial` moves a configuration),
    then its target, the arrow from q′ whose fibre chart y solves ψ(β(arrow_from(q′,
    τ_{q′}(y)))) = 0 from the chart coordinates of a at its own source (on a pair groupoid of
    a vector space: a's increment carried to q′)."""

    def __init__(self, groupoid, residual: Callable, max_iterations: int = 50):
        self.groupoid, self.residual = groupoid, residual
        self.max_iterations = max_iterations

    def _onto(self, q: tuple, x: np.ndarray, p: np.ndarray) -> np.ndarray | None:
        """The chart y near ``x`` with ψ(β(arrow_from(q, τ_q(y)))) = 0, or None."""
        best, _, _ = gauss_newton(lambda y: self.residual(y, q, p), x, self.max_iterations)
        return None if best is None or not best[0] < PROJECTED else best[1]

    def __call__(self, arrow: Sequence, p: np.ndarray) -> tuple | None:
        """The arrow of N near ``arrow`` (numeric coordinates), or None when no point of M
        is near its source or target."""
        G = self.groupoid
        q = tuple(float(v) for v in G.source(tuple(arrow)))
        identity = tuple(G.fibre_of(G.identity(q)))
        x = self._onto(q, np.array(G.fibre_chart_inverse(identity, q), float), p)
        if x is None:
            return None
        on_m = tuple(float(v) for v in G.target(G.numeric_fibre_arrow(q, x)))
        start = G.fibre_chart_inverse(tuple(G.fibre_of(tuple(arrow))), q)
        y = self._onto(on_m, np.array(start, float), p)
        return None if y is None else tuple(float(v) for v in
                                            G.numeric_fibre_arrow(on_m, y))


__all__ = ["PROJECTED", "RestrictedArrows", "gauss_newton"]
