"""verify_stationary of forced systems: the discrete Lagrange–d'Alembert principle
(docs/conventions.md §20), dS/dt + W = 0 along random admissible variations, W the forces'
virtual work along the same variation.

A forced trajectory passes; the same arrows checked with the forces dropped (the unforced
twin), with the inputs shifted by one step, or with an interior arrow moved, fail.  On a
vector space pair groupoid (a damped, driven point in the plane), on SO(3) (a damped rigid
body driven by body torques), on the pair groupoid of SO(3) (the forced spherical pendulum
of ``systems.spherical_chain``), and on every kind of forced system: constrained,
holonomic, nonholonomic (varied along D_c), second order, on a time groupoid.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from test_chains import spherical_initial
from test_forces import PLANE_PARAMS, _plane_system, _torque_and_damping, u
from test_forces_kinds import initial, kind, steps_of

import symgroupoid as sg
from symgroupoid import systems
from symgroupoid.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _inputs(traj) -> np.ndarray:
    """The input of every action term as the trajectory's states hold them (terms, m)."""
    names = traj._layout.input_names
    return np.stack([np.asarray(traj[name], float) for name in names], axis=1)


def _arrows(traj) -> np.ndarray:
    return traj._layout.arrows(traj.states)


@pytest.fixture(scope="module")
def plane_run():
    system = _plane_system(_torque_and_damping, [u])
    sim = system.euler_lagrange().compile(backend="numpy")
    steps = 30
    U = np.sin(0.5 * np.arange(steps))[:, None]
    traj = sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.012), "u": [0.3]}, steps,
                        PLANE_PARAMS, inputs=U)
    return system, traj


def test_a_damped_driven_run_on_a_pair_groupoid_satisfies_lagrange_dalembert(plane_run):
    system, traj = plane_run
    report = sg.verify_stationary(traj, system)
    assert report.stationary, report
    assert abs(report.work) > 1e-3 * report.scale  # the forces' work is what balances dS/dt
    # the arrows and the inputs given separately: the same check
    again = sg.verify_stationary(_arrows(traj), system, PLANE_PARAMS, inputs=_inputs(traj))
    assert again.stationary and again.derivatives == report.derivatives


def test_the_forced_run_is_not_a_critical_point_of_the_action_alone(plane_run):
    """The same arrows checked against the unforced system (the forces dropped)."""
    _, traj = plane_run
    report = sg.verify_stationary(_arrows(traj), _plane_system(), PLANE_PARAMS)
    assert not report.stationary
    assert abs(report.extrapolated) > 1e-3 * report.scale


@pytest.mark.parametrize("change", ["shifted", "zero", "bent"])
def test_wrong_inputs_or_a_moved_arrow_fail(plane_run, change):
    system, traj = plane_run
    arrows, U = _arrows(traj), _inputs(traj)
    if change == "shifted":  # u_j read as the input of g_{j+1}
        U = np.roll(U, 1, axis=0)
    elif change == "zero":
        U = np.zeros_like(U)
    else:
        arrows = arrows.copy()
        arrows[10, 3] += 1e-4  # the target y of g_10, which is the source of g_11
        arrows[11, 1] += 1e-4
    report = sg.verify_stationary(arrows, system, PLANE_PARAMS, inputs=U)
    assert not report.stationary, report


H_, C_ = sp.symbols("h c", positive=True)
TAUS = sp.symbols("tau1:4", real=True)


def _rigid_body(forced: bool) -> sg.DiscreteSystem:
    """A rigid body on SO(3), L = −tr(J_d W)/h, driven by body torques τ and damped by
    −c·ω, ω = vee(W − Wᵀ)/(2h), held over the step (f⁻ = f⁺ = (h/2)(τ − c·ω))."""
    Jd = systems.discrete_inertia(1, 2, 3)

    def L(g):
        return -(Jd * g.matrix).trace() / H_

    def forces(g):
        W = g.matrix
        omega = [(W[2, 1] - W[1, 2]) / (2 * H_), (W[0, 2] - W[2, 0]) / (2 * H_),
                 (W[1, 0] - W[0, 1]) / (2 * H_)]
        half = [H_ / 2 * (t - C_ * o) for t, o in zip(TAUS, omega)]
        return half, half

    if not forced:
        return sg.DiscreteSystem(sg.SO3("W"), L, parameters=[H_, C_], name="free_body",
                                 time_step=H_)
    return sg.DiscreteSystem(sg.SO3("W"), L, parameters=[H_, C_], forces=forces,
                             inputs=list(TAUS), name="driven_body", time_step=H_)


