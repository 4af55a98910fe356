"""Elroy's beanie reduced by SE(2): the Atiyah groupoid (Q × Q)/SE(2) ⇉ S¹ (seed 002;
docs/conventions.md §13).

Two planar bodies joined at their centres of mass: Q = SE(2) × S¹ ∋ (x, y, θ, ψ),

    L = ½ m (ẋ² + ẏ²) + ½ I₁ θ̇² + ½ I₂ (θ̇ + ψ̇)² − V(ψ),

SE(2)-invariant (left action on the SE(2) factor).  With c = I₂/(I₁ + I₂) the locked angle
θ + cψ separates the rotation: ½(I₁ + I₂)(θ̇ + cψ̇)² + ½ μ ψ̇², μ = I₁I₂/(I₁ + I₂).

Discretisation on the pair groupoid of Q, g = (q₀, q₁):

    L_d(q₀, q₁) = m/(2h²) |x₁ − x₀|² + (I₁ + I₂)/h² (1 − cos(θ₁ − θ₀ + c(ψ₁ − ψ₀)))
                  + ½ μ ((ψ₁ − ψ₀)/h)² − V((ψ₀ + ψ₁)/2).

The Atiyah groupoid in the connection-adapted (locked-frame) chart, 𝒜(ψ₀, ψ₁) = exp(cΔψ E_θ),
has arrows (ψ₀, ψ₁, W̃) with W̃ = (R(Ω₃), u): u = R(θ₀)ᵀ(x₁ − x₀) and Ω₃ = Δθ + cΔψ.  Its product
(ψ₀, ψ₁, u, Ω₃)(ψ₁, ψ₂, u′, Ω₃′) = (ψ₀, ψ₂, u + R(Ω₃ − cΔψ)u′, Ω₃ + Ω₃′) is derived from 𝒜, and
the seed's reduced Lagrangian

    𝔏_d = m/(2h²)(Ω₁² + Ω₂²) + (I₁ + I₂)/h² (1 − cos Ω₃) + ½ μ (Δψ/h)² − V(ψ̄)

is checked to satisfy L_d = 𝔏_d∘π (seed 000 Def. 4.2).  The script derives the discrete
Lagrange–Poincaré equations, runs both systems as compiled kernels, and checks that

- the reduced trajectory equals the projection of the unreduced one (to 1e-12);
- it satisfies Ω₃,k+1 = Ω₃,k, (Ω₁, Ω₂)_{k+1} = R(cΔψ_k − Ω₃,k)(Ω₁, Ω₂)_k and the ψ equation —
  the seed prints the angle as +(Ω₃ + cΔψ_k), which the trajectory violates;
- of the two printings of the continuous equations, the one with I₂ in both places is the
  limit of the discrete ones;
- the reconstruction from the reduced trajectory and the first arrow is the unreduced one.

The pair groupoid of SE(2) × S¹ is written as (pair groupoid of SE(2), as the action
groupoid of right multiplication) × (pair groupoid of S¹); the quotient map uses only its
source and target maps.

Run:  python examples/elroys_beanie.py [--steps 400]
"""

from __future__ import annotations

import argparse

import numpy as np
import sympy as sp

import symgroupoid as sg

h, m, I1, I2, k = sp.symbols("h m I_1 I_2 k", positive=True)
c = I2 / (I1 + I2)
mu = I1 * I2 / (I1 + I2)
PARAMS = {"h": 0.05, "m": 1.0, "I_1": 1.0, "I_2": 2.0, "k": 0.5}


def V(psi):
    return k * (1 - sp.cos(psi))


class LieGroupPair(sg.ActionGroupoid):
    """The pair groupoid of a matrix Lie group K as K × K ⇉ K, (q, F) ↦ (q, qF)."""

    def __init__(self, K: sg.MatrixLieGroup, point: str):
        names = [f"{point}_{i + 1}{j + 1}" for i, j in K._free]
        super().__init__(sg.EuclideanSpace(names), K,
                         lambda p, F: tuple(K.entries(K.matrix(p) * F)))
        self.name = f"pair groupoid of {K.group_name}"

    def random_base_point(self, rng):
        x = [sp.Float(v) for v in rng.uniform(-1.0, 1.0, self.group.rank)]
        return tuple(float(v) for v in self.group.fibre_chart(x))


def configuration_space():
    return (sg.SE2("g"), sg.EuclideanSpace("psi"))


