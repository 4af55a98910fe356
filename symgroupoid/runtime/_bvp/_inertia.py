"""The second-order condition: the inertia of the reduced Hessian at a solution.

The Jacobian K of the necessary conditions is the KKT matrix of min Σ L s.t. Φ = 0; its
inertia, from a banded LDLᵀ (runtime/_banded.py), gives that of the Hessian of the
Lagrangian Σ [L + λ·Φ] on the admissible variations tangent to the constraints (Gould
1985), hence whether a solution is a local minimum, and steers the inertia correction of
the globalised path.
"""

from __future__ import annotations

import numpy as np

from .._banded import Inertia, banded_inertia
from ._layout import _multiplier_rows
from ._state import _Problem, _SolverState


def _reduced_inertia(state: _SolverState) -> Inertia | None:
    """The inertia of the Hessian of the Lagrangian Σ [L + λ·Φ] restricted to the admissible
    variations tangent to the constraints, from the KKT matrix K (the symmetric part of the
    Jacobian at the iterate of ``state``, :func:`banded_inertia`): when K is nonsingular the
    constraint gradients have full rank and inertia(K) = inertia(ZᵀHZ) + (n_λ, n_λ, 0) (Z a
    basis of their null space; Gould 1985), so ZᵀHZ has pos(K) − n_λ positive and
    neg(K) − n_λ negative eigenvalues.  None when K is numerically singular (the reduced
    Hessian and the constraint rank are then not determined by the inertia alone)."""
    assembled = state.assembled
    inertia = banded_inertia(assembled.rows, assembled.cols, assembled.vals,
                             state.problem.lay.size)
    n_lam, (plus, minus) = _bordering(state)
    if inertia is None or inertia.zero or inertia.negative < n_lam + minus \
            or inertia.positive < n_lam + plus:
        return None
    return Inertia(inertia.positive - n_lam - plus, inertia.negative - n_lam - minus, 0)


def _inertia_at(system, arrows: np.ndarray, lam: np.ndarray, p: np.ndarray
                ) -> Inertia | None:
    """:func:`_reduced_inertia` at a solution (arrows, λ) of ``system``, its KKT matrix
    assembled there."""
    return _reduced_inertia(_SolverState.at(_Problem.of(system, len(arrows), p), arrows, lam))


def _bordering(state: _SolverState) -> tuple[int, tuple[int, int]]:
    """The multiplier rows that border the Hessian (n_λ), and the signs of those that are
    decoupled — a row and column with nothing but a diagonal entry d, such as a multiplier
    fixed by a boundary condition (row λ = 0): each adds one eigenvalue of the sign of d,
    not a ± pair."""
    lay, assembled = state.problem.lay, state.assembled
    lam_rows = _multiplier_rows(lay, state.problem.m)
    if not len(lam_rows):
        return 0, (0, 0)
    rows, cols, vals = assembled.rows, assembled.cols, assembled.vals
    off = (rows != cols) & (vals != 0)
    touched = np.zeros(lay.size, bool)
    touched[rows[off]] = touched[cols[off]] = True
    alone = lam_rows[~touched[lam_rows]]
    diag = np.bincount(rows[~off & (rows == cols)], weights=vals[~off & (rows == cols)],
                       minlength=lay.size)[alone]
    return len(lam_rows) - len(alone), (int((diag > 0).sum()), int((diag < 0).sum()))


def _is_minimum(inertia: Inertia | None) -> bool:
    return inertia is not None and inertia.negative == 0


def _describe(inertia: Inertia | None) -> str:
    if inertia is None:
        return "degenerate: the reduced Hessian is singular to rounding"
    if inertia.negative == 0:
        return "a strict local minimum"
    return (f"a saddle: the reduced Hessian has {inertia.negative} negative "
            f"eigenvalue{'s' if inertia.negative > 1 else ''}")
