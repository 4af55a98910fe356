"""The globalised path: inertia-corrected Newton (SQP) steps on the action.

K, the Jacobian of the necessary conditions, is the KKT matrix of min Σ L s.t. Φ = 0: the
Hessian of the Lagrangian Σ [L + λ·Φ] in the variations δ, bordered by the constraint
gradients.  Each step solves with K + μ·I_δ, μ ≥ 0 the least regularisation that gives it
the inertia (n_δ, n_λ, 0) (its δ-block positive definite on the tangent space of the
constraints), and is backtracked on the exact ℓ₁ penalty function φ_ν = Σ L + ν‖Φ‖₁
(Nocedal–Wright §18.3; Ipopt's inertia correction): a descent method on the action, as an
interior-point NLP solver is, where the fast path seeks any root of F.
"""

from __future__ import annotations

import numpy as np

from ..._errors import BoundaryValueDivergenceError, SingularJacobianError
from .._banded import banded_inertia
from ._assembly import _Assembled
from ._inertia import _bordering
from ._layout import _multiplier_rows, _variation_rows
from ._linear import _apply
from ._state import _Problem, _SolverState, _Step

#: at most this many trial regularisations μ per globalised iteration
MAX_CORRECTIONS = 40


def _globalised_after(state: _SolverState, starts: list, why: str) -> None:
    """The globalised iteration from each of ``starts`` (arrows, λ) in turn until one
    converges; the next start is tried after a line search without decrease, a non-finite
    residual or a singular Jacobian, not after a stall (the update fell below ``tol_step``
    or stopped changing the iterate: the caller's criterion, or the rounding floor) nor at
    the iteration cap, which counts every start.  The last one's errors name why the fast
    path ended too."""
    for k, start in enumerate(starts):
        state.at_floor = 0
        try:
            return _globalised(state, *start)
        except (BoundaryValueDivergenceError, SingularJacobianError) as exc:
            if k + 1 < len(starts) and not state.stalled and \
                    state.iterations < state.problem.max_iterations:
                why = (f"{why}; from its best iterate, the globalised iteration "
                       f"{_first_line(exc)}")
                continue
            same = str(exc.args[0]) in why  # (the fast path's error, word for word)
            after = ("the Newton fast path ended the same way" if same
                     else f"after the Newton fast path {why}")
            exc.args = (f"{exc.args[0]} ({after})",) + exc.args[1:]
            raise


def _first_line(exc: Exception) -> str:
    """What went wrong, in the words of ``exc`` without its owner prefix or its numbers."""
    text = str(exc.args[0]) if exc.args else type(exc).__name__
    text = text.split(": ", 1)[-1]
    return text.split(";", 1)[0]


def _globalised(state: _SolverState, arrows, lam) -> None:
    """Inertia-corrected Newton (SQP) steps from (arrows, λ) with a backtracking search on
    the ℓ₁ merit function φ_ν = Σ L + ν‖Φ‖₁: every step decreases φ_ν, so the iteration
    descends the action (seeks a local minimum of Σ L on Φ = 0, as an interior-point NLP
    solver does) instead of any root of F; near a minimum μ = 0 and the full Newton step is
    taken whenever it decreases |F|₂ too, which keeps the convergence quadratic."""
    state.methods.append("inertia-corrected Newton")
    state.move_to(arrows, lam)
    if not state.assembled.finite():
        raise state.divergence("met a non-finite residual", np.inf)
    nu, mu_last = 0.0, 0.0
    lam_rows = _multiplier_rows(state.problem.lay, state.problem.m)
    while True:
        state.record()
        if state.converged():
            return
        excess = state.excess()
        state.check_budget(excess)
        dz, mu, curvature = _convexified_direction(state, mu_last)
        mu_last = mu
        g = _gradient_of_cost(state)
        violation = float(np.abs(state.assembled.F[lam_rows]).sum())
        lam_next = np.abs(_current_multipliers(state) + dz)[lam_rows]
        nu = max(nu, 1.1 * float(np.max(lam_next, initial=0.0)))
        if violation > 0:  # Nocedal–Wright (18.36), ρ = 0.1
            nu = max(nu, (float(g @ dz) + max(curvature, 0.0) / 2) / (0.9 * violation))
        slope = float(g @ dz) - nu * violation
        step = _merit_search(state, dz, nu, slope, newton=mu == 0.0)
        if step is None:
            raise state.divergence("found no decrease of the merit function Σ L + ν‖Φ‖₁ "
                                   "along the inertia-corrected Newton direction (line search)",
                                   excess)
        state.take(step)


