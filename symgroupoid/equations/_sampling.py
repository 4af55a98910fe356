"""Numeric findings: the step evaluated at random admissible points, and the null spaces
of its Jacobian there.

The residuals are analytic in the unknowns, the knowns and the parameters, so a determinant
that vanishes at several random points of an open set vanishes identically; a regular point
anywhere clears the system.  Points where the residuals are not finite are not evidence and
are replaced by others; a relative nudge of the inputs tells rounding noise from a small
value.  The points come from a fixed seed, so the findings are deterministic.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._errors import DomainError, ParameterError
from ..derivation import parameter_value, scaled_norm
from ._findings import (
    DEPENDENT_CONSTRAINTS,
    NOT_REGULAR,
    Finding,
    Layout,
    compose,
    listed,
    undetermined,
)

_SMALL = 1e-8     # rows this small (relative to max(1, the largest entry)) may be noise
_NUDGE = 1e-7     # relative move of the inputs that tells rounding noise from a function
_RANK = 1e-12     # singular values below this fraction of the largest one are zero
SUPPORT = 1e-3   # weight of a row/column in a null space that counts it as involved
POINTS = 3       # random points that must all agree before anything is concluded
_ATTEMPTS = 12    # points tried at most (non-finite ones are skipped)


def program_of(step):
    """The step's program over the expression graph, or None when the step is symbolic
    only (it uses undefined functions or other expressions code cannot evaluate)."""
    from .._errors import UnsupportedExpressionError

    try:
        return step.program
    except (UnsupportedExpressionError, AttributeError):
        return None



# --- numeric checks -------------------------------------------------------------------------

def random_point(step, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(unknowns, knowns, parameters) at random: the known arrows composable and drawn by the
    groupoid (group parts in the group), other knowns (multipliers, momenta) standard normal,
    parameters by :func:`parameter_value`, and the unknowns near the step's prediction."""
    G = step.groupoid
    arrows = step.arrows
    offsets = sorted(arrows)
    values: dict = {}
    previous = None
    for o in offsets[:-1]:
        a = G.random_arrow(rng) if previous is None else G.random_arrow(rng, G.target(previous))
        names, nums = (arrows[o], a) if previous is None else (G.fibre_of(arrows[o]),
                                                               G.fibre_of(a))
        values.update({s: float(v) for s, v in zip(names, nums) if isinstance(s, sp.Symbol)})
        previous = a
    knowns = np.array([values[s] if s in values else rng.normal() for s in step.knowns])
    params = np.array([parameter_value(s, rng) for s in step.parameters])
    guess = predicted_unknowns(step, knowns, params)
    n_chart = len(step.unknowns) - step.n_constraints
    chart = np.asarray(G.random_chart(rng), float)
    if chart.shape != (n_chart,):
        chart = rng.uniform(-0.5, 0.5, n_chart)
    delta = np.concatenate([0.2 * chart, 0.2 * rng.normal(size=step.n_constraints)])
    return guess + delta, knowns, params


def predicted_unknowns(step, knowns: np.ndarray, params: np.ndarray) -> np.ndarray:
    """The step's prediction of the unknowns at these knowns (0 where it is not a finite
    number, and everywhere when the step has none): from its program's ``predict`` output
    when it has one (NumPy, no SymPy evaluation), else from the SymPy expressions."""
    prediction = list(getattr(step, "prediction", []))
    if len(prediction) != len(step.unknowns):
        return np.zeros(len(step.unknowns))
    program = program_of(step)
    if program is not None and "predict" in program.outputs:
        with np.errstate(all="ignore"):
            guess = program.numpy_function(["predict"], ["known", "p"])(knowns, params)[0]
        return np.where(np.isfinite(guess), guess, 0.0)
    at = {s: sp.Float(v) for s, v in zip(step.knowns, knowns)}
    return np.array([_number(e, at) for e in prediction])


def _number(expr, at: dict) -> float:
    try:
        value = complex(sp.sympify(expr).xreplace(at).evalf())
    except (TypeError, ValueError, ZeroDivisionError):
        return 0.0
    return value.real if np.isfinite(value.real) and value.imag == 0 else 0.0


def numeric(step) -> bool:
    """Whether the residuals can be evaluated numerically: the step has a program (no
    undefined functions such as an abstract L_d(…), no unevaluated derivatives)."""
    return program_of(step) is not None


@dataclass
class Sample:
    """F and J at a random point, and at the same point with every input moved by a relative
    ``_NUDGE``: a genuine value moves by about that fraction, rounding noise by ~100 %."""

    F: np.ndarray
    J: np.ndarray
    F_nudged: np.ndarray
    J_nudged: np.ndarray


