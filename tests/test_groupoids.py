"""Groupoid structure (the axioms of every groupoid: test_groupoid_properties.py): axiom
failures reported with the failing arrows, and a user-defined pair groupoid
giving the same discrete Euler–Lagrange equations as the built-in one (seed 000 §2.2)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import sympy as sp
from _registry import EXAMPLES
from _systems import heavy_top_groupoid

import symgroupoid as sg


def line_groupoid(check: bool = True, **overrides) -> sg.DefinedGroupoid:
    """The pair groupoid of R written by hand (seed 001 §2.1.1), optionally with a map replaced
    (``check=False`` skips the construction-time axiom check)."""
    maps: dict[str, Callable] = dict(
        source=lambda a: (a[0],), target=lambda a: (a[1],),
        multiply=lambda a, b: (a[0], b[1]), identity=lambda q: (q[0], q[0]),
        inverse=lambda a: (a[1], a[0]), sections=lambda q, t: [(q[0], q[0] + t)])
    maps.update(overrides)
    return sg.DefinedGroupoid("line", base_names=["q"], fibre_names=["q"], **maps, check=check)


def test_product_flattens_and_counts() -> None:
    """A product of products is one product with the factors' dimensions added
    (plate-ball: R²×R²×SO(3) ⇉ R² has rank 2 + 3 = 5, seed 000 §6.2)."""
    G = sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("g")
    assert (G.rank, G.base_dim, G.arrow_dim) == (5, 2, 13)
    H = G * sg.SO2("r")
    assert len(H.factors) == 3 and H.rank == 6


# --- broken groupoids -------------------------------------------------------------------------

def labelled_groupoid(z_multiply: Callable = lambda z, w: z + w,
                      z_inverse: Callable = lambda z: -z,
                      check: bool = True) -> sg.DefinedGroupoid:
    """R × R × R ⇉ R: the pair groupoid of R times the group (R, +), arrows (q₀, q₁, z);
    the label's product and inverse can be replaced to break associativity or inverses."""
    return sg.DefinedGroupoid(
        "labelled", base_names=["q"], fibre_names=["q", "z"],
        source=lambda a: (a[0],), target=lambda a: (a[1],),
        multiply=lambda a, b: (a[0], b[1], z_multiply(a[2], b[2])),
        identity=lambda q: (q[0], q[0], 0), inverse=lambda a: (a[1], a[0], z_inverse(a[2])),
        sections=lambda q, t: [(q[0], q[0] + t, 0), (q[0], q[0], t)], check=check)


BROKEN: dict[str, Callable[..., sg.DefinedGroupoid]] = {
    "β(ab) = β(b)": lambda check=False: line_groupoid(
        multiply=lambda a, b: (a[0], b[1] + a[0] / 10), check=check),
    # z·w = z + w + z w² has 0 as unit but is not associative
    "associativity (ab)c = a(bc)": lambda check=False: labelled_groupoid(
        z_multiply=lambda z, w: z + w + z * w**2, check=check),
    # z⁻¹ = z: α, β of the inverse are right, a·a⁻¹ is not an identity
    "a·a⁻¹ = ε(α(a))": lambda check=False: labelled_groupoid(z_inverse=lambda z: z,
                                                            check=check),
    "α(a⁻¹) = β(a), β(a⁻¹) = α(a)": lambda check=False: line_groupoid(
        inverse=lambda a: (a[1], a[0] + 1), check=check),
    "section 0: h(0) = ε(q)": lambda check=False: line_groupoid(
        sections=lambda q, t: [(q[0], q[0] + t + 1)], check=check),
    "section 0: h(t) in the α-fibre of q": lambda check=False: line_groupoid(
        sections=lambda q, t: [(q[0] + t, q[0] + t)], check=check),
}


