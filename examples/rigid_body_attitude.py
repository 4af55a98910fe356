"""Optimal attitude control of a rigid body on SO(3), second order (seed 001 §3.3.4).

Continuous problem (seed 001 eqs. (25)–(26)).  The controlled Euler equations

    Ω̇₁ = P₁ Ω₂ Ω₃ + u₁,   Ω̇₂ = P₂ Ω₁ Ω₃ + u₂,   Ω̇₃ = P₃ Ω₁ Ω₂ + u₃,          (25)

with Ṙ = R Ω̂, and the cost ½∫|u|² dt.  Solving (25) for u turns the cost into the second-order
Lagrangian L̃(Ω, Ω̇) = ½|u(Ω, Ω̇)|² of (26).  Here P₁ = (I₂ − I₃)/I₁, P₂ = (I₃ − I₁)/I₂,
P₃ = (I₁ − I₂)/I₃ — Euler's equations I₁Ω̇₁ = (I₂ − I₃)Ω₂Ω₃ + τ₁ with u = τ/I — whereas the
seed prints the reciprocals (P₁ = I₁/(I₂ − I₃), …), which would not make (25) the rigid body.

Discretisation (seed 001 eqs. (27)–(28)), exactly as implemented.  The arrows are
W_k = R_kᵀ R_{k+1} ∈ SO(3) and their Cayley coordinates x_k = cay⁻¹(W_k) ∈ R³ (``.coordinates``,
so x_k = hξ_k with ξ_k the seed's discrete angular velocity, ξ_k ≈ Ω(t_{k+1/2}), t_k the time
of R_k).  On the composable pair (W_k, W_{k+1}), centred at t_{k+1}:

    Ω_{k+1}  = (x_k + x_{k+1}) / (2h)              (the seed's ξ_{k+1/2}),
    Ω̇_{k+1}  = (x_{k+1} − x_k) / h²               (the seed's ξ_{k,k+1} = (ξ_{k+1} − ξ_k)/h),
    u_{k+1}  = Ω̇_{k+1} − (P₁Ω₂Ω₃, P₂Ω₁Ω₃, P₃Ω₁Ω₂)_{k+1}       (discrete (25)),
    L_d(W_k, W_{k+1}) = h L̃(Ω_{k+1}, Ω̇_{k+1}) = (h/2) |u_{k+1}|²                       (27).

The discrete cost Σ_{k=0}^{N−2} L_d(W_k, W_{k+1}) (28) is made stationary with R₀, R₁, R_{N−1},
R_N fixed (a two-point problem: g₀ and g_{N−1} fixed arrows); the optimality conditions are the
discrete second-order Euler–Poincaré equations (seed 001 §3.1.2).  Ω_{k+1}, Ω̇_{k+1} and u_{k+1}
are second-order accurate at t_{k+1} on samples of a smooth motion (x_k/h = Ω(t_{k+1/2}) + O(h²)
for Cayley; the averages and divided differences are centred at t_{k+1}).

Time grid and boundary data.  The N + 1 configurations sit at t = (k − ½)h, k = 0 … N, with
h = T/(N − 1), so the pair terms are centred at (k + ½)h ∈ [h/2, T − h/2] and the end conditions
act at t = 0 and t = T through the first and last arrows:

    R₀ = R(0) cay(−hΩ(0)/2),  R₁ = R(0) cay(hΩ(0)/2),  R_{N−1} = R(T) cay(−hΩ(T)/2),
    R_N = R(T) cay(hΩ(T)/2)

(rest to rest: R₀ = R₁, R_{N−1} = R_N, first and last arrows the identity).  Both ends are then
symmetric about t = 0 and t = T and the discrete optimum converges at second order (cost and
controls).  Reading R₀ … R_N at t = kh with h = T/N instead puts the rest condition half a step
off the boundary, which costs one order: first-order convergence.

Run:  python examples/rigid_body_attitude.py [--steps 100] [--plot]
"""

from __future__ import annotations

import argparse
import functools
import time
from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
I1, I2, I3 = sp.symbols("I_1 I_2 I_3", positive=True)
PARAMETERS = (h, I1, I2, I3)

#: Default moments of inertia and maneuver.
INERTIA = (1.0, 2.0, 3.0)
FINAL_AXIS_ANGLE = (0.6, -0.4, 0.9)
DURATION = 1.0


