"""Every property × every groupoid: the properties each groupoid the library builds must
have (``_registry.every_groupoid`` runs a test over ``symgroupoid.groupoids.examples()``).

1. The axioms of seed 000 Definition 2.1 and the section curves of docs/conventions.md §1.
2. Left- and right-invariant vector fields commute, [X⃖, Y⃗] = 0 (seed 000 §2.1, eqs. (1)–(2):
   X⃖ generates right translations, Y⃗ left translations, and these commute by associativity).
3. The section flow composed on the expression graph is the one composed in SymPy.
4. Fibre charts: an arrow built from a base point and chart coordinates has that source and
   gives the chart coordinates back.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from _registry import EXAMPLES, every_groupoid, groupoid
from hypothesis import given, settings
from hypothesis import strategies as st

import symgroupoid as sg
from symgroupoid.ir import Graph, Program

SETTINGS = settings(max_examples=20, deadline=None)
seeds = st.integers(min_value=0, max_value=2**32 - 1)


def test_registry_holds_every_kind_of_groupoid() -> None:
    """The registry has a groupoid of every concrete kind the library exports."""
    kinds = {type(f()).__name__ for f in EXAMPLES.values()}
    assert kinds >= {"PairGroupoid", "SO2", "SO3", "SE2", "SE3", "TrivialisedPairGroupoid",
                     "ActionGroupoid", "ProductGroupoid", "TimeGroupoid", "AtiyahGroupoid",
                     "DefinedGroupoid"}


# --- 1. axioms ------------------------------------------------------------------------------

@every_groupoid()
def test_axioms(G: sg.Groupoid) -> None:
    """Seed 000 Definition 2.1 (α, β of products, associativity, identities, inverses) and
    the section curves of docs/conventions.md §1, on random composable arrows."""
    sg.check_axioms(G, samples=3)


# --- 2. [X⃖, Y⃗] = 0 -----------------------------------------------------------------------

@functools.cache
def _fields(G: sg.Groupoid):
    """The polynomial ring of G's arrow coordinates and its left/right fields, or None where
    a field's components are not polynomials (the exact test needs a ring)."""
    a = sp.symbols(f"a0:{G.arrow_dim}")
    R, *_ = sp.ring(a, sp.QQ)
    try:
        def to_ring(fields):
            return [[R.from_expr(sp.sympify(c)) for c in v] for v in fields]

        return R, to_ring(G.left_field(a)), to_ring(G.right_field(a))
    except (ValueError, sp.polys.polyerrors.PolynomialError):
        return None


#: the groupoids whose invariant fields are not polynomials in the arrow coordinates (the
#: exact test needs a ring).  Named rather than found when the tests are collected: finding
#: them derives the fields of every groupoid (30 s in each test process, most of it on these
#: two and on the costly ones below); the slow test
#: ``test_the_groupoids_without_polynomial_fields_are_those_named`` checks the list.
NON_POLYNOMIAL_FIELDS = ("atiyah (R2 x SO3)2/SO3 right twisted",
                         "atiyah (SE2 x R)2/SE2 beanie")
#: the exact test's ring grows with the arrow coordinates: beyond this it is not run
MAX_FIELD_DIM = 20


def _small(G: sg.Groupoid) -> bool:
    return G.arrow_dim <= MAX_FIELD_DIM


def _apply(field: list, f):
    """The derivative of f along the vector field with components ``field``."""
    gens = f.ring.gens
    return sum((f.diff(x) * v for x, v in zip(gens, field) if v), f.ring.zero)


def _random_function(R, rng: np.random.Generator):
    """A random polynomial test function: a linear form plus four monomials of degree 2–4 in
    randomly chosen coordinates (so first and mixed second derivatives both enter)."""
    a = R.gens
    f = sum((int(w) * x for w, x in zip(rng.integers(-3, 4, size=len(a)), a)), R.zero)
    for _ in range(4):
        coeff = sp.QQ(int(rng.integers(-9, 10)), int(rng.integers(1, 5)))
        idx = rng.choice(len(a), size=3)
        f += coeff * a[idx[0]] * a[idx[1]] ** int(rng.integers(0, 2)) * a[idx[2]] ** 2
    return f


