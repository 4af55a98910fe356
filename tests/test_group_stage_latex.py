"""A Galerkin step on Lie-group factors printed in the group stage notation
(docs/conventions.md §22, "The stage notation on a group factor"): the junction row
dτ_{Δ_k}^{−T}P_k + S_{k+1} − Ad_{τ(Δ_{k+1})⁻¹}^T dτ_{Δ_{k+1}}^{−T}P_{k+1} = 0 and the stage
rows per factor, with the curve, the chart Lagrangian's derivatives and the sums in the
"where" list — offered only when every printed row, computed from its "where" list as
printed at 50 digits, equals the step's residual at random points of the group.  The
documents typeset whole with pdflatex (tests/test_latex_pdf.py's helpers)."""

import shutil

import mpmath
import pytest
import sympy as sp
from test_group_stage_notation import SYSTEMS, h
from test_latex_pdf import equation_numbers, lost_content, needs_tex, typeset

import symgroupoid as sg

# white-box: whether the form is offered, and the retraction's maps the check reads, have no
# public name
from symgroupoid.equations import _group_stage_forms as group_forms
from symgroupoid.ir import Graph, Program, interpret, interpret_precise

J = sp.diag(*sp.symbols("I1:4", positive=True))
mgl = sp.Symbol("mgl", positive=True)


def _top(scheme=None, **options):
    system = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * J * xi)[0, 0] / 2
                                 - mgl * R[2, 2], parameters=[h, mgl, *J.diagonal()],
                                 name="top", **options)
    return system.discretize(h, scheme or sg.GaussLegendre(2)).euler_lagrange()


def test_the_heavy_top_prints_in_the_group_stage_notation():
    """The top at order 4: one junction row and a stage row for each arrow (three vector
    equations for nine residuals), the chart increments, the stage attitudes R_{j,i} =
    R_{j−1}τ(X_{j,i}) and body velocities, and N, M written out from L."""
    text = _top().latex()
    assert text.count("0 &=") == 3
    assert (r"0 &= S_{k+1} - \mathrm{Ad}_{\tau(\Delta_{k+1})^{-1}}^{T} "
            r"\mathrm{d}\tau_{\Delta_{k+1}}^{-T} P_{k+1} + \mathrm{d}\tau_{\Delta_{k}}^{-T} P_{k}"
            in text)
    for row in (r"\Delta_{j} &= \tau^{-1}(R_{j-1}^{-1} R_{j})", r"R_{j,1} = R_{j-1} \tau(X_{j,1})",
                r"\Xi_{j,1} = \mathrm{d}\tau_{X_{j,1}} V_{j,1}",
                r"B_{j,1} = \mathrm{d}\tau_{X_{j,1}}^{T} M_{j,1}",
                r"N &= \left[\begin{matrix}R_{32} mgl\\- R_{31} mgl\\0\end{matrix}\right]"):
        assert row in text, row


def _forget_the_curvature(monkeypatch) -> None:
    """The check's group maps with the derivative of dτ_X V in X taken as 0 (the term a hand
    derivation forgets): the printed rows then differ from the residual."""
    real = group_forms._group_maps

    def forgetful(F):
        real(F)
        if F.is_group:
            F.maps["curvature_t"] = lambda x, v: mpmath.matrix(len(x), len(x))

    monkeypatch.setattr(group_forms, "_group_maps", forgetful)


def test_a_row_that_does_not_hold_is_not_offered(monkeypatch):
    """The check can fail: with the derivative of dτ_X V in X taken as 0 (the term a hand
    derivation forgets) the printed rows differ from the residual, the form is not offered
    and the step is refused as before (its residuals written out are too large)."""
    _forget_the_curvature(monkeypatch)
    step = _top()
    assert group_forms.group_stage_rows(step, 450.0, None) is None
    with pytest.raises(sg.UnsupportedFeatureError, match="written out as formulas have"):
        step.latex()


def _pendulum_top(half):
    """A body on SO(3) in a potential −k R_31 written with ``half`` = 1/2 or the double 0.5."""
    k = sp.Symbol("k", positive=True)
    return sg.ContinuousSystem(
        sg.SO3("R"), lambda R, xi: (xi.T * xi)[0, 0] / 2 - half * k * R[2, 0],
        parameters=[h, k], name="body").discretize(h, sg.GaussLegendre(2)).euler_lagrange(
        progress=False)