def coefficients(inertia: Sequence) -> tuple:
    """(P₁, P₂, P₃) of eq. (25) from the moments of inertia (Euler's equations)."""
    a, b, c = inertia
    return ((b - c) / a, (c - a) / b, (a - b) / c)


def torque(omega: Sequence, omega_dot: Sequence, inertia: Sequence) -> list:
    """u of eq. (25): Ω̇ − (P₁Ω₂Ω₃, P₂Ω₁Ω₃, P₃Ω₁Ω₂); symbolic or NumPy arrays alike."""
    P = coefficients(inertia)
    w, dw = omega, omega_dot
    return [dw[0] - P[0] * w[1] * w[2], dw[1] - P[1] * w[0] * w[2],
            dw[2] - P[2] * w[0] * w[1]]


def discrete_state(xa, xb, step):
    """(Ω_{k+1}, Ω̇_{k+1}) from the Cayley coordinates x_k, x_{k+1} of a composable pair."""
    return [(a + b) / (2 * step) for a, b in zip(xa, xb)], \
        [(b - a) / step ** 2 for a, b in zip(xa, xb)]


@functools.cache
def attitude_system() -> sg.SecondOrderSystem:
    """L_d(W_k, W_{k+1}) = (h/2)|u_{k+1}|² on SO(3) with the Cayley chart (eq. (27))."""

    def L(a, b):
        omega, omega_dot = discrete_state(list(a.coordinates), list(b.coordinates), h)
        u = torque(omega, omega_dot, (I1, I2, I3))
        return h * sum(c ** 2 for c in u) / 2

    return sg.SecondOrderSystem(sg.SO3("W"), L, parameters=list(PARAMETERS),
                                name="rigid_body_attitude")


def rotation(axis_angle: Sequence) -> np.ndarray:
    """exp(ω̂) for ω = axis_angle (Rodrigues)."""
    w = np.asarray(axis_angle, float)
    th = float(np.linalg.norm(w))
    if th == 0.0:
        return np.eye(3)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / th
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def cayley(x: Sequence) -> np.ndarray:
    """cay(x̂) = I + 4/(4 + |x|²)(x̂ + x̂²/2) (seed 001 eq. (63))."""
    x = np.asarray(x, float)
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])
    return np.eye(3) + 4.0 / (4.0 + x @ x) * (X + X @ X / 2)


def boundary_data(steps: int, duration: float = DURATION,
                  final: Sequence = FINAL_AXIS_ANGLE, omega_start: Sequence = (0, 0, 0),
                  omega_end: Sequence = (0, 0, 0)) -> tuple:
    """((R₀, R₁), (R_{N−1}, R_N)) for the maneuver from R(0) = I with Ω(0) = omega_start to
    R(T) = exp(final^) with Ω(T) = omega_end, on the grid t = (k − ½)h, h = T/(N − 1)."""
    dt = time_step(steps, duration)
    w0, wT = dt * np.asarray(omega_start, float) / 2, dt * np.asarray(omega_end, float) / 2
    R0, RT = np.eye(3), rotation(final)
    return (R0 @ cayley(-w0), R0 @ cayley(w0)), (RT @ cayley(-wT), RT @ cayley(wT))


def time_step(steps: int, duration: float = DURATION) -> float:
    """h = T/(N − 1): N + 1 configurations at t = (k − ½)h, k = 0 … N."""
    return duration / (steps - 1)


def parameter_values(steps: int, duration: float = DURATION,
                     inertia: Sequence = INERTIA) -> dict:
    return {h: time_step(steps, duration), I1: inertia[0], I2: inertia[1], I3: inertia[2]}


def solve(steps: int = 100, duration: float = DURATION, inertia: Sequence = INERTIA,
          **maneuver) -> sg.BoundaryValueSolution:
    """Solve the maneuver as a two-point problem with N = ``steps`` arrows."""
    start, end = boundary_data(steps, duration, **maneuver)
    return sg.solve_boundary_value(attitude_system(), start, end, steps,
                                   params=parameter_values(steps, duration, inertia))


def discrete_torques(x: np.ndarray, step: float, inertia: Sequence = INERTIA) -> np.ndarray:
    """u_{k+1}, k = 0 … N−2 (rows), from the Cayley coordinates x_k of the N arrows."""
    x = np.asarray(x, float)
    omega, omega_dot = discrete_state(x[:-1].T, x[1:].T, step)
    return np.array(torque(omega, omega_dot, inertia)).T


