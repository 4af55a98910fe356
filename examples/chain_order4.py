"""The 3D two- or three-body pendulum at order 4: a Galerkin variational integrator on SO(3)ⁿ
from its continuous Lagrangian, against an accurate solution of the continuous equations
(docs/conventions.md §21, §22).

n = 2 (or 3, ``--bodies 3``) rigid bodies in a chain, body 1 pinned at the origin, body i
hanging from the end of body i − 1 by a ball joint; unit masses, principal inertias
Jᵢ = ``systems.chain_inertia(i)`` about the centres of mass (the physics of
``symgroupoid.systems.spherical_chain``), the link ℓ = (0, 0, −1) and the centre of mass
ρ = (0, 0, −½) in each body's frame.  With the body velocities ξᵢ = RᵢᵀṘᵢ,

    L(R, ξ) = Σᵢ ½ ξᵢᵀJᵢξᵢ + ½|ċᵢ|² − g e₃·cᵢ,
    cᵢ = Σ_{j<i} R_j ℓ + Rᵢ ρ,   ċᵢ = Σ_{j<i} R_j ξ̂_j ℓ + Rᵢ ξ̂ᵢ ρ.

``ContinuousSystem([SO3, …, SO3], L).discretize(h, GaussLegendre(2))`` is the two-stage
Gauss–Legendre Galerkin integrator through each factor's Cayley retraction (order 4).  The
reference integrates the continuous equations derived here independently of the library:
Ṙᵢ = Rᵢξ̂ᵢ and the Euler–Poincaré equations of the left-trivialised Lagrangian (Holm–Schmah–
Stoica, Geometric Mechanics and Symmetry, §7),

    d/dt Πᵢ + ξᵢ × Πᵢ = Tᵢ,   Πᵢ = ∂L/∂ξᵢ,   Tᵢ·η = d/dε|₀ L(…, Rᵢ exp(εη̂), …; ξ),

i.e. M(R) ξ̇ = T − ξ × Π − Σ_j (∂Π/∂R_j)·R_jξ̂_j with M = ∂Π/∂ξ (L is quadratic in ξ), by
scipy's DOP853 at tolerance 1e-13.  The script prints the final-time error of the attitudes
against h = T/N and the observed order; it exits with status 1 when the observed order
misses 4 by more than 0.1 (tests/test_examples.py checks the printed numbers as well).
Deriving and compiling the two-body step takes about half a minute, the three-body step
about as long (measured on 27 November 2026, three bodies: errors 6.9e-6, 4.3e-7, 2.7e-8 at
N = 20, 40, 80, observed order 3.995).

Run:  python examples/chain_order4.py [--bodies 3]
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import symgroupoid as sg
from symgroupoid.systems import chain_inertia

LINK, CENTRE = sp.Matrix([0, 0, -1]), sp.Matrix([0, 0, sp.Rational(-1, 2)])
GRAVITY = 9.81
#: the initial attitudes (rotation vectors) and body velocities of up to three bodies
ROTATION_VECTORS = ([0.6, 0.2, 0.0], [0.9, -0.4, 0.2], [-0.3, 1.0, 0.5])
BODY_VELOCITIES = [0.5, -0.3, 0.8, 1.0, 0.4, -0.6, -0.7, 0.9, 0.2]
T = 1.0
STEPS = [20, 40, 80]
SCHEME = sg.GaussLegendre(2)


def hat(w) -> sp.Matrix:
    """ŵ, the skew matrix with ŵv = w × v."""
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def lagrangian(R: Sequence[sp.Matrix], xi: Sequence[sp.Matrix], grav) -> sp.Expr:
    """L(R, ξ) of the module docstring."""
    joint, joint_rate, L = sp.zeros(3, 1), sp.zeros(3, 1), sp.S.Zero
    for i, (Ri, wi) in enumerate(zip(R, xi), start=1):
        c, c_dot = joint + Ri * CENTRE, joint_rate + Ri * hat(wi) * CENTRE
        L += ((wi.T * chain_inertia(i) * wi)[0, 0] / 2 + (c_dot.T * c_dot)[0, 0] / 2
              - grav * c[2])
        joint, joint_rate = joint + Ri * LINK, joint_rate + Ri * hat(wi) * LINK
    return L


def chain(n: int) -> sg.ContinuousSystem:
    h, grav = sp.symbols("h g", positive=True)
    factors = [sg.SO3(f"R{i}") for i in range(1, n + 1)]
    return sg.ContinuousSystem(factors, lambda q, v: lagrangian(list(q), list(v), grav),
                               parameters=[h, grav], name=f"chain_{n}")


# --- the reference: the Euler–Poincaré equations, derived here ---------------------------------

def euler_poincare(n: int):
    """Numerical M(y) and rhs(y), y = (R₁ row by row, …, ξ₁, …), lambdified from the
    symbolic Euler–Poincaré equations of the module docstring (n bodies)."""
    R = [sp.Matrix(3, 3, sp.symbols(f"r{i}_0:9")) for i in range(n)]
    xi = [sp.Matrix(sp.symbols(f"w{i}_0:3")) for i in range(n)]
    L = lagrangian(R, xi, sp.Float(GRAVITY))
    w = sp.Matrix.vstack(*xi)
    Pi = sp.Matrix([sp.diff(L, s) for s in w])
    M = Pi.jacobian(w)
    basis = [hat(sp.eye(3)[:, k]) for k in range(3)]
    rhs = []
    for i, (Ri, wi) in enumerate(zip(R, xi)):
        dL = Ri.applyfunc(lambda r: sp.diff(L, r))
        torque = sp.Matrix([sum(dL.multiply_elementwise(Ri * E)) for E in basis])
        rhs.append(torque - wi.cross(Pi[3 * i:3 * i + 3, 0]))
    rhs = sp.Matrix.vstack(*rhs)
    for Rj, wj in zip(R, xi):
        rate = Rj * hat(wj)
        for a in range(3):
            for b in range(3):
                rhs -= Pi.diff(Rj[a, b]) * rate[a, b]
    args = [*(s for Ri in R for s in Ri), *w]
    return (sp.lambdify([args], M, "numpy", cse=True),
            sp.lambdify([args], rhs, "numpy", cse=True))


def reference(T: float, attitudes: Sequence[np.ndarray], xi0: np.ndarray) -> np.ndarray:
    """The attitudes at T, row by row, body after body (DOP853 at tolerance 1e-13)."""
    n = len(attitudes)
    M, f = euler_poincare(n)

    def rhs(t, y):
        w = y[9 * n:]
        rates = [y[9 * i:9 * i + 9].reshape(3, 3)
                 @ np.array(hat(w[3 * i:3 * i + 3]).tolist(), float) for i in range(n)]
        dw = np.linalg.solve(np.asarray(M(y), float), np.asarray(f(y), float).ravel())
        return np.concatenate([*(r.ravel() for r in rates), dw])

    y0 = np.concatenate([*(R.ravel() for R in attitudes), xi0])
    sol = solve_ivp(rhs, (0.0, T), y0, method="DOP853", rtol=1e-13, atol=1e-13)
    return sol.y[:9 * n, -1]


def rotation(v: Sequence[float]) -> np.ndarray:
    """exp(v̂) by Rodrigues' formula."""
    v = np.asarray(v, float)
    angle = np.linalg.norm(v)
    K = np.array(hat(v / angle).tolist(), float)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description="the 3D chain at order 4")
    parser.add_argument("--bodies", type=int, choices=(2, 3), default=2)
    n = parser.parse_args(argv).bodies
    attitudes = [rotation(v) for v in ROTATION_VECTORS[:n]]
    xi0 = np.array(BODY_VELOCITIES[:3 * n], float)
    configuration = {f"R{i}": R for i, R in enumerate(attitudes, start=1)}
    report = sg.convergence_order(chain(n), SCHEME, (configuration, xi0), {"g": GRAVITY}, T,
                                  STEPS, reference=reference(T, attitudes, xi0))
    print(f"3D {n}-body pendulum on SO(3)^{n}, "
          f"{type(SCHEME).__name__}({SCHEME.stages}), T = {T}, against DOP853 (tol 1e-13)")
    print(report)
    if abs(report.order - SCHEME.order) > 0.1:
        raise SystemExit(f"chain_order4: observed order {report.order:.3f}, theoretical "
                         f"{SCHEME.order}")


if __name__ == "__main__":
    main()
