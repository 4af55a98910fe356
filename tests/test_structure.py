"""Structure preservation of the compiled integrators, shown on real runs.

- plate-ball: the constraints hold at every step;
- heavy top: |Γ| and Π·Γ are conserved, the energy error stays bounded without drift;
- Moser–Veselov rigid body: |Π| is conserved;
- a pair-groupoid pendulum: the discrete Hamiltonian map (q_k, p_k) ↦ (q_{k+1}, p_{k+1}) is
  symplectic.

The body momentum is Π = axial(W J_d − J_d Wᵀ).  It is not assumed: the tests first check
that the step residual *is* −(1/h)(Π(W_{k+1}) − W_kᵀ Π(W_k) − m g l h² Γ_{k+1} × e) at
arbitrary (non-solution) points (docs/conventions.md §9), so that on solutions
Π_{k+1} = W_kᵀ Π_k + m g l h² Γ_{k+1} × e.  With Γ_{k+1} = W_kᵀ Γ_k this gives
Π_{k+1}·Γ_{k+1} = Π_k·Γ_k, and for the free rigid body |Π_{k+1}| = |Π_k|.
"""

from __future__ import annotations

import numpy as np
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SEED_DATA,
    SESSION_CACHE,
    body_momentum,
    compiled,
    constraint_function,
    discrete_inertia,
    initial_state,
    isolated_cache,
    needs_cc,
)

import symgroupoid as sg

pytestmark = needs_cc


def _random_rotation(group, rng, scale=0.3):
    return np.asarray(sp.N(group.cayley(list(rng.uniform(-scale, scale, 3)))), dtype=float)


def test_plate_ball_constraints_hold_over_1e4_steps():
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    traj = sim.simulate(initial_state(sim, "plate_ball"), 10_000, params)
    phi = constraint_function("plate_ball")
    p = sim.parameters(params)
    violation = np.abs(np.asarray(phi(traj.states.T, p), float)).max()
    assert violation <= 1e-10
    assert np.abs(traj.multipliers).max() > 1e-3  # the constraint forces are active
    assert np.ptp(traj["x"]) > 1.0  # and the ball moves


def test_heavy_top_residual_is_the_body_momentum_balance():
    sim = compiled("heavy_top")
    params = SEED_DATA["heavy_top"][0]
    h, mgl = params["h"], params["mgl"]
    Jd = discrete_inertia(params["I1"], params["I2"], params["I3"])
    p = sim.parameters(params)
    rng = np.random.default_rng(3)
    group = sim.equations.groupoid.group
    for _ in range(5):
        gamma = rng.normal(size=3)
        W0 = _random_rotation(group, rng)
        u = rng.uniform(-0.3, 0.3, 3)
        W1 = np.empty(9)
        known = np.concatenate([gamma, W0.ravel()])
        buffer = sim.kernel.ffi.from_buffer
        sim.kernel.lib.heavy_top_reconstruct(buffer("double[]", u), buffer("double[]", known),
                                             buffer("double[]", p), buffer("double[]", W1))
        W1 = W1.reshape(3, 3)
        F = sim.kernel.residual(u, np.concatenate([gamma, W0.ravel()]), p)
        gamma1 = W0.T @ gamma
        balance = (body_momentum(W1, Jd) - W0.T @ body_momentum(W0, Jd)
                   - mgl * h ** 2 * np.cross(gamma1, [0.0, 0.0, 1.0]))
        assert np.abs(F - (-balance / h)).max() <= 1e-12 * np.abs(F).max()


def test_heavy_top_casimir_momentum_and_energy_over_1e5_steps():
    sim = compiled("heavy_top")
    params = SEED_DATA["heavy_top"][0]
    h, mgl = params["h"], params["mgl"]
    inertia = np.array([params["I1"], params["I2"], params["I3"]])
    Jd = discrete_inertia(*inertia)
    traj = sim.simulate(initial_state(sim, "heavy_top"), 100_000, params)
    gamma, W = traj["Gamma"], traj["W"]
    norm = np.linalg.norm(gamma, axis=1)
    assert np.abs(norm - norm[0]).max() <= 1e-10 * norm[0]
    vertical = np.einsum("ki,ki->k", body_momentum(W, Jd), gamma)
    assert np.abs(vertical - vertical[0]).max() <= 1e-10 * max(abs(vertical[0]), 1.0)
    # energy with ω_k = cay⁻¹(W_k)/h and the potential at the midpoint of Γ_k, Γ_{k+1}
    omega = body_axial_cayley(W) / h
    gamma_next = np.einsum("kji,kj->ki", W, gamma)  # W_kᵀ Γ_k
    energy = (0.5 * np.einsum("ki,i,ki->k", omega, inertia, omega)
              + mgl * 0.5 * (gamma[:, 2] + gamma_next[:, 2]))
    error = energy - energy[0]
    assert np.abs(error).max() <= h ** 2 * abs(energy[0])  # bounded, O(h²)
    tenth = len(error) // 10
    drift = abs(error[-tenth:].mean() - error[:tenth].mean())
    assert drift <= 0.05 * np.ptp(error)  # no drift beyond 5 % of the oscillation


