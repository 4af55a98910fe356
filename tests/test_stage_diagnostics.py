"""Diagnostics of forced systems with internal stages (docs/conventions.md §22): the momenta
of a forced step are the forced discrete Legendre transforms F⁻L − f⁻ and F⁺L + f⁺
(Marsden–West eq. (3.2.4)) taken at the stages the step solved, ∂L/∂ζ + f_ζ = 0 with the
inputs of the state's arrow; their matching p⁺(g_k) = p⁻(g_{k+1}) is the forced DEL.  Checked
against GaussLegendre(2) on R written by hand in Marsden–West's control-point form, with
its stages solved here by Newton: at the forced stages the hand momenta and energy are the
library's, at the unforced ones ζ* (∂L/∂ζ = 0) the momenta do not match."""

import functools

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
c = sp.Symbol("c", real=True)
u = sp.Symbol("u", real=True)
C, DT, STEPS = 0.4, 0.05, 120


def _duffing() -> sg.ContinuousSystem:
    """q̈ = −q − q³ − c q̇ + u."""
    return sg.ContinuousSystem(
        sg.EuclideanSpace("q"), lambda q, v: v[0] ** 2 / 2 - q[0] ** 2 / 2 - q[0] ** 4 / 4,
        parameters=[h, c], forces=lambda q, v: [-c * v[0] + u], inputs=[u], name="duffing")


@functools.cache
def _by_hand():
    """GaussLegendre(2) on R by hand: control points q₀, q₀ + Δ/2 + ζ, q₁; L_d = h Σ_i b_i
    L(q(c_i h), q̇(c_i h)); the control points' forces f_j = h Σ_i b_i ℓ_j(c_i) F_i carried
    to the ends and the stage (f⁻ = f₀ + f₁/2, f⁺ = f₂ + f₁/2, f_ζ = f₁).  Returns numeric
    functions of (q₀, q₁, ζ, u, h): the stage row of L alone and its ζ-derivative, the
    forced stage row and its derivative, p⁻ = −∂L/∂q₀ − f⁻, p⁺ = ∂L/∂q₁ + f⁺, and −∂L/∂h."""
    q0, q1, z, uu, hh, tau = sp.symbols("q0 q1 z uu hh tau", real=True)
    nodes = [sp.Rational(1, 2) - sp.sqrt(3) / 6, sp.Rational(1, 2) + sp.sqrt(3) / 6]
    times = [0, sp.Rational(1, 2), 1]
    ell = [sp.prod([(tau - times[i]) / (times[j] - times[i]) for i in range(3) if i != j])
           for j in range(3)]
    P = [q0, q0 + (q1 - q0) / 2 + z, q1]
    at = [(sum(e.subs(tau, ci) * p for e, p in zip(ell, P)),
           sum(sp.diff(e, tau).subs(tau, ci) * p for e, p in zip(ell, P)) / hh) for ci in nodes]
    L = hh * sum(v ** 2 / 2 - q ** 2 / 2 - q ** 4 / 4 for q, v in at) / 2
    f = [hh * sum(e.subs(tau, ci) * (-C * v + uu) for ci, (q, v) in zip(nodes, at)) / 2
         for e in ell]
    f_minus, f_plus, f_zeta = f[0] + f[1] / 2, f[2] + f[1] / 2, f[1]
    row, forced = sp.diff(L, z), sp.diff(L, z) + f_zeta
    args = (q0, q1, z, uu, hh)
    exprs = [row, sp.diff(row, z), forced, sp.diff(forced, z), -sp.diff(L, q0) - f_minus,
             sp.diff(L, q1) + f_plus, -sp.diff(L, hh)]
    return [sp.lambdify(args, e, "numpy") for e in exprs]


def _stages(row, slope, q0, q1, uk) -> np.ndarray:
    """The root near 0 of a stage row at every arrow (Newton, vectorised)."""
    z = np.zeros_like(q0)
    for _ in range(30):
        z = z - row(q0, q1, z, uk, DT) / slope(q0, q1, z, uk, DT)
    assert np.abs(row(q0, q1, z, uk, DT)).max() < 1e-13  # terms of size 1
    return z


@pytest.fixture(scope="module")
def run():
    sim = _duffing().discretize(h, sg.GaussLegendre(2)).euler_lagrange().compile(
        backend="numpy")
    drive = np.sin(0.3 * np.arange(STEPS + 1)) + 0.5
    return sim.simulate({"q": (0.5, 0.53), "u": [drive[0]]}, STEPS, {"h": DT, "c": C},
                        inputs=drive[1:, None])


def test_forced_momenta_match_along_a_forced_gauss_trajectory(run):
    """p⁺ of arrow k equals p⁻ of arrow k + 1 to rounding; the library's momenta and energy
    are the hand-written ones at the forced stages of every state (with its input u_k)."""
    momenta = run.momenta()
    scale = np.abs(momenta.plus).max()
    assert np.abs(momenta.matching()).max() < 1e-14 * STEPS * scale
    row, slope, forced, forced_slope, p_minus, p_plus, energy = _by_hand()
    q0, q1, uk = run.states[:, 0], run.states[:, 1], run.states[:, 2]
    z = _stages(forced, forced_slope, q0, q1, uk)
    np.testing.assert_allclose(momenta.minus[:, 0], p_minus(q0, q1, z, uk, DT), rtol=0,
                               atol=1e-13 * scale)
    np.testing.assert_allclose(momenta.plus[:, 0], p_plus(q0, q1, z, uk, DT), rtol=0,
                               atol=1e-13 * scale)
    E = run.energy()
    np.testing.assert_allclose(E, energy(q0, q1, z, uk, DT), rtol=0,
                               atol=1e-13 * np.abs(E).max())
    # at the unforced stages ζ* the forced transforms do not match: the stages matter
    star = _stages(row, slope, q0, q1, uk)
    assert np.abs(star - z).max() > 1e-5
    wrong = p_plus(q0, q1, star, uk, DT)[:-1] - p_minus(q0, q1, star, uk, DT)[1:]
    assert np.abs(wrong).max() > 1e-6
    summary = sg.diagnostics.conservation_summary(run)
    assert summary.momentum_matching < 1e-14 * STEPS * scale
    assert any("forced" in line for line in summary.lines())


@pytest.mark.parametrize("scheme", [sg.LobattoIIIAB(3), "midpoint"])
def test_forced_momenta_match_for_other_schemes(scheme):
    """The same matching for a Lobatto scheme with stages and for the midpoint rule (no
    stages; its forced transforms are the momenta too)."""
    sim = _duffing().discretize(h, scheme).euler_lagrange().compile(backend="numpy")
    drive = np.cos(0.2 * np.arange(61))
    traj = sim.simulate({"q": (0.5, 0.53), "u": [drive[0]]}, 60, {"h": DT, "c": C},
                        inputs=drive[1:, None])
    momenta = traj.momenta()
    assert np.abs(momenta.matching()).max() < 1e-13 * np.abs(momenta.plus).max()
