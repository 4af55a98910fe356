"""Assembly: the residual F of the necessary conditions, its Jacobian and rounding floors.

The equations are the junction residuals and the constraints of every term; each depends
only on a window of neighbouring unknowns, so the Jacobian is block-banded.  Its blocks are
X⃖ and X⃗ derivatives of the window residual (the window kernel's outputs); where each
output lands in F and in the Jacobian is the same at every iterate (:class:`_Pattern`), so
an assembly is a gather.  Alongside every residual the kernel computes the running-error
bound of its evaluation, whence the rounding floor of each equation and the residual
criterion of the solver (:func:`_excess`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ._linear import _Band

if TYPE_CHECKING:
    from ._state import _Problem

#: accept the iterate when every |F_i| ≤ max(tol/ε, ROUNDING_FACTOR)·floor_i, floor_i the rounding
#: floor of equation i (:func:`_rounding_floor`): ε·M_i, M_i the size of the terms that cancel
#: in F_i (every operation of its evaluation rounded once), plus the effect of the rounding of
#: the coordinates.  ε·M_i bounds the rounding of F_i up to the depth of the evaluation, while
#: rounding errors mostly cancel one another: at solutions |F_i| sits at 0.01–0.5 of floor_i
#: (measured on SO(3), SE(3) with translations up to 10⁴, SE(2), plate-ball, second-order
#: rigid body with N up to 1000, heavy top with rotors, time groupoid with t ≈ 10³).
#: A factor 8 leaves a margin of ≥ 16 over those, and a residual below 8·floor_i is a
#: solution to within 8 roundings of its own terms.
ROUNDING_FACTOR = 8.0

_EPS = float(np.finfo(float).eps)


class _Assembled(NamedTuple):
    """The residual F, the Jacobian (COO triplets), the configuration where |F| is largest,
    and the magnitude of the terms that cancel in every equation."""

    F: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    worst: int
    cancel: np.ndarray  # per equation: the magnitude of the terms that cancel in it
    band: _Band | None = None  # where each triplet lands in LAPACK's banded storage

    def finite(self) -> bool:
        return bool(np.isfinite(self.F).all() and np.isfinite(self.vals).all())


class _Pattern(NamedTuple):
    """Where every output of the window programs lands in F and in the Jacobian, for one
    layout: the sparsity pattern is the same at every iterate, so the assembly is a gather.

    The outputs are read from the flat vector [junction outputs, term outputs, 1]: triplet
    k has the value sign[k]·flat[src[k]], equation f_rows[i] the residual flat[f_src[i]] and
    the cancelling magnitude flat[c_src[i]]; the rows ``pin_rows`` hold the holonomic
    multipliers λ[pin_terms, m − held:] of the terms with a fixed source node."""

    rows: np.ndarray
    cols: np.ndarray
    src: np.ndarray
    sign: np.ndarray
    f_rows: np.ndarray
    f_src: np.ndarray
    c_src: np.ndarray
    pin_rows: np.ndarray
    pin_terms: np.ndarray
    band: _Band


def _pattern(kernel, lay) -> _Pattern:
    """The :class:`_Pattern` of ``lay``: the scatter of :func:`_add` run once on the
    positions of the outputs (position + 1, negated where the block enters with a minus)."""
    a, r, m, nz = kernel.arity, kernel.rank, kernel.m, kernel.n_stages
    rows, cols, vals = [], [], []
    f_rows, f_src, c_src = [], [], []
    base = 0
    J = lay.junctions
    if len(J):
        width = (r + 2 * r * r * len(kernel.offsets) + r * (m + nz) * len(kernel.starts)
                 + r)
        positions = 1.0 + np.arange(len(J) * width, dtype=float).reshape(len(J), width)
        res, left, right, dlam, dzeta, sizes = kernel.split_junction(positions)
        eq = lay.delta_at[J]
        f_rows.append((eq[:, None] + np.arange(r)).ravel())
        f_src.append(res.ravel())
        c_src.append(sizes.ravel())
        for o in kernel.offsets:  # arrow j+o moves with δ_{j+o} (left) and δ_{j+o−1} (right)
            _add(rows, cols, vals, lay.delta_at, eq, J + o, left[o], r)
            _add(rows, cols, vals, lay.delta_at, eq, J + o - 1, -right[o], r)
        for s in kernel.starts:
            _add(rows, cols, vals, lay.lam_at, eq, J + s, dlam[s], m)
        for s in kernel.starts if nz else ():  # ∂r/∂ζ of the terms j + s (§22)
            _add(rows, cols, vals, lay.zeta_at, eq, J + s, dzeta[s], nz)
        base = positions.size
    if m:
        T = lay.terms
        width = m + 2 * m * r * a + m
        positions = base + 1.0 + np.arange(len(T) * width, dtype=float).reshape(len(T), width)
        res, left, right, sizes = kernel.split_term(positions)
        eq = lay.lam_at[T]
        f_rows.append((eq[:, None] + np.arange(m)).ravel())
        f_src.append(res.ravel())
        c_src.append(sizes.ravel())
        for o in range(a):
            _add(rows, cols, vals, lay.delta_at, eq, T + o, left[o], r, m)
            _add(rows, cols, vals, lay.delta_at, eq, T + o - 1, -right[o], r, m)
        base += positions.size
    if nz:  # the stage rows of every term t: its arrow g_t moves with δ_t and δ_{t−1} (§22)
        T = lay.terms
        width = nz + 2 * nz * r + nz * nz + nz
        positions = base + 1.0 + np.arange(len(T) * width, dtype=float).reshape(len(T), width)
        res, left, right, dz, sizes = kernel.split_stage(positions)
        eq = lay.zeta_at[T]
        f_rows.append((eq[:, None] + np.arange(nz)).ravel())
        f_src.append(res.ravel())
        c_src.append(sizes.ravel())
        _add(rows, cols, vals, lay.delta_at, eq, T, left, r, nz)
        _add(rows, cols, vals, lay.delta_at, eq, T - 1, -right, r, nz)
        _add(rows, cols, vals, lay.zeta_at, eq, T, dz, nz, nz)
        base += positions.size
    pin_rows, pin_terms = _pinned(kernel, lay)
    if len(pin_rows):  # the row λ = 0: a unit diagonal, read from the trailing 1
        rows.append(pin_rows)
        cols.append(pin_rows)
        vals.append(np.full(len(pin_rows), base + 1.0))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    code = np.concatenate(vals)
    as_index = lambda parts: (np.concatenate(parts) - 1).astype(np.int64)  # noqa: E731
    pattern = _Pattern(rows, cols, (np.abs(code) - 1).astype(np.int64), np.sign(code),
                       np.concatenate(f_rows).astype(np.int64), as_index(f_src),
                       as_index(c_src), pin_rows, pin_terms, _Band.of(rows, cols, lay.size))
    for array in (*pattern[:-1], pattern.band.index):  # shared by every assembly
        array.flags.writeable = False
    return pattern


def _pinned(kernel, lay) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the holonomic multipliers of the terms whose source node is fixed by the
    boundary data (``held`` per term, in order), and those terms.

    Their row ψ(α(g_t)) is a constant (checked to be 0) and they enter no junction, so the
    row becomes λ = 0 (docs/conventions.md §15).  A term's source node is free exactly when
    it is the node of a free junction, α(g_t) = β(g_{t−1}) with t − 1 a junction."""
    m, held = kernel.m, kernel.held
    if not held:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    free = set((lay.junctions + 1).tolist())
    fixed = [int(t) for t in lay.terms if int(t) not in free]
    rows = [lay.lam_index[t] + np.arange(m - held, m) for t in fixed]
    return (np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64),
            np.array(fixed, np.int64))


