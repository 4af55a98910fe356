"""Documents that typeset whole, and SO(3) systems printed without their basis entries.

Targets: a document breaks its lines at the width of its own page (geometry), its displays
break across pages, a term too wide for a line is set smaller, and pdflatex places every
equation — ``pdftotext`` shows each equation number and the log no overfull box beyond 1 pt —
for the seed systems (``symgroupoid/systems.py``) and a satellite with a reaction wheel;
``derive --pdf`` fails with :class:`LostContentError` when LaTeX reports lost content.  The
satellite uses the abbreviations it is given (warning about those it does not); that,
written with Ω = vee(W − Wᵀ)/(2h) or with the entries of W, it prints no entry of a basis
matrix (E_a)_{ij} and is never longer than ``sympy.latex`` of its residuals is checked with
the printer's own measures in tests/test_latex_layout.py.

The tests that typeset skip when pdflatex or pdftotext is missing (``.ci/run`` installs
them: TeX Live's texlive-latex-base and poppler-utils).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import warnings
from pathlib import Path

import pytest
import sympy as sp
from kernel_support import REPO

import symgroupoid as sg
from symgroupoid import systems
from symgroupoid.cli import OVERFULL_TOLERANCE, load_system, lost_content, main
from symgroupoid.equations import PAGE_WIDTH, UnusedAbbreviationWarning, WideLinesWarning

needs_tex = pytest.mark.skipif(
    shutil.which("pdflatex") is None or shutil.which("pdftotext") is None,
    reason="pdflatex or pdftotext is not installed (TeX Live's texlive-latex-base and "
           "poppler-utils; .ci/run installs them)")

SATELLITE = REPO / "examples" / "cli" / "satellite.py"

#: the satellite as first written: Ω from the entries of W (what printed 324 entries
#: (E_i)_{jk} of the basis matrices, in 19 792 characters)
SATELLITE_ENTRIES = '''
import sympy as sp
import symgroupoid as sg

h, I1, I2, I3, Jw = sp.symbols("h I1 I2 I3 J_w", positive=True)


def satellite() -> sg.DiscreteSystem:
    G = sg.SO3("W") * sg.PairGroupoid(sg.EuclideanSpace("theta"))

    def L(g):
        W = g[0].matrix
        (th0,), (th1,) = g[1].source, g[1].target
        A = W - W.T
        w = sp.Matrix([A[2, 1], A[0, 2], A[1, 0]]) / (2 * h)
        return h * ((w.T * sp.diag(I1, I2, I3) * w)[0, 0] / 2
                    + Jw * (w[2] + (th1 - th0) / h) ** 2 / 2)

    return sg.DiscreteSystem(G, L, parameters=[h, I1, I2, I3, Jw], name="satellite")
'''

#: one equation whose last term, h sin(q_k + p_1 + … + p_24), is wider than any page
WIDE = '''
import sympy as sp
import symgroupoid as sg

h = sp.Symbol("h", positive=True)
p = sp.symbols("p_1:25", positive=True)


def L(arrow):
    (q0,), (q1,) = arrow.source, arrow.target
    return h * (((q1 - q0) / h) ** 2 / 2 + sp.cos(q0 + sum(p)))


system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, *p],
                           name="wide")
'''


def _file(tmp_path: Path, name: str, source: str) -> Path:
    path = tmp_path / f"{name}.py"
    path.write_text(source)
    return path


@pytest.fixture(scope="module")
def satellite():
    """The satellite of examples/cli/satellite.py (Ω = vee(W − Wᵀ)/(2h)) and its file."""
    return load_system(str(SATELLITE))


@pytest.fixture(scope="module")
def satellite_step(satellite):
    return satellite.system.euler_lagrange()


@pytest.fixture(scope="module")
def entries_step(tmp_path_factory):
    path = _file(tmp_path_factory.mktemp("satellite"), "satellite", SATELLITE_ENTRIES)
    return load_system(str(path)).system.euler_lagrange()


def typeset(document: str, folder: Path) -> tuple[str, str]:
    """pdflatex's log and pdftotext's text (``-layout``) of ``document``."""
    tex = folder / "doc.tex"
    tex.write_text(document)
    run = subprocess.run(["pdflatex", "-interaction=nonstopmode", "-halt-on-error", tex.name],
                         cwd=folder, capture_output=True, text=True, errors="replace",
                         timeout=300)
    assert run.returncode == 0, run.stdout[-3000:]
    text = subprocess.run(["pdftotext", "-layout", "doc.pdf", "-"], cwd=folder,
                          capture_output=True, text=True, check=True, timeout=60).stdout
    return (folder / "doc.log").read_text(errors="replace"), text


def equation_numbers(text: str) -> list[int]:
    """The equation numbers at the ends of the lines of a PDF's text."""
    return [int(n) for n in re.findall(r"\((\d+)\)\s*$", text, re.M)]


