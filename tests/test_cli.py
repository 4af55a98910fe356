"""The ``symgroupoid`` command line on system files written to a temporary directory.

Every command runs in process through ``symgroupoid.cli.main`` (one kernel build per system
for the whole module, in a module-wide cache); one real run of the console script checks
the installed entry point, its exit status and its one-line error.
"""

from __future__ import annotations

import json
import math
import os
import re
import shlex
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _hostile_cases import case_of
from kernel_support import REPO, isolated_cache, needs_cc  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid import ParameterError, ShapeError
from symgroupoid.cli import (
    JACOBIAN_TOLERANCE,
    InputError,
    SystemFileError,
    conservation_lines,
    load_system,
    main,
    parse_count,
    parse_params,
    sample_points,
)
from symgroupoid.runtime.toolchain import cache_info, clear_cache

EXAMPLES = REPO / "examples" / "cli"
#: a particle on a circle (pair groupoid of R², one constraint; rotations are a symmetry,
#: translations are not), the system found through its annotated function
RING = (EXAMPLES / "ring.py").read_text()
#: a discrete harmonic oscillator on R, a top-level system object
SPRING = (EXAMPLES / "spring.py").read_text()

RING_INITIAL = {"x": [1.0, math.cos(0.01)], "y": [0.0, math.sin(0.01)], "lambda": [0.0]}
RING_PARAMS = {"h": 0.01, "r": 1.0}


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("systems")
    (folder / "ring.py").write_text(RING)
    (folder / "spring.py").write_text(SPRING)
    return folder


@pytest.fixture(scope="module")
def kernels(tmp_path_factory) -> Path:
    """One kernel cache for the module: each system is compiled once."""
    return tmp_path_factory.mktemp("kernels")


@pytest.fixture
def cached(isolated_cache, kernels, monkeypatch):  # noqa: F811
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(kernels))
    return kernels


