"""A chain of rigid bodies joined by spherical joints: the 3D n-body pendulum.

``symgroupoid.systems.spherical_chain(n)`` (the Lie group variational integrator of Lee, Leok
and McClamroch): body 1 is pinned at the origin, body i has unit mass, attitude R_i ∈ SO(3),
principal inertia J_i = diag(1 + i/10, 6/5 + i/10, 1/2 + i/20), the vector (0, 0, −1) from its
joint to the next one and (0, 0, −½) to its centre of mass c_i.  One step moves R_{i,k} to
R_{i,k+1} = R_{i,k} F_i, and

    L_d = Σᵢ (1/h) tr((I₃ − F_i) J_{d,i}) + (1/(2h)) |c_i(R_{k+1}) − c_i(R_k)|²
          − (h/2) g e₃·(c_i(R_k) + c_i(R_{k+1})),        J_{d,i} = ½ tr(J_i) I₃ − J_i,

on the pair groupoid of SO(3)ⁿ: an arrow carries every body's R_k and R_{k+1}, and a step
solves for the Cayley coordinates of the increments F_i = R_{i,k}ᵀR_{i,k+1}.  The script derives the
step for n = 2, prints its size and the start of two LaTeX lines, compiles it, simulates, and
reports two structure checks along the motion:

- the discrete energy E_k = Σᵢ (1/h²) tr((I₃ − F_i) J_{d,i}) + |Δc_i|²/(2h²) + g e₃·c̄_i
  (c̄_i the mean of c_i over the step) oscillates without drift;
- the discrete Noether momentum of rotations about the vertical,
  J_k = d/ds L_d(R_k, e^{s ê₃} R_{k+1})|₀, is conserved to rounding.

It then runs the same motion on the same groupoid in increment coordinates
(``systems.spherical_chain_increments``: the state keeps R_k and F_k − I), whose momentum
stays closer to the rounding floor over long runs.

Run:  python examples/pendulum_chain_3d.py [--bodies 2] [--steps 20000]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid import systems

PARAMS = {"h": 0.01, "g": 9.81}
E3 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # ê₃
COMPLEX_STEP = 1e-30


def cayley(x: np.ndarray) -> np.ndarray:
    """cay(x) = I + 4/(4 + |x|²)(x̂ + x̂²/2)."""
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)
    return np.eye(3) + 4 / (4 + x @ x) * (X + X @ X / 2)


def initial_state(n: int, h: float) -> dict:
    """A tilted, spinning chain: R_{i,0} = cay(a_i) and R_{i,1} = R_{i,0} cay(h ω_i)."""
    state = {}
    for i in range(1, n + 1):
        R = cayley(np.array([0.5 * np.cos(i), 0.4 * np.sin(i), 0.3 * i]))
        F = cayley(h * np.array([0.8 * np.sin(i), -0.6, 1.5]))
        state[f"R{i}"] = (R, R @ F)
    return state


def attitudes(states: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(R_{k−1}, R_k) per state (the arrow of the pair groupoid): arrays (K, n, 3, 3)."""
    blocks = states.reshape(len(states), 2, n, 3, 3)
    return blocks[:, 0], blocks[:, 1]


def centres(R: np.ndarray) -> np.ndarray:
    """c_i = Σ_{j<i} R_j (0, 0, −1) + R_i (0, 0, −½) for R of shape (..., n, 3, 3)."""
    column = R[..., :, 2]  # R_i e₃: R_i (0, 0, −1) = −column, R_i (0, 0, −½) = −column/2
    joints = np.cumsum(-column, axis=-2) + column  # Σ_{j<i} R_j (0, 0, −1)
    return joints - column / 2


def lagrangian(Ra: np.ndarray, Rb: np.ndarray, h: float, g: float):
    """L_d(R_k, R_{k+1}) for one pair (n, 3, 3), complex-safe."""
    n = Ra.shape[0]
    total = 0
    ca, cb = centres(Ra), centres(Rb)
    for i in range(n):
        J = np.array([1 + (i + 1) / 10, 1.2 + (i + 1) / 10, 0.5 + (i + 1) / 20])
        Jd = np.diag(J.sum() / 2 - J)
        total = total + np.trace((np.eye(3) - Ra[i].T @ Rb[i]) @ Jd) / h
        d = cb[i] - ca[i]
        total = total + d @ d / (2 * h) - h / 2 * g * (ca[i, 2] + cb[i, 2])
    return total


def energy(Ra: np.ndarray, Rb: np.ndarray, h: float, g: float) -> float:
    """E_k: kinetic terms over h, potential at the step's mean."""
    n = Ra.shape[0]
    ca, cb = centres(Ra), centres(Rb)
    total = 0.0
    for i in range(n):
        J = np.array([1 + (i + 1) / 10, 1.2 + (i + 1) / 10, 0.5 + (i + 1) / 20])
        total += np.trace((np.eye(3) - Ra[i].T @ Rb[i]) @ np.diag(J.sum() / 2 - J)) / h**2
        d = cb[i] - ca[i]
        total += d @ d / (2 * h**2) + g * (ca[i, 2] + cb[i, 2]) / 2
    return float(total)


def vertical_momentum(Ra: np.ndarray, Rb: np.ndarray, h: float, g: float) -> float:
    """J_k = d/ds L_d(R_k, (I + s ê₃) R_{k+1}) at s = 0 (complex step: exact to rounding)."""
    turned = (np.eye(3) + 1j * COMPLEX_STEP * E3) @ Rb
    return float(lagrangian(Ra, turned, h, g).imag / COMPLEX_STEP)