def assert_typesets_whole(step, folder: Path, **options) -> str:
    """The document of ``step`` typesets with every equation number, in order, and no box
    beyond 1 pt past its page; its LaTeX."""
    document = step.latex(document=True, **options)
    log, text = typeset(document, folder)
    assert equation_numbers(text) == list(range(1, len(step) + 1)), text[-3000:]
    assert lost_content(log, tolerance=1.0) == [], step.name
    return document


# --- the page -------------------------------------------------------------------------------------

def test_documents_are_as_wide_as_their_lines_and_break_across_pages():
    step = systems.rigid_body().euler_lagrange()
    doc = step.latex(document=True, width=300)
    assert "\\usepackage[a4paper,textwidth=300pt,vmargin=2.5cm]{geometry}" in doc
    assert "\\allowdisplaybreaks" in doc
    assert f"textwidth={PAGE_WIDTH:g}pt" in step.latex(document=True)


@needs_tex
def test_a_small_document_typesets_whole(tmp_path):
    """The rigid body's three equations, each number on the page, nothing past its margins."""
    assert_typesets_whole(systems.rigid_body().euler_lagrange(), tmp_path)


@needs_tex
def test_a_text_wider_than_a4_gets_a_wider_paper(tmp_path):
    """A text 700 pt wide on A4 (597.5 pt) ran off the paper, equation numbers first, with no
    overfull box in the log: the paper now leaves an inch on either side of the text."""
    step = systems.planar_chain(2).euler_lagrange()
    document = step.latex(document=True, width=700)
    assert "paperwidth=844.54pt,paperheight=297mm,textwidth=700pt" in document
    assert "a4paper" in step.latex(document=True, width=452)
    log, text = typeset(document, tmp_path)
    assert equation_numbers(text) == list(range(1, len(step) + 1)), text[-3000:]
    assert "Package geometry Warning" not in log


@needs_tex
def test_a_term_wider_than_the_page_is_set_smaller(tmp_path):
    step = _system(WIDE).euler_lagrange()
    plain = step.latex()
    assert "\\scalebox" not in plain  # the align alone: for any page, left whole
    document = assert_typesets_whole(step, tmp_path)
    assert re.search(r"\\scalebox\{0\.\d\d\}\{\$\\displaystyle - h \\sin\(q_\{k\}", document)


def _system(source: str):
    namespace: dict = {}
    exec(compile(source, "<system>", "exec"), namespace)
    return namespace["system"]


@needs_tex
@pytest.mark.slow
@pytest.mark.parametrize("name", ["plate_ball", "heavy_top", "rigid_body"])
def test_seed_documents_typeset_whole(name, tmp_path):
    assert_typesets_whole(getattr(systems, name)().euler_lagrange(), tmp_path)


@needs_tex
@pytest.mark.slow
def test_satellite_documents_typeset_whole(satellite, satellite_step, entries_step, tmp_path):
    for i, (step, options) in enumerate([
            (satellite_step, {}), (entries_step, {}),
            (satellite_step, {"abbreviations": satellite.convention("ABBREVIATIONS")}),
            (satellite_step, {"width": 300})]):
        folder = tmp_path / str(i)
        folder.mkdir()
        assert_typesets_whole(step, folder, **options)


