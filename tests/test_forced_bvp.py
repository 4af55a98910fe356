"""Boundary-value problems of forced systems (docs/conventions.md §20): the junction
residuals of the discrete Lagrange–d'Alembert principle, with a given input sequence.

A forced run simulated from (q₀, q₁) with an input sequence is recovered by the boundary-value
solve between q₀ and the run's q_N with the same inputs, from a perturbed path, to Newton
tolerance; the solution satisfies the forced step's residuals (the SymPy residuals of
``euler_lagrange()``, independent of the window programs); on a Lie group (SO(3), torque
inputs and damping), with forces without inputs (damping), at second order (the driven
spline's fourth differences), through the sweep and the CLI; bad inputs are refused before
any solve.
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
from symgroupoid import systems

h, c = sp.symbols("h c", positive=True)
u1, u2, u = sp.symbols("u1 u2 u", real=True)
taus = sp.symbols("tau1:4", real=True)
G0 = sp.Rational(981, 100)


@pytest.fixture(autouse=True)
def numpy_windows(monkeypatch):
    """Window programs and steps evaluated with NumPy (the same bits as C, §17): no builds."""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


def _midpoint(g):
    q0, q1 = g.source, g.target
    return [(x + y) / 2 for x, y in zip(q0, q1)], [(y - x) / h for x, y in zip(q0, q1)]


def _double_pendulum_lagrangian(g):
    (a, b), (va, vb) = _midpoint(g)
    return h * (va ** 2 + vb ** 2 / 2 + va * vb * sp.cos(a - b) + 2 * G0 * sp.cos(a)
                + G0 * sp.cos(b))


@functools.cache
def driven_double_pendulum() -> sg.DiscreteSystem:
    """The damped, driven double pendulum on the pair groupoid of R²: midpoint L_d and the
    midpoint forces f± = (h/2)·(−c·θ̇ + u) (joint torques u1, u2 as inputs)."""
    forces = sg.midpoint_forces(lambda q, v: [-c * v[0] + u1, -c * v[1] + u2], h)
    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace(["a", "b"])),
                             _double_pendulum_lagrangian, parameters=[h, c], forces=forces,
                             inputs=[u1, u2], name="driven_pendulum", time_step=h)


@functools.cache
def damped_double_pendulum() -> sg.DiscreteSystem:
    """The same pendulum with Rayleigh damping alone: forces without inputs."""
    forces = sg.rayleigh_damping(lambda q, v: c * (v[0] ** 2 + v[1] ** 2) / 2, h)
    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace(["a", "b"])),
                             _double_pendulum_lagrangian, parameters=[h, c], forces=forces,
                             name="damped_pendulum", time_step=h)


@functools.cache
def free_pendulum() -> sg.DiscreteSystem:
    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace(["a", "b"])),
                             _double_pendulum_lagrangian, parameters=[h, c],
                             name="free_pendulum", time_step=h)


@functools.cache
def driven_body() -> sg.DiscreteSystem:
    """The rigid body on SO(3) (L = −tr(J_d W)/h) with body torques τ as inputs and damping
    of the body angular velocity, ω ≈ vee(W − Wᵀ)/(2h), both held over the step."""
    Jd = sp.Matrix(systems.discrete_inertia(1, 2, 3))

    def L(g):
        return -(Jd * g.matrix).trace() / h

    def forces(g):
        W = g.matrix
        omega = [(W[2, 1] - W[1, 2]) / (2 * h), (W[0, 2] - W[2, 0]) / (2 * h),
                 (W[1, 0] - W[0, 1]) / (2 * h)]
        half = [h / 2 * (t - c * o) for t, o in zip(taus, omega)]
        return half, list(half)

    return sg.DiscreteSystem(sg.SO3("W"), L, parameters=[h, c], forces=forces,
                             inputs=list(taus), name="driven_body", time_step=h)


PENDULUM = {"h": 0.05, "c": 0.3}
BODY = {"h": 0.1, "c": 0.2}


def pendulum_run(system, steps: int, U=None):
    """A run of ``steps`` arrows g_0 … g_{N−1} from (q₀, q₁) (U[k]: the input of g_k):
    the arrows (N, 4)."""
    sim = system.euler_lagrange().compile(backend="numpy")
    start = {"a": (0.3, 0.32), "b": (-0.2, -0.19)}
    if U is None:
        return sim.simulate(start, steps - 1, PENDULUM).states[:, :4]
    start.update({"u1": [U[0, 0]], "u2": [U[0, 1]]})
    return sim.simulate(start, steps - 1, PENDULUM, inputs=U[1:]).states[:, :4]


def body_run(steps: int, U):
    sim = driven_body().euler_lagrange().compile(backend="numpy")
    W0 = Rotation.from_rotvec([0.1, 0.05, 0.2]).as_matrix()
    start = {"W": W0, **{str(t): [U[0, i]] for i, t in enumerate(taus)}}
    return sim.simulate(start, steps - 1, BODY, inputs=U[1:]).states[:, :9]


def perturbed_points(arrows: np.ndarray, rng, size: float = 0.05) -> np.ndarray:
    """The arrows of the path through the run's configurations moved by ``size``·N(0, 1),
    the ends kept (pair groupoid of Rⁿ: arrows (q_k, q_{k+1}))."""
    n = arrows.shape[1] // 2
    q = np.vstack([arrows[:, :n], arrows[-1:, n:]])
    q[1:-1] += size * rng.normal(size=q[1:-1].shape)
    return np.hstack([q[:-1], q[1:]])


def perturbed_rotations(arrows: np.ndarray, rng, size: float = 0.05) -> np.ndarray:
    """The arrows W_k = P_k⁻¹P_{k+1} of the run's attitudes P_k each turned by a random
    rotation of about ``size`` rad, the first and last kept."""
    P = [np.eye(3)]
    for a in arrows:
        P.append(P[-1] @ a.reshape(3, 3))
    Q = [P[0]] + [p @ Rotation.from_rotvec(size * rng.normal(size=3)).as_matrix()
                  for p in P[1:-1]] + [P[-1]]
    return np.array([(Q[k].T @ Q[k + 1]).ravel() for k in range(len(arrows))]), P[-1]


def forced_step_residuals(system, arrows: np.ndarray, U, params: dict) -> np.ndarray:
    """The forced step's residuals X⃖_b[L](g_j) − X⃗_b[L](g_{j+1}) + f⁺_b(g_j) + f⁻_b(g_{j+1})
    (the SymPy residuals of ``euler_lagrange()``, §20) at every junction of ``arrows``, row j
    with the inputs U[j], U[j + 1]: (N − 1, rank)."""
    step = system.euler_lagrange()
    m = len(step.inputs)
    symbols = list(dict.fromkeys([*step.arrows[0], *step.arrows[1],
                                  *step.knowns[len(step.knowns) - 2 * m:], *step.parameters]))
    f = sp.lambdify(symbols, step.residuals[:system.groupoid.rank], "numpy")
    p = [params[str(s)] for s in step.parameters]
    U = np.zeros((len(arrows), 0)) if U is None else U
    out = []
    for j in range(len(arrows) - 1):
        values = dict(zip(step.arrows[0], arrows[j]))
        values.update(zip(step.arrows[1], arrows[j + 1]))
        values.update(zip(step.knowns[len(step.knowns) - 2 * m:], [*U[j], *U[j + 1]]))
        values.update(zip(step.parameters, p))
        out.append(f(*[values[s] for s in symbols]))
    return np.array(out, float)


# --- the run is recovered ----------------------------------------------------------------------

def test_a_driven_damped_double_pendulum_run_is_recovered():
    """Simulated with random torques from (q₀, q₁), the run is the boundary-value solution
    between q₀ and q_N with the same inputs, found from a perturbed path to Newton tolerance;
    the solution satisfies the forced step's residuals, and the unforced problem's solution
    does not (the forces are in the equations)."""
    system, steps = driven_double_pendulum(), 40
    U = np.random.default_rng(1).normal(size=(steps, 2))
    arrows = pendulum_run(system, steps, U)
    guess = perturbed_points(arrows, np.random.default_rng(2))
    sol = sg.solve_boundary_value(system, arrows[0, :2], arrows[-1, 2:], steps, guess=guess,
                                  params=PENDULUM, inputs=U)
    np.testing.assert_allclose(sol.arrows, arrows, rtol=0, atol=1e-12)
    assert sol.forced and sol.inertia is None and sol.is_local_minimum is None
    assert "Lagrange–d'Alembert" in sol.kind and np.array_equal(sol.inputs, U)
    assert np.abs(forced_step_residuals(system, sol.arrows, U, PENDULUM)).max() < 1e-11
    assert np.abs(forced_step_residuals(system, arrows, U, PENDULUM)).max() < 1e-11
    plain = sg.solve_boundary_value(free_pendulum(), arrows[0, :2], arrows[-1, 2:], steps,
                                    guess=guess, params=PENDULUM)
    assert np.abs(plain.arrows - arrows).max() > 1e-3
    assert np.abs(forced_step_residuals(system, plain.arrows, U, PENDULUM)).max() > 1e-2


def test_a_forced_rigid_body_run_on_so3_is_recovered():
    """SO(3) with torque inputs and damping: the run (more than a full turn in all) is
    recovered from perturbed attitudes; the solution satisfies the forced step residuals."""
    steps = 30
    U = np.random.default_rng(3).normal(size=(steps, 3))
    arrows = body_run(steps, U)
    guess, end = perturbed_rotations(arrows, np.random.default_rng(4))
    sol = sg.solve_boundary_value(driven_body(), np.eye(3), end, steps, guess=guess,
                                  params=BODY, inputs=U)
    np.testing.assert_allclose(sol.arrows, arrows, rtol=0, atol=1e-12)
    assert np.abs(forced_step_residuals(driven_body(), sol.arrows, U, BODY)).max() < 1e-11


def test_forces_without_inputs_damping_alone():
    """Rayleigh damping (forces, no inputs): the damped run is recovered; inputs given to it
    are refused."""
    system, steps = damped_double_pendulum(), 30
    arrows = pendulum_run(system, steps)
    guess = perturbed_points(arrows, np.random.default_rng(5))
    sol = sg.solve_boundary_value(system.euler_lagrange(), arrows[0, :2], arrows[-1, 2:],
                                  steps, guess=guess, params=PENDULUM)
    np.testing.assert_allclose(sol.arrows, arrows, rtol=0, atol=1e-12)
    assert sol.forced and sol.inputs is None
    assert np.abs(forced_step_residuals(system, sol.arrows, None, PENDULUM)).max() < 1e-11
    with pytest.raises(sg.ShapeError, match="its forces take no inputs"):
        sg.solve_boundary_value(system, arrows[0, :2], arrows[-1, 2:], steps,
                                params=PENDULUM, inputs=np.zeros((steps, 1)))


def test_a_forced_constrained_system():
    """A particle held to the diagonal (φ = Δx − Δy) with a drive u along x and damping:
    the run (multipliers from λ₀ = 0) is recovered; its multipliers up to the constant the
    junctions do not see (φ depends on the increment only, so λ enters as differences)."""
    k = sp.Symbol("k", positive=True)

    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return h * (((x1 - x0) / h) ** 2 / 2 + ((y1 - y0) / h) ** 2 / 2
                    - k * ((x0 + x1) ** 2 + (y0 + y1) ** 2) / 8)

    def phi(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return [(x1 - x0) - (y1 - y0)]

    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace(["x", "y"])), L, phi, parameters=[h, k, c],
        forces=sg.midpoint_forces(lambda q, v: [-c * v[0] + u, -c * v[1]], h), inputs=[u],
        name="diagonal_forced", time_step=h)
    sim = system.euler_lagrange().compile(backend="numpy")
    steps, p = 20, {"h": 0.1, "k": 1.0, "c": 0.4}
    U = np.random.default_rng(9).normal(size=(steps, 1))
    start = sim.state({"x": (0.0, 0.1), "y": (0.0, 0.1), "lambda": [0.0], "u": [U[0, 0]]}, p)
    run = sim.simulate(start, steps - 1, p, inputs=U[1:]).states
    sol = sg.solve_boundary_value(system, run[0, :2], run[-1, 2:4], steps, params=p, inputs=U)
    np.testing.assert_allclose(sol.arrows, run[:, :4], rtol=0, atol=1e-13)
    shift = sol.multipliers[:, 0] - run[:, 4]
    np.testing.assert_allclose(shift, shift[0], rtol=0, atol=1e-12)
    assert np.ptp(run[:, 4]) > 1e-2


def test_constant_inputs_and_a_simulator_as_the_system():
    """Inputs (m,) are held for every term: the same bits as the full table; a simulator is
    taken for its system."""
    system, steps = driven_double_pendulum(), 12
    U = np.tile([0.4, -0.3], (steps, 1))
    arrows = pendulum_run(system, steps, U)
    ends = arrows[0, :2], arrows[-1, 2:]
    sim = system.euler_lagrange().compile(backend="numpy")
    held = sg.solve_boundary_value(sim, *ends, steps, params=PENDULUM, inputs=[0.4, -0.3])
    table = sg.solve_boundary_value(system, *ends, steps, params=PENDULUM, inputs=U)
    assert np.array_equal(held.arrows, table.arrows)
    np.testing.assert_allclose(held.arrows, arrows, rtol=0, atol=1e-12)


def test_a_driven_spline_second_order():
    """Second order: the driven spline L = (Δ²q)²/(2h³), f¹ = h·u at each pair's middle
    point; its junction residual at q_{j+1} is Δ⁴q = −h⁴·u_j, u_j the input of the pair
    (g_j, g_{j+1}) centred there: N − 1 rows of inputs."""
    system = sg.SecondOrderSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda g1, g2: (g2.target[0] - 2 * g1.target[0] + g1.source[0]) ** 2 / (2 * h ** 3),
        parameters=[h], forces=lambda g1, g2: ([0], [h * u], [0]), inputs=[u],
        name="driven_spline")
    steps, hh = 16, 0.1
    U = np.sin(np.arange(steps - 1))[:, None]
    sol = sg.solve_boundary_value(system, (0.0, 0.01), (0.5, 0.52), steps, params={"h": hh},
                                  inputs=U)
    q = np.array(sol.configurations, float).ravel()
    fourth = q[4:] - 4 * q[3:-1] + 6 * q[2:-2] - 4 * q[1:-3] + q[:-4]  # centred at q_2 …
    np.testing.assert_allclose(fourth, -hh ** 4 * U[1:-1, 0], rtol=0, atol=1e-12)
    with pytest.raises(sg.ShapeError, match=r"\(15, 1\)"):
        sg.solve_boundary_value(system, (0.0, 0.01), (0.5, 0.52), steps, params={"h": hh},
                                inputs=np.zeros((steps, 1)))


# --- the programs ------------------------------------------------------------------------------

def test_the_inputs_are_named_inputs_of_the_window_program():
    """The window program of a forced system takes the inputs of each of its terms after the
    multipliers, and its residual is the forced step's at those values."""
    system = driven_double_pendulum()
    programs = sg.equations.window_programs(system)
    assert programs.forced and programs.n_inputs == 2
    names = [str(s) for s in programs.junction.inputs["a"]]
    assert names[8:12] == ["u2_0", "u2_1", "u3_0", "u3_1"] and names[12:] == ["h", "c"]
    assert not sg.equations.window_programs(free_pendulum()).forced
    arrows = pendulum_run(system, 6, np.ones((6, 2)))
    U = np.random.default_rng(6).normal(size=(6, 2))
    values = np.hstack([arrows[:-1], arrows[1:], U[:-1], U[1:], np.tile([0.05, 0.3], (5, 1))])
    (out,) = programs.junction.numpy_function(["junction"], ["a"])(values.T)
    np.testing.assert_allclose(np.asarray(out)[:2].T,
                               forced_step_residuals(system, arrows, U, PENDULUM),
                               rtol=1e-12, atol=1e-13)