def body_axial_cayley(W: np.ndarray) -> np.ndarray:
    """cay⁻¹(W) = axial(2 (W − Wᵀ) / (1 + tr W)) on SO(3), for a stack of matrices."""
    skew = 2 * (W - np.swapaxes(W, -1, -2)) / (1 + np.trace(W, axis1=-2, axis2=-1))[:, None, None]
    return np.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], axis=-1)


def test_moser_veselov_conserves_body_momentum_norm():
    sim = compiled("rigid_body")
    params = SEED_DATA["rigid_body"][0]
    h = params["h"]
    Jd = discrete_inertia(params["I1"], params["I2"], params["I3"])
    p = sim.parameters(params)
    rng = np.random.default_rng(5)
    for _ in range(3):  # the residual is −(1/h)(Π(W_{k+1}) − W_kᵀ Π(W_k))
        W0 = _random_rotation(sim.equations.groupoid, rng)
        u = rng.uniform(-0.3, 0.3, 3)
        W1 = np.asarray(sp.N(sim.equations.groupoid.cayley(list(u))), dtype=float)
        F = sim.kernel.residual(u, W0.ravel(), p)
        balance = body_momentum(W1, Jd) - W0.T @ body_momentum(W0, Jd)
        assert np.abs(F + balance / h).max() <= 1e-12 * np.abs(F).max()
    traj = sim.simulate(initial_state(sim, "rigid_body"), 100_000, params)
    norm = np.linalg.norm(body_momentum(traj["W"], Jd), axis=1)
    assert np.abs(norm - norm[0]).max() <= 1e-10 * norm[0]
    assert np.ptp(traj["W"][:, 0, 1]) > 1e-4  # the increments W_k change along the run


# --- symplecticity on the pair groupoid -----------------------------------------------------

def double_pendulum() -> sg.DiscreteSystem:
    """Planar double pendulum (unit masses and lengths) in its angles (a, b), midpoint rule:
    L_d(q₀, q₁) = h L((q₀ + q₁)/2, (q₁ − q₀)/h)."""
    h, grav = sp.symbols("h g", positive=True)

    def L(g):
        q0, q1 = sp.Matrix(g.source), sp.Matrix(g.target)
        (a, b), (va, vb) = (q0 + q1) / 2, (q1 - q0) / h
        kinetic = va ** 2 + vb ** 2 / 2 + va * vb * sp.cos(a - b)
        potential = -2 * grav * sp.cos(a) - grav * sp.cos(b)
        return h * (kinetic - potential)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("a b")), L,
                             parameters=[h, grav], name="double_pendulum")


def test_pendulum_hamiltonian_map_is_symplectic():
    """M = ∂(q₁, p₁)/∂(q₀, p₀) by central differences satisfies Mᵀ Ω M = Ω to 1e-8, where
    g₁ = (q₀, q₁) solves F⁻L(g₁) = p₀ and p₁ = F⁻L(g₂) with g₂ from the compiled step."""
    system = double_pendulum()
    sim = system.euler_lagrange().compile(backend="c", cache_dir=SESSION_CACHE)
    legendre = system.legendre()
    params = {"h": 0.1, "g": 9.81}
    p = sim.parameters(params)
    tight = sg.NewtonOptions(tol_residual=1e-15, tol_step=1e-13)

    def flow(z):
        state = sim.from_momentum({"a": z[0], "b": z[1]}, z[2:], params)
        nxt = sim.step(state, params, options=tight)
        minus, _ = legendre.evaluate(nxt, (), p)
        return np.concatenate([state[2:4], minus])

    z0 = np.array([0.7, -0.4, 0.3, 0.5])
    eps = 1e-5
    M = np.column_stack([(flow(z0 + eps * e) - flow(z0 - eps * e)) / (2 * eps)
                         for e in np.eye(4)])
    omega = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])
    assert np.abs(M.T @ omega @ M - omega).max() <= 1e-8
    assert np.abs(M - np.eye(4)).max() > 0.1  # a genuine, non-trivial map