@needs_tex
def test_derive_pdf_of_the_plate_ball_has_every_equation(tmp_path, capsys):
    """The command line's PDF of seed 000 §6.2 (259 pt past the margin before)."""
    path = _file(tmp_path, "plate", "from symgroupoid import systems\n"
                                     "plate_ball = systems.plate_ball\n")
    tex = tmp_path / "plate.tex"
    assert main(["derive", f"{path}:plate_ball", "--document", str(tex), "--pdf"]) == 0
    text = subprocess.run(["pdftotext", "-layout", str(tex.with_suffix(".pdf")), "-"],
                          capture_output=True, text=True, check=True).stdout
    assert equation_numbers(text) == list(range(1, 9))
    log = tex.with_suffix(".log").read_text(errors="replace")
    assert lost_content(log, tolerance=1.0) == []


# --- lost content ---------------------------------------------------------------------------------

LOG = """\
Overfull \\hbox (69.63286pt too wide) detected at line 132
[]
Overfull \\hbox (2.5pt too wide) detected at line 140
Overfull \\vbox (2523.39365pt too high) has occurred while \\output is active []
Missing character: There is no ^^A in font cmr10!
"""


def test_the_log_tells_lost_content():
    assert lost_content(LOG) == [
        "a line 69.6 pt too wide (detected at line 132)", "a page 2523.4 pt too high",
        "character ^^A missing from font cmr10"]
    assert 2.5 < OVERFULL_TOLERANCE
    assert lost_content(LOG, tolerance=1.0)[1] == "a line 2.5 pt too wide (detected at line 140)"
    assert lost_content("Overfull \\hbox (0.4pt too wide) in paragraph at lines 3--4\n") == []


def _fake_pdflatex(folder: Path, log: str) -> Path:
    """A pdflatex (first on PATH) that writes NAME.pdf and NAME.log (``log``) for its last
    argument NAME.tex."""
    tools = folder / "tools"
    tools.mkdir()
    (folder / "fake.log").write_text(log)
    fake = tools / "pdflatex"
    fake.write_text('#!/bin/sh\nfor last; do :; done\nprintf %%PDF > "${last%.tex}.pdf"\n'
                    f'cp {folder / "fake.log"} "${{last%.tex}}.log"\n')
    fake.chmod(0o755)
    return tools


def test_derive_pdf_fails_on_lost_content(tmp_path, capsys, monkeypatch):
    path = _file(tmp_path, "wide", WIDE)
    monkeypatch.setenv("PATH", f"{_fake_pdflatex(tmp_path, LOG)}{os.pathsep}/usr/bin:/bin")
    code = main(["derive", str(path), "--document", str(tmp_path / "wide.tex"), "--pdf"])
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("symgroupoid: error:")]
    assert code == 1 and len(errors) == 1 and "Traceback" not in err
    err = errors[0]
    assert err.startswith("symgroupoid: error: pdflatex could not fit all of ")
    assert "a line 69.6 pt too wide (detected at line 132); a page 2523.4 pt too high" in err
    assert "ABBREVIATIONS" in err and f"see {tmp_path / 'wide.log'}" in err
    # the incomplete PDF and its log are written beside the document, as the error says
    assert (tmp_path / "wide.pdf").read_bytes() == b"%PDF"
    assert (tmp_path / "wide.log").read_text() == LOG


@needs_tex
def test_derive_pdf_fails_when_a_line_runs_past_the_page(tmp_path, capsys, monkeypatch):
    """With the wide term left at full size, pdflatex's overfull box is an error."""
    monkeypatch.setattr("symgroupoid.equations._layout.SMALLEST_SCALE", 1.0)  # the fault
    path = _file(tmp_path, "wide", WIDE)
    with pytest.warns(WideLinesWarning):  # (said before pdflatex runs)
        code = main(["derive", str(path), "--document", str(tmp_path / "wide.tex"), "--pdf"])
    err = capsys.readouterr().err
    assert code == 1 and "pdflatex could not fit all of" in err and "pt too wide" in err