# costly in exact arithmetic (3–8 s each); their families are covered by the others
COSTLY_FIELDS = ("SE3 exp", "pair SO3", "pair SE2 x SO2", "increments SO3 cayley",
                 "increments SO3 exp", "increments SE2 exp", "increments SE2 cayley",
                 "product SE2 x SO2 x pair R", "atiyah (R2 x SO3)2/SO3 left")


@every_groupoid(where=_small, slow=COSTLY_FIELDS, exclude=NON_POLYNOMIAL_FIELDS)
@SETTINGS
@given(seed=seeds)
def test_left_and_right_invariant_fields_commute(G: sg.Groupoid, seed: int) -> None:
    """Seed 000 eqs. (1)–(2): X⃖_i[Y⃗_j[f]](g) = Y⃗_j[X⃖_i[f]](g) for all basis sections i, j,
    a random polynomial f and a random arrow g — exactly, in rational arithmetic."""
    rng = np.random.default_rng(seed)
    fields = _fields(G)
    assert fields is not None, f"{G}: fields not polynomial; name it in NON_POLYNOMIAL_FIELDS"
    R, left, right = fields
    f = _random_function(R, rng)
    point = [sp.QQ.convert(sp.Rational(float(v))) for v in G.random_arrow(rng)]
    for i in range(G.rank):
        for j in range(G.rank):
            lr = _apply(left[i], _apply(right[j], f))
            rl = _apply(right[j], _apply(left[i], f))
            assert lr(*point) == rl(*point), (i, j)


@pytest.mark.slow  # derives the fields of every registered groupoid (30 s)
def test_the_groupoids_without_polynomial_fields_are_those_named() -> None:
    """NON_POLYNOMIAL_FIELDS, which the commutation test leaves out, is exactly the list of
    the registry's groupoids (up to MAX_FIELD_DIM arrow coordinates) whose fields are not
    polynomials: the test above leaves out none it could run."""
    found = [n for n in sorted(EXAMPLES)
             if _small(groupoid(n)) and _fields(groupoid(n)) is None]
    assert found == sorted(NON_POLYNOMIAL_FIELDS)


@SETTINGS
@given(seed=seeds)
def test_left_fields_do_not_commute_on_so3(seed: int) -> None:
    """Control for the property above: two *left*-invariant fields on SO(3) do not commute —
    [E⃖₁, E⃖₂] = E⃖₃ for the so(3) basis of seed 000 §6.2 — so the check can detect a
    non-commuting pair."""
    rng = np.random.default_rng(seed)
    R, left, _ = _fields(groupoid("SO3 cayley"))
    f = _random_function(R, rng)
    bracket = _apply(left[0], _apply(left[1], f)) - _apply(left[1], _apply(left[0], f))
    assert bracket == _apply(left[2], f)
    assert bracket != 0


# --- 3. the section flow on the graph ------------------------------------------------------

@every_groupoid()
def test_section_flow_on_the_graph_is_the_section_flow(G: sg.Groupoid) -> None:
    """``section_flow_nodes`` (the flow composed on the expression graph) evaluates to
    ``section_flow`` (composed in SymPy) at random arrows and chart vectors."""
    a = tuple(sp.Dummy(f"a{i}", real=True) for i in range(G.arrow_dim))
    d = tuple(sp.Dummy(f"d{i}", real=True) for i in range(G.rank))
    g = Graph()
    nodes = {x: g.input(x) for x in (*a, *d)}
    flow = G.section_flow_nodes(g, [nodes[x] for x in a], [nodes[x] for x in d])
    f = Program(g, {"a": list(a), "d": list(d)}, {"flow": flow}).numpy_function(
        ["flow"], ["a", "d"])
    rng = np.random.default_rng(3)
    for _ in range(3):
        arrow = G.random_arrow(rng)
        delta = rng.uniform(-0.3, 0.3, G.rank)
        target = G.target(arrow)
        expected = [float(sp.N(c)) for c in G.section_flow(target, [sp.Float(v) for v in delta])]
        np.testing.assert_allclose(f(np.array(arrow), delta)[0], expected, rtol=1e-12,
                                   atol=1e-12)


