"""Holonomic constraints on the configuration space: ψ(q) = 0 at every node.

``DiscreteSystem(G, L, holonomic=lambda q: [...])`` restricts the motion to M = {ψ = 0} ⊂ Q
(seed 000 §3.3 with N = G|_M, docs/conventions.md §15).  One step solves

    X⃖[L](g_k) − X⃗[L](g_{k+1}) + λ_{k+1}·dψ(β(g_k))(ρ(X)) = 0,    ψ(β(g_{k+1})) = 0

for g_{k+1} and λ_{k+1}, the multiplier at the node β(g_k) (ρ the anchor): on Q × Q the
constrained discrete Euler–Lagrange equations D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) +
λ·∇ψ(q_k) = 0 of SHAKE type.  For each system the script prints the equations in LaTeX,
emits and compiles the C kernel through the kernel cache, simulates, and checks:

- the spherical pendulum (pair groupoid of R³, ψ = |q|² − ℓ²): |q_k| = ℓ at every node to
  rounding, the angular momentum about the vertical (a Noether quantity: rotations are
  tangent to the sphere) conserved to rounding, the discrete energy bounded;
- a planar chain of three links in Cartesian coordinates (pair groupoid of R⁶,
  ψ_i = |p_i − p_{i−1}|² − l_i²): every link keeps its length, the energy stays bounded,
  and without gravity the angular momentum about the pivot is conserved;
- the heavy top with its nutation held fixed, on S² × SO(3) ⇉ S² with ψ(Γ) = Γ₃ − cos θ₀:
  a base that is not Rⁿ, where the anchor ρ(E_a)(Γ) = Γ × e_a enters the equations; Γ₃
  stays fixed, the energy is bounded, and for a symmetric top the spin about the symmetry
  axis (E₃ is tangent to the circle) is conserved;
- the 3D chain of two rigid bodies in maximal coordinates (each body's attitude on the pair
  groupoid of SO(3) and its centre of mass on that of R³, ψ: the ball joints, three rows
  each): the same trajectory as the chain in relative attitudes (``spherical_chain(2)``,
  the same discrete Lagrangian on the constraint set), the joints held to rounding;
- with ``--plate-ball``: the plate-ball of seed 000 §6.2 (R² × R² × SO(3) ⇉ R²) with the ball
  kept on the circle |x| = R, three rolling constraints and one holonomic constraint.

Run:  python examples/holonomic_constraints.py [--steps 5000] [--plate-ball] [--latex]
Exits with status 1 when a check fails.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid import systems

EPS = float(np.finfo(float).eps)
FAILURES: list[str] = []


def check(label: str, value: float, bound: float) -> None:
    """Print a check; remember it when it fails."""
    ok = value <= bound
    print(f"  {label}: {value:.2e} (bound {bound:.1e}) {'ok' if ok else 'FAILED'}")
    if not ok:
        FAILURES.append(label)



def equation_rows(text: str) -> list[str]:
    """The numbered equations of an ``align`` block, each with its continuation lines (a
    row ends at the first line not marked ``\\notag``; the "where" list is not one)."""
    rows, row = [], []
    for line in text.splitlines():
        if line.startswith("\\intertext"):
            break
        if line.startswith("0 &=") or row:
            row.append(line.removeprefix("&\\quad ").removesuffix(" \\\\")
                       .removesuffix(" \\notag"))
            if "\\notag" not in line:
                rows.append(" ".join(row))
                row = []
    return rows


def derive(system: sg.DiscreteSystem, latex: bool):
    """The step, its LaTeX, its C source and the compiled simulator."""
    t0 = time.perf_counter()
    step = system.euler_lagrange()
    print(f"{system!r}: {len(step)} equations in {len(step.unknowns)} unknowns "
          f"({time.perf_counter() - t0:.2f} s)")
    text = step.latex()
    rows = equation_rows(text)
    print(text if latex else f"  LaTeX, the DEL along X_1:  {rows[0]}\n"
          f"  LaTeX, the holonomic row:  {rows[-1]}")
    with tempfile.TemporaryDirectory() as tmp:
        step.emit_c(Path(tmp) / system.name)
        size = (Path(tmp) / f"{system.name}.c").stat().st_size
    t0 = time.perf_counter()
    sim = step.compile(backend="c")
    print(f"  C kernel: {size} bytes of source, compiled in {time.perf_counter() - t0:.2f} s")
    return step, sim


def spherical_pendulum(steps: int, latex: bool) -> None:
    system = systems.spherical_pendulum()
    _, sim = derive(system, latex)
    params = {"h": 0.01, "ell": 1.0, "g": 9.81}
    start = sim.from_momentum({"x": np.sin(0.8), "y": 0.0, "z": -np.cos(0.8)},
                              [0.0, 1.2, 0.0], params)
    traj = sim.simulate(start, steps=steps, params=params)
    q = np.stack([traj["x"], traj["y"], traj["z"]], axis=1)
    check("max | |q_k| − ℓ |", float(np.max(np.abs(np.linalg.norm(q, axis=1) - 1.0))), 4 * EPS)
    vertical = system.noether(lambda p: [-p[1], p[0], 0])
    assert vertical.is_symmetry
    Lz = vertical.along(traj)
    check("angular momentum about the vertical, max drift / |L_z|",
          float(np.max(np.abs(Lz - Lz[0])) / abs(Lz[0])), 1e-12)
    E = traj.energy()
    check("discrete energy E_d, max |E − E₀| / |E₀|", float(np.max(np.abs(E - E[0])) / abs(E[0])),
          1e-3)


def link_chain(steps: int, latex: bool) -> None:
    system = systems.link_chain(3)
    _, sim = derive(system, latex)
    angles = np.array([0.6, 1.1, 1.5])
    rates = np.array([0.5, -0.4, 0.8])
    lengths = np.array([1.0, 0.8, 0.6])
    h = 0.005

    def tips(th: np.ndarray) -> np.ndarray:
        """The joints of the chain with link angles th from the downward vertical."""
        return np.cumsum(lengths[:, None] * np.stack([np.sin(th), -np.cos(th)], axis=1), axis=0)

    p0, p1 = tips(angles), tips(angles + h * rates)
    initial = {f"{c}{i + 1}": (p0[i, j], p1[i, j]) for i in range(3) for j, c in enumerate("xy")}
    for g in (9.81, 0.0):
        params = {"h": h, "g": g, "l1": 1.0, "l2": 0.8, "l3": 0.6}
        traj = sim.simulate(initial, steps=steps, params=params)
        p = np.stack([np.stack([traj[f"x{i}"], traj[f"y{i}"]], axis=1) for i in (1, 2, 3)],
                     axis=1)
        links = np.linalg.norm(np.diff(np.concatenate([np.zeros_like(p[:, :1]), p], axis=1),
                                       axis=1), axis=2)
        print(f"  g = {g}:")
        check("max link length error", float(np.max(np.abs(links - lengths))), 8 * EPS)
        E = traj.energy()
        check("discrete energy, max |E − E₀| / max(1, |E₀|)",
              float(np.max(np.abs(E - E[0]))) / max(1.0, abs(E[0])), 1e-2)
        if g == 0.0:
            pivot = system.noether(lambda q: [c for i in range(3)
                                              for c in (-q[2 * i + 1], q[2 * i])])
            # gravity breaks the symmetry (not verified for every g), g = 0 restores it
            grav = next(s for s in system.parameters if str(s) == "g")
            assert not pivot.is_symmetry and sp.expand(pivot.defect.subs(grav, 0)) == 0
            J = pivot.along(traj)
            check("angular momentum about the pivot, max drift / |J|",
                  float(np.max(np.abs(J - J[0])) / abs(J[0])), 1e-11)


def tilted_top(steps: int, latex: bool) -> None:
    system = systems.tilted_top()
    _, sim = derive(system, latex)
    tilt = 0.5
    I1, I2 = (next(s for s in system.parameters if str(s) == n) for n in ("I1", "I2"))
    spin = system.noether(2)
    # the spin about e₃ is a Noether quantity of the symmetric top: the defect vanishes at
    # I₂ = I₁ (the multiplier term too: E₃ is tangent to the circle Γ₃ = c)
    assert not spin.is_symmetry and sp.expand(spin.defect.subs(I2, I1)) == 0
    for i2 in (1.4, 1.0):
        params = {"h": 0.01, "mgl": 1.0, "I1": 1.0, "I2": i2, "I3": 0.5, "c": np.cos(tilt)}
        start = sim.from_momentum({"Gamma": (0.0, np.sin(tilt), np.cos(tilt))},
                                  (0.2, 0.1, 3.0), params)
        traj = sim.simulate(start, steps=steps, params=params)
        print(f"  I = diag(1, {i2}, 0.5):")
        gamma = traj["Gamma"]
        check("max |Γ₃ − cos θ₀|", float(np.max(np.abs(gamma[:, 2] - np.cos(tilt)))), 4 * EPS)
        E = traj.energy()
        check("discrete energy, max |E − E₀| / |E₀|",
              float(np.max(np.abs(E - E[0])) / abs(E[0])), 1e-8)
        if i2 == 1.0:
            S = spin.along(traj)
            check("spin about the symmetry axis, max drift / |S|",
                  float(np.max(np.abs(S - S[0])) / abs(S[0])), 1e-12)


def rotation(w: np.ndarray) -> np.ndarray:
    """exp(ŵ) (Rodrigues' formula)."""
    angle = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def maximal_chain(steps: int, latex: bool) -> None:
    n, params = 2, {"h": 0.01, "g": 9.81}
    _, sim = derive(systems.spherical_chain_maximal(n), latex)
    minimal = systems.spherical_chain(n).euler_lagrange().compile(backend="c")
    link, centre = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, -0.5])
    R0 = [rotation(np.array([0.4, -0.2, 0.1])), rotation(np.array([-0.3, 0.5, 0.2]))]
    R1 = [R @ rotation(np.array([0.01, 0.02, -0.01])) for R in R0]
    start = {f"R{i + 1}": (R0[i], R1[i]) for i in range(n)}
    named = dict(start)
    for which, attitudes in enumerate((R0, R1)):
        joint = np.zeros(3)
        for i, R in enumerate(attitudes):
            c = joint + R @ centre
            joint = joint + R @ link
            for a, axis in enumerate("xyz"):
                named.setdefault(f"{axis}{i + 1}", [0.0, 0.0])[which] = c[a]
    traj = sim.simulate(named, steps=steps, params=params)
    reference = minimal.simulate(start, steps=steps, params=params)
    difference = max(float(np.max(np.abs(traj[f"R{i + 1}"] - reference[f"R{i + 1}"])))
                     for i in range(n))
    check("attitudes against the chain in relative attitudes, max difference", difference,
          1e-9)
    joint, error = np.zeros((len(traj["R1"]), 3)), 0.0
    for i in range(n):
        R = traj[f"R{i + 1}"].reshape(-1, 3, 3)
        c = np.stack([traj[f"{a}{i + 1}"] for a in "xyz"], axis=1)
        error = max(error, float(np.max(np.abs(c - R @ centre - joint))))
        joint = c + R @ (link - centre)
    check("max ball-joint error", error, 64 * EPS)