def _evaluate(step, u, k, p) -> tuple[np.ndarray, np.ndarray]:
    """F and J at one point; NaN where they are not finite there, or the point's parameters
    break their symbols' assumptions (``step.evaluate`` refuses such a point with a
    :class:`DomainError` or :class:`ParameterError`: here it is only left out)."""
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            F, J = step.evaluate(u, k, p)
        except (DomainError, ParameterError):  # (a nudged integer parameter, too)
            n = len(step.residuals)
            return np.full(n, np.nan), np.full((n, len(step.unknowns)), np.nan)
    return np.asarray(F, float), np.asarray(J, float)


def sample(step, points: int, seed: int) -> list[Sample]:
    """:class:`Sample` at ``points`` random points where everything is finite (fewer if
    not found).

    A point whose state cannot be drawn, or where F or J is not finite, is replaced by
    another; if ``step.evaluate`` itself fails (a function NumPy cannot evaluate), there is
    no numeric evidence at all and nothing is returned.  The samples of a step are drawn
    once (the structural and the numeric checks read the same ones).
    """
    memo = getattr(step, "__dict__", {}).setdefault("_regularity_samples", {})
    if (points, seed) not in memo:
        memo[(points, seed)] = _draw_samples(step, points, seed)
    return list(memo[(points, seed)])


def _draw_samples(step, points: int, seed: int) -> list[Sample]:
    rng = np.random.default_rng(seed)
    out: list[Sample] = []
    attempts = 0
    while len(out) < points and attempts < _ATTEMPTS:
        drawn = []
        while len(drawn) < points - len(out) and attempts < _ATTEMPTS:
            attempts += 1
            try:
                u, k, p = random_point(step, rng)
            except (ArithmeticError, ValueError, TypeError):
                continue
            nudge = [x * (1 + _NUDGE * rng.uniform(-1, 1, np.shape(x))) for x in (u, k, p)]
            drawn.append(((u, k, p), tuple(nudge)))
        if not drawn:
            break
        try:
            values = evaluate_points(step, [d[0] for d in drawn] + [d[1] for d in drawn])
        except Exception:  # noqa: BLE001 - no numeric evidence; the structural checks stand
            return []
        for i in range(len(drawn)):
            both = values[i] + values[len(drawn) + i]
            if all(np.all(np.isfinite(v)) for v in both):
                out.append(Sample(*both))
    return out