def test_a_damped_driven_rigid_body_on_so3():
    system = _rigid_body(True)
    sim = system.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.05, "c": 0.5}
    W0 = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    U = 4 * np.random.default_rng(2).normal(size=(15, 3))
    traj = sim.simulate({"W": W0, "tau1": 0.0, "tau2": 0.0, "tau3": 0.1}, 15, params, inputs=U)
    report = sg.verify_stationary(traj, system)
    assert report.stationary, report
    dropped = sg.verify_stationary(_arrows(traj), _rigid_body(False), params)
    assert not dropped.stationary and abs(dropped.extrapolated) > 1e-4 * dropped.scale
    reversed_inputs = sg.verify_stationary(_arrows(traj), system, params,
                                           inputs=_inputs(traj)[::-1])
    assert not reversed_inputs.stationary


def test_the_forced_spherical_pendulum_on_the_pair_groupoid_of_so3():
    """``spherical_chain(1, forced=True)``: a torque at the pivot (inputs) and damping."""
    chain = systems.spherical_chain(1, forced=True)
    sim = chain.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "g": 9.81, "c": 0.4}
    U = np.random.default_rng(3).normal(size=(15, 3))
    traj = sim.simulate(np.concatenate([spherical_initial(1), np.zeros(6)]), 15, params,
                        inputs=U)
    assert sg.verify_stationary(traj, chain).stationary
    dropped = sg.verify_stationary(_arrows(traj), systems.spherical_chain(1),
                                   {"h": 0.01, "g": 9.81})
    assert not dropped.stationary and abs(dropped.extrapolated) > 1e-3 * dropped.scale
    assert not sg.verify_stationary(_arrows(traj), chain, params,
                                    inputs=_inputs(traj)[::-1]).stationary


KINDS = ["holonomic", "nonholonomic", "second_order",
         pytest.param("constrained", marks=pytest.mark.slow),
         pytest.param("time_rigid_body", marks=pytest.mark.slow),
         pytest.param("second_order_so3", marks=pytest.mark.slow)]


@pytest.mark.parametrize("name", KINDS)
def test_every_kind_of_forced_run_passes_and_fails_without_its_forces(name):
    """Constrained (the multipliers varied too), holonomic (λ·ψ at the source nodes),
    nonholonomic (the Hölder principle: varied along D_c), second order (the pair forces
    f⁰, f¹, f² at the pair's three base points), time groupoid (the time section varied:
    the forced energy balance)."""
    k = kind(name)
    sim = steps_of(name)[0].compile(backend="numpy")
    m = sim.layout.n_inputs
    U = 0.3 * np.random.default_rng(1).normal(size=(12, m))
    traj = sim.simulate(initial(name), 12, k.params, inputs=U)
    report = sg.verify_stationary(traj, k.forced)
    assert report.stationary, report
    assert report.work != 0.0
    plain_multipliers = None
    if sim.layout.n_multipliers and not isinstance(k.plain, sg.NonholonomicSystem):
        plain_multipliers = traj.multipliers
    dropped = sg.verify_stationary(_arrows(traj), k.plain, k.params,
                                   multipliers=plain_multipliers)
    assert not dropped.stationary, dropped


def test_an_unforced_nonholonomic_run_is_checked_along_the_distribution():
    """(A NonholonomicSystem was asked for multipliers it does not have — ShapeError — and
    varied in every direction, off D_c, where its trajectory is not stationary.)"""
    k = kind("nonholonomic")
    sim = k.plain.euler_lagrange().compile(backend="numpy")
    start = {key: value for key, value in k.start.items() if key not in ("u", "w")}
    traj = sim.simulate(start, 12, k.params)
    assert sg.verify_stationary(traj, k.plain).stationary
    bent = _arrows(traj).copy()
    bent[5, 3] += 1e-4  # the target x of g_5 and the source x of g_6
    bent[6, 0] += 1e-4
    assert not sg.verify_stationary(bent, k.plain, k.params).stationary


