"""LaTeX a paper can use: named pieces, collected terms, lines that fit a page, a "where" list.

Targets: every line of the double pendulum's equations renders (matplotlib mathtext, 10 pt)
within 450 pt; its whole LaTeX is at most a third of the plain, fully expanded printing; the
plate-ball still prints as in seed 000 §6.2.  Every printed form is the explicit residual:
checked here again numerically at random points, and the printing is shown to refuse forms
that are not.  Lines leave room for the equation numbers; the chosen form is never longer
than ``sympy.latex`` of the residuals (the seed systems, and the satellite of
tests/test_latex_pdf.py, which prints no entry of a basis matrix); constant matrix parts are
evaluated.
"""

from __future__ import annotations

import io
import re
import warnings

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import systems
from symgroupoid.cli import load_system
from symgroupoid.derivation import PieceRule

# white-box: the line breaking and its page measures, the collection, the choice and the
# verification of the printed forms, and the constant matrix parts are checked inside
# (equations/_latex.py, _layout.py, _printing.py, _matrix_parts.py), below what latex() shows
from symgroupoid.equations import (
    LatexOptionError,
    LatexVerificationError,
    UnusedAbbreviationWarning,
    _latex,
    _layout,
    _matrix_parts,
    _printing,
    equation_lines,
)

mathtext = pytest.importorskip("matplotlib.mathtext")
from test_latex import _line_widths, _lines  # noqa: E402
from test_latex_pdf import SATELLITE, SATELLITE_ENTRIES, _file  # noqa: E402

PAGE = 450.0  # pt

#: the double pendulum of the request (masses m₁, m₂ and lengths l₁, l₂), midpoint rule
#: L_d(q₀, q₁) = h L((q₀ + q₁)/2, (q₁ − q₀)/h); a system file, also for the command line
DOUBLE_PENDULUM = '''
import sympy as sp
import symgroupoid as sg

h, g, m1, m2, l1, l2 = sp.symbols("h g m_1 m_2 l_1 l_2", positive=True)


def L(arrow):
    q0, q1 = sp.Matrix(arrow.source), sp.Matrix(arrow.target)
    (a, b), (va, vb) = (q0 + q1) / 2, (q1 - q0) / h
    kinetic = ((m1 + m2) * l1**2 * va**2 / 2 + m2 * l2**2 * vb**2 / 2
               + m2 * l1 * l2 * va * vb * sp.cos(a - b))
    potential = -(m1 + m2) * g * l1 * sp.cos(a) - m2 * g * l2 * sp.cos(b)
    return h * (kinetic - potential)


system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("theta1 theta2")), L,
                           parameters=[h, g, m1, m2, l1, l2], name="double_pendulum")
'''

#: a pendulum in its angle, midpoint rule: small, for the options and the command line
PENDULUM = '''
import sympy as sp
import symgroupoid as sg

h, g = sp.symbols("h g", positive=True)


def L(arrow):
    (q0,), (q1,) = arrow.source, arrow.target
    return h * (((q1 - q0) / h) ** 2 / 2 + g * sp.cos((q0 + q1) / 2))


system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, g],
                           name="pendulum")
'''


def _system(source: str) -> sg.DiscreteSystem:
    namespace: dict = {}
    exec(compile(source, "<system>", "exec"), namespace)
    return namespace["system"]


@pytest.fixture(scope="module")
def double_pendulum() -> sg.DiscreteSystem:
    return _system(DOUBLE_PENDULUM)


@pytest.fixture(scope="module")
def dp_step(double_pendulum):
    return double_pendulum.euler_lagrange()


@pytest.fixture(scope="module")
def dp_latex(dp_step) -> str:
    return dp_step.latex()


@pytest.fixture(scope="module")
def pendulum_step():
    return _system(PENDULUM).euler_lagrange()


@pytest.fixture(scope="module")
def plate_ball_latex(plate_ball_step) -> str:
    return plate_ball_step.latex()


@pytest.fixture(scope="module")
def satellite_step():
    """The satellite of examples/cli/satellite.py (Ω = vee(W − Wᵀ)/(2h))."""
    return load_system(str(SATELLITE)).system.euler_lagrange()


