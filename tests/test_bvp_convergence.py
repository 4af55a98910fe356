"""The boundary-value solver to the rounding floor, and what it says about the point it found:
the cost Σ L_d and the second-order condition (its parts one by one — the line search at the
floor, the globalised iteration, the inertia against dense linear algebra —
tests/test_bvp.py)."""

from __future__ import annotations

import pathlib

import numpy as np
import pytest
import sympy as sp
from conftest import load_example
from kernel_support import benchmark_module

import symgroupoid as sg
from symgroupoid.ir import Graph, rounding_error
from symgroupoid.runtime import interpolate_arrows
from symgroupoid.verification import action

h = sp.Symbol("h", positive=True)


@pytest.fixture
def numpy_windows(monkeypatch):
    """Window programs evaluated with NumPy: small problems need no C build."""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


@pytest.fixture(scope="module")
def problems():
    return benchmark_module("_bvp_problems")


# --- an independent solution of the SO(3) Cayley problem: shooting on seed 000 §6.1 -------------

INERTIA = (1.0, 2.0, 3.0)


def _cay(x) -> np.ndarray:
    """cay(x̂) = I + 4/(4 + |x|²)(x̂ + x̂²/2) (seed 001 eq. (63))."""
    X = np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])
    return np.eye(3) + 4.0 / (4.0 + float(np.dot(x, x))) * (X + X @ X / 2)


def _next_chart(x: tuple) -> tuple:
    """x_{k+1} from seed 000 §6.1 with l = ½ξᵀIξ, x = hξ (the factors h cancel):
    (1 + x̂_{k+1}/2 + x_{k+1}x_{k+1}ᵀ/4)·I·x_{k+1} = (1 − x̂_k/2 + x_k x_kᵀ/4)·I·x_k
    (the duals of the left-trivialised dcay⁻¹ at ±x, App. D): with m = I·x,
    m_{k+1} + x_{k+1} × m_{k+1}/2 + x_{k+1}(x_{k+1}·m_{k+1})/4 = μ_k, solved by fixed-point
    iteration (a contraction by about |x|); plain floats, the vectors are three long."""
    a, b, c = INERTIA
    x1, x2, x3 = x
    m1, m2, m3 = a * x1, b * x2, c * x3
    d = (x1 * m1 + x2 * m2 + x3 * m3) / 4
    mu = (m1 - (x2 * m3 - x3 * m2) / 2 + x1 * d, m2 - (x3 * m1 - x1 * m3) / 2 + x2 * d,
          m3 - (x1 * m2 - x2 * m1) / 2 + x3 * d)
    y1, y2, y3 = x
    for _ in range(40):
        m1, m2, m3 = a * y1, b * y2, c * y3
        d = (y1 * m1 + y2 * m2 + y3 * m3) / 4
        z1 = (mu[0] - (y2 * m3 - y3 * m2) / 2 - y1 * d) / a
        z2 = (mu[1] - (y3 * m1 - y1 * m3) / 2 - y2 * d) / b
        z3 = (mu[2] - (y1 * m2 - y2 * m1) / 2 - y3 * d) / c
        done = max(abs(z1 - y1), abs(z2 - y2), abs(z3 - y3)) <= 1e-16 * max(
            abs(y1), abs(y2), abs(y3))
        y1, y2, y3 = z1, z2, z3
        if done:
            break
    return y1, y2, y3


def _shoot(x0, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """March the discrete equations from the first chart; the end attitude and all charts."""
    x = tuple(float(v) for v in x0)
    charts = [x]
    for _ in range(steps - 1):
        x = _next_chart(x)
        charts.append(x)
    R = np.eye(3)
    for c in charts:
        R = R @ _cay(c)
    return R, np.array(charts)


def _shooting_solution(end: np.ndarray, steps: int, x0: np.ndarray) -> np.ndarray:
    """The charts x_k of the solution reaching ``end``: Newton on the first chart, with a
    finite-difference Jacobian of the end attitude's skew part."""

    def miss(x):
        R, charts = _shoot(x, steps)
        E = R.T @ end
        return np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]), charts

    for _ in range(12):
        f, charts = miss(x0)
        if np.abs(f).max() <= 1e-14:
            return charts
        eps = 1e-7 * np.abs(x0).max()
        J = np.column_stack([(miss(x0 + eps * e)[0] - f) / eps for e in np.eye(3)])
        x0 = x0 + np.linalg.solve(J, -f)
    raise AssertionError("the shooting reference did not converge")


@pytest.fixture(scope="module")
def so3_control():
    """Seed 000 §6.1: L(g) = h·½ξᵀIξ, ξ = cay⁻¹(g)/h, I = diag(1, 2, 3)."""

    def L(g):
        xi = g.coordinates / h
        return h * (xi.T * sp.diag(1, 2, 3) * xi)[0, 0] / 2

    return sg.DiscreteSystem(sg.SO3("g"), L, parameters=[h], name="so3_control")


