"""The structure maps a matrix group derives once per class and substitutes for every
element (``translated_retraction`` q·τ(x), ``increment_coordinates`` τ⁻¹(q⁻¹p)) equal the
direct symbolic products; the numeric retraction and the pair groupoid's numeric fibre
arrow equal SymPy's evaluation of the symbolic maps."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

# white-box: the subject is how the matrix groups' closed forms are made — the templates
# derived once per class against the direct products (groupoids/_matrix_templates.py), the
# stored file and its builder (_closed_forms.py, _closed_forms_build.py), and pair groupoids
# of products of group manifolds built directly (_manifold.py); none of it is public
from symgroupoid.groupoids import Groupoid, _closed_forms, _closed_forms_build
from symgroupoid.groupoids._closed_forms_build import _PlaceholderPrinter
from symgroupoid.groupoids._manifold import GroupManifold, ProductManifold
from symgroupoid.groupoids._matrix_templates import (
    _builtin,
    _cayley_template,
    _direct_increment_coordinates,
    _direct_translated_retraction,
    _dtau_dummies,
    _simplify_matrix,
    _stored_form,
)

CASES = [(sg.SO2, "cayley"), (sg.SO2, "exp"), (sg.SO3, "cayley"), (sg.SO3, "exp"),
         (sg.SE2, "cayley"), (sg.SE2, "exp"), (sg.SE3, "cayley"), (sg.SE3, "exp")]


def _at(exprs, values: dict) -> np.ndarray:
    return np.array([complex(sp.N(sp.sympify(e).xreplace(values), 30)) for e in exprs])


@pytest.mark.parametrize("group,retraction", CASES)
def test_translated_retraction_is_the_product(group, retraction):
    """q·τ(x) from the class template equals the product computed for this element, at a
    random point (two elements of one class share the template but keep their symbols)."""
    G, H = group("A", retraction=retraction), group("B", retraction=retraction)
    rng = np.random.default_rng(3)
    for K in (G, H):
        q = sp.symbols(f"{K.name}q0:{K.arrow_dim}", real=True)
        x = sp.symbols(f"{K.name}x0:{K.rank}", real=True)
        got = K.translated_retraction(q, x)
        assert set().union(*(sp.sympify(e).free_symbols for e in got)) <= set(q) | set(x)
        want = _direct_translated_retraction(K, (*q, *x))
        values = {s: sp.Float(v, 30) for s, v in zip((*q, *x),
                                                      rng.uniform(-0.7, 0.7, len(q) + len(x)))}
        assert np.allclose(_at(got, values), _at(want, values), rtol=0, atol=1e-20)


@pytest.mark.parametrize("group,retraction", CASES)
def test_increment_coordinates_invert_the_chart(group, retraction):
    """τ⁻¹(q⁻¹p) at p = q·τ(y) returns y (q, p in the group), and equals the direct
    computation symbolically evaluated."""
    G = group("g", retraction=retraction)
    rng = np.random.default_rng(5)
    q = G.numeric_fibre_chart(rng.uniform(-0.5, 0.5, G.rank))
    y = rng.uniform(-0.5, 0.5, G.rank)
    p = G.numeric_matrix(q) @ G.numeric_tau(y)
    p = [p[i, j] for i, j in G._free]
    qs = sp.symbols(f"q0:{G.arrow_dim}", real=True)
    ps = sp.symbols(f"p0:{G.arrow_dim}", real=True)
    got = G.increment_coordinates(qs, ps)
    values = {**{s: sp.Float(v, 30) for s, v in zip(qs, q)},
              **{s: sp.Float(v, 30) for s, v in zip(ps, p)}}
    assert np.allclose(_at(got, values).real, y, rtol=0, atol=1e-12)
    want = _direct_increment_coordinates(G, (*qs, *ps))
    assert np.allclose(_at(got, values), _at(want, values), rtol=0, atol=1e-20)


@pytest.mark.parametrize("group,retraction", CASES)
def test_numeric_tau_is_the_symbolic_retraction(group, retraction):
    G = group("g", retraction=retraction)
    x = np.random.default_rng(7).uniform(-0.8, 0.8, G.rank)
    want = np.array(G.tau([sp.Float(v, 30) for v in x]).evalf(30).tolist(), dtype=float)
    assert np.allclose(G.numeric_tau(x), want, rtol=0, atol=1e-15)
    assert np.allclose(G.numeric_tau(np.zeros(G.rank)), np.eye(G.n), rtol=0, atol=0)


def test_pair_groupoid_numeric_fibre_arrow_is_the_symbolic_one():
    """The pair groupoid of SO(3) × SE(2) × R draws its arrows (q, q·τ(x)) numerically; the
    generic route (the symbolic fibre chart, compiled) gives the same arrow."""
    P = sg.PairGroupoid(ProductManifold(GroupManifold(sg.SO3("R")),
                                        GroupManifold(sg.SE2("g", retraction="exp")),
                                        sg.EuclideanSpace("z")))
    rng = np.random.default_rng(11)
    q = P.random_base_point(rng)
    x = P.random_chart(rng)
    got = P.numeric_fibre_arrow(q, x)
    want = Groupoid.numeric_fibre_arrow(P, q, x)
    assert len(got) == len(want) == 2 * P.base_dim
    assert np.allclose(got, want, rtol=0, atol=1e-14)
    assert np.allclose(got[:P.base_dim], q, rtol=0, atol=0)


def test_matrix_form_keeps_the_structured_product():
    """In matrix form (coordinates: the entries of one MatrixSymbol) the chart is the
    structured product R·τ(x), not the entrywise template."""
    G = sg.SO3("R")
    R = sp.MatrixSymbol("R", 3, 3)
    q = tuple(R[i, j] for i in range(3) for j in range(3))
    x = sp.symbols("x0:3", real=True)
    got = G.translated_retraction(q, x)
    assert got == _direct_translated_retraction(G, (*q, *x))


def _pair_groupoids():
    return [
        sg.PairGroupoid(sg.EuclideanSpace("x y")),
        sg.PairGroupoid(sg.SO3("R")),
        sg.PairGroupoid(ProductManifold(GroupManifold(sg.SE3("g")),
                                        GroupManifold(sg.SO2("r", retraction="exp")),
                                        sg.EuclideanSpace("z"))),
        sg.PairGroupoid(ProductManifold(GroupManifold(sg.SE2("g", retraction="exp")),
                                        GroupManifold(sg.SO3("R", retraction="exp")))),
    ]


@pytest.mark.parametrize("index", range(4))
@pytest.mark.parametrize("side", ["left", "right"])
def test_pair_groupoid_fields_in_closed_form(index, side):
    """The pair groupoid's closed-form fields (the space's tangent basis q·E_b padded with
    zeros) equal the generic derivation d/dt m(a, h_b(t)) (left), −d/dt m(h_b(t)⁻¹, a)
    (right) at t = 0 on the graph, at a random arrow."""
    _check_closed_form_fields(_pair_groupoids()[index], side, seed=13)


def _check_closed_form_fields(G, side: str, seed: int) -> None:
    """G's own ``field_nodes`` against the generic derivation of the base class on the
    graph, at a random arrow (30 digits)."""
    from symgroupoid.ir import Graph, to_sympy

    g = Graph()
    symbols = sp.symbols(f"a0:{G.arrow_dim}", real=True)
    coords = [g.input(s) for s in symbols]
    closed = G.field_nodes(g, side, coords)
    generic = Groupoid.field_nodes(G, g, side, coords)
    assert len(closed) == len(generic) == G.rank
    arrow = G.random_arrow(np.random.default_rng(seed))
    values = {s: sp.Float(v, 30) for s, v in zip(symbols, arrow)}
    for a, b in zip(closed, generic):
        assert len(a) == len(b) == G.arrow_dim
        assert np.allclose(_at(to_sympy(g, a), values), _at(to_sympy(g, b), values),
                           rtol=0, atol=1e-20)


def _closed_form_groupoids():
    """Groupoids whose fields have a closed form of their own: increment coordinates, and
    products (each factor's fields, zero elsewhere)."""
    inc = sg.TrivialisedPairGroupoid
    return [
        inc(sg.SO3("R")),
        inc(sg.SO2("r", retraction="exp")),
        inc(sg.SO3("R1")) * inc(sg.SO3("R2", retraction="exp")),
        sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("W"),
        sg.SE2("g") * sg.PairGroupoid(sg.SO3("R")),
        inc(sg.SE3("g")),
        inc(sg.SE2("g", retraction="exp")),
    ]


@pytest.mark.parametrize("index", range(7))
@pytest.mark.parametrize("side", ["left", "right"])
def test_increment_and_product_fields_in_closed_form(index, side):
    """Their closed-form fields equal the generic derivation on the graph at a random
    arrow, as the pair groupoid's do."""
    _check_closed_form_fields(_closed_form_groupoids()[index], side, seed=17)


# -- stored templates (groupoids/_closed_forms.py) ----------------------------------------------

def test_stored_templates_are_the_derived_trees_and_the_file_is_current(monkeypatch):
    """Every template a new process reads from groupoids/_closed_forms.py is, node for node,
    the tree its derivation gives (so the equations, the LaTeX and the C are those of the
    derivation), and the file is what the builder writes today (``make closed-forms``)."""
    derived = _closed_forms_build.derived_templates()
    # the builder writes these same derivations (not derived a second time: 12 s)
    monkeypatch.setattr(_closed_forms_build, "derived_templates", lambda: derived)
    assert sorted(key for key, _, _ in derived) == sorted(_closed_forms.FORMS)
    for key, template, placeholders in derived:
        stored = _stored_form(key, placeholders)
        assert type(stored) is type(template), key
        assert stored == template and sp.srepr(stored) == sp.srepr(template), key
        if isinstance(template, sp.MatrixBase):
            pairs = zip(stored, template)
        else:
            pairs = zip(stored, template, strict=True)
        assert all(a.args == b.args and a.func == b.func for a, b in pairs), key
    assert _closed_forms_build.source() == Path(_closed_forms.__file__).read_text("utf-8")


def test_the_stored_file_is_what_a_derivation_without_it_writes():
    """In a process where no stored template is ever read (every one derived, the Cayley map
    under q·τ(x) and τ⁻¹(q⁻¹p) included), the builder writes the stored file exactly."""
    import subprocess
    import sys

    probe = ("import sys; from symgroupoid.groupoids import _matrix_templates as mg; "
             "mg._stored_form = lambda key, placeholders: None; "
             "from symgroupoid.groupoids import _closed_forms_build as b; "
             "sys.stdout.write(b.source())")
    run = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, cwd=Path(__file__).resolve().parents[1])
    assert run.stdout == Path(_closed_forms.__file__).read_text("utf-8")