def cost(sol: sg.BoundaryValueSolution, inertia: Sequence = INERTIA) -> float:
    """The discrete cost (28): Σ (h/2)|u_{k+1}|²."""
    step = sol.parameters["h"]
    u = discrete_torques(sol.controls, step, inertia)
    return float(step * np.sum(u ** 2) / 2)


def summary(sol: sg.BoundaryValueSolution, inertia: Sequence = INERTIA) -> dict:
    """Plot-ready arrays on the grid t = (k − ½)h: the times (k + ½)h of the pair terms with Ω
    and u there, the times kh of the arrows with their velocities ξ_k = x_k/h, the attitudes
    R_k at (k − ½)h, and the cost."""
    step = sol.parameters["h"]
    x = np.asarray(sol.controls, float)
    n = len(x)
    omega, _ = discrete_state(x[:-1].T, x[1:].T, step)
    return {"t": step * (np.arange(n - 1) + 0.5), "omega": np.array(omega).T,
            "u": discrete_torques(x, step, inertia),
            "t_arrow": step * np.arange(n), "xi": x / step,
            "t_attitude": step * (np.arange(n + 1) - 0.5),
            "attitude": np.array(sol.configurations), "cost": cost(sol, inertia)}


# --- a smooth reference motion: discrete (25) against the continuous one -------------------

def reference_motion() -> tuple[Callable, Callable]:
    """R(t) = R_z(φ)R_y(ψ)R_x(χ) with smooth angles; returns numeric R(t) and (Ω, Ω̇)(t)
    with Ω = vee(RᵀṘ) differentiated exactly (SymPy)."""
    t = sp.Symbol("t", real=True)
    phi, psi, chi = sp.sin(2 * t) + t / 2, sp.cos(3 * t) / 2 - t ** 2, t + t ** 3 / 3

    def axis(i, a):
        c, s = sp.cos(a), sp.sin(a)
        M = sp.eye(3)
        j, k = [m for m in range(3) if m != i]
        M[j, j], M[j, k], M[k, j], M[k, k] = c, -s, s, c
        return M

    R = axis(2, phi) * axis(1, psi) * axis(0, chi)
    S = R.T * R.diff(t)
    omega = sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])
    R_num = sp.lambdify(t, R, "numpy")
    state = sp.lambdify(t, [list(omega), list(omega.diff(t))], "numpy")
    return (lambda s: np.array(R_num(s), float)), (lambda s: np.array(state(s), float))


def consistency_errors(steps: Sequence[int] = (20, 40, 80), duration: float = DURATION,
                       inertia: Sequence = INERTIA) -> list[float]:
    """max_k |u_{k+1} − u(t_{k+1})| on samples R_k = R(t_k) of the reference motion, where
    u_{k+1} is read off the system's own Lagrangian ((h/2)|u|² is checked against L_d) and
    u(t) is eq. (25) at the exact Ω, Ω̇."""
    R_of, state_of = reference_motion()
    system = attitude_system()
    L = sp.lambdify([[c for s in system._fs.slots for c in s], list(PARAMETERS)],
                    system._fs.lagrangian, "numpy")
    G = system.groupoid
    errors = []
    for n in steps:
        dt = duration / n
        Rs = [R_of(k * dt) for k in range(n + 1)]
        arrows = np.array([(Ra.T @ Rb).ravel() for Ra, Rb in zip(Rs[:-1], Rs[1:])])
        x = np.array([G.fibre_chart_inverse(a) for a in arrows])
        u = discrete_torques(x, dt, inertia)
        p = [dt, *inertia]
        Ld = np.array([L(np.concatenate([a, b]), p) for a, b in zip(arrows[:-1], arrows[1:])])
        if not np.allclose(Ld, dt * np.sum(u ** 2, axis=1) / 2, rtol=1e-10, atol=1e-12):
            raise AssertionError("the torques do not reproduce the system's Lagrangian")
        exact = []
        for k in range(1, n):
            omega, omega_dot = state_of(k * dt)
            exact.append(torque(omega, omega_dot, inertia))
        errors.append(float(np.max(np.abs(u - np.array(exact)))))
    return errors