def run(capsys, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("symgroupoid: error:")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


# --- system files -------------------------------------------------------------------------------

def test_system_file_selection(tmp_path, files):
    assert load_system(str(files / "ring.py")).name == "ring"  # the annotated function
    assert load_system(str(files / "spring.py")).name == "spring"  # the top-level object
    chosen = load_system(f"{files / 'ring.py'}:ring")
    assert isinstance(chosen.system, sg.DiscreteSystem) and chosen.system.name == "ring"

    two = tmp_path / "two.py"
    two.write_text(SPRING + "other = spring\nthird = sg.DiscreteSystem(spring.groupoid, L, "
                   "parameters=[h, k], name='third')\n")
    with pytest.raises(SystemFileError, match=r"several systems; choose one: two.py:spring, "
                                              r"two.py:third"):
        load_system(str(two))
    assert load_system(f"{two}:third").system.name == "third"
    with pytest.raises(SystemFileError, match=r"defines no 'nope' \(systems: spring, other, "
                                              r"third\)$"):
        load_system(f"{two}:nope")
    with pytest.raises(SystemFileError, match=r"helper needs arguments"):
        load_system(f"{files / 'ring.py'}:helper")
    with pytest.raises(SystemFileError, match=r"PARAMS is a dict, not a DiscreteSystem"):
        load_system(f"{files / 'ring.py'}:PARAMS")

    bare = tmp_path / "bare.py"
    bare.write_text("def make():\n    return 1\n")
    with pytest.raises(SystemFileError, match=r"defines no system.*functions without "
                                              r"arguments: make"):
        load_system(str(bare))
    with pytest.raises(SystemFileError, match=r"make\(\) returned int, not a DiscreteSystem"):
        load_system(f"{bare}:make")
    with pytest.raises(SystemFileError, match=r"no such file"):
        load_system(str(tmp_path / "missing.py"))
    # a system function imported from another module is named in the message, not taken
    (tmp_path / "ringmodule.py").write_text((files / "ring.py").read_text())
    importer = tmp_path / "importer.py"
    importer.write_text(f"import sys\nsys.path.insert(0, {str(tmp_path)!r})\n"
                        f"from ringmodule import ring\n")
    with pytest.raises(SystemFileError, match=r"imported from other modules: ring \(name "
                                              r"one: FILE.py:ring\)"):
        load_system(str(importer))
    assert load_system(f"{importer}:ring").system.name == load_system(
        str(files / "ring.py")).system.name


def test_system_file_errors_are_one_line_and_debug_shows_the_traceback(tmp_path, capsys):
    broken = tmp_path / "broken.py"
    broken.write_text("import math\nvalue = math.sqrt(-1)\n")
    code, out, err = run(capsys, "derive", broken)
    assert code == 1 and out == ""
    assert one_line_error(err) == (f"symgroupoid: error: {broken}: importing it raised "
                                   f"ValueError: math domain error (--debug shows the "
                                   f"traceback)")
    with pytest.raises(SystemFileError) as caught:
        main(["--debug", "derive", str(broken)])
    assert isinstance(caught.value.__cause__, ValueError)
    with pytest.raises(SystemFileError):
        main(["derive", str(broken), "--debug"])  # after the command too


# --- derive and emit ----------------------------------------------------------------------------

def test_derive_prints_latex_sizes_and_times(files, capsys):
    code, out, err = run(capsys, "derive", files / "ring.py")
    assert code == 0
    assert "% ring: 3 equations in 3 unknowns (order 1, 1 constraint, 5 knowns)" in out
    assert "% Jacobian 3×3: 6 structurally nonzero entries" in out
    assert "% derived in " in out and "% LaTeX written in " in out
    assert "\\begin{align}" in out and "\\frac{x_{k+1} + x_{k-1} - 2 x_{k}}{h}" in out


def test_derive_document_and_pdf(files, tmp_path, capsys, monkeypatch):
    tex = tmp_path / "ring.tex"
    code, out, _ = run(capsys, "derive", files / "ring.py", "--document", tex)
    assert code == 0 and f"wrote {tex}" in out
    assert tex.read_text().startswith("\\documentclass")

    monkeypatch.setenv("PATH", str(tmp_path / "no-tools"))
    code, out, err = run(capsys, "derive", files / "ring.py", "--document", tex, "--pdf")
    assert code == 1
    assert "--pdf needs pdflatex on PATH" in one_line_error(err)

    tools = tmp_path / "tools"
    tools.mkdir()
    fake = tools / "pdflatex"  # writes NAME.pdf and an empty NAME.log for its last argument
    fake.write_text('#!/bin/sh\nfor last; do :; done\nprintf %%PDF > "${last%.tex}.pdf"\n'
                    ': > "${last%.tex}.log"\n')
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", str(tools))
    code, out, _ = run(capsys, "derive", files / "ring.py", "--document", tex, "--pdf")
    assert code == 0 and f"wrote {tex.with_suffix('.pdf')}" in out
    assert tex.with_suffix(".pdf").read_bytes() == b"%PDF" and tex.with_suffix(".log").exists()

    # (pdflatex wrote OUT.pdf in place: a run that failed — a full disk, a TeX error —
    # left no PDF where the earlier run's was) the earlier PDF is kept, the log beside it
    fake.write_text('#!/bin/sh\nfor last; do :; done\necho "! TeX capacity exceeded"\n'
                    'echo "the failed run" > "${last%.tex}.log"\n'
                    'printf %%PDF-half > "${last%.tex}.pdf"\nexit 1\n')
    code, _, err = run(capsys, "derive", files / "ring.py", "--document", tex, "--pdf")
    message = one_line_error(err)
    assert code == 1 and "TeX capacity exceeded" in message
    assert f"see {tex.with_suffix('.log')}" in message
    assert tex.with_suffix(".pdf").read_bytes() == b"%PDF"
    assert tex.with_suffix(".log").read_text() == "the failed run\n"
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]

    code, _, err = run(capsys, "derive", files / "ring.py", "--document", tmp_path / "x.txt")
    assert code == 1 and "must end in .tex" in one_line_error(err)