@pytest.mark.parametrize("half", [sp.Rational(1, 2), 0.5], ids=["rational", "double"])
def test_a_double_in_the_lagrangian_prints_in_the_group_stage_notation(half, monkeypatch):
    """With 0.5·k the step was refused ("written out as formulas have …"): the printed rows
    and the program fold the double with the rationals around it in different places and
    agreed to 1e-20, against a check at 1e-35.  Doubles are now compared at
    FLOAT_TOLERANCE; a row that does not hold is still not offered."""
    text = _pendulum_top(half).latex()
    assert r"\mathrm{d}\tau" in text and ("0.5 R_{33} k" in text) == (half == 0.5)
    _forget_the_curvature(monkeypatch)
    assert group_forms.group_stage_rows(_pendulum_top(half), 450.0, None) is None


@pytest.mark.slow
def test_a_damped_driven_top_prints_its_force_at_the_nodes():
    """A top driven by a body torque u and damped (F = u − cΞ): the force at each node joins
    N (A = dτ^T(F + N) + …, S = h Σ b_i Ad^T(F + N)), written with the inputs u_j of the
    arrow, and the form still holds at points of the group."""
    c = sp.Symbol("c", positive=True)
    u = list(sp.symbols("u1:4", real=True))
    system = sg.ContinuousSystem(
        sg.SO3("R"), lambda R, xi: (xi.T * J * xi)[0, 0] / 2 - mgl * R[2, 2],
        parameters=[h, mgl, c, *J.diagonal()], name="driven_top", inputs=u,
        forces=lambda R, xi: [u[a] - c * xi[a] for a in range(3)])
    text = system.discretize(h, sg.GaussLegendre(2)).euler_lagrange().latex()
    assert r"\mathrm{d}\tau_{X_{j,1}}^{T} \left(F_{j,1} + N_{j,1}\right)" in text
    assert (r"F &= \left[\begin{matrix}u_{1} - \Xi_{1} c\\u_{2} - \Xi_{2} c\\u_{3} - "
            r"\Xi_{3} c\end{matrix}\right]") in text
    # the inputs by their names, at their values on g_j (an undefined u_j beside u_1 before)
    assert (r"and the force, with the inputs ($u_{1}, u_{2}, u_{3}$ in its formula) at their "
            r"values on $g_j$: $N_{j,i}$, $M_{j,i}$ and $F_{j,i}$ are $N$, $M$ and $F$ at "
            r"($R_{j,i}, \Xi_{j,i}$)") in text


@pytest.mark.slow  # 22 s: the top's document typesets with the tests
@needs_tex
def test_the_document_of_a_chain_of_three_bodies_typesets_whole(tmp_path):
    """The 3D chain of three bodies at order 4 (examples/chain_order4.py's L, on SO(3)³):
    nine vector equations numbered in order, no box beyond 1 pt past its page; its N and M,
    pages long written out, are described instead of printed."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / "chain_order4.py"
    spec = importlib.util.spec_from_file_location("chain_order4", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    continuous = module.chain(3)
    step = continuous.discretize(continuous.parameters[0], sg.GaussLegendre(2)).euler_lagrange()
    document = step.latex(document=True)
    log, text = typeset(document, tmp_path)
    assert equation_numbers(text) == list(range(1, 10))
    assert lost_content(log, tolerance=1.0) == []
    assert "too long to print usefully" in document


@pytest.mark.slow
@needs_tex
def test_the_document_of_the_top_typesets_whole(tmp_path):
    document = _top(sg.LobattoIIIAB(3)).latex(document=True)
    log, text = typeset(document, tmp_path)
    assert equation_numbers(text) == [1, 2, 3]
    assert lost_content(log, tolerance=1.0) == []


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SYSTEMS))
@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2), sg.LobattoIIIAB(3), sg.GaussLegendre(3)],
                         ids=["gauss2", "lobatto3", "gauss3"])
def test_every_group_system_is_offered_the_form(name, scheme):
    """SO(3), SE(3), SO(3) × R and SO(3) × SO(3) at orders 4 and 6: the printed rows hold
    (one junction row per factor, a stage row per factor, interior stage and arrow)."""
    continuous = SYSTEMS[name]()
    step = continuous.discretize(h, scheme).euler_lagrange()
    rows = group_forms.group_stage_rows(step, 450.0, None)
    assert rows is not None
    factors = len(continuous.factors)
    equations = [item for item in rows.items if type(item).__name__ == "Row"]
    assert len(equations) == factors * (1 + 2 * scheme.tableau().interior)


def test_interpret_precise_is_the_graph_at_fifty_digits():
    """The precise walk gives the binary64 walk's values to rounding, and at 50 digits the
    graph's exact constants: √3/6 · x at x = 6 is √3 to 49 digits."""
    g = Graph()
    x = sp.Symbol("x")
    node = g.mul(g.const(sp.sqrt(3) / 6), g.input(x))
    square = g.pow(g.add(node, g.const(1)), 2)
    program = Program(graph=g, inputs={"u": [x]}, outputs={"F": [node, square]})
    precise = interpret_precise(program, ["F"], {x: 6}, 50)["F"]
    with mpmath.workdps(50):
        assert abs(precise[0] - mpmath.sqrt(3)) < mpmath.mpf(10) ** -49
    (floats,) = interpret(program, ["F"], ["u"], [6.0])
    assert [float(v) for v in precise] == pytest.approx(list(floats), rel=1e-15)


