"""The documentation runs as written.

Every fenced ```python block of README.md and docs/*.md is executed as a user would run it:
all of them, in file order (README.md, then docs/*.md by name) and within a file in order,
pasted into one script and run with ``python script.py`` in a fresh process, in an empty
temporary directory (so files the examples write land there), with no
``if __name__ == "__main__":`` guard added.  A failure names the Markdown file and line of
the failing code.  Each documentation file also runs on its own (slow test), as a reader
who pastes a single page would run it.  A block that is not meant to run is fenced
```python no-run (rare: each is counted).

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
    try:
        return str(path.relative_to(REPO))
    except ValueError:  # (a file outside the project: the tests' own examples)
        return path.name


RUNNABLE = [p for p in DOC_FILES if any(info == RUN for info, _, _ in fenced_blocks(p))]


def docs_script(paths: list[Path]) -> tuple[str, list[tuple[int, Path, int]]]:
    """The ```python blocks of ``paths``, in order, as one script, and where each block came
    from: (first line of the block in the script, Markdown file, its first line there)."""
    lines: list[str] = []
    origins = []
    for path in paths:
        for info, first, code in fenced_blocks(path):
            if info != RUN:
                continue
            lines.append(f"# --- {_label(path)}:{first}")
            origins.append((len(lines) + 1, path, first))
            lines.extend(code.splitlines())
    return "\n".join(lines) + "\n", origins


def markdown_location(line: int, origins) -> str:
    """``file.md:line`` of a line of the script of :func:`docs_script`."""
    for start, path, first in reversed(origins):
        if line >= start:
            return f"{_label(path)}:{first + line - start}"
    return f"line {line} of the script"


def run_script(source: str, origins, work: Path) -> subprocess.Popen:
    """``python docs.py`` in ``work`` (the package found as installed or from this
    checkout), output to ``work/output.txt``."""
    env = dict(os.environ, MPLBACKEND="Agg", SYMGROUPOID_CACHE=str(SESSION_CACHE),
               PYTHONHASHSEED="0", PYTHONPATH=os.pathsep.join(
                   [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
    env.pop("SYMGROUPOID_BACKEND", None)
    (work / "docs.py").write_text(source, encoding="utf-8")
    with open(work / "output.txt", "w") as out:
        return subprocess.Popen([sys.executable, "docs.py"], cwd=work, env=env, stdout=out,
                                stderr=subprocess.STDOUT)


def finished(process: subprocess.Popen, work: Path, origins, what: str) -> str:
    """Wait for a docs script; its output, or a failure that names the Markdown lines of
    the traceback."""
    try:
        process.wait(timeout=900)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        pytest.fail(f"{what}: the code blocks did not finish in 15 minutes")
    output = (work / "output.txt").read_text(encoding="utf-8", errors="replace")
    if process.returncode != 0:
        where = [markdown_location(int(n), origins)
                 for n in re.findall(r'File ".*docs\.py", line (\d+)', output)]
        pytest.fail(f"{what} failed (exit code {process.returncode}) at "
                    f"{' <- '.join(reversed(where)) or 'an unknown line'}:\n{output[-6000:]}")
    return output


@pytest.fixture(scope="module")
def all_docs(tmp_path_factory):
    """Every runnable block of the documentation as one script, started once."""
    paths = [p for p in RUNNABLE if HAVE_CC or '"cc"' not in runnable_source(p)]
    source, origins = docs_script(paths)
    work = tmp_path_factory.mktemp("docs")
    process = run_script(source, origins, work)
    yield process, work, origins
    if process.poll() is None:
        process.kill()
        process.wait()


def test_the_documentation_runs_as_one_plain_script(all_docs):
    """README.md and docs/*.md, every ```python block in order, pasted into one file and run
    with ``python docs.py``: no ``__main__`` guard, so nothing of it may rely on one (the
    sweeps' workers never import the script)."""
    process, work, origins = all_docs
    finished(process, work, origins, "README.md + docs/*.md as one script")


def test_the_tutorial_writes_its_figures_and_c_program(all_docs):
    if not HAVE_CC:
        pytest.skip("no C compiler (cc)")
    process, work, origins = all_docs
    finished(process, work, origins, "README.md + docs/*.md as one script")
    for name in ("conservation.png", "pendulum.png", "spherical_pendulum.c",
                 "spherical_pendulum.h"):
        assert (work / name).stat().st_size > 0, name


@pytest.mark.slow
@pytest.mark.parametrize("path", RUNNABLE, ids=_label)
def test_each_documentation_file_runs_on_its_own(path, tmp_path):
    if not HAVE_CC and '"cc"' in runnable_source(path):
        pytest.skip("the file compiles a C program and there is no C compiler (cc)")
    source, origins = docs_script([path])
    finished(run_script(source, origins, tmp_path), tmp_path, origins, _label(path))


def test_a_failing_block_is_reported_at_its_markdown_line(tmp_path):
    doc = tmp_path / "x.md"
    doc.write_text("text\n```python\na = 1\n```\nmore\n```python\n\nraise ValueError(a)\n```\n")
    source, origins = docs_script([doc])
    process = run_script(source, origins, tmp_path)
    with pytest.raises(pytest.fail.Exception, match=r"(?s)at x\.md:8:.*ValueError: 1"):
        finished(process, tmp_path, origins, "x.md")


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
