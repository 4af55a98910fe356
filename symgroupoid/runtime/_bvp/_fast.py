"""The fast path: structured Newton on the necessary conditions, backtracking on |F|₂².

From a good initial path it converges quadratically, one banded solve and (near a solution)
one assembly per iteration.  It hands over to the globalised iteration (:class:`_Handover`)
when its line search finds no decrease, when it takes MAX_DAMPED damped steps in a row (far
from a solution, where a descent method on the action does better), or at a singular
Jacobian; the handover carries its last iterates, and :func:`_restart_points` says where
the globalised iteration starts.
"""

from __future__ import annotations

import collections
from collections.abc import Sequence

import numpy as np

from ..._errors import SingularJacobianError
from ._layout import _multiplier_rows
from ._state import _Iterate, _SolverState, _Step

#: the fast path hands over to the globalised iteration after this many consecutive damped
#: Newton steps (line-search length at most DAMPED_LENGTH)
MAX_DAMPED = 4
DAMPED_LENGTH = 0.25

#: the fast path keeps its last this many iterates as restart points for the globalised
#: iteration (with the initial path: :func:`_restart_points`)
RESTART_CANDIDATES = 8


class _Handover(Exception):
    """The fast path gives up (no decrease, or damped steps only): the reason, and its last
    iterates (arrows, λ, assembled system), oldest first."""

    def __init__(self, why: str, iterates: Sequence = ()):
        super().__init__(why)
        self.iterates = list(iterates)


def _fast_newton(state: _SolverState) -> None:
    """Structured Newton on the necessary conditions from the iterate of ``state``, until it
    converges there.  Raises :class:`_Handover` when the line search finds no decrease,
    MAX_DAMPED consecutive steps were damped (far from a solution, where the globalised
    iteration does better) or the Jacobian is singular (constraints that the boundary data
    make dependent, whose multipliers the globalised iteration regularises)."""
    state.methods.append("Newton")
    damped = 0
    recent = collections.deque(maxlen=RESTART_CANDIDATES)
    while True:
        state.record()
        recent.append(state.iterate)
        if state.converged():
            return
        excess = state.excess()
        state.check_budget(excess)
        try:
            dz = state.newton_direction()
        except SingularJacobianError as exc:  # e.g. constraints made dependent by the ends
            raise _Handover(f"a singular Jacobian ({exc})", recent) from exc
        step = _line_search(state, dz)
        if step is None:
            raise _Handover("found no decrease of |F| along the Newton direction (line search)",
                            recent)
        state.take(step)
        damped = damped + 1 if step.length <= DAMPED_LENGTH else 0
        if damped >= MAX_DAMPED and not state.stalled:
            recent.append(state.iterate)
            raise _Handover(f"{MAX_DAMPED} damped Newton steps in a row", recent)


def _line_search(state: _SolverState, dz: np.ndarray) -> _Step | None:
    """Backtracking on |F|₂² from the iterate of ``state``: the full Newton step when it
    decreases the residual enough (Armijo: by the fraction 10⁻⁴·t of it, t the step length;
    always so near a solution, where convergence stays quadratic), else the step halved, at
    most MAX_HALVINGS times.  Backtracking stops at the rounding floor: a trial whose |F|₂²
    is within the floor's (Σ (ROUNDING_FACTOR·floor_i)², where the comparison of two
    residuals is rounding noise) is taken at once, and the convergence test decides.

    Returns the accepted :class:`_Step`, or None when no step length gave a decrease with
    finite values: the caller then does not carry on from
    an iterate that is worse than the last (a Newton direction that is not a descent
    direction of |F|₂² means the Jacobian is wrong or the values are not smooth there, e.g.
    an arrow near the chart's cut locus).
    """
    F = state.assembled.F
    f0 = float(F @ F)  # above |F| ≈ 1e154: inf (backtrack halves such trials)
    return state.backtrack(dz, lambda length, arrows, trial, f: f <= (1 - 1e-4 * length) * f0)


def _restart_points(state: _SolverState, initial: _Iterate, iterates: Sequence) -> list:
    """Where the globalised iteration starts after a handover, in the order to try: the
    fast path's iterate of least ℓ₁ merit φ_ν = Σ L + ν‖Φ‖₁ (ν = 1.1·max|λ| over the
    candidates, the globalised iteration's own first weight) when it is below the initial
    path's, then the initial path (the fallback: a descent from there reaches the minimum
    the initial path leads to even when the fast path wandered off towards another
    stationary point)."""
    problem = state.problem
    lam_rows = _multiplier_rows(problem.lay, problem.m)
    nu = 1.1 * max((float(np.max(np.abs(lam), initial=0.0)) for _, lam, _ in iterates),
                   default=0.0)

    def merit(point) -> float:
        arrows, _, assembled = point
        value = problem.cost(arrows, problem.p) + nu * float(np.abs(assembled.F[lam_rows]).sum())
        return value if np.isfinite(value) else np.inf

    best = min(iterates, key=merit, default=None)
    if best is None or merit(best) >= merit(initial):
        return [initial[:2]]
    return [best[:2], initial[:2]]