def test_derive_pdf_alone_writes_only_the_pdf(files, tmp_path, capsys, monkeypatch):
    """``derive --pdf`` without ``--document`` typesets in a private directory: a NAME.tex of
    the user's in the working directory is left as it was (it was overwritten), and no
    .aux or .log file appears beside the PDF; a failure writes nothing."""
    tools = tmp_path / "tools"
    tools.mkdir()
    fake = tools / "pdflatex"  # writes NAME.pdf and an empty NAME.log in its directory
    fake.write_text('#!/bin/sh\nfor last; do :; done\nprintf %%PDF > "${last%.tex}.pdf"\n'
                    ': > "${last%.tex}.log"\n: > "${last%.tex}.aux"\n')
    fake.chmod(0o755)
    work = tmp_path / "work"
    work.mkdir()
    mine = work / "ring.tex"
    mine.write_text("my own notes\n")
    monkeypatch.chdir(work)
    monkeypatch.setenv("PATH", str(tools))
    code, out, _ = run(capsys, "derive", files / "ring.py", "--pdf")
    assert code == 0 and "wrote ring.pdf" in out
    assert sorted(p.name for p in work.iterdir()) == ["ring.pdf", "ring.tex"]
    assert mine.read_text() == "my own notes\n" and (work / "ring.pdf").read_bytes() == b"%PDF"

    (work / "ring.pdf").unlink()
    fake.write_text("#!/bin/sh\necho '! Undefined control sequence.'\nexit 1\n")
    code, _, err = run(capsys, "derive", files / "ring.py", "--pdf")
    message = one_line_error(err)
    assert code == 1 and "Undefined control sequence" in message and "--document" in message
    assert sorted(p.name for p in work.iterdir()) == ["ring.tex"]

    monkeypatch.setenv("PATH", str(tmp_path / "no-tools"))
    code, _, err = run(capsys, "derive", files / "ring.py", "--pdf")
    assert code == 1 and "--pdf needs pdflatex on PATH" in one_line_error(err)
    assert sorted(p.name for p in work.iterdir()) == ["ring.tex"]


def test_emit_writes_source_and_header(files, tmp_path, capsys):
    code, out, _ = run(capsys, "emit", files / "ring.py", "-o", tmp_path / "c")
    assert code == 0
    source, header = tmp_path / "c" / "ring.c", tmp_path / "c" / "ring.h"
    assert f"wrote {source}" in out and f"wrote {header}" in out
    assert '#include "ring.h"' in source.read_text()
    assert "ring_simulate" in header.read_text()
    assert "print the equations with StepEquations.latex()" in source.read_text()
    code, _, _ = run(capsys, "emit", files / "ring.py", "-o", tmp_path / "tex", "--latex")
    latex = (tmp_path / "tex" / "ring.c").read_text()
    assert code == 0 and "print the equations with" not in latex
    assert latex.count(" *   F[") == source.read_text().count(" *   F[") > 0


def test_emit_refuses_a_name_or_prefix_and_leaves_no_directory(files, tmp_path, capsys):
    """``emit -o newdir --prefix 1abc`` failed but had created newdir; ``--name ../escape``
    wrote escape.c and ``--name ""`` the system's name, without a word."""
    out = tmp_path / "new" / "dir"
    code, _, err = run(capsys, "emit", files / "ring.py", "-o", out, "--prefix", "1abc")
    assert code == 1 and "is not a prefix of C identifiers" in one_line_error(err)
    assert not (tmp_path / "new").exists()
    for name, hint in [("../escape", "'escape' would do"), ("", "not empty"),
                       ("a b", "'a_b' would do")]:
        code, _, err = run(capsys, "emit", files / "ring.py", "-o", out, "--name", name)
        assert code == 1 and hint in one_line_error(err)
    assert not (tmp_path / "new").exists() and not (tmp_path / "escape.c").exists()
    code, _, _ = run(capsys, "emit", files / "ring.py", "-o", out, "--name", "ring_v2")
    assert code == 0 and sorted(p.name for p in out.iterdir()) == ["ring_v2.c", "ring_v2.h"]


# --- simulate -----------------------------------------------------------------------------------

