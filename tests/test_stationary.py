"""verify_stationary: computed trajectories are critical points of the discrete action
(seed 000 §5; seed 001 §3.2), checked independently of the derived equations."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from conftest import newton, predicted

import symgroupoid as sg
from symgroupoid.verification import action


def _march(step, known, params, n):
    states = [np.asarray(known, float)]
    for _ in range(n):
        k = states[-1]
        u = newton(step, predicted(step, k, params), k, params)
        states.append(step.advance(u, k, params))
    return np.array(states)


def test_plate_ball_trajectory_is_stationary_and_a_perturbed_one_is_not(plate_ball,
                                                                         plate_ball_step):
    """Constrained: vary arrows at every interior junction and the multipliers."""
    system, _ = plate_ball
    params = [0.1, 1.0, 0.5, 0.3]
    W = np.array(sg.SO3("g").cayley([0.0, 0.0, -0.06]).tolist(), float)  # tr(W E3)/2h = −c
    known = np.concatenate([[0.0, 0.0, 0.05, 0.02], W.ravel(), [0.1, -0.2, 0.05]])
    states = _march(plate_ball_step, known, params, 12)[1:]  # states satisfying φ = 0
    arrows, lam = states[:, :13], states[:, 13:]
    report = sg.verify_stationary(arrows, system, params, multipliers=lam)
    assert report.stationary, report
    bent = arrows.copy()
    bent[5, 2] += 1e-3  # move one interior point off the solution
    bent[6, 0] += 1e-3
    assert not sg.verify_stationary(bent, system, params, multipliers=lam).stationary


def test_heavy_top_trajectory_is_stationary(heavy_top, heavy_top_step):
    system, _ = heavy_top
    params = [0.05, 1.0, 9.81, 0.3, 1.0, 1.3, 0.7]
    G0 = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    W = np.array(sg.SO3("W").cayley([0.02, -0.05, 0.08]).tolist(), float)
    arrows = _march(heavy_top_step, np.concatenate([G0, W.ravel()]), params, 10)
    assert sg.verify_stationary(arrows, system, params).stationary
    assert action(system, arrows, None, params) != 0


def test_second_order_pair_trajectory_is_stationary():
    """Seed 001 eq. (16) on a cubic-spline-like second-order Lagrangian."""
    h = sp.Symbol("h", positive=True)
    Q = sg.EuclideanSpace("q")
    system = sg.SecondOrderSystem(
        sg.PairGroupoid(Q),
        lambda a, b: ((b.target[0] - 2 * a.target[0] + a.source[0]) / h ** 2) ** 2 * h / 2
        + sp.cos(a.target[0]) * h, parameters=[h], name="spline")
    step = system.euler_lagrange()
    known = np.array([0.0, 0.1, 0.25, 0.45])  # q_{k-2} … q_{k+1}
    states = _march(step, known, [0.1], 8)
    points = list(states[0]) + [s[-1] for s in states[1:]]
    arrows = np.array([[points[i], points[i + 1]] for i in range(len(points) - 1)])
    assert sg.verify_stationary(arrows, system, [0.1]).stationary
    arrows[4, 1] += 1e-3
    arrows[5, 0] += 1e-3
    assert not sg.verify_stationary(arrows, system, [0.1]).stationary


def test_lie_group_and_time_dependent_trajectories_are_stationary():
    """Discrete Euler–Poincaré (seed 000 §6.1) and the adaptive time step (§6.3, Ex. 6.1):
    the variations include the time section, so energy balance is part of the check."""
    inertia = sp.diag(1, 2, 3)

    def L_rb(g):
        xi = g.coordinates / h_
        return h_ * (xi.T * inertia * xi)[0, 0] / 2

    h_ = sp.Symbol("h", positive=True)
    rb = sg.DiscreteSystem(sg.SO3("W"), L_rb, parameters=[h_], name="ep")
    W = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    arrows = _march(rb.euler_lagrange(), W.ravel(), [0.05], 8)
    assert sg.verify_stationary(arrows, rb, [0.05]).stationary

    def L_t(g):
        dt = g.t1 - g.t0
        xi = g.coordinates / dt
        return dt * (xi.T * inertia * xi)[0, 0] / 2

    timed = sg.DiscreteSystem(sg.TimeGroupoid(sg.SO3("W")), L_t, name="adaptive")
    arrows = _march(timed.euler_lagrange(), np.concatenate([[0.0, 0.05], W.ravel()]), [], 8)
    assert sg.verify_stationary(arrows, timed, []).stationary
    arrows[4, 1] += 1e-4  # shift one intermediate time: no longer critical
    arrows[5, 0] += 1e-4
    assert not sg.verify_stationary(arrows, timed, []).stationary


def test_time_groupoid_check_does_not_depend_on_when_the_run_started():
    """L_d reads t through t_{k+1} − t_k: the same run started at t = 100 (a run resumed
    later) is as stationary as at t = 0, and a shifted intermediate time still fails.  (The
    time section was varied by ε·|t|, 0.1 at t = 100 against steps of 0.05.)"""
    inertia = sp.diag(1, 2, 3)

    def L_t(g):
        dt = g.t1 - g.t0
        xi = g.coordinates / dt
        return dt * (xi.T * inertia * xi)[0, 0] / 2

    timed = sg.DiscreteSystem(sg.TimeGroupoid(sg.SO3("W")), L_t, name="adaptive_late")
    W = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    arrows = _march(timed.euler_lagrange(), np.concatenate([[0.0, 0.05], W.ravel()]), [], 8)
    for start in (100.0, 1e4):
        late = arrows.copy()
        late[:, :2] += start
        assert sg.verify_stationary(late, timed, []).stationary, start
        late[4, 1] += 1e-4
        late[5, 0] += 1e-4
        assert not sg.verify_stationary(late, timed, []).stationary, start


def _relativistic():
    """A relativistic particle in a harmonic well, L_d = −h√(1 − ((q₁ − q₀)/h)²) − h q̄²/2:
    defined for speeds below 1 only."""
    h = sp.Symbol("h", positive=True)

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return -h * sp.sqrt(1 - ((q1 - q0) / h) ** 2) - h * ((q0 + q1) / 2) ** 2 / 2

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h],
                             name="relativistic")


def test_a_trajectory_at_the_edge_of_the_domain_is_checked_with_smaller_variations():
    """A solution whose speeds are 0.99, within 1e-3 of the edge of L_d's domain: variations
    of the default size ε = 1e-3 left it, and the report said "not stationary" with a NaN
    scale.  The variations are now made smaller until the varied action is finite; a
    perturbed path there is still refuted, and a path on the edge itself is refused."""
    system = _relativistic()
    sol = sg.solve_boundary_value(system.euler_lagrange(), 0.0, 0.99, 10, params={"h": 0.1})
    assert np.diff(sol.arrows, axis=1).max() / 0.1 > 0.989
    report = sg.verify_stationary(sol, system)
    assert report and np.isfinite(report.scale) and max(report.derivatives) < 1e-3
    bent = sol.arrows.copy()
    bent[4, 1] += 1e-4
    bent[5, 0] += 1e-4
    assert not sg.verify_stationary(bent, system, [0.1], multipliers=np.zeros((10, 0)))
    edge = np.array([[k / 8, (k + 1) / 8] for k in range(10)])  # speed 1 exactly: the edge
    with pytest.raises(sg.DomainError, match="varied action is not finite at any variation"):
        sg.verify_stationary(edge, system, [1 / 8], multipliers=np.zeros((10, 0)))