# --- SO(3) systems written with matrix entries ----------------------------------------------------

def test_satellite_uses_its_abbreviations_and_names_the_unused(satellite, satellite_step):
    abbreviations = dict(satellite.convention("ABBREVIATIONS"))
    abbreviations["M"] = sp.Symbol("I1", positive=True) + sp.Symbol("I2", positive=True)
    with pytest.warns(UnusedAbbreviationWarning, match="abbreviation M does not") \
            as caught:
        tex = satellite_step.latex(abbreviations=abbreviations)
    assert [w.message.names for w in caught] == [["M"]]
    for a in (1, 2, 3):
        assert f"(\\Omega_{{{a}}})_{{k+1/2}}" in tex
        assert f"(\\Omega_{{{a}}})_{{j-1/2}} &= " in tex or \
            f"(\\Omega_{{{a}}})_{{j-1/2}} = " in tex
    assert "M = " not in tex and len(tex) < len(satellite_step.latex())


def test_derive_prints_the_abbreviations_it_did_not_use(tmp_path, capsys):
    path = _file(tmp_path, "pendulum", '''
import sympy as sp
import symgroupoid as sg

h, g = sp.symbols("h g", positive=True)


def L(arrow):
    (q0,), (q1,) = arrow.source, arrow.target
    return h * (((q1 - q0) / h) ** 2 / 2 + g * sp.cos((q0 + q1) / 2))


system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, g],
                           name="pendulum")
ABBREVIATIONS = {"G": 2 * g, r"\\vartheta": lambda a: (a.source[0] + a.target[0]) / 2}
''')
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # reported as a line, not as a Python warning
        assert main(["derive", str(path)]) == 0
    out = capsys.readouterr().out
    assert "% abbreviations not used (not a part of the printed equations): G\n" in out
    assert "\\sin(\\vartheta_{" in out


def test_derive_names_malformed_abbreviations(tmp_path, capsys):
    path = _file(tmp_path, "wide", WIDE + 'ABBREVIATIONS = [("M", 1)]\n')
    assert main(["derive", str(path)]) == 1
    err = capsys.readouterr().err
    assert "wide.py:system: ABBREVIATIONS: latex: abbreviations must be a mapping" in err


def test_a_document_line_that_will_not_fit_even_at_half_size_is_reported(tmp_path):
    """The optimal-control step on SO(3) had 168 of 306 lines wider than its page at half
    size, cut off in the PDF without a word; such a line now raises a WideLinesWarning (the
    command line's --pdf then fails with LostContentError, above)."""
    step = load_system(str(_file(tmp_path, "wide", WIDE))).system.euler_lagrange()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        step.latex(document=True)  # its wide term fits at a smaller size
    with pytest.warns(WideLinesWarning, match="will not fit the page even at half size") \
            as caught:
        step.latex(document=True, width=150)
    warning = caught[0].message
    assert str(warning).endswith("or abbreviations= that name their long parts")
    assert warning.widths and min(warning.widths) > 2 * warning.room
    assert caught[0].filename == __file__


@needs_tex
def test_lie_poisson_and_legendre_print_as_documents(tmp_path):
    """Their align blocks had no document form: rows too wide for the page (the SO(3)
    optimal-control problem's momenta, up to 1,433 pt) could not be set smaller, nor were
    they reported.  As documents they typeset (what cannot fit is a WideLinesWarning:
    below)."""
    rigid = systems.rigid_body()
    for i, document in enumerate([rigid.lie_poisson().latex(document=True),
                                  rigid.legendre().latex(document=True)]):
        folder = tmp_path / str(i)
        folder.mkdir()
        log, _ = typeset(document, folder)
        assert lost_content(log, tolerance=1.0) == []
    with pytest.raises(sg.ShapeError, match="document must be True or False"):
        rigid.lie_poisson().latex(document="yes")
    # what cannot fit is reported with the advice these printings can take (they take no
    # abbreviations: a step's warning names them)
    with pytest.warns(WideLinesWarning, match=r"larger width= \(a landscape page\)$"):
        rigid.lie_poisson().latex(document=True, width=40)