@needs_cc
def test_simulate_writes_the_library_trajectory(files, tmp_path, cached, capsys):
    out_npz, out_csv = tmp_path / "traj.npz", tmp_path / "traj.csv"
    code, out, _ = run(capsys, "simulate", files / "ring.py", "--steps", "1e3", "--every",
                       "10", "-o", out_npz)
    assert code == 0
    assert "ring: 1000 steps in" in out and "kept 101 states" in out
    assert "Newton iterations:" in out and "largest final residual" in out
    assert "largest constraint violation |φ|" in out and "within rounding" in out
    system = load_system(str(files / "ring.py")).system
    sim = system.euler_lagrange().compile(cache_dir=cached)
    expected = sim.simulate(RING_INITIAL, 1000, RING_PARAMS, every=10)
    with np.load(out_npz) as data:
        assert np.array_equal(data["states"], expected.states)  # bitwise the library's run
        assert np.array_equal(data["step_indices"], expected.step_indices)
        assert np.array_equal(data["x"], expected["x"])
        assert list(data["columns"]) == ["x (step k-1)", "y (step k-1)", "x", "y",
                                         "lambda[0]"]
        assert dict(zip(data["parameter_names"], data["parameter_values"])) == RING_PARAMS
    # the constraint report: |φ| on every kept state, here against states pushed off it
    from symgroupoid.runtime import constraint_check

    states = expected.states + 1e-3 * np.arange(len(expected.states))[:, None]
    values, levels = constraint_check(sim.equations).values(states, np.array([0.01, 1.0]))
    x0, y0, x1, y1 = states[:, :4].T
    assert np.allclose(values[:, 0], np.abs(x1 ** 2 + y1 ** 2 - x0 ** 2 - y0 ** 2) / 2,
                       rtol=0, atol=1e-14)  # differences of O(1) squares
    assert values.shape == levels.shape == (len(states), 1) and (levels < 1e-12).all()

    code, _, _ = run(capsys, "simulate", files / "ring.py", "--steps", "50", "-o", out_csv)
    assert code == 0
    table = np.genfromtxt(out_csv, delimiter=",", skip_header=1)
    expected = sim.simulate(RING_INITIAL, 50, RING_PARAMS)
    assert np.array_equal(table[:, 1:6], expected.states)  # 17 digits read back exactly
    assert np.array_equal(table[1:, 6], expected.newton_iterations)
    assert out_csv.read_text().splitlines()[0] == (
        "step,x (step k-1),y (step k-1),x,y,lambda[0],newton_iterations,residual_norm")


@needs_cc
def test_simulate_initial_state_forms(files, tmp_path, cached, capsys):
    ring = files / "ring.py"
    named = tmp_path / "named.json"
    named.write_text(json.dumps(RING_INITIAL))
    flat = tmp_path / "flat.json"
    flat.write_text(json.dumps([1.0, 0.0, math.cos(0.01), math.sin(0.01), 0.0]))
    momentum = tmp_path / "momentum.json"
    momentum.write_text(json.dumps({"configuration": {"x": 1.0, "y": 0.0},
                                    "momentum": [0.0, 1.0]}))
    outs = {}
    inline = json.dumps(RING_INITIAL)  # docs/cli.md: the JSON text itself
    for name, path in (("named", named), ("flat", flat), ("momentum", momentum),
                       ("inline", inline)):
        outs[name] = tmp_path / f"{name}.npz"
        assert run(capsys, "simulate", ring, "--steps", 5, "--initial", path, "-o",
                   outs[name])[0] == 0
    with np.load(outs["named"]) as a, np.load(outs["flat"]) as b:
        assert np.array_equal(a["states"], b["states"])
    with np.load(outs["named"]) as a, np.load(outs["inline"]) as b:
        assert np.array_equal(a["states"], b["states"])
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--initial", '{"x": [1, 2],}')
    assert code == 1 and "--initial: not valid JSON" in one_line_error(err)
    with np.load(outs["momentum"]) as m:
        assert np.allclose(np.hypot(m["x"], m["y"]), 1.0, atol=1e-12)
    # a saved run continues from its last state
    assert run(capsys, "simulate", ring, "--steps", 5, "--initial", outs["named"], "-o",
               tmp_path / "more.npz")[0] == 0
    with np.load(outs["named"]) as a, np.load(tmp_path / "more.npz") as b:
        assert np.array_equal(b["states"][0], a["states"][-1])

    mixed = tmp_path / "mixed.json"
    mixed.write_text(json.dumps({"momentum": [0, 1], "x": [0, 1]}))
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--initial", mixed)
    assert code == 1 and "only the keys 'configuration', 'momentum', 'inputs'; got also x" in err
    off = tmp_path / "off.json"
    off.write_text(json.dumps({**RING_INITIAL, "x": [1.0, 1.1]}))
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--initial", off)
    assert code == 1 and "the initial state violates the constraints" in one_line_error(err)
    assert "(on the command line: --project)" in one_line_error(err)
    near = tmp_path / "near.json"  # typed to a few digits: --project moves it onto the ring
    near.write_text(json.dumps({**RING_INITIAL, "x": [1.0, 0.99995]}))
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--initial", near, "--project",
                       "-o", tmp_path / "projected.npz")
    assert code == 0, err
    with np.load(tmp_path / "projected.npz") as m:
        assert np.allclose(np.hypot(m["x"], m["y"]), 1.0, atol=1e-12)
    bad = tmp_path / "bad.json"
    bad.write_text("{\"x\": [1, 2],}")
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--initial", bad)
    assert code == 1 and f"--initial {bad}: not valid JSON" in one_line_error(err)