def _convexified_direction(state: _SolverState, mu_last: float):
    """The step of the globalised iteration and its regularisation μ ≥ 0.

    With K the Jacobian (the Hessian of the Lagrangian Σ [L + λ·Φ] in the variations δ,
    bordered by the constraint gradients: the KKT matrix of min Σ L s.t. Φ = 0), K + μ·I_δ
    is required to have the inertia (n_δ, n_λ, 0) — then its δ-block is positive definite on
    the tangent space of the constraints, and the step is a descent direction of the merit
    function (Nocedal–Wright §18.3; Ipopt's inertia correction).  μ = 0 when K itself has it
    (the step is then Newton's); else μ starts at max(μ_min, μ_last/3) and grows ×8.  A zero
    eigenvalue (dependent constraint gradients) also puts −δ_c·I on the multiplier block.
    Returns (dz, μ, pᵀ(H + μI)p) with p the δ part of dz."""
    lay, assembled = state.problem.lay, state.assembled
    dvars, lvars = _variation_rows(lay, state.problem.r), _multiplier_rows(lay, state.problem.m)
    n_lam, (plus, minus) = _bordering(state)
    expected = (len(dvars) + plus, n_lam + minus, 0)
    diag = assembled.rows == assembled.cols
    scale = float(np.mean(np.abs(assembled.vals[diag]))) if diag.any() else 1.0
    mu, delta_c = 0.0, 0.0
    for _ in range(MAX_CORRECTIONS):
        rows = np.concatenate([assembled.rows, dvars, lvars])
        cols = np.concatenate([assembled.cols, dvars, lvars])
        vals = np.concatenate([assembled.vals, np.full(len(dvars), mu),
                               np.full(len(lvars), -delta_c)])
        inertia = banded_inertia(rows, cols, vals, lay.size)
        if inertia is not None and tuple(inertia) == expected:
            dz = state.newton_direction(rows, cols, vals)
            p = np.zeros(lay.size)
            p[dvars] = dz[dvars]
            return dz, mu, float(np.sum(vals * p[rows] * p[cols]))
        if inertia is not None and inertia.zero and len(lvars):
            delta_c = 1e-8 * scale
        mu = max(1e-8 * scale, mu_last / 3.0) if mu == 0.0 else 8.0 * mu
    raise state.singular()


def _current_multipliers(state: _SolverState) -> np.ndarray:
    """The iterate's multipliers λ placed in their rows of the unknowns (zero elsewhere)."""
    lay, m = state.problem.lay, state.problem.m
    z = np.zeros(lay.size)
    for t, k in lay.lam_index.items():
        z[k:k + m] = state.lam[t]
    return z


def _gradient_of_cost(state: _SolverState) -> np.ndarray:
    """∇S in the unknowns (zero in the multiplier rows): the junction residuals are ∂/∂δ of
    Σ [L + λ·Φ], so ∇S = F_δ − (∂F_δ/∂λ)·λ."""
    lay, assembled = state.problem.lay, state.assembled
    z = _current_multipliers(state)
    g = assembled.F - _apply(assembled.rows, assembled.cols, assembled.vals, z, lay.size)
    g[_multiplier_rows(lay, state.problem.m)] = 0.0
    return g


def _merit(problem: _Problem, arrows, assembled: _Assembled, nu: float) -> float:
    """φ_ν = Σ L + ν·‖Φ‖₁ (the exact ℓ₁ penalty function)."""
    phi = assembled.F[_multiplier_rows(problem.lay, problem.m)]
    return problem.cost(arrows, problem.p) + nu * float(np.abs(phi).sum())


def _merit_search(state: _SolverState, dz, nu: float, slope: float, newton: bool
                  ) -> _Step | None:
    """Backtracking until φ_ν decreases by the Armijo fraction 10⁻⁴·t·|slope|; a full
    unregularised Newton step is also taken when it decreases |F|₂² (near a solution, where
    the merit function would reject it: the Maratos effect), and any step that lands within
    the rounding floor.  None when no step length gives a decrease."""
    problem = state.problem
    phi0 = _merit(problem, state.arrows, state.assembled, nu)
    F = state.assembled.F
    f0 = float(F @ F)  # above |F| ≈ 1e154: inf (backtrack halves such trials)

    def accept(length: float, arrows, trial: _Assembled, f: float) -> bool:
        accepted = slope < 0 and \
            _merit(problem, arrows, trial, nu) <= phi0 + 1e-4 * length * slope
        if newton and length == 1.0:
            accepted = accepted or f <= (1 - 1e-4) * f0
        return accepted

    return state.backtrack(dz, accept)
