"""verify_stationary for discrete Lagrangians with internal stages (docs/conventions.md §22):
the stages of every arrow are solved from the system's own stage rows ∂L/∂ζ + f_ζ = 0, then
held while the arrows vary (the envelope theorem), and the (forced) variational principle is
checked as for any system.

Simulated runs of Galerkin discretisations pass, on R² (a double pendulum, Gauss–Legendre
and Lobatto IIIA–IIIB) and on the pair groupoid of SO(3) (a rigid body); the same runs with
one configuration moved, with the forces dropped or with the inputs shifted by one arrow
fail; stages without a root are reported, not checked at a non-solution.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation
from test_stage_bvp import BODY, PEND, double_pendulum, rigid_body, taus

import symgroupoid as sg
from symgroupoid.diagnostics import DiagnosticsError

h = sp.Symbol("h", positive=True)


@pytest.fixture(autouse=True)
def numpy_windows(monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


def _moved(arrows: np.ndarray, k: int, size: float = 1e-3) -> np.ndarray:
    """The pair-groupoid arrows with configuration q_k (k ≥ 1, interior) moved by ``size``."""
    n = arrows.shape[1] // 2
    out = arrows.copy()
    out[k - 1, n:] += size
    out[k, :n] += size
    return out


def _pendulum_run(system, steps: int, U=None):
    sim = system.euler_lagrange().compile(backend="numpy")
    inputs = {} if U is None else {"inputs": U[0]}
    start = sim.from_velocity({"a": 0.4, "b": -0.2}, [0.3, 0.5], PEND, **inputs)
    return sim.simulate(start, steps - 1, PEND, **({} if U is None else {"inputs": U[1:]}))


@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2), sg.LobattoIIIAB(3)],
                         ids=["gauss2", "lobatto3"])
def test_a_run_passes_and_a_moved_configuration_fails_on_r2(scheme):
    system = double_pendulum(scheme)
    traj = _pendulum_run(system, 20)
    report = sg.verify_stationary(traj, system)
    assert report and abs(report.extrapolated) < 1e-9 * report.scale
    arrows = traj.states[:, :4]
    assert sg.verify_stationary(arrows, system, PEND)
    assert not sg.verify_stationary(_moved(arrows, 7), system, PEND)
    # the stages matter: the run of another scheme is not a solution of this one
    other = _pendulum_run(double_pendulum("midpoint"), 20).states[:, :4]
    assert not sg.verify_stationary(other, system, PEND)


def test_a_forced_run_passes_and_fails_without_its_forces_or_with_shifted_inputs():
    """The damped, driven pendulum with GaussLegendre(2): its run (the inputs held in its
    states) passes; the same arrows checked against the unforced system, or with the inputs
    shifted by one arrow, or with one configuration moved, fail."""
    system, steps = double_pendulum(sg.GaussLegendre(2), forced=True), 20
    U = np.random.default_rng(4).normal(size=(steps, 1))
    traj = _pendulum_run(system, steps, U)
    report = sg.verify_stationary(traj, system)
    assert report and abs(report.work) > 1e-3
    arrows = traj.states[:, :4]
    assert sg.verify_stationary(arrows, system, PEND, inputs=U)
    assert not sg.verify_stationary(arrows, double_pendulum(sg.GaussLegendre(2)), PEND)
    assert not sg.verify_stationary(arrows, system, PEND, inputs=np.roll(U, 1, axis=0))
    assert not sg.verify_stationary(_moved(arrows, 5), system, PEND, inputs=U)
    with pytest.raises(sg.ShapeError, match="inputs"):
        sg.verify_stationary(arrows, system, PEND, inputs=U[:-1])
    with pytest.raises(sg.ShapeError, match="inputs"):
        sg.verify_stationary(arrows, system, PEND)


def _body_run(system, steps: int, U=None):
    sim = system.euler_lagrange().compile(backend="numpy")
    inputs = {} if U is None else {"inputs": U[0]}
    start = sim.from_velocity({"R": np.eye(3)}, [0.3, 1.0, 0.4], BODY, **inputs)
    return sim.simulate(start, steps - 1, BODY, **({} if U is None else {"inputs": U[1:]}))


def _turned(arrows: np.ndarray, k: int, angle: float = 1e-3) -> np.ndarray:
    """The pair-groupoid arrows of SO(3) with attitude R_k turned by ``angle``."""
    out = arrows.copy()
    turn = Rotation.from_rotvec([angle, -angle, angle / 2]).as_matrix()
    moved = (out[k, :9].reshape(3, 3) @ turn).ravel()
    out[k - 1, 9:] = out[k, :9] = moved
    return out


def test_a_run_on_so3_passes_and_a_turned_attitude_fails():
    system = rigid_body()
    traj = _body_run(system, 12)
    assert sg.verify_stationary(traj, system)
    assert not sg.verify_stationary(_turned(traj.states[:, :18], 6), system, BODY)


@pytest.mark.slow
def test_a_forced_run_on_so3():
    """Damping and torque inputs on the pair groupoid of SO(3) (its derivation takes about
    20 s of CPU): the run passes, the unforced body's check of its arrows and shifted inputs
    fail."""
    system, steps = rigid_body(forced=True), 12
    U = np.random.default_rng(5).normal(size=(steps, len(taus)))
    traj = _body_run(system, steps, U)
    assert sg.verify_stationary(traj, system)
    arrows = traj.states[:, :18]
    assert not sg.verify_stationary(arrows, rigid_body(), BODY)
    assert not sg.verify_stationary(arrows, system, BODY, inputs=np.roll(U, 1, axis=0))


def test_stages_without_a_root_are_reported():
    """∂L/∂ζ = 1 + ζ² + 2Δζ has no root near 0 for small Δ: a DiagnosticsError, not a check
    at a non-solution."""
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    system = sg.DiscreteSystem(
        G, lambda g, z: (g.target[0] - g.source[0]) ** 2 / (2 * h) + z[0] + z[0] ** 3 / 3
        + (g.target[0] - g.source[0]) * z[0] ** 2, parameters=[h], time_step=h, stages=1)
    arrows = np.array([[0.0, 0.1], [0.1, 0.2], [0.2, 0.3]])
    with pytest.raises(DiagnosticsError, match="internal stages"):
        sg.verify_stationary(arrows, system, {"h": 0.1})
