"""The discrete heavy top on the action groupoid S² × SO(3) ⇉ S² (seed 002, "Example: The heavy
top"; docs/conventions.md §9): with L_d(Γ, W) = −(1/h) tr(J_d W) − h m g l Γ·e the derived equations
equal −1/h times

    Π_{k+1} − W_kᵀ Π_k − m g l h² Γ_{k+1} × e,     Π = axial(W J_d − J_d Wᵀ),  Γ_{k+1} = W_kᵀ Γ_k,

the seed's Π_{k+1} = W_kᵀ Π_k + m g l h² Γ_{k+1} × e.  W_kᵀ M_k W_k = hat(W_kᵀ Π_k) needs W_k
orthogonal, so W_k and W_{k+1} are parametrised by the Cayley map (seed 001 eq. (63)).

The slide's preceding matrix form, M_{k+1} − W_kᵀ M_k W_k + m g l h² (Γ_{k+1} × e)^ = 0, has the
gravity term with the opposite sign; the Lagrangian as printed gives the Π form (checked below).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from _seedcheck import axial, cay_so3, is_zero, nonzero_somewhere, substitute
from _systems import HT_E, HT_G, HT_H, HT_J, HT_L, HT_M, HT_PARAMETERS, heavy_top_system

import symgroupoid as sg

h, m, grav, ell = HT_H, HT_M, HT_G, HT_L
e_vec, J_d, PARAMETERS = HT_E, HT_J, HT_PARAMETERS


@pytest.fixture(scope="module")
def step() -> sg.StepEquations:
    return heavy_top_system().euler_lagrange()


def seed_equations(step: sg.StepEquations) -> sp.Matrix:
    """Π_{k+1} − W_kᵀ Π_k − m g l h² Γ_{k+1} × e (seed 002), in the step's symbols."""
    Wk, Wp = step.symbol("W", "k"), step.symbol("W", "k+1")
    Gamma_next = Wk.T * step.symbol("Gamma", "k")

    def Pi(W: sp.Matrix) -> sp.Matrix:
        return axial(W * J_d - J_d * W.T)

    return Pi(Wp) - Wk.T * Pi(Wk) - m * grav * ell * h**2 * Gamma_next.cross(e_vec)


def test_heavy_top_equals_seed_on_the_group(step: sg.StepEquations) -> None:
    """Seed 002 heavy-top DEL: residual = −(1/h)(Π_{k+1} − W_kᵀΠ_k − m g l h² Γ_{k+1}×e),
    exactly, for W_k = cay(a), W_{k+1} = cay(b) with a, b symbolic (general symmetric inertia,
    general e)."""
    a, b = sp.symbols("a1:4", real=True), sp.symbols("b1:4", real=True)
    Wk, Wp = step.symbol("W", "k"), step.symbol("W", "k+1")
    on_group = dict(zip(Wk, cay_so3(a))) | dict(zip(Wp, cay_so3(b)))
    expected = -seed_equations(step) / h
    assert len(step.residuals) == 3
    for res, exp in zip(step.residuals, expected):
        assert is_zero(substitute(res - exp, on_group))


def test_heavy_top_matrix_form_sign_differs(step: sg.StepEquations) -> None:
    """Seed 002 also prints M_{k+1} − W_kᵀM_kW_k + m g l h² (Γ_{k+1}×e)^ = 0, M = hat(Π): with
    that sign of the gravity term the derived equations do not match (on the group)."""
    Wk, Wp, Gk = step.symbol("W", "k"), step.symbol("W", "k+1"), step.symbol("Gamma", "k")
    a, b = sp.symbols("a1:4", real=True), sp.symbols("b1:4", real=True)
    on_group = dict(zip(Wk, cay_so3(a))) | dict(zip(Wp, cay_so3(b)))
    gravity = m * grav * ell * h**2 * (Wk.T * Gk).cross(e_vec)
    matrix_form = seed_equations(step) + 2 * gravity  # Π_{k+1} − W_kᵀΠ_k + m g l h² Γ×e
    assert any(nonzero_somewhere(substitute(res + eq / h, on_group))
               for res, eq in zip(step.residuals, matrix_form))


def test_heavy_top_needs_orthogonality(step: sg.StepEquations) -> None:
    """Control: off the group (W_k an arbitrary matrix) the seed's form W_kᵀΠ_k differs from the
    derived axial(J_d W_k − W_kᵀ J_d) — the comparison above really uses W_k ∈ SO(3)."""
    expected = -seed_equations(step) / h
    assert any(sp.expand(res - exp) != 0 for res, exp in zip(step.residuals, expected))


def test_heavy_top_numeric_supplement(step: sg.StepEquations) -> None:
    """Seed 002 heavy top, numerically at random orthogonal W_k, W_{k+1} (supplement to the
    symbolic check): the residual evaluated through ``step.evaluate`` equals −(1/h)·(seed form).
    Tolerance 1e-12 relative: both sides are O(1) sums of products of O(1) numbers."""
    rng = np.random.default_rng(7)
    G = step.groupoid
    Wk, Gk = step.symbol("W", "k"), step.symbol("Gamma", "k")
    chart = step.unknowns
    seed_fn = sp.lambdify([list(Gk), list(Wk), chart, PARAMETERS],
                          -seed_equations(step).xreplace(step.reconstruction) / h, "numpy")
    for _ in range(20):
        params = np.concatenate([rng.uniform(0.1, 1.0, 4), rng.normal(size=9)])
        known = np.array(G.random_arrow(rng))
        u = rng.uniform(-1.0, 1.0, 3)
        F, _ = step.evaluate(u, known, params)
        ref = np.asarray(seed_fn(known[:3], known[3:], u, params), float).ravel()
        np.testing.assert_allclose(F, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