@needs_tex
def test_a_noether_quantity_prints_as_a_document(tmp_path):
    """latex() of a Noether quantity is one line (1,520 characters for a forced
    oscillator's on a time groupoid: 2,140 pt past a page), and took no width or document;
    with either it is the row F_X = … broken to the width, and its document typesets
    without a box past the page."""
    kappa, omega = sp.symbols("kappa omega", positive=True)

    def Ld(a):
        dt, q0, q1 = a.step, a.source[0], a.target[0]
        t = (a.t0 + a.t1) / 2
        return dt * (((q1 - q0) / dt) ** 2 / 2
                     - kappa * (1 + sp.cos(omega * t)) * ((q0 + q1) / 2) ** 2 / 2)

    system = sg.DiscreteSystem(sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q"))), Ld,
                               parameters=[kappa, omega], name="pumped")
    energy = system.noether(0)
    line = energy.latex()
    assert r"\\" not in line and len(line) > 1000
    rows = energy.latex(width=300)
    assert rows.startswith("\\begin{align}\nF_{X} &= ") and rows.count(r"\notag") > 5
    log, text = typeset(energy.latex(document=True), tmp_path)
    assert lost_content(log, tolerance=1.0) == [] and "FX=" in text.replace(" ", "")
    with pytest.raises(sg.equations.LatexOptionError, match="width must be a number"):
        energy.latex(width=-3)


DENOMINATOR_ROW = "D_{j} &= (g_{j})_{11} + (g_{j})_{22} + (g_{j})_{33} + 1"


@pytest.fixture(scope="module")
def so3_control():
    import _systems

    return _systems.so3_control_system()


@pytest.mark.slow
def test_the_cayley_denominator_is_named_and_the_control_step_fits(so3_control, tmp_path):
    """The optimal-control step of seed 000 §6.1 on SO(3) (L and φ in the Cayley
    coordinates τ⁻¹(g)/h) divides by powers of 1 + tr g: expanded, 222 of its lines ran off
    the page even at half size (1,855 pt).  Named D_j, every line fits and the document
    typesets whole."""
    step = so3_control.euler_lagrange()
    with warnings.catch_warnings():
        warnings.simplefilter("error", WideLinesWarning)
        document = assert_typesets_whole(step, tmp_path)
    assert DENOMINATOR_ROW in document and "scalebox" not in document
    assert "D_{k+1}^{2}" in document and "(g_{k+1})_{33}^{2}" not in document


@pytest.mark.slow
def test_the_named_denominator_takes_a_free_name(so3_control):
    """A user's abbreviation named D keeps its name; the denominator takes the next one."""
    step = so3_control.euler_lagrange()
    tex = step.latex(abbreviations={"D": lambda g: g.matrix[0, 1] - g.matrix[1, 0]})
    assert "D_{j} &= (g_{j})_{12} - (g_{j})_{21}" in tex
    assert r"\mathcal{D}_{j} = (g_{j})_{11} + (g_{j})_{22} + (g_{j})_{33} + 1" in tex


@pytest.mark.slow
def test_the_so3_control_momenta_fit_with_the_denominator_named(so3_control, tmp_path):
    """(20 s.)  The Lie–Poisson equations and the Legendre transforms of the same problem:
    94 lines of its momenta (up to 1,433 pt) would not fit even at half size."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", WideLinesWarning)
        for i, printout in enumerate((so3_control.lie_poisson(), so3_control.legendre())):
            document = printout.latex(document=True)
            folder = tmp_path / str(i)
            folder.mkdir()
            log, _ = typeset(document, folder)
            assert lost_content(log, tolerance=1.0) == []
            assert "scalebox" not in document
            assert (DENOMINATOR_ROW if i == 0 else DENOMINATOR_ROW.replace("j}", "k}")) \
                in document
