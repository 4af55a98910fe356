"""The continuous limit: a degenerate kinetic energy (docs/conventions.md §19).

At a few points (q, v) the step is evaluated at the state of a small step h, and h·∂F/∂x is
extrapolated to its leading term R₀, minus the velocity Hessian ∂²L/∂v² of the continuous
limit; a rank-deficient R₀ is refused, or warned about when velocity-linear terms make the
step regular along its null directions.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._arguments import caller_level
from .._errors import DegenerateLagrangianWarning, DegenerateSystemError
from ..derivation import SCALES, extrapolate, limit_points
from ._findings import Finding, Layout
from ._sampling import SUPPORT, evaluate_points, numeric, predicted_unknowns

#: cause reported in :attr:`DegenerateSystemError.findings` for a degenerate kinetic energy
DEGENERATE_KINETIC = "degenerate kinetic energy"

_KINETIC_RANK = 1e-10  # singular values of the leading term below this fraction are zero
_GYROSCOPIC = 1e-6     # an order-h⁰ block below this fraction of the step's scale vanishes
_FLOOR = 1e-11         # rows/columns below this fraction of the largest are not rescaled


@dataclass
class LeadingTerms:
    """The step Jacobian at a state of step h near the identity, restricted to the
    constraint directions: h·Yᵀ(∂F/∂x)Z = R₀ + h R₁ + h² R₂ + … (Y ⊥ the constraint forces,
    Z tangent to the constraints).  R₀ = −(the velocity Hessian of the continuous limit) in
    section × chart coordinates; ``left``/``right`` span its null spaces, ``chart`` maps
    the columns of Z back to the step's unknowns."""

    R0: np.ndarray
    R1: np.ndarray
    scale: float
    rank: int
    left: np.ndarray
    right: np.ndarray
    chart: list
    Z: np.ndarray

    @property
    def size(self) -> int:
        return self.R0.shape[1]

    def first_order_regular(self) -> bool:
        """Whether the order-h⁰ block on the null spaces, leftᵀ R₁ right, is invertible."""
        block = self.left.T @ self.R1 @ self.right
        if block.size == 0:
            return False
        sv = np.linalg.svd(block, compute_uv=False)
        return bool(sv[-1] > _GYROSCOPIC * self.scale)


def check_kinetic(step, layout: Layout, time_steps: Sequence) -> None:
    """Refuse (or warn about) a degenerate kinetic energy (docs/conventions.md §19).

    ``time_steps``: the step parameter (the declared one, or those the continuous limit
    identifies; None for a time groupoid's own t₁ − t₀); nothing is checked without one, and
    with several the kinetic energy must be degenerate for each.  At three points (q, v)
    (:func:`~symgroupoid.derivation.limit_points`) the step is evaluated at the state
    g_k = g_h(q, v) with the step at h (on a time groupoid the time row and unknown left out),
    for the scales h of :data:`~symgroupoid.derivation.SCALES`, and h·∂F/∂x is
    extrapolated to its leading term R₀, restricted to the constraint directions.  R₀ is
    minus the velocity Hessian ∂²L/∂v² of the continuous limit: on Q×Q, ∂F/∂q_{k+1} =
    D₁D₂L_d(q_k, q_{k+1}) = −M/h + O(1).  Rank deficient at every point: a
    :class:`DegenerateSystemError` naming the direction, unless the order-h⁰ term (the
    velocity-linear part of L) is invertible on the null directions, which is a
    :class:`DegenerateLagrangianWarning`.
    """
    if step.order != 1 or not time_steps or not numeric(step):
        return
    found = [_degenerate_terms(step, layout, t) for t in time_steps]
    if any(terms is None for terms in found):
        return  # no evidence, or regular with some step
    terms, time_step = found[0], time_steps[0]
    first = terms[0]
    null = first.Z @ first.right
    unknowns = [layout.unknowns[j] for j in first.chart]
    shown = _directions(null, [_velocity_name(u) for u in unknowns])
    weight = np.linalg.norm(null, axis=1)
    involved = tuple(u for u, w in zip(unknowns, weight) if w > SUPPORT * weight.max())
    on = " restricted to the constraint directions" if layout.constraint_rows else ""
    head = (f"the velocity Hessian ∂²L/∂v² of the continuous limit L(q, v) = "
            f"lim_{{h→0}} L_d(g_h(q, v))/h{on} is singular along {shown} (rank "
            f"{first.rank} of {first.size} at every sampled point; the step h is "
            f"{time_step if time_step is not None else 't₁ − t₀'})")
    if all(t.first_order_regular() for t in terms):
        warnings.warn(DegenerateLagrangianWarning(
            f"{step.name}: {head}; velocity-linear terms of L make the step regular along it "
            f"(the continuous equations are of first order there), and the two-step discrete "
            f"flow carries parasitic modes beside the motion (docs/conventions.md §19)"),
            stacklevel=caller_level())  # the caller of euler_lagrange()
        return
    text = (f"The kinetic energy is degenerate: {head}. The step equations determine that "
            f"direction only through the potential, at order h, so along it the discrete flow "
            f"has a period-2 mode that does not die out (it grows), and no solution "
            f"approximates a motion as h → 0 (docs/conventions.md §19). Give L a kinetic "
            f"energy along {shown}, or constrain the motion along it (constraints= or "
            f"holonomic=).")
    finding = Finding(DEGENERATE_KINETIC, (), involved, text)
    raise DegenerateSystemError(f"{step.name}: the discrete Lagrangian has no regular "
                                f"continuous limit, so its steps approximate no motion. {text}",
                                findings=(finding,))


