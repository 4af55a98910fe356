"""The compiled Newton stepper and its NumPy mirror: the LU with its one-pass row scan, the
single finiteness test of a solve, the norms, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SEED_DATA,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
)

from symgroupoid.runtime._backends import (
    NON_FINITE,
    OK,
    SINGULAR_JACOBIAN,
    lu_apply,
    lu_factor,
    norm_inf,
)


@needs_cc
@pytest.mark.parametrize("name", ["plate_ball", "heavy_top", "rigid_body"])
def test_c_and_numpy_steppers_agree_bit_for_bit(name):
    """Same iterations, residual norms and states: the C loops (unrolled for few unknowns) do
    the operations of the NumPy mirror in the same order."""
    c_sim, np_sim = compiled(name), compiled(name, backend="numpy")
    params = SEED_DATA[name][0]
    state = initial_state(c_sim, name)
    a, b = c_sim.simulate(state, 25, params), np_sim.simulate(state, 25, params)
    assert np.array_equal(a.states, b.states)
    assert np.array_equal(a.newton_iterations, b.newton_iterations)
    assert np.array_equal(a.residual_norms, b.residual_norms)


def test_norm_inf_returns_the_first_non_finite_entry():
    assert norm_inf(np.array([1.0, -3.0, 2.0])) == 3.0
    assert np.isnan(norm_inf(np.array([1.0, np.nan, -np.inf])))
    assert norm_inf(np.array([1.0, -np.inf, np.nan])) == np.inf


def test_lu_statuses_follow_the_first_failing_row():
    """A zero row before a non-finite one is singular, the other way round non-finite."""
    assert lu_factor(np.array([[0.0, 0.0], [np.nan, 1.0]]))[0] == SINGULAR_JACOBIAN
    assert lu_factor(np.array([[np.inf, 0.0], [0.0, 0.0]]))[0] == NON_FINITE


def test_an_overflowing_scaled_right_hand_side_is_non_finite():
    """b scaled by 2^-e can overflow; the single test of x catches it (b is not tested first)."""
    status, factors = lu_factor(np.diag([1e-300, 1.0]))
    assert status == OK
    assert lu_apply(factors, [1e300, 1.0])[0] == NON_FINITE
    assert lu_apply(factors, [np.nan, 1.0])[0] == NON_FINITE
    assert lu_apply(factors, [1e-300, 1.0])[0] == OK


@needs_cc
@pytest.mark.parametrize("name", ["rigid_body", "plate_ball"])
def test_runaway_guesses_are_never_returned_as_solutions(name: str) -> None:
    """Guesses up to 10⁸ from the solution: Newton may run away to |u| ~ 10⁹⁰, where its
    relative updates are tiny and the pivots' ratio huge.  Such an iterate was returned as
    converged with |F| = 99 (rigid body) or 0.02 (plate-ball); every OK now has a residual a
    rounding-level update explains, in C and in NumPy alike."""
    rng = np.random.default_rng(1)
    sim = compiled(name)
    mirror = compiled(name, backend="numpy")
    state = initial_state(sim, name)
    p = sim.parameters(SEED_DATA[name][0])
    solved = 0
    for trial in range(600):
        guess = rng.standard_normal(sim.kernel.n_u) * 10.0 ** rng.uniform(-1, 8)
        status, u, _, norm = sim.kernel.solve_step(state, p, guess, sim.options)
        if status == 0:
            solved += 1
            assert norm <= 1e-10, (trial, norm, np.abs(u).max())
        if trial < 150:  # the NumPy mirror agrees bit for bit
            same = mirror.kernel.solve_step(state, p, guess, mirror.options)
            assert same[0] == status and np.array_equal(same[1], u), trial
    assert solved > 50  # the nearer guesses still converge
