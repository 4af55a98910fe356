"""The momentum- and energy-preserving nonholonomic integrator (seed 002, last slides:
Ferraro, Iglesias, Martín de Diego) against the discrete Hölder method (docs/conventions.md
§10, §14).

System (in the class of the method: L = ½G_c(a, a), a linear constraint distribution D): a
particle in R² × S¹ ∋ (x, z, y) with the nonholonomic constraint ż = sin(y) ẋ.  L and D are
invariant under translations of (x, z), so the system lives on the groupoid
(R², +) × (S¹ × S¹) ⇉ S¹: an arrow is a translation increment (u, w) and a pair (y₀, y₁) of
S¹, written as the rotation R(y₀) and the increment F = R(y₁ − y₀) (the pair groupoid of SO(2)
presented as an action groupoid).  Sections: ∂x, ∂z, ∂y;  G_c = identity;

    L_d = (u² + w²)/(2h) + (1 − cos(y₁ − y₀))/h,     D = ⟨∂x + sin(y) ∂z, ∂y⟩.

Energy–momentum method (``method="energy_momentum"``): on D the momenta are continuous, on D⊥
their sum vanishes; no discrete constraint is needed.  Hölder method: the DEL along D and the
discrete constraint w = u (sin y₀ + sin y₁)/2.  The script derives and compiles both, runs
them from the same arrow, and reports the energy ½‖F⁺L‖² and the momentum p_y = ⟨F⁺L, ∂y⟩:
the energy–momentum method keeps both to rounding, the Hölder method does not keep the
energy.  ``--figure PATH`` draws the energy errors of both methods.

Run:  python examples/nonholonomic_energy_momentum.py [--steps 20000] [--figure out.png]
"""

from __future__ import annotations

import argparse

import numpy as np
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
PARAMS = {"h": 0.01}


class LieGroupPair(sg.ActionGroupoid):
    """The pair groupoid of a matrix Lie group K as K × K ⇉ K, (q, F) ↦ (q, qF)."""

    def __init__(self, K: sg.MatrixLieGroup, point: str):
        names = [f"{point}_{i + 1}{j + 1}" for i, j in K._free]
        super().__init__(sg.EuclideanSpace(names), K,
                         lambda p, F: tuple(K.entries(K.matrix(p) * F)))

    def random_base_point(self, rng):
        x = [sp.Float(v) for v in rng.uniform(-1.0, 1.0, self.group.rank)]
        return tuple(float(v) for v in self.group.fibre_chart(x))


def groupoid() -> sg.Groupoid:
    translations = sg.DefinedGroupoid(
        "translations of (x, z)", base_names=[], fibre_names=["u", "w"],
        source=lambda a: (), target=lambda a: (),
        multiply=lambda a, b: (a[0] + b[0], a[1] + b[1]), identity=lambda q: (0, 0),
        inverse=lambda a: (-a[0], -a[1]), sections=lambda q, t: [(t, 0), (0, t)])
    return translations * LieGroupPair(sg.SO2("F"), "R")


def lagrangian(g):
    u, w = g[0].coords
    F = g[1].matrix
    return (u**2 + w**2) / (2 * h) + (1 - F[0, 0]) / h


#: D = ⟨∂x + sin(y) ∂z, ∂y⟩; the base point is (cos y, −sin y, sin y, cos y)
DISTRIBUTION = [lambda q: [1, q[2], 0], [0, 0, 1]]


def discrete_constraint(g):
    """Hölder's M_c: w = u (sin y₀ + sin y₁)/2."""
    u, w = g[0].coords
    F, q = g[1].matrix, g[1].point
    sin0 = q[2]
    sin1 = q[2] * F[0, 0] + q[3] * F[1, 0]
    return [w - u * (sin0 + sin1) / 2]


def systems(G=None):
    G = G or groupoid()
    em = sg.NonholonomicSystem(G, lagrangian, None, DISTRIBUTION, parameters=[h],
                               method="energy_momentum", metric=sp.eye(3),
                               name="particle_energy_momentum")
    holder = sg.NonholonomicSystem(G, lagrangian, discrete_constraint, DISTRIBUTION,
                                   parameters=[h], name="particle_holder")
    return em, holder


def initial_arrow(p: dict) -> np.ndarray:
    """y₀ = 0.3, y₁ − y₀ = 0.5h, and (u, w) = 0.8h (1, sin y₀)-ish on the constraint."""
    hh = p["h"]
    y0, dy = 0.3, 0.5 * hh
    w = 0.8 * hh * (np.sin(y0) + np.sin(y0 + dy)) / 2
    return np.array([0.8 * hh, w, np.cos(y0), -np.sin(y0), np.sin(y0), np.cos(y0),
                     np.cos(dy), -np.sin(dy), np.sin(dy), np.cos(dy)])


def run(steps: int, p: dict = PARAMS):
    """Energy and momentum errors of both methods: {method: (|ΔE|, |Δp_y|)}."""
    em, holder = systems()
    invariants = em.conserved_quantities()
    out = {}
    for system in (em, holder):
        traj = system.euler_lagrange().compile().simulate(initial_arrow(p), steps, p)
        E, J = invariants.evaluate(traj.states, [p["h"]])
        out[system.name] = (np.abs(E - E[0]), np.abs(J[:, 1] - J[0, 1]))
    return em, invariants, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--figure", default=None, help="write the energy errors to this file")
    args = parser.parse_args()

    em, invariants, errors = run(args.steps)
    print(em.euler_lagrange().latex())
    print(f"energy  E = {invariants.energy}   (conservation identity: "
          f"{invariants.energy_check})")
    print(f"momenta J = {invariants.momenta}   (conservation identities: "
          f"{invariants.momentum_checks}: the first, along ∂x + sin(y) ∂z, is not a "
          f"conserved quantity of this system and is expected to fail; p_y's holds)")
    print(f"{'method':28s} {'max |E - E0|':>14s} {'max |p_y - p_y0|':>18s}")
    for name, (dE, dJ) in errors.items():
        print(f"{name:28s} {dE.max():14.2e} {dJ.max():18.2e}")
    em_dE, em_dJ = errors["particle_energy_momentum"]
    holder_dE, _ = errors["particle_holder"]
    if em_dE.max() > 1e-10 or em_dJ.max() > 1e-10 or holder_dE.max() < 1e-8:
        raise SystemExit("unexpected conservation behaviour")
    if args.figure:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4))
        k = np.arange(1, args.steps + 1)
        for name, (dE, _) in errors.items():
            ax.semilogy(k, np.maximum(dE[1:], 1e-18), label=name.replace("particle_", ""))
        ax.set_xlabel("step k")
        ax.set_ylabel("|E_k - E_0|")
        ax.set_title("nonholonomic particle, z' = sin(y) x'")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.figure, dpi=120)
        print(f"figure written to {args.figure}")


if __name__ == "__main__":
    main()
