"""User groupoids are checked: ``DefinedGroupoid`` runs ``check_axioms`` when constructed
(``check=False`` opts out), ``check_axioms`` handles structure maps with symbolic parameters
(random values respecting their assumptions, reported on failure, or a ``parameters``
mapping), and coordinate names that collide with the multipliers or with each other are
rejected (seed 000 Def. 2.1; docs/conventions.md §1)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

k = sp.Symbol("k", positive=True)
w = sp.Symbol("w", negative=True)


def line(check: bool = True, **overrides: Callable) -> sg.DefinedGroupoid:
    """The pair groupoid of R by hand, a map optionally replaced."""
    maps: dict = dict(source=lambda a: (a[0],), target=lambda a: (a[1],),
                      multiply=lambda a, b: (a[0], b[1]), identity=lambda q: (q[0], q[0]),
                      inverse=lambda a: (a[1], a[0]), sections=lambda q, t: [(q[0], q[0] + t)])
    maps.update(overrides)
    return sg.DefinedGroupoid("line", base_names=["q"], fibre_names=["q"], check=check, **maps)


def scaled(scale: sp.Expr, inverse_scale: sp.Expr | None = None, check: bool = True,
           name: str = "scaled") -> sg.DefinedGroupoid:
    """R × R ⇉ R, arrows (p, s) with β(p, s) = p + c·s (an action groupoid of (R, +)); a
    wrong ``inverse_scale`` breaks α(a⁻¹) = β(a) unless it equals ``scale``."""
    c_inv = scale if inverse_scale is None else inverse_scale
    return sg.DefinedGroupoid(
        name, base_names=["p"], fibre_names=["s"], source_offset=0, check=check,
        source=lambda a: (a[0],), target=lambda a: (a[0] + scale * a[1],),
        multiply=lambda a, b: (a[0], a[1] + b[1]), identity=lambda q: (q[0], 0),
        inverse=lambda a: (a[0] + c_inv * a[1], -a[1]), sections=lambda q, t: [(q[0], t)])


# --- checked at construction ------------------------------------------------------------------

def test_wrong_multiplication_is_rejected_at_construction() -> None:
    """m(a, b) = (a₀, 2b₁ − a₁) has β(ab) ≠ β(b): it used to be accepted and to simulate
    q = −35310 where the answer is −0.549.  Now the constructor names the axiom, the arrows
    and how to opt out."""
    with pytest.raises(sg.AxiomError,
                       match=r"^line: β\(ab\) = β\(b\) fails for a=\(.*\), b=\(.*\) "
                             r"\(DefinedGroupoid checks the groupoid axioms when it is "
                             r"constructed; check=False skips this\)$") as info:
        line(multiply=lambda a, b: (a[0], 2 * b[1] - a[1]))
    assert info.value.axiom == "β(ab) = β(b)"


def test_check_false_opts_out() -> None:
    """With check=False the groupoid is built; check_axioms still finds the fault."""
    G = line(multiply=lambda a, b: (a[0], 2 * b[1] - a[1]), check=False)
    with pytest.raises(sg.AxiomError, match=r"β\(ab\) = β\(b\) fails"):
        sg.check_axioms(G)


@pytest.mark.parametrize("sections, axiom", [
    (lambda q, t: [(q[0], q[0] + t + 1)], "section 0: h(0) = ε(q)"),
    (lambda q, t: [(q[0] + 1, q[0] + 1 + t)], "section 0: h(0) = ε(q)"),
])
def test_section_curve_not_through_the_identity(sections, axiom: str) -> None:
    """A section curve must start at ε(q) in the α-fibre of q (docs/conventions.md §1)."""
    with pytest.raises(sg.AxiomError, match=r"^line: " + axiom.replace("(", r"\(").replace(
            ")", r"\)")) as info:
        line(sections=sections)
    assert info.value.axiom == axiom


def test_section_curve_leaving_the_fibre() -> None:
    """h(0) = ε(q) but h(t) leaves α⁻¹(q)."""
    with pytest.raises(sg.AxiomError, match=r"section 0: h\(t\) in the α-fibre of q"):
        line(sections=lambda q, t: [(q[0] + t**2, q[0] + t)])


def test_valid_groupoid_constructs_quickly() -> None:
    """The construction-time check is cheap (a few random arrows)."""
    start = time.perf_counter()
    line()
    assert time.perf_counter() - start < 2.0


def test_checked_groupoid_simulates_like_the_pair_groupoid() -> None:
    """The hand-written pair groupoid of R (accepted by the check) steps a harmonic oscillator
    exactly like PairGroupoid (Marsden–West)."""
    h = sp.Symbol("h", positive=True)

    def L(g):
        q0, q1 = g.coords
        return h / 2 * ((q1 - q0) / h) ** 2 - h * (q0**2 + q1**2) / 4

    runs = []
    for G in (line(), sg.PairGroupoid(sg.EuclideanSpace("q"))):
        sim = sg.DiscreteSystem(G, L, parameters=[h]).euler_lagrange().compile(backend="numpy")
        traj = sim.simulate({"q": (1.0, 0.99)}, steps=30, params={"h": 0.1})
        runs.append(np.asarray(traj["q"]))
    assert np.allclose(runs[0], runs[1], rtol=0, atol=1e-12)
    assert np.ptp(runs[0]) > 1.5  # it oscillates


# --- symbolic parameters in the structure maps --------------------------------------------------

def test_parametrised_groupoid_is_checked_with_random_values() -> None:
    """β(p, s) = p + k s: k gets a random positive value and the axioms hold for it."""
    G = scaled(k)
    sg.check_axioms(G)
    sg.check_axioms(G, parameters={k: 3.0})
    sg.check_axioms(G, parameters={"k": 0.25})


def test_parametrised_groupoid_failure_reports_the_values() -> None:
    """α(a⁻¹) = β(a) fails for i(p, s) = (p + s, −s) unless k = 1; the message shows the k
    used and that it was random; with parameters={k: 1} the axioms hold."""
    with pytest.raises(sg.AxiomError,
                       match=r"^bad: α\(a⁻¹\) = β\(a\), β\(a⁻¹\) = α\(a\) fails for a=\(.*\) "
                             r"\(with parameter values k=\d\.\d+; k chosen at random — pass "
                             r"parameters=\{\.\.\.\} to check_axioms to choose them\)") as info:
        scaled(k, inverse_scale=1, name="bad")
    assert set(info.value.parameters) == {"k"} and 0.5 <= info.value.parameters["k"] <= 2.0
    G = scaled(k, inverse_scale=1, check=False, name="bad")
    sg.check_axioms(G, parameters={k: 1})
    with pytest.raises(sg.AxiomError, match=r"\(with parameter values k=3\)$"):
        sg.check_axioms(G, parameters={"k": 3})


def test_random_parameter_values_respect_assumptions() -> None:
    """A negative symbol gets a negative value."""
    with pytest.raises(sg.AxiomError) as info:
        scaled(w, inverse_scale=1, name="neg")
    assert -2.0 <= info.value.parameters["w"] <= -0.5


def test_parameters_mapping_is_validated() -> None:
    G = scaled(k, check=False)
    with pytest.raises(sg.ShapeError,
                       match=r"scaled: the value of parameter k must be a real number"):
        sg.check_axioms(G, parameters={k: "big"})
    with pytest.raises(sg.ShapeError, match=r"parameters must map SymPy symbols"):
        sg.check_axioms(G, parameters={3: 1.0})


def test_parametrised_groupoid_derives() -> None:
    """The parameter k flows into the equations: declare it like any other parameter."""
    h = sp.Symbol("h", positive=True)
    G = scaled(k)
    step = sg.DiscreteSystem(G, lambda g: g.coords[1] ** 2 / (2 * h) + G.target(g.coords)[0],
                             parameters=[h, k]).euler_lagrange()
    assert k in set().union(*(r.free_symbols for r in step.residuals))


# --- coordinate names --------------------------------------------------------------------------

@pytest.mark.parametrize("where", ["base_names", "fibre_names"])
@pytest.mark.parametrize("name", ["lambda", "λ", "multipliers"])
def test_reserved_coordinate_names(where: str, name: str) -> None:
    """"lambda", "λ" and "multipliers" name the multipliers in step.symbol."""
    names = {"base_names": ["q"], "fibre_names": ["q"], where: [name]}
    with pytest.raises(sg.CoordinateNameError,
                       match=rf"^hand: the {where.split('_')[0]} coordinate name '{name}' is "
                             r"reserved for the multipliers"):
        sg.DefinedGroupoid("hand", **names, source=None, target=None, multiply=None,
                           identity=None, inverse=None, sections=None)


def test_repeated_coordinate_names() -> None:
    with pytest.raises(sg.CoordinateNameError, match=r"fibre coordinate name 'x' is repeated"):
        sg.DefinedGroupoid("hand", base_names=["q"], fibre_names=["x", "x"], source=None,
                           target=None, multiply=None, identity=None, inverse=None,
                           sections=None)


def test_base_and_fibre_name_with_source_offset_zero() -> None:
    """With source_offset=0 the source of g_k and its fibre carry the same label k: a shared
    name would make them one symbol."""
    with pytest.raises(sg.CoordinateNameError, match=r"'p' names both a base and a fibre"):
        sg.DefinedGroupoid("hand", base_names=["p"], fibre_names=["p"], source_offset=0,
                           source=None, target=None, multiply=None, identity=None,
                           inverse=None, sections=None)


@pytest.mark.parametrize("name", ["lambda", "λ", "lamda", r"\lambda", "multipliers"])
def test_reserved_name_on_a_built_in_groupoid(name) -> None:
    """The same collision on a built-in groupoid is caught when the space is made, in every
    spelling that prints as λ (lamda and \\lambda were accepted and printed as the
    multipliers)."""
    with pytest.raises(sg.CoordinateNameError, match=r"as the multipliers are"):
        sg.EuclideanSpace([name])


# --- what the maps return -----------------------------------------------------------------------

def test_a_symbol_the_maps_bring_must_be_declared() -> None:
    """(A section curve q + x·t with x declared nowhere passed the axiom check, x being given
    a random value there, and the derived equations carried x until compile() refused it as
    an unsupported expression.)  The system refuses it as it refuses an undeclared symbol of
    L, naming the groupoid; declared as a parameter, it is accepted."""
    h, x = sp.Symbol("h", positive=True), sp.Symbol("x", positive=True)
    G = line(sections=lambda q, t: [(q[0], q[0] + x * t)])

    def L(a):
        q0, q1 = a.coords
        return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4

    with pytest.raises(sg.UndeclaredSymbolError,
                       match=r"groupoid line \(its structure maps\) uses symbol\(s\) x "):
        sg.DiscreteSystem(G, L, parameters=[h, k], name="osc")
    step = sg.DiscreteSystem(G, L, parameters=[h, k, x], name="osc").euler_lagrange()
    assert x in set().union(*(r.free_symbols for r in step.residuals))


@pytest.mark.parametrize("overrides, what", [
    (dict(source=lambda a: (True,)), "the source map returned bool True as coordinate 0"),
    (dict(target=lambda a: ("abc",)), "the target map returned the string 'abc'"),
    (dict(sections=lambda q, t: [(q[0], sp.Gt(q[0], t))]), "the section curve 0 returned "
                                                             "StrictGreaterThan"),
])
def test_maps_returning_what_is_not_a_coordinate_are_refused(overrides, what) -> None:
    """(A truth value gave a raw AttributeError from evalf; a string was read as a symbol
    of its text, and the error was a failed identity axiom with 'abc' chosen at random.)"""
    with pytest.raises(sg.ShapeError, match=what):
        line(**overrides)


def test_an_action_returning_a_truth_value_is_refused_and_its_symbols_are_named() -> None:
    s = sp.Symbol("s", positive=True)
    plane = sg.EuclideanSpace.vector("x", 2)
    with pytest.raises(sg.ShapeError, match="the action returned bool True as coordinate 0"):
        sg.ActionGroupoid(plane, sg.SO2("W"), lambda p, W: (True, p[1]))
    with pytest.raises(sg.AxiomError, match=r"p·I ≠ p .* with s=[0-9.]+ \(its symbols other "
                                            r"than the point's coordinates chosen at random"):
        sg.ActionGroupoid(plane, sg.SO2("W"), lambda p, W: tuple(s * W.T * sp.Matrix(p)))