@pytest.fixture(scope="module")
def entries_step(tmp_path_factory):
    """The satellite as first written: Ω from the entries of W."""
    path = _file(tmp_path_factory.mktemp("satellite"), "satellite", SATELLITE_ENTRIES)
    return load_system(str(path)).system.euler_lagrange()


def _plain(step) -> str:
    """The plain printing: every residual fully expanded, one unbroken row each."""
    return "\\begin{align}\n" + " \\\\\n".join(equation_lines(step)) + "\n\\end{align}"


# --- the targets ------------------------------------------------------------------------------

def test_double_pendulum_lines_render_within_a_page(dp_latex):
    widths = _line_widths(dp_latex)
    assert len(widths) >= 8
    assert max(widths) <= PAGE, widths
    for _, body, _ in _lines(dp_latex):
        mathtext.math_to_image(f"${body}$", io.BytesIO(), format="png")


def test_double_pendulum_latex_is_at_most_a_third_of_the_plain_printing(dp_step, dp_latex):
    """Measured against the plain printing by the same printer (products in the papers'
    order, sums over one denominator): 4,979 characters fully expanded (``sympy.latex``
    prints the same residuals in 5,839)."""
    plain = _plain(dp_step)
    per_equation = [len(line) for line in equation_lines(dp_step)]
    assert min(per_equation) > 2000, per_equation
    assert 3 * len(dp_latex) <= len(plain), (len(dp_latex), len(plain))


def test_double_pendulum_prints_in_midpoints_and_difference_quotients(dp_latex):
    """D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1}) through ∂L/∂q̄ and ∂L/∂Δq at k ∓ 1/2, each
    partial given once as a function of the pieces, then the pieces at j − 1/2."""
    assert ("\\intertext{where, for $j = k, k+1$, $(\\cdot)_{j-1/2}$ is taken at the pieces "
            "of index $j - 1/2$:}") in dp_latex
    for name in ("\\bar{\\theta}_{1}", "\\Delta \\theta_{2}"):
        assert f"(\\partial_{{{name}}} L)_{{k+1/2}}" in dp_latex
        assert f"(\\partial_{{{name}}} L)_{{k-1/2}}" in dp_latex
        assert f"\n\\partial_{{{name}}} L &=" in dp_latex
    assert "\\intertext{with}" in dp_latex
    assert ("(\\bar{\\theta}_{1})_{j-1/2} &= \\frac{(\\theta_{1})_{j-1} + (\\theta_{1})_{j}}{2}"
            in dp_latex)
    assert "(\\Delta \\theta_{1})_{j-1/2} = \\frac{(\\theta_{1})_{j} - (\\theta_{1})_{j-1}}{h}" \
        in dp_latex
    # collected by parameters, parameters first in each product
    assert "g \\left(m_{1} + m_{2}\\right) \\sin(\\bar{\\theta}_{1})" in dp_latex
    assert "h l_{2} m_{2} \\left(l_{1} \\Delta \\theta_{1} \\cos(\\bar{\\theta}_{1} - " \
        "\\bar{\\theta}_{2}) + l_{2} \\Delta \\theta_{2}\\right)" in dp_latex
    assert len(re.findall(r"^0 &=", dp_latex, re.M)) == 2


