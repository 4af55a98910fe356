"""Boundary-value problems of discrete Lagrangians with internal stages (docs/conventions.md
§22): the Galerkin discretisations GaussLegendre(s) and LobattoIIIAB(s) of continuous
systems, solved with the stages ζ_k of every arrow as unknowns and their stage rows
∂L/∂ζ(g_k, ζ_k) (+ f_ζ) as equations.

The solution between two configurations is the initial-value run started from its first
arrow (the step solves the same rows), on R² (a double pendulum), with a holonomic
constraint (Lobatto IIIA–IIIB), on the pair groupoid of SO(3) (a rigid body), with forces
and inputs; it is not the solution of the midpoint rule (the stages are in the equations);
the sweep and the command line take such systems; bad input is refused before any solve.
The Jacobian against finite differences is a white-box test of tests/test_bvp.py.
"""

from __future__ import annotations

import functools
import json
import warnings

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (module_cache: autouse fixture)
    module_cache,
    module_cache_root,
    needs_cc,
)
from scipy.spatial.transform import Rotation

import symgroupoid as sg

h, g, c = sp.symbols("h g c", positive=True)
u1 = sp.Symbol("u1", real=True)
taus = sp.symbols("tau1:4", real=True)
J = sp.diag(*sp.symbols("J1:4", positive=True))
PEND = {"h": 0.05, "g": 9.81, "c": 0.3}
BODY = {"h": 0.1, "J1": 1.0, "J2": 2.0, "J3": 3.0, "c": 0.2}


@pytest.fixture(autouse=True)
def numpy_windows(monkeypatch):
    """Window programs and steps evaluated with NumPy (the same bits as C, §17): no builds."""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


def _double_pendulum_lagrangian(q, v):
    return ((2 * v[0] ** 2 + v[1] ** 2 + 2 * v[0] * v[1] * sp.cos(q[0] - q[1])) / 2
            + g * (2 * sp.cos(q[0]) + sp.cos(q[1])))


@functools.cache
def double_pendulum(scheme, forced: bool = False) -> sg.DiscreteSystem:
    """The double pendulum in its angles (R², no constraint), discretised by ``scheme``;
    ``forced``: joint damping −c·θ̇ and a torque input u1 on the first joint."""
    forces = {}
    if forced:
        forces = {"forces": lambda q, v: [-c * v[0] + u1, -c * v[1]], "inputs": [u1]}
    name = "driven_pendulum" if forced else "pendulum"
    continuous = sg.ContinuousSystem(sg.EuclideanSpace("a b"), _double_pendulum_lagrangian,
                                     parameters=[h, g, c], name=name, **forces)
    return continuous.discretize(h, scheme)


@functools.cache
def rigid_body(forced: bool = False) -> sg.DiscreteSystem:
    """The free rigid body on SO(3) (the pair groupoid of SO(3) once discretised) with
    GaussLegendre(2); ``forced``: body damping −cξ and torque inputs τ."""
    forces = {}
    if forced:
        forces = {"forces": lambda R, xi: [-c * xi[a] + taus[a] for a in range(3)],
                  "inputs": list(taus)}
    continuous = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * J * xi)[0, 0] / 2,
                                     parameters=[h, *J.diagonal(), c],
                                     name="driven_body" if forced else "body", **forces)
    return continuous.discretize(h, sg.GaussLegendre(2))


def _points_run(system, arrows: np.ndarray, params: dict, U=None) -> np.ndarray:
    """The run of len(arrows) arrows on the pair groupoid of R² started from the first of
    ``arrows`` (with the inputs U, row k the input of arrow k)."""
    sim = system.euler_lagrange().compile(backend="numpy")
    a0 = arrows[0]
    start = {"a": (a0[0], a0[2]), "b": (a0[1], a0[3])}
    if U is None:
        return sim.simulate(start, len(arrows) - 1, params).states[:, :4]
    start["u1"] = [U[0, 0]]
    return sim.simulate(start, len(arrows) - 1, params, inputs=U[1:]).states[:, :4]


def _body_run(system, arrows: np.ndarray, params: dict, U=None) -> np.ndarray:
    """The run on the pair groupoid of SO(3) from the first of ``arrows``."""
    sim = system.euler_lagrange().compile(backend="numpy")
    start = {"R": (arrows[0, :9].reshape(3, 3), arrows[0, 9:].reshape(3, 3))}
    if U is None:
        return sim.simulate(start, len(arrows) - 1, params).states[:, :18]
    start.update({str(t): [U[0, i]] for i, t in enumerate(taus)})
    return sim.simulate(start, len(arrows) - 1, params, inputs=U[1:]).states[:, :18]