@needs_cc
def test_compiled_windows_give_the_same_bits(monkeypatch):
    """The forced window program compiled to C (built before the solve, no fallback warning)
    and in NumPy: the same solution, bit for bit."""
    steps = 10
    U = np.random.default_rng(7).normal(size=(steps, 2))
    arrows = pendulum_run(driven_double_pendulum(), steps, U)
    ends = arrows[0, :2], arrows[-1, 2:]
    numpy_solution = sg.solve_boundary_value(driven_double_pendulum(), *ends, steps,
                                             params=PENDULUM, inputs=U)
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "c")
    fresh = driven_double_pendulum.__wrapped__()  # its own window kernels, built in C
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # NumPy fallback: "stay in NumPy"
        c_solution = sg.solve_boundary_value(fresh, *ends, steps, params=PENDULUM, inputs=U)
    assert np.array_equal(c_solution.arrows, numpy_solution.arrows)
    assert c_solution.history == numpy_solution.history


# --- what a forced solve does not do -----------------------------------------------------------

def test_minimum_is_refused_for_a_forced_system():
    """minimum=True asks for a local minimum of the action, which a forced system's solution
    is not (the solve without it: test_bvp.py, the fast path alone)."""
    with pytest.raises(sg.UnsupportedFeatureError, match="minimum"):
        sg.solve_boundary_value(driven_double_pendulum(), (0.3, -0.2), (0.5, 0.1), 8,
                                params=PENDULUM, inputs=[0.0, 0.0], minimum=True)


