"""Reduction by groupoid morphisms (seed 000 Thm 4.5, Cor. 4.6, Remark 4.7;
docs/conventions.md §13).

Each system is reduced with ``DiscreteSystem.reduce`` and checked on compiled trajectories:
Φ maps the unreduced solution to a solution of the reduced equations (residuals at rounding
level, and the reduced kernel run from the projected first state reproduces it), the
reconstruction from the projection and the first arrow is the unreduced solution, and the
momenta are A*Φ-related (Thm 4.5 (ii)–(iii))."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from _lie_pairs import LieGroupPair
from conftest import load_example
from kernel_support import isolated_cache  # noqa: F401  (isolated_cache: autouse fixture)

import symgroupoid as sg
from symgroupoid import systems

E3 = sp.Matrix([0, 0, 1])


def _ends(P, coords):
    return P.group.matrix(P.source(coords)), P.group.matrix(P.target(coords))


def _to_group(P, K):
    """(g₀, g₁) ↦ g₀⁻¹g₁, with the section W ↦ (e, W)."""
    def phi(g):
        g0, g1 = _ends(P, g.coords)
        return K._inverse_matrix(g0) * g1

    unit = P.group.entries(sp.eye(P.group.n))
    return sg.GroupoidMorphism(P, K, phi, section=lambda w: P.arrow_from(unit, w.coords))


def _chart(G, arrow):
    return np.asarray(G.fibre_chart_inverse(G.fibre_of(tuple(arrow))), float)


def _corollary_4_6(full, reduced, state0, params: dict, steps: int) -> dict:
    """Defects of Corollary 4.6 / Remark 4.7 along a compiled unreduced run."""
    traj = full.euler_lagrange().compile().simulate(state0, steps, params)
    proj = reduced.project(traj, params)
    step = reduced.euler_lagrange()
    G, n = reduced.groupoid, reduced.groupoid.arrow_dim
    u = np.array([np.concatenate([_chart(G, s[:n]), s[n:]]) for s in proj[1:]])
    p = [params[str(s)] for s in step.parameters]
    F, _ = step.evaluate(u.T, proj[:-1].T, p)
    run = step.compile().simulate(proj[0], steps, params)
    back = reduced.reconstruct(proj, traj.states[0], params)
    relation = max(reduced.related_momenta(s[:full.groupoid.arrow_dim],
                                           s[full.groupoid.arrow_dim:], params).defect
                   for s in traj.states[:: max(1, steps // 5)])
    return {"residual": float(np.abs(F).max()),
            "rerun": float(np.abs(run.states - proj).max()),
            "reconstruction": float(np.abs(back - traj.states).max()),
            "momenta": relation, "moved": float(np.ptp(proj[:, :n], axis=0).max())}


def _translations():
    """A free particle on the pair groupoid of R reduced by Φ(x₀, x₁) = s(x₁ − x₀) to the
    translations u (a groupoid over a point), L′(u) = (u/s)²/(2h)."""
    h, s = sp.symbols("h s", positive=True)
    T = sg.DefinedGroupoid("translations", base_names=[], fibre_names=["u"],
                           source=lambda a: (), target=lambda a: (),
                           multiply=lambda a, b: (a[0] + b[0],), identity=lambda q: (0,),
                           inverse=lambda a: (-a[0],), sections=lambda q, t: [(t,)])
    P = sg.PairGroupoid(sg.EuclideanSpace("x"))
    full = sg.DiscreteSystem(P, lambda g: (g.target[0] - g.source[0]) ** 2 / (2 * h),
                             parameters=[h], name="free")
    phi = sg.GroupoidMorphism(P, T, lambda g: (s * (g.target[0] - g.source[0]),))
    return full.reduce(phi, lagrangian=lambda w: (w.coords[0] / s) ** 2 / (2 * h))


def test_the_reduced_systems_numerics_check_their_arguments():
    """project, reconstruct and related_momenta raised a bare KeyError for a missing
    parameter, returned NaN for a NaN one or a NaN arrow, and failed inside lambdified code
    (ValueError) on an arrow of the wrong length or a string; a morphism whose map gives
    NaN was reported without naming it."""
    red = _translations()
    states, params = np.array([[0.0, 0.1], [0.1, 0.2]]), {"h": 0.1, "s": 2.0}
    assert np.allclose(red.project(states, params), [[0.2], [0.2]])
    for bad, message in [({"h": 0.1}, "missing parameter s"),
                         ({"h": 0.1, "s": np.nan}, "non-finite parameter s"),
                         ({"h": 0.1, "s": -1.0}, "declared positive")]:
        with pytest.raises(sg.ParameterError, match=message):
            red.project(states, bad)
        with pytest.raises(sg.ParameterError, match=message):
            red.related_momenta([0.0, 0.1], (), bad)
        with pytest.raises(sg.ParameterError, match=message):
            red.reconstruct(red.project(states, params), states[0], bad)
    with pytest.raises(sg.DomainError, match="non-finite entries in the arrow"):
        red.related_momenta([np.nan, 0.1], (), params)
    with pytest.raises(sg.ShapeError, match="2 entries expected for the arrow, got 1"):
        red.related_momenta([0.1], (), params)
    with pytest.raises(sg.ShapeError, match="0 entries expected for the multipliers"):
        red.related_momenta([0.0, 0.1], [1.0], params)
    with pytest.raises(sg.ShapeError, match="must be an array of real numbers"):
        red.project("abc", params)
    P, T = red.unreduced.groupoid, red.groupoid
    nan_map = sg.GroupoidMorphism(P, T, lambda g: (sp.nan * g.target[0],))
    with pytest.raises(sg.DomainError, match=r"Φ: .*: the map's value at a random arrow is "
                                             r"not a finite real number"):
        sg.check_morphism(nan_map)


def test_project_refuses_states_off_their_group():
    """project returned Φ(1.5·I, 1.5·I) = 2.25·I as a reduced arrow of SO(3), where a run
    from that state is refused; a property check over every groupoid is
    tests/test_groupoid_properties.py's."""
    rb = systems.rigid_body()
    h, I1, I2, I3 = rb.parameters
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))
    P = sg.PairGroupoid(sg.SO3("R"))
    full = sg.DiscreteSystem(P, lambda g: -(Jd * g.source.T * g.target).trace() / h,
                             parameters=rb.parameters, name="rb_pair")
    phi = sg.GroupoidMorphism(P, rb.groupoid, lambda g: g.source.T * g.target,
                              section=lambda w: P.arrow_from(tuple(sp.eye(3)),
                                                             tuple(w.matrix)))
    red = full.reduce(phi)
    params = {"h": 0.1, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    R = _rotation([0.1, -0.2, 0.3])
    good = np.concatenate([np.eye(3).ravel(), R.ravel()])
    assert np.allclose(red.project(good[None, :], params).reshape(3, 3), R)
    with pytest.raises(sg.DomainError, match="unreduced state 1 is not an arrow"):
        red.project(np.vstack([good, 1.5 * good]), params)


def _rotation(x):
    return np.array(sg.SO3("t").cayley([sp.Float(v) for v in x]).evalf().tolist(), float)


@pytest.mark.slow
def test_pair_groupoid_of_so3_reduces_to_the_discrete_euler_poincare_equations():
    """Reducing L(g₀, g₁) = −tr(J_d g₀ᵀg₁)/h by (g₀, g₁) ↦ g₀⁻¹g₁ gives, with L′ found through
    the section, exactly the Moser–Veselov (discrete Euler–Poincaré) equations of
    ``systems.rigid_body``; Cor. 4.6 holds on a compiled run."""
    rb = systems.rigid_body()
    h, (I1, I2, I3) = rb.parameters[0], rb.parameters[1:]
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))
    P = LieGroupPair(sg.SO3)

    def L(g):
        g0, g1 = _ends(P, g.coords)
        return -(Jd * g0.T * g1).trace() / h

    full = sg.DiscreteSystem(P, L, parameters=rb.parameters, name="rigid_body_pair")
    reduced = full.reduce(_to_group(P, rb.groupoid))
    assert [c.method for c in reduced.checks] == ["symbolic"]
    expected = rb.euler_lagrange().residuals
    got = reduced.euler_lagrange().residuals
    assert all(sp.expand(a - b) == 0 for a, b in zip(got, expected))
    params = {"h": 0.1, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    state0 = np.concatenate([_rotation([0.3, -0.2, 0.5]).ravel(),
                             _rotation([0.05, 0.1, -0.08]).ravel()])
    d = _corollary_4_6(full, reduced, state0, params, 150)
    assert d["moved"] > 0.05
    assert d["residual"] < 1e-11 and d["rerun"] < 1e-10
    assert d["reconstruction"] < 1e-12 and d["momenta"] < 1e-13
    bad = np.vstack([state0, state0])
    bad[1, 4] = np.nan  # (project returned NaN rows for it, without a word)
    with pytest.raises(sg.DomainError, match="unreduced state 1 has a non-finite entry"):
        reduced.project(bad, params)


@pytest.mark.slow
def test_pair_groupoid_of_se2_reduces_to_se2():
    """L = m/(2h)|u|² + (I/h)(1 − cos θ) of g₀⁻¹g₁ = (R(θ), u), written with α and β;
    the reduced Lagrangian is given and L = L′∘Φ holds only on the group (numeric check)."""
    h, m, inertia = sp.symbols("h m I", positive=True)
    K = sg.SE2("W")
    P = LieGroupPair(sg.SE2, point="q")

    def Lr(w):
        W = w.matrix
        return m / (2 * h) * (W[0, 2] ** 2 + W[1, 2] ** 2) + inertia / h * (1 - W[0, 0])

    def L(g):
        g0, g1 = _ends(P, g.coords)
        R = g0[:2, :2].T * g1[:2, :2]
        dx = g1[:2, 2] - g0[:2, 2]
        return m / (2 * h) * dx.dot(dx) + inertia / h * (1 - R[0, 0])

    full = sg.DiscreteSystem(P, L, parameters=[h, m, inertia], name="se2_pair")
    reduced = full.reduce(_to_group(P, K), lagrangian=Lr)
    assert [c.method for c in reduced.checks] == ["numeric"]
    se2 = sg.SE2("t", retraction="exp")
    q0 = np.array(se2.exp([0.4, 1.0, -0.5]).evalf().tolist(), float)
    F = np.array(se2.exp([0.1, 0.08, 0.03]).evalf().tolist(), float)
    params = {"h": 0.1, "m": 2.0, "I": 0.5}
    d = _corollary_4_6(full, reduced, np.concatenate([q0[:2].ravel(), F[:2].ravel()]),
                       params, 150)
    assert d["moved"] > 0.05
    assert d["residual"] < 1e-11 and d["rerun"] < 1e-10
    assert d["reconstruction"] < 1e-11 and d["momenta"] < 1e-13


@pytest.mark.slow
def test_heavy_top_as_reduction_of_the_pair_groupoid_of_so3():
    """(R₀, R₁) ↦ (R₀ᵀe₃, R₀ᵀR₁) maps L(R₀, R₁) = −tr(J_d R₀ᵀR₁)/h − h mgl (R₀ᵀe₃)₃ onto the
    heavy top of ``systems.heavy_top`` (S² × SO(3) ⇉ S²): same equations, Cor. 4.6 on a run.
    There is no global section (S² has no nonvanishing field), so L′ is given."""
    ht = systems.heavy_top()
    h, mgl, I1, I2, I3 = ht.parameters
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))
    P = LieGroupPair(sg.SO3)

    def L(g):
        g0, g1 = _ends(P, g.coords)
        return -(Jd * g0.T * g1).trace() / h - h * mgl * (g0.T * E3)[2]

    def phi(g):
        g0, g1 = _ends(P, g.coords)
        return (g0.T * E3, g0.T * g1)

    full = sg.DiscreteSystem(P, L, parameters=ht.parameters, name="top_pair")
    pi = sg.GroupoidMorphism(P, ht.groupoid, phi)
    with pytest.raises(ValueError, match="has no section"):
        full.reduce(pi)
    reduced = full.reduce(pi, lagrangian=ht.lagrangian)
    assert [c.method for c in reduced.checks] == ["symbolic"]
    got, expected = reduced.euler_lagrange().residuals, ht.euler_lagrange().residuals
    assert all(sp.expand(a - b) == 0 for a, b in zip(got, expected))
    params = {"h": 0.05, "mgl": 1.0, "I1": 1.0, "I2": 1.5, "I3": 0.5}
    state0 = np.concatenate([_rotation([0.4, 0.3, -0.2]).ravel(),
                             _rotation([0.02, -0.05, 0.1]).ravel()])
    d = _corollary_4_6(full, reduced, state0, params, 150)
    assert d["moved"] > 0.05
    assert d["residual"] < 1e-11 and d["rerun"] < 1e-10
    assert d["reconstruction"] < 1e-12 and d["momenta"] < 1e-13


