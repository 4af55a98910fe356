"""LaTeX output: the papers' notation (seed 000 §6.2), and every formula renders."""

from __future__ import annotations

import io
import re
import shutil
import subprocess

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid.derivation import matrix_form_values
from symgroupoid.equations import LatexOptionError
from symgroupoid.groupoids import to_explicit

mathtext = pytest.importorskip("matplotlib.mathtext")
from matplotlib.font_manager import FontProperties  # noqa: E402

PAGE = 450.0  # pt


# --- reading an align environment back ------------------------------------------------------

def _lines(tex: str) -> list[tuple[str, str, bool]]:
    """(left-hand side, body, is a continuation line) of every line of an ``align``."""
    body = tex.split("\\begin{align}\n", 1)[1].rsplit("\n\\end{align}", 1)[0]
    out = []
    for raw in body.split(" \\\\\n"):
        raw = re.sub(r"^\\intertext\{.*\}\n", "", raw).removesuffix(" \\notag")
        lhs, rhs = raw.split("&", 1)
        continuation = rhs.startswith("\\quad ")
        out.append((lhs.strip(), rhs.removeprefix("\\quad ").removeprefix("= "), continuation))
    return out


_PARSER = mathtext.MathTextParser("path")
_FONT = FontProperties(family="DejaVu Sans", size=10, math_fontfamily="dejavusans")


def _width(formula: str) -> float:
    """Rendered width in pt at 10 pt (measured at 720 dpi)."""
    return _PARSER.parse(f"${formula}$", dpi=720, prop=_FONT)[0] / 10


def _line_widths(tex: str) -> list[float]:
    """Each line as it renders in the ``align``: the widest left-hand side of the block (the
    alignment column), ``=``, and ``\\quad`` before a continuation."""
    lines = _lines(tex)
    column = max((lhs for lhs, _, _ in lines if lhs), key=_width)
    quad = "\\quad "
    return [_width(f"{column} = {quad if cont else ''}{body}") for _, body, cont in lines]


def _formulas(latex_align: str) -> list[str]:
    """The right-hand sides of the rows of an ``align`` (continuation lines included), with
    their ``\\notag`` and the ``\\intertext`` before them removed."""
    body = latex_align.split("\\begin{align}")[1].split("\\end{align}")[0]
    out = []
    for line in body.strip().split(" \\\\\n"):
        line = re.sub(r"^\\intertext\{.*\}\n", "", line).removesuffix(" \\notag")
        if "&=" in line:
            out.append(line.split("&=", 1)[1].strip())
        elif line.startswith("&\\quad "):
            out.append(line.removeprefix("&\\quad "))
    return out


def _equations(latex_align: str) -> list[str]:
    """Each numbered equation of an ``align`` whole: its row and continuation lines joined."""
    body = latex_align.split("\\begin{align}")[1].split("\\end{align}")[0]
    out, current = [], []
    for line in body.strip().split(" \\\\\n"):
        current.append(line.split("&", 1)[1].removeprefix("= ").removeprefix("\\quad "))
        if not line.endswith("\\notag"):
            out.append(" ".join(current))
            current = []
    return out


def _renders(formula: str) -> None:
    mathtext.math_to_image(f"${formula}$", io.BytesIO(), format="png")


def test_plate_ball_rotational_rows_read_as_in_seed(plate_ball_step):
    """Seed 000 §6.2 prints the rotational equations with tr(g_k E_i E_j), tr(E_i g_{k+1} E_j)."""
    tex = plate_ball_step.latex()
    assert tex.startswith("\\begin{align}") and tex.rstrip().endswith("\\end{align}")
    equations = _equations(tex)
    assert len(equations) == 8
    for i in (1, 2, 3):
        row = equations[1 + i]
        assert f"\\operatorname{{tr}}(g_{{k}} E_{{{i}}} E_{{{i % 3 + 1}}})" in row
        for j in (1, 2, 3):
            assert f"\\operatorname{{tr}}(E_{{{i}}} g_{{k+1}} E_{{{j}}})" in row
        assert "(g_{k})_{" not in row, "matrix part printed entrywise"
    assert "\\operatorname{tr}(g_{k+1} E_{3})" in equations[7]


