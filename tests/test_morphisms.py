"""Groupoid morphisms (seed 000 Def. 4.1–4.2, §4.1; docs/conventions.md §13): the axioms on
random composable pairs, the derived base map, the induced algebroid map and the A*Φ-relation,
and morphisms of discrete constrained Lagrangian systems."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from _lie_pairs import LieGroupPair

import symgroupoid as sg
from symgroupoid import systems

E3 = sp.Matrix([0, 0, 1])


def _pair_so3() -> LieGroupPair:
    return LieGroupPair(sg.SO3)


def _ends(P, g):
    """(q₀, q₁) of an arrow of the pair groupoid of SO(3), as matrices."""
    return P.group.matrix(P.source(g.coords)), P.group.matrix(P.target(g.coords))


def _to_lie_group(P, K=None):
    K = K or sg.SO3("W")

    def phi(g):
        R0, R1 = _ends(P, g)
        return R0.T * R1

    return sg.GroupoidMorphism(P, K, phi, section=lambda w: P.arrow_from(
        P.group.entries(sp.eye(3)), w.coords))


def _to_heavy_top(P, HT):
    def phi(g):
        R0, R1 = _ends(P, g)
        return (R0.T * E3, R0.T * R1)

    return sg.GroupoidMorphism(P, HT, phi)


def test_lie_group_reduction_is_a_morphism_with_identity_algebroid_map():
    """(g₀, g₁) ↦ g₀⁻¹g₁ from the pair groupoid of SO(3): Def. 4.1 holds; the base map is
    derived (the base of a Lie group is a point); AΦ maps the basis E_a to E_a."""
    P = _pair_so3()
    phi = _to_lie_group(P)
    sg.check_morphism(phi)
    assert phi.base_image == ()
    q = P.random_base_point(np.random.default_rng(4))
    assert np.allclose(phi.algebroid_matrix(q), np.eye(3), atol=1e-12)
    p = np.array([0.3, -0.1, 2.0])
    assert np.allclose(phi.pull_back_momentum(q, p), p)


def test_heavy_top_reduction_is_a_morphism_with_derived_base_map():
    """(R₀, R₁) ↦ (R₀ᵀe₃, R₀ᵀR₁) onto S² × SO(3) ⇉ S²: Φ₀(R) = Rᵀe₃ is derived."""
    P = _pair_so3()
    HT = systems.heavy_top().groupoid
    phi = _to_heavy_top(P, HT)
    sg.check_morphism(phi)
    R = P.random_base_point(np.random.default_rng(2))
    expected = np.array(P.group.matrix(R).tolist(), float).T @ np.array([0, 0, 1.0])
    assert np.allclose([float(v) for v in phi.base(R)], expected, atol=1e-14)


def test_a_map_that_does_not_respect_products_is_reported_with_its_arrows():
    P = _pair_so3()

    def phi(g):
        R0, R1 = _ends(P, g)
        return R1.T * R0 * R1 * R0.T * R1  # not multiplicative

    bad = sg.GroupoidMorphism(P, sg.SO3("W"), phi)
    with pytest.raises(sg.MorphismError) as info:
        sg.check_morphism(bad)
    assert info.value.axiom == "Φ(ab) = Φ(a)Φ(b)"
    assert set(info.value.arrows) == {"a", "b"}
    assert "Φ(ab) = Φ(a)Φ(b) fails for a=(" in str(info.value)


def test_a_map_that_breaks_composability_is_reported():
    """Γ taken at the target instead of the source: (Φa, Φb) are not composable."""
    P = _pair_so3()
    HT = systems.heavy_top().groupoid

    def phi(g):
        R0, R1 = _ends(P, g)
        return (R1.T * E3, R0.T * R1)

    with pytest.raises(sg.MorphismError, match="composable"):
        sg.check_morphism(sg.GroupoidMorphism(P, HT, phi))


def test_base_map_given_by_the_user_is_checked():
    P = _pair_so3()
    HT = systems.heavy_top().groupoid
    phi = sg.GroupoidMorphism(P, HT, _to_heavy_top(P, HT)._map,
                              base_map=lambda q: tuple(P.group.matrix(q).T * E3))
    sg.check_morphism(phi)
    wrong = sg.GroupoidMorphism(P, HT, _to_heavy_top(P, HT)._map,
                                base_map=lambda q: tuple(P.group.matrix(q) * E3))
    with pytest.raises(sg.MorphismError, match="α′∘Φ = Φ₀∘α"):
        sg.check_morphism(wrong)


def test_algebroid_map_and_related_sections_on_a_linear_morphism():
    """Φ(x₀, y₀, x₁, y₁) = (x₀ + 2y₀, x₁ + 2y₁) between pair groupoids: AΦ(∂x) = ∂u,
    AΦ(∂y) = 2∂u; related sections are exactly those with c′ = Mᵀc."""
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    H = sg.PairGroupoid(sg.EuclideanSpace("u"))
    phi = sg.GroupoidMorphism(G, H, lambda g: (g.source[0] + 2 * g.source[1],
                                               g.target[0] + 2 * g.target[1]))
    sg.check_morphism(phi)
    assert np.allclose(phi.algebroid_matrix((0.3, 0.4)), [[1.0], [2.0]])
    assert phi.related([1, 0], [1])
    assert phi.related([0, 1], [2])
    assert not phi.related([0, 1], [1])
    # X = y ∂x has AΦ(X)(q) = y ∂u, which is X′ = ∂u at Φ₀(q) only where y = 1
    assert not phi.related(lambda q: [q[1], 0], [1])
    assert np.allclose(phi.pull_back_momentum((0.0, 0.0), [3.0]), [3.0, 6.0])


def test_symbolic_parameters_get_random_values_and_are_reported():
    """Φ(x₀, x₁) = (a x₀, a x₁) is a morphism for every a; (a x₀, x₁) is not, and the error
    names the parameter value used."""
    a = sp.Symbol("a", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))
    good = sg.GroupoidMorphism(G, G, lambda g: (a * g.source[0], a * g.target[0]))
    assert good.parameters == [a]
    sg.check_morphism(good)
    bad = sg.GroupoidMorphism(G, G, lambda g: (a * g.source[0], g.target[0]))
    with pytest.raises(sg.MorphismError) as info:
        sg.check_morphism(bad, params={"a": 3.0})
    assert info.value.parameters == {"a": 3.0}
    assert "a=3" in str(info.value)


def test_map_errors_are_clear():
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    with pytest.raises(sg.ShapeError, match="3 coordinates, but an arrow"):
        sg.GroupoidMorphism(G, G, lambda g: (g.source[0], g.source[1], g.target[0]))
    with pytest.raises(sg.CallableError, match="the map raised ZeroDivisionError"):
        sg.GroupoidMorphism(G, G, lambda g: 1 / 0)
    with pytest.raises(TypeError, match="target must be a Groupoid"):
        sg.GroupoidMorphism(G, "R", lambda g: g.coords)


def test_system_morphism_checks_lagrangian_and_constraints():
    """Def. 4.2: L = L′∘Φ (here only because R₀ is a rotation: verified numerically) and
    φ = φ′∘Φ; a wrong reduced Lagrangian is rejected with the arrow."""
    P = _pair_so3()
    rb = systems.rigid_body()
    h, (I1, I2, I3) = rb.parameters[0], rb.parameters[1:]
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))

    def L(g):  # in the increment F = R₀ᵀR₁ of this presentation
        return -(Jd * g.matrix).trace() / h

    full = sg.DiscreteSystem(P, L, parameters=rb.parameters, name="rigid_body_pair")
    phi = _to_lie_group(P, rb.groupoid)
    checks = sg.check_system_morphism(phi, full, rb)
    assert [c.method for c in checks] == ["numeric"]
    wrong = sg.DiscreteSystem(rb.groupoid, lambda w: -(Jd * w.matrix.T).trace() / h + 1,
                              parameters=rb.parameters)
    with pytest.raises(sg.MorphismError, match="L = L′∘Φ fails at the arrow"):
        sg.check_system_morphism(phi, full, wrong)