def test_cayley_problem_at_n1000_agrees_with_an_independent_solution(so3_control):
    """Default options, N = 1000: the velocities ξ_k = x_k/h agree with the shooting solution
    of seed 000 §6.1's equations to 1e-12 (with the former fixed tol = 1e-10 the solve
    stopped one iteration early, 2e-11 away)."""
    n = 1000
    end = _cay(np.array([0.9, -0.6, 1.4]))
    sol = sg.solve_boundary_value(so3_control, np.eye(3), end, n, params=[1 / n])
    first = interpolate_arrows(so3_control.groupoid, end.ravel(), n)[0]  # the geodesic
    reference = _shooting_solution(end, n, np.array(so3_control.groupoid.fibre_chart_inverse(
        first)))
    assert np.abs(sol.controls - reference).max() * n < 1e-12
    assert sol.is_local_minimum and sol.cost == pytest.approx(
        action(so3_control, sol.arrows, None, [1 / n]), rel=1e-13)


# --- the rounding floor ------------------------------------------------------------------------

def test_rounding_error_counts_the_rounding_of_perturbed_inputs():
    """E(x·y − z) with x, y, z rounded values bounds the change |y||x| + |x||y| + |z| of the
    result when each moves by its own rounding; exact inputs add nothing."""
    g = Graph()
    x, y, z = (g.input(sp.Symbol(s)) for s in "xyz")
    f = g.sub(g.mul(x, y), z)
    exact, = rounding_error(g, [f])
    rounded, = rounding_error(g, [f], [x, y, z])
    only_z, = rounding_error(g, [f], [z])
    from symgroupoid.ir import Program
    values = {"x": 3.0e8, "y": -2.0, "z": 5.0e8}
    P = Program(g, {"v": [sp.Symbol(s) for s in "xyz"]},
                {"E": [exact, rounded, only_z]})
    E = P.numpy_function(["E"], ["v"])(np.array(list(values.values())))[0]
    change = 2 * abs(values["x"] * values["y"]) + abs(values["z"])
    assert E[1] >= E[0] + change - 1e-6 * change
    assert E[2] == pytest.approx(E[0] + abs(values["z"]), rel=1e-12)


@pytest.mark.usefixtures("numpy_windows")
def test_cli_prints_the_cost_and_the_second_order_condition(tmp_path, capsys):
    import json

    from symgroupoid.cli import main

    problem = tmp_path / "problem.json"
    problem.write_text(json.dumps({"start": 0.0, "end": 1.0, "steps": 20,
                                   "params": {"h": 0.05, "k": 16.0}}))
    spring = pathlib.Path(__file__).resolve().parent.parent / "examples" / "cli" / "spring.py"
    assert main(["bvp", str(spring), str(problem)]) == 0
    out = capsys.readouterr().out
    assert "cost Σ L_d = " in out
    assert "second-order condition: NOT a local minimum: a saddle with 1 descent direction" \
        in out
    assert main(["bvp", str(spring), str(problem), "--params", "k=1"]) == 0
    assert "second-order condition: local minimum" in capsys.readouterr().out


# --- slow: large N and the comparison with an interior-point NLP solver ----------------------

@pytest.mark.slow
def test_rigid_body_at_n16000_converges_like_n1000():
    """Seed 001 §3.3.4 at N = 16000 (the residual's floor grows like N²): as many Newton
    iterations as at N = 1000 (±1), every update a full step, and the costs of N = 1000,
    4000, 16000 converge at second order (the N = 16000 solution is the limit's)."""
    rb = load_example("rigid_body_attitude")
    sols = {n: rb.solve(n) for n in (1000, 4000, 16000)}
    assert abs(sols[16000].iterations - sols[1000].iterations) <= 1
    costs = [sols[n].cost for n in (1000, 4000, 16000)]
    ratio = (costs[0] - costs[1]) / (costs[1] - costs[2])
    assert 14 < ratio < 18, ratio  # (1/1000² − 1/4000²)/(1/4000² − 1/16000²) = 16
    assert sols[16000].is_local_minimum


@pytest.mark.slow
def test_twenty_random_problems_against_ipopt(problems):
    """SO(3) and SE(2), end rotations up to 150°, random inertias and N in [100, 2000], the
    default guess: every problem Ipopt (on the CasADi Opti transcription, at most 500
    iterations) solves, the library solves too, at the same stationary point or at a lower
    cost; and every solution is a strict local minimum."""
    casadi_models = pytest.importorskip("casadi") and benchmark_module("_bvp_casadi")
    for p in problems.random_problems():
        G = p.system.groupoid
        guess = interpolate_arrows(G, G.arrow_between(p.start, p.end), p.steps)
        chart = np.array([G.fibre_chart_inverse(a) for a in guess])
        ipopt = casadi_models.solve_ipopt(casadi_models.first_order(p.kind, p.end, p.params,
                                                                    chart), max_iter=500)
        if not ipopt.success:
            continue
        sol = p.solve()
        assert sol.is_local_minimum, p.label
        same = np.abs(sol.controls - ipopt.chart).max() < 1e-8
        assert same or sol.cost < ipopt.cost - 1e-9, (p.label, sol.cost, ipopt.cost)