@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2),
                                    pytest.param(sg.LobattoIIIAB(4), marks=pytest.mark.slow)],
                         ids=["gauss2", "lobatto4"])
def test_planar_groups_and_a_plane_beside_a_rotation_are_offered_the_form(scheme):
    """SO(2), SE(2), and SO(3) × R² (a factor of two coordinates, named by them: P^{(x, y)})
    print in the group form, checked at points of the group."""
    k = sp.Symbol("k", positive=True)
    systems = [
        sg.ContinuousSystem(sg.SO2("Q"), lambda R, w: w[0] ** 2 / 2 - k * R[0, 0],
                            parameters=[h, k], name="rotor"),
        sg.ContinuousSystem(sg.SE2("g"), lambda g, xi: (xi.T * xi)[0, 0] / 2
                            - k * g[0, 2] ** 2, parameters=[h, k], name="cart"),
        sg.ContinuousSystem([sg.SO3("R"), sg.EuclideanSpace("x y")],
                            lambda q, v: (v[0].T * v[0])[0, 0] / 2 + (v[1].T * v[1])[0, 0] / 2
                            - k * q[0][2, 2] * q[1][0] - k * q[1][1] ** 2,
                            parameters=[h, k], name="mix")]
    for continuous in systems:
        step = continuous.discretize(h, scheme).euler_lagrange()
        assert group_forms.group_stage_rows(step, 450.0) is not None, continuous.name
    text = step.latex()
    assert r"0 &= - P^{(x, y)}_{k+1} + P^{(x, y)}_{k} + S^{(x, y)}_{k+1}" in text


@pytest.mark.slow  # 34 s; the Cayley steps print with the tests
def test_a_step_through_the_exponential_map_prints_with_it():
    """SO(3) through the exponential retraction: dexp's smooth functions are evaluated at
    their closed form at 50 digits in the check (their binary64 Taylor polynomial would be
    off by 10⁻¹⁷), and the words name the exponential map."""
    system = sg.ContinuousSystem(sg.SO3("R", retraction="exp"),
                                 lambda R, xi: (xi.T * J * xi)[0, 0] / 2 - mgl * R[2, 2],
                                 parameters=[h, mgl, *J.diagonal()], name="top_exp")
    text = system.discretize(h, sg.LobattoIIIAB(3)).euler_lagrange().latex()
    assert r"(unknowns of the step), $\tau$ the exponential map" in text
    assert text.count("0 &=") == 3


