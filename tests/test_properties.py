"""Property tests (hypothesis).

1. Left- and right-invariant vector fields commute, [X⃖, Y⃗] = 0 (seed 000 §2.1, eqs. (1)–(2):
   X⃖ generates right translations, Y⃗ left translations, and these commute by associativity):
   for random arrows and random test functions f, X⃖[Y⃗[f]] = Y⃗[X⃖[f]].
2. The exact step Jacobian agrees with central finite differences of the residual through
   ``StepEquations.evaluate`` at random points: plate-ball (seed 000 §6.2), heavy top (seed 002),
   optimal control on SE(2) with the Cayley retraction (seed 000 §6.1).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import pytest
import sympy as sp
from _systems import (
    heavy_top_groupoid,
    heavy_top_system,
    plate_ball_system,
    se2_control_system,
)
from hypothesis import given, settings
from hypothesis import strategies as st

import symgroupoid as sg

SETTINGS = settings(max_examples=20, deadline=None)
seeds = st.integers(min_value=0, max_value=2**32 - 1)

# --- 1. [X⃖, Y⃗] = 0 -----------------------------------------------------------------------

GROUPOIDS: dict[str, Callable[[], sg.Groupoid]] = {
    "pair R2": lambda: sg.PairGroupoid(sg.EuclideanSpace("x y")),
    "SO3": lambda: sg.SO3("g"),
    "SE2": lambda: sg.SE2("s"),
    "SE3": lambda: sg.SE3("s"),
    "action S2 x SO3": heavy_top_groupoid,
    "product pair x SO3": lambda: sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("g"),
    "time R x R x SE2": lambda: sg.TimeGroupoid(sg.SE2("s")),
}


@functools.cache
def _fields(name: str):
    """The groupoid, the polynomial ring of its arrow coordinates, and the left/right fields.

    For all built-in groupoids the components of X⃖, X⃗ are polynomials in the arrow coordinates
    (matrix entries, points), so they are computed exactly in Q[a₀, …, a_n].
    """
    G = GROUPOIDS[name]()
    a = sp.symbols(f"a0:{G.arrow_dim}")
    R, *_ = sp.ring(a, sp.QQ)

    def to_ring(fields):
        return [[R.from_expr(sp.sympify(c)) for c in v] for v in fields]

    return G, R, to_ring(G.left_field(a)), to_ring(G.right_field(a))


def _apply(field: list, f):
    """The derivative of f along the vector field with components ``field``."""
    gens = f.ring.gens
    return sum((f.diff(x) * v for x, v in zip(gens, field) if v), f.ring.zero)


def _random_function(R, rng: np.random.Generator):
    """A random polynomial test function: a linear form plus four monomials of degree 2–4 in
    randomly chosen coordinates (so first and mixed second derivatives both enter)."""
    a = R.gens
    f = sum((int(w) * x for w, x in zip(rng.integers(-3, 4, size=len(a)), a)), R.zero)
    for _ in range(4):
        coeff = sp.QQ(int(rng.integers(-9, 10)), int(rng.integers(1, 5)))
        idx = rng.choice(len(a), size=3)
        f += coeff * a[idx[0]] * a[idx[1]] ** int(rng.integers(0, 2)) * a[idx[2]] ** 2
    return f


def _random_point(G: sg.Groupoid, rng: np.random.Generator) -> list:
    """A random arrow of G, its floating-point coordinates converted exactly to rationals."""
    return [sp.QQ.convert(sp.Rational(float(v))) for v in G.random_arrow(rng)]


@pytest.mark.parametrize("name", sorted(GROUPOIDS))
@SETTINGS
@given(seed=seeds)
def test_left_and_right_invariant_fields_commute(name: str, seed: int) -> None:
    """Seed 000 eqs. (1)–(2): X⃖_i[Y⃗_j[f]](g) = Y⃗_j[X⃖_i[f]](g) for all basis sections i, j,
    a random polynomial f and a random arrow g — exactly, in rational arithmetic."""
    rng = np.random.default_rng(seed)
    G, R, left, right = _fields(name)
    f = _random_function(R, rng)
    point = _random_point(G, rng)
    for i in range(G.rank):
        for j in range(G.rank):
            lr = _apply(left[i], _apply(right[j], f))
            rl = _apply(right[j], _apply(left[i], f))
            assert lr(*point) == rl(*point), (i, j)


@SETTINGS
@given(seed=seeds)
def test_left_fields_do_not_commute_on_so3(seed: int) -> None:
    """Control for the property above: two *left*-invariant fields on SO(3) do not commute —
    [E⃖₁, E⃖₂] = E⃖₃ for the so(3) basis of seed 000 §6.2 — so the check can detect a
    non-commuting pair."""
    rng = np.random.default_rng(seed)
    G, R, left, _ = _fields("SO3")
    f = _random_function(R, rng)
    bracket = _apply(left[0], _apply(left[1], f)) - _apply(left[1], _apply(left[0], f))
    assert bracket == _apply(left[2], f)
    assert bracket != 0


# --- 2. Jacobian against finite differences ------------------------------------------------

@functools.cache
def _step(name: str) -> sg.StepEquations:
    return {"plate_ball": plate_ball_system, "heavy_top": heavy_top_system,
            "oc_se2": se2_control_system}[name]().euler_lagrange()


def _random_state(step: sg.StepEquations, rng: np.random.Generator):
    """Random knowns (an arrow g_k of the groupoid and λ_k), unknowns and positive parameters."""
    G = step.groupoid
    m = step.n_constraints
    known = np.concatenate([G.random_arrow(rng), rng.uniform(-1.0, 1.0, m)])
    unknown = np.concatenate([G.random_chart(rng), rng.uniform(-1.0, 1.0, m)])
    params = rng.uniform(0.2, 1.5, len(step.parameters))
    return unknown, known, params


# Central differences with δ = 1e-5: truncation error δ²/6·|F'''| ≈ 2e-11·|F'''| and rounding
# error ≈ ε_mach·|F|/δ ≈ 2e-11·|F|; with residuals and their derivatives of order 1–100 at
# these points the FD error is ≲ 1e-8.  The tolerance 1e-7 (times the scale of J) leaves a
# margin while any wrong Jacobian entry (an O(1) discrepancy) fails by orders of magnitude.
FD_STEP = 1e-5
FD_TOL = 1e-7


@pytest.mark.parametrize("name", ["plate_ball", "heavy_top", "oc_se2"])
@SETTINGS
@given(seed=seeds)
def test_jacobian_matches_finite_differences(name: str, seed: int) -> None:
    """The exact Jacobian ∂F/∂(unknowns) through the α-fibre chart (docs/conventions.md §2) equals
    central differences of F at random points (seed 000 §6.2, seed 002, seed 000 §6.1)."""
    step = _step(name)
    rng = np.random.default_rng(seed)
    u, known, params = _random_state(step, rng)
    F0, J = step.evaluate(u, known, params)
    assert J.shape == (len(step), len(step.unknowns))
    fd = np.empty_like(J)
    for j in range(len(u)):
        du = np.zeros_like(u)
        du[j] = FD_STEP
        fp, _ = step.evaluate(u + du, known, params)
        fm, _ = step.evaluate(u - du, known, params)
        fd[:, j] = (fp - fm) / (2 * FD_STEP)
    scale = max(1.0, float(np.abs(J).max()))
    assert np.abs(fd - J).max() <= FD_TOL * scale, np.abs(fd - J).max()