def test_constants_of_one_name_keep_their_own_values(heavy_top_step):
    """Two systems whose constant matrices share a name (the fixture's J_d in I_1, I_2, I_3
    and the library's heavy top's J_d in I1, I2, I3): each system's matrix form, built
    after the other's, is written out with its own J_d (the name alone once chose the
    matrix seen last, process-wide)."""
    other = sg.systems.heavy_top().euler_lagrange()
    for step in (other, heavy_top_step, other):
        values = matrix_form_values(step.groupoid, (0, 1))
        assert step.structured is not None
        for s, e in zip(step.structured, step.residuals):
            assert sp.expand(to_explicit(s, values) - e) == 0
        assert "J_{d}" in step.latex()
    J1 = {c.name: c for s in heavy_top_step.structured for c in s.atoms(sp.MatrixSymbol)}
    J2 = {c.name: c for s in other.structured for c in s.atoms(sp.MatrixSymbol)}
    assert J1["J_d"] != J2["J_d"] and str(J1["J_d"]) == str(J2["J_d"]) == "J_d"


def test_matrix_form_equals_explicit_residuals(plate_ball_step, heavy_top_step):
    """The printed (matrix) form is the same equation as the explicit one, exactly."""
    for step in (plate_ball_step, heavy_top_step):
        assert step.structured is not None
        values = matrix_form_values(step.groupoid, (0, 1))
        for s, e in zip(step.structured, step.residuals):
            assert sp.expand(to_explicit(s, values) - e) == 0


def test_named_constant_matrix_prints_by_name(heavy_top_step):
    tex = heavy_top_step.latex()
    assert "\\operatorname{tr}(J_{d} W_{k} E_{1})" in tex
    assert "\\begin{matrix}" not in tex


@pytest.mark.slow  # 9 s; the documents are typeset by LaTeX itself in tests/test_latex_pdf.py
def test_every_formula_renders_with_mathtext(plate_ball, heavy_top, plate_ball_step,
                                            heavy_top_step):
    rigid = sg.DiscreteSystem(sg.SO3("W"), lambda g: (g.matrix * sp.diag(1, 2, 3)).trace(),
                              name="rigid")
    q = sg.EuclideanSpace("q")
    second = sg.SecondOrderSystem(
        sg.PairGroupoid(q), lambda a, b: (b.target[0] - 2 * a.target[0] + a.source[0]) ** 2,
        name="spline")
    lie_poisson = rigid.lie_poisson().latex()
    sources = [plate_ball_step.latex(), heavy_top_step.latex(),
               plate_ball[0].legendre().latex(), heavy_top[0].legendre().latex(),
               lie_poisson, second.euler_lagrange().latex()]
    count = 0
    for tex in sources:
        for formula in _formulas(tex):
            _renders(formula)
            count += 1
        assert max(_line_widths(tex)) <= PAGE
    # Lie–Poisson: μ_{k+1} = Ad*μ_k, 0 = 𝔽⁻L_{k+1} − Ad*𝔽⁻L_k and three "where" rows
    assert count >= 8 + 3 + 10 + 6 + 5 + 1
    # Ad*_{g_k} is printed as an operator, not as its cofactor expansion (seed 000 §6.1)
    assert "\\mu_{k+1} &= \\operatorname{Ad}^{*}_{W_{k}} \\mu_{k}" in lie_poisson
    assert ("0 &= (\\mathbb{F}^{-}L)_{k+1} - \\operatorname{Ad}^{*}_{W_{k}} "
            "(\\mathbb{F}^{-}L)_{k}") in lie_poisson
    assert "((\\mathbb{F}^{-}L)_{j})_{1} &=" in lie_poisson and "(W_{k})_{" not in lie_poisson


def test_standalone_document_and_jupyter(plate_ball_step, tmp_path):
    doc = plate_ball_step.latex(document=True)
    assert doc.startswith("\\documentclass") and "\\end{document}" in doc
    assert "% plate_ball: 8 equations in 8 unknowns" in doc
    rep = plate_ball_step._repr_latex_()
    assert rep.startswith("$$") and rep.endswith("$$") and "aligned" in rep
    if shutil.which("pdflatex") is None:
        pytest.skip("pdflatex not installed; mathtext rendering is tested above")
    (tmp_path / "eq.tex").write_text(doc)
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "eq.tex"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout[-2000:]