@pytest.mark.slow
def test_constrained_system_reduces_with_its_multipliers():
    """φ(g₀, g₁) = tr(g₀ᵀg₁ E₃)/2 on the pair groupoid of SO(3) reduces to φ′(W) = tr(W E₃)/2
    on SO(3) (found through the section); the multipliers are shared."""
    rb = systems.rigid_body()
    h, (I1, I2, I3) = rb.parameters[0], rb.parameters[1:]
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))
    E = sp.Matrix(sg.SO3.basis_matrices()[2])
    P = LieGroupPair(sg.SO3)

    def L(g):
        g0, g1 = _ends(P, g.coords)
        return -(Jd * g0.T * g1).trace() / h

    def phi(g):
        g0, g1 = _ends(P, g.coords)
        return [(g0.T * g1 * E).trace() / 2]

    full = sg.DiscreteSystem(P, L, constraints=phi, parameters=rb.parameters,
                             name="constrained_pair")
    reduced = full.reduce(_to_group(P, rb.groupoid))
    assert reduced.n_constraints == 1
    assert [c.method for c in reduced.checks] == ["symbolic", "symbolic"]
    params = {"h": 0.1, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    state0 = np.concatenate([_rotation([0.3, -0.2, 0.5]).ravel(),
                             _rotation([0.08, 0.05, 0.0]).ravel(), [0.1]])
    d = _corollary_4_6(full, reduced, state0, params, 100)
    assert d["moved"] > 0.05
    assert d["residual"] < 1e-11 and d["rerun"] < 1e-10
    assert d["reconstruction"] < 1e-11 and d["momenta"] < 1e-13


def test_reduction_refuses_what_is_not_a_system_morphism():
    rb = systems.rigid_body()
    h, (I1, I2, I3) = rb.parameters[0], rb.parameters[1:]
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))
    P = LieGroupPair(sg.SO3)

    def L(g):
        g0, g1 = _ends(P, g.coords)
        return -(Jd * g0.T * g1).trace() / h

    full = sg.DiscreteSystem(P, L, parameters=rb.parameters)
    phi = _to_group(P, rb.groupoid)
    with pytest.raises(sg.MorphismError, match="L = L′∘Φ fails"):
        full.reduce(phi, lagrangian=lambda w: -(Jd * w.matrix).trace() / (2 * h))
    with pytest.raises(sg.ShapeError, match="no constraints"):
        full.reduce(phi, constraints=lambda w: [w.matrix[0, 1]])
    other = sg.DiscreteSystem(rb.groupoid, rb.lagrangian, parameters=rb.parameters)
    with pytest.raises(ValueError, match="starts at"):
        other.reduce(phi)
    with pytest.raises(TypeError, match="GroupoidMorphism"):
        full.reduce(lambda g: g)


