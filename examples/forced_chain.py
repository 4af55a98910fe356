"""A 3D chain of three rigid bodies driven to a target pose by a controller written in Python.

``symgroupoid.systems.spherical_chain(3, forced=True)``: body 1 hangs from a fixed point,
each joint j applies a torque u_j to body j (in body j's frame) and its reaction to body
j − 1, and every joint is damped (parameter c).  The inputs are the joint torques
(docs/conventions.md §20).  Each step, the controller reads the state and computes the
torques of the new arrow, and the loop calls ``sim.step(state, p, inputs=u)``.  The
controller is a joint-space PD law with gravity compensation (Takegaki–Arimoto):

    u_j = −K_p e_j − K_d (Ω_j − Q_jᵀΩ_{j−1}) + R_jᵀ T_j^g,

- Q_j = R_{j−1}ᵀR_j is the joint's relative rotation (R_0 = I), Q_j* its target, and
  e_j = vee(Q_j*ᵀQ_j − Q_jᵀQ_j*)/2 its error in body j's frame;
- Ω_i = vee(F_i − F_iᵀ)/(2h) is body i's angular velocity over the last step,
  F_i = R_{i,k−1}ᵀR_{i,k};
- T_j^g = g Σ_{i≥j} (c_i − p_j) × e₃ is the torque that holds bodies j, …, n against
  gravity about joint j (at p_j; c_i are the centres of mass).

Checks printed at the end:

- the chain reaches its target pose: every joint's rotation error is below 1e-3 rad;
- the forced Noether balance about the vertical holds to rounding along the loop: the
  discrete Noether momentum J_k = d/ds L_d(R_{k−1}, e^{s ê₃}R_k)|₀ (rotations of the whole
  chain about the vertical, a symmetry of L_d) changes over each step by the impulse of the
  pivot's torque alone, (h/2) e₃·(T₁(g_k) + T₁(g_{k+1})), T₁ = R₁u₁ − c ω₁: the torques and
  the damping of joints 2 and 3 are internal (docs/conventions.md §20).

Run:  python examples/forced_chain.py [--steps 2000]
Exits with status 1 when a check fails.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from symgroupoid import systems

N = 3
PARAMS = {"h": 0.01, "g": 9.81, "c": 0.05}
KP, KD = 40.0, 12.0
LINK, CENTRE = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, -0.5])
E3 = np.array([0.0, 0.0, 1.0])
TOLERANCE = 1e-3  # rad: the final error of every joint


def hat(x: np.ndarray) -> np.ndarray:
    return np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)


def vee(M: np.ndarray) -> np.ndarray:
    return np.array([M[2, 1], M[0, 2], M[1, 0]])


def rotation(axis, angle: float) -> np.ndarray:
    """exp(angle·â) by Rodrigues' formula."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    A = hat(a)
    return np.eye(3) + np.sin(angle) * A + (1 - np.cos(angle)) * A @ A


#: the target relative rotations of the three joints: lift, bend and twist
TARGET = [rotation([1, 0, 0], 0.6), rotation([0, 1, 0], -0.5), rotation([0, 0, 1], 0.8)]


def attitudes(state: np.ndarray) -> tuple[list, list]:
    """(R_{k−1}, R_k) of every body from the flat state (row-major attitudes)."""
    R = [state[9 * i: 9 * i + 9].reshape(3, 3) for i in range(2 * N)]
    return R[:N], R[N:]


def gravity_torques(R: list, g: float) -> list:
    """T_j^g = g Σ_{i≥j} (c_i − p_j) × e₃ (spatial) for every joint j."""
    joints, centres, p = [], [], np.zeros(3)
    for Ri in R:
        joints.append(p)
        centres.append(p + Ri @ CENTRE)
        p = p + Ri @ LINK
    return [g * sum(np.cross(c - joints[j], E3) for c in centres[j:]) for j in range(N)]


def controller(state: np.ndarray) -> np.ndarray:
    """The joint torques u_{k+1} (body frames, stacked) from the state (R_{k−1}, R_k, …)."""
    before, R = attitudes(state)
    h = PARAMS["h"]
    omega = [vee(A.T @ B - B.T @ A) / (2 * h) for A, B in zip(before, R)]
    hold = gravity_torques(R, PARAMS["g"])
    u = []
    for j in range(N):
        parent, w_parent = (R[j - 1], omega[j - 1]) if j else (np.eye(3), np.zeros(3))
        Q = parent.T @ R[j]
        error = vee(TARGET[j].T @ Q - Q.T @ TARGET[j]) / 2
        relative = omega[j] - Q.T @ w_parent
        u.append(-KP * error - KD * relative + R[j].T @ hold[j])
    return np.concatenate(u)