# --- bad inputs --------------------------------------------------------------------------------

BAD_INPUTS = [
    (None, sg.ShapeError, "has inputs"),
    (np.zeros((7, 2)), sg.ShapeError, r"\(8, 2\)"),
    (np.zeros((9, 2)), sg.ShapeError, r"\(8, 2\)"),
    (np.zeros((8, 3)), sg.ShapeError, r"\(8, 2\)"),
    (np.zeros((8,)), sg.ShapeError, r"\(8, 2\)"),
    (np.zeros((1, 8, 2)), sg.ShapeError, r"\(8, 2\)"),
    ([1.0], sg.ShapeError, r"\(8, 2\)"),
    (np.full((8, 2), np.nan), sg.DomainError, "finite"),
    ([0.0, np.inf], sg.DomainError, "u2 of term 0 is inf"),
    ("0.1, 0.2", sg.ShapeError, "inputs"),
    (np.zeros((8, 2), complex), sg.ShapeError, "inputs"),
    ([[0.0, "a"]] * 8, sg.ShapeError, "inputs"),
    ({"u1": 0.0}, sg.ShapeError, "inputs"),
]


@pytest.mark.parametrize("bad, error, match", BAD_INPUTS)
def test_bad_inputs_are_refused_before_any_solve(bad, error, match):
    """The inputs are checked before the boundary data (themselves checked before the solve):
    with an end that is not a point the error is still the inputs'."""
    for end in ((0.5, 0.1), (np.nan, 0.1)):
        with pytest.raises(error, match=match):
            sg.solve_boundary_value(driven_double_pendulum(), (0.3, -0.2), end, 8,
                                    params=PENDULUM, inputs=bad)