def evaluate_points(step, points: list) -> list[tuple[np.ndarray, np.ndarray]]:
    """(F, J) at each (u, k, p) of ``points``: a step's program walked once for all of them
    (:func:`symgroupoid.ir.interpret`, no code compiled), else ``step.evaluate`` per point."""
    from ..ir import interpret
    from ._step import StepEquations

    program = program_of(step)
    if type(step).evaluate is not StepEquations.evaluate or program is None:
        return [_evaluate(step, *point) for point in points]
    U, K, P = (np.stack([np.asarray(pt[i], float) for pt in points], axis=-1)
               for i in range(3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        F, J = interpret(program, ["F", "J"], ["u", "known", "p"], U, K, P)
    J = J.reshape((len(step), len(step.unknowns), len(points)))
    return [(F[:, b], J[:, :, b]) for b in range(len(points))]


def _vanishing(value: np.ndarray, nudged: np.ndarray, scale: float) -> np.ndarray:
    """Rows (of a vector or matrix) that are zero up to rounding: exactly zero, or small
    (≤ _SMALL·max(1, scale)) and changing by more than 10 % under the relative nudge of the
    inputs — rounding noise, where a genuine function of that size would move by ~_NUDGE."""
    value, nudged = np.atleast_2d(value.T).T, np.atleast_2d(nudged.T).T
    size = scaled_norm(value, axis=1)
    change = scaled_norm(nudged - value, axis=1)
    small = size <= _SMALL * max(1.0, scale)
    return (size == 0) | (small & (change > 0.1 * size))


def _zero_rows(s: Sample) -> np.ndarray:
    return _vanishing(s.J, s.J_nudged, float(np.max(np.abs(s.J), initial=0.0)))


def _zero_columns(s: Sample) -> np.ndarray:
    return _vanishing(s.J.T, s.J_nudged.T, float(np.max(np.abs(s.J), initial=0.0)))


def small_residuals(s: Sample) -> np.ndarray:
    """Residuals at most _SMALL relative to the sample's scale (candidates for zero)."""
    scale = float(max(np.max(np.abs(s.F), initial=0.0), np.max(np.abs(s.J), initial=0.0)))
    return np.abs(s.F) <= _SMALL * max(1.0, scale)


def zero_residuals(s: Sample) -> np.ndarray:
    scale = float(max(np.max(np.abs(s.F), initial=0.0), np.max(np.abs(s.J), initial=0.0)))
    return _vanishing(s.F, s.F_nudged, scale)


def _equilibrated(J: np.ndarray) -> np.ndarray:
    r = scaled_norm(J, axis=1)
    J = J / np.where(r > 0, r, 1.0)[:, None]
    c = scaled_norm(J, axis=0)
    return J / np.where(c > 0, c, 1.0)[None, :]


def _null_spaces(J: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Numerical rank of the equilibrated J and bases of its left and right null spaces."""
    U, s, Vt = np.linalg.svd(_equilibrated(J))
    rank = int(np.sum(s > _RANK * s[0])) if s.size and s[0] > 0 else 0
    return rank, U[:, rank:], Vt[rank:].T


def _support(basis: np.ndarray) -> set[int]:
    return set(np.flatnonzero(np.linalg.norm(basis, axis=1) > SUPPORT).tolist())


def numeric_findings(step, layout: Layout, points: int = POINTS,
                     seed: int = 0) -> list[Finding]:
    """Zero rows/columns and rank deficiency of the Jacobian, each required at every sampled
    point; nothing is concluded from fewer than ``points`` finite samples."""
    if not numeric(step):
        return []
    samples = sample(step, points, seed)
    n = len(layout.labels)
    if len(samples) < points or any(s.J.shape != (n, n) for s in samples):
        return []
    zero_rows = np.all([_zero_rows(s) for s in samples], axis=0)
    zero_cols = np.all([_zero_columns(s) for s in samples], axis=0)
    if zero_rows.any() or zero_cols.any():
        vanish = np.all([zero_residuals(s) for s in samples], axis=0)
        rows = np.flatnonzero(zero_rows)
        zero = [int(i) for i in rows if vanish[i]]
        idle = [int(i) for i in rows if not vanish[i]]
        return compose(layout, zero, idle, [int(j) for j in np.flatnonzero(zero_cols)])
    spaces = [_null_spaces(s.J) for s in samples]
    if any(rank == n for rank, _, _ in spaces):
        return []
    return [_classify(layout, samples, spaces)]


def _classify(layout: Layout, samples, spaces) -> Finding:
    """Dependent constraint rows, then dependent multiplier columns, else not regular."""
    rows, cols = layout.constraint_rows, layout.multiplier_columns
    if rows:
        sub = [_null_spaces(s.J[rows, :]) for s in samples]
        if all(rank < len(rows) for rank, _, _ in sub):
            involved = sorted(set().union(*(_support(left) for _, left, _ in sub)))
            names = [layout.constraint_names[i] for i in involved]
            lam = tuple(layout.unknowns[cols[i]] for i in involved) if cols else ()
            text = (f"The constraints {listed(names)} are dependent (their derivatives on the "
                    "unknown arrow are linearly dependent at every sampled point), so the "
                    "constraint set is not cut out by independent equations"
                    + (f" and the multipliers {listed(lam)} are not determined" if lam else "")
                    + "; remove the redundant constraints.")
            return Finding(DEPENDENT_CONSTRAINTS, tuple(layout.labels[rows[i]]
                                                        for i in involved), lam, text)
    if cols:
        sub = [_null_spaces(s.J[:, cols]) for s in samples]
        if all(rank < len(cols) for rank, _, _ in sub):
            involved = sorted(set().union(*(_support(right) for _, _, right in sub)))
            return undetermined(layout, [cols[i] for i in involved], dependent=True)
    rank = max(r for r, _, _ in spaces)
    unknowns = sorted(set().union(*(_support(right) for _, _, right in spaces)))
    equations = sorted(set().union(*(_support(left) for _, left, _ in spaces)))
    eqs = tuple(layout.labels[i] for i in equations)
    names = tuple(layout.unknowns[j] for j in unknowns)
    on = " on the constraint set" if rows else ""
    text = (f"The step Jacobian is singular at every sampled point (rank {rank} of "
            f"{len(layout.labels)}): the discrete Lagrangian is not regular{on} (seed 000 "
            f"Thm 2.16); the dependent equations are {listed(eqs)}, and the unknowns "
            f"{listed(names)} are not determined along the null directions.")
    return Finding(NOT_REGULAR, eqs, names, text)