def lagrangian_increments(R: np.ndarray, D: np.ndarray, h: float, g: float):
    """L_d from the attitudes R_k and the offsets D = F − I of the increments (n, 3, 3),
    as ``systems.spherical_chain_increments`` writes it: nothing cancels (complex-safe)."""
    total = 0
    joint, moved = np.zeros(3), np.zeros(3)
    for i in range(R.shape[0]):
        J = np.array([1 + (i + 1) / 10, 1.2 + (i + 1) / 10, 0.5 + (i + 1) / 20])
        dc = moved + R[i] @ D[i] @ np.array([0, 0, -0.5])
        c = joint + R[i] @ np.array([0, 0, -0.5])
        total = total - np.trace(D[i] @ np.diag(J.sum() / 2 - J)) / h + dc @ dc / (2 * h)
        total = total - h / 2 * g * (2 * c[2] + dc[2])
        joint, moved = joint + R[i] @ np.array([0, 0, -1.0]), moved + R[i] @ D[i] @ [0, 0, -1.0]
    return total


def vertical_momentum_increments(R: np.ndarray, D: np.ndarray, h: float, g: float) -> float:
    """J_k in increment coordinates: R_{k+1} ↦ (I + s ê₃)R_{k+1} moves F to F·η with
    η = skew(M⁻¹ê₃M), M = R_k F (its skew part: tangent to SO(3) to rounding)."""
    varied = []
    for Ri, Di in zip(R, D):
        M = Ri @ (np.eye(3) + Di)
        A = np.linalg.solve(M, E3 @ M)
        varied.append(Di + 1j * COMPLEX_STEP * (np.eye(3) + Di) @ (A - A.T) / 2)
    return float(lagrangian_increments(R, np.array(varied), h, g).imag / COMPLEX_STEP)


def increments_run(n: int, h: float, steps: int, Ra: np.ndarray) -> None:
    """The same motion on the pair groupoid in increment coordinates
    (``systems.spherical_chain_increments``, docs/conventions.md §18)."""
    sim = systems.spherical_chain_increments(n).euler_lagrange().compile()
    start = {}
    for i, (R0, R1) in enumerate(initial_state(n, h).values(), start=1):
        start[f"R{i}"], start[f"F{i}"] = R0, R0.T @ R1
    traj = sim.simulate(start, steps, PARAMS)
    R = np.stack([sim.layout.view(traj.states, f"R{i}") for i in range(1, n + 1)], axis=1)
    F = np.stack([sim.layout.view(traj.states, f"F{i}") for i in range(1, n + 1)], axis=1)
    J = np.array([vertical_momentum_increments(r, f - np.eye(3), h, PARAMS["g"])
                  for r, f in zip(R, F)])
    print(f"in increment coordinates (state R_k, F_k - I): attitudes agree with the pair "
          f"groupoid's to {np.abs(R - Ra).max():.1e}; max |J_k - J_0| = "
          f"{np.abs(J - J[0]).max():.2e}")


def shorten(text: str, width: int = 150) -> str:
    return text if len(text) <= width else text[: width - 5] + " \\dots"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, default=2)
    parser.add_argument("--steps", type=int, default=20_000)
    args = parser.parse_args()
    n, h, g = args.bodies, PARAMS["h"], PARAMS["g"]

    t0 = time.perf_counter()
    system = systems.spherical_chain(n)
    step = system.euler_lagrange()
    t1 = time.perf_counter()
    ops = sum(sp.count_ops(r) for r in step.residuals)
    kernel = sg.codegen.generate_c(step)
    print(f"{step.name}: {len(step)} equations in {len(step.unknowns)} unknowns "
          f"(Cayley coordinates of F_1..F_{n}), {len(step.knowns)} knowns; derived in "
          f"{t1 - t0:.1f} s; {ops} operations in the residuals; C kernel "
          f"{len(kernel.source) / 1e3:.0f} kB")
    L = system.lagrangian(step.groupoid.view(step.arrows[0]))
    print("L_d = " + shorten(sg.latex(L)))
    for line in step.latex().splitlines()[1:3]:
        print(shorten(line))

    t2 = time.perf_counter()
    sim = step.compile()
    t3 = time.perf_counter()
    traj = sim.simulate(initial_state(n, h), args.steps, PARAMS)
    t4 = time.perf_counter()
    print(f"compiled in {t3 - t2:.1f} s; {args.steps} steps of h = {h} in {t4 - t3:.3f} s "
          f"({(t4 - t3) / args.steps * 1e6:.2f} us/step, Newton iterations per step "
          f"{traj.newton_iterations.mean():.2f})")

    Ra, Rb = attitudes(traj.states, n)
    E = np.array([energy(a, b, h, g) for a, b in zip(Ra, Rb)])
    J = np.array([vertical_momentum(a, b, h, g) for a, b in zip(Ra, Rb)])
    orthogonality = np.abs(np.einsum("kiab,kiac->kibc", Ra, Ra) - np.eye(3)).max()
    half = len(E) // 2
    print(f"energy: E_0 = {E[0]:.6f}, max |E_k - E_0| = {np.abs(E - E[0]).max():.2e} "
          f"(first half {np.abs(E[:half] - E[0]).max():.2e}, second half "
          f"{np.abs(E[half:] - E[0]).max():.2e}: bounded, no drift)")
    print(f"vertical angular momentum: J_0 = {J[0]:.6f}, max |J_k - J_0| = "
          f"{np.abs(J - J[0]).max():.2e}")
    print(f"attitudes: max |R^T R - I| = {orthogonality:.1e}")
    increments_run(n, h, args.steps, Ra)
    if np.abs(J - J[0]).max() > 1e-8 * max(1.0, abs(J[0])):
        raise SystemExit("the vertical angular momentum is not conserved")


if __name__ == "__main__":
    main()