@needs_cc
def test_counts_and_parameters_follow_the_library_rules(files, tmp_path, cached, capsys):
    ring = files / "ring.py"
    assert parse_count("1e7", "steps") == 10**7
    for text, message in (("-5", "--steps must be at least 0, got -5"),
                          ("2.5", "--steps must be an integer, got 2.5"),
                          ("nan", "--steps must be a finite integer"),
                          ("ten", "--steps: 'ten' is not a number")):
        code, out, err = run(capsys, "simulate", ring, "--steps", text)
        assert code == 1 and message in one_line_error(err), text
        assert out == ""  # refused before any work
    with pytest.raises(ShapeError, match="--every must be at least 1, got 0"):
        main(["--debug", "simulate", str(ring), "--steps", "10", "--every", "0"])
    assert parse_params(" h=0.01, k = 2 ,") == {"h": 0.01, "k": 2.0}
    for text, message in (("h", "'h' is not of the form name=value"),
                          ("h=1,h=2", "--params: h given twice"),
                          ("h=abc", "--params h: 'abc' is not a number")):
        with pytest.raises(InputError, match=message):
            parse_params(text)
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--params", "q=1")
    assert code == 1 and "ring: unknown parameter q; the parameters are h, r" in err
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "--params", "h=-0.01")
    assert code == 1 and "parameter h is declared positive, got h = -0.01" in err
    with pytest.raises(ParameterError):
        main(["--debug", "simulate", str(ring), "--steps", "5", "--params", "h=-0.01"])
    code, _, err = run(capsys, "simulate", ring, "--steps", 5, "-o", tmp_path / "t.txt")
    assert code == 1 and "must end in .npz or .csv" in err
    # --params overrides the file's PARAMS by name: a larger step, the same circle
    code, out, _ = run(capsys, "simulate", ring, "--steps", 5, "--params", "h=0.02")
    assert code == 0 and "within rounding" in out


@needs_cc
def test_simulate_takes_the_newton_options(files, tmp_path, cached, capsys):
    """--tol, --tol-residual, --max-iterations, --floor-factor, --trust-factor and
    --no-extrapolate reach NewtonOptions; bad values are one-line errors naming the option,
    refused before any work."""
    ring = files / "ring.py"
    for args, message in ((["--tol", "-1"], "--tol must be at least 0.0, got -1.0"),
                          (["--trust-factor", "nan"], "--trust-factor must be finite"),
                          (["--floor-factor", "x"], "--floor-factor: 'x' is not a number"),
                          (["--max-iterations", "2.5"],
                           "--max-iterations must be an integer, got 2.5")):
        code, out, err = run(capsys, "simulate", ring, "--steps", 5, *args)
        assert code == 1 and message in one_line_error(err), args
        assert out == ""
    code, out, err = run(capsys, "simulate", ring, "--steps", 50, "--max-iterations", 1)
    assert code == 1 and "max_iterations=1)" in one_line_error(err)
    code, out, _ = run(capsys, "simulate", ring, "--steps", 50, "--no-extrapolate",
                       "--tol", "1e-12", "--tol-residual", "1e-10", "--trust-factor", "0",
                       "--floor-factor", "4", "--max-iterations", "20",
                       "-o", tmp_path / "t.npz")
    assert code == 0 and "Newton iterations" in out  # (the loose tolerances show in |φ|)
    plain = run(capsys, "simulate", ring, "--steps", 50, "-o", tmp_path / "u.npz")[1]
    assert "Newton iterations" in plain
    a, b = np.load(tmp_path / "t.npz"), np.load(tmp_path / "u.npz")
    assert a["newton_iterations"].sum() != b["newton_iterations"].sum()  # the options applied