def _degenerate_terms(step, layout: Layout, time_step) -> list[LeadingTerms] | None:
    """The leading terms at the sampled points when R₀ is rank deficient at each of them;
    None when it is regular at one, or a point gives no evidence."""
    timed = step.groupoid.timed
    terms = []
    for point in limit_points(step.groupoid, step.parameters):
        leading = _leading_terms(step, layout, point, time_step, timed)
        if leading is None or leading.rank == leading.size:
            return None
        terms.append(leading)
    return terms or None


def _small_step_state(step, point, h: float, time_step) -> tuple | None:
    """(unknowns, knowns, parameters) at g_k = g_h(q, v), with the step parameter at h, the
    multipliers 0 and the unknown arrow at the step's constant-velocity prediction."""
    G = step.groupoid
    try:
        arrow = G.numeric_fibre_arrow(point.q, point.x0 + h * point.v)
    except (ArithmeticError, ValueError, TypeError):
        return None
    first = sorted(step.arrows)[0]
    values = {s: float(v) for s, v in zip(step.arrows[first], arrow)
              if isinstance(s, sp.Symbol)}
    knowns = np.array([values.get(s, 0.0) for s in step.knowns])
    params = np.array(point.p, float)
    if time_step is not None:
        params[list(step.parameters).index(time_step)] = h
    guess = np.array(predicted_unknowns(step, knowns, params), float)
    if step.n_constraints:
        guess[-step.n_constraints:] = 0.0
    return guess, knowns, params


def _leading_terms(step, layout: Layout, point, time_step, timed: bool) -> LeadingTerms | None:
    states = [_small_step_state(step, point, h, time_step) for h in SCALES]
    if any(s is None for s in states):
        return None
    try:
        values = evaluate_points(step, states)
    except Exception:  # noqa: BLE001 - no numeric evidence
        return None
    if not all(np.all(np.isfinite(J)) for _, J in values):
        return None
    # one common factor leaves every rank and null space as it is, and keeps the norms and
    # factorisations below in range (a Lagrangian scaled by 1e200 overflowed them)
    size = max(float(np.max(np.abs(J), initial=0.0)) for _, J in values)
    if size > 0:
        values = [(F / size, J / size) for F, J in values]
    crows, mcols = layout.constraint_rows, layout.multiplier_columns
    free = [i for i in range(len(layout.labels)) if i not in crows][int(timed):]
    chart = [j for j in range(len(layout.unknowns)) if j not in mcols][int(timed):]
    A = [h * J[np.ix_(free, chart)] for h, (_, J) in zip(SCALES, values)]
    A0 = extrapolate(A, SCALES)
    A1 = extrapolate([(a - A0) / h for a, h in zip(A, SCALES)], SCALES)
    A2 = extrapolate([((a - A0) / h - A1) / h for a, h in zip(A, SCALES)], SCALES)
    Y = _null(_unit_columns([J[np.ix_(free, mcols)] for _, J in values]).T, len(free))
    Z = _null(_unit_columns([J[np.ix_(crows, chart)].T for _, J in values]).T, len(chart))
    R0, R1 = Y.T @ A0 @ Z, Y.T @ A1 @ Z
    scale = max(np.linalg.norm(A0, 2), np.linalg.norm(A1, 2), np.linalg.norm(A2, 2))
    if R0.size and np.linalg.norm(R0, 2) <= _KINETIC_RANK * scale:
        # no leading term at all (no kinetic energy: L = g cos θ): what the extrapolation
        # leaves is rounding, whose own singular values must not count as a rank
        rank, left, right = 0, np.eye(R0.shape[0]), np.eye(R0.shape[1])
    else:
        rank, left, right = _leading_null_spaces(R0)
    return LeadingTerms(R0, R1, float(scale), rank, left, right, chart, Z)