def test_symbols_print_in_paper_notation(plate_ball_step):
    assert sg.latex(plate_ball_step.symbol("x", "k+1")) == "x_{k+1}"
    lam = plate_ball_step.symbol("lambda", "k+1")
    assert [sg.latex(v) for v in lam] == [f"(\\lambda_{{k+1}})_{{{a}}}" for a in (1, 2, 3)]
    g = plate_ball_step.symbol("g", "k")
    assert sg.latex(g[0, 1]) == "(g_{k})_{12}"
    assert re.search(r"x_\{k-1\}", plate_ball_step.latex())


# --- what is too large to write out ---------------------------------------------------------

def test_expanded_size_counts_a_shared_node_at_every_use():
    """x·x + (x·x)·y: the graph has 3 operations (x·x once), the written-out formula 4."""
    from symgroupoid.ir import Graph, Program

    x, y = sp.symbols("x y")
    g = Graph()
    square = g.mul(g.input(x), g.input(x))
    total = g.add(square, g.mul(square, g.input(y)))
    program = Program(g, {"z": [x, y]}, {"out": [total]})
    assert program.size(["out"]) == 3 and program.expanded_size(["out"]) == 4
    assert program.expanded_size() == 4  # every output
    for bad in (["nope"], "out", [3]):
        with pytest.raises(sg.DomainError, match="names must be a list of the program's"):
            program.expanded_size(bad)


def test_expanded_terms_on_the_graph_bound_the_sympy_forms():
    """Program.expanded_terms counts as the printers' bound on a SymPy expression counts
    (sums add, products multiply, pⁿ of t terms at most C(t + n − 1, n), the rest one
    term): equal on random expressions, fewer only where the graph folds constants
    (sin 2 + sin 4 is one constant there)."""
    import random

    # white-box: the printers' bound on SymPy expressions is compared with the graph's, and
    # the identity test of the printed forms is watched; no public name reaches either
    from symgroupoid.equations._printing import expanded_terms
    from symgroupoid.ir import Graph, Program, from_sympy

    x, y, z = sp.symbols("x y z")
    rng = random.Random(3)

    def draw(depth):
        if depth == 0:
            return rng.choice([x, y, z, sp.Integer(2), sp.Rational(1, 3)])
        k = rng.random()
        a = draw(depth - 1)
        return (a + draw(depth - 1) if k < 0.35 else a * draw(depth - 1) if k < 0.7
                else a ** rng.randint(2, 3) if k < 0.85 else sp.sin(a) if k < 0.93 else 1 / a)

    for _ in range(200):
        e = draw(rng.randint(1, 5))
        g = Graph()
        node = from_sympy(g, e, {s: g.input(s) for s in (x, y, z)}, "e", {})
        terms = Program(g, {"v": [x, y, z]}, {"F": [node]}).expanded_terms(["F"])
        if any(f.is_number for f in e.atoms(sp.Function)):
            assert terms <= expanded_terms([e]), e
        else:
            assert terms == expanded_terms([e]), e
    g = Graph()
    xs = sp.symbols("x0:100")
    wide = g.add(*[g.input(v) for v in xs])
    s = g.add(g.input(x), g.input(y))
    program = Program(g, {"v": [x, y, *xs]}, {"huge": [g.pow(wide, sp.Integer(100))],
                                               "high": [g.pow(s, sp.Integer(10**6))]})
    assert program.expanded_terms(["huge"]) == 10**30  # C(199, 100), capped
    assert program.expanded_terms(["high"]) == 10**6 + 1 == expanded_terms([(x + y) ** 10**6])
    for bad in (["nope"], "huge", [3]):
        with pytest.raises(sg.DomainError, match="expanded_terms: names must be a list"):
            program.expanded_terms(bad)


