"""The discrete heavy top on the action groupoid S² × SO(3) ⇉ S² (seed 002; docs/conventions.md §9).

Arrows (Γ, W) with α = Γ, β = WᵀΓ, (Γ, W)(WᵀΓ, W') = (Γ, WW'), and the discrete Lagrangian

    L_d(Γ, W) = −(1/h) tr(J_d W) − h m g l Γ·e,     J_d = ½ tr(I) I₃ − I.

The seed derives Π_{k+1} = W_kᵀ Π_k + m g l h² Γ_{k+1} × e with Π = axial(W J_d − J_d Wᵀ) and
Γ_{k+1} = W_kᵀ Γ_k.  This script derives the equations from L_d alone, prints them, and checks
that they equal −1/h · (Π_{k+1} − W_kᵀ Π_k − m g l h² Γ_{k+1} × e) exactly, with W_k and
W_{k+1} written through the Cayley map (seed 001 eq. (63)) so that they are rotations.

Run:  python examples/heavy_top.py
"""

from __future__ import annotations

import sympy as sp

import symgroupoid as sg

h, m, grav, ell = sp.symbols("h m g l", positive=True)
I1, I2, I3 = sp.symbols("I_1 I_2 I_3", positive=True)
e = sp.Matrix(sp.symbols("e1:4", real=True))
INERTIA = sp.diag(I1, I2, I3)
J_d = sg.NamedMatrix(INERTIA.trace() / 2 * sp.eye(3) - INERTIA, name="J_d")


def heavy_top() -> sg.DiscreteSystem:
    G = sg.ActionGroupoid(sg.EuclideanSpace.vector("Gamma", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))

    def L(g):
        return -(J_d * g.matrix).trace() / h - h * m * grav * ell * sp.Matrix(g.point).dot(e)

    return sg.DiscreteSystem(G, L, parameters=[h, m, grav, ell, I1, I2, I3, *e],
                             name="heavy_top")


def axial(M: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([M[2, 1], M[0, 2], M[1, 0]])


def cayley(w) -> sp.Matrix:
    """cay(ω̂) = I₃ + 4/(4 + |ω|²)(ω̂ + ω̂²/2), seed 001 eq. (63)."""
    W = sg.hat3(w)
    return sp.eye(3) + 4 / (4 + sum(v**2 for v in w)) * (W + W * W / 2)


def main() -> None:
    step = heavy_top().euler_lagrange()
    print(step.latex())
    Wk, Wp, Gk = step.symbol("W", "k"), step.symbol("W", "k+1"), step.symbol("Gamma", "k")
    J = sp.Matrix(J_d)

    def Pi(W):
        return axial(W * J - J * W.T)

    seed_form = Pi(Wp) - Wk.T * Pi(Wk) - m * grav * ell * h**2 * (Wk.T * Gk).cross(e)
    a, b = sp.symbols("a1:4", real=True), sp.symbols("b1:4", real=True)
    rotations = dict(zip(Wk, cayley(a))) | dict(zip(Wp, cayley(b)))
    for i, (residual, seed_i) in enumerate(zip(step.residuals, seed_form), 1):
        difference = (residual + seed_i / h).xreplace(rotations)
        if sp.cancel(sp.together(difference)) != 0:
            raise SystemExit(f"component {i} differs from the seed's heavy-top equation")
    print("derived = -(1/h) (Pi_{k+1} - W_k^T Pi_k - m g l h^2 Gamma_{k+1} x e), exactly")
    print("verified against seed 002 (heavy top on S^2 x SO(3))")


if __name__ == "__main__":
    main()