@pytest.mark.parametrize("axiom", sorted(BROKEN))
def test_broken_groupoid_reports_axiom_and_arrows(axiom: str) -> None:
    """A deliberately broken user groupoid fails check_axioms with an AxiomError that names the
    violated axiom (seed 000 Def. 2.1) and the arrows it fails for; re-evaluating the maps at
    the reported arrows reproduces the failure."""
    G = BROKEN[axiom]()
    with pytest.raises(sg.AxiomError, match=rf"^{G.name}: ") as info:
        sg.check_axioms(G)
    err = info.value
    assert err.axiom == axiom
    assert axiom in str(err)
    assert "fails for" in str(err) and "np.float64" not in str(err)
    shown = err.arrows
    for key, coords in shown.items():
        assert f"{key}=(" in str(err)
        assert all(isinstance(c, float) for c in coords)
    if axiom == "β(ab) = β(b)":
        a, b = shown["a"], shown["b"]
        assert G.target(a) == (b[0],)  # composable …
        assert not np.isclose(G.target(G.multiply(a, b))[0], G.target(b)[0])  # … yet fails
    if axiom.startswith("associativity"):
        a, b, c = shown["a"], shown["b"], shown["c"]
        lhs = G.multiply(G.multiply(a, b), c)
        rhs = G.multiply(a, G.multiply(b, c))
        assert not np.allclose(np.array(lhs, float), np.array(rhs, float), rtol=1e-9)
    if axiom == "a·a⁻¹ = ε(α(a))":
        a = shown["a"]
        assert not np.allclose(np.array(G.multiply(a, G.inverse(a)), float),
                               np.array(G.identity((a[0],)), float))
    if axiom.startswith("α(a⁻¹)"):
        a = shown["a"]
        assert G.target(G.inverse(a)) != (a[0],)


@pytest.mark.parametrize("axiom", sorted(BROKEN))
def test_broken_groupoid_is_rejected_at_construction(axiom: str) -> None:
    """DefinedGroupoid checks the axioms when it is constructed: each broken groupoid fails
    there with the same axiom (check=False is what lets the test above build it)."""
    with pytest.raises(sg.AxiomError, match=r"check=False skips this\)$") as info:
        BROKEN[axiom](check=True)
    assert info.value.axiom == axiom


def test_dependent_sections_are_reported() -> None:
    """Two section curves with parallel velocities are not a basis of AG
    (docs/conventions.md §1)."""
    G = sg.DefinedGroupoid(
        "plane", base_names=["x", "y"], fibre_names=["x", "y"],
        source=lambda a: (a[0], a[1]), target=lambda a: (a[2], a[3]),
        multiply=lambda a, b: (a[0], a[1], b[2], b[3]),
        identity=lambda q: (q[0], q[1], q[0], q[1]), inverse=lambda a: (a[2], a[3], a[0], a[1]),
        sections=lambda q, t: [(q[0], q[1], q[0] + t, q[1] + t),
                               (q[0], q[1], q[0] + 2 * t, q[1] + 2 * t)], check=False)
    with pytest.raises(sg.AxiomError, match="linearly independent fails for q=\\("):
        sg.check_axioms(G)


# --- a user-defined groupoid derives the same equations as the built-in one ----------------

def test_defined_line_equals_pair_groupoid() -> None:
    """Seed 000 §2.2: a pair groupoid written by hand as a DefinedGroupoid yields the same
    discrete Euler–Lagrange equation as PairGroupoid for an arbitrary L (Marsden–West)."""
    F = sp.Function("L_d")
    built_in = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")),
                                 lambda g: F(*g.coords)).euler_lagrange()
    by_hand = sg.DiscreteSystem(line_groupoid(), lambda g: F(*g.coords)).euler_lagrange()
    assert by_hand.knowns == built_in.knowns
    assert by_hand.unknowns == built_in.unknowns
    assert sp.expand(by_hand.residuals[0] - built_in.residuals[0]) == 0


def test_translation_groupoid_del() -> None:
    """docs/conventions.md §2 on the translation groupoid (p, s): X⃖ = ∂/∂s and
    X⃗[f](p, s) = −d/dt f(p + t, s − t), so the DEL read
    ∂L/∂s(g_k) + ∂L/∂p(g_{k+1}) − ∂L/∂s(g_{k+1}) = 0, with g_{k+1} = (p_k + s_k, s_{k+1})."""
    a, b = sp.symbols("a b", positive=True)

    def lagrangian(p, s):
        return a * p**2 * s + b * s**3 + sp.exp(p) * s**2

    step = sg.DiscreteSystem(EXAMPLES["defined translations"](), lambda g: lagrangian(*g.coords),
                             parameters=[a, b]).euler_lagrange()
    u, v = sp.symbols("u v")
    Luv = lagrangian(u, v)
    (pk, sk), (pk1, sk1) = step.arrows[0], step.arrows[1]
    assert sp.expand(pk1 - (pk + sk)) == 0  # g_{k+1} starts where g_k ends
    at_k, at_k1 = {u: pk, v: sk}, {u: pk1, v: sk1}
    expected = (Luv.diff(v).subs(at_k) + Luv.diff(u).subs(at_k1) - Luv.diff(v).subs(at_k1))
    assert sp.expand(step.residuals[0] - expected) == 0