def test_interpret_precise_evaluates_a_smooth_function_exactly_near_its_point():
    """(1 − cos θ)/θ² at θ² = 10⁻³: binary64's Taylor polynomial is right to 10⁻¹⁷ only; the
    precise walk takes the closed form at 50 digits (and the exact value at θ = 0)."""
    from symgroupoid.ir import OneMinusCosOverTheta2, smooth_spec

    g = Graph()
    s = sp.Symbol("s")
    node = g.func(smooth_spec(OneMinusCosOverTheta2), g.input(s))
    program = Program(graph=g, inputs={"u": [s]}, outputs={"F": [node]})
    with mpmath.workdps(50):
        theta = mpmath.sqrt(mpmath.mpf("1e-3"))
        exact = (1 - mpmath.cos(theta)) / theta ** 2
        (value,) = interpret_precise(program, ["F"], {s: mpmath.mpf("1e-3")}, 50)["F"]
        assert abs(value - exact) < mpmath.mpf(10) ** -45
        assert interpret_precise(program, ["F"], {s: 0}, 50)["F"][0] == mpmath.mpf(1) / 2


@needs_tex
@pytest.mark.parametrize("scheme, width", [(sg.LobattoIIIAB(3), None),
                                           pytest.param(sg.GaussLegendre(2), 345,
                                                        marks=pytest.mark.slow)])
def test_the_document_of_a_driven_top_fits_its_page(tmp_path, scheme, width):
    """Its sum S_j of h Ad^T(F + N) terms over six fractions was measured with text-style
    fractions (SymPy printed the non-commutative products' \\frac itself), set with display
    ones: 96 pt past the text at the default width, 23 pt at 345 pt."""
    w = sp.symbols("w1:4", real=True)
    system = sg.ContinuousSystem(
        sg.SO3("R"), lambda R, xi: (xi.T * J * xi)[0, 0] / 2 - mgl * R[2, 2],
        parameters=[h, mgl, *J.diagonal()], name="driven_top", inputs=list(w),
        forces=lambda R, xi: list(w))
    document = system.discretize(h, scheme).euler_lagrange().latex(document=True, width=width)
    log, text = typeset(document, tmp_path)
    assert equation_numbers(text) == [1, 2, 3]
    assert lost_content(log, tolerance=1.0) == []


# --- the midpoint and trapezoid rules on a group, too large written out ---------------------

I_body = sp.symbols("I1:4", positive=True)
m_body = sp.Symbol("m", positive=True)


def _free_body(rule: str):
    """A free rigid body on SE(3) (body velocity (ω, v)) by ``rule``: its residuals written
    out have about 10⁶ operations (the Cayley map of SE(3) in every entry)."""
    def L(T, xi):
        return (sum(inertia * w ** 2 for inertia, w in zip(I_body, xi[:3]))
                + m_body * sum(v ** 2 for v in xi[3:])) / 2

    system = sg.ContinuousSystem(sg.SE3("T"), L, parameters=[h, *I_body, m_body],
                                 name=f"free_{rule}")
    return system.discretize(h, rule).euler_lagrange()


@pytest.mark.slow
def test_the_midpoint_rule_on_se3_prints_in_the_group_notation(tmp_path):
    """The free body on SE(3) by the midpoint rule was refused (1.05·10⁶ operations written
    out, over PRINT_LIMIT).  It prints in the rule's group form: L read at X = Δ/2 and the
    velocity V = Δ/h itself (no dτ on it), so A = dτ_X^T N and P = M + hA/2 — checked
    against the residual at points of the group — and its document typesets whole."""
    from symgroupoid.equations import PRINT_LIMIT

    step = _free_body("midpoint")
    assert step.program.expanded_size(["F"]) > PRINT_LIMIT
    text = step.latex()
    assert text.count("0 &=") == 1
    for row in (r"\Delta_{j} &= \tau^{-1}(T_{j-1}^{-1} T_{j})", r"V_{j,1} = \frac{\Delta_{j}}{h}",
                r"X_{j,1} = \frac{h V_{j,1}}{2}", r"T_{j,1} = T_{j-1} \tau(X_{j,1})",
                r"A_{j,1} &= \mathrm{d}\tau_{X_{j,1}}^{T} N_{j,1}",
                r"P_{j} &= M_{j,1} + \frac{h A_{j,1}}{2}",
                r"$N$ and $M$ at ($T_{j,i}, V_{j,i}$)"):
        assert row in text, row
    assert r"\Xi_{j,1}" not in text and "B_{j,1}" not in text
    if shutil.which("pdflatex") and shutil.which("pdftotext"):
        log, pdf_text = typeset(step.latex(document=True), tmp_path)
        assert equation_numbers(pdf_text) == [1] and lost_content(log, tolerance=1.0) == []