def test_reconstruction_needs_an_initial_arrow_over_the_first_reduced_arrow():
    rb = systems.rigid_body()
    P = LieGroupPair(sg.SO3)
    phi = _to_group(P, rb.groupoid)
    W = _rotation([0.1, 0.2, 0.3])
    arrows = np.array([W.ravel(), W.ravel()])
    g0 = np.concatenate([_rotation([0.5, 0, 0]).ravel(), W.ravel()])
    back = phi.reconstruct(arrows, g0)
    assert np.allclose(back[1, 9:], W.ravel(), atol=1e-12)
    assert np.allclose(back[1, :9], (_rotation([0.5, 0, 0]) @ W).ravel(), atol=1e-12)
    wrong = np.concatenate([_rotation([0.5, 0, 0]).ravel(), np.eye(3).ravel()])
    with pytest.raises(sg.ReconstructionError, match="initial arrow projects"):
        phi.reconstruct(arrows, wrong)
    with pytest.raises(sg.ShapeError):
        phi.reconstruct(arrows[:, :4], g0)


def test_second_order_systems_are_not_reduced_silently():
    P = LieGroupPair(sg.SO3)
    h = sp.Symbol("h", positive=True)
    so = sg.SecondOrderSystem(P, lambda a, b: (a.matrix.trace() - b.matrix.trace()) ** 2 / h,
                              parameters=[h])
    with pytest.raises(sg.UnsupportedFeatureError, match="first-order"):
        so.reduce(_to_group(P, sg.SO3("W")))


@pytest.mark.slow
def test_elroys_beanie_reduces_through_the_section_too():
    """L′ found by substitution through the Atiyah quotient's section equals the seed's
    reduced Lagrangian on random arrows."""
    eb = load_example("elroys_beanie")
    A, P = eb.atiyah_groupoid(), eb.pair_groupoid()
    pi = A.quotient_map_from(P)
    full = sg.DiscreteSystem(P, eb.unreduced_lagrangian,
                             parameters=[eb.h, eb.m, eb.I1, eb.I2, eb.k])
    reduced = full.reduce(pi)
    rng = np.random.default_rng(5)
    values = {eb.h: 0.1, eb.m: 1.3, eb.I1: 0.7, eb.I2: 1.9, eb.k: 0.4}
    for _ in range(4):
        g = A.view(A.random_arrow(rng))
        x = sp.sympify(reduced.lagrangian(g)).xreplace(values)
        y = sp.sympify(eb.reduced_lagrangian(g)).xreplace(values)
        assert abs(float(x) - float(y)) < 1e-12 * (1 + abs(float(y)))
