"""Constrained optimal control on SO(3) and SE(2) with the Cayley retraction, checked against
the seeds' formulas (seed 000 §6.1; seed 001 Appendix D; docs/conventions.md §5).

With step h, cost l(ξ) = ½ ξᵀ I ξ and control constraints ψᵃ(ξ) = 0,

    L(g) = h l(τ⁻¹(g)/h),   φᵃ(g) = h ψᵃ(τ⁻¹(g)/h),   ξ_k = τ⁻¹(g_k)/h,

and seed 000 §6.1 states the discrete equations as

    (dτ⁻¹_{hξ_k})*(dl(ξ_k) + λ_k·dψ(ξ_k)) = (dτ⁻¹_{−hξ_{k+1}})*(dl(ξ_{k+1}) + λ_{k+1}·dψ(ξ_{k+1}))

with dτ the *left*-trivialised tangent (T_ξτ = T_e ℓ_{τ(ξ)} ∘ dτ_ξ).  Seed 001 App. D prints the
*right*-trivialised Cayley tangents — dcay⁻¹_x y = (e − x/2) y (e + x/2) in general and
dcay⁻¹_ω = I − ω̂/2 + ωωᵀ/4 on SO(3) (eq. (64)) — so the left-trivialised ones are those at −x.

The script derives the equations from L and φ alone, substitutes g_k = cay(hξ_k) and
g_{k+1} = cay(hξ_{k+1}), and checks that they equal the formula above exactly; it also checks
the library's symbolic (right-trivialised) dτ⁻¹ against the printed App. D forms.

Run:  python examples/optimal_control_so3_se2.py
"""

from __future__ import annotations

import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)


# --- the printed Appendix D formulas ----------------------------------------------------------

def so3_dcay_inv_right(w) -> sp.Matrix:
    """dcay⁻¹_ω = I₃ − ω̂/2 + ωωᵀ/4 (seed 001 eq. (64), right-trivialised)."""
    w = sp.Matrix(w)
    return sp.eye(3) - sg.hat3(w) / 2 + w * w.T / 4


def so3_cay(w) -> sp.Matrix:
    """cay(ω̂) = I₃ + 4/(4 + |ω|²)(ω̂ + ω̂²/2) (seed 001 eq. (63))."""
    W = sg.hat3(w)
    return (sp.eye(3) + 4 / (4 + sum(v**2 for v in w)) * (W + W * W / 2)).applyfunc(sp.cancel)


def se2_hat(x) -> sp.Matrix:
    return sp.Matrix([[0, -x[0], x[1]], [x[0], 0, x[2]], [0, 0, 0]])


