"""The NumPy twin of the C library beside it (``stepper.c``): the same Newton stepper,
operation for operation, so that a kernel evaluated with NumPy gives the bits of its C.

Each function names its C counterpart (``<prefix>_lu_factor`` is ``SG_NAME(lu_factor)`` in
``stepper.c``): the same row scaling by powers of two, LU with partial pivoting and the
singularity threshold, the same summation orders of the rounding floors, the same
convergence tests, warm start, extrapolation and trust region, and the same statuses
(:class:`~._status.Status`).  :class:`NumpyStepper` runs Newton and ``simulate`` over a
kernel's functions evaluated in NumPy (the step's program: ``runtime.NumpyKernel``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ._status import Status
from ._time import (
    HOLD_ITERATIONS,
    HOLD_TOLERANCE,
    NO_TIME,
    SETTLE_ITERATIONS,
    STEP_RATIO,
    TimeLayout,
)

OK, SINGULAR_JACOBIAN, NOT_CONVERGED, NON_FINITE, INVALID_ARGUMENT, STALLED, BRANCH_JUMP = (
    int(s) for s in Status if s <= Status.BRANCH_JUMP)
OUTSIDE_DOMAIN = int(Status.OUTSIDE_DOMAIN)

#: default Newton options, as ``SG_NAME(default_options)`` sets them (a test checks it)
DEFAULT_OPTIONS = {"tol_residual": 0.0, "tol_step": 1e-16, "max_iterations": 50,
                   "floor_factor": 8.0, "trust_factor": 10.0}

#: the most OpenMP threads ``<prefix>_simulate_batch`` starts (``SG_MAX_THREADS``: a team is
#: created whole, and thousands of threads exhaust memory before any work is done)
MAX_THREADS = 1024

#: the least motion the trust region of a step allows for (``SG_TRUST_FLOOR``)
TRUST_FLOOR = 1e-2

#: largest value of a C ``int`` (Newton iteration caps and counts are ints in the kernel)
C_INT_MAX = 2**31 - 1

#: from this many unknowns the back substitution goes column by column
#: (``SG_LU_PANEL_FROM`` in ``stepper.c``, which also switches the factorisation to panels of
#: the same bits; a test checks the two values agree)
LU_PANEL_FROM = 24

#: the unit roundoff of double precision (C's DBL_EPSILON)
EPSILON = float(np.finfo(float).eps)


def norm_inf(v: np.ndarray) -> float:
    """max |v_i|, or a non-finite value if any entry is NaN or infinite (as the C kernel)."""
    a = np.abs(np.asarray(v, dtype=float))
    if a.size == 0:
        return 0.0
    bad = ~np.isfinite(a)
    if bad.any():
        return float(a[np.argmax(bad)])
    return float(a.max())


@dataclass
class LUFactors:
    """The factors of :func:`lu_factor`: scaled, permuted and eliminated A (L below the
    diagonal, U on and above; in band storage with ``band``), row exponents, pivot rows and
    reciprocal pivots."""

    A: np.ndarray
    e: np.ndarray
    perm: np.ndarray
    inv: np.ndarray
    band: BandOrder | None = None


@dataclass(frozen=True)
class BandOrder:
    """A Jacobian banded in a reordering of its unknowns and equations (``SG_BAND_KL``,
    ``SG_BAND_KU``, ``SG_BAND_ORDER`` of a kernel): entry (i, j) of
    B = J[order[i]][order[j]] is zero unless −kl ≤ j − i ≤ ku."""

    kl: int
    ku: int
    order: tuple[int, ...]

    def __post_init__(self) -> None:
        """A :class:`~symgroupoid.ShapeError` unless kl and ku are integers ≥ 0 and the order
        is a permutation of 0 … n − 1 (else the factors would read outside their rows)."""
        from .._errors import ShapeError

        if not all(type(v) is int and v >= 0 for v in (self.kl, self.ku)):
            raise ShapeError(f"BandOrder: kl and ku must be integers >= 0, got kl = "
                             f"{self.kl!r}, ku = {self.ku!r}")
        if sorted(self.order) != list(range(len(self.order))) or not all(
                type(i) is int for i in self.order):
            raise ShapeError("BandOrder: the order must be a permutation of 0 ... n - 1 "
                             "(Python ints)")

    @property
    def width(self) -> int:
        """The columns of a row of the band storage (``SG_BAND_WIDTH``): kl + 1 + kl + ku."""
        return 2 * self.kl + self.ku + 1


def lu_factor(A: np.ndarray, band: BandOrder | None = None
              ) -> tuple[int, LUFactors | None]:
    """(status, factors) exactly as ``<prefix>_lu_factor`` in the C kernel (of a kernel
    with the band ``band``: :func:`band_factor`).

    Every row of A is scaled by the power of two 2^-e bringing the row's largest |entry|
    into [1/2, 1) (exact), so singularity is judged relative to each equation; then LU with
    partial pivoting (reciprocal pivots, zero multipliers skipped).  The status is
    ``SINGULAR_JACOBIAN`` for a zero row or a pivot not above n·ε, ``NON_FINITE`` when a
    value is infinite or NaN (overflow), else ``OK``.
    """
    A = np.array(A, dtype=float)
    n = len(A)
    tiny = n * EPSILON
    e = np.zeros(n, dtype=np.int64)
    with np.errstate(all="ignore"):
        for i in range(n):
            m = norm_inf(A[i])
            if not np.isfinite(m):
                return NON_FINITE, None
            if m == 0.0:
                return SINGULAR_JACOBIAN, None
            e[i] = int(np.frexp(m)[1])
            A[i] = A[i] * np.ldexp(1.0, -e[i]) if -1000 < e[i] < 1000 else np.ldexp(A[i],
                                                                                  -e[i])
        if band is not None:
            return band_factor(A, e, band)
        # entries now lie in [-1, 1]; partial pivoting grows them at most 2^(n-1): no overflow
        perm = np.zeros(n, dtype=np.int64)
        inv = np.empty(n)
        for k in range(n):
            column = np.abs(A[k:, k])
            piv = k + int(np.argmax(column))
            if not column[piv - k] > tiny:
                return SINGULAR_JACOBIAN, None
            perm[k] = piv
            if piv != k:
                A[[k, piv]] = A[[piv, k]]
            inv[k] = 1.0 / A[k, k]
            for i in range(k + 1, n):
                lik = A[i, k] * inv[k]
                A[i, k] = lik
                if lik != 0.0:
                    A[i, k + 1:] -= lik * A[k, k + 1:]
    return OK, LUFactors(A, e, perm, inv)


def band_factor(scaled: np.ndarray, e: np.ndarray, band: BandOrder
                ) -> tuple[int, LUFactors | None]:
    """``<prefix>_band_fill`` and ``<prefix>_band_eliminate``: the row-scaled ``scaled``
    reordered into band storage (row i holds columns i − kl … i + kl + ku, entry (i, j) at
    column j − i + kl), then partial pivoting over rows k … k + kl, rows swapped from column
    k on, multipliers stored in place, zero ones skipped (LAPACK's dgbtf2 order)."""
    n, kl, ku, w = len(scaled), band.kl, band.ku, band.width
    if len(band.order) != n:
        from .._errors import ShapeError

        raise ShapeError(f"band_factor: a band order of {len(band.order)} unknowns for a "
                         f"matrix of {n}")
    order = np.asarray(band.order, dtype=np.int64)
    tiny = n * EPSILON
    B = np.zeros((n, w))
    for i in range(n):
        lo, hi = max(0, i - kl), min(n - 1, i + ku)
        B[i, lo - i + kl:hi - i + kl + 1] = scaled[order[i], order[lo:hi + 1]]
    perm = np.zeros(n, dtype=np.int64)
    inv = np.empty(n)
    for k in range(n):
        last, end = min(k + kl, n - 1), min(k + kl + ku, n - 1)
        column = np.abs(np.array([B[i, k - i + kl] for i in range(k, last + 1)]))
        piv = k + int(np.argmax(column))
        if not column[piv - k] > tiny:
            return SINGULAR_JACOBIAN, None
        perm[k] = piv
        if piv != k:
            row_k = B[k, kl:end - k + kl + 1].copy()
            B[k, kl:end - k + kl + 1] = B[piv, k - piv + kl:end - piv + kl + 1]
            B[piv, k - piv + kl:end - piv + kl + 1] = row_k
        inv[k] = 1.0 / B[k, kl]
        for i in range(k + 1, last + 1):
            lik = B[i, k - i + kl] * inv[k]
            B[i, k - i + kl] = lik
            if lik != 0.0:
                B[i, k + 1 - i + kl:end - i + kl + 1] -= lik * B[k, kl + 1:end - k + kl + 1]
    return OK, LUFactors(B, e, perm, inv, band)


def _band_apply(factors: LUFactors, b: np.ndarray) -> np.ndarray:
    """The substitutions of ``<prefix>_lu_apply`` with band factors (``b`` scaled)."""
    B, band = factors.A, factors.band
    n, kl, reach = len(b), band.kl, band.kl + band.ku
    order = np.asarray(band.order, dtype=np.int64)
    y = b[order]
    for k in range(n):  # step k's row swap, then its multipliers
        piv = int(factors.perm[k])
        y[k], y[piv] = y[piv], y[k]
        last = min(k + kl, n - 1)
        rows = np.arange(k + 1, last + 1)
        y[k + 1:last + 1] -= B[rows, k - rows + kl] * y[k]
    for i in range(n - 1, -1, -1):  # column by column
        y[i] = y[i] * factors.inv[i]
        rows = np.arange(max(0, i - reach), i)
        y[rows] -= B[rows, i - rows + kl] * y[i]
    x = np.empty(n)
    x[order] = y
    return x


def lu_apply(factors: LUFactors, b: np.ndarray) -> tuple[int, np.ndarray]:
    """(status, x) solving A x = b with the factors, exactly as ``<prefix>_lu_apply``;
    ``NON_FINITE`` when x is not finite (in particular when b or its scaling is not)."""
    A, n = factors.A, len(factors.A)
    with np.errstate(all="ignore"):
        b = np.array(b, dtype=float)
        for i in range(n):
            e = int(factors.e[i])
            b[i] = b[i] * np.ldexp(1.0, -e) if -1000 < e < 1000 else np.ldexp(b[i], -e)
        # a non-finite entry of the scaled b stays non-finite through the substitutions
        # (finite multipliers, zero ones applied too, and pivots): one test of x covers it
        if factors.band is not None:
            b = _band_apply(factors, b)
            return (OK if np.isfinite(norm_inf(b)) else NON_FINITE), b
        for k in range(n):  # the row swaps, in order (L's rows were swapped with them)
            piv = int(factors.perm[k])
            if piv != k:
                b[[k, piv]] = b[[piv, k]]
        for k in range(n):  # every b_i, i > k, takes one update (elementwise: the same bits)
            b[k + 1:] -= A[k + 1:, k] * b[k]
        if n < LU_PANEL_FROM:  # row by row, each sum in the order j = i+1, i+2, ...
            for i in range(n - 1, -1, -1):
                t = b[i]
                for j in range(i + 1, n):
                    t -= A[i, j] * b[j]
                b[i] = t * factors.inv[i]
        else:  # column by column: b_i's updates in the order j = n-1, n-2, ...
            for i in range(n - 1, -1, -1):
                b[i] = b[i] * factors.inv[i]
                b[:i] -= A[:i, i] * b[i]
    return (OK if np.isfinite(norm_inf(b)) else NON_FINITE), b


def coordinate_floor(J: np.ndarray, u: np.ndarray) -> np.ndarray:
    """C_i = ε·Σ_j |J_ij|·|u_j|, as ``<prefix>_coordinate_floor`` (the same summation order)."""
    C = np.zeros(len(J))
    for j in range(J.shape[1]):
        C = C + np.abs(J[:, j]) * abs(u[j])
    return EPSILON * C


def explained_by_rounding(F: np.ndarray, J: np.ndarray, u: np.ndarray, uJ: np.ndarray,
                          ratio: float) -> bool:
    """As ``<prefix>_explained_by_rounding``: every |F_i| ≤ 64ε·κ·Σ_j |J_ij|·(1 + m_j),
    m_j = min(|u_j|, |u_J,j|), κ the pivot ratio — the residual a rounding-level update of a
    solve with J (evaluated at u_J) would leave; the weights never exceed those at u_J, so a
    runaway iterate is not accepted for its small relative update (the same summation
    order).  The C kernel first compares |F_i| with the bound times max_j |J_ij| when every
    weight is finite (S_i is at least that as computed, rounding being monotone), and sums
    only when that does not decide: the answer is always this one."""
    bound = 64.0 * EPSILON * ratio
    m = 1.0 + np.minimum(np.abs(u), np.abs(uJ))
    S = np.zeros(len(J))
    for j in range(J.shape[1]):
        S = S + np.abs(J[:, j]) * m[j]
    return bool(np.all(np.abs(F) <= bound * S))


def pivot_ratio(factors: LUFactors, uJ: np.ndarray) -> float:
    """As ``<prefix>_pivot_ratio``: the smaller of max |pivot| / min |pivot| (from the
    reciprocal pivots) and the same ratio with each pivot weighted by 1 + |u_J,j| for the
    column j it eliminates (the condition of J·diag(1 + |u_J|), the scale in which updates
    are measured)."""
    a = np.abs(factors.inv)
    columns = np.arange(len(a)) if factors.band is None else np.array(factors.band.order)
    with np.errstate(all="ignore"):  # an infinite weight: w/0, that ratio is not taken
        w = a / (1.0 + np.abs(np.asarray(uJ, dtype=float)[columns]))
        plain, weighted = np.max(a) / np.min(a), np.max(w) / np.min(w)
    return float(weighted if weighted < plain else plain)


def polish(d: np.ndarray, u: np.ndarray, last_step: float, it: int
           ) -> tuple[np.ndarray, int]:
    """The polishing update of ``<prefix>_newton``: one more chord update d of an accepted
    iterate u (from its residual, no evaluation), when smaller than the last update;
    (u, updates made)."""
    if relative_norm(d, u) < last_step:
        return u - d, it + 1
    return u, it


#: as ``SG_FLOOR_UPDATE``: the largest update (relative) an iterate at a rounding floor may
#: still call for (a true floor's noise: up to 5e-8 for a body far from the origin; a
#: non-solution accepted on its terms' size: 0.07-0.3; runaways to a chart's cut locus:
#: 8e-5 and 1.05e-4)
FLOOR_UPDATE = 1e-6
#: as ``SG_GUESS_MARGIN``: an iterate whose |F|∞ is more than this many times its guess's is
#: never taken for a rounding floor (a runaway to a chart's cut locus, where F is noise of
#: size 1e5, passed the floor of the unknowns' rounding)
GUESS_MARGIN = 1e3
#: as ``SG_TRIAL_CUT``: a chord update that cuts the residual by this factor shows an iterate
#: off its rounding floor (a true floor of F's terms keeps at least 0.006 of it)
TRIAL_CUT = 1e-3


def floor_norm(d: np.ndarray, u: np.ndarray, g: np.ndarray) -> float:
    """As ``<prefix>_floor_norm``: max_j |d_j| / (1 + min(|u_j|, |g_j|)), g the guess."""
    return float(np.max(np.abs(d) / (1.0 + np.minimum(np.abs(u), np.abs(g))), initial=0.0))


def update_negligible(factors: LUFactors, F: np.ndarray, u: np.ndarray, g: np.ndarray
                      ) -> tuple[bool, np.ndarray]:
    """As ``<prefix>_update_negligible``: (whether the update d the factorisation gives for
    ``F`` is at most :data:`FLOOR_UPDATE` relative to ``u`` and the guess ``g``
    (:func:`floor_norm`; a residual that still calls for a larger one is not rounding,
    however large the terms it is computed from), d)."""
    status, d = lu_apply(factors, F)
    return status == OK and floor_norm(d, u, g) <= FLOOR_UPDATE, d


def above_rounding(d: np.ndarray, u: np.ndarray, factor: float) -> bool:
    """As ``<prefix>_above_rounding``: some factor·|d_j| > ε·|u_j|."""
    return bool(np.any(factor * np.abs(d) > EPSILON * np.abs(u)))


def relative_norm(d: np.ndarray, u: np.ndarray) -> float:
    """max_j |d_j| / (1 + |u_j|), as ``<prefix>_relative_norm``."""
    with np.errstate(all="ignore"):
        return float(np.max(np.abs(d) / (1.0 + np.abs(u)), initial=0.0))


def lu_solve(A: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """(status, x) of A x = b: :func:`lu_factor` then :func:`lu_apply`."""
    status, factors = lu_factor(A)
    if status != OK:
        return status, np.array(b, dtype=float)
    return lu_apply(factors, b)


@dataclass
class NumpyWarmStart:
    """The NumPy twin of ``<prefix>_warm_start``: the last three solved unknowns and whether
    the next guess extrapolates them quadratically (see :meth:`extrapolate`)."""

    count: int = 0
    u_last: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u_earlier: np.ndarray = field(default_factory=lambda: np.zeros(0))
    quadratic: bool = False

    def _linear(self) -> np.ndarray:
        return 2.0 * self.u_last - self.u_before

    def _quadratic(self) -> np.ndarray:
        return 3.0 * (self.u_last - self.u_before) + self.u_earlier

    def extrapolate(self) -> np.ndarray:
        """As ``<prefix>_extrapolate`` (count ≥ 2): the quadratic guess
        3(u_last − u_before) + u_earlier when three solutions are held and ``quadratic``,
        else the linear 2u_last − u_before."""
        return self._quadratic() if self.count == 3 and self.quadratic else self._linear()

    def trusts(self, guess: np.ndarray, u: np.ndarray, factor: float) -> bool:
        """As ``<prefix>_trusted``: whether the solution ``u`` of a step lies in the trust
        region of its extrapolated ``guess``, |u − guess| ≤ factor·(m + TRUST_FLOOR) (|·|
        relative to each unknown at ``u_last``; m the larger motion of the last two steps),
        or the check is off (factor 0, fewer than three solutions held: one motion alone can
        be the small one of an oscillation)."""
        if not factor > 0.0 or self.count < 3:
            return True
        scale = 1.0 + np.abs(self.u_last)
        motion = np.maximum(np.abs(self.u_last - self.u_before),
                            np.abs(self.u_before - self.u_earlier))
        radius = factor * (float(np.max(motion / scale, initial=0.0)) + TRUST_FLOOR)
        return bool(np.all(np.abs(u - guess) <= radius * scale))

    def remember(self, u: np.ndarray) -> None:
        """As ``<prefix>_remember``: adds the solution ``u``; with three solutions held,
        ``quadratic`` becomes whether the quadratic extrapolation would have guessed ``u``
        more closely than the linear one (relative norm): O(h³) against O(h²) on smooth
        motion, worse on an oscillation of fewer than about six steps per period."""
        if self.count == 3:
            self.quadratic = bool(relative_norm(u - self._quadratic(), u)
                                  < relative_norm(u - self._linear(), u))
        else:
            self.quadratic = False
        self.u_earlier, self.u_before = self.u_before, self.u_last
        self.u_last = np.array(u, dtype=float)
        self.count = min(self.count + 1, 3)


def _newton_update(residual_jacobian: Callable, x: np.ndarray, known, p,
                   held: TimeLayout | None = None) -> np.ndarray | None:
    """The Newton update J⁻¹F at ``x`` (None when J is singular or not finite); with
    ``held``, of the fixed-step equations: the time row replaced by t_{k+1} = its value."""
    F, J = residual_jacobian(x, known, p)
    F, J = np.array(F, dtype=float), np.array(J, dtype=float).reshape(len(x), len(x))
    if held is not None:
        F[held.row] = 0.0
        J[held.row, :] = 0.0
        J[held.row, held.unknown] = 1.0
    status, factors = lu_factor(J)
    if status != OK:
        return None
    status, d = lu_apply(factors, F)
    return d if status == OK else None


def hold_time(residual_jacobian: Callable, time: TimeLayout, known, p, u) -> np.ndarray:
    """As ``<prefix>_hold_time``: the guess ``u`` of a step on a time groupoid moved onto
    its fixed-step equations (seed 000 Example 6.2): Newton with t_{k+1} held, its row
    replaced by t_{k+1} = guess, at most ``HOLD_ITERATIONS`` updates until one is at most
    ``HOLD_TOLERANCE`` (relative); ``u`` itself when that fails (a singular or non-finite
    system) or the step has no time row (docs/conventions.md §7).  ``residual_jacobian``:
    (u, known, p) → (F, J)."""
    if time.row < 0 or time.unknown < 0:
        return u
    x = np.array(u, dtype=float)
    with np.errstate(all="ignore"):
        for _ in range(HOLD_ITERATIONS):
            d = _newton_update(residual_jacobian, x, known, p, time)
            if d is None:
                return u
            step = relative_norm(d, x)
            x = x - d
            if step <= HOLD_TOLERANCE:
                return x
    return u


def settle_time(residual_jacobian: Callable, time: TimeLayout, known, p, u) -> np.ndarray:
    """As ``<prefix>_settle_time``: the last try of a step on a time groupoid, Newton on
    the time step along the fixed-step solutions: from the held guess ``u``, each round
    takes the full Newton update (its time component the reduced energy equation's), keeps
    the time step within [1/STEP_RATIO, STEP_RATIO] times the last and holds the result
    again (:func:`hold_time`), at most ``SETTLE_ITERATIONS`` rounds until the time update
    is at most ``HOLD_TOLERANCE`` (relative); the last held iterate."""
    if time.row < 0 or time.unknown < 0:
        return u
    x = np.array(u, dtype=float)
    last = np.float64(known[time.known]) - np.float64(known[time.before])
    low, high = ((last / STEP_RATIO, last * STEP_RATIO) if last > 0.0
                 else (last * STEP_RATIO, last / STEP_RATIO))
    with np.errstate(all="ignore"):
        for _ in range(SETTLE_ITERATIONS):
            d = _newton_update(residual_jacobian, x, known, p)
            if d is None:
                return x
            dt = d[time.unknown]
            x = x - d
            t = x[time.unknown] - np.float64(known[time.known])
            if t < low:
                x[time.unknown] = np.float64(known[time.known]) + low
            elif t > high:
                x[time.unknown] = np.float64(known[time.known]) + high
            x = hold_time(residual_jacobian, time, known, p, x)
            if abs(dt) <= HOLD_TOLERANCE * (1.0 + abs(x[time.unknown])):
                return x
    return x


def time_step_kept(time: TimeLayout, known, u, factor: float) -> bool:
    """As ``<prefix>_time_step_kept``: the time step h_{k+1} = t_{k+1} − t_k of the solution
    ``u`` has the sign of h_k = t_k − t_{k−1} and 1/STEP_RATIO ≤ h_{k+1}/h_k ≤ STEP_RATIO,
    or the check is off (``factor`` 0) or the step has no time."""
    if time.unknown < 0:
        return True
    with np.errstate(all="ignore"):
        ratio = ((np.float64(u[time.unknown]) - np.float64(known[time.known]))
                 / (np.float64(known[time.known]) - np.float64(known[time.before])))
    return bool(not factor > 0.0 or (1.0 / STEP_RATIO <= ratio <= STEP_RATIO))


#: a kernel's functions of (u, known, p) or (known, p), evaluated in NumPy
StepFunction = Callable[..., np.ndarray]


@dataclass(frozen=True)
class StepFunctions:
    """The functions a kernel generates, as the stepper calls them (flat float arrays):
    F(u; known, p), (F, J) with J[i, j] = ∂F_i/∂u_j, the scale S of F's terms, the
    prediction u(known, p), the next known state from a solved step, and the values of the
    window's terms defined on part of the real line only (``<prefix>_domain``; None: none)."""

    residual: StepFunction
    residual_jacobian: Callable[..., tuple[np.ndarray, np.ndarray]]
    residual_scale: StepFunction
    predict: StepFunction
    next_knowns: StepFunction
    domain: StepFunction | None = None


class NumpyStepper:
    """``SG_NAME(newton)`` and ``SG_NAME(simulate)`` of ``stepper.c`` over the
    :class:`StepFunctions` of a kernel of ``n_unknowns`` unknowns.  ``options``: anything
    with the fields of ``runtime.NewtonOptions``; ``time``: the kernel's time indices
    (``<PREFIX>_TIME_ROW``, ...; :data:`~._time.NO_TIME` without a time groupoid);
    ``band``: the kernel's :class:`BandOrder` (``<PREFIX>_BAND_*``), None for dense factors."""

    def __init__(self, functions: StepFunctions, n_unknowns: int,
                 time: TimeLayout = NO_TIME, band: BandOrder | None = None):
        self.f = functions
        self.n_u = n_unknowns
        self.time = time
        self.band = band  # the kernel's band order (SG_BAND_*), None for dense factors

    def warm_start(self) -> NumpyWarmStart:
        """A fresh warm start (no solution held)."""
        return NumpyWarmStart(0, np.zeros(self.n_u), np.zeros(self.n_u), np.zeros(self.n_u))

    def solve_step(self, known, p, u0, options):
        """Newton's method exactly as ``<prefix>_newton`` in the C kernel: (status, last
        iterate, updates, |F|_inf of the last iterate)."""
        with np.errstate(all="ignore"):
            status, u, it, rnorm = self.newton(known, p, np.array(u0, dtype=float), options)
            if status == OK and not self.in_domain(u, known, p):
                status = OUTSIDE_DOMAIN
        return status, u, it, rnorm

    def in_domain(self, u, known, p) -> bool:
        """As the check of ``<prefix>_newton``: whether every value of the kernel's
        ``domain`` is finite at the solution u (L defined there; docs/conventions.md §11)."""
        if self.f.domain is None:
            return True
        return bool(np.isfinite(norm_inf(self.f.domain(u, known, p))))

    def at_floor(self, u, known, p, F, C, factor: float) -> bool:
        """As ``<prefix>_at_floor``: every |F_i| ≤ factor·(C_i + N_i), N_i the larger change
        of F_i when every unknown moves by 4 ulps (alternating signs, both ways)."""
        move = 4.0 * EPSILON * np.where(np.abs(u) > np.finfo(float).tiny, np.abs(u), 1.0)
        signs = np.where(np.arange(len(u)) % 2 == 0, 1.0, -1.0)
        N = np.zeros(len(F))
        for sign in (-1.0, 1.0):
            G = self.f.residual(u + sign * signs * move, known, p)
            N = np.maximum(N, np.abs(G - F))
        return bool(np.all(np.abs(F) <= factor * (C + N)))

    def at_rounding_floor(self, u, known, p, F, J, uJ, g, factors, options
                          ) -> tuple[bool, np.ndarray | None]:
        """As ``<prefix>_at_rounding_floor``: (whether a rounding-level update explains F
        (:func:`explained_by_rounding`) or F is within the rounding of the unknowns
        (:meth:`at_floor`), and the update d that F calls for is negligible (as
        :func:`update_negligible`; a runaway iterate with a numerically singular Jacobian
        passes the first bound at |F| ~ 5e13), d or None)."""
        floor = explained_by_rounding(F, J, u, uJ, pivot_ratio(factors, uJ)) or self.at_floor(
            u, known, p, F, coordinate_floor(J, uJ), options.floor_factor)
        if not floor:
            return False, None
        return update_negligible(factors, F, u, g)

    def within_scale(self, u, known, p, F, factor: float) -> bool:
        """As ``<prefix>_within_scale``: every |F_i| ≤ factor·ε·S_i, S the program's
        ``F_scale`` (the size of the terms F_i is computed from)."""
        S = self.f.residual_scale(u, known, p)
        return bool(np.all(np.abs(F) <= factor * EPSILON * S))

    def chord_cuts(self, factors, F, u, known, p, rnorm: float) -> bool:
        """As ``<prefix>_chord_cuts``: the update the factorisation gives for F cuts the
        residual by :data:`TRIAL_CUT` (evaluated at u − d): a slow stretch of Newton, not a
        rounding floor, however small F is against the size of its terms."""
        status, d = lu_apply(factors, F)
        if status != OK:
            return False
        return norm_inf(self.f.residual(u - d, known, p)) <= TRIAL_CUT * rnorm

    def hold_time(self, known, p, u) -> np.ndarray:
        """As ``<prefix>_hold_time`` (:func:`hold_time` with this kernel's functions)."""
        return hold_time(self.f.residual_jacobian, self.time, known, p, u)

    def settle_time(self, known, p, u) -> np.ndarray:
        """As ``<prefix>_settle_time`` (:func:`settle_time` with this kernel's functions)."""
        return settle_time(self.f.residual_jacobian, self.time, known, p, u)

    def time_step_kept(self, known, u, factor: float) -> bool:
        """As ``<prefix>_time_step_kept`` (:func:`time_step_kept` with this kernel's
        indices)."""
        return time_step_kept(self.time, known, u, factor)

    def newton(self, known, p, u, options):
        """As ``<prefix>_newton`` (see ``runtime.NewtonOptions``): (status, last iterate,
        updates made, |F|_inf of the last iterate)."""
        previous = last_step = guess = 0.0
        factors = uJ = None
        done = 0  # 1: stopped on a rounding-noise update, 2: on the estimated error
        fresh = False  # the last update was a Newton update (J factored where it started)
        it = 0
        while True:
            here = False  # J factored at this iterate
            if it == 0:
                F, J = self.f.residual_jacobian(u, known, p)
            else:
                F = self.f.residual(u, known, p)
            rnorm = norm_inf(F)
            if not np.isfinite(rnorm):
                return NON_FINITE, u, it, rnorm
            if it == 0:
                guess, g0 = rnorm, u
            worse = rnorm > GUESS_MARGIN * guess  # no floor: Newton made the guess worse
            if done and not worse:  # after the final update: accepted only at the floor
                settled, d = self.at_rounding_floor(u, known, p, F, J, uJ, g0, factors, options)
                if settled:  # after a stop on the estimate: one more chord update (d)
                    if done == 2 and it < options.max_iterations:
                        u, it = polish(d, u, last_step, it)
                    return OK, u, it, rnorm
            done = 0  # a small update, a residual above the floor: iterate on
            if it == 0:  # factor J before any convergence test (a degenerate step fails)
                uJ, here = u, True
                status, factors = lu_factor(J, self.band)
                if status != OK:
                    return status, u, it, rnorm
            if rnorm <= options.tol_residual:
                return OK, u, it, rnorm
            slow = it > 0 and not rnorm <= 0.1 * previous
            ratio = pivot_ratio(factors, uJ)
            # rounding noise of a solve, and only a Newton update's (see the C kernel)
            noise = slow and fresh and last_step <= 64.0 * EPSILON * ratio
            # a chord update may contract slowly without any stall: only a Newton update
            # that did not reduce |F| tenfold is a stall
            if slow and fresh and not worse:
                floor = self.at_floor(u, known, p, F, coordinate_floor(J, uJ),
                                      options.floor_factor)
                scale = not floor and self.within_scale(u, known, p, F, options.floor_factor)
                if (floor or scale) and update_negligible(factors, F, u, g0)[0]:
                    if floor or not self.chord_cuts(factors, F, u, known, p, rnorm):
                        return OK, u, it, rnorm  # at the rounding of the unknowns or F's terms
                    noise = False  # off the floor: Newton goes on from u
            if noise:
                settled = (not worse and explained_by_rounding(F, J, u, uJ, ratio)
                           and update_negligible(factors, F, u, g0)[0])
                return (OK if settled else STALLED), u, it, rnorm
            if it >= options.max_iterations:  # the cap: at the rounding floor, a solution
                at_floor = not worse and self.at_rounding_floor(u, known, p, F, J, uJ, g0, factors,
                                                                options)[0]
                return (OK if at_floor else NOT_CONVERGED), u, it, rnorm
            if slow:
                F, J = self.f.residual_jacobian(u, known, p)
                uJ, here = u, True
                status, factors = lu_factor(J, self.band)
                if status != OK:
                    return status, u, it, rnorm
            previous, fresh = rnorm, here
            status, du = lu_apply(factors, F)
            if status != OK:
                return status, u, it, rnorm
            step = relative_norm(du, u)
            u = u - du
            if step <= 4.0 * EPSILON:  # the update is rounding noise of u
                done = 1
            elif it > 0 and step < last_step:
                rho = step / last_step
                if rho / (1.0 - rho) * step <= options.tol_step:  # polished unless below
                    # rounding; always after the first two updates (rho, a single ratio,
                    # overstates the contraction when the first update also fixed the
                    # unknowns that enter linearly, such as multipliers)
                    done = 2 if it == 1 or above_rounding(du, u, rho / (1.0 - rho)) else 1
            last_step = step
            it += 1

    def simulate(self, known0, p, n_steps: int, options, warm: NumpyWarmStart
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int, np.ndarray]:
        """As ``<prefix>_simulate``: extrapolate from the warm start when it holds at least
        two solutions (and ``options.extrapolate``), else predict; retry from the prediction
        when Newton fails from an extrapolated guess or its solution lies outside the
        guess's trust region (:meth:`NumpyWarmStart.trusts`), and stop with ``BRANCH_JUMP``
        when the retry's does too; without extrapolation, stop so when the solution from the
        prediction lies outside the trust region of the extrapolation (from the fourth
        step).  ``warm`` (from :meth:`warm_start`) is continued and
        updated.  Returns (states (n_steps + 1, n_known), iterations (n_steps,) int64,
        residual norms (n_steps,), status, failed step (−1 on success), last iterate); after
        a failure at step k only rows 0 … k of the states are valid."""
        states = np.empty((n_steps + 1, len(known0)))
        states[0] = known0
        iterations = np.zeros(n_steps, dtype=np.int64)
        norms = np.zeros(n_steps)
        for k in range(n_steps):
            current = states[k]
            extrapolated = bool(options.extrapolate) and warm.count >= 2
            watched = not extrapolated and warm.count >= 3  # (checked, not started from)
            factor = options.trust_factor
            with np.errstate(all="ignore"):
                guess = warm.extrapolate() if extrapolated or watched else None
                start = guess if extrapolated else self.f.predict(current, p)
            status, u, iterations[k], norms[k] = self.solve_step(
                current, p, self.hold_time(current, p, start), options)
            jumped = status == OK and (
                ((extrapolated or watched) and not warm.trusts(guess, u, factor))
                or not self.time_step_kept(current, u, factor))
            if extrapolated and (status != OK or jumped):  # retry from the prediction
                far, far_norm = u, norms[k]
                with np.errstate(all="ignore"):
                    u0 = self.hold_time(current, p, self.f.predict(current, p))
                status, u, more, norms[k] = self.solve_step(current, p, u0, options)
                iterations[k] = min(iterations[k] + more, C_INT_MAX)
                if status != OK and jumped:  # report the far solution
                    u, norms[k] = far, far_norm
                if (not warm.trusts(guess, u, factor) or not self.time_step_kept(current, u,
                                                                                  factor)
                        if status == OK else jumped):
                    status = BRANCH_JUMP
            elif jumped:  # from the prediction: no other guess to try
                status = BRANCH_JUMP
            if status != OK and self.time.row >= 0 and self.time.unknown >= 0:
                # the last try on a time groupoid: the prediction settled on the energy
                # equation along the fixed-step solutions (settle_time)
                with np.errstate(all="ignore"):
                    y = self.settle_time(current, p, self.hold_time(
                        current, p, self.f.predict(current, p)))
                again, y, more, settled_norm = self.solve_step(current, p, y, options)
                iterations[k] = min(iterations[k] + more, C_INT_MAX)
                if again == OK and self.time_step_kept(current, y, factor) and (
                        not (extrapolated or watched) or warm.trusts(guess, y, factor)):
                    status, u, norms[k] = OK, y, settled_norm
            if status == OK:
                with np.errstate(all="ignore"):
                    following = self.f.next_knowns(u, current, p)
                if not np.isfinite(norm_inf(following)):
                    status = NON_FINITE
            if status != OK:
                return states, iterations, norms, status, k, u
            states[k + 1] = following
            warm.remember(u)
        return states, iterations, norms, OK, -1, np.zeros(self.n_u)


__all__ = ["BRANCH_JUMP", "BandOrder", "C_INT_MAX", "DEFAULT_OPTIONS", "EPSILON",
           "INVALID_ARGUMENT", "LUFactors", "MAX_THREADS", "NON_FINITE", "NOT_CONVERGED",
           "OUTSIDE_DOMAIN",
           "NumpyStepper", "NumpyWarmStart", "OK", "SINGULAR_JACOBIAN", "STALLED",
           "StepFunctions", "TRUST_FLOOR", "above_rounding", "band_factor", "coordinate_floor",
           "explained_by_rounding", "hold_time", "settle_time", "lu_apply", "lu_factor", "lu_solve",
           "norm_inf", "pivot_ratio", "polish", "relative_norm", "time_step_kept"]