def test_plate_ball_prints_as_in_seed_and_fits(plate_ball_latex):
    """Seed 000 §6.2: (x_{k+1} − 2x_k + x_{k−1})/h, Ω h/2 ((λ_{k+1})₁ + (λ_k)₁), the
    rotational rows in r (λ)_a tr(g_k E_i E_j), tr(E_i g_{k+1} E_j), the constraints; the
    "where" list only defines the basis E_a (its signs decide the equations')."""
    tex = plate_ball_latex
    assert "\\frac{x_{k+1} + x_{k-1} - 2 x_{k}}{h}" in tex
    assert "\\frac{\\Omega h}{2} \\left((\\lambda_{k+1})_{1} + (\\lambda_{k})_{1}\\right)" in tex
    assert "r (\\lambda_{k})_{2} \\operatorname{tr}(g_{k} E_{1} E_{2})" in tex
    assert "r (\\lambda_{k+1})_{1} \\operatorname{tr}(E_{2} g_{k+1} E_{1})" in tex
    assert "c h + \\frac{\\operatorname{tr}(g_{k+1} E_{3})}{2}" in tex
    assert "(g_{k})_{" not in tex
    where = tex.split("\\intertext{where, with $e_{i}$ the $i$-th standard unit vector of "
                      "$\\mathbb{R}^{3}$,}")[1]
    assert where.strip().startswith("E_{1} &= - e_{2} e_{3}^{T} + e_{3} e_{2}^{T}, \\quad "
                                    "E_{2} = e_{1} e_{3}^{T} - e_{3} e_{1}^{T}"), where
    # the three rotational rows take two lines each on the page (seed 000 writes them so)
    assert tex.count("\\notag") == 4 and len(_lines(tex)) == 12
    assert max(_line_widths(tex)) <= PAGE


def test_group_parts_keep_their_names(heavy_top_step):
    """g_kᵀ stays a transpose: W_kᵀΓ_k on the heavy top's action groupoid (Ad*_{g_k} stays
    an operator: tests/test_latex.py)."""
    assert "\\left(W_{k}^{T} \\Gamma_{k}\\right)_{2}" in heavy_top_step.latex()


def test_products_print_numbers_parameters_variables_then_functions(plate_ball_step):
    x = plate_ball_step.symbol("x", "k")
    h, m = sp.symbols("h m")
    assert sg.latex(3 * x * sp.sin(x) * m * h) == "3 h m x_{k} \\sin(x_{k})"
    assert sg.latex(-x * h / 2) == "- \\frac{h x_{k}}{2}"
    assert sg.latex(x * h * (m + 1)) == "h \\left(m + 1\\right) x_{k}"


# --- every printed form is the residual ---------------------------------------------------------

def _evaluate(expr, layers, point) -> float:
    out = _latex.uncollected(sp.sympify(expr))
    for layer in layers:
        if layer:
            out = out.xreplace(dict(layer))
    return float(out.doit().xreplace(point).evalf(30))


def test_every_verified_form_equals_the_residual_at_random_points(pendulum_step, plate_ball_step,
                                                                   heavy_top_step):
    rng = np.random.default_rng(11)
    for step in (pendulum_step, plate_ball_step, heavy_top_step):
        forms = _printing.verified_forms(step)
        assert len(forms) >= 1
        symbols = set().union(*[r.free_symbols for r in step.residuals])
        for _ in range(2):
            point = {s: sp.Float(rng.uniform(0.2, 1.3), 30) for s in symbols}
            want = [float(r.xreplace(point).evalf(30)) for r in step.residuals]
            for form in forms:
                got = [_evaluate(sp.Add(*[t.value() for t in terms]), form.layers, point)
                       for terms in form.equations]
                assert np.allclose(got, want, rtol=1e-12, atol=1e-12), step.name
                for d in form.definitions:  # each "where" row, at j = k
                    if isinstance(d.lhs, sp.MatrixSymbol):  # a named constant: J_d = diag(…)
                        assert sp.ImmutableMatrix(d.rhs) == d.lhs.value, d.lhs
                        continue
                    lhs = _evaluate(d.lhs.xreplace(form.generic), form.layers, point)
                    rhs = _evaluate(d.rhs.xreplace(form.generic), form.layers, point)
                    assert abs(lhs - rhs) <= 1e-12 * (1 + abs(lhs)), (step.name, d.lhs)


def test_a_form_that_is_not_the_residual_is_not_printed(pendulum_step, monkeypatch):
    """A piece whose definition is wrong (q̄ = (q₀ + q₁)/3) makes every form written in the
    pieces fail the check: only the form as derived is left to print."""
    class Wrong(PieceRule):
        def definitions(self, q0, q1, mid, diff):
            return [(mid, (q0 + q1) / 3) if p == mid else (p, v)
                    for p, v in super().definitions(q0, q1, mid, diff)]

    assert len(_printing.verified_forms(pendulum_step)) == 3  # as derived, pieces, ∂L
    h = sp.Symbol("h", positive=True)
    monkeypatch.setattr(_printing, "best_rule", lambda *a: Wrong("midpoint", h))
    forms = _printing.verified_forms(pendulum_step)
    assert len(forms) == 1 and not forms[0].definitions