def _unit_columns(blocks: list) -> np.ndarray:
    """The columns of a block at h → 0, as directions: each column normalised at every
    scale and extrapolated (a column that is zero at every scale is left out)."""
    norms = np.array([np.linalg.norm(b, axis=0) for b in blocks])
    keep = np.all(norms > 0, axis=0)
    return extrapolate([b[:, keep] / n[keep] for b, n in zip(blocks, norms)], SCALES)


def _null(rows: np.ndarray, n: int) -> np.ndarray:
    """An orthonormal basis (columns) of the vectors of length n orthogonal to ``rows``."""
    if rows.size == 0:
        return np.eye(n)
    _, sv, Vt = np.linalg.svd(rows)
    rank = int(np.sum(sv > 1e-8 * sv[0])) if sv.size and sv[0] > 0 else 0
    return Vt[rank:].T


def _leading_null_spaces(R: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Rank of R after equilibration (rows and columns below :data:`_FLOOR` of the largest
    are not rescaled: they are rounding of zeros), and unit bases of its left and right
    null spaces in R's own coordinates."""
    if R.size == 0:
        return 0, np.zeros((R.shape[0], 0)), np.zeros((R.shape[1], 0))
    dr = _scaling(np.linalg.norm(R, axis=1))
    dc = _scaling(np.linalg.norm(dr[:, None] * R, axis=0))
    U, sv, Vt = np.linalg.svd(dr[:, None] * R * dc[None, :])
    rank = int(np.sum(sv > _KINETIC_RANK * sv[0])) if sv[0] > 0 else 0
    left, right = dr[:, None] * U[:, rank:], dc[:, None] * Vt[rank:].T
    left = left / np.linalg.norm(left, axis=0, keepdims=True) if left.size else left
    right = right / np.linalg.norm(right, axis=0, keepdims=True) if right.size else right
    return rank, left, right


def _scaling(norms: np.ndarray) -> np.ndarray:
    """1/norm for the rows (or columns) above :data:`_FLOOR` of the largest, 1/largest for
    the others (1 when all are zero)."""
    top = float(norms.max(initial=0.0))
    if top == 0:
        return np.ones_like(norms)
    return 1.0 / np.where(norms > _FLOOR * top, norms, top)


def _velocity_name(unknown: str) -> str:
    """The chart velocity of an unknown: ``x_{k+1}`` → ``v_x``; other names → ``d/dt(…)``
    with the step label removed."""
    import re

    base = re.sub(r"_\{k[+-]?\d*\}", "", unknown)
    return f"v_{base}" if re.fullmatch(r"[A-Za-z]\w*", base) else f"d/dt {base}"


def _directions(null: np.ndarray, names: list[str]) -> str:
    """The null space spanned by the columns of ``null``, readable: every direction, or the
    rows of the reduced row echelon form of its basis, each as a combination."""
    n, k = null.shape
    if k >= n:
        return f"every direction ({', '.join(names)})"
    rows = null.T.copy()
    r = 0
    for col in range(n):
        if r == k:
            break
        pivot = r + int(np.argmax(np.abs(rows[r:, col])))
        if abs(rows[pivot, col]) < 1e-8 * np.abs(rows).max():
            continue
        rows[[r, pivot]] = rows[[pivot, r]]
        rows[r] /= rows[r, col]
        for i in range(k):
            if i != r:
                rows[i] -= rows[i, col] * rows[r]
        r += 1
    return " and ".join(_combination(row, names) for row in rows[:r])


def _combination(vector: np.ndarray, names: list[str]) -> str:
    """A direction as a readable combination, ``v_x − v_y`` or ``2 v_x − v_y`` (the first
    coefficient positive; whole numbers when the ratios are simple fractions)."""
    from fractions import Fraction
    from math import lcm

    vector = np.asarray(vector, float)
    top = np.abs(vector).max()
    if top == 0:
        return "0"
    first = next(c for c in vector if abs(c) > 1e-6 * top)
    vector = vector / (top if first > 0 else -top)
    vector[np.abs(vector) <= 1e-6] = 0.0
    fractions = [Fraction(float(c)).limit_denominator(12) for c in vector]
    if all(abs(float(f) - c) < 1e-6 for f, c in zip(fractions, vector)):
        vector = vector * lcm(*(f.denominator for f in fractions))
        vector = np.round(vector)
    terms = []
    for c, name in zip(vector, names):
        if c == 0:
            continue
        size = f"{abs(c):.0f}" if float(c).is_integer() else f"{abs(c):.3g}"
        terms.append(("−" if c < 0 else "+", name if size == "1" else f"{size} {name}"))
    return terms[0][1] + "".join(f" {s} {t}" for s, t in terms[1:])