# --- 4. fibre charts -----------------------------------------------------------------------

@every_groupoid(slow=("SE3 exp", "increments SE3 exp"))  # 8–10 s: symbolic inverse
def test_fibre_chart_round_trip(G: sg.Groupoid) -> None:
    """The arrow of base point q and chart coordinates x has source q, its fibre variables
    are ``numeric_fibre_chart(x, q)``, and ``fibre_chart_inverse`` gives x back."""
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = G.random_base_point(rng)
        x = np.asarray(G.random_chart(rng, 0.4), float)
        a = G.numeric_fibre_arrow(q, x)
        np.testing.assert_allclose(np.asarray(G.source(a), float), q, atol=1e-13)
        f = np.asarray(G.fibre_of(a), float)
        np.testing.assert_allclose(G.numeric_fibre_chart(x, q), f, atol=1e-13)
        back = np.asarray(G.fibre_chart_inverse(list(f), q), float)
        np.testing.assert_allclose(back, x, atol=1e-12)


@pytest.mark.parametrize("name", ["SO3 cayley", "pair R"])
def test_registry_builds_fresh_groupoids(name: str) -> None:
    assert EXAMPLES[name]() is not EXAMPLES[name]()


# --- 5. the numerics an evaluator asks a groupoid ---------------------------------------------

@every_groupoid(slow=("SE3 exp", "increments SE3 exp"))
def test_geodesic_runs_from_the_identity_to_the_arrow(G: sg.Groupoid) -> None:
    """``geodesic(total, s)``: P(0) = ε(α(total)), P(1) = total, every P(s) in the α-fibre of
    α(total) (its source is α(total))."""
    rng = np.random.default_rng(6)
    total = np.asarray(G.random_arrow(rng), float)
    s = np.linspace(0.0, 1.0, 5)
    P = G.geodesic(total, s)
    q = np.asarray(G.source(total), float)
    assert P.shape == (len(s), G.arrow_dim)
    np.testing.assert_allclose(P[0], np.asarray(G.identity(tuple(q)), float), atol=1e-12)
    np.testing.assert_allclose(P[-1], total, atol=1e-12)
    for row in P:
        np.testing.assert_allclose(np.asarray(G.source(row), float), q, atol=1e-12)


@every_groupoid(where=lambda G: G.is_lie_group)
def test_log_and_exp_are_inverse(G: sg.MatrixLieGroup) -> None:
    """``exp_rows(log_coordinates(M))`` is M, on random elements and (SO(3), SE(3)) at a
    half-turn, where the Cayley chart is not defined."""
    rng = np.random.default_rng(7)
    arrows = [np.asarray(G.random_arrow(rng), float) for _ in range(3)]
    if G.n - G.affine == 3:  # SO(3), SE(3): a half-turn about the first axis
        half = np.diag([1.0, -1.0, -1.0] + [1.0] * (G.n - 3))
        arrows.append(np.array([half[i, j] for i, j in G.free_entries]))
    for a in arrows:
        x = G.log_coordinates(G.numeric_matrix(a))
        assert x is not None and x.shape == (G.rank,)
        np.testing.assert_allclose(G.exp_rows(x[None, :])[0], a, atol=1e-12)


def _has_configurations(G: sg.Groupoid) -> bool:
    return G.is_lie_group or (isinstance(G, sg.PairGroupoid) and G.pair_coordinates() != [])