# --- the solution is the run from its first arrow -------------------------------------------

@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2), sg.LobattoIIIAB(3)],
                         ids=["gauss2", "lobatto3"])
def test_the_solution_is_the_run_from_its_first_arrow_on_r2(scheme):
    """Between (0.4, −0.2) and (0.6, 0.1) over 1 s (20 steps): Newton from the straight
    initial path gives up (damped steps; with stages there is no globalised iteration,
    §22), and from the midpoint rule's solution (found by the globalised iteration)
    converges.  The simulated run from the solution's first arrow is the solution, to
    1e-12; the stages are the solution's own (the action is stationary), and the solution
    is not the midpoint rule's (the stages are in the equations)."""
    system, steps, ends = double_pendulum(scheme), 20, ([0.4, -0.2], [0.6, 0.1])
    with pytest.raises(sg.BoundaryValueDivergenceError, match="internal stages"):
        sg.solve_boundary_value(system, *ends, steps, params=PEND)
    midpoint = sg.solve_boundary_value(double_pendulum("midpoint"), *ends, steps, params=PEND)
    assert "inertia-corrected" in midpoint.method
    sol = sg.solve_boundary_value(system, *ends, steps, params=PEND, guess=midpoint.arrows)
    assert sol.stages.shape == (steps, system.stages) and np.abs(sol.stages).max() > 1e-8
    run = _points_run(system, sol.arrows, PEND)
    np.testing.assert_allclose(run, sol.arrows, rtol=0, atol=1e-12)
    assert sol.inertia is None and sol.is_local_minimum is None
    assert "internal stages" in sol.kind and "internal stages" in repr(sol)
    assert sg.verify_stationary(sol, system)
    assert np.abs(midpoint.arrows - sol.arrows).max() > 1e-4


def test_a_simulated_run_is_recovered_and_its_cost_is_the_action_of_l_d():
    """A run simulated from (q₀, v₀) is the solution between its end configurations (the
    default initial path, then Newton); the reported cost is Σ L(g_k, ζ_k) at the stages,
    which is the action of L_d: Σ_k of the cost of each arrow as a problem of one step."""
    system, steps = double_pendulum(sg.GaussLegendre(2)), 30
    sim = system.euler_lagrange().compile(backend="numpy")
    run = sim.simulate(sim.from_velocity({"a": 0.4, "b": -0.2}, [0.3, 0.5], PEND), steps - 1,
                       PEND).states[:, :4]
    sol = sg.solve_boundary_value(system.euler_lagrange(), run[0, :2], run[-1, 2:], steps,
                                  params=PEND)
    np.testing.assert_allclose(sol.arrows, run, rtol=0, atol=1e-12)
    halves = [sg.solve_boundary_value(system, run[0, :2], run[k, 2:], k + 1, params=PEND)
              for k in (9, steps - 1)]
    assert np.abs(halves[0].arrows - run[:10]).max() < 1e-12
    rest = sg.solve_boundary_value(system, run[10, :2], run[-1, 2:], steps - 10, params=PEND)
    assert abs(halves[0].cost + rest.cost - sol.cost) < 1e-12 * abs(sol.cost)
    assert abs(halves[1].cost - sol.cost) < 1e-12 * abs(sol.cost)


def test_a_holonomic_constraint_with_lobatto():
    """The pendulum in Cartesian coordinates, x² + y² = 1, with LobattoIIIAB(3): the interior
    multiplier is a stage (§22); the solution keeps the constraint at every node and is the
    run from its first arrow and first multiplier."""
    continuous = sg.ContinuousSystem(
        sg.EuclideanSpace("x y"), lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - g * q[1],
        parameters=[h, g], holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1], name="cartesian")
    system, steps, p = continuous.discretize(h, sg.LobattoIIIAB(3)), 20, {"h": 0.05, "g": 9.81}
    ends = [[np.sin(t), -np.cos(t)] for t in (0.3, 1.1)]
    sol = sg.solve_boundary_value(system, *ends, steps, params=p)
    assert sol.stages.shape == (steps, 3) and sol.multipliers.shape == (steps, 1)
    q = np.vstack([sol.arrows[:, :2], sol.arrows[-1:, 2:]])
    assert np.abs((q ** 2).sum(axis=1) - 1).max() < 1e-13
    sim = system.euler_lagrange().compile(backend="numpy")
    a0 = sol.arrows[0]
    start = sim.state({"x": (a0[0], a0[2]), "y": (a0[1], a0[3]),
                       "lambda": sol.multipliers[0]}, p)
    run = sim.simulate(start, steps - 1, p).states[:, :4]
    np.testing.assert_allclose(run, sol.arrows, rtol=0, atol=1e-11)


