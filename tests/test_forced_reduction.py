"""Reduction of forced systems by groupoid morphisms (seed 000 Def. 4.2, 4.4, Thm 4.5,
Cor. 4.6, Remark 4.7 with forces; docs/conventions.md §13, §20).

A morphism Φ: G → G′ with L = L′∘Φ reduces a forced system when the forces are A*Φ-related,
f±(g) = M·f′±(Φ(g)) (M the algebroid matrix of Φ): the forced junction residual of G is M
times that of G′, so Φ maps forced runs to forced runs of the reduced system with the same
inputs.  Checked on the pair groupoid of SO(2) → SO(2) by (q₀, q₁) ↦ q₁ᵀq₀ (M = −1: a
reduced force written without M is refused) and on the pair groupoid of SO(3) → SO(3) by
(q₀, q₁) ↦ C q₀ᵀq₁ Cᵀ (M = Cᵀ, a permutation of the axes), each a rotor or rigid body with
torque inputs and damping, on runs with random inputs.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from _lie_pairs import LieGroupPair
from kernel_support import module_cache, module_cache_root  # noqa: F401  (autouse fixture)
from scipy.spatial.transform import Rotation

import symgroupoid as sg
from symgroupoid import systems

h, c, inertia = sp.symbols("h c I", positive=True)
u = sp.Symbol("u", real=True)
taus = sp.symbols("tau1:4", real=True)


def _ends(P, coords):
    return P.group.matrix(P.source(coords)), P.group.matrix(P.target(coords))


# --- the rotor: pair groupoid of SO(2) → SO(2), M = −1 ------------------------------------------

@functools.cache
def rotor():
    """A rotor with a torque input u and damping c on the pair groupoid of SO(2):
    L = (I/h)(1 − cos Δθ), f± = (h/2)(u − c·sin Δθ/h), Δθ the angle of q₀ᵀq₁; Φ(q₀, q₁) =
    q₁ᵀq₀ = (q₀ᵀq₁)⁻¹ (a morphism onto the abelian SO(2), with M = −1)."""
    P = LieGroupPair(sg.SO2)
    K = sg.SO2("W")

    def phi(g):
        g0, g1 = _ends(P, g.coords)
        return g1.T * g0

    def L(g):
        g0, g1 = _ends(P, g.coords)
        return inertia / h * (1 - (g0.T * g1)[0, 0])

    def forces(g):
        g0, g1 = _ends(P, g.coords)
        f = h / 2 * (u - c * (g0.T * g1)[1, 0] / h)
        return [f], [f]

    full = sg.DiscreteSystem(P, L, parameters=[h, c, inertia], forces=forces, inputs=[u],
                             name="rotor_pair", time_step=h)
    return full, sg.GroupoidMorphism(P, K, phi)


def rotor_lagrangian(w):
    return inertia / h * (1 - w.matrix[0, 0])


def rotor_forces(w):
    """f′ = M⁻¹f with M = −1: Φ(g) = W′ turns by −Δθ, so sin Δθ = −W′₁₀."""
    f = -h / 2 * (u + c * w.matrix[1, 0] / h)
    return [f], [f]


def rotation2(t: float) -> np.ndarray:
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


ROTOR = {"h": 0.1, "c": 0.3, "I": 2.0}


def test_a_forced_rotor_reduces_and_the_runs_agree():
    """The reduced forced run from the projected first state, with the same inputs, is the
    projection of the unreduced run (Cor. 4.6 with forces), and the reconstruction of the
    projection is the unreduced run (Remark 4.7)."""
    full, phi = rotor()
    reduced = full.reduce(phi, lagrangian=rotor_lagrangian, forces=rotor_forces)
    assert [c.method for c in reduced.checks] == ["symbolic", "numeric"]
    assert "A*Φ-related" in str(reduced.checks[1]) and reduced.inputs == [u]
    steps = 60
    U = np.random.default_rng(1).normal(size=(steps + 1, 1))
    state0 = np.concatenate([rotation2(0.4).ravel(), rotation2(0.2).ravel(), U[0], U[0]])
    run = full.euler_lagrange().compile(backend="numpy").simulate(state0, steps, ROTOR,
                                                                  inputs=U[1:])
    proj = reduced.project(run, ROTOR)
    again = reduced.euler_lagrange().compile(backend="numpy").simulate(proj[0], steps, ROTOR,
                                                                      inputs=U[1:])
    np.testing.assert_allclose(again.states, proj, rtol=0, atol=1e-13)
    np.testing.assert_allclose(reduced.reconstruct(proj, run.states[0], ROTOR), run.states,
                               rtol=0, atol=1e-13)
    unforced = full.euler_lagrange().compile(backend="numpy").simulate(
        state0, steps, ROTOR, inputs=np.zeros((steps, 1)))
    assert np.abs(unforced.states[:, 4:8] - run.states[:, 4:8]).max() > 1e-2


def test_the_forced_residuals_are_related_by_the_algebroid_matrix():
    """R(g_k, g_{k+1}) = M·R′(Φ(g_k), Φ(g_{k+1})) at random composable arrows and inputs (the
    identity behind the reduction, docs/conventions.md §13): the step residuals of the
    unreduced and reduced systems, evaluated at a step that is not a solution."""
    full, phi = rotor()
    reduced = full.reduce(phi, lagrangian=rotor_lagrangian, forces=rotor_forces)
    step, rstep = full.euler_lagrange(), reduced.euler_lagrange()
    rng = np.random.default_rng(2)
    p = [ROTOR[str(s)] for s in step.parameters]
    for _ in range(4):
        a, b, t = rng.uniform(-1, 1, 3)
        uk, un = rng.normal(size=2)
        known = np.concatenate([rotation2(a).ravel(), rotation2(b).ravel(), [uk, un]])
        x = np.array([t])  # the unknown: the new arrow's chart coordinates
        F, _ = step.evaluate(x, known, p)
        new = np.asarray(step.advance(x, known, p), float).ravel()[:8]
        r = phi.project(np.array([known[:8], new]), ROTOR)
        rknown = np.concatenate([r[0], [uk, un]])
        G = reduced.groupoid
        rx = np.asarray(G.fibre_chart_inverse(G.fibre_of(tuple(r[1]))), float)
        RF, _ = rstep.evaluate(rx, rknown, [ROTOR[str(s)] for s in rstep.parameters])
        assert abs(float(np.ravel(F)[0])) > 1e-3
        np.testing.assert_allclose(np.ravel(F), -np.ravel(RF), rtol=1e-12, atol=1e-14)


def test_a_reduced_force_that_is_not_related_is_refused():
    """f′ written without the algebroid matrix (M = −1 forgotten), a wrong damping, and a
    force on one side only are refused with a MorphismError naming the side; a forced system
    reduced without its reduced forces, and forces given to an unforced one, are refused."""
    full, phi = rotor()

    def forgotten(w):
        f = h / 2 * (u + c * w.matrix[1, 0] / h)
        return [f], [f]

    def damped_twice(w):
        f = -h / 2 * (u + 2 * c * w.matrix[1, 0] / h)
        return [f], [f]

    def one_side(w):
        f = -h / 2 * (u + c * w.matrix[1, 0] / h)
        return [f], [0]

    for wrong, side in ((forgotten, "f⁻"), (damped_twice, "f⁻"), (one_side, "f⁺")):
        with pytest.raises(sg.MorphismError, match="not A\\*Φ-related") as info:
            full.reduce(phi, lagrangian=rotor_lagrangian, forces=wrong)
        assert info.value.axiom.startswith(side) and "u=" in str(info.value)
    with pytest.raises(sg.ShapeError, match="forced; give its reduced forces"):
        full.reduce(phi, lagrangian=rotor_lagrangian)
    plain = sg.DiscreteSystem(full.groupoid, full.lagrangian, parameters=full.parameters,
                              name="rotor_free")
    with pytest.raises(sg.ShapeError, match="no forces; reduced forces were given"):
        plain.reduce(phi, lagrangian=rotor_lagrangian, forces=rotor_forces)
    with pytest.raises(sg.UndeclaredSymbolError):
        full.reduce(phi, lagrangian=rotor_lagrangian,
                    forces=lambda w: ([sp.Symbol("z") * h], [0]))


def test_check_system_morphism_of_forced_systems():
    full, phi = rotor()
    other = sg.DiscreteSystem(phi.target, rotor_lagrangian, parameters=[h, c, inertia],
                              forces=rotor_forces, inputs=[u], name="rotor")
    checks = sg.check_system_morphism(phi, full, other)
    assert [c.method for c in checks] == ["symbolic", "numeric"]
    wrong = sg.DiscreteSystem(phi.target, rotor_lagrangian, parameters=[h, c, inertia],
                              forces=lambda w: ([h * u], [h * u]), inputs=[u], name="rotor_w")
    with pytest.raises(sg.MorphismError, match="A\\*Φ-related"):
        sg.check_system_morphism(phi, full, wrong)
    v = sp.Symbol("v", real=True)
    renamed = sg.DiscreteSystem(phi.target, rotor_lagrangian, parameters=[h, c, inertia],
                                forces=lambda w: ([h * v], [h * v]), inputs=[v],
                                name="rotor_v")
    with pytest.raises(sg.ShapeError, match="inputs differ"):
        sg.check_system_morphism(phi, full, renamed)


# --- the rigid body: pair groupoid of SO(3) → SO(3), M = Cᵀ --------------------------------------

C = sp.Matrix([[0, 0, 1], [1, 0, 0], [0, 1, 0]])  # a rotation permuting the axes


def _omega(W):
    """vee(W − Wᵀ)/(2h), the body angular velocity of the increment W to first order."""
    return [(W[2, 1] - W[1, 2]) / (2 * h), (W[0, 2] - W[2, 0]) / (2 * h),
            (W[1, 0] - W[0, 1]) / (2 * h)]


@functools.cache
def rigid_body():
    """L = −tr(J_d q₀ᵀq₁)/h with body torques τ and damping c·ω; Φ(q₀, q₁) = C q₀ᵀq₁ Cᵀ, so
    AΦ(E_a) = C E_a Cᵀ = hat(C e_a) and M = Cᵀ; L′(W) = −tr(C J_d Cᵀ W)/h and f′ = C·f∘Φ⁻¹."""
    Jd = sp.Matrix(systems.discrete_inertia(1, 2, 3))
    P = LieGroupPair(sg.SO3)

    def phi(g):
        g0, g1 = _ends(P, g.coords)
        return C * g0.T * g1 * C.T

    def L(g):
        g0, g1 = _ends(P, g.coords)
        return -(Jd * g0.T * g1).trace() / h

    def forces(g):
        g0, g1 = _ends(P, g.coords)
        half = [h / 2 * (t - c * o) for t, o in zip(taus, _omega(g0.T * g1))]
        return half, list(half)

    full = sg.DiscreteSystem(P, L, parameters=[h, c], forces=forces, inputs=list(taus),
                             name="body_pair", time_step=h)
    return full, sg.GroupoidMorphism(P, sg.SO3("W"), phi), Jd


def body_forces(w):
    half = C * sp.Matrix([h / 2 * (t - c * o) for t, o in zip(taus, _omega(C.T * w.matrix * C))])
    return list(half), list(half)


@pytest.mark.slow
def test_a_forced_rigid_body_on_the_pair_groupoid_of_so3_reduces():
    """The rigid body with torque inputs and damping, reduced by a conjugated quotient map
    (M = Cᵀ a permutation of the axes, so the reduced torques are permuted): the reduced run
    is the projection of the unreduced one; the reduced torques without the permutation are
    refused."""
    full, phi, Jd = rigid_body()

    def Lr(w):
        return -(C * Jd * C.T * w.matrix).trace() / h

    reduced = full.reduce(phi, lagrangian=Lr, forces=body_forces)
    params, steps = {"h": 0.1, "c": 0.2}, 40
    U = np.random.default_rng(3).normal(size=(steps + 1, 3))
    q0 = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    W0 = Rotation.from_rotvec([0.05, 0.1, -0.08]).as_matrix()
    state0 = np.concatenate([q0.ravel(), W0.ravel(), U[0], U[0]])
    run = full.euler_lagrange().compile(backend="numpy").simulate(state0, steps, params,
                                                                  inputs=U[1:])
    proj = reduced.project(run, params)
    again = reduced.euler_lagrange().compile(backend="numpy").simulate(proj[0], steps, params,
                                                                      inputs=U[1:])
    np.testing.assert_allclose(again.states, proj, rtol=0, atol=1e-12)
    assert np.ptp(proj[:, :9], axis=0).max() > 0.1

    def unpermuted(w):
        half = [h / 2 * (t - c * o) for t, o in zip(taus, _omega(C.T * w.matrix * C))]
        return half, list(half)

    with pytest.raises(sg.MorphismError, match="A\\*Φ-related"):
        full.reduce(phi, lagrangian=Lr, forces=unpermuted)
