"""The pair groupoid Q × Q ⇉ Q: discrete Euler–Lagrange equations of Marsden and West.

On the pair groupoid the generic rule X⃖[L](g_k) = X⃗[L](g_{k+1}) (seed 000 Thm 2.13) becomes

    D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) = 0

(seed 000 §2.2, after Remark 2.14).  This script derives the equations for an *arbitrary*
discrete Lagrangian L (an undefined SymPy function of all 2n coordinates) on R¹ and R², prints
them, and checks symbolically that they are exactly the Marsden–West equations.

Run:  python examples/pair_groupoid.py
"""

from __future__ import annotations

import sympy as sp

import symgroupoid as sg


def partial(F: sp.Function, n: int, slot: int, point: tuple) -> sp.Expr:
    """∂F/∂(argument ``slot``) of a function F of n variables, evaluated at ``point``."""
    u = sp.symbols(f"u0:{n}", real=True)
    return sp.diff(F(*u), u[slot]).subs(dict(zip(u, point)), simultaneous=True).doit()


def marsden_west(F: sp.Function, names: list[str], step: sg.StepEquations) -> list[sp.Expr]:
    """D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) in the step's own symbols."""
    n = len(names)
    qm, q, qp = (tuple(step.symbol(s, k) for s in names) for k in ("k-1", "k", "k+1"))
    return [partial(F, 2 * n, n + j, qm + q) + partial(F, 2 * n, j, q + qp) for j in range(n)]


def main() -> None:
    F = sp.Function("L_d")
    for names in ("q", "x y"):
        space = sg.EuclideanSpace(names)
        system = sg.DiscreteSystem(sg.PairGroupoid(space), lambda g: F(*g.source, *g.target),
                                   name=f"pair_{space.dim}d")
        step = system.euler_lagrange()
        print(f"R^{space.dim}: unknowns {step.unknowns}, knowns {step.knowns}")
        print(step.latex())
        expected = marsden_west(F, list(space.names), step)
        for residual, seed_form in zip(step.residuals, expected):
            if sp.expand(residual - seed_form) != 0:
                raise SystemExit(f"mismatch on R^{space.dim}: {residual} vs {seed_form}")
    print("verified against seed 000 §2.2 (Marsden–West DEL, arbitrary L on R^1 and R^2)")


if __name__ == "__main__":
    main()
