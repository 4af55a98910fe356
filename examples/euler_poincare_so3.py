"""Discrete Euler–Poincaré equations on SO(3) (seed 001 §2.2.5; seed 000 Thm 2.13, §6.1).

For a Lie group G ⇉ {e} the discrete Euler–Lagrange equations are

    ℓ*_{g_k} dL(g_k) = r*_{g_{k+1}} dL(g_{k+1}),   i.e.
    d/dt L(g_k e^{tE_i})|₀ − d/dt L(e^{tE_i} g_{k+1})|₀ = 0,   i = 1, 2, 3.

The script derives them for an arbitrary L: SO(3) → R (an undefined function of the nine
matrix entries) and checks them against the right-hand side computed independently with the
explicit rotation matrices e^{tE_i}; then, for the rigid body L(g) = tr(J g), it checks the
discrete Lie–Poisson form μ_{k+1} = Ad*_{g_k} μ_k with μ_k = r*_{g_k} dL(g_k) (seed 000 §6.1)
on rotations g_k = cay(a).

Run:  python examples/euler_poincare_so3.py
"""

from __future__ import annotations

import sympy as sp

import symgroupoid as sg

t = sp.Symbol("t", real=True)


def rotation(axis: int) -> sp.Matrix:
    """e^{t E_axis}, written out."""
    c, s = sp.cos(t), sp.sin(t)
    return [sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]]),
            sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])][axis]


def d_dt(expr: sp.Expr) -> sp.Expr:
    return sp.diff(expr, t).subs(t, 0).doit()


def arbitrary_lagrangian() -> None:
    F = sp.Function("L_d")
    step = sg.DiscreteSystem(sg.SO3("g"), lambda g: F(*g.matrix),
                             name="euler_poincare").euler_lagrange()
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    for i, residual in enumerate(step.residuals):
        R = rotation(i)
        expected = d_dt(F(*(gk * R))) - d_dt(F(*(R * gp)))
        if sp.expand(residual - expected) != 0:
            raise SystemExit(f"Euler–Poincaré equation {i + 1} differs")
    print(f"arbitrary L: {len(step)} equations, e.g.\n  0 = {step.residuals[0]}")


def rigid_body() -> None:
    Js = sp.symbols("J11 J22 J33", positive=True)
    J = sp.diag(*Js)
    G = sg.SO3("g")
    step = sg.DiscreteSystem(G, lambda g: (J * g.matrix).trace(), parameters=Js,
                             name="rigid_body").euler_lagrange()
    print(step.latex())
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    basis = [sp.Matrix(E) for E in sg.SO3.basis_matrices()]
    mu_k = sp.Matrix([(J * E * gk).trace() for E in basis])      # r*_{g_k} dL(g_k)
    mu_next = sp.Matrix([(J * E * gp).trace() for E in basis])   # r*_{g_{k+1}} dL(g_{k+1})
    a = sp.symbols("a1:4", real=True)
    W = sg.hat3(a)
    on_group = dict(zip(gk, sp.eye(3) + 4 / (4 + sum(v**2 for v in a)) * (W + W * W / 2)))
    lie_poisson = G.Ad_star(gk) * mu_k - mu_next   # Ad*_{g_k} μ_k − μ_{k+1}
    for residual, lp in zip(step.residuals, lie_poisson):
        if sp.cancel(sp.together((residual - lp).xreplace(on_group))) != 0:
            raise SystemExit("rigid body: residual is not Ad*_{g_k} mu_k - mu_{k+1}")
    print("rigid body: residual = Ad*_{g_k} mu_k - mu_{k+1} on SO(3)")


def main() -> None:
    arbitrary_lagrangian()
    rigid_body()
    print("verified against seed 001 §2.2.5 and seed 000 §6.1 (discrete Euler–Poincaré)")


if __name__ == "__main__":
    main()
