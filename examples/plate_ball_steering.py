"""Steering the plate-ball system between two configurations (seed 000 §6.2).

A ball of radius r rolls without slipping on a plate turning at rate Ω; the controls are the
velocities (ẋ, ẏ) of the contact point and the spin about the vertical is fixed (ω_z = c).
Minimise ½∫(ẋ² + ẏ²) dt from (x₀, y₀, R₀) to (x_T, y_T, R_T).  With the discrete Lagrangian
and constraints of seed 000 §6.2 on R²×R²×SO(3) ⇉ R²,

    L = (h/2)[((x₁−x₀)/h)² + ((y₁−y₀)/h)²],
    φ¹ = h[(y₁−y₀)/h − r/(2h) tr(g E₁) − Ω(x₁+x₀)/2],
    φ² = h[(x₁−x₀)/h + r/(2h) tr(g E₂) + Ω(y₁+y₀)/2],
    φ³ = h[c + tr(g E₃)/(2h)],

the optimality conditions are the eight constrained DEL, solved here for the whole trajectory
at once.  The end configuration is produced by rolling the ball along a wiggly path (so it is
reachable); that path is the initial guess, and the solver finds the cheapest one.

Run:  python examples/plate_ball_steering.py
"""

from __future__ import annotations

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid.systems import plate_ball  # the system of seed 000 §6.2, as above


def rolling_arrow(x0, y0, x1, y1, params) -> np.ndarray:
    """The rotation arrow g with φ(x₀, y₀, x₁, y₁, g) = 0, from the traces it must have:
    tr(gE_a) = −8w_a/(4 + |w|²) for g = cay(w)."""
    hh, rr, oo, cc = params
    t = np.array([2 / rr * ((y1 - y0) - hh * oo * (x1 + x0) / 2),
                  -2 / rr * ((x1 - x0) + hh * oo * (y1 + y0) / 2),
                  -2 * hh * cc])
    # w = −t(4 + s)/8 with s = |w|²:  s = |t|²(4 + s)²/64, the small root
    a = float(t @ t) / 64
    s = ((1 - 8 * a) - np.sqrt(max((1 - 8 * a) ** 2 - 64 * a * a, 0.0))) / (2 * a) if a else 0.0
    w = -t * (4 + s) / 8
    return np.array(sg.SO3("g").cayley([sp.Float(v) for v in w]).tolist(), float)


def rolled_path(params, steps: int, seed: int = 0):
    """A feasible trajectory: roll along a wiggly planar path; returns arrows and ends."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0, 1, steps + 1)
    bumps = sum(rng.normal(scale=0.15) * np.sin((j + 1) * np.pi * s) for j in range(3))
    x, y = 0.8 * s + bumps, 0.5 * np.sin(np.pi * s) + 0.3 * s
    arrows, R = [], np.eye(3)
    for k in range(steps):
        W = rolling_arrow(x[k], y[k], x[k + 1], y[k + 1], params)
        arrows.append(np.concatenate([[x[k], y[k], x[k + 1], y[k + 1]], W.ravel()]))
        R = R @ W
    start, end = ((x[0], y[0]), np.eye(3)), ((x[-1], y[-1]), R)
    return np.array(arrows), start, end


def solve(steps: int = 40, params=(None, 1.0, 0.5, 0.3)) -> tuple:
    params = (1.0 / steps,) + tuple(params[1:])
    system = plate_ball()
    guess, start, end = rolled_path(params, steps)
    sol = sg.solve_boundary_value(system.euler_lagrange(), start, end, steps,
                                  params=list(params), guess=guess)
    return system, sol, guess, params


def cost(arrows: np.ndarray, hh: float) -> float:
    dx, dy = arrows[:, 2] - arrows[:, 0], arrows[:, 3] - arrows[:, 1]
    return float(0.5 * np.sum(dx ** 2 + dy ** 2) / hh)


def main() -> None:
    system, sol, guess, params = solve()
    print(f"plate-ball steering, N = {sol.steps}: {sol.iterations} Newton iterations, "
          f"|F|∞ = {sol.residual_norm:.1e}, {sol.seconds:.2f} s")
    print(f"cost of the rolled guess {cost(guess, params[0]):.4f} → optimum "
          f"{cost(sol.arrows, params[0]):.4f}")
    print(f"end position ({sol['x'][-1]:.4f}, {sol['y'][-1]:.4f}); "
          f"stationary: {bool(sg.verify_stationary(sol, system))}")


if __name__ == "__main__":
    main()
