"""The documentation runs as written.

Every fenced ```python block of README.md and docs/**/*.md is executed as a user would run it:
all of them, in file order (README.md, then the Markdown files under docs/ by their path) and
within a file in order,
pasted into one script and run with ``python script.py`` in a fresh process, in an empty
temporary directory (so files the examples write land there), with no
``if __name__ == "__main__":`` guard added.  A failure names the Markdown file and line of
the failing code.  Each documentation file also runs on its own (slow test), as a reader
who pastes a single page would run it.  A block that is not meant to run is fenced
```python no-run (rare: each is counted).

Every relative link of README.md and the docs leads to a file of the project (and an anchor
to a heading of it), and every ``docs/….md`` the project's text names exists.

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


def doc_files(root: Path = REPO) -> list[Path]:
    """README.md, then every Markdown file under docs/ (subdirectories too), ordered by its
    path relative to docs/ (``cli.md`` < ``how-to/simulate.md`` < ``tutorial/…``), a stable
    order whatever the file system lists first."""
    docs = root / "docs"
    return [root / "README.md",
            *sorted(docs.rglob("*.md"), key=lambda p: p.relative_to(docs).as_posix())]


DOC_FILES = doc_files()
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
    """README.md and docs/**/*.md, every ```python block in order, pasted into one file and run
    with ``python docs.py``: no ``__main__`` guard, so nothing of it may rely on one (the
    sweeps' workers never import the script)."""
    process, work, origins = all_docs
    finished(process, work, origins, "README.md + docs/**/*.md as one script")


def test_the_tutorial_writes_its_figures_and_c_program(all_docs):
    if not HAVE_CC:
        pytest.skip("no C compiler (cc)")
    process, work, origins = all_docs
    finished(process, work, origins, "README.md + docs/**/*.md as one script")
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


# --- links ---------------------------------------------------------------------------------------

#: pages linked before they are part of the project: docs/architecture.md is written at the
#: same time on another branch; a link to it is checked like any other once the file exists
PENDING = {"docs/architecture.md"}
LINK = re.compile(r"\]\(([^()\s]+)(?:\s+\"[^\"]*\")?\)")
CODE_SPAN = re.compile(r"(`+).*?\1", re.S)
DOC_PATH = re.compile(r"\bdocs/[\w./-]*\w\.md\b")


def prose(text: str) -> str:
    """``text`` with its fenced blocks and code spans blanked (links there are code, not
    links), every character kept in its place."""
    def blank(m: re.Match) -> str:
        return re.sub(r"[^\n]", " ", m.group(0))
    return CODE_SPAN.sub(blank, FENCE.sub(blank, text))


def heading_anchors(path: Path) -> set[str]:
    """The anchors of the headings of a Markdown file, as GitHub makes them: the text
    lower-cased, punctuation dropped, spaces as hyphens, repeats numbered -1, -2, …"""
    seen: dict[str, int] = {}
    anchors = set()
    for m in re.finditer(r"^#{1,6}[ \t]+(.*?)[ \t#]*$", FENCE.sub("", path.read_text()), re.M):
        title = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", m.group(1).replace("`", ""))
        slug = re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        anchors.add(slug if n == 0 else f"{slug}-{n}")
    return anchors


def broken_links(path: Path, root: Path = REPO) -> list[str]:
    """Every relative link of the Markdown file ``path`` that leads to no file under
    ``root`` (or to no heading of it), as ``file:line: target``."""
    text = path.read_text(encoding="utf-8")
    out = []
    for m in LINK.finditer(prose(text)):
        target = m.group(1)
        if re.match(r"[a-z][a-z0-9+.-]*:", target) or not re.search(r"[./#]", target):
            continue                    # https:, mailto:; X⃖[f](g), a formula, not a path
        file, _, anchor = target.partition("#")
        where = (path.parent / file).resolve() if file else path
        line = text.count("\n", 0, m.start()) + 1
        try:
            name = where.relative_to(root.resolve()).as_posix()
        except ValueError:
            out.append(f"{_label(path)}:{line}: {target} (outside the project)")
            continue
        if not where.exists():
            if name not in PENDING:
                out.append(f"{_label(path)}:{line}: {target} (no such file)")
        elif anchor and where.suffix == ".md" and anchor not in heading_anchors(where):
            out.append(f"{_label(path)}:{line}: {target} (no such heading)")
    return out


def test_every_relative_link_of_the_docs_resolves():
    """README.md and docs/**/*.md: every relative link leads to an existing file, and an
    anchor to one of its headings."""
    assert [bad for path in DOC_FILES for bad in broken_links(path)] == []


def test_every_docs_page_the_project_names_exists():
    """A page named in prose or a docstring (``docs/latex.md``, ``docs/conventions.md §4``)
    exists: a page moved leaves no stale name in the docs, the code, examples or tests."""
    texts = [*DOC_FILES, *(REPO / "docs" / "api").glob("*.rst"),
             *(p for folder in ("symgroupoid", "examples", "tests", "templates", "benchmarks")
               for p in sorted((REPO / folder).rglob("*"))
               if p.suffix in (".py", ".j2", ".md", ".c", ".h"))]
    named = {(m.group(0), _label(p)) for p in texts
             if p.name != "test_docs.py"  # (its own examples)
             for m in DOC_PATH.finditer(p.read_text(encoding="utf-8", errors="replace"))}
    assert sorted((page, where) for page, where in named
                  if not (REPO / page).is_file() and page not in PENDING) == []


def test_a_broken_link_is_reported(tmp_path):
    (tmp_path / "docs" / "how-to").mkdir(parents=True)
    (tmp_path / "docs" / "a.md").write_text("# A title, `with code`\n\n## Twice\n## Twice\n")
    page = tmp_path / "docs" / "how-to" / "b.md"
    page.write_text("# B\n[ok](../a.md#a-title-with-code) [ok](../a.md#twice-1) [ok](#b)\n"
                    "[web](https://example.org/x.md) `[code](nowhere.md)` X⃖[f](g_k)\n"
                    "[gone](../gone.md)\n[bad anchor](../a.md#nothing)\n"
                    "[out](../../../../outside.md)\n"
                    "```sh\n[in a block](nowhere.md)\n```\n")
    assert broken_links(page, tmp_path) == [
        "b.md:4: ../gone.md (no such file)", "b.md:5: ../a.md#nothing (no such heading)",
        "b.md:6: ../../../../outside.md (outside the project)"]


def test_docs_files_are_found_in_subdirectories_in_a_stable_order(tmp_path):
    for name in ("docs/tutorial/z.md", "docs/b.md", "docs/how-to/a.md", "docs/a.md",
                 "README.md"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("x\n")
    assert [p.relative_to(tmp_path).as_posix() for p in doc_files(tmp_path)] == [
        "README.md", "docs/a.md", "docs/b.md", "docs/how-to/a.md", "docs/tutorial/z.md"]


def test_the_docs_state_the_defaults_they_show():
    """Where the docs show system.noether(section, f=…) they show the signature's default."""
    default = inspect.signature(sg.DiscreteSystem.noether).parameters["f"].default
    shown = [(p, m.group(0)) for p in DOC_FILES
             for m in re.finditer(r"noether\(section, f=[^)]*\)", p.read_text())]
    assert shown, "no page shows the signature of system.noether"
    for path, text in shown:
        assert text == f"noether(section, f={default!r})", (_label(path), text)


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
