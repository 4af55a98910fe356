"""Second-order optimal control (seed 001 §3.3): rigid-body attitude control on SO(3)
(eqs. (25)–(28)) and the underactuated heavy top with two rotors (§3.3.5), as two-point
problems (the solver's Jacobian at rest and its window kernel: tests/test_bvp.py)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from conftest import load_example

import symgroupoid as sg
from symgroupoid.verification import action


@pytest.fixture(scope="module")
def rb():
    return load_example("rigid_body_attitude")


@pytest.fixture(scope="module")
def ht():
    return load_example("heavy_top_rotors")


@pytest.fixture(scope="module")
def attitude(rb):
    return rb.solve(100), rb.boundary_data(100)


# --- rigid body on SO(3) ---------------------------------------------------------------------

def test_equation_25_is_the_torque_free_rigid_body(rb):
    """With u = 0, eq. (25) with the example's P_i conserves the energy ½ΩᵀIΩ and |IΩ|² for
    generic inertias — it is Euler's equation (the seed's printed reciprocals are not)."""
    w = sp.symbols("w1:4", real=True)
    inertia = sp.symbols("I1:4", positive=True)
    rate = [-c for c in rb.torque(w, [0, 0, 0], inertia)]  # Ω̇ = P∘(ΩΩ) when u = 0
    energy = sum(i * c ** 2 for i, c in zip(inertia, w)) / 2
    momentum = sum((i * c) ** 2 for i, c in zip(inertia, w))
    for q in (energy, momentum):
        assert sp.simplify(sum(sp.diff(q, c) * r for c, r in zip(w, rate))) == 0
    a, b, c = inertia
    printed = (a / (b - c), b / (c - a), c / (a - b))  # the seed's P_i
    wrong = [printed[0] * w[1] * w[2], printed[1] * w[0] * w[2], printed[2] * w[0] * w[1]]
    assert sp.simplify(sum(sp.diff(energy, c) * r for c, r in zip(w, wrong))) != 0


def test_attitude_bvp_converges_keeps_the_boundary_and_is_stationary(rb, attitude):
    """N = 100 rest-to-rest: |F|∞ < 1e-10, quadratic convergence, the fixed arrows g₀ and
    g_{N−1} and the four boundary attitudes kept, and a critical point of Σ L_d (eq. (28))."""
    sol, ((R0, R1), (RN1, RN)) = attitude
    assert sol.residual_norm < 1e-10 and sol.iterations <= 6
    assert sol.history[-2] < 1e-4 * sol.history[0]
    G = rb.attitude_system().groupoid
    assert np.allclose(sol.arrows[0], G.arrow_between(R0, R1), atol=1e-14)
    assert np.allclose(sol.arrows[-1], G.arrow_between(RN1, RN), atol=1e-14)
    for k, R in ((0, R0), (1, R1), (-2, RN1), (-1, RN)):
        assert np.allclose(sol.configurations[k], R, atol=1e-12)
    assert sg.verify_stationary(sol, rb.attitude_system()).stationary
    # the printed cost is the system's own action, Σ L_d(W_k, W_{k+1})
    params = [sol.parameters[str(s)] for s in rb.PARAMETERS]
    assert rb.cost(sol) == pytest.approx(action(rb.attitude_system(), sol.arrows, None, params),
                                         rel=1e-12)


def test_attitude_summary_is_plot_ready(rb, attitude):
    sol, _ = attitude
    data = rb.summary(sol)
    n = sol.steps
    assert data["t"].shape == (n - 1,) and data["u"].shape == (n - 1, 3)
    assert data["omega"].shape == (n - 1, 3) and data["attitude"].shape == (n + 1, 3, 3)
    assert data["t"][0] == pytest.approx(sol.parameters["h"] / 2)
    assert data["t"][-1] == pytest.approx(rb.DURATION - sol.parameters["h"] / 2)
    # rest at both ends: the first and last arrows are the identity, ξ₀ = ξ_{N−1} = 0
    assert np.abs(data["xi"][[0, -1]]).max() < 1e-12


def test_discrete_torques_approximate_equation_25_at_second_order(rb):
    """On samples of a smooth motion, u_{k+1} (read off L_d, checked against the system's
    Lagrangian inside consistency_errors) differs from u(t_{k+1}) of eq. (25) by O(h²)."""
    errors = rb.consistency_errors((20, 40, 80))
    orders = rb.observed_orders(errors)
    assert errors[0] > errors[1] > errors[2]
    assert min(orders) >= 1.8, orders


def test_attitude_maneuver_converges_under_refinement(rb):
    """N = 20, 40, 80, 160 (h = T/(N − 1)): the optimal cost and the controls at fixed times
    converge at second order."""
    ref = rb.refinement((20, 40, 80, 160))
    assert ref["cost_changes"][0] > ref["cost_changes"][1] > ref["cost_changes"][2]
    assert min(ref["cost_orders"]) >= 1.8, ref["cost_orders"]
    assert min(ref["torque_orders"]) >= 1.8, ref["torque_orders"]


def test_given_velocity_maneuver(rb):
    """Ω(0) and Ω(T) prescribed: the end arrows carry them (x₀/h = Ω(0) + O(h²))."""
    w0, wT = np.array([0.5, 0.0, -0.3]), np.array([0.0, 0.8, 0.2])
    n = 60
    sol = rb.solve(n, omega_start=w0, omega_end=wT)
    dt = sol.parameters["h"]
    assert sol.residual_norm < 1e-10
    assert sg.verify_stationary(sol, rb.attitude_system()).stationary
    xi = sol.controls / dt
    assert np.abs(xi[0] - w0).max() < dt ** 2 and np.abs(xi[-1] - wT).max() < dt ** 2
    (_, _), (_, RT) = rb.boundary_data(n, omega_start=w0, omega_end=wT)
    assert np.allclose(sol.configurations[-1], RT, atol=1e-12)


# --- heavy top with two rotors ----------------------------------------------------------------

def _heavy_top_symbols():
    Om = sp.Matrix(sp.symbols("W1:4", real=True))
    dOm = sp.Matrix(sp.symbols("dW1:4", real=True))
    dth = sp.Matrix(sp.symbols("dth1:3", real=True))
    ddth = sp.Matrix(sp.symbols("ddth1:3", real=True))
    Gam = sp.Matrix(sp.symbols("G1:4", real=True))
    p = {n: sp.Symbol(n, positive=True) for n in ("gamma_1", "gamma_2", "Ibar_3", "J_1", "J_2",
                                                   "Mgl")}
    return Om, dOm, dth, ddth, Gam, p


def test_heavy_top_equations_follow_from_the_reduced_lagrangian(ht):
    """Π̇ − Π×Ω − MgℓΓ×e₃ and d/dt ∂l/∂θ̇ for the seed's l equal the example's Φ and u."""
    Om, dOm, dth, ddth, Gam, p = _heavy_top_symbols()
    v = sp.Matrix([*Om, *dth])
    g1, g2, i3, j1, j2, c = (p[n] for n in ("gamma_1", "gamma_2", "Ibar_3", "J_1", "J_2", "Mgl"))
    M = sp.Matrix([[g1, 0, 0, j1, 0], [0, g2, 0, 0, j2], [0, 0, i3, 0, 0],
                   [j1, 0, 0, j1, 0], [0, j2, 0, 0, j2]])
    lag = (v.T * M * v)[0, 0] / 2 - c * Gam[2]
    rates = dict(zip([*Om, *dth], [*dOm, *ddth]))

    def dt(e):  # time derivative along (Ω̇, θ̈); l's momenta do not depend on Γ
        return sum(sp.diff(e, s) * r for s, r in rates.items())

    Pi = sp.Matrix([sp.diff(lag, w) for w in Om])
    ep = sp.Matrix([dt(x) for x in Pi]) - Pi.cross(Om) - c * Gam.cross(sp.Matrix([0, 0, 1]))
    phi = ht.continuous_constraints(Gam, Om, dOm, dth, ddth, p)
    assert all(sp.expand(a - b) == 0 for a, b in zip(ep, phi))
    u = ht.continuous_controls(dOm, ddth, p)
    assert all(sp.expand(dt(sp.diff(lag, s)) - ui) == 0 for s, ui in zip(dth, u))


def test_heavy_top_energy_and_vertical_momentum(ht):
    """Sign checks of the model: on Φ = 0 with Γ̇ = Γ×Ω the vertical angular momentum Π·Γ is
    conserved for any rotor torques, and with u = 0 the energy is conserved."""
    Om, dOm, dth, ddth, Gam, p = _heavy_top_symbols()
    g1, g2, i3, j1, j2, c = (p[n] for n in ("gamma_1", "gamma_2", "Ibar_3", "J_1", "J_2", "Mgl"))
    Pi = sp.Matrix([g1 * Om[0] + j1 * dth[0], g2 * Om[1] + j2 * dth[1], i3 * Om[2]])
    dGam = Gam.cross(Om)
    phi = ht.continuous_constraints(Gam, Om, dOm, dth, ddth, p)
    acc = sp.solve(phi, list(dOm), dict=True)[0]
    dPi = sp.Matrix([g1 * dOm[0] + j1 * ddth[0], g2 * dOm[1] + j2 * ddth[1], i3 * dOm[2]])
    assert sp.simplify(((dPi.T * Gam)[0, 0] + (Pi.T * dGam)[0, 0]).subs(acc)) == 0
    free = sp.solve(list(phi) + ht.continuous_controls(dOm, ddth, p), [*dOm, *ddth], dict=True)[0]
    v = sp.Matrix([*Om, *dth])
    dv = sp.Matrix([*dOm, *ddth])
    M = sp.Matrix([[g1, 0, 0, j1, 0], [0, g2, 0, 0, j2], [0, 0, i3, 0, 0],
                   [j1, 0, 0, j1, 0], [0, j2, 0, 0, j2]])
    dE = (v.T * M * dv)[0, 0] + c * dGam[2]
    assert sp.simplify(dE.subs(free)) == 0


def test_heavy_top_discretisation_is_second_order_consistent(ht):
    """The system's Φ_d/h and discrete controls on samples of a smooth motion approach the
    continuous controlled equations at t_{k+1} with observed order ≈ 2 (centred scheme)."""
    errors = ht.consistency_errors((20, 40, 80))
    for key in ("phi", "u"):
        e = errors[key]
        assert e[0] > e[1] > e[2]
        assert min(errors[f"{key}_orders"]) >= 1.8, (key, errors[f"{key}_orders"])


@pytest.mark.slow
def test_heavy_top_steering_bvp(ht):
    """N = 30 steering between the ends of a feasible reference run: converged, every Φ_d = 0,
    the boundary arrows kept, cheaper than the reference program, stationary."""
    sol, problem = ht.solve_steering(30)
    assert sol.residual_norm < 1e-10
    phi, u, _ = ht.window_values(sol.arrows, problem["params"])
    assert np.abs(phi).max() < 1e-12
    assert np.allclose(sol.arrows[[0, -1]], problem["guess"][[0, -1]], atol=1e-13)
    (_, R_end), theta_end = problem["end"][1]
    assert np.allclose(sol.configurations[-1][0][1], R_end, atol=1e-10)
    assert np.allclose(sol.configurations[-1][1], theta_end, atol=1e-10)
    assert ht.cost(sol) < 0.9 * problem["reference_cost"]
    assert sg.verify_stationary(sol, ht.heavy_top_system()).stationary