#: the patterns of the layouts met lately, per kernel (a solve of N steps reuses its own)
_PATTERNS_KEPT = 8


def _pattern_of(kernel, lay) -> _Pattern:
    cache = kernel.__dict__.setdefault("_patterns", {})
    key = (lay.size, len(lay.junctions), len(lay.terms))
    if key not in cache:
        if len(cache) >= _PATTERNS_KEPT:
            cache.pop(next(iter(cache)))
        cache[key] = _pattern(kernel, lay)
    return cache[key]


def _assemble(problem: _Problem, arrows, lam) -> _Assembled:
    """F, its Jacobian and the cancelling magnitudes at (arrows, λ) of ``problem``: the window
    programs on every junction and term window (and, with internal stages, the stage program
    on every term), gathered into place by the layout's :class:`_Pattern`.  ``lam`` holds the
    unknowns of every term: its multipliers, then its stages ζ (docs/conventions.md §22)."""
    kernel, lay, p = problem.kernel, problem.lay, problem.p
    a, m, nz = kernel.arity, kernel.m, kernel.n_stages
    pattern = _pattern_of(kernel, lay)
    parts, worst_val, worst = [], -1.0, 0
    J = lay.junctions
    if len(J):
        windows = np.stack([arrows[J + o] for o in kernel.offsets], axis=1)
        lams = (np.stack([lam[J + s, :m] for s in kernel.starts], axis=1) if m
                else np.zeros((len(J), len(kernel.starts), 0)))
        zetas = (np.stack([lam[J + s, m:] for s in kernel.starts], axis=1) if nz else None)
        inputs = np.stack([problem.inputs[J + s] for s in kernel.starts], axis=1)
        out = kernel.junction_values(windows, lams, p, inputs, zetas)
        parts.append(out.ravel())
        bad = np.max(np.abs(out[:, :kernel.rank]), axis=1)
        worst_val, worst = bad.max(), int(J[np.argmax(bad)]) + 1
    T = lay.terms
    if m:
        out = kernel.term_values(np.stack([arrows[T + o] for o in range(a)], axis=1), p)
        parts.append(out.ravel())
        bad = np.max(np.abs(out[:, :m]), axis=1)
        if bad.max() > worst_val:
            worst_val, worst = bad.max(), int(T[np.argmax(bad)]) + 1
    if nz:
        out = kernel.stage_values(arrows[T], lam[T, m:], problem.inputs[T], p)
        parts.append(out.ravel())
        bad = np.max(np.abs(out[:, :nz]), axis=1)
        if bad.max() > worst_val:
            worst = int(T[np.argmax(bad)]) + 1
    parts.append(np.ones(1))
    flat = np.concatenate(parts)
    F = np.zeros(lay.size)
    cancel = np.zeros(lay.size)
    F[pattern.f_rows] = flat[pattern.f_src]
    cancel[pattern.f_rows] = flat[pattern.c_src]
    if len(pattern.pin_rows):  # the rows λ = 0 (docs/conventions.md §15, _pinned)
        F[pattern.pin_rows] = lam[pattern.pin_terms, m - kernel.held:m].reshape(-1)
        cancel[pattern.pin_rows] = 0.0
    vals = pattern.sign * flat[pattern.src]
    return _Assembled(F, pattern.rows, pattern.cols, vals, worst, cancel, pattern.band)


