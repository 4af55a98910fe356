"""The discrete plate-ball system (seed 000 §6.2), derived and checked against the seed.

Groupoid R² × R² × SO(3) ⇉ R², arrow (x₀, y₀, x₁, y₁, g); discrete Lagrangian and rolling
constraints of seed 000 eq. (8):

    L  = (h/2)[((x₁−x₀)/h)² + ((y₁−y₀)/h)²],
    φ¹ = h[(y₁−y₀)/h − r/(2h) tr(g E₁) − Ω(x₁+x₀)/2],
    φ² = h[(x₁−x₀)/h + r/(2h) tr(g E₂) + Ω(y₁+y₀)/2],
    φ³ = h[c + tr(g E₃)/(2h)].

The script derives the eight equations (five DEL, three constraints), prints them, and compares
each with the equation printed in the seed, transcribed below with the traces tr(g_k E_i E_j),
tr(E_i g_{k+1} E_j) written as explicit matrix products.  Each derived equation must be a
nonzero constant times the printed one.  The printed rotational rows carry (λ)₃ with the
opposite sign (they belong to −φ³, docs/conventions.md §6); since a multiplier is fixed only
up to the sign of its constraint, (λ)₃ is replaced by −(λ)₃ in those rows before comparing.

Run:  python examples/plate_ball.py
"""

from __future__ import annotations

import sympy as sp

import symgroupoid as sg

h, r, Omega, c = sp.symbols("h r Omega c", positive=True)
E1, E2, E3 = (sp.Matrix(E) for E in sg.SO3.basis_matrices())


def plate_ball() -> sg.DiscreteSystem:
    G = sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("g")

    def L(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        return h / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)

    def phi(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return [h * ((y1 - y0) / h - r / (2 * h) * (W * E1).trace() - Omega * (x1 + x0) / 2),
                h * ((x1 - x0) / h + r / (2 * h) * (W * E2).trace() + Omega * (y1 + y0) / 2),
                h * (c + (W * E3).trace() / (2 * h))]

    return sg.DiscreteSystem(G, L, constraints=phi, parameters=[h, r, Omega, c],
                             name="plate_ball")


def seed_equations(step: sg.StepEquations) -> list[sp.Expr]:
    """The eight equations 0 = … printed in seed 000 §6.2, with (λ)₃ → −(λ)₃ in rows 3–5."""
    xm, x, xp = (step.symbol("x", s) for s in ("k-1", "k", "k+1"))
    ym, y, yp = (step.symbol("y", s) for s in ("k-1", "k", "k+1"))
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    lk, lp = step.symbol("lambda", "k"), step.symbol("lambda", "k+1")
    tr = sp.Matrix.trace
    eqs = [(xp - 2 * x + xm) / h**2 + (lp[1] - lk[1]) / h + Omega * (lp[0] + lk[0]) / 2,
           (yp - 2 * y + ym) / h**2 + (lp[0] - lk[0]) / h - Omega * (lp[1] + lk[1]) / 2]
    flip = -1  # the printed rows belong to −φ³
    for Ei in (E1, E2, E3):
        eqs.append(-r * lk[0] * tr(gk * Ei * E1) + r * lp[0] * tr(Ei * gp * E1)
                   + r * lk[1] * tr(gk * Ei * E2) - r * lp[1] * tr(Ei * gp * E2)
                   - flip * lk[2] * tr(gk * Ei * E3) + flip * lp[2] * tr(Ei * gp * E3))
    eqs += [(yp - y) / h - r / (2 * h) * tr(gp * E1) - Omega * (xp + x) / 2,
            (xp - x) / h + r / (2 * h) * tr(gp * E2) + Omega * (yp + y) / 2,
            c + tr(gp * E3) / (2 * h)]
    return eqs


def main() -> None:
    step = plate_ball().euler_lagrange()
    print(f"{len(step)} equations in the unknowns {step.unknowns}")
    print(step.latex())
    variables = set(step.knowns) | set(step.unknowns) | set(step.fibre_unknowns)
    for i, (residual, printed) in enumerate(zip(step.residuals, seed_equations(step)), 1):
        ratio = sp.factor(sp.cancel(residual / printed))
        if ratio == 0 or ratio.free_symbols & variables:
            raise SystemExit(f"equation {i} is not a constant multiple of the seed's: {ratio}")
        print(f"equation {i}: derived = ({ratio}) × printed")
    print("verified against seed 000 §6.2 (all eight equations)")


if __name__ == "__main__":
    main()