def test_stored_templates_are_used_only_for_the_groups_they_were_derived_for():
    """A subclass (here one with another basis order) derives its own templates."""
    class Reordered(sg.SO3):
        @classmethod
        def _basis(cls):
            return list(reversed(sg.SO3._basis()))

    assert _builtin(sg.SO3) and not _builtin(Reordered)
    x = sp.symbols("x0:3", real=True)
    cay = Reordered("R").cayley(x)
    want = sg.SO3("S").cayley(list(reversed(x)))
    assert all(sp.simplify(a - b) == 0 for a, b in zip(cay, want))
    assert _cayley_template(Reordered) != _cayley_template(sg.SO3)


def test_a_stored_template_that_names_a_foreign_symbol_is_refused():
    a, b = sp.Dummy("a"), sp.Dummy("b")
    assert _PlaceholderPrinter([a]).doprint(a + sp.Symbol("c")) in (
        "Add(P[0], Symbol('c'))", "Add(Symbol('c'), P[0])")
    with pytest.raises(ValueError, match="foreign placeholder"):
        _PlaceholderPrinter([a]).doprint(a + b)


def test_so3_cayley_closed_form_is_the_solved_one() -> None:
    """SO(3)'s Cayley template comes from the closed form I + 4/(4 + |x|²)(x̂ + x̂²/2): the
    same canonical expressions (srepr) as solving (I − x̂/2) M = I + x̂/2 and simplifying."""
    from symgroupoid.groupoids import SO3

    X = SO3.hat(_dtau_dummies(SO3))
    solved = _simplify_matrix((sp.eye(3) - X / 2).LUsolve(sp.eye(3) + X / 2))
    assert [sp.srepr(e) for e in _cayley_template(SO3)] == [sp.srepr(e) for e in solved]