def test_inputs_given_to_an_unforced_system_are_refused():
    with pytest.raises(sg.ShapeError, match="it is not forced"):
        sg.solve_boundary_value(free_pendulum(), (0.3, -0.2), (np.nan, 0.1), 8,
                                params=PENDULUM, inputs=np.zeros((8, 2)))


def test_the_callers_inputs_are_copied():
    """The solution keeps the inputs it was solved with, not a view of the caller's array."""
    U = np.zeros((8, 2))
    sol = sg.solve_boundary_value(driven_double_pendulum(), (0.3, -0.2), (0.5, 0.1), 8,
                                  params=PENDULUM, inputs=U)
    U[:] = 1.0
    assert not sol.inputs.any() and not sol.inputs.flags.writeable


# --- the sweep and the CLI ---------------------------------------------------------------------

def test_sweep_with_shared_and_per_run_inputs():
    """One input table for every run, or one per run: each run is the solve of its own."""
    system, steps = driven_double_pendulum(), 10
    rng = np.random.default_rng(8)
    U = rng.normal(size=(2, steps, 2))
    ends = [(0.5, 0.1), (0.4, 0.0)]
    shared = sg.sweep_boundary_value(system, [(0.3, -0.2)], ends, steps, PENDULUM,
                                     inputs=U[0], workers=1)
    each = sg.sweep_boundary_value(system, [(0.3, -0.2)], ends, steps, PENDULUM,
                                   inputs=U, workers=1)
    for r in range(2):
        alone = sg.solve_boundary_value(system, (0.3, -0.2), ends[r], steps, params=PENDULUM,
                                        inputs=U[r])
        assert np.array_equal(each.solutions[r].arrows, alone.arrows)
        assert np.array_equal(each.solutions[r].inputs, U[r])
    assert np.array_equal(shared.solutions[0].arrows, each.solutions[0].arrows)
    assert not np.array_equal(shared.solutions[1].arrows, each.solutions[1].arrows)
    with pytest.raises(sg.ShapeError, match=r"\(2, 10, 2\)"):
        sg.sweep_boundary_value(system, [(0.3, -0.2)], ends, steps, PENDULUM,
                                inputs=np.zeros((3, steps, 2)), workers=1)
    bad = U.copy()
    bad[1, 4, 0] = np.nan
    with pytest.raises(sg.DomainError, match="run 1"):
        sg.sweep_boundary_value(system, [(0.3, -0.2)], ends, steps, PENDULUM, inputs=bad,
                                workers=1)
    with pytest.raises(sg.ShapeError, match="has inputs"):
        sg.sweep_boundary_value(system, [(0.3, -0.2)], ends, steps, PENDULUM, workers=1)