def test_the_solution_is_the_run_from_its_first_arrow_on_so3():
    """The rigid body on the pair groupoid of SO(3) with GaussLegendre(2): between the
    identity and a rotation by 1.2 rad in 12 steps, the run from the solution's first arrow
    is the solution to 1e-12."""
    system, steps = rigid_body(), 12
    end = Rotation.from_rotvec([0.3, 1.0, 0.4]).as_matrix()
    sol = sg.solve_boundary_value(system, np.eye(3), end, steps, params=BODY)
    assert sol.stages.shape == (steps, 3) and sol.inertia is None
    run = _body_run(system, sol.arrows, BODY)
    np.testing.assert_allclose(run, sol.arrows, rtol=0, atol=1e-12)
    assert np.abs(sol.arrows[-1, 9:].reshape(3, 3) - end).max() < 1e-14


# --- forced ------------------------------------------------------------------------------------

def test_a_forced_run_with_inputs_on_r2():
    """The damped double pendulum driven by a random torque sequence (one input per arrow):
    the run is recovered from its ends with the same inputs, and the solution is the run from
    its first arrow; without the inputs (zeros) the solution is another path."""
    system, steps = double_pendulum(sg.GaussLegendre(2), forced=True), 30
    U = np.random.default_rng(1).normal(size=(steps, 1))
    sim = system.euler_lagrange().compile(backend="numpy")
    start = sim.from_velocity({"a": 0.4, "b": -0.2}, [0.3, 0.5], PEND, inputs=U[0])
    run = sim.simulate(start, steps - 1, PEND, inputs=U[1:]).states[:, :4]
    sol = sg.solve_boundary_value(system, run[0, :2], run[-1, 2:], steps, params=PEND,
                                  inputs=U)
    np.testing.assert_allclose(sol.arrows, run, rtol=0, atol=1e-12)
    assert sol.forced and np.array_equal(sol.inputs, U)
    np.testing.assert_allclose(_points_run(system, sol.arrows, PEND, U), sol.arrows, rtol=0,
                               atol=1e-12)
    still = sg.solve_boundary_value(system, run[0, :2], run[-1, 2:], steps, params=PEND,
                                    inputs=np.zeros(1))
    assert np.abs(still.arrows - run).max() > 1e-4
    assert sg.verify_stationary(sol, system) and not sg.verify_stationary(still, system,
                                                                         inputs=U)


@pytest.mark.slow
def test_a_forced_run_with_inputs_on_so3():
    """The rigid body with damping and torque inputs (its derivation takes about 20 s of
    CPU): the solution with the inputs is the run from its first arrow, to 1e-12."""
    system, steps = rigid_body(forced=True), 12
    U = np.random.default_rng(2).normal(size=(steps, 3))
    end = Rotation.from_rotvec([0.3, 1.0, 0.4]).as_matrix()
    sol = sg.solve_boundary_value(system, np.eye(3), end, steps, params=BODY, inputs=U)
    np.testing.assert_allclose(_body_run(system, sol.arrows, BODY, U), sol.arrows, rtol=0,
                               atol=1e-12)


@needs_cc
def test_compiled_windows_give_the_same_bits(monkeypatch):
    """The junction and stage programs compiled to C (built before the solve, no fallback
    warning) and in NumPy: the same solution and stages, bit for bit."""
    steps, ends = 10, ([0.4, -0.2], [0.5, 0.3])
    U = np.random.default_rng(8).normal(size=(steps, 1))
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    scheme = sg.GaussLegendre(2)
    numpy_solution = sg.solve_boundary_value(double_pendulum(scheme, forced=True), *ends,
                                             steps, params=PEND, inputs=U)
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "c")
    fresh = double_pendulum.__wrapped__(scheme, forced=True)  # its own kernels, built in C
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # NumPy fallback: "stay in NumPy"
        c_solution = sg.solve_boundary_value(fresh, *ends, steps, params=PEND, inputs=U)
    assert np.array_equal(c_solution.arrows, numpy_solution.arrows)
    assert np.array_equal(c_solution.stages, numpy_solution.stages)
    assert c_solution.history == numpy_solution.history