def test_the_energy_momentum_method_is_refused():
    plane = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    system = sg.NonholonomicSystem(plane, lambda g: (g.target[0] - g.source[0]) ** 2 / H_,
                                   distribution=[[1, 1]], parameters=[H_],
                                   method="energy_momentum", metric=sp.eye(2), name="em")
    arrows = np.array([[0.0, 0.0, 0.1, 0.1], [0.1, 0.1, 0.2, 0.2], [0.2, 0.2, 0.3, 0.3]])
    with pytest.raises(sg.UnsupportedFeatureError, match="energy–momentum"):
        sg.verify_stationary(arrows, system, {"h": 0.1})


def test_bad_inputs_are_named(plane_run):
    system, traj = plane_run
    arrows, U = _arrows(traj), _inputs(traj)
    with pytest.raises(sg.ShapeError, match=r"has inputs \(u\); give them with inputs="):
        sg.verify_stationary(arrows, system, PLANE_PARAMS)
    with pytest.raises(sg.ShapeError, match=r"inputs must have shape \(31, 1\)"):
        sg.verify_stationary(arrows, system, PLANE_PARAMS, inputs=U[:-1])
    bad = U.copy()
    bad[4] = np.nan
    with pytest.raises(sg.DomainError, match="inputs have non-finite values"):
        sg.verify_stationary(arrows, system, PLANE_PARAMS, inputs=bad)
    with pytest.raises(sg.ShapeError, match="has no inputs"):
        sg.verify_stationary(arrows, _plane_system(), PLANE_PARAMS, inputs=U)


def test_a_trajectory_that_skips_states_is_refused(plane_run):
    """(With every = 2 the arrows of the kept states are not consecutive: the check varied
    a sequence that is not the run's and reported it not stationary.)"""
    system, traj = plane_run
    sim = system.euler_lagrange().compile(backend="numpy")
    sampled = sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.012), "u": [0.3]}, 10,
                           PLANE_PARAMS, inputs=np.zeros(1), every=2)
    with pytest.raises(sg.DomainError, match="every=1"):
        sg.verify_stationary(sampled, system)


def test_the_command_line_verifies_a_forced_file(tmp_path, capsys):
    """``symgroupoid verify`` of a forced system file takes ``--inputs``; the variational
    principle's row is the Lagrange–d'Alembert check (the file's short run failed before:
    its inputs were never passed)."""
    U = tmp_path / "U.csv"
    U.write_text("u\n" + "\n".join(f"{np.sin(0.3 * j):.6f}" for j in range(20)) + "\n")
    command = ["verify", str(ROOT / "examples" / "cli" / "driven_spring.py"), "--backend",
               "numpy", "--no-sympy", "--points", "1"]
    assert main([*command, "--inputs", str(U)]) == 0
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("variational principle"))
    assert "pass" in row and "Lagrange–d'Alembert" in row, out
    assert main(command) != 0
    assert "--inputs" in capsys.readouterr().err


@pytest.mark.parametrize("junk", [
    "u", b"u", object(), {"v": 1.0}, [["a"]], 1 + 2j, np.full((31, 1), 1j), np.zeros((31, 1, 1)),
    np.full((31, 1), np.inf), np.zeros((0, 1)), [[True]] * 31, [1.0, 2.0]])
def test_hostile_inputs_get_named_errors(plane_run, junk):
    """Whatever ``inputs=`` holds, a named error (never a raw exception, never a report)."""
    system, traj = plane_run
    with pytest.raises(sg.SymgroupoidError, match="driven|plane|inputs"):
        sg.verify_stationary(_arrows(traj), system, PLANE_PARAMS, inputs=junk)


def test_inputs_held_constant_are_the_table_of_that_value(plane_run):
    """A number (one input) or (m,) is held for every term, as simulate and
    solve_boundary_value take it: the same report as the whole table."""
    system, traj = plane_run
    arrows = _arrows(traj)
    table = sg.verify_stationary(arrows, system, PLANE_PARAMS,
                                 inputs=np.full((len(arrows), 1), 2.0))
    for held in (2.0, [2.0]):
        report = sg.verify_stationary(arrows, system, PLANE_PARAMS, inputs=held)
        assert report.derivatives == table.derivatives and not report.stationary
