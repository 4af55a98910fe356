"""Forces, damping and control inputs: the discrete Lagrange–d'Alembert principle.

``DiscreteSystem(G, L, forces=f, inputs=[u, ...])`` adds the discrete forces f⁺(g_k) +
f⁻(g_{k+1}) to each junction residual (Marsden–West eq. (3.2.3) on Q × Q,
docs/conventions.md §20).  The value u_k of an input belongs to the arrow g_k: the state
carries the inputs of its own arrow, and each step reads those of the arrow it computes.

- The damped, driven double pendulum (the midpoint rule of L and of the joint torques
  F = −c·θ̇ + u(t)): its energy balance.  The energy changes by the work of the forces.
- A satellite with a reaction wheel (``systems.satellite_with_wheel()``), on SO(3) × SO(2):
  the body's attitude increment W and the wheel's angle relative to the body V.  The motor
  torque τ acts on the wheel's relative angle, and the body reacts.  The total angular
  momentum about the wheel's axis stays constant to rounding.  The wheel's momentum changes
  by exactly the motor's impulse (the forced Noether theorem, ``NoetherQuantity.impulse``).
  ``examples/embed/closed_loop.c`` steers its attitude with a PD controller in C.

Run:  python examples/forced_systems.py [--steps 2000] [--latex]
Exits with status 1 when a check fails.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid import systems

h, c = sp.symbols("h c", positive=True)


def double_pendulum() -> sg.DiscreteSystem:
    """Two unit links of unit masses; torques u1, u2 at the joints and damping c."""
    g0 = sp.Rational(981, 100)
    u1, u2 = sp.symbols("u1 u2", real=True)
    G = sg.PairGroupoid(sg.EuclideanSpace(["a", "b"]))

    def midpoint(g):
        (a0, b0), (a1, b1) = g.source, g.target
        return ((a0 + a1) / 2, (b0 + b1) / 2), ((a1 - a0) / h, (b1 - b0) / h)

    def L(g):
        (a, b), (va, vb) = midpoint(g)
        T = va**2 + vb**2 / 2 + va * vb * sp.cos(a - b)
        V = -2 * g0 * sp.cos(a) - g0 * sp.cos(b)
        return h * (T - V)

    forces = sg.midpoint_forces(lambda q, v: [-c * v[0] + u1, -c * v[1] + u2], h)
    return sg.DiscreteSystem(G, L, parameters=[h, c], forces=forces, inputs=[u1, u2],
                             time_step=h, name="driven_double_pendulum")


def check(name: str, ok: bool, detail: str) -> bool:
    print(f"  {'ok  ' if ok else 'FAIL'} {name}: {detail}")
    return ok


def run_pendulum(steps: int, latex: bool) -> bool:
    system = double_pendulum()
    step = system.euler_lagrange()
    if latex:
        print(step.latex())
    sim = step.compile()
    p = {"h": 0.01, "c": 0.5}
    t = 0.01 * np.arange(steps)
    U = np.c_[0.8 * np.sin(2 * t), np.zeros(steps)]  # a drive at the first joint
    traj = sim.simulate({"a": (0.5, 0.5), "b": (0.0, 0.0), "u1": 0.0, "u2": 0.0}, steps, p,
                        inputs=U)
    a, b = traj["a"], traj["b"]
    print(f"driven double pendulum, {steps} steps: a ∈ [{a.min():.3f}, {a.max():.3f}], "
          f"b ∈ [{b.min():.3f}, {b.max():.3f}]")
    undriven = sim.simulate({"a": (0.5, 0.5), "b": (0.0, 0.0), "u1": 0.0, "u2": 0.0},
                            steps, p, inputs=[0.0, 0.0])
    energy = undriven.energy()
    rest = -3 * 9.81  # both links hanging down, at rest
    # over 20 s (2000 steps) the damping takes out 90 % of the energy above rest; over a
    # shorter run, some of it
    near_rest = steps >= 2000
    name = ("damping alone brings it to rest" if near_rest
            else "damping alone takes energy out")
    kept = 0.1 if near_rest else 1.0
    return check(name, energy[-1] - rest < kept * (energy[0] - rest),
                 f"E − E_rest from {energy[0] - rest:.4f} to {energy[-1] - rest:.4f}")


def run_satellite(steps: int, latex: bool) -> bool:
    system = systems.satellite_with_wheel()
    if latex:
        print(system.euler_lagrange().latex())
    total, wheel = system.noether(2), system.noether(3)
    sim = system.euler_lagrange().compile()
    W0 = sp.matrix2numpy(sp.rot_axis1(0.01) * sp.rot_axis3(0.02), dtype=float).T
    V0 = np.array([[np.cos(0.05), -np.sin(0.05)], [np.sin(0.05), np.cos(0.05)]])
    p = {"h": 0.02, "I": 2.0, "I3": 3.0, "Iw": 0.1}
    U = 0.5 * np.sin(0.1 * np.arange(steps))  # the motor's torque, step by step
    traj = sim.simulate({"W": W0, "V": V0, "tau": 0.0}, steps, p, inputs=U)
    J, Jw = total.along(traj), wheel.along(traj)
    balance = np.abs(np.diff(Jw) - wheel.impulse(traj)).max()
    print(f"satellite with a reaction wheel, {steps} steps: the wheel's momentum ranges "
          f"over {np.ptp(Jw):.4f}")
    ok = check("total axial momentum conserved", np.ptp(J) < 1e-12,
               f"spread {np.ptp(J):.2e}")
    return check("the wheel's momentum changes by the motor's impulse", balance < 1e-13,
                 f"largest defect {balance:.2e}") and ok


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--latex", action="store_true", help="print the equations in LaTeX")
    args = parser.parse_args(argv)
    ok = run_pendulum(args.steps, args.latex)
    ok = run_satellite(args.steps, args.latex) and ok
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