def joint_errors(state: np.ndarray) -> np.ndarray:
    """The rotation angle of Q_j*ᵀQ_j for every joint."""
    _, R = attitudes(state)
    parents = [np.eye(3), *R[:-1]]
    cosines = [(np.trace(T.T @ P.T @ Rj) - 1) / 2 for T, P, Rj in zip(TARGET, parents, R)]
    return np.arccos(np.clip(cosines, -1.0, 1.0))


def chain_inertia(i: int) -> np.ndarray:
    """Principal moments of body i (1-based), as ``systems.chain_inertia``."""
    return np.array([1 + i / 10, 6 / 5 + i / 10, 1 / 2 + i / 20])


def lagrangian(Ra: list, Rb: list) -> complex:
    """L_d of ``systems.spherical_chain`` at the arrow (R_k, R_{k+1}) (complex-safe)."""
    h, g = PARAMS["h"], PARAMS["g"]
    total, pa, pb = 0.0, np.zeros(3), np.zeros(3)
    for i, (A, B) in enumerate(zip(Ra, Rb), start=1):
        J = chain_inertia(i)
        ca, cb = pa + A @ CENTRE, pb + B @ CENTRE
        total = total + np.trace((np.eye(3) - A.T @ B) @ np.diag(J.sum() / 2 - J)) / h
        total = total + (cb - ca) @ (cb - ca) / (2 * h) - h / 2 * g * (ca[2] + cb[2])
        pa, pb = pa + A @ LINK, pb + B @ LINK
    return total


def vertical_momentum(Ra: list, Rb: list) -> float:
    """J = d/ds L_d(R_k, e^{s ê₃} R_{k+1}) at s = 0, by the complex step: the discrete
    Noether momentum of rotations of the whole chain about the vertical."""
    step = 1e-30
    turned = [(np.eye(3) + 1j * step * hat(E3)) @ B for B in Rb]
    return float(lagrangian(Ra, turned).imag / step)


def pivot_impulse(states: np.ndarray) -> np.ndarray:
    """(h/2) e₃·(T₁(g_k) + T₁(g_{k+1})) for each step: the pivot's torque T₁ = R₁u₁ − c ω₁
    of both arrows at the junction's attitude R_{1,k+1} (``systems.spherical_chain``,
    forced); the states carry the inputs of their own arrows after the attitudes."""
    h, c = PARAMS["h"], PARAMS["c"]
    out = []
    for a, b in zip(states[:-1], states[1:]):
        (A, R), (_, B) = attitudes(a), attitudes(b)
        torques = []
        for (P, Q), x in (((A[0], R[0]), a), ((R[0], B[0]), b)):
            omega = vee(Q @ P.T - P @ Q.T) / (2 * h)
            torques.append(R[0] @ x[18 * N: 18 * N + 3] - c * omega)
        out.append(h / 2 * E3 @ (torques[0] + torques[1]))
    return np.array(out)


def check(name: str, ok: bool, detail: str) -> bool:
    print(f"  {'ok  ' if ok else 'FAIL'} {name}: {detail}")
    return ok


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    args = parser.parse_args(argv)
    system = systems.spherical_chain(N, forced=True)
    sim = system.euler_lagrange().compile()
    hanging = np.concatenate([np.eye(3).ravel()] * (2 * N) + [np.zeros(6 * N)])
    state = sim.state(hanging, PARAMS)
    U = np.empty((args.steps, 3 * N))
    history = [state.copy()]
    for k in range(args.steps):  # the closed loop
        U[k] = controller(state)
        state = sim.step(state, PARAMS, inputs=U[k])
        history.append(state.copy())
    errors = joint_errors(state)
    print(f"3D chain of {N} bodies, PD control with gravity compensation, {args.steps} steps "
          f"of h = {PARAMS['h']}: joint errors {', '.join(f'{e:.1e}' for e in errors)} rad, "
          f"largest torque {np.abs(U).max():.2f}")
    ok = check("the chain reaches its target pose", errors.max() < TOLERANCE,
               f"largest joint error {errors.max():.1e} rad (< {TOLERANCE:.0e})")
    states = np.array(history)
    J = np.array([vertical_momentum(*attitudes(x)) for x in states])
    defect = np.abs(np.diff(J) - pivot_impulse(states)).max()
    ok = check("vertical angular momentum changes by the pivot's impulse alone",
               defect < 1e-12 * max(1.0, np.abs(J).max()),
               f"J ranges over [{J.min():.3f}, {J.max():.3f}], largest defect {defect:.1e} "
               f"per step") and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
