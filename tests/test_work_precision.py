"""benchmarks/work_precision.py and its models (benchmarks/_chain_models.py): the
reference's equations (Euler's equations for one free body, energy conserved by DOP853),
the conversions to MuJoCo's ball-joint coordinates, the interpolation of the targets, and
schemes refused by the library reported as "not implemented"; the quick run itself is slow
(it builds two kernels)."""

import math

import numpy as np
import pytest
from kernel_support import benchmark_module
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import symgroupoid as sg

wp = benchmark_module("work_precision")
models = benchmark_module("_chain_models")


def test_one_free_body_gives_eulers_equations():
    """For one body with ρ = 0 the derived Euler–Poincaré equations are J ξ̇ = Jξ × ξ (the
    sign of the ξ × ∂L/∂ξ term of the left-trivialised equations)."""
    assert wp.check_rigid_body()


def test_the_heavy_top_reference_conserves_energy_and_vertical_momentum():
    """One body pinned at the origin (a heavy top): DOP853 at 1e-12 on the derived
    equations keeps E and the angular momentum about the vertical to 1e-10 over 2 s, and
    the attitudes on SO(3)."""
    ode = models.ChainODE.build(1)
    y0 = ode.state([Rotation.from_rotvec([0.6, 0.2, 0.0]).as_matrix()], [0.5, -0.3, 0.8])
    sol = solve_ivp(ode.rhs, (0, 2.0), y0, method="DOP853", rtol=1e-12, atol=1e-12)
    yT = sol.y[:, -1]
    assert abs(ode.energy(yT) - ode.energy(y0)) < 1e-10
    assert abs(ode.vertical_momentum(yT) - ode.vertical_momentum(y0)) < 1e-10
    assert abs(ode.energy(yT) - ode.energy(y0 * 1.01)) > 1e-3  # (E does depend on y)
    R = ode.attitudes(yT)[0]
    assert np.abs(R.T @ R - np.eye(3)).max() < 1e-10


def test_mujoco_coordinates_round_trip():
    """(R_i, ξ_i) → (qpos, qvel) of the ball joints → (R_i, ξ_i), without MuJoCo."""
    attitudes, xi = wp.initial_data()
    qpos, qvel = models.mujoco_state(attitudes, xi)
    assert np.allclose(np.linalg.norm(qpos.reshape(3, 4), axis=1), 1)
    y = wp.chain_states(qpos[None, :], qvel[None, :])[:, 0]
    assert np.abs(y[:27] - np.concatenate([R.ravel() for R in attitudes])).max() < 1e-14
    assert np.abs(y[27:] - xi).max() < 1e-14
    # a rotation by π about x (the branch of the quaternion's largest diagonal entry)
    flip = np.diag([1.0, -1.0, -1.0])
    assert np.allclose(Rotation.from_quat(np.roll(models._quaternion(flip), -1)).as_matrix(),
                       flip)


def test_the_targets_interpolate_on_log_scales():
    """time_at: the cost of an error level along a method's front (log–log); step_at: the h
    of an error level; None outside the points."""
    P = wp.Point
    points = [P("a", "", 100, 1e-4, 0.1, 0.05, 0.04), P("a", "", 1000, 1e-6, 1.0, 0.5, 0.4),
              P("a", "", 200, 1e-3, 5.0, 2.5, 2.0)]  # (a dominated point: not on the front)
    assert math.isclose(wp.time_at(points, "a", 1e-5), math.sqrt(0.05 * 0.5))
    assert wp.time_at(points, "a", 1e-7) is None
    assert math.isclose(wp.time_at(points, "a", 1e-2), 0.05)
    assert math.isclose(wp.time_at(points, "a", 1e-5, "cpu_per_second"), math.sqrt(0.04 * 0.4))
    assert math.isclose(wp.step_at(points[:2], "a", 1e-5), wp.T_FINAL / math.sqrt(1e5))
    assert wp.step_at(points, "a", 1e-9) is None
    assert not wp.past_floor(points[:2], "a") and wp.past_floor(points, "a")


def test_schemes_the_library_refuses_are_reported_not_implemented(monkeypatch):
    """A scheme whose discretisation is refused is reported, not a crash of the run."""
    def refused(scheme):
        raise sg.UnsupportedFeatureError(f"{scheme} is refused here")

    monkeypatch.setattr(wp, "SCHEMES", (("GaussLegendre(3)", sg.GaussLegendre(3), 6),))
    monkeypatch.setattr(wp, "build_scheme", refused)
    results = wp.Results("here", "now")
    assert wp.library_points(results, None, quick=True) == {}
    assert results.status == {"GaussLegendre(3)": "not implemented"} and results.points == []


@pytest.mark.slow
def test_the_quick_run(tmp_path):
    """The smoke run: the midpoint scheme converges to the reference at order 2 (and
    MuJoCo's RK4, where installed, at order 4: the models match); the figure is written."""
    figure = tmp_path / "wp.png"
    results = wp.main(["--quick", "--figure", str(figure)])
    assert figure.stat().st_size > 0
    assert results.reference["energy_change"] <= 1e-10
    assert abs(results.orders["midpoint"] - 2) < 0.1
    assert results.status["GaussLegendre(2)"] in ("ok", "not implemented")
    if results.status["MuJoCo RK4"].startswith("ok"):
        assert abs(results.orders["MuJoCo RK4"] - 4) < 0.2
    else:
        assert results.status["MuJoCo RK4"] == "not installed"