def observed_orders(errors: Sequence[float]) -> list[float]:
    """log₂ of successive error ratios (halved steps)."""
    return [float(np.log2(a / b)) for a, b in zip(errors[:-1], errors[1:])]


def refinement(steps: Sequence[int] = (20, 40, 80, 160)) -> dict:
    """The maneuver solved for each N: costs, and u interpolated (linearly in t) to the common
    times 0.1, 0.2, …, 0.9·T; successive differences and their observed orders."""
    grid = DURATION * np.linspace(0.1, 0.9, 9)
    costs, torques = [], []
    for n in steps:
        data = summary(solve(n))
        costs.append(data["cost"])
        torques.append(np.array([np.interp(grid, data["t"], data["u"][:, i])
                                 for i in range(3)]).T)
    cost_changes = [abs(a - b) for a, b in zip(costs[:-1], costs[1:])]
    torque_changes = [float(np.abs(a - b).max()) for a, b in zip(torques[:-1], torques[1:])]
    return {"steps": list(steps), "costs": costs, "cost_changes": cost_changes,
            "torque_changes": torque_changes, "cost_orders": observed_orders(cost_changes),
            "torque_orders": observed_orders(torque_changes)}


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100, help="number of arrows N")
    parser.add_argument("--plot", action="store_true", help="save rigid_body_attitude.png")
    args = parser.parse_args(argv)

    t0 = time.perf_counter()
    sol = solve(args.steps)
    seconds = time.perf_counter() - t0
    data = summary(sol)
    _, (_, end) = boundary_data(args.steps)
    print(f"rest-to-rest maneuver I → exp({FINAL_AXIS_ANGLE}^) in T = {DURATION}, "
          f"inertia {INERTIA}, N = {args.steps}, h = T/(N − 1) = {sol.parameters['h']:.5f}")
    print(f"  {sol.iterations} Newton iterations, |F|∞ = {sol.residual_norm:.2e}, "
          f"{seconds:.2f} s (kernel build included), cost Σ L_d = {data['cost']:.6f}")
    print(f"  stationary: {bool(sg.verify_stationary(sol, attitude_system()))}, "
          f"end attitude error {np.abs(sol.configurations[-1] - end).max():.1e}")
    print("\n     k     t       u1          u2          u3         |Ω|")
    for k, (t, u, w) in enumerate(zip(data["t"], data["u"], data["omega"]), start=1):
        print(f"  {k:4d} {t:6.3f} {u[0]:11.5f} {u[1]:11.5f} {u[2]:11.5f} {np.linalg.norm(w):9.5f}")
    print("\n  plot-ready arrays (summary()):")
    for key, value in data.items():
        shape = np.shape(value)
        print(f"    {key:10s} shape {shape}" if shape else f"    {key:10s} {value:.6f}")
    errors = consistency_errors()
    print(f"\n  discrete (25) on a smooth motion, N = 20, 40, 80: max |u_k − u(t_k)| = "
          f"{', '.join(f'{e:.2e}' for e in errors)}; orders "
          f"{', '.join(f'{o:.2f}' for o in observed_orders(errors))}")
    ref = refinement()
    print(f"  maneuver for N = {ref['steps']}: costs "
          f"{', '.join(f'{c:.6f}' for c in ref['costs'])}")
    print(f"    cost changes {', '.join(f'{c:.2e}' for c in ref['cost_changes'])} (orders "
          f"{', '.join(f'{o:.2f}' for o in ref['cost_orders'])}); max u changes at t = 0.1…0.9 "
          f"{', '.join(f'{c:.2e}' for c in ref['torque_changes'])} (orders "
          f"{', '.join(f'{o:.2f}' for o in ref['torque_orders'])})")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
        for i in range(3):
            axes[0].plot(data["t"], data["omega"][:, i], label=f"Ω{i + 1}")
            axes[1].plot(data["t"], data["u"][:, i], label=f"u{i + 1}")
        axes[0].set_ylabel("angular velocity")
        axes[1].set_ylabel("control u")
        axes[1].set_xlabel("t")
        for ax in axes:
            ax.legend()
        fig.tight_layout()
        fig.savefig("rigid_body_attitude.png", dpi=120)
        print("  saved rigid_body_attitude.png")


if __name__ == "__main__":
    main()
