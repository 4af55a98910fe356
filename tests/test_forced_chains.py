"""The forced chains of ``symgroupoid.systems`` (docs/conventions.md §20): joint torques as
inputs and joint damping.

- ``planar_chain(n, forced=True)``: the residual is Marsden–West's forced DEL
  D₂L_d + D₁L_d + f⁺(θ_{k−1}, θ_k) + f⁻(θ_k, θ_{k+1}), with L_d (through the chain's mass
  matrix) and the midpoint forces (h/2)·Q, Q_j = u_j − u_{j+1} − ∂D/∂θ̇_j, written
  independently here;
- ``spherical_chain(n, forced=True)``: the residual is the junction derivative of the action
  (``test_chains``) plus the body-frame joint torques (h/2)·R_iᵀ(T_i − T_{i+1}) at the
  junction's attitudes, T_j = R_j u_j − c (ω_j − ω_{j−1}), written independently here;
  along compiled steps the vertical angular momentum changes by the pivot's impulse alone
  (the forced Noether balance: the other joints' torques are internal).

With the inputs held at zero and no damping, the planar chain's steps are bitwise those of
the unforced chain; the 3D chain's agree to rounding (the compacted program factors the
damping's monomials together with the Lagrangian's, so their sums are rounded in another
order).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SESSION_CACHE,
    isolated_cache,
    needs_cc,
)
from test_chains import (
    _rotation_section,
    action_residual,
    cayley,
    configurations,
    marsden_west,
    spherical_initial,
)

import symgroupoid as sg
from symgroupoid import systems

H, G, C = 0.01, 9.81, 0.4
E3 = np.array([0.0, 0.0, 1.0])


@functools.cache
def forced_step(kind: str, n: int) -> sg.StepEquations:
    constructor = systems.planar_chain if kind == "planar" else systems.spherical_chain
    return constructor(n, forced=True).euler_lagrange()


# --- planar chain -----------------------------------------------------------------------------


def planar_force(q0, q1, u, h, c) -> np.ndarray:
    """(h/2)·Q at the midpoint of (q0, q1): Q_j = u_j − u_{j+1} − c(v_j − v_{j−1}) +
    c(v_{j+1} − v_j), v = (q1 − q0)/h, v₀ = 0, u_{n+1} = v_{n+1} − v_n = 0."""
    v = (q1 - q0) / h
    rel = np.diff(np.concatenate([[0.0], v]))  # v_j − v_{j−1}
    Q = u - np.append(u[1:], 0.0) - c * rel + c * np.append(rel[1:], 0.0)
    return h / 2 * Q


def test_forced_planar_chain_is_forced_marsden_west() -> None:
    """At random points the residual is D₂L_d + D₁L_d + f⁺(θ_{k−1}, θ_k; u_k) +
    f⁻(θ_k, θ_{k+1}; u_{k+1}); the state ends with u_k, then u_{k+1}."""
    n = 3
    step = forced_step("planar", n)
    assert [str(p) for p in step.parameters] == ["h", "g", "c"]
    assert len(step.knowns) == 4 * n and len(step) == n
    rng = np.random.default_rng(7)
    for _ in range(5):
        qm, qk, qp, uk, up = (rng.uniform(-2, 2, n) for _ in range(5))
        h, g, c = rng.uniform(0.01, 0.2), rng.uniform(1, 10), rng.uniform(0, 2)
        F, _ = step.evaluate(qp, np.concatenate([qm, qk, uk, up]), [h, g, c])
        expected = (marsden_west(qm, qk, qp, h, g) + planar_force(qm, qk, uk, h, c)
                    + planar_force(qk, qp, up, h, c))
        np.testing.assert_allclose(F, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def planar_initial(n: int) -> np.ndarray:
    j = np.arange(1, n + 1)
    theta = 0.6 * np.cos(0.9 * j)
    return np.concatenate([theta - H * 0.4 * np.sin(1.3 * j), theta])


@needs_cc
def test_forced_planar_chain_at_rest_inputs_is_the_chain_bitwise() -> None:
    """Inputs held at zero and c = 0: the steps are bitwise the unforced chain's (the forces'
    terms add exact zeros)."""
    n = 3
    forced = forced_step("planar", n).compile(backend="c", cache_dir=SESSION_CACHE)
    plain = systems.planar_chain(n).euler_lagrange().compile(backend="c",
                                                             cache_dir=SESSION_CACHE)
    x = planar_initial(n)
    a = plain.simulate(x, 300, {"h": H, "g": G})
    b = forced.simulate(np.concatenate([x, np.zeros(2 * n)]), 300, {"h": H, "g": G, "c": 0.0},
                        inputs=np.zeros((300, n)))
    np.testing.assert_array_equal(b.states[:, :2 * n], a.states)
    driven = forced.simulate(np.concatenate([x, np.zeros(2 * n)]), 300,
                             {"h": H, "g": G, "c": 0.0}, inputs=[0.5, 0.0, 0.0])
    assert np.abs(driven.states[:, :2 * n] - a.states).max() > 1e-3  # the inputs act


def test_forced_chains_validate_forced() -> None:
    """``forced`` must be True or False; the forced systems name their inputs."""
    for bad in ("yes", None, 2):
        with pytest.raises(sg.ShapeError, match="forced must be True or False"):
            systems.planar_chain(2, forced=bad)
        with pytest.raises(sg.ShapeError, match="forced must be True or False"):
            systems.spherical_chain(2, forced=bad)
    assert [str(u) for u in systems.planar_chain(2, forced=True).inputs] == ["u1", "u2"]
    assert [str(u) for u in systems.spherical_chain(2, forced=True).inputs] == [
        "u1_1", "u1_2", "u1_3", "u2_1", "u2_2", "u2_3"]


# --- spherical chain --------------------------------------------------------------------------


def spin(A, B, h) -> np.ndarray:
    """ω = vee(B Aᵀ − A Bᵀ)/(2h): the spatial angular velocity over the arrow (A, B)."""
    S = B @ A.T - A @ B.T
    return np.array([S[2, 1], S[0, 2], S[1, 0]]) / (2 * h)


def joint_torques(Ra, Rb, R, u, h, c) -> list:
    """T_j = R_j u_j − c(ω_j − ω_{j−1}) (spatial), ω over the arrow (Ra, Rb), R_j at R."""
    w = [spin(a, b, h) for a, b in zip(Ra, Rb)]
    return [R[j] @ u[j] - c * (w[j] - (w[j - 1] if j else 0)) for j in range(len(R))]


def body_forces(Ra, Rb, R, u, h, c) -> np.ndarray:
    """(h/2) R_iᵀ(T_i − T_{i+1}) for every body, at the attitudes R."""
    T = joint_torques(Ra, Rb, R, u, h, c) + [np.zeros(3)]
    return np.concatenate([h / 2 * R[i].T @ (T[i] - T[i + 1]) for i in range(len(R))])


def test_forced_spherical_chain_is_variational_plus_joint_torques() -> None:
    """At random points the residual is the action's junction derivative plus f⁺ of the
    known arrow (R_{k−1}, R_k; u_k) and f⁻ of the new one (R_k, R_{k+1}; u_{k+1}), both at
    the attitudes R_k."""
    n = 2
    step = forced_step("3d", n)
    assert len(step) == 3 * n and len(step.knowns) == 18 * n + 6 * n
    rng = np.random.default_rng(11)
    for _ in range(4):
        h, g, c = rng.uniform(0.01, 0.2), rng.uniform(1, 10), rng.uniform(0, 2)
        R0 = [cayley(rng.normal(size=3)) for _ in range(n)]
        R1 = [r @ cayley(0.3 * rng.normal(size=3)) for r in R0]
        x = 0.3 * rng.normal(size=3 * n)
        R2 = [r @ cayley(x[3 * i: 3 * i + 3]) for i, r in enumerate(R1)]
        uk, up = rng.normal(size=3 * n), rng.normal(size=3 * n)
        known = np.concatenate([r.ravel() for r in R0 + R1] + [uk, up])
        F, _ = step.evaluate(x, known, [h, g, c])
        expected = (action_residual(R0, R1, R2, h, g)
                    + body_forces(R0, R1, R1, uk.reshape(n, 3), h, c)
                    + body_forces(R1, R2, R1, up.reshape(n, 3), h, c))
        np.testing.assert_allclose(F, expected, rtol=1e-11, atol=1e-11 * np.abs(expected).max())


def pivot_impulse(states: np.ndarray, n: int, h: float, c: float) -> np.ndarray:
    """(h/2) e₃·(T₁(g_k) + T₁(g_{k+1})) at the junction's attitudes, from the kept states
    (every body's R_{k−1}, R_k, then u_k, u_{k+1}): the external impulse about the vertical."""
    out = []
    for a, b in zip(states[:-1], states[1:]):
        (R0, R1), (_, R2) = configurations(a, n), configurations(b, n)
        u0 = a[18 * n: 21 * n].reshape(n, 3)
        u1 = b[18 * n: 21 * n].reshape(n, 3)
        T_plus = joint_torques(R0, R1, R1, u0, h, c)[0]
        T_minus = joint_torques(R1, R2, R1, u1, h, c)[0]
        out.append(h / 2 * E3 @ (T_plus + T_minus))
    return np.array(out)


@functools.cache
def forced_3d_simulator(n: int):
    return forced_step("3d", n).compile(backend="c", cache_dir=SESSION_CACHE)


@needs_cc
def test_forced_spherical_chain_noether_balance() -> None:
    """Along compiled steps of the driven, damped chain of two bodies: the vertical angular
    momentum changes by the library's impulse to rounding, and that impulse is the pivot's
    alone (the second joint's torque and damping are internal).  With the pivot free
    (u₁ = 0, c = 0) the momentum is conserved to rounding while the second joint drives the
    chain."""
    n, steps = 2, 300
    system = systems.spherical_chain(n, forced=True)
    vertical = system.noether(_rotation_section(n, 2))
    assert vertical.is_symmetry
    sim = forced_3d_simulator(n)
    x0 = np.concatenate([spherical_initial(n), np.zeros(6 * n)])
    rng = np.random.default_rng(3)
    U = rng.normal(size=(steps, 3 * n))
    run = sim.simulate(x0, steps, {"h": H, "g": G, "c": C}, inputs=U)
    J, impulse = vertical.along(run), vertical.impulse(run)
    external = pivot_impulse(run.states, n, H, C)
    assert np.abs(external).max() > 1e-3  # the pivot's torque acts
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-12)
    np.testing.assert_allclose(impulse, external, rtol=0, atol=1e-14)
    U[:, :3] = 0.0  # the pivot free, the second joint driven, no damping
    free = sim.simulate(x0, steps, {"h": H, "g": G, "c": 0.0}, inputs=U)
    J = vertical.along(free)
    assert np.abs(vertical.impulse(free)).max() < 1e-15
    assert np.abs(J - J[0]).max() < 1e-12 * max(1.0, abs(J[0]))
    plain = systems.spherical_chain(n).euler_lagrange().compile(backend="c",
                                                                cache_dir=SESSION_CACHE)
    undriven = plain.simulate(spherical_initial(n), steps, {"h": H, "g": G})
    assert np.abs(free.states[:, :18 * n] - undriven.states).max() > 1e-3  # joint 2 acts