@every_groupoid(where=_has_configurations)
def test_configurations_from_arrows(G: sg.Groupoid) -> None:
    """c_{k+1} = c_k·g_k: the arrow between consecutive configurations is g_k."""
    rng = np.random.default_rng(8)
    a = G.random_arrow(rng)
    arrows = [a]
    for _ in range(3):
        arrows.append(G.random_arrow(rng, G.target(arrows[-1])))
    arrows = np.array(arrows, float)
    start = G.numeric_matrix(G.random_arrow(rng)) if G.is_lie_group else tuple(G.source(a))
    configurations = G.configurations_from(start, arrows)
    assert len(configurations) == len(arrows) + 1
    for c0, c1, g in zip(configurations, configurations[1:], arrows):
        np.testing.assert_allclose(np.asarray(G.arrow_between(c0, c1), float), g, atol=1e-12)


@every_groupoid()
def test_pair_coordinates_sit_at_source_and_target(G: sg.Groupoid) -> None:
    """At an identity arrow every pair coordinate has equal source and target values, and
    at a random arrow they are the values of the source and the target points."""
    coords = G.pair_coordinates()
    assert len({c.name for c in coords}) == len(coords)
    rng = np.random.default_rng(9)
    q = G.random_base_point(rng)
    identity = np.asarray(G.identity(tuple(q)), float)
    for c in coords:
        assert identity[c.source] == identity[c.target]
    a = np.asarray(G.random_arrow(rng), float)
    sources, targets = set(np.asarray(G.source(a), float)), set(np.asarray(G.target(a), float))
    for c in coords:
        assert a[c.source] in sources and a[c.target] in targets


@every_groupoid()
def test_the_base_groups_are_groups_of_the_arrows_that_the_base_holds(G: sg.Groupoid) -> None:
    """``base_groups`` (which decides where a Noether quantity without stages is checked
    at random arrows alone) names groups of the arrow's named coordinates that fit in a
    base point: none for a Lie group (its base is a point), the group itself for the pair
    groupoid of a group."""
    base, named = G.base_groups(), G.named_groups()
    assert all(name in named and named[name] == group for name, group in base.items())
    assert sum(group.arrow_dim for group in base.values()) <= G.base_dim
    if isinstance(G, sg.PairGroupoid):
        assert base == named


@every_groupoid()
def test_random_arrows_lie_on_their_groups_and_scaled_ones_do_not(G: sg.Groupoid) -> None:
    """``off_group_rows`` (what the reduced system's ``project`` checks its states with)
    passes random arrows of every groupoid, and flags them with every coordinate doubled
    where the arrow holds a part of a matrix group (doubled, a rotation is not one)."""
    rng = np.random.default_rng(7)
    arrows = np.array([G.random_arrow(rng) for _ in range(4)], float)
    assert list(G.off_group_rows(arrows, sg.groupoids.GROUP_TOLERANCE)) == []
    position = set(G.named_arrow(0))
    held = any(e in position for name in G.named_groups()
               for o in (-1, 0, 1)
               for value in [G.symbols_by_name(o).get(name)] if hasattr(value, "shape")
               for e in value)
    flagged = G.off_group_rows(2 * arrows, sg.groupoids.GROUP_TOLERANCE)
    assert list(flagged) == ([0, 1, 2, 3] if held else []), (G.name, flagged)
    for bad, tolerance in [(arrows[:, 1:], 1e-9), ("rows", 1e-9), (arrows, -1.0)]:
        with pytest.raises(sg.ShapeError):
            G.off_group_rows(bad, tolerance)


def test_pair_coordinates_are_found_through_products() -> None:
    names = {n: [c.name for c in groupoid(n).pair_coordinates()]
             for n in ("pair R3", "product SE2 x SO2 x pair R",
                       "product pair R2 x SO3 (plate-ball)", "SO3 cayley", "pair SO3")}
    assert names == {"pair R3": ["x", "y", "z"], "product SE2 x SO2 x pair R": ["q"],
                     "product pair R2 x SO3 (plate-ball)": ["x", "y"], "SO3 cayley": [],
                     "pair SO3": []}
    G = groupoid("product SE2 x SO2 x pair R")
    (c,) = G.pair_coordinates()
    assert (c.source, c.target) == (G.arrow_dim - 2, G.arrow_dim - 1)