def test_conservation_lines_report_nothing_without_diagnostics():
    assert conservation_lines(object()) == []


# --- bvp ----------------------------------------------------------------------------------------

@needs_cc
def test_bvp_solves_writes_and_checks(files, tmp_path, cached, capsys):
    problem = tmp_path / "problem.json"
    shutil.copy(EXAMPLES / "spring_bvp.json", problem)
    out_npz, out_csv = tmp_path / "sol.npz", tmp_path / "sol.csv"
    code, out, _ = run(capsys, "bvp", files / "spring.py", problem, "--check", "-o", out_npz)
    assert code == 0
    assert "spring: 20 steps, converged in" in out and "|F|∞ by iteration:" in out
    assert "critical point of the discrete action: yes" in out
    source = load_system(str(files / "spring.py"))
    expected = sg.solve_boundary_value(source.system.euler_lagrange(), 0.0, 1.0, 20,
                                       params={"h": 0.05, "k": 4.0})
    with np.load(out_npz) as data:
        assert np.array_equal(data["arrows"], expected.arrows)
        assert np.array_equal(data["q"], expected["q"])
        assert data["q"][-1] == pytest.approx(1.0, abs=1e-12)
    # --params overrides the file's "params"
    code, _, _ = run(capsys, "bvp", files / "spring.py", problem, "--params", "k=1",
                     "-o", out_csv)
    assert code == 0
    table = np.genfromtxt(out_csv, delimiter=",", names=True)
    other = sg.solve_boundary_value(source.system.euler_lagrange(), 0.0, 1.0, 20,
                                    params={"h": 0.05, "k": 1.0})
    assert np.array_equal(table["q"], other["q"])

    for content, message in (({"start": 0, "end": 1}, "missing steps"),
                             ({"start": 0, "end": 1, "steps": 20, "stop": 1},
                              "unknown key\\(s\\) stop"),
                             ({"start": 0, "end": 1, "steps": -3},
                              "steps must be at least 0, got -3")):
        problem.write_text(json.dumps(content))
        code, _, err = run(capsys, "bvp", files / "spring.py", problem)
        assert code == 1
        assert re.search(message, one_line_error(err)), err


# --- verify -------------------------------------------------------------------------------------

@needs_cc
def test_verify_passes_on_a_correct_system(files, cached, capsys):
    code, out, _ = run(capsys, "verify", files / "ring.py")
    assert code == 0, out
    rows = {line.split("  ")[0]: line for line in out.splitlines()}
    for check in ("Jacobian vs finite differences", "compiled C vs NumPy program",
                  "compiled C vs SymPy residuals", "variational principle (20 steps)",
                  "Noether: angular momentum"):
        assert " pass " in rows[check], out
    assert "symmetry verified symbolically" in rows["Noether: angular momentum"]
    assert out.splitlines()[-1] == "ring: 5 of 5 checks passed"


@needs_cc
def test_verify_fails_what_is_wrong(files, tmp_path, cached, capsys, monkeypatch):
    # a declared quantity that is not conserved: translations do not preserve the circle
    wrong = tmp_path / "wrong.py"
    wrong.write_text(RING.replace('"section": lambda q: [-q[1], q[0]]', '"section": 0'))
    code, out, _ = run(capsys, "verify", wrong, "--no-sympy")
    assert code == 1
    row = next(line for line in out.splitlines() if line.startswith("Noether"))
    assert " FAIL " in row and "NOT verified to be a symmetry" in row
    assert "kernel vs SymPy residuals" in out and " skip " in out
    assert out.splitlines()[-1] == "ring: 3 of 4 checks passed, 1 skipped"

    # a wrong Jacobian is caught by the finite differences and by the kernel comparison
    original = sg.StepEquations.evaluate

    def skewed(self, *args, **kwargs):
        F, J = original(self, *args, **kwargs)
        return F, J * (1 + 1e-4)

    monkeypatch.setattr(sg.StepEquations, "evaluate", skewed)
    code, out, _ = run(capsys, "verify", files / "ring.py", "--no-sympy")
    assert code == 1
    rows = {line.split("  ")[0]: line for line in out.splitlines()}
    assert " FAIL " in rows["Jacobian vs finite differences"]
    assert " FAIL " in rows["compiled C vs NumPy program"]
    assert 1e-4 > JACOBIAN_TOLERANCE

    code, _, err = run(capsys, "verify", files / "ring.py", "--steps", 1)
    assert code == 1 and "--steps must be at least 2, got 1" in err