def test_a_step_too_large_to_write_out_is_refused_at_once(monkeypatch):
    """A free rigid body discretised at order 4 on SO(3): about 2 000 operations in its
    graph, 10⁹ written out (every stage shares the retraction's subexpressions); printing
    them never finished.  It prints in the group stage notation, checked without writing
    them out (tests/test_group_stage_latex.py); where that form is not offered, the step is
    refused at once, naming the sizes and the limit."""
    # white-box: the group form is taken away to reach the refusal, which no public name does
    from symgroupoid.equations import PRINT_LIMIT, _printing

    J = sp.diag(1, 2, 3)
    h = sp.Symbol("h", positive=True)
    body = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * J * xi)[0, 0] / 2,
                               parameters=[h])
    step = body.discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    assert step.program.expanded_size(["F"]) > 100 * PRINT_LIMIT
    monkeypatch.setattr(_printing, "group_stage_form", lambda *args: None)
    with pytest.raises(sg.UnsupportedFeatureError, match="written out as formulas have"):
        step.latex()


@pytest.mark.slow
def test_a_step_whose_expansion_is_too_large_is_refused_at_once():
    """The second-order attitude problem on SO(3) (seed 001 eqs. (27)–(28)): 4.9·10⁴
    operations written out, under PRINT_LIMIT, but its Cayley quotients' products of sums
    expand to about 1.5·10⁶ terms, and collecting and checking them never finished
    (`symgroupoid derive` sat in "writing the equations as LaTeX" for over ten minutes).
    Refused in about a second, naming the bound and the limit."""
    import time

    from conftest import load_example

    from symgroupoid.equations import EXPANSION_LIMIT, PRINT_LIMIT

    step = load_example("rigid_body_attitude").attitude_system().euler_lagrange()
    assert step.program.expanded_size(["F"]) < PRINT_LIMIT
    t0 = time.perf_counter()
    with pytest.raises(sg.UnsupportedFeatureError,
                       match=r"could have 1\.5\de\+06 terms, more than the 1e\+05") as refused:
        step.latex()
    assert time.perf_counter() - t0 < 30
    assert "rigid_body_attitude" in str(refused.value) and EXPANSION_LIMIT == 100_000


def test_the_expansion_bound_counts_products_of_sums_and_powers():
    """expanded_terms bounds sympy.expand's terms: products of sums multiply, a power of a
    sum counts its monomials, a quotient's denominator and a function are one factor, and
    it is never below the true count on these."""
    from symgroupoid.equations._printing import expanded_terms

    a, b, c, d = sp.symbols("a b c d")
    cases = [(a + b) * (c + d), (a + b + c) ** 3, (a + b) * (c + d) / (a + c + d),
             sp.sin(a + b) * (c + d) + a, (a + b) ** -2 * (c - d) ** 2, a * b]
    exact = [4, 10, 4, 3, 3, 1]
    for e, n in zip(cases, exact):
        assert expanded_terms([e]) == n, e
        assert len(sp.Add.make_args(sp.expand(e))) <= n, e
    # computed at once: exactly where few products do it (it was capped at 10³⁰, a bound
    # far above the 10⁶ + 1 monomials), capped where the count is past the cap
    assert expanded_terms([(a + b) ** 10**6]) == 10**6 + 1
    assert expanded_terms([sp.Add(*sp.symbols("y0:100")) ** 10**6]) == 10**30


def test_the_expansion_bound_walks_deep_expressions_without_recursion():
    """A Horner-like nest three times deeper than Python's recursion limit (a long chain's
    recurrences) is counted, not a RecursionError: each level adds one term."""
    import sys

    from symgroupoid.equations._printing import expanded_terms

    x, y = sp.symbols("x y")
    depth = 3 * sys.getrecursionlimit()
    e = x
    for i in range(depth):
        e = sp.Add(sp.Mul(e, y, evaluate=False), sp.Integer(i + 1), evaluate=False)
    assert expanded_terms([e]) == depth + 1


@pytest.mark.parametrize("junk", [object(), "x", None, np.array([1.0, 2.0]),
                                  [sp.Symbol("x"), object()]],
                         ids=["object", "string", "None", "array", "list-with-object"])
