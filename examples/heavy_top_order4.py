"""The heavy top at order 4: a Galerkin variational integrator on SO(3) from its continuous
Lagrangian, against an accurate solution of the continuous equations (docs/conventions.md
§21, §22).

A rigid body with a fixed point, inertia J about it (body frame), mass m and centre of mass at
χ (body frame), in gravity g along −e₃:

    L(R, ξ) = ½ ξᵀJξ − m g e₃·(R χ),     ξ = Rᵀ Ṙ (the body angular velocity).

``ContinuousSystem(SO3, L).discretize(h, GaussLegendre(2))`` is the two-stage Gauss–Legendre
Galerkin integrator through the Cayley retraction (order 4).  The reference solves the
continuous equations, written here independently of the library (the heavy top's
Euler–Poincaré equations; Holm, Geometric Mechanics II, §2.4), with Γ = Rᵀe₃:

    Ṙ = R ξ̂,     J ξ̇ = Jξ × ξ + m g Γ × χ,

by scipy's DOP853 at tolerance 1e-13.  The script prints the observed order (the final-time
error of R at T against h = T/N) and, over a longer run, the energy error (E_d against the
continuous energy E = ½ξᵀJξ + m g e₃·Rχ at t = 0, bounded at O(h⁴)) and the angular
momentum about the vertical, e₃·(R Π) with Π = J ξ the body momentum (conserved: gravity
is vertical), to rounding.  It exits with status 1 when a number misses what the theory
says; tests/test_examples.py checks the printed numbers as well.

Run:  python examples/heavy_top_order4.py
"""

from __future__ import annotations

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import symgroupoid as sg

h, m, grav = sp.symbols("h m g", positive=True)
J1, J2, J3 = sp.symbols("J1:4", positive=True)
chi = sp.Matrix(sp.symbols("chi1:4", real=True))
E3 = sp.Matrix([0, 0, 1])

PARAMS = {"m": 1.0, "g": 9.81, "J1": 0.8, "J2": 1.0, "J3": 0.4,
          "chi1": 0.02, "chi2": 0.0, "chi3": 0.3}
R0 = np.array([[1.0, 0.0, 0.0],
               [0.0, np.cos(0.4), -np.sin(0.4)],
               [0.0, np.sin(0.4), np.cos(0.4)]])      # tilted by 0.4 rad about e₁
XI0 = np.array([0.5, -0.3, 3.0])                      # spinning about its axis
T = 2.0
STEPS = [40, 80, 160]
SCHEME = sg.GaussLegendre(2)


def heavy_top() -> sg.ContinuousSystem:
    J = sp.diag(J1, J2, J3)

    def L(R, xi):
        return (xi.T * J * xi)[0, 0] / 2 - m * grav * (E3.T * R * chi)[0, 0]

    return sg.ContinuousSystem(sg.SO3("R"), L, parameters=[h, m, grav, J1, J2, J3, *chi],
                               name="heavy_top")


# --- the reference: the continuous equations, independently ------------------------------------

def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _constants() -> tuple[np.ndarray, np.ndarray, float]:
    J = np.diag([PARAMS["J1"], PARAMS["J2"], PARAMS["J3"]])
    c = np.array([PARAMS["chi1"], PARAMS["chi2"], PARAMS["chi3"]])
    return J, c, PARAMS["m"] * PARAMS["g"]


def rhs(t: float, y: np.ndarray) -> np.ndarray:
    """y = (R row by row, ξ): Ṙ = Rξ̂, Jξ̇ = Jξ × ξ + m g Γ × χ, Γ = Rᵀe₃."""
    J, c, mg = _constants()
    R, w = y[:9].reshape(3, 3), y[9:]
    Gamma = R[2]  # Rᵀe₃: the third row of R
    return np.r_[(R @ _hat(w)).ravel(), np.linalg.solve(J, np.cross(J @ w, w)
                                                        + mg * np.cross(Gamma, c))]


def reference(T: float) -> np.ndarray:
    """R(T) row by row, DOP853 at tolerance 1e-13."""
    sol = solve_ivp(rhs, (0.0, T), np.r_[R0.ravel(), XI0], method="DOP853", rtol=1e-13,
                    atol=1e-13)
    return sol.y[:9, -1]


def continuous_energy() -> float:
    J, c, mg = _constants()
    return 0.5 * XI0 @ J @ XI0 + mg * (R0 @ c)[2]


# --- the structure over a longer run ----------------------------------------------------------

def long_run(steps: int, step: float) -> tuple[float, float, float]:
    """Energy error max |E_d − E(0)|, its growth (last tenth against the first) and the drift
    of the vertical angular momentum e₃·(R_{k+1} Π_k⁺) over ``steps`` steps."""
    sim = heavy_top().discretize(h, SCHEME).euler_lagrange().compile()
    params = {**PARAMS, "h": step}
    traj = sim.simulate(sim.from_velocity({"R": R0}, XI0, params), steps, params)
    error = np.abs(sg.diagnostics.energy(traj) - continuous_energy())
    R = np.asarray(traj.configurations())[1:]
    Pi = sg.diagnostics.momenta(traj).plus
    vertical = np.einsum("kj,kj->k", R[:, 2, :], Pi)  # e₃·(R Π)
    tenth = max(len(error) // 10, 1)
    growth = error[-tenth:].max() / error[:tenth].max()
    return float(error.max()), float(growth), float(np.abs(vertical - vertical[0]).max())


def main() -> None:
    report = sg.convergence_order(heavy_top(), SCHEME, ({"R": R0}, XI0), PARAMS, T, STEPS,
                                  reference=reference(T))
    print(f"heavy top on SO(3), {type(SCHEME).__name__}({SCHEME.stages}), T = {T}, "
          f"against DOP853 (tol 1e-13)")
    print(report)
    steps, step = 4000, 0.05
    energy, growth, momentum = long_run(steps, step)
    print(f"over {steps} steps at h = {step}: energy error {energy:.3e} "
          f"(last tenth / first tenth {growth:.3f}), vertical angular momentum drift "
          f"{momentum:.3e}")
    failures = []
    if abs(report.order - SCHEME.order) > 0.1:
        failures.append(f"observed order {report.order:.3f}, theoretical {SCHEME.order}")
    if energy > 1e-3 or growth > 1.5:
        failures.append(f"energy error {energy:.3e} (growth {growth:.3f})")
    if momentum > 1e-12:
        failures.append(f"vertical angular momentum drifts by {momentum:.3e}")
    if failures:
        raise SystemExit("heavy_top_order4: " + "; ".join(failures))


if __name__ == "__main__":
    main()