# --- cache, version, the console script -------------------------------------------------------

@needs_cc
def test_cache_info_and_clear(files, cached, tmp_path, capsys, monkeypatch):
    assert run(capsys, "simulate", files / "ring.py", "--steps", 1)[0] == 0
    root = tmp_path / "copy"
    shutil.copytree(cached, root)  # a cache holding the module's kernels
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(root))
    before = cache_info()
    assert before.root == root and before.kernels
    code, out, _ = run(capsys, "cache", "info")
    assert code == 0 and f"kernel cache: {root}" in out
    assert f"{len(before.kernels)} kernels" in out and "ring" in out
    code, out, _ = run(capsys, "cache", "clear")
    assert code == 0 and f"removed {len(before.kernels)} kernels" in out
    assert cache_info().kernels == [] and cache_info().index_entries == 0
    assert run(capsys, "cache", "info")[1].count("0 kernels") == 1


@needs_cc
def test_cache_clear_leaves_a_kernel_being_built(files, cached, tmp_path, capsys):
    import fcntl

    assert run(capsys, "simulate", files / "ring.py", "--steps", 1)[0] == 0
    root = tmp_path / "cache"
    shutil.copytree(cached, root)
    keys = sorted(p.name for p in (root / "kernels").iterdir())
    (root / "locks").mkdir(exist_ok=True)
    with open(root / "locks" / f"{keys[0]}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another process building keys[0]
        result = clear_cache(root)
    assert result.busy == [keys[0]] and result.removed == len(keys) - 1
    assert [p.name for p in (root / "kernels").iterdir()] == [keys[0]]


def test_version_and_usage(capsys):
    with pytest.raises(SystemExit) as caught:
        main(["--version"])
    assert caught.value.code == 0 and capsys.readouterr().out == f"symgroupoid {sg.__version__}\n"
    with pytest.raises(SystemExit) as caught:
        main(["simulate"])
    assert caught.value.code == 2


def _console_script() -> str:
    script = Path(sys.executable).parent / "symgroupoid"
    if not script.exists():
        pytest.skip("the symgroupoid console script is not installed beside this Python")
    return str(script)


def test_console_script(files, tmp_path):
    """The installed entry point: exit status 1, nothing on stdout, one line on stderr."""
    script = _console_script()
    bad = subprocess.run([script, "simulate", str(files / "ring.py"), "--steps", "-5"],
                         capture_output=True, text=True)
    assert bad.returncode == 1 and bad.stdout == ""
    assert bad.stderr == "symgroupoid: error: --steps must be at least 0, got -5\n"


@needs_cc
def test_readme_commands_run(tmp_path, cached, capsys, monkeypatch):
    """Every command of the README's "Command line" section succeeds as written."""
    readme = (REPO / "README.md").read_text()
    section = readme.split("## Command line", 1)[1].split("\n## ", 1)[0]
    block = section.split("```sh\n", 1)[1].split("```", 1)[0]
    commands = [shlex.split(line.split("  #", 1)[0]) for line in block.splitlines()]
    assert len(commands) == 7 and all(c[0] == "symgroupoid" for c in commands)
    (tmp_path / "examples").symlink_to(REPO / "examples")
    monkeypatch.chdir(tmp_path)
    for command in commands:
        code, out, err = run(capsys, *command[1:])
        assert code == 0, (command, out, err)
    assert {"build", "ring.npz", "spring.csv"} <= {p.name for p in tmp_path.iterdir()}


@needs_cc
def test_simulate_keeps_the_states_before_a_failure_or_an_interruption(
        files, tmp_path, cached, capsys, monkeypatch):
    original = sg.Simulator.simulate

    def failing(self, initial, steps, params, **kwargs):
        err = sg.NewtonDivergenceError(f"{self.name}: step 10 failed: no convergence")
        err.trajectory = original(self, initial, 10, params)
        raise err

    monkeypatch.setattr(sg.Simulator, "simulate", failing)
    out = tmp_path / "partial.npz"
    code, _, err = run(capsys, "simulate", files / "ring.py", "--steps", 100, "-o", out)
    assert code == 1
    assert one_line_error(err) == (f"symgroupoid: error: ring: step 10 failed: no convergence;"
                                   f" the 11 states up to step 10 are in {out}")
    with np.load(out) as data:
        assert data["states"].shape == (11, 5)

    def interrupted(self, initial, steps, params, **kwargs):
        stop = KeyboardInterrupt()
        stop.trajectory = original(self, initial, 3, params)
        raise stop

    monkeypatch.setattr(sg.Simulator, "simulate", interrupted)
    code, _, err = run(capsys, "simulate", files / "ring.py", "--steps", 100, "-o", out)
    assert code == 130 and f"interrupted; the 4 states up to step 3 are in {out}" in err


def test_verify_samples_at_most_every_state():
    """(``symgroupoid verify --points 1e9`` allocated 10⁹ sample positions.)"""
    case = case_of("oscillator")
    states = case.sim.simulate(case.flat, 4, case.params).states
    points = sample_points(case.sim, states, case.sim.parameters(case.params), 10**12,
                           np.random.default_rng(0))
    assert len(points) == len(states)


def test_derive_document_replaces_links_and_never_blocks_on_a_fifo(files, tmp_path, capsys):
    """(``--document`` wrote with ``write_text``: through a symlink into the file it points
    to, blocking forever on a FIFO.)  It writes as every other output does: a temporary
    file renamed into place."""
    target = tmp_path / "elsewhere.tex"
    target.write_text("keep me")
    link = tmp_path / "ring.tex"
    link.symlink_to(target)
    code, out, _ = run(capsys, "derive", files / "ring.py", "--document", link)
    assert code == 0 and f"wrote {link}" in out
    assert target.read_text() == "keep me" and not link.is_symlink()
    assert link.read_text().startswith("\\documentclass")
    fifo = tmp_path / "pipe.tex"
    os.mkfifo(fifo)
    code, out, _ = run(capsys, "derive", files / "ring.py", "--document", fifo)
    assert code == 0 and fifo.is_file() and not stat.S_ISFIFO(fifo.stat().st_mode)
    (tmp_path / "dir.tex").mkdir()
    code, _, err = run(capsys, "derive", files / "ring.py", "--document", tmp_path / "dir.tex")
    assert code == 1 and "it is a directory" in one_line_error(err)


def test_an_output_path_that_names_a_directory_is_refused_before_the_run(capsys, cached,
                                                                         files, tmp_path):
    """``-o out.npz/`` wrote the file out.npz (the separator dropped), and ``-o U.npy/x.npz``
    with U.npy a file said that the directory did not exist; ``Trajectory.save`` alike."""
    ring = files / "ring.py"
    code, _, err = run(capsys, "simulate", ring, "--steps", 3, "-o", f"{tmp_path / 'x.npz'}/")
    assert code == 1 and "names a directory" in one_line_error(err)
    assert not (tmp_path / "x.npz").exists()
    (tmp_path / "U.npy").write_bytes(b"")
    code, _, err = run(capsys, "simulate", ring, "--steps", 3, "-o", tmp_path / "U.npy" / "x.npz")
    assert code == 1 and "U.npy' is not a directory" in one_line_error(err)
    sim = load_system(str(ring)).system.euler_lagrange().compile(backend="numpy")
    traj = sim.simulate(RING_INITIAL, 2, RING_PARAMS)
    with pytest.raises(sg.OutputError, match="it names a directory"):
        traj.save(f"{tmp_path / 'y.npz'}/")
    with pytest.raises(sg.OutputError, match="is not a directory"):
        traj.save(tmp_path / "U.npy" / "y.npz")


def test_cache_info_prints_a_path_with_a_newline_on_one_line(tmp_path, capsys, monkeypatch):
    """(A cache path holding a newline was printed across two lines.)"""
    root = tmp_path / "two\nlines"
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(root))
    code, out, _ = run(capsys, "cache", "info")
    assert code == 0 and out.splitlines()[0] == f"kernel cache: {str(root)!r}"
