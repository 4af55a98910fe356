"""Discrete optimal control examples (seed 000 §6.1, §6.2), solved as two-point problems."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from conftest import load_example

import symgroupoid as sg


@pytest.fixture(scope="module")
def lie():
    return load_example("optimal_control_lie_groups")


@pytest.fixture(scope="module")
def plate():
    return load_example("plate_ball_steering")


def _constraint_values(system, arrows, params):
    fs = system._fs
    f = sp.lambdify([list(fs.slots[0]), list(system.parameters)], fs.constraints, "numpy")
    return np.array([np.asarray(f(a, params), float) for a in arrows])


@pytest.mark.parametrize("retraction", ["cayley", "exp"])
def test_so3_without_third_axis_control(lie, retraction):
    """ψ(ξ) = ξ₃ = 0 on every step, end attitude reached, action stationary."""
    sol = lie.solve_so3(retraction, steps=40)
    system = lie.so3_problem(retraction)
    assert sol.residual_norm < 1e-10
    assert np.abs(_constraint_values(system, sol.arrows, [1 / 40])).max() < 1e-12
    assert np.allclose(sol.configurations[-1], lie.rotation([0.6, -0.4, 0.9]), atol=1e-10)
    assert sg.verify_stationary(sol, system).stationary


@pytest.mark.parametrize("retraction", ["cayley", "exp"])
def test_se2_unicycle(lie, retraction):
    """No sideways velocity; the optimum is cheaper than the feasible three-arc path."""
    sol = lie.solve_se2(retraction, steps=45)
    system = lie.se2_problem(retraction)
    guess, end = lie.unicycle_path(retraction, 45)
    assert sol.residual_norm < 1e-10
    assert np.abs(sol.controls[:, 2]).max() < 1e-12
    assert np.allclose(sol.configurations[-1], end, atol=1e-10)
    def cost(arrows):
        x = np.array([system.groupoid.fibre_chart_inverse(a) for a in arrows]) * 45
        return 0.5 * np.sum(x[:, 0] ** 2 + x[:, 1] ** 2) / 45
    assert cost(sol.arrows) < cost(guess)
    assert sg.verify_stationary(sol, system).stationary


def test_plate_ball_steering(plate):
    """Seed 000 §6.2 as a steering problem: constraints hold on every arrow, the end
    configuration is reached, the cost drops below the rolled guess, and it is stationary."""
    system, sol, guess, params = plate.solve(steps=30)
    assert sol.residual_norm < 1e-10
    assert np.abs(_constraint_values(system, sol.arrows, list(params))).max() < 1e-12
    R = np.eye(3)
    for a in sol.arrows:
        R = R @ a[4:].reshape(3, 3)
    assert np.allclose(R, sol.configurations[-1][1], atol=1e-12)
    assert plate.cost(sol.arrows, params[0]) < plate.cost(guess, params[0])
    assert sg.verify_stationary(sol, system).stationary