def se2_vee(M: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([M[1, 0], M[0, 2], M[1, 2]])


def se2_dcay_inv_right(x) -> sp.Matrix:
    """y ↦ (e − x/2) y (e + x/2) as a 3×3 matrix (seed 001 App. D, right-trivialised)."""
    X, e = se2_hat(x), sp.eye(3)
    return sp.Matrix.hstack(*[se2_vee((e - X / 2) * se2_hat(e[:, j]) * (e + X / 2))
                              for j in range(3)])


def se2_cay(x) -> sp.Matrix:
    X, e = se2_hat(x), sp.eye(3)
    return ((e - X / 2).inv() * (e + X / 2)).applyfunc(sp.cancel)


# --- the problems -------------------------------------------------------------------------------

def so3_problem():
    I1, I2, I3, u = sp.symbols("I_1 I_2 I_3 u", positive=True)

    def cost(xi):
        return (I1 * xi[0] ** 2 + I2 * xi[1] ** 2 + I3 * xi[2] ** 2) / 2

    def psi(xi):  # spin about the third axis prescribed; a nonlinear coupling of the others
        return [xi[2] - u, xi[0] ** 2 + xi[1] * xi[2] - 1]

    return sg.SO3("g"), "g", cost, psi, [h, I1, I2, I3, u], so3_cay, so3_dcay_inv_right


def se2_problem():
    A, M, kappa = sp.symbols("A M kappa", positive=True)

    def cost(xi):  # ξ = (ω, v₁, v₂)
        return (A * xi[0] ** 2 + M * xi[1] ** 2 + M * xi[2] ** 2) / 2

    def psi(xi):  # lateral velocity tied to the turning rate; a nonlinear constraint
        return [xi[2] - kappa * xi[0], xi[1] ** 2 + xi[0] * xi[2] - 1]

    return sg.SE2("s"), "s", cost, psi, [h, A, M, kappa], se2_cay, se2_dcay_inv_right


def substitute(expr: sp.Expr, values: dict) -> sp.Expr:
    """``expr.xreplace(values)``, cancelling substituted power bases first (e.g.
    1/(1 + tr g) with g = cay(ω) becomes (4 + |ω|²)/16) so the final cancel stays small."""
    pows = [p for p in expr.atoms(sp.Pow) if p.base.free_symbols & set(values)]
    bases = {p: sp.factor(sp.cancel(p.base.xreplace(values))) ** p.exp for p in pows}
    return expr.xreplace(bases).xreplace(values)


def gradient(f, xi) -> sp.Matrix:
    return sp.Matrix([sp.diff(f, v) for v in xi])


def verify(problem) -> None:
    G, name, cost, psi, params, cay, dcay_inv_right = problem()
    system = sg.DiscreteSystem(
        G, lambda g: h * cost(list(g.coordinates / h)),
        constraints=lambda g: [h * p for p in psi(list(g.coordinates / h))],
        parameters=params, name=f"optimal_control_{G.group_name}")
    step = system.euler_lagrange()
    print(f"{system.name}: {len(step)} equations in {step.unknowns}")
    print(step.latex())

    def left(x):  # left-trivialised dcay⁻¹_x = right-trivialised at −x
        return dcay_inv_right([-v for v in x])

    r = G.rank
    xk, xp = sp.symbols(f"xi1:{r + 1}", real=True), sp.symbols(f"eta1:{r + 1}", real=True)
    lk, lp = step.symbol("lambda", "k"), step.symbol("lambda", "k+1")

    def momentum(xi, lam):
        p = gradient(cost(xi), xi)
        for la, ps in zip(lam, psi(xi)):
            p += la * gradient(ps, xi)
        return p

    seed = (left([h * v for v in xk]).T * momentum(xk, lk)
            - left([-h * v for v in xp]).T * momentum(xp, lp))
    gk, gp = step.symbol(name, "k"), step.symbol(name, "k+1")
    ck, cp = cay([h * v for v in xk]), cay([h * v for v in xp])
    on_group = {gk[i, j]: ck[i, j] for i in range(gk.rows) for j in range(gk.cols)
                if gk[i, j].is_Symbol}
    on_group |= {gp[i, j]: cp[i, j] for i in range(gp.rows) for j in range(gp.cols)
                 if gp[i, j].is_Symbol}
    expected = list(seed) + [h * p for p in psi(xp)]
    for i, (residual, exp) in enumerate(zip(step.residuals, expected), 1):
        if sp.cancel(sp.together(substitute(residual, on_group) - exp)) != 0:
            raise SystemExit(f"{system.name}: equation {i} differs from seed 000 §6.1")
    x = sp.symbols(f"x1:{r + 1}", real=True)
    if any(sp.cancel(d) != 0 for d in G.dtau_inverse(x, "right") - dcay_inv_right(x)):
        raise SystemExit(f"{G.name}: the library's dtau^-1 differs from App. D")
    print(f"{system.name}: equations = seed 000 §6.1 with App. D dcay^-1 (left = right at -x)")


def main() -> None:
    verify(so3_problem)
    verify(se2_problem)
    print("verified against seed 000 §6.1 and seed 001 Appendix D (SO(3) and SE(2))")


if __name__ == "__main__":
    main()
