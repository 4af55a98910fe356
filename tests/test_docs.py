"""The documentation runs as written.

Every fenced ```python block of README.md and docs/*.md is executed: the blocks of one file
in order, in one fresh Python process, in an empty temporary directory (so files the
examples write land there).  A block that is not meant to run is fenced ```python no-run
(rare: each is counted).  Tracebacks name the Markdown file and its line.  The files run
concurrently, one process each.

The API reference (Sphinx, docs/api) is built with warnings as errors by ``make docs`` and
by the slow test below; the fast tests check its configuration.
"""

from __future__ import annotations

import inspect
import os
import re
import runpy
import subprocess
import sys
from pathlib import Path

import pytest
from kernel_support import HAVE_CC, REPO, SESSION_CACHE

import symgroupoid as sg

DOC_FILES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.S | re.M)
RUN, NO_RUN = "python", "python no-run"
#: at most this many blocks in all the docs may be exempt from running
MAX_NO_RUN = 2


def fenced_blocks(path: Path) -> list[tuple[str, int, str]]:
    """(info string, first line number of the code, code) of every fenced block."""
    text = path.read_text(encoding="utf-8")
    out = []
    for m in FENCE.finditer(text):
        first_line = text.count("\n", 0, m.start(2)) + 1
        out.append((m.group(1).strip(), first_line, m.group(2)))
    return out


def runnable_source(path: Path) -> str:
    """The ```python blocks of ``path`` at their own line numbers (blank lines between)."""
    lines: list[str] = []
    for info, first, code in fenced_blocks(path):
        if info != RUN:
            continue
        lines.extend([""] * (first - 1 - len(lines)))
        lines.extend(code.splitlines())
    return "\n".join(lines) + "\n"


def _label(path: Path) -> str:
    return str(path.relative_to(REPO))


RUNNABLE = [p for p in DOC_FILES if any(info == RUN for info, _, _ in fenced_blocks(p))]


@pytest.fixture(scope="module")
def doc_runs(tmp_path_factory):
    """One process per documentation file, started together; {path: (process, log path)}."""
    env = dict(os.environ, MPLBACKEND="Agg", SYMGROUPOID_CACHE=str(SESSION_CACHE),
               PYTHONHASHSEED="0")
    env.pop("SYMGROUPOID_BACKEND", None)
    runs = {}
    for path in RUNNABLE:
        if not HAVE_CC and '"cc"' in runnable_source(path):
            continue
        work = tmp_path_factory.mktemp(path.stem)
        code = (f"import sys; sys.path.insert(0, {str(REPO)!r}); "
                f"exec(compile(open({str(work / 'doc.py')!r}, encoding='utf-8').read(), "
                f"{str(path)!r}, 'exec'), {{'__name__': '__main__'}})")
        (work / "doc.py").write_text(runnable_source(path), encoding="utf-8")
        log = work / "output.txt"
        with open(log, "w") as out:
            runs[path] = (subprocess.Popen([sys.executable, "-c", code], cwd=work, env=env,
                                           stdout=out, stderr=subprocess.STDOUT), log, work)
    yield runs
    for process, _, _ in runs.values():
        if process.poll() is None:
            process.kill()
            process.wait()


@pytest.mark.parametrize("path", RUNNABLE, ids=_label)
def test_documentation_runs_as_written(path, doc_runs):
    if path not in doc_runs:
        pytest.skip("the file compiles a C program and there is no C compiler (cc)")
    process, log, _ = doc_runs[path]
    try:
        process.wait(timeout=600)
    except subprocess.TimeoutExpired:
        process.kill()
        pytest.fail(f"{_label(path)}: its code blocks did not finish in 10 minutes")
    output = log.read_text(encoding="utf-8", errors="replace")
    assert process.returncode == 0, f"{_label(path)} failed:\n{output[-6000:]}"


def test_the_tutorial_writes_its_figures_and_c_program(doc_runs):
    tutorial = REPO / "docs" / "first-system.md"
    if tutorial not in doc_runs:
        pytest.skip("no C compiler (cc)")
    process, log, work = doc_runs[tutorial]
    process.wait(timeout=600)
    assert process.returncode == 0, log.read_text(encoding="utf-8", errors="replace")[-6000:]
    for name in ("conservation.png", "pendulum.png", "spherical_pendulum.c",
                 "spherical_pendulum.h"):
        assert (work / name).stat().st_size > 0, name


def test_code_blocks_are_fenced_to_run():
    """Every Python block is ```python (runs) or ```python no-run (rare); a block fenced with
    another spelling would silently escape the test above."""
    exempt = []
    for path in DOC_FILES:
        for info, line, _ in fenced_blocks(path):
            if info.split(" ")[0].lower() in ("python", "py", "python3", "pycon"):
                assert info in (RUN, NO_RUN), f"{_label(path)}:{line}: fence '```{info}'"
            if info == NO_RUN:
                exempt.append(f"{_label(path)}:{line}")
    assert len(exempt) <= MAX_NO_RUN, f"too many blocks exempt from running: {exempt}"


def test_extraction_keeps_the_markdown_line_numbers(tmp_path):
    doc = tmp_path / "x.md"
    doc.write_text("text\n```python\na = 1\n```\nmore\n```sh\nls\n```\n```python\n"
                   "raise ValueError(a)\n```\n```python no-run\nnot python\n```\n")
    source = runnable_source(doc)
    assert source.splitlines()[2] == "a = 1" and source.splitlines()[9] == "raise ValueError(a)"
    assert "ls" not in source and "not python" not in source
    with pytest.raises(ValueError) as err:
        exec(compile(source, str(doc), "exec"), {})
    assert err.traceback[-1].lineno + 1 == 10  # pytest counts from 0


def test_no_reference_to_files_outside_the_project():
    """Docstrings and docs cite docs/conventions.md or the seed papers, never a notes file
    that is not part of the project."""
    missing = "EQUATIONS" + ".md"
    hits = [f"{_label(p)}" for folder in ("symgroupoid", "docs", "examples", "tests")
            for p in (REPO / folder).rglob("*") if p.suffix in (".py", ".md", ".rst", ".j2")
            and missing in p.read_text(encoding="utf-8", errors="replace")]
    hits += [name for name in ("README.md",) if missing in (REPO / name).read_text()]
    assert hits == []


def test_readme_states_the_defaults_it_shows():
    """The README shows system.noether(section, f=…) with the signature's default."""
    default = inspect.signature(sg.DiscreteSystem.noether).parameters["f"].default
    assert f"noether(section, f={default!r})" in (REPO / "README.md").read_text()


# --- the API reference ---------------------------------------------------------------------------

def _sphinx_conf() -> dict:
    return runpy.run_path(str(REPO / "docs" / "api" / "conf.py"))


def test_api_reference_configuration_loads():
    conf = _sphinx_conf()
    assert "sphinx.ext.autodoc" in conf["extensions"]
    escape = conf["_escape_bars"]
    assert escape("|x| and ``a|b``") == r"\|x\| and ``a|b``"
    index = (REPO / "docs" / "api" / "index.rst").read_text()
    for page in re.findall(r"^   (\w+)$", index, re.M):
        assert (REPO / "docs" / "api" / f"{page}.rst").is_file(), page


@pytest.mark.slow
def test_api_reference_builds_without_warnings(tmp_path):
    pytest.importorskip("sphinx", reason="the docs extra: pip install -e '.[docs]'")
    result = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         str(REPO / "docs" / "api"), str(tmp_path / "html")],
        capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-6000:]
    runtime = (tmp_path / "html" / "runtime.html").read_text()
    assert "project_initial" in runtime and "conservation_summary" in runtime