# --- the invariant derivations of docs/conventions.md §1 -------------------------------------

def _curve_derivative(f: Callable, curve: Callable) -> sp.Expr:
    """d/dt f(curve(t)) at t = 0 for an undefined function f of the arrow coordinates."""
    t = sp.Symbol("t", real=True)
    return sp.diff(f(*curve(t)), t).subs(t, 0).doit()


def _matrix_cases() -> dict[str, sg.MatrixLieGroup]:
    return {"SO3": sg.SO3("g"), "SE2": sg.SE2("s"), "SO2": sg.SO2("r")}


@pytest.mark.parametrize("name", sorted(_matrix_cases()))
def test_lie_group_derivations_match_table(name: str) -> None:
    """docs/conventions.md §1 / seed 000 eqs. (1)–(2) on a Lie group: X⃖_E[f](g) = d/dt f(g(I + tE)),
    X⃗_E[f](g) = d/dt f((I + tE)g) (any curve with velocity E gives the same derivative), for f
    an undefined function of the matrix entries; via ``left_derivative``/``right_derivative``."""
    G = _matrix_cases()[name]
    F = sp.Function("f")
    a = G.named_arrow(0)
    g = G.matrix(a)
    left = sg.left_derivative(G, lambda arrow: F(*arrow.coords), a)
    right = sg.right_derivative(G, lambda arrow: F(*arrow.coords), a)
    for E, lv, rv in zip(G.basis_matrices(), left, right):
        E = sp.Matrix(E)
        exp_l = _curve_derivative(F, lambda t, E=E: G.entries(g * (sp.eye(G.n) + t * E)))
        exp_r = _curve_derivative(F, lambda t, E=E: G.entries((sp.eye(G.n) + t * E) * g))
        assert sp.expand(lv - exp_l) == 0
        assert sp.expand(rv - exp_r) == 0


def test_pair_and_time_derivations_match_table() -> None:
    """docs/conventions.md §1: on Q × Q, X⃖[f] = ∂f/∂q₁·v and X⃗[f] = −∂f/∂q₀·v; on R × R × G the
    time section adds ∂/∂t₁ (left) and −∂/∂t₀ (right)."""
    F = sp.Function("f")
    P = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    a = P.named_arrow(0)
    left = sg.left_derivative(P, F(*a), a)
    right = sg.right_derivative(P, F(*a), a)
    for j in range(2):
        assert sp.expand(left[j] - sp.diff(F(*a), a[2 + j])) == 0
        assert sp.expand(right[j] + sp.diff(F(*a), a[j])) == 0
    T = sg.TimeGroupoid(P)
    b = T.named_arrow(0)
    left_t = sg.left_derivative(T, F(*b), b)
    right_t = sg.right_derivative(T, F(*b), b)
    assert sp.expand(left_t[0] - sp.diff(F(*b), b[1])) == 0
    assert sp.expand(right_t[0] + sp.diff(F(*b), b[0])) == 0
    for j in range(2):
        assert sp.expand(left_t[1 + j] - sp.diff(F(*b), b[4 + j])) == 0
        assert sp.expand(right_t[1 + j] + sp.diff(F(*b), b[2 + j])) == 0


def test_action_groupoid_derivations_match_table() -> None:
    """docs/conventions.md §1, action groupoid with p·W = Wᵀp (heavy top, seed 002):
    X⃖[f](p, W) = d/dt f(p, W(I + tE)), X⃗[f](p, W) = −d/dt f((I + tE)ᵀp, (I − tE)W)."""
    G = heavy_top_groupoid()
    F = sp.Function("f")
    a = G.named_arrow(0)
    p, W = sp.Matrix(a[:3]), sp.Matrix(3, 3, a[3:])
    left = sg.left_derivative(G, F(*a), a)
    right = sg.right_derivative(G, F(*a), a)
    for E, lv, rv in zip(sg.SO3.basis_matrices(), left, right):
        E = sp.Matrix(E)
        exp_l = _curve_derivative(F, lambda t, E=E: (*p, *(W * (sp.eye(3) + t * E))))
        exp_r = -_curve_derivative(
            F, lambda t, E=E: (*((sp.eye(3) + t * E).T * p), *((sp.eye(3) - t * E) * W)))
        assert sp.expand(lv - exp_l) == 0
        assert sp.expand(rv - exp_r) == 0