def test_latex_of_what_is_not_mathematics_is_refused(junk):
    """SymPy prints an arbitrary object as its repr in typewriter type (an array as
    ``\\mathtt{\\text{[1. 2.]}}``): refused by name instead, as is an unknown setting."""
    with pytest.raises(LatexOptionError, match="latex: expected a SymPy expression"):
        sg.latex(junk)


def test_latex_prints_expressions_numbers_and_containers_and_refuses_unknown_settings():
    x = sp.Symbol("x")
    assert sg.latex([x ** 2, 1.5, {x: 2}]) == \
        r"\left[ x^{2}, \  1.5, \  \left\{ x : 2\right\}\right]"
    with pytest.raises(LatexOptionError, match="Unknown setting 'colour'"):
        sg.latex(x, colour="red")


def test_the_printed_forms_zero_test_agrees_with_cancel():
    """The exact identity test of the printed forms (``equals_explicit``) brings a
    difference over the lcm of its factored denominators instead of SymPy's ``together``
    (seconds per row on SE(3) in Cayley coordinates, where the denominators are powers of
    1 + tr g in several expanded forms): the same verdict as ``cancel(together(·))`` on
    random rational differences, None where it is not rational over Q."""
    import random

    from symgroupoid._rational import vanishes

    x, y, z = sp.symbols("x y z")
    D = 1 + x + y + z
    assert vanishes(sp.expand(2 / (2 * D ** 2) - 1 / sp.expand(D ** 2))) is True
    assert vanishes(sp.expand(x / (x ** 2 - 1) - 1 / (2 * (x + 1)) - 1 / (2 * (x - 1))))
    assert vanishes(sp.expand(1 / (x + 1) - 1 / (x + 2))) is False
    assert vanishes(sp.sin(x) / (x + 1)) is None and vanishes(sp.cbrt(2) / (x + 1)) is None
    r2, r3, r6 = sp.sqrt(2), sp.sqrt(3), sp.sqrt(6)  # the Gauss nodes' square roots
    assert vanishes(sp.sqrt(2) / (x + 1)) is False
    assert vanishes(sp.expand(r2 / (x + r3) - (r2 * x - r6) / (x ** 2 - 3))) is True
    assert vanishes(sp.expand(r6 / (x + r3) - r2 * (x - r3) / (x ** 2 - 3))) is False
    assert vanishes(sp.expand(1 / D ** 3 - D / sp.expand(D ** 4))) is True  # D⁴ expanded
    rng = random.Random(7)
    atoms = [x, y, z, D, 1 + x * y, x - z]
    for trial in range(10):
        terms = [sp.Rational(rng.randint(-3, 3), rng.randint(1, 3)) * rng.choice(atoms)
                 / rng.choice(atoms[3:]) ** rng.randint(1, 2) for _ in range(3)]
        e = sp.Add(*terms)
        together = sp.together(e)
        for candidate in (e - together, e - together + x / D):
            difference = sp.expand(candidate)
            # the reference verdict: cancel(together(·)) on three of the ten (it takes
            # seconds each); on all, the difference's exact value at a random rational point
            # (e − together(e) ≡ 0, and x/D is not 0 at the point)
            point = {v: sp.Rational(rng.randint(5, 50), rng.randint(51, 97)) for v in (x, y, z)}
            reference = (sp.cancel(sp.together(difference)) == 0 if trial < 3
                         else difference.subs(point) == 0)
            assert vanishes(difference) == reference


def test_a_large_difference_is_tested_at_random_points():
    """The printed equations of a heavy top with rotors (examples/heavy_top_rotors.py) left
    differences of 2,012 terms over powers of several Cayley denominators, which the common
    denominator took hours to bring together: from LARGE_TERMS terms on, the difference is
    evaluated exactly at random rational points (a nonzero value refutes it for certain),
    with the same verdicts as the exact test."""
    from symgroupoid._rational import LARGE_TERMS, vanishes, vanishes_at_points

    x, y, z = sp.symbols("x y z")
    D, E = 1 + x**2 + y**2 + z**2, 1 + x * y - z
    big = sp.expand((x + y + z + 1) ** 12)  # 455 terms
    assert len(big.args) > LARGE_TERMS
    zero = sp.expand(big / D + big / E) - sp.expand(big * (D + E) / sp.expand(D * E))
    assert vanishes_at_points(sp.expand(zero)) is True
    off = sp.expand(zero + x / (D * E) ** 2)
    assert vanishes_at_points(off) is False
    assert vanishes_at_points(sp.sin(x) + big) is None  # not rational: the exact test decides
    assert vanishes_at_points(sp.sqrt(2) * x) is None
    assert vanishes_at_points(1 / (x - x * y) - 1 / (x - x * y)) is True
    small = sp.expand(1 / (x + 1) - 1 / (x + 2))  # the same verdict as the exact test
    assert vanishes_at_points(small) is vanishes(small) is False