def plate_ball_on_a_circle(steps: int, latex: bool) -> None:
    """Seed 000 §6.2 with ψ(x, y) = x² + y² − R² on the base R² (the SO(3) factor's base is a
    point: the base point of the product is ((x, y), ()))."""
    base = systems.plate_ball()
    R = sp.Symbol("R", positive=True)
    system = sg.DiscreteSystem(base.groupoid, base.lagrangian, constraints=base.constraints,
                               parameters=[*base.parameters, R], name="plate_ball_circle",
                               holonomic=lambda q: [q[0][0] ** 2 + q[0][1] ** 2 - R**2])
    _, sim = derive(system, latex)
    params = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02, "R": 2.0}
    start = sim.from_momentum({"x": 2.0, "y": 0.0}, (0.0, 0.5, 0.01, 0.02, 0.01), params)
    traj = sim.simulate(start, steps=steps, params=params)
    radius = np.hypot(traj["x"], traj["y"])
    check("max | |x_k| − R |", float(np.max(np.abs(radius - 2.0))), 8 * EPS)
    phi = traj.constraint_residuals()
    check("max |φ| (rolling and circle)", float(np.max(np.abs(phi))), 1e-12)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=5000)
    parser.add_argument("--plate-ball", action="store_true",
                        help="also the plate-ball kept on a circle (a larger kernel)")
    parser.add_argument("--latex", action="store_true", help="print every LaTeX line")
    args = parser.parse_args()
    spherical_pendulum(args.steps, args.latex)
    link_chain(args.steps, args.latex)
    tilted_top(args.steps, args.latex)
    maximal_chain(args.steps, args.latex)
    if args.plate_ball:
        plate_ball_on_a_circle(args.steps, args.latex)
    if FAILURES:
        print(f"FAILED: {', '.join(FAILURES)}")
        return 1
    print("all holonomic checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