def test_a_broken_line_that_loses_a_term_is_refused(dp_step, monkeypatch):
    split = _layout._split
    monkeypatch.setattr(_layout, "_split", lambda *a: split(*a)[:-1])
    with pytest.raises(LatexVerificationError, match="differ from the equation"):
        dp_step.latex(width=200)


def test_broken_lines_equal_up_to_a_denominator_written_otherwise_are_kept():
    """A pendulum of varying length on the time groupoid: its rows broken to the page held
    2X/(2t₁² − 4t₁t₀ + 2t₀²) where the unbroken row held X/(t₁ − t₀)²; expanded, the two
    differ, and the correct printing was refused with LatexVerificationError."""
    eps, ell = sp.symbols("epsilon ell0", positive=True)

    def L(a):
        dt, (q0,), (q1,) = a.t1 - a.t0, a.source, a.target
        stretch = (1 + eps * sp.sin((a.t0 + a.t1) / 2)) ** 2
        return dt * ell ** 2 * stretch * ((q1 - q0) / dt) ** 2 / 2

    step = sg.DiscreteSystem(sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q"))), L,
                             parameters=[eps, ell], name="varlen").euler_lagrange()
    tex = step.latex()
    assert tex.count("0 &=") == 2 and r"\left(t_{k+1} - t_{k}\right)^{2}" in tex
    with pytest.raises(LatexVerificationError, match="differ from the equation"):
        _layout.same_sum([_layout.Term(1, sp.Symbol("a"))], [_layout.Term(1, sp.Symbol("b"))],
                         "rows")


# --- options --------------------------------------------------------------------------------------

def test_abbreviations_name_pieces_and_are_listed(pendulum_step):
    def mean(arrow):
        (q0,), (q1,) = arrow.source, arrow.target
        return (q0 + q1) / 2

    g = sp.Symbol("g", positive=True)
    with pytest.warns(UnusedAbbreviationWarning, match="abbreviation G does not"):
        tex = pendulum_step.latex(abbreviations={"\\vartheta": mean, "G": 2 * g})
    # defined at the generic arrow, in its pieces or its coordinates (whichever form is
    # shorter), and checked there: the row at j is the abbreviation at k written out
    assert any(row in tex for row in ("\\vartheta_{j-1/2} &= \\bar{q}_{j-1/2}",
                                      "\\vartheta_{j-1/2} = \\bar{q}_{j-1/2}",
                                      "\\vartheta_{j-1/2} &= \\frac{q_{j-1} + q_{j}}{2}"))
    assert "\\sin(\\vartheta_{j-1/2})" in tex or "\\sin(\\vartheta_{k" in tex
    assert tex.count("\\sin(\\bar{q}") == 0


def test_parameter_abbreviations_print_with_the_parameters(dp_step):
    m1, m2 = sp.symbols("m_1 m_2", positive=True)
    tex = dp_step.latex(abbreviations={"M": m1 + m2})
    assert "M &= m_{1} + m_{2}" in tex and "\\left(m_{1} + m_{2}\\right)" not in tex
    assert "M g \\sin(\\bar{\\theta}_{1})" in tex