@needs_cc
def test_forced_spherical_chain_at_rest_inputs_is_the_chain() -> None:
    """Inputs held at zero and c = 0: the steps are the unforced chain's to rounding (not
    bitwise: the compacted program factors the damping's monomials together with the
    Lagrangian's, so the sums are rounded in another order)."""
    n, steps = 2, 300
    plain = systems.spherical_chain(n).euler_lagrange().compile(backend="c",
                                                                cache_dir=SESSION_CACHE)
    a = plain.simulate(spherical_initial(n), steps, {"h": H, "g": G})
    b = forced_3d_simulator(n).simulate(
        np.concatenate([spherical_initial(n), np.zeros(6 * n)]), steps,
        {"h": H, "g": G, "c": 0.0}, inputs=np.zeros(3 * n))
    assert np.abs(b.states[:, :18 * n] - a.states).max() < 1e-12


@needs_cc
def test_forced_run_across_chunks_is_one_run() -> None:
    """A forced run that keeps every state is filled in place chunk by chunk (CHUNK_STEPS =
    2¹⁴ steps each); its states are bitwise those of the same run kept every 5th state (one
    kernel call), across the chunk boundary too."""
    n, steps = 2, (1 << 14) + 300
    sim = forced_step("planar", n).compile(backend="c", cache_dir=SESSION_CACHE)
    start = np.concatenate([planar_initial(n), np.zeros(2 * n)])
    U = 0.2 * np.random.default_rng(5).standard_normal((steps, n))
    params = {"h": H, "g": G, "c": C}
    whole = sim.simulate(start, steps, params, inputs=U)
    sampled = sim.simulate(start, steps, params, inputs=U, every=5)
    np.testing.assert_array_equal(sampled.states, whole.states[sampled.step_indices])
    assert np.array_equal(whole["u1"][1:], U[:, 0]) and len(whole.newton_iterations) == steps
