"""The stage notation of constrained Galerkin steps (docs/conventions.md §22, "Printed in
the stage notation"): LobattoIIIAB(s) with holonomic constraints ψ (Jay's SPARK methods in
variational form) prints its rows in the node values Q_{k,i}, V_{k,i}, with the interior
multipliers Λ_{k,i} (the arrow's last internal stages) in the junction and stage rows through
Λ·∇ψ(Q_{k,i}), the end multiplier λ_{k+1} at q_k, the multipliers' rows ψ(Q_{k,i}) = 0 and
the step's last row ψ(q_{k+1}) = 0; every row is checked against the residuals (the printer
raises otherwise), and the document typesets whole with pdflatex."""

import pytest
import sympy as sp
from test_latex_pdf import assert_typesets_whole, needs_tex

import symgroupoid as sg

h, grav = sp.symbols("h g", positive=True)


def _pendulum(scheme) -> sg.StepEquations:
    """The pendulum in Cartesian coordinates on the unit circle."""
    return sg.ContinuousSystem(
        sg.EuclideanSpace("x y"), lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - grav * q[1],
        parameters=[h, grav], holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1],
        name="pendulum").discretize(h, scheme).euler_lagrange()


@pytest.mark.slow
def test_constrained_lobatto_prints_the_stage_notation():
    step = _pendulum(sg.LobattoIIIAB(3))
    text = step.latex()
    rows = text[:text.index(r"\intertext{where")]
    assert rows.count("0 &=") == len(step) == 9
    # the junction rows: both arrows' interior multipliers and λ_{k+1}·∇ψ(q_k)
    assert r"(Q_{k+1,2})_{x} \Lambda_{k+1,2} + (Q_{k,2})_{x} \Lambda_{k,2}" in rows
    assert r"2 (\lambda_{k+1})_{1} x_{k}" in rows
    # the stage rows, the multipliers' rows ψ(Q_{k,2}) = 0, and ψ(q_{k+1}) = 0 last
    assert r"0 &= 2 (Q_{k,2})_{x} \Lambda_{k,2} + \frac{2}{3}" in rows
    assert r"0 &= (Q_{k,2})_{x}^{2} + (Q_{k,2})_{y}^{2} - 1 \\" in rows
    assert rows.rstrip().endswith(r"0 &= x_{k+1}^{2} + y_{k+1}^{2} - 1 \\")
    where = text[text.index(r"\intertext{where"):]
    assert r"\Lambda_{k,2} = (\zeta_{k})_{3}" in where
    assert r"(Q_{k,2})_{x} &= x_{k-1} + h \left(\frac{5 (V_{k,1})_{x}}{24}" in where
    assert "(\\zeta_{k})_{3}" not in rows  # the multipliers by their names


@pytest.mark.slow
def test_two_interior_nodes_and_two_constraints():
    """LobattoIIIAB(4) with two constraints (a point on a circle in a plane of R³): two
    interior nodes, each with two multipliers (Λ_{k,i})_c."""
    step = sg.ContinuousSystem(
        sg.EuclideanSpace("x y z"),
        lambda q, v: (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - grav * q[1],
        parameters=[h, grav], holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1, q[2]],
        name="ring").discretize(h, sg.LobattoIIIAB(4)).euler_lagrange()
    text = step.latex()
    rows = text[:text.index(r"\intertext{where")]
    assert rows.count("0 &=") == len(step)
    for name in (r"(\Lambda_{k,2})_{1}", r"(\Lambda_{k,3})_{2}", r"(\Lambda_{k+1,3})_{1}"):
        assert name in rows


@needs_tex
def test_the_constrained_stage_notation_typesets_whole(tmp_path):
    document = assert_typesets_whole(_pendulum(sg.LobattoIIIAB(3)), tmp_path)
    assert r"\Lambda_{k+1,2}" in document


def _driven(scheme) -> sg.StepEquations:
    """A damped, driven quartic oscillator on R (a forced Galerkin step on a vector space)."""
    m, c = sp.symbols("m c", positive=True)
    u = sp.Symbol("u", real=True)
    return sg.ContinuousSystem(
        sg.EuclideanSpace("q"), lambda q, v: m * v[0] ** 2 / 2 - q[0] ** 4 / 4,
        parameters=[h, m, c], forces=lambda q, v: [-c * v[0] + u], inputs=[u],
        name="driven").discretize(h, scheme)


