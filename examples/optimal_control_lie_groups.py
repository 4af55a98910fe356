"""Discrete optimal control on Lie groups with control constraints (seed 000 §6.1).

Continuous problem: steer ġ = g ξ from g(0) = g₀ to g(T) = g_T minimising ∫ l(ξ) dt subject
to control constraints ψ(ξ) = 0.  Discretisation with a retraction τ (Cayley or exp) and step h:

    L(g) = h · l(τ⁻¹(g)/h),   φᵃ(g) = h · ψᵃ(τ⁻¹(g)/h),   ξ_k = τ⁻¹(g_k)/h,

whose constrained discrete Euler–Lagrange equations are seed 000's
(dτ⁻¹_{hξ_k})*(dl(ξ_k) + λ_k·dψ(ξ_k)) = (dτ⁻¹_{−hξ_{k+1}})*(dl(ξ_{k+1}) + λ_{k+1}·dψ(ξ_{k+1})).

Two problems, each with both retractions:

- SO(3), no control about the third body axis: l = ½(ξ₁² + 2ξ₂²), ψ = ξ₃;
- SE(2), a unicycle that cannot slide sideways: ξ = (ω, v₁, v₂), l = ½(ω² + v₁²), ψ = v₂.

Run:  python examples/optimal_control_lie_groups.py
"""

from __future__ import annotations

import numpy as np
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)


def so3_problem(retraction: str = "cayley") -> sg.DiscreteSystem:
    """SO(3) attitude steering without torque about the third axis."""

    def L(g):
        xi = g.coordinates / h
        return h * (xi[0] ** 2 + 2 * xi[1] ** 2) / 2

    def phi(g):
        return [h * (g.coordinates[2] / h)]

    return sg.DiscreteSystem(sg.SO3("g", retraction=retraction), L, constraints=phi,
                             parameters=[h], name=f"so3_{retraction}")


def se2_problem(retraction: str = "cayley") -> sg.DiscreteSystem:
    """SE(2) unicycle: forward speed and turning rate, no sideways velocity."""

    def L(g):
        w, v1, _ = (c / h for c in g.coordinates)
        return h * (w ** 2 + v1 ** 2) / 2

    def phi(g):
        return [h * (g.coordinates[2] / h)]

    return sg.DiscreteSystem(sg.SE2("s", retraction=retraction), L, constraints=phi,
                             parameters=[h], name=f"se2_{retraction}")


def rotation(axis_angle) -> np.ndarray:
    """exp of ω̂ for ω = axis_angle (Rodrigues)."""
    w = np.asarray(axis_angle, float)
    th = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / th
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def pose(x: float, y: float, theta: float) -> np.ndarray:
    """An element of SE(2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])


def solve_so3(retraction: str = "cayley", steps: int = 60) -> sg.BoundaryValueSolution:
    system = so3_problem(retraction)
    return sg.solve_boundary_value(system.euler_lagrange(), np.eye(3),
                                   rotation([0.6, -0.4, 0.9]), steps, params={h: 1.0 / steps})


def unicycle_path(retraction: str, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Arrows of a feasible (v₂ = 0) but not optimal path — three arcs of constant turning
    rate and speed — and the pose it reaches.  The turning rate changes sign, so the optimum
    passes through (nearly) pure translations, where the exp retraction's logarithm relies on
    its smooth small-angle forms."""
    G = se2_problem(retraction).groupoid
    legs = [(3.0, 1.5), (-3.0, 1.5), (1.0, -1.0)]
    sizes = [steps // 3, steps // 3, steps - 2 * (steps // 3)]
    dt = 1.0 / steps
    arrows, M = [], np.eye(3)
    for (w, v), n in zip(legs, sizes):
        A = G.numeric_fibre_chart([w * dt, v * dt, 0.0])
        for _ in range(n):
            arrows.append(A)
            M = M @ G.numeric_matrix(A)
    return np.array(arrows), M


def solve_se2(retraction: str = "cayley", steps: int = 60) -> sg.BoundaryValueSolution:
    """Steer the unicycle to the end pose of a feasible three-arc path, starting Newton from
    that path: the solver finds the cheapest manoeuvre with the same end pose."""
    system = se2_problem(retraction)
    guess, end = unicycle_path(retraction, steps)
    return sg.solve_boundary_value(system.euler_lagrange(), np.eye(3), end, steps,
                                   params={h: 1.0 / steps}, guess=guess)


def main() -> None:
    for retraction in ("cayley", "exp"):
        sol = solve_so3(retraction)
        xi = sol.controls * 60
        print(f"SO(3), {retraction:6s}: {sol.iterations} Newton iterations, "
              f"|F| = {sol.residual_norm:.1e}, max |ξ₃| = {np.abs(xi[:, 2]).max():.1e}, "
              f"stationary: {bool(sg.verify_stationary(sol, so3_problem(retraction)))}")
        sol = solve_se2(retraction)
        v = sol.controls * 60
        end = sol.configurations[-1]
        cost = 0.5 * np.sum(v[:, 0] ** 2 + v[:, 1] ** 2) / 60
        print(f"SE(2), {retraction:6s}: {sol.iterations} Newton iterations, "
              f"|F| = {sol.residual_norm:.1e}, max |v₂| = {np.abs(v[:, 2]).max():.1e}, "
              f"end pose ({end[0, 2]:.3f}, {end[1, 2]:.3f}, "
              f"{np.arctan2(end[1, 0], end[0, 0]):.3f}), cost {cost:.4f}")


if __name__ == "__main__":
    main()