FORCED_FILE = '''
import sympy as sp
import symgroupoid as sg

h, c = sp.symbols("h c", positive=True)
u = sp.Symbol("u", real=True)

def L(g):
    (x0,), (x1,) = g.source, g.target
    return h * (((x1 - x0) / h) ** 2 / 2 - ((x0 + x1) / 2) ** 2 / 2)

system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x")), L, parameters=[h, c],
                           forces=sg.midpoint_forces(lambda q, v: [-c * v[0] + u], h),
                           inputs=[u], name="driven_oscillator")
'''


def test_the_cli_bvp_takes_inputs(tmp_path, capsys):
    """``bvp --inputs U.npy``: the solve of the file's system with those inputs; a table of
    the wrong length, and no inputs for a system with inputs, are one-line errors."""
    from symgroupoid.cli import load_system, main

    (tmp_path / "forced.py").write_text(FORCED_FILE)
    problem = {"start": [0.0], "end": [1.0], "steps": 6, "params": {"h": 0.1, "c": 0.5}}
    (tmp_path / "bvp.json").write_text(json.dumps(problem))
    U = np.linspace(0, 1, 6)[:, None]
    np.save(tmp_path / "u.npy", U)
    out = tmp_path / "sol.npz"
    assert main(["bvp", str(tmp_path / "forced.py"), str(tmp_path / "bvp.json"),
                 "--inputs", str(tmp_path / "u.npy"), "-o", str(out)]) == 0
    assert "Lagrange–d'Alembert" in capsys.readouterr().out
    system = load_system(str(tmp_path / "forced.py")).system
    direct = sg.solve_boundary_value(system, [0.0], [1.0], 6, params={"h": 0.1, "c": 0.5},
                                     inputs=U)
    with np.load(out) as data:
        assert np.array_equal(data["arrows"], direct.arrows)
    np.save(tmp_path / "short.npy", U[:5])
    assert main(["bvp", str(tmp_path / "forced.py"), str(tmp_path / "bvp.json"),
                 "--inputs", str(tmp_path / "short.npy")]) != 0
    assert "5 rows for the 6 terms of 6 steps" in capsys.readouterr().err
    assert main(["bvp", str(tmp_path / "forced.py"), str(tmp_path / "bvp.json")]) != 0
    err = capsys.readouterr().err
    assert "has inputs" in err and "--inputs" in err and "inputs=" not in err
    # a longer table gives its first rows, as for simulate (docs/cli.md)
    np.save(tmp_path / "long.npy", np.vstack([U, np.full((4, 1), 9.0)]))
    longer = tmp_path / "longer.npz"
    assert main(["bvp", str(tmp_path / "forced.py"), str(tmp_path / "bvp.json"), "--check",
                 "--inputs", str(tmp_path / "long.npy"), "-o", str(longer)]) == 0
    printed = capsys.readouterr().out
    assert "critical point of the discrete Lagrange–d'Alembert principle (forced): yes" \
        in printed and "of the discrete action" not in printed
    with np.load(longer) as data:
        assert np.array_equal(data["arrows"], direct.arrows)


@pytest.mark.parametrize("torque", [1e16, 1e30])
def test_a_step_that_raises_the_residual_far_out_is_not_converged(torque):
    """Inputs held at 1e16 (or 1e30) on the forced planar chain: a Newton step took the
    arrows so far out that the rounding of their coordinates excused any residual, and the
    solve reported convergence with |F| raised from 5e14 to 2.9e30 (1 iteration).  A step
    at the floor is taken only when it does not raise |F| above the iterate's own floor:
    the solve now fails loudly, and never returns such a path."""
    step = systems.planar_chain(2, forced=True).euler_lagrange()
    U = np.full((10, 2), torque)
    with pytest.raises(sg.BoundaryValueDivergenceError) as failed:
        sg.solve_boundary_value(step, [0.1, 0.0], [0.3, -0.2], 10,
                                params={"h": 0.05, "g": 9.81, "c": 0.1}, inputs=U)
    history = failed.value.history  # (no step raised |F| by orders of magnitude)
    assert max(history) < 10 * history[0], history