# --- sweeps and the command line ---------------------------------------------------------------

def test_a_sweep_solves_each_run_as_solve_boundary_value():
    system, steps = double_pendulum(sg.GaussLegendre(2), forced=True), 12
    U = np.random.default_rng(3).normal(size=(2, steps, 1))
    ends = [(0.5, 0.1), (0.9, -0.3)]
    result = sg.sweep_boundary_value(system, [(0.4, -0.2)], ends, steps, PEND, inputs=U,
                                     combine="zip", workers=1)
    for r, end in enumerate(ends):
        direct = sg.solve_boundary_value(system, (0.4, -0.2), end, steps, params=PEND,
                                         inputs=U[r])
        got = result.solutions[r]
        assert np.array_equal(got.arrows, direct.arrows)
        assert np.array_equal(got.stages, direct.stages)


STAGED_FILE = '''
import sympy as sp
import symgroupoid as sg

h, k = sp.symbols("h k", positive=True)

continuous = sg.ContinuousSystem(
    sg.EuclideanSpace("x"), lambda q, v: v[0] ** 2 / 2 - k * q[0] ** 4 / 4,
    parameters=[h, k], name="quartic")
system = continuous.discretize(h, sg.GaussLegendre(3))
'''


def test_the_cli_bvp_solves_a_discretised_system(tmp_path, capsys):
    """``symgroupoid bvp`` on a file whose system is a Galerkin discretisation: the solution
    written is the direct solve's, with its stages."""
    from symgroupoid.cli import load_system, main

    (tmp_path / "staged.py").write_text(STAGED_FILE)
    problem = {"start": [0.0], "end": [1.0], "steps": 8, "params": {"h": 0.1, "k": 2.0}}
    (tmp_path / "bvp.json").write_text(json.dumps(problem))
    out = tmp_path / "sol.npz"
    assert main(["bvp", str(tmp_path / "staged.py"), str(tmp_path / "bvp.json"), "--check",
                 "-o", str(out)]) == 0
    said = capsys.readouterr().out
    assert "internal stages" in said and "critical point of the discrete action: yes" in said
    system = load_system(str(tmp_path / "staged.py")).system
    direct = sg.solve_boundary_value(system, [0.0], [1.0], 8, params={"h": 0.1, "k": 2.0})
    with np.load(out) as data:
        assert np.array_equal(data["arrows"], direct.arrows)
        assert np.array_equal(data["stages"], direct.stages)
        assert data["stages"].shape == (8, 2)


# --- refusals ----------------------------------------------------------------------------------

def test_bad_input_is_refused_before_any_solve():
    """Inputs of the wrong shape, type or value, inputs for an unforced system, minimum=True
    (no descent method on Σ L(g, ζ), §22) and a guess of the wrong shape get named errors;
    the iteration cap raises, never a non-solution."""
    forced = double_pendulum(sg.GaussLegendre(2), forced=True)
    plain = double_pendulum(sg.GaussLegendre(2))
    ends, steps = ([0.4, -0.2], [1.1, 0.6]), 10
    for bad, error in ((np.zeros((steps - 1, 1)), sg.ShapeError),
                       (np.zeros((steps, 2)), sg.ShapeError),
                       ("u", sg.SymgroupoidError), ([[np.nan]] * steps, sg.DomainError),
                       (None, sg.ShapeError)):
        with pytest.raises(error):
            sg.solve_boundary_value(forced, *ends, steps, params=PEND, inputs=bad)
    with pytest.raises(sg.ShapeError, match="not forced"):
        sg.solve_boundary_value(plain, *ends, steps, params=PEND, inputs=np.zeros(1))
    for system in (plain, forced):
        with pytest.raises(sg.UnsupportedFeatureError, match="minimum"):
            sg.solve_boundary_value(system, *ends, steps, params=PEND, minimum=True,
                                    inputs=np.zeros(1) if system is forced else None)
    with pytest.raises(sg.ShapeError):
        sg.solve_boundary_value(plain, *ends, steps, params=PEND, guess=np.zeros((3, 4)))
    with pytest.raises(sg.BoundaryValueDivergenceError, match="did not converge"):
        sg.solve_boundary_value(plain, *ends, steps, params=PEND, max_iterations=1)