def test_abbreviations_keep_the_stage_notation_and_say_why():
    """An abbreviation dropped the stage notation of a step on a vector space for the
    expanded residuals, with a warning that did not say so; as on a group, the notation is
    kept and the abbreviation reported unused because the notation names its own parts."""
    step = _driven(sg.GaussLegendre(2)).euler_lagrange()
    plain = step.latex()
    m, c = sp.symbols("m c", positive=True)
    with pytest.warns(sg.UnusedAbbreviationWarning, match="the stage notation names its own "
                                                          "parts"):
        abbreviated = step.latex(abbreviations={r"\mu": m * c})
    assert "Q_{k,1}" in plain and abbreviated == plain


@pytest.mark.slow
def test_a_noether_quantity_names_the_stages_as_the_step_does():
    """F_X of a Galerkin system printed its generic stages ζ₀, ζ₁; the step prints those of
    the state's arrow (x_{k−1}, x_k) as (ζ_k)_1, (ζ_k)_2."""
    system = sg.ContinuousSystem(
        sg.EuclideanSpace("x y"),
        lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2) ** 2 / 4,
        parameters=[h], name="plane").discretize(h, sg.GaussLegendre(2))
    text = system.noether(lambda q: [-q[1], q[0]]).latex()
    step_text = system.euler_lagrange().latex()
    assert r"(\zeta_{k})_{1}" in text and r"(\zeta_{k})_{2}" in text
    assert r"\zeta_{0}" not in text and r"(\zeta_{k})_{1}" in step_text
    assert "x_{k-1}" in text and "x_{k+1}" not in text


def test_a_noether_quantity_too_long_for_a_line_is_refused_at_once():
    """A free body on SO(3) by the midpoint rule: F_X has 2,736 terms expanded, which
    printed on one line made about 5 MB of LaTeX that no page holds."""
    J = sp.symbols("J1:4", positive=True)
    body = sg.ContinuousSystem(
        sg.SO3("R"), lambda R, xi: sum(j * x**2 for j, x in zip(J, xi)) / 2,
        parameters=[h, *J], name="free_body").discretize(h, "midpoint")
    quantity = body.noether(0)
    with pytest.raises(sg.UnsupportedFeatureError, match="more than the 400 one line"):
        quantity.latex()


def test_a_hopeless_quantity_on_the_graph_is_refused_before_its_sympy_form():
    """The heavy top by GaussLegendre(2): F_X could have 3.5e12 terms expanded; its SymPy
    form took 5 minutes to be built and refused.  Counted on the graph it is evaluated on
    (3.5e11) it is refused at once; its values along a run are unaffected."""
    m, grav = sp.symbols("m g", positive=True)
    J = sp.symbols("J1:4", positive=True)
    chi = sp.Matrix(sp.symbols("chi1:4", real=True))

    def L(R, xi):
        return (sum(j * x**2 for j, x in zip(J, xi)) / 2
                - m * grav * (sp.Matrix([[0, 0, 1]]) * R * chi)[0, 0])

    top = sg.ContinuousSystem(sg.SO3("R"), L, parameters=[h, m, grav, *J, *chi],
                              name="top").discretize(h, sg.GaussLegendre(2))
    quantity = top.noether(lambda q: [q[6], q[7], q[8]])
    with pytest.raises(sg.UnsupportedFeatureError, match=r"could have about \d{12} terms "
                                                         r"expanded \(counted on the "
                                                         r"expression graph"):
        quantity.latex()
    assert quantity.symbolic_forms is not None and "on the expression graph" in repr(quantity)


def test_terms_apart_only_by_a_surd_are_one_term():
    """The Gauss nodes' √3 left √3 sin Q and 3 sin Q as two terms of a stage row; they
    print as (√3 + 3) sin Q."""
    g = sp.Symbol("g", positive=True)
    pendulum = sg.ContinuousSystem(
        sg.EuclideanSpace("theta"), lambda q, v: v[0] ** 2 / 2 + g * sp.cos(q[0]),
        parameters=[h, g], name="pendulum").discretize(h, sg.GaussLegendre(2))
    text = pendulum.euler_lagrange().latex()
    assert r"\left(\sqrt{3} + 3\right) \sin(Q_{k+1,1})" in text
    assert r"\sin(Q_{k+1,1}) \sqrt{3}" not in text