@pytest.mark.slow
def test_the_trapezoid_rule_on_se3_prints_in_the_group_notation():
    """The trapezoid rule's form: L at both ends (X = 0 and X = Δ, weights 1/2)."""
    text = _free_body("trapezoid").latex()
    for row in (r"X_{j,1} = 0", r"X_{j,2} = h \left(\frac{V_{j,1}}{2} + \frac{V_{j,2}}{2}\right)",
                r"P_{j} &= \frac{M_{j,1}}{2} + \frac{M_{j,2}}{2} + \frac{h A_{j,2}}{2}"):
        assert row in text, row


@pytest.mark.slow
def test_a_rule_form_that_does_not_hold_is_not_offered(monkeypatch):
    """With dτ_Δ^{−T} taken as the identity (a hand derivation's slip) the rows differ from
    the residual: the form is not offered and the step is refused as before."""
    real = group_forms._group_maps

    def slipped(F):
        real(F)
        if F.is_group:
            F.maps["dtau_inv_t"] = lambda x: mpmath.eye(len(x))

    monkeypatch.setattr(group_forms, "_group_maps", slipped)
    step = _free_body("midpoint")
    assert group_forms.group_rule_form(step) is None
    with pytest.raises(sg.UnsupportedFeatureError, match="written out as formulas have"):
        step.latex()


def test_the_heavy_top_by_the_midpoint_rule_prints_in_the_group_notation():
    """The top by the midpoint rule was refused as well (1.58·10⁶ operations written out);
    its rule form writes N from L, with the potential's gradient at the node attitude.
    (A rule's step on a group prints in this form whatever its size.)"""
    step = _top("midpoint")
    text = step.latex()
    assert text.count("0 &=") == 1 and r"R_{j,1} = R_{j-1} \tau(X_{j,1})" in text
    assert r"N &= \left[\begin{matrix}R_{32} mgl\\- R_{31} mgl\\0\end{matrix}\right]" in text


def test_a_pendulum_on_so2_by_the_midpoint_rule_prints_at_once():
    """Checking its written-out forms did not finish in 400 s (the Cayley quotients'
    expansions); the rule's group form prints it in seconds."""
    import time

    grav = sp.Symbol("g", positive=True)
    pendulum = sg.ContinuousSystem(sg.SO2("R"), lambda R, xi: xi[0] ** 2 / 2 - grav * R[0, 0],
                                   parameters=[h, grav], name="pendulum")
    step = pendulum.discretize(h, "midpoint").euler_lagrange()
    t0 = time.perf_counter()
    text = step.latex()
    assert time.perf_counter() - t0 < 60
    assert r"P_{j} &= M_{j,1} + \frac{h A_{j,1}}{2}" in text and r"N &= - R_{12} g" in text


def test_a_rule_on_a_group_the_notation_cannot_print_is_refused_at_once():
    """A mass named M (one of the notation's letters) or holonomic constraints: the rule's
    group form is not offered, and checking the written-out forms did not finish (> 150 s).
    Refused at once, naming why; names the rule form does not print (B, F) still print."""
    import time

    def pendulum(name, **options):
        mass = sp.Symbol(name, positive=True)
        return sg.ContinuousSystem(sg.SO2("R"), lambda R, xi: mass * (xi[0] ** 2 / 2 - R[0, 0]),
                                   parameters=[h, mass], name="pendulum", **options)

    t0 = time.perf_counter()
    with pytest.raises(sg.UnsupportedFeatureError, match="names M read as its symbols"):
        pendulum("M").discretize(h, "midpoint").euler_lagrange().latex()
    assert r"M = V_{1} B" in pendulum("B").discretize(h, "midpoint").euler_lagrange().latex()
    ring = sg.ContinuousSystem([sg.SO2("R"), sg.EuclideanSpace(["x", "y"])],
                               lambda q, v: (v[0][0] ** 2 + v[1][0] ** 2 + v[1][1] ** 2) / 2,
                               parameters=[h], name="ring",
                               holonomic=lambda q: [q[1][0] ** 2 + q[1][1] ** 2 - 1])
    with pytest.raises(sg.UnsupportedFeatureError, match="it has holonomic constraints"):
        ring.discretize(h, "midpoint").euler_lagrange().latex()
    assert time.perf_counter() - t0 < 90
