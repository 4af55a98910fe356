"""The planar double pendulum at order 6: two Galerkin variational integrators from its
continuous Lagrangian, against an accurate solution of the continuous equations
(docs/conventions.md §21, §22).

Two point masses m₁, m₂ on massless rods of lengths l₁, l₂, the angles θ₁, θ₂ from the
downward vertical (Q = R²):

    L(θ, θ̇) = ½(m₁ + m₂) l₁² θ̇₁² + ½ m₂ l₂² θ̇₂² + m₂ l₁ l₂ θ̇₁ θ̇₂ cos(θ₁ − θ₂)
              + (m₁ + m₂) g l₁ cos θ₁ + m₂ g l₂ cos θ₂.

``discretize(h, GaussLegendre(3))`` (three Gauss nodes, order 6) and
``discretize(h, LobattoIIIAB(4))`` (four Lobatto nodes, order 2·4 − 2 = 6) are measured
against the Euler–Lagrange equations written here by hand, M(θ) θ̈ = f(θ, θ̇),

    M = [[(m₁ + m₂) l₁², m₂ l₁ l₂ c], [m₂ l₁ l₂ c, m₂ l₂²]],   c = cos(θ₁ − θ₂), s = sin(θ₁ − θ₂),
    f = (−m₂ l₁ l₂ s θ̇₂² − (m₁ + m₂) g l₁ sin θ₁,  m₂ l₁ l₂ s θ̇₁² − m₂ g l₂ sin θ₂),

solved by scipy's DOP853 at tolerance 1e-13.  The script prints, per scheme, the final-time
error of θ against h = T/N and the observed order; it exits with status 1 when an observed
order misses the theoretical one by more than 0.1 (tests/test_examples.py checks the
printed numbers as well).

Run:  python examples/double_pendulum_order6.py
"""

from __future__ import annotations

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import symgroupoid as sg

h, grav = sp.symbols("h g", positive=True)
m1, m2, l1, l2 = sp.symbols("m1 m2 l1 l2", positive=True)

PARAMS = {"g": 9.81, "m1": 1.0, "m2": 0.5, "l1": 1.0, "l2": 0.8}
THETA0, OMEGA0 = [0.6, -0.4], [0.0, 1.0]
T = 2.0
STEPS = [40, 80, 160]
SCHEMES = [sg.GaussLegendre(3), sg.LobattoIIIAB(4)]


def double_pendulum() -> sg.ContinuousSystem:
    def L(q, v):
        c = sp.cos(q[0] - q[1])
        kinetic = ((m1 + m2) * l1 ** 2 * v[0] ** 2 / 2 + m2 * l2 ** 2 * v[1] ** 2 / 2
                   + m2 * l1 * l2 * v[0] * v[1] * c)
        return kinetic + (m1 + m2) * grav * l1 * sp.cos(q[0]) + m2 * grav * l2 * sp.cos(q[1])

    return sg.ContinuousSystem(sg.EuclideanSpace("theta1 theta2"), L,
                               parameters=[h, grav, m1, m2, l1, l2], name="double_pendulum")


def rhs(t: float, y: np.ndarray) -> np.ndarray:
    """y = (θ₁, θ₂, θ̇₁, θ̇₂): M(θ) θ̈ = f(θ, θ̇) of the module docstring."""
    g, a, b, p, r = (PARAMS[k] for k in ("g", "m1", "m2", "l1", "l2"))
    t1, t2, w1, w2 = y
    c, s = np.cos(t1 - t2), np.sin(t1 - t2)
    M = np.array([[(a + b) * p ** 2, b * p * r * c], [b * p * r * c, b * r ** 2]])
    f = np.array([-b * p * r * s * w2 ** 2 - (a + b) * g * p * np.sin(t1),
                  b * p * r * s * w1 ** 2 - b * g * r * np.sin(t2)])
    return np.r_[w1, w2, np.linalg.solve(M, f)]


def reference(T: float) -> np.ndarray:
    """θ(T), DOP853 at tolerance 1e-13."""
    sol = solve_ivp(rhs, (0.0, T), np.r_[THETA0, OMEGA0], method="DOP853", rtol=1e-13,
                    atol=1e-13)
    return sol.y[:2, -1]


def main() -> None:
    system, target = double_pendulum(), reference(T)
    initial = ({"theta1": THETA0[0], "theta2": THETA0[1]}, OMEGA0)
    failures = []
    for scheme in SCHEMES:
        report = sg.convergence_order(system, scheme, initial, PARAMS, T, STEPS,
                                      reference=target)
        print(f"double pendulum, {type(scheme).__name__}({scheme.stages}), T = {T}, "
              f"against DOP853 (tol 1e-13)")
        print(report)
        if abs(report.order - scheme.order) > 0.1:
            failures.append(f"{type(scheme).__name__}({scheme.stages}): observed order "
                            f"{report.order:.3f}, theoretical {scheme.order}")
    if failures:
        raise SystemExit("double_pendulum_order6: " + "; ".join(failures))


if __name__ == "__main__":
    main()