def _rounding_floor(assembled: _Assembled) -> np.ndarray:
    """The rounding floor of each equation: ε·E_i, E_i the running-error bound of its
    evaluation computed by the window kernels alongside it (:func:`symgroupoid.ir.rounding_error`)
    with the arrows' coordinates and the multipliers taken as rounded values themselves.

    So the floor counts every rounding of the evaluation — a junction residual
    r = X⃖[S](g_j) − X⃗[S](g_{j+1}) is the difference of two halves, each rounded — and, to
    first order, the residual's change when each stored coordinate a_m moves by ε·|a_m|
    (Σ_m |∂F_i/∂a_m|·|a_m|, propagated through the program with absolute values): an
    iterate cannot be held closer than that.  A residual scaled like 1/h² thus has a floor
    ~ N²·ε·|coordinates|, which a fixed tolerance would miss; a constraint on small chart
    coordinates computed from matrix entries near 1 feels the rounding of those entries
    although they do not move along the group (the rounding leaves the group), which the
    variations alone would miss.
    """
    with np.errstate(all="ignore"):
        return _EPS * np.nan_to_num(assembled.cancel, nan=np.inf)


def _add(rows, cols, vals, index, eq, targets, block, width, height=None):
    """Scatter ``block[w]`` (height × width) at equation row ``eq[w]`` and the unknowns of
    ``targets[w]`` in ``index`` (an array over positions, −1 where there is no unknown;
    targets that are not unknowns are skipped)."""
    height = block.shape[1] if height is None else height
    inside = (targets >= 0) & (targets < len(index))
    start = np.full(len(targets), -1)
    start[inside] = index[targets[inside]]
    keep = start >= 0
    if not keep.any():
        return
    start = start[keep]
    ii = eq[keep][:, None, None] + np.arange(height)[None, :, None]
    jj = start[:, None, None] + np.arange(width)[None, None, :]
    ii, jj = np.broadcast_arrays(ii, jj)
    rows.append(ii.ravel())
    cols.append(jj.ravel())
    vals.append(block[keep].reshape(-1))




def _excess(F: np.ndarray, floor: np.ndarray, tol: float) -> float:
    """max_i |F_i| / (max(tol/ε, ROUNDING_FACTOR)·floor_i): at most 1 when converged.

    ``tol`` is relative, on the scale of ε: floor_i/ε is the size of the terms of F_i and of
    its sensitivity to the coordinates, so the criterion is invariant under a rescaling of
    the Lagrangian or of the step (an absolute tolerance accepts the initial path of
    equations whose terms are all below it)."""
    if not F.size:
        return 0.0
    with np.errstate(all="ignore"):
        ratio = np.abs(F) / (max(tol / _EPS, ROUNDING_FACTOR) * floor)
    ratio[F == 0] = 0.0  # an exact zero meets any floor, also a zero one (0/0)
    return float(np.nan_to_num(ratio, nan=np.inf).max())


def _within_floor(assembled: _Assembled, f: float) -> bool:
    """|F|₂² = ``f`` ≤ Σ (ROUNDING_FACTOR·floor_i)²: the residual is at its rounding floor,
    where comparing two residuals is comparing noise."""
    floor = ROUNDING_FACTOR * _rounding_floor(assembled)
    bound = float(floor @ floor)
    if bound < np.inf:
        return f <= bound
    # terms beyond 1e154: the squares overflow; compared scaled by a power of two instead
    F = assembled.F
    top = max(float(np.max(np.abs(F), initial=0.0)), float(np.max(np.abs(floor))))
    if not top < np.inf:
        return False
    scale = np.ldexp(1.0, -np.frexp(top)[1])
    return float(np.sum((F * scale) ** 2)) <= float(np.sum((floor * scale) ** 2))