def test_a_large_printed_equation_is_tested_at_points_before_it_is_expanded(monkeypatch):
    """The printed junction rows of the heavy top with rotors differ from the explicit
    residuals, written out, by 31,000-node expressions that took 13–16 s each to expand
    (the print: 81 s); from LARGE_NODES nodes unexpanded they are decided at random rational
    points first (0.3 s each; the print: 33 s, the same document).  A printed form that
    differs is refuted as before, and a small one is still decided exactly."""
    from symgroupoid._rational import vanishes_at_points
    from symgroupoid.equations import _forms

    x, y, z = sp.symbols("x y z")
    D = 1 + x**2 + y**2 + z**2
    printed = sp.Add(*[((x + k * y) ** 3 - z) / D ** (k % 3 + 1) for k in range(300)])
    explicit = sp.expand(sp.together(printed))
    calls = []

    def spy(expr):
        calls.append(expr)
        return vanishes_at_points(expr)

    monkeypatch.setattr(_forms, "vanishes_at_points", spy)
    assert _forms.equals_explicit(printed, explicit, [])
    assert calls == [printed - explicit]  # as written: not expanded
    assert not _forms.equals_explicit(printed + x / D ** 7, explicit, [])
    calls.clear()
    assert _forms.equals_explicit(x / D + y, (x + y * D) / D, []) and not calls
    assert not _forms.equals_explicit(x / D + y, x / D, [])


def test_a_lagrangian_with_float_coefficients_prints():
    """(0.5·(q₁ − q₀)²/h − 0.3·h·q₀q₁ made every printed form raise a raw AttributeError:
    the printer took each coefficient for a fraction.)  It prints, with its floats, and the
    printed form is checked against the residuals as any other."""
    h = sp.Symbol("h", positive=True)
    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a: 0.5 * (a.target[0] - a.source[0]) ** 2 / h - h * 0.3 * a.source[0] * a.target[0],
        parameters=[h], name="floats")
    tex = system.euler_lagrange().latex()
    assert "0.3" in tex and "q_{k+1}" in tex
    assert "0.3" in system.legendre().latex()


def test_a_sum_of_parameters_over_a_parameter_prints_without_a_unit_factor():
    """(1/h)(I₁ − I₂ − I₃) inside a sum printed \\frac{1 (I_1 - I_2 - I_3)}{h}."""
    from symgroupoid import systems

    h, e = sp.symbols("h e", positive=True)
    inertias = sp.symbols("I1 I2 I3", positive=True)
    Jd = systems.discrete_inertia(*inertias)
    body = sg.DiscreteSystem(sg.SO3("W"),
                             lambda g: -(Jd * g.matrix).trace() / h + e * g.matrix[0, 0],
                             parameters=[h, *inertias, e], name="tilted")
    text = body.legendre().latex()
    assert r"\frac{1 \left(" not in text
    assert r"2 e + \frac{I_{1} - I_{2} - I_{3}}{h}" in text


def test_numbered_parameters_print_in_the_order_of_their_numbers():
    """SymPy orders names as strings: α₁ α₁₀ α₁₁ α₂ … in a product."""
    h = sp.Symbol("h", positive=True)
    alphas = sp.symbols("alpha_1:12", positive=True)
    step = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("x")),
        lambda a: (a.target[0] - a.source[0]) ** 2 / (2 * h) - h * sp.Mul(*alphas) * a.target[0],
        parameters=[h, *alphas], name="numbered").euler_lagrange()
    product = " ".join(rf"\alpha_{{{i}}}" for i in range(1, 12))
    assert product in step.latex()