def atiyah_groupoid() -> sg.AtiyahGroupoid:
    """(Q × Q)/SE(2) in the locked-frame chart 𝒜(ψ₀, ψ₁) = exp(c(ψ₁ − ψ₀)E_θ)."""
    return sg.AtiyahGroupoid(configuration_space(), sg.SE2, action="left",
                             connection=lambda s0, s1: (c * (s1[0] - s0[0]), 0, 0))


def pair_groupoid() -> sg.Groupoid:
    return LieGroupPair(sg.SE2("F"), "q") * sg.PairGroupoid(sg.EuclideanSpace("psi"))


def unreduced_lagrangian(g):
    """L_d(q₀, q₁), written with the source and target points only."""
    (q0, q1), se2 = (g.alpha, g.beta), sg.SE2("t")
    H0, H1 = se2.matrix(q0[:6]), se2.matrix(q1[:6])
    R = H0[:2, :2].T * H1[:2, :2]
    dx, dpsi = H1[:2, 2] - H0[:2, 2], q1[6] - q0[6]
    cos_locked = R[0, 0] * sp.cos(c * dpsi) - R[1, 0] * sp.sin(c * dpsi)
    return (m / (2 * h**2) * dx.dot(dx) + (I1 + I2) / h**2 * (1 - cos_locked)
            + mu / 2 * (dpsi / h) ** 2 - V((q0[6] + q1[6]) / 2))


def reduced_lagrangian(a):
    """The seed's 𝔏_d(ψ_k, ψ_{k+1}, Ω_k) with (Ω₁, Ω₂) = u and cos Ω₃ = W̃₁₁."""
    (p0,), (p1,) = a.source, a.target
    W = a.matrix
    return (m / (2 * h**2) * (W[0, 2] ** 2 + W[1, 2] ** 2) + (I1 + I2) / h**2 * (1 - W[0, 0])
            + mu / 2 * ((p1 - p0) / h) ** 2 - V((p0 + p1) / 2))


def systems():
    """(unreduced system, quotient map π, reduced system)."""
    A = atiyah_groupoid()
    P = pair_groupoid()
    pi = A.quotient_map_from(P)
    full = sg.DiscreteSystem(P, unreduced_lagrangian, parameters=[h, m, I1, I2, k],
                             name="beanie")
    reduced = full.reduce(pi, lagrangian=reduced_lagrangian, name="beanie_reduced")
    return full, pi, reduced


def initial_state() -> np.ndarray:
    """g₀ = (q₋₁, q₀) in the pair groupoid's coordinates: (q₋₁, F, ψ₋₁, ψ₀), q₀ = q₋₁F."""
    se2 = sg.SE2("t", retraction="exp")
    H = np.array(se2.exp([0.3, 0.1, -0.2]).evalf().tolist(), float)
    F = np.array(se2.exp([0.04, 0.05, 0.02]).evalf().tolist(), float)
    return np.concatenate([H[:2].ravel(), F[:2].ravel(), [0.2, 0.25]])


def lagrange_poincare_defects(states: np.ndarray, p: dict, printed: bool = False) -> dict:
    """Largest residuals of the discrete Lagrange–Poincaré equations along reduced states
    (ψ_a, ψ_b, W̃ entries): the corrected rotation angle cΔψ_k − Ω₃,k, or the printed one."""
    cc = p["I_2"] / (p["I_1"] + p["I_2"])
    mu_ = p["I_1"] * p["I_2"] / (p["I_1"] + p["I_2"])
    psi = np.concatenate([states[:1, 0], states[:, 1]])
    W = states[:, 2:]
    u, omega3 = W[:, [2, 5]], np.arctan2(W[:, 3], W[:, 0])
    dpsi = np.diff(psi)
    angle = (omega3 + cc * dpsi) if printed else (cc * dpsi - omega3)
    rot = np.stack([np.cos(angle), -np.sin(angle), np.sin(angle), np.cos(angle)],
                   axis=1).reshape(-1, 2, 2)
    predicted = np.einsum("kij,kj->ki", rot[:-1], u[:-1])
    dV = p["k"] * np.sin((psi[1:] + psi[:-1]) / 2)
    hh = p["h"]
    shape = mu_ * (psi[2:] - 2 * psi[1:-1] + psi[:-2]) / hh**2 + (dV[1:] + dV[:-1]) / 2
    return {"Omega_12": float(np.abs(u[1:] - predicted).max()),
            "Omega_3": float(np.abs(np.diff(omega3)).max()),
            "psi": float(np.abs(shape).max() * hh**2)}