@pytest.mark.parametrize("option, message", [
    ({"abbreviations": [("M", 1)]}, "must be a mapping"),
    ({"abbreviations": {"": sp.Symbol("g", positive=True)}}, "non-empty string"),
    ({"abbreviations": {3: sp.Symbol("g", positive=True)}}, "non-empty string"),
    ({"abbreviations": {"h": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"M": "g + 1"}}, "must stand for a SymPy expression"),
    ({"abbreviations": {"M": 2}}, "must stand for a SymPy expression"),
    ({"abbreviations": {"M": sp.sqrt(2)}}, r"got sqrt\(2\) \(a number, sqrt\(2\), is printed as "
                                           r"itself"),
    ({"width": -1}, "number of points from 20 to 16000"),
    ({"width": float("nan")}, "number of points from 20 to 16000"),
    ({"width": "wide"}, "number of points from 20 to 16000"),
    # (True was a width of 1 pt, 1e-9 a document pdflatex refused, "yes" a document)
    ({"width": True}, "number of points from 20 to 16000, got True"),
    ({"width": 1e-9}, "number of points from 20 to 16000"),
    ({"width": 1e6}, "number of points from 20 to 16000"),
    # (names that read as a coordinate, the Lagrangian, a number or an operator, or that
    # break a row, were accepted: the PDF read "a = ā − b̄" beside a_k, "sin(2)")
    ({"abbreviations": {"q": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"L": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {r"\sin": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    # (the step index k printed as a factor beside terms indexed by k, j inside the rows
    # "for j = k, k+1", g beside the arrows g_k)
    ({"abbreviations": {"k": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"j": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"Δ": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {r"\lambda": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"2": sp.Symbol("g", positive=True)}}, "holds no letter"),
    ({"abbreviations": {"-": sp.Symbol("g", positive=True)}}, "holds no letter"),
    ({"abbreviations": {r"\left(": sp.Symbol("g", positive=True)}}, "breaks a row"),
    ({"abbreviations": {r"\end{align}": sp.Symbol("g", positive=True)}}, "breaks a row"),
    ({"abbreviations": {"x^": sp.Symbol("g", positive=True)}}, "breaks a row"),
    # (names that typeset as a taken one were compared as written: L_{} and {L} printed L
    # beside the Lagrangian's partial derivatives, \operatorname{sin} as sin, \partial as
    # the derivatives' symbol; a width "450" was read as a number)
    ({"abbreviations": {"L_{}": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"{L}": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {r"\operatorname{sin}": sp.Symbol("g", positive=True)}},
     "prints like a symbol"),
    ({"abbreviations": {r"\partial": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"abbreviations": {"h_{}": sp.Symbol("g", positive=True)}}, "prints like a symbol"),
    ({"width": "450"}, "number of points from 20 to 16000, got '450'"),
])
def test_bad_options_are_named(pendulum_step, option, message):
    with pytest.raises(LatexOptionError, match=message):
        pendulum_step.latex(**option)


def test_document_is_a_flag(pendulum_step):
    """(document="yes" was taken as True; the momenta's latex refused it.)"""
    with pytest.raises(sg.ShapeError, match="pendulum: document must be True or False"):
        pendulum_step.latex(document="yes")


def test_a_narrower_page_gives_narrower_lines(dp_step):
    """At 250 pt the sums break further (a product wider than the page would stay whole)."""
    tex = dp_step.latex(width=250)
    assert max(_line_widths(tex)) <= 250
    assert tex.count("\\notag") > dp_step.latex().count("\\notag")


# --- laziness ------------------------------------------------------------------------------------

def test_deriving_and_evaluating_never_print(double_pendulum, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("LaTeX printed while deriving")

    monkeypatch.setattr(_printing, "verified_forms", refuse)
    monkeypatch.setattr(_latex.GroupoidLatexPrinter, "doprint", refuse)
    step = double_pendulum.euler_lagrange()
    F, _ = step.evaluate(np.full(2, 0.3), np.full(4, 0.1), np.ones(6))
    assert np.all(np.isfinite(F))


def test_jupyter_shows_the_plain_repr_above_the_display_limit(pendulum_step, monkeypatch):
    assert pendulum_step._repr_latex_().startswith("$$\\begin{aligned}")
    monkeypatch.setattr(_latex, "DISPLAY_LIMIT", 3)
    assert pendulum_step._repr_latex_() is None


def test_derive_on_the_command_line_prints_the_readable_form(pendulum_step, tmp_path, capsys):
    from symgroupoid.cli import main

    path = tmp_path / "pendulum.py"
    path.write_text(PENDULUM)
    assert main(["derive", str(path)]) == 0
    out = capsys.readouterr().out
    assert pendulum_step.latex() in out
    assert "\\frac{q_{k+1} + q_{k-1} - 2 q_{k}}{h}" in out  # collected, over one denominator
    assert re.search(r"% LaTeX written in [0-9.]+ s \([0-9]+ characters\)", out)


# --- page measures, the chosen form, constant matrix parts -------------------------------------

def test_lines_leave_room_for_the_equation_numbers():
    """align centres its block: a number stays on its line only with the number and
    0.5 em free on both sides of the block (measured with pdflatex: a 308 pt row keeps "(6)"
    on a 345 pt page, a 318 pt row does not)."""
    room = _layout.line_room(345.0, numbered=True)
    assert 345.0 - 2 * (18 + _layout.TAG_SEPARATION) >= room * _layout.TEX_PER_MATHTEXT
    assert _layout.line_room(345.0, numbered=False) == pytest.approx(
        345.0 / _layout.TEX_PER_MATHTEXT)


def test_satellite_prints_no_basis_entries_and_is_shorter_than_sympy(satellite_step,
                                                                      entries_step):
    """19 792 characters with 324 entries (E_i)_{jk} before; sympy.latex: 4 029."""
    for step in (satellite_step, entries_step):
        tex = step.latex()
        plain = sum(len(sp.latex(r)) for r in step.residuals)
        assert "E_{" not in tex and "matrix" not in tex
        assert len(tex) <= plain, (len(tex), plain)
        assert _printing.chosen_printed(step).length <= _printing.plain_length(step)


@pytest.mark.parametrize("name", ["plate_ball", "heavy_top", "rigid_body"])
def test_printed_forms_are_never_longer_than_sympy(name, plate_ball_step):
    """The papers' tr(g_k E_i E_j) where it is not longer than the plain printing."""
    step = plate_ball_step if name == "plate_ball" else getattr(systems, name)()\
        .euler_lagrange()
    printed = _printing.chosen_printed(step)
    assert printed.keeps and printed.length <= _printing.plain_length(step)


def test_constant_entries_are_evaluated():
    """(E_1)_{11} (W)_{12} is 0, (W E_1)_{32} is (W)_{33}, tr(E_1ᵀ W) is W_{32} − W_{23};
    tr(W E_1 E_2) keeps its name."""
    G = sg.SO3("W")
    E1, E2 = sp.MatrixSymbol("E_{1}", 3, 3), sp.MatrixSymbol("E_{2}", 3, 3)
    W = sp.MatrixSymbol("W_{k}", 3, 3)
    basis = G.basis_matrices()
    entries = sp.ImmutableMatrix(G.named_matrix(0))
    values = {E1: sp.ImmutableMatrix(basis[0]), E2: sp.ImmutableMatrix(basis[1]), W: entries}
    constants = {E1, E2}

    def evaluated(expr):
        return _matrix_parts.evaluated_constants(expr, values, constants)

    assert evaluated(E1[0, 0] * W[0, 1] + E1[2, 1] * W[0, 1]) == entries[0, 1]
    assert evaluated((W * E1)[2, 1]) == entries[2, 2]
    explicit_transpose = sp.ImmutableMatrix(basis[0]).T
    assert evaluated(sp.Trace(sp.MatMul(explicit_transpose, W))) == entries[2, 1] - entries[1, 2]
    kept = sp.Trace(sp.MatMul(W, E1, E2))
    assert evaluated(kept) == kept and evaluated(sp.Trace(sp.MatMul(E1, E2))) == 0


def test_a_callable_abbreviation_on_a_lie_group_is_checked_at_its_arrow():
    """The "where" row of a callable abbreviation is written at the generic arrow g_j and
    checked at g_k.  On a Lie group (no pieces to carry the renaming) the check compared
    (W_j) with (W_k) entries, so every form failed and the printing raised
    LatexVerificationError."""
    h, i1, i2, i3 = sp.symbols("h I1:4", positive=True)

    def spin(W):
        return sg.SO3.vee(W - W.T) / (2 * h)

    def L(g):
        w = spin(g.matrix)
        return h * (i1 * w[0] ** 2 + i2 * w[1] ** 2 + i3 * w[2] ** 2) / 2

    step = sg.DiscreteSystem(sg.SO3("W"), L, parameters=[h, i1, i2, i3],
                             name="free_body").euler_lagrange()
    tex = step.latex(abbreviations={rf"\Omega_{{{a + 1}}}": (lambda g, a=a: spin(g.matrix)[a])
                                    for a in range(3)})
    assert r"(\Omega_{1})_{j} &= \frac{(W_{j})_{32} - (W_{j})_{23}}{2 h}" in tex
    assert r"(\Omega_{3})_{k+1}" in tex


def test_an_abbreviated_product_is_found_among_more_factors():
    """``abbreviations={"P": m₂·l}`` was reported unused although −l·m₂·(…) was printed:
    only sums were looked for inside terms.  The rows at j say which j they stand for."""
    h, m1, m2, ell = sp.symbols("h m_1 m_2 l", positive=True)

    def L(a):
        q0, q1 = sp.Matrix(a.source), sp.Matrix(a.target)
        (_, th), (vx, vth) = (q0 + q1) / 2, (q1 - q0) / h
        return h * ((m1 + m2) * vx ** 2 / 2 + m2 * ell * vx * vth * sp.cos(th)
                    + m2 * ell ** 2 * vth ** 2 / 2)

    step = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x theta")), L,
                             parameters=[h, m1, m2, ell], name="cart").euler_lagrange()
    with warnings.catch_warnings():
        warnings.simplefilter("error", UnusedAbbreviationWarning)
        tex = step.latex(abbreviations={"P": m2 * ell})
    assert "P &= l m_{2}" in tex and tex.count("l m_{2}") == 1
    assert r"P \Delta \theta_{k+1/2}" in tex


def test_a_denominator_of_one_pair_arrow_is_named():
    """On a pair groupoid a denominator in q_{k−1} and q_k is one arrow's (q_k alone would
    be two arrows'): a rational potential's (1 + q̄²)² printed as an expanded quartic."""
    h, kappa = sp.symbols("h kappa", positive=True)

    def L(a):
        q0, q1 = sp.Matrix(a.source), sp.Matrix(a.target)
        (p, s), (vp, vs) = (q0 + q1) / 2, (q1 - q0) / h
        return h * ((vp ** 2 + vs ** 2) / 2 - kappa / (1 + p ** 2 + s ** 2))

    step = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("phi psi")), L,
                             parameters=[h, kappa], name="rational").euler_lagrange()
    tex = step.latex()
    assert "D_{k+1/2}^{2}" in tex and "D_{k-1/2}^{2}" in tex
    assert (r"D_{j-1/2} &= \left(\frac{\phi_{j-1} + \phi_{j}}{2}\right)^{2} + "
            r"\left(\frac{\psi_{j-1} + \psi_{j}}{2}\right)^{2} + 1") in tex


def test_a_time_groupoid_step_prints_as_derived_when_expanding_spreads_its_quotients():
    """A pendulum on TimeGroupoid (seed 000 Example 6.1): expanded, each quotient by
    (t_{k+1} − t_k)² spread over 2t_{k+1}² − 4t_{k+1}t_k + 2t_k², and the printing took
    1,574 characters against SymPy's 662.  The residuals as derived are printed instead,
    checked like every form, with the square kept."""
    kappa = sp.Symbol("kappa", positive=True)

    def L(a):
        dt, q0, q1 = a.step, a.source[0], a.target[0]
        return dt * (((q1 - q0) / dt) ** 2 / 2 + kappa * sp.cos((q0 + q1) / 2))

    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    step = sg.DiscreteSystem(G, L, parameters=[kappa], name="timed").euler_lagrange()
    text = step.latex()
    plain = sum(len(sp.latex(r)) for r in step.residuals)
    assert len(text) < 1.1 * plain
    assert "t_{k}^{2}" not in text and r"\left(t_{k+1} - t_{k}\right)^{2}" in text
    assert text.count("&= ") == 2
