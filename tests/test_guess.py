"""The Newton guess of a step: linear or quadratic extrapolation of the last solutions, chosen
by hindsight (``<prefix>_extrapolate`` / ``<prefix>_remember`` and their NumPy twins).

Smooth motion takes the quadratic guess (its error O(h³) against O(h²)), which cuts Newton's
updates; an oscillation of few steps per period, where higher order extrapolates worse, keeps
the linear one; C and NumPy choose alike, bit for bit, and a warm start reset to count 0
forgets the old choice.
"""

from __future__ import annotations

import numpy as np
import pytest
from _hostile import oscillator
from kernel_support import BACKENDS, isolated_cache, needs_cc  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid.stepper import NumpyWarmStart
from symgroupoid.systems import planar_chain

CHAIN_PARAMS = {"h": 0.01, "g": 9.81}


def chain_state(n: int) -> np.ndarray:
    """A swinging planar chain: θ_0,j = 0.6 cos(0.9 j), θ̇_0,j = 0.4 sin(1.3 j)."""
    j = np.arange(1, n + 1)
    theta = 0.6 * np.cos(0.9 * j)
    return np.concatenate([theta - CHAIN_PARAMS["h"] * 0.4 * np.sin(1.3 * j), theta])


def remembered(sequence) -> NumpyWarmStart:
    warm = NumpyWarmStart(0, np.zeros(1), np.zeros(1), np.zeros(1))
    for value in sequence:
        warm.remember(np.array([float(value)]))
    return warm


def test_hindsight_prefers_the_extrapolation_that_would_have_guessed_better():
    """A quadratic sequence is guessed exactly by the quadratic extrapolation; cos(2.5 k)
    (2.5 steps per period) is guessed worse by it than by the linear one."""
    k = np.arange(8)
    smooth = remembered(k ** 2 - 3 * k)
    assert smooth.count == 3 and smooth.quadratic
    assert smooth.extrapolate()[0] == 8 ** 2 - 3 * 8
    fast = remembered(np.cos(2.5 * k))
    assert fast.count == 3 and not fast.quadratic
    assert fast.extrapolate()[0] == 2 * np.cos(2.5 * 7) - np.cos(2.5 * 6)
    # two or three solutions remembered: no hindsight yet, the linear guess
    assert not remembered(k[:3] ** 2).quadratic and not remembered(k[:2] ** 2).quadratic


@pytest.mark.parametrize("backend", BACKENDS)
def test_smooth_motion_takes_the_quadratic_guess_and_fewer_updates(backend):
    """The planar 4-link chain: from step 4 on the quadratic guess is taken, and Newton needs
    on average at most 3.5 updates (5.2 with the linear guess alone)."""
    step = planar_chain(4).euler_lagrange()
    sim = step.compile(backend=backend)
    kernel, warm = sim.kernel, sim.kernel.warm_start()
    run = kernel.simulate(chain_state(4), sim.parameters(CHAIN_PARAMS), 400, sim.options, warm)
    assert run.status == 0 and warm.count == 3 and warm.quadratic
    assert np.mean(run.iterations[4:]) <= 3.5


@needs_cc
def test_c_and_numpy_choose_alike_bit_for_bit():
    """The same states, iterations, residuals and final warm start in C and NumPy, on a
    smooth system (the chain) and on an oscillator stepped at h·ω = 2 (π steps per period),
    where the linear guess is kept."""
    cases = [(planar_chain(3), chain_state(3), CHAIN_PARAMS, 60, True),
             (oscillator(), np.array([1.0, 0.9]), {"h": 0.1, "k": 400.0}, 60, False)]
    for system, state, params, steps, quadratic in cases:
        step = system.euler_lagrange()
        runs = []
        for backend in ("c", "numpy"):
            sim = step.compile(backend=backend)
            warm = sim.kernel.warm_start()
            run = sim.kernel.simulate(state, sim.parameters(params), steps, sim.options, warm)
            assert run.status == 0
            runs.append((run, warm))
        (a, wa), (b, wb) = runs
        assert np.array_equal(a.states, b.states), system.name
        assert np.array_equal(a.iterations, b.iterations), system.name
        assert np.array_equal(a.residual_norms, b.residual_norms), system.name
        assert (wa.count, bool(wa.quadratic)) == (wb.count, wb.quadratic) == (3, quadratic)
        for name in ("u_last", "u_before", "u_earlier"):
            assert np.array_equal(list(getattr(wa, name)), getattr(wb, name)), name


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_warm_start_reset_to_count_zero_is_a_fresh_start(backend):
    """A used warm start (quadratic chosen) with count set to 0 gives bitwise the run of a
    zeroed one: the old choice and solutions are forgotten."""
    step = planar_chain(3).euler_lagrange()
    sim = step.compile(backend=backend)
    kernel, p = sim.kernel, sim.parameters(CHAIN_PARAMS)
    used = kernel.warm_start()
    first = kernel.simulate(chain_state(3), p, 50, sim.options, used)
    assert used.quadratic
    used.count = 0
    again = kernel.simulate(first.states[-1], p, 30, sim.options, used)
    fresh = kernel.simulate(first.states[-1], p, 30, sim.options, kernel.warm_start())
    assert np.array_equal(again.states, fresh.states)
    assert np.array_equal(again.iterations, fresh.iterations)


def test_newton_options_still_turn_extrapolation_off():
    """extrapolate=False: every step from the prediction, the same solutions to rounding."""
    step = planar_chain(3).euler_lagrange()
    sim = step.compile(backend="numpy")
    a = sim.simulate(chain_state(3), 30, CHAIN_PARAMS)
    b = sim.simulate(chain_state(3), 30, CHAIN_PARAMS,
                     options=sg.NewtonOptions(extrapolate=False))
    assert np.max(np.abs(a.states - b.states)) <= 1e-13
    assert np.mean(b.newton_iterations) > np.mean(a.newton_iterations)


@pytest.mark.parametrize("field, value", [("count", 4), ("count", -1), ("quadratic", 2),
                                          ("quadratic", "yes")])
def test_numpy_refuses_a_damaged_warm_start(field, value):
    """As the C kernel's INVALID_ARGUMENT: a count outside 0…3 or a choice other than
    True/False is refused by name before any step."""
    sim = planar_chain(2).euler_lagrange().compile(backend="numpy")
    warm = sim.kernel.warm_start()
    setattr(warm, field, value)
    with pytest.raises(sg.ShapeError, match="warm start"):
        sim.kernel.simulate(chain_state(2), sim.parameters(CHAIN_PARAMS), 3, sim.options, warm)