def continuous_defects(states: np.ndarray, p: dict) -> tuple[float, float]:
    """Residuals of the two printed continuous equations for (Ω̇₁, Ω̇₂) along the discrete
    solution (Ω = u/h, Ω₃ and ψ̇ per step, differences centred between steps): the printing
    with I₂/(I₁+I₂) in both equations, and the one with I₁/(I₁+I₂) in the second."""
    hh = p["h"]
    psi = np.concatenate([states[:1, 0], states[:, 1]])
    W = states[:, 2:]
    om = W[:, [2, 5]] / hh
    om3 = np.arctan2(W[:, 3], W[:, 0])[:-1] / hh
    psidot = np.diff(psi)[:-1] / hh
    rate = np.diff(om, axis=0) / hh
    avg = (om[1:] + om[:-1]) / 2
    out = []
    for coefficient in (p["I_2"], p["I_1"]):
        second = coefficient / (p["I_1"] + p["I_2"])
        first = p["I_2"] / (p["I_1"] + p["I_2"])
        r1 = rate[:, 0] - (avg[:, 1] * om3 - first * psidot * avg[:, 1])
        r2 = rate[:, 1] - (-avg[:, 0] * om3 + second * psidot * avg[:, 0])
        out.append(float(max(np.abs(r1).max(), np.abs(r2).max())))
    return out[0], out[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=400)
    args = parser.parse_args()

    full, pi, reduced = systems()
    A = reduced.groupoid
    sg.check_morphism(pi)
    print("pi is a groupoid morphism (seed 000 Def. 4.1), checked on random composable pairs")
    for check in reduced.checks:
        print(check)

    # the derived product against the seed's twisted product, at random arrows
    rng = np.random.default_rng(3)
    cc = PARAMS["I_2"] / (PARAMS["I_1"] + PARAMS["I_2"])
    values = {I1: PARAMS["I_1"], I2: PARAMS["I_2"]}
    for _ in range(3):
        a = A.random_arrow(rng)
        b = A.random_arrow(rng, A.target(a))
        ab = [float(sp.sympify(v).xreplace(values)) for v in A.multiply(a, b)]
        om, om2 = np.arctan2(a[5], a[2]), np.arctan2(b[5], b[2])
        ang = om - cc * (a[1] - a[0])
        rot = np.array([[np.cos(ang), -np.sin(ang)], [np.sin(ang), np.cos(ang)]])
        u = np.array([a[4], a[7]]) + rot @ np.array([b[4], b[7]])
        printed = [a[0], b[1], np.cos(om + om2), -np.sin(om + om2), u[0],
                   np.sin(om + om2), np.cos(om + om2), u[1]]
        if not np.allclose(ab, printed, atol=1e-12):
            raise SystemExit(f"derived product {ab} differs from the seed's {printed}")
    print("derived product = (psi0, psi2, u + R(Omega3 - c dpsi) u', Omega3 + Omega3')")

    step = reduced.euler_lagrange()
    print(step.latex())
    sim_full = full.euler_lagrange().compile()
    sim_red = step.compile()
    traj = sim_full.simulate(initial_state(), args.steps, PARAMS)
    projected = reduced.project(traj, PARAMS)
    red = sim_red.simulate(projected[0], args.steps, PARAMS)
    gap = float(np.abs(red.states - projected).max())
    print(f"reduced trajectory vs reduction of the unreduced one: {gap:.2e}")
    if gap > 1e-12:
        raise SystemExit("the reduced trajectory is not the reduction of the unreduced one")

    right = lagrange_poincare_defects(red.states, PARAMS)
    wrong = lagrange_poincare_defects(red.states, PARAMS, printed=True)
    print(f"discrete Lagrange-Poincare residuals (angle c dpsi - Omega3): {right}")
    print(f"with the printed angle +(Omega3 + c dpsi): Omega_12 residual {wrong['Omega_12']:.2e}")
    if max(right.values()) > 1e-11 or wrong["Omega_12"] < 1e-6:
        raise SystemExit("the discrete Lagrange-Poincare equations do not hold as corrected")

    ok, misprint = continuous_defects(red.states, PARAMS)
    print(f"continuous equation for dOmega2/dt: I2-version residual {ok:.2e}, "
          f"I1-version residual {misprint:.2e}")
    if not ok < 0.05 * misprint:
        raise SystemExit("the I2 printing of the continuous equations is not the limit")

    motion = reduced.reconstruct(red, traj.states[0], PARAMS)
    back = float(np.abs(motion - traj.states).max())
    print(f"reconstruction from the reduced trajectory vs unreduced trajectory: {back:.2e}")
    if back > 1e-10:
        raise SystemExit("reconstruction does not recover the unreduced trajectory")
    print("verified against seed 002 (Elroy's beanie, discrete Lagrange-Poincare equations)")


if __name__ == "__main__":
    main()
