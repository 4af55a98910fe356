"""Lie groups G ⇉ {e}: discrete Euler–Poincaré equations (seed 000 Thm 2.13 and §6.1, seed 001
§2.2.5), constrained optimal control with the Cayley retraction on SO(3) and SE(2) (seed 000
§6.1; docs/conventions.md §5), and the library's symbolic dτ, dτ⁻¹ against seed 001 Appendix D.

Which trivialisation seed 000 §6.1 needs.  Its final formula

    (dτ⁻¹_{hξ_k})*(dl(ξ_k) + λ_k·dψ(ξ_k)) = (dτ⁻¹_{−hξ_{k+1}})*(dl(ξ_{k+1}) + λ_{k+1}·dψ(ξ_{k+1}))

uses the *left*-trivialised tangent (T_ξτ = T_e ℓ_{τ(ξ)} ∘ dτ_ξ, stated just below it): with
f = F∘τ⁻¹, d/dt f(g e^{tE}) = dF(x)·(dτ^L_x)⁻¹E and d/dt f(e^{tE} g) = dF(x)·(dτ^R_x)⁻¹E, and
dτ^R_x = dτ^L_{−x}.  Seed 001 App. D prints the *right*-trivialised Cayley formulas, so the left
ones are taken as dcay^L_x = dcay^R_{−x}: on SO(3), (dcay^L_ω)⁻¹ = I + ω̂/2 + ωωᵀ/4, and
(dcay^L_{−hξ})⁻¹ = (dcay^R_{hξ})⁻¹ = I − hξ̂/2 + h²ξξᵀ/4 is eq. (64) as printed.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import pytest
import sympy as sp
from _seedcheck import (
    cay_se2,
    cay_so3,
    dcay_inv_se2_right,
    dcay_inv_so3_right,
    dcay_se2_right,
    dcay_so3_right,
    gradient,
    hat,
    is_zero,
    nonzero_somewhere,
    substitute,
)
from _systems import se2_control_system, se2_cost, se2_psi, so3_control_system, so3_cost, so3_psi

import symgroupoid as sg

t = sp.Symbol("t", real=True)


def _rotation(axis: int) -> sp.Matrix:
    """exp(t E_axis): the rotation by angle t about coordinate axis ``axis``, written out."""
    cs, sn = sp.cos(t), sp.sin(t)
    return [sp.Matrix([[1, 0, 0], [0, cs, -sn], [0, sn, cs]]),
            sp.Matrix([[cs, 0, sn], [0, 1, 0], [-sn, 0, cs]]),
            sp.Matrix([[cs, -sn, 0], [sn, cs, 0], [0, 0, 1]])][axis]


# --- discrete Euler–Poincaré ----------------------------------------------------------------

def test_euler_poincare_arbitrary_lagrangian_so3() -> None:
    """Seed 001 §2.2.5 / seed 000 §6.1: ℓ*_{g_k}dL(g_k) − r*_{g_{k+1}}dL(g_{k+1}) = 0, i.e.
    d/dt L(g_k e^{tE_i}) − d/dt L(e^{tE_i} g_{k+1}) at t = 0, for L an undefined function of the
    nine entries of g and e^{tE_i} the explicit rotation matrices."""
    F = sp.Function("L_d")
    step = sg.DiscreteSystem(sg.SO3("g"), lambda g: F(*g.matrix), name="ep").euler_lagrange()
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    assert len(step.residuals) == 3
    for i, res in enumerate(step.residuals):
        R = _rotation(i)
        left = sp.diff(F(*(gk * R)), t).subs(t, 0).doit()
        right = sp.diff(F(*(R * gp)), t).subs(t, 0).doit()
        assert sp.expand(res - (left - right)) == 0
        # control: the two trivialisations are not interchangeable
        swapped = (sp.diff(F(*(R * gk)), t).subs(t, 0).doit()
                   - sp.diff(F(*(gp * R)), t).subs(t, 0).doit())
        assert sp.expand(res - swapped) != 0


def test_euler_poincare_rigid_body_lie_poisson() -> None:
    """Seed 000 §6.1, discrete Lie–Poisson form μ_{k+1} = Ad*_{g_k} μ_k with μ_k = r*_{g_k}dL(g_k),
    for the rigid body L(g) = tr(J g) (J symmetric): the residual equals
    ℓ*_{g_k}dL(g_k) − μ_{k+1} and ℓ*_{g_k}dL(g_k) = Ad*_{g_k} μ_k on SO(3) (g_k = cay(a))."""
    Js = sp.symbols("J11 J12 J13 J22 J23 J33", real=True)
    J = sp.Matrix([[Js[0], Js[1], Js[2]], [Js[1], Js[3], Js[4]], [Js[2], Js[4], Js[5]]])
    G = sg.SO3("g")
    step = sg.DiscreteSystem(G, lambda g: (J * g.matrix).trace(), parameters=Js,
                             name="rigid_body").euler_lagrange()
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    basis = [sp.Matrix(E) for E in sg.SO3.basis_matrices()]
    left_k = [(J * gk * E).trace() for E in basis]  # ℓ*_{g_k} dL(g_k)
    mu = [(J * E * gk).trace() for E in basis]  # r*_{g_k} dL(g_k)
    mu_next = [(J * E * gp).trace() for E in basis]
    for res, lk, mn in zip(step.residuals, left_k, mu_next):
        assert sp.expand(res - (lk - mn)) == 0
    a = sp.symbols("a1:4", real=True)
    on_group = dict(zip(gk, cay_so3(a)))
    Ad_star_mu = G.Ad_star(gk) * sp.Matrix(mu)
    for lk, am in zip(left_k, Ad_star_mu):
        assert is_zero(substitute(lk - am, on_group))


# --- optimal control with the Cayley retraction ---------------------------------------------

def _seed_000_rhs(cost: Callable, psi: Callable, dcay_inv_left: Callable, h: sp.Symbol,
                  xi_k: list, xi_p: list, lam_k: list, lam_p: list) -> sp.Matrix:
    """(dτ⁻¹_{hξ_k})*(dl(ξ_k) + λ_k·dψ(ξ_k))
    − (dτ⁻¹_{−hξ_{k+1}})*(dl(ξ_{k+1}) + λ_{k+1}·dψ(ξ_{k+1})),
    dτ⁻¹ left-trivialised (seed 000 §6.1, final display)."""
    def momentum(xi: list, lam: list) -> sp.Matrix:
        p = gradient(cost(xi), xi)
        for la, ps in zip(lam, psi(xi)):
            p += la * gradient(ps, xi)
        return p

    return (dcay_inv_left([h * v for v in xi_k]).T * momentum(xi_k, lam_k)
            - dcay_inv_left([-h * v for v in xi_p]).T * momentum(xi_p, lam_p))


def _so3_left(w: Sequence) -> sp.Matrix:
    """Left-trivialised (dcay^L_ω)⁻¹ = right-trivialised at −ω (seed 001 eq. (64))."""
    return dcay_inv_so3_right([-v for v in w])


def _se2_left(x: Sequence) -> sp.Matrix:
    """Left-trivialised (dcay^L_x)⁻¹ y = (e + x/2) y (e − x/2) (seed 001 App. D at −x)."""
    return dcay_inv_se2_right([-v for v in x])


CASES = {
    "SO3": dict(system=so3_control_system, name="g", cost=so3_cost, psi=so3_psi,
                cay=cay_so3, left=_so3_left, right=dcay_inv_so3_right),
    "SE2": dict(system=se2_control_system, name="s", cost=se2_cost, psi=se2_psi,
                cay=cay_se2, left=_se2_left, right=dcay_inv_se2_right),
}


@pytest.mark.parametrize("case", [  # SO(3) (10 s): with the slow tests
    pytest.param(c, marks=pytest.mark.slow) if c == "SO3" else c for c in sorted(CASES)])
def test_optimal_control_cayley(case: str) -> None:
    """Seed 000 §6.1 (final display), docs/conventions.md §5, with quadratic cost l(ξ) = ½ξᵀIξ and a
    linear plus a nonlinear control constraint ψ: after g_k = cay(hξ_k), g_{k+1} = cay(hξ_{k+1})
    the derived DEL equal the seed's formula with dcay⁻¹ from seed 001 App. D (left-trivialised
    = right-trivialised at −x), and the constraint rows equal h·ψ(ξ_{k+1}).
    Control: with the printed right-trivialised dcay⁻¹ used as is, the identity fails."""
    cfg = CASES[case]
    system = cfg["system"]()
    G, h = system.groupoid, system.parameters[0]
    step = system.euler_lagrange()
    r = G.rank
    xi_k = list(sp.symbols(f"xi1:{r + 1}", real=True))
    xi_p = list(sp.symbols(f"eta1:{r + 1}", real=True))
    gk, gp = step.symbol(cfg["name"], "k"), step.symbol(cfg["name"], "k+1")
    lam_k, lam_p = step.symbol("lambda", "k"), step.symbol("lambda", "k+1")
    ck, cp = cfg["cay"]([h * v for v in xi_k]), cfg["cay"]([h * v for v in xi_p])
    free = [(i, j) for i in range(gk.rows) for j in range(gk.cols) if gk[i, j].is_Symbol]
    on_group = ({gk[i, j]: ck[i, j] for i, j in free} | {gp[i, j]: cp[i, j] for i, j in free})
    expected = _seed_000_rhs(cfg["cost"], cfg["psi"], cfg["left"], h, xi_k, xi_p, lam_k, lam_p)
    wrong = _seed_000_rhs(cfg["cost"], cfg["psi"], cfg["right"], h, xi_k, xi_p, lam_k, lam_p)
    assert len(step.residuals) == r + 2
    derived = [substitute(res, on_group) for res in step.residuals]
    for i in range(r):
        assert is_zero(derived[i] - expected[i])
    assert any(nonzero_somewhere(derived[i] - wrong[i]) for i in range(r))
    for res, p in zip(derived[r:], cfg["psi"](xi_p)):
        assert is_zero(res - h * p)


# --- dτ and dτ⁻¹ against seed 001 Appendix D ------------------------------------------------

W = sp.symbols("w1:4", real=True)
X_SE2 = sp.symbols("x1:4", real=True)


def _zero_matrix(M: sp.Matrix) -> bool:
    return all(sp.cancel(e) == 0 for e in M)


def test_so3_dcay_matches_appendix_d_eq64() -> None:
    """Seed 001 eq. (64): right-trivialised dcay_ω = 2/(4+|ω|²)(2I₃ + ω̂) and
    dcay⁻¹_ω = I₃ − ω̂/2 + ωωᵀ/4; left-trivialised = right-trivialised at −ω
    (docs/conventions.md §5)."""
    G = sg.SO3("g")
    minus = [-v for v in W]
    assert _zero_matrix(G.dtau(W, "right") - dcay_so3_right(W))
    assert _zero_matrix(G.dtau_inverse(W, "right") - dcay_inv_so3_right(W))
    assert _zero_matrix(G.dtau(W, "left") - dcay_so3_right(minus))
    assert _zero_matrix(G.dtau_inverse(W, "left") - dcay_inv_so3_right(minus))
    # and the two sides really differ (ω̂ ≠ 0)
    assert not _zero_matrix(G.dtau(W, "left") - G.dtau(W, "right"))


def test_so3_dcay_matches_appendix_d_general_form() -> None:
    """Seed 001 App. D general form on so(3): dcay_x y = (e − x/2)⁻¹ y (e + x/2)⁻¹ and
    dcay⁻¹_x y = (e − x/2) y (e + x/2), y running over E₁, E₂, E₃ (right-trivialised)."""
    G = sg.SO3("g")
    X, e = hat(W), sp.eye(3)
    A, B = (e - X / 2).inv(), (e + X / 2).inv()
    basis = [sp.Matrix(E) for E in sg.SO3.basis_matrices()]
    D = sp.Matrix.hstack(*[G.vee(A * E * B) for E in basis])
    Dinv = sp.Matrix.hstack(*[G.vee((e - X / 2) * E * (e + X / 2)) for E in basis])
    assert _zero_matrix(G.dtau(W, "right") - D)
    assert _zero_matrix(G.dtau_inverse(W, "right") - Dinv)


def test_se2_dcay_matches_appendix_d_general_form() -> None:
    """Seed 001 App. D general form on se(2), right-trivialised:
    dcay_x y = (e − x/2)⁻¹ y (e + x/2)⁻¹, dcay⁻¹_x y = (e − x/2) y (e + x/2); left at −x."""
    G = sg.SE2("s")
    minus = [-v for v in X_SE2]
    assert _zero_matrix(G.dtau(X_SE2, "right") - dcay_se2_right(X_SE2))
    assert _zero_matrix(G.dtau_inverse(X_SE2, "right") - dcay_inv_se2_right(X_SE2))
    assert _zero_matrix(G.dtau(X_SE2, "left") - dcay_se2_right(minus))
    assert _zero_matrix(G.dtau_inverse(X_SE2, "left") - dcay_inv_se2_right(minus))
    assert not _zero_matrix(G.dtau(X_SE2, "left") - G.dtau(X_SE2, "right"))


def test_cayley_map_matches_appendix_d_eq63() -> None:
    """Seed 001 eq. (63): cay(ω̂) = I₃ + 4/(4+|ω|²)(ω̂ + ω̂²/2), and the library's τ⁻¹ inverts it
    (``.coordinates`` of cay(ω) is ω) on SO(3) and SE(2)."""
    G = sg.SO3("g")
    assert _zero_matrix(G.cayley(W) - cay_so3(W))
    assert _zero_matrix(G.retraction_inverse(cay_so3(W)) - sp.Matrix(W))
    S = sg.SE2("s")
    assert _zero_matrix(S.cayley(X_SE2) - cay_se2(X_SE2))
    assert _zero_matrix(S.retraction_inverse(cay_se2(X_SE2)) - sp.Matrix(X_SE2))
