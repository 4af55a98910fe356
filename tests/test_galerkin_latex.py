"""A Galerkin step printed in the papers' stage notation (docs/conventions.md §22;
Marsden–West §2.6, Hairer–Lubich–Wanner VI.6): the rows in the node values Q_{k,i}, V_{k,i}
of each arrow's curve, the velocities in the step's unknowns and the stage equations
Q_{k,i} = q_{k−1} + h Σ_j a_ij V_{k,j} in the "where" list, every row checked against the
residuals; the document typesets whole with pdflatex (tests/test_latex_pdf.py's helper)."""

import pytest
import sympy as sp
from test_latex_pdf import assert_typesets_whole, needs_tex

import symgroupoid as sg

h, grav = sp.symbols("h g", positive=True)
c, u = sp.Symbol("c", real=True), sp.Symbol("u", real=True)


def _pendulum(**forcing) -> sg.ContinuousSystem:
    return sg.ContinuousSystem(sg.EuclideanSpace("theta"),
                               lambda q, v: v[0] ** 2 / 2 + grav * sp.cos(q[0]),
                               parameters=[h, grav, *([c] if forcing else [])],
                               name="pendulum", **forcing)


def test_lobatto_prints_the_stage_notation():
    """Lobatto IIIA–IIIB (3): the interior node is the internal stage; the rows read
    sin(Q_{k,2}) and the stage equation Q_{k,2} = θ_{k−1} + h(5V_{k,1}/24 + V_{k,2}/3 −
    V_{k,3}/24) (the Lobatto IIIA coefficients)."""
    step = _pendulum().discretize(h, sg.LobattoIIIAB(3)).euler_lagrange()
    text = step.latex()
    assert text.count("0 &=") == 3
    assert r"\sin(Q_{k,2})" in text and r"\sin(Q_{k+1,2})" in text
    assert r"Q_{k,2} &= \theta_{k-1} + h \left(\frac{5 V_{k,1}}{24} + \frac{V_{k,2}}{3} - " \
           r"\frac{V_{k,3}}{24}\right)" in text
    assert r"V_{k,1} &= \frac{4 (\zeta_{k})_{1} - \theta_{k-1} + \theta_{k}}{h}" in text
    # ζ, which the "where" rows read, is said before them (it was left undefined)
    assert (r"\intertext{where, with $\zeta_{k}$ and $\zeta_{k+1}$ the internal stages of the "
            r"known and the new arrow (unknowns of the step),}") in text


@pytest.mark.slow
def test_gauss_with_forces_prints_the_stage_notation():
    """GaussLegendre(2) of a damped, driven pendulum: the Gauss coefficients a_ij
    (1/4, 1/4 ∓ √3/6), and the force at the nodes, c·V_{k,i} and the inputs u_k, u_{k+1}."""
    step = _pendulum(forces=lambda q, v: [-c * v[0] + u], inputs=[u]).discretize(
        h, sg.GaussLegendre(2)).euler_lagrange()
    text = step.latex()
    assert text.count("0 &=") == 3
    assert r"\left(\frac{1}{4} - \frac{\sqrt{3}}{6}\right) V_{k,2}" in text
    assert "Q_{k,1} &= \\theta_{k-1} + h" in text and "Q_{k+1,2}" in text
    assert "u_{k+1}" in text and "c" in text
    # the force named at each node, F_{k,i} = F(Q_{k,i}, V_{k,i}, u_k), given after "where"
    assert r"F_{k,1} = u_{k} - c V_{k,1}" in text
    assert r"F_{k+1,1} = u_{k+1} - c V_{k+1,1}" in text
    assert r"\frac{h}{3} \left(F_{k,1} + F_{k,2} - g" in text  # the stage row


@pytest.mark.slow
def test_a_forced_system_named_F_prints_without_the_stage_notation():
    """A parameter printed F would read as the node force F_{k,i}: the stage notation is
    not offered (the step prints as derived), as for the other letters of the notation."""
    F = sp.Symbol("F", positive=True)
    step = sg.ContinuousSystem(
        sg.EuclideanSpace("theta"), lambda q, v: v[0] ** 2 / 2 + grav * sp.cos(q[0]),
        parameters=[h, grav, F], forces=lambda q, v: [F * sp.sin(q[0])],
        name="pendulum").discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    text = step.latex()
    assert "Q_{k" not in text and "F_{k" not in text and "F" in text


def test_the_rules_without_stages_print_as_before():
    text = _pendulum().discretize(h, "midpoint").euler_lagrange().latex()
    assert "Q_{k" not in text and "V_{k" not in text and "zeta" not in text


def test_a_galerkin_step_on_a_group_says_what_its_stages_are():
    """The group stage notation defined ζ_j as the vector of its components but not what it
    is; a rule (no stages) does not mention them."""
    top = sg.ContinuousSystem(sg.SO3("R"), lambda R, w: (w[0] ** 2 + 2 * w[1] ** 2
                                                          + 3 * w[2] ** 2) / 2 - grav * R[2, 2],
                              parameters=[h, grav], name="top")
    staged = top.discretize(h, sg.GaussLegendre(2)).euler_lagrange().latex()
    assert (r"nodes $i$, with $\zeta_{j}$ the internal stages of the arrow ending at $j$ "
            r"(unknowns of the step), $\tau$ the Cayley map") in staged
    rule = top.discretize(h, "trapezoid").euler_lagrange().latex()
    assert r"nodes $i$, with $\tau$ the Cayley map" in rule and "zeta" not in rule


@pytest.mark.slow
def test_a_forced_constrained_step_prints_in_the_stage_notation():
    """Lobatto with a holonomic constraint and a damping force (this printed as derived, and
    before that raised LatexVerificationError): the stage notation with the forces at the
    nodes, the interior multipliers Λ and the end multiplier λ_{k+1} (tests/test_stage_latex.py
    has the constrained forms in detail)."""
    cartesian = sg.ContinuousSystem(
        sg.EuclideanSpace("x y"), lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - grav * q[1],
        parameters=[h, grav, c], holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1],
        forces=lambda q, v: [-c * v[0], -c * v[1]], name="cart")
    step = cartesian.discretize(h, sg.LobattoIIIAB(3)).euler_lagrange()
    text = step.latex()
    assert text.count("0 &=") == len(step) == 9
    assert r"\Lambda_{k+1,2} = (\zeta_{k+1})_{3}" in text
    assert r"\frac{h}{6} \left((F_{k+1,1})_{x} + 2 (F_{k+1,2})_{x}" in text
    assert r"(F_{k+1,2})_{y} = - c (V_{k+1,2})_{y}" in text


@needs_tex
@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2), sg.LobattoIIIAB(3)])
def test_the_stage_notation_typesets_whole(scheme, tmp_path):
    step = _pendulum(forces=lambda q, v: [-c * v[0] + u], inputs=[u]).discretize(
        h, scheme).euler_lagrange()
    document = assert_typesets_whole(step, tmp_path)
    assert "Q_{k,2} &= " in document and "V_{k+1,2}" in document
