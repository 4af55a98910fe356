"""``derive`` (the equations as LaTeX, sizes and times) and ``emit`` (C source and header)."""

from __future__ import annotations

import argparse
import contextlib
import re
import shutil
import subprocess
import tempfile
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from .._arguments import counted
from .._progress import Task
from ..equations import LatexOptionError, UnusedAbbreviationWarning
from ..runtime import atomic_write, output_problem
from ._common import Derived, derive, file_stem, say
from ._errors import ExternalToolError, InputError, LostContentError

#: seconds pdflatex may run on one document
PDFLATEX_TIMEOUT = 300
#: pt a box may overflow the page before ``--pdf`` reports lost content (TeX's own
#: \\hfuzz is 0.1 pt; a few points disappear in the margin)
OVERFULL_TOLERANCE = 3.0

_OVERFULL = re.compile(r"^Overfull \\([hv])box \(([0-9.]+)pt too (?:wide|high)\)(.*)$")
_MISSING = re.compile(r"^Missing character: There is no (.+?) in font (.+?)!?$")


def sizes(derived: Derived) -> list[str]:
    """The sizes of the derived step: equations, unknowns, Jacobian, program operations."""
    step = derived.step
    t0 = time.perf_counter()
    program = step.program
    graph = program.graph
    nonzero = sum(1 for n in program.outputs["J"] if n != graph.zero)
    n, u = len(step), len(step.unknowns)
    params = ", ".join(map(str, step.parameters)) or "none"
    seconds = time.perf_counter() - t0
    return [
        f"{step.name}: {n} equations in {u} unknowns (order {step.order}, "
        f"{counted(step.n_constraints, 'constraint')}, {len(step.knowns)} knowns)",
        f"parameters: {params}",
        f"Jacobian {n}×{u}: {nonzero} structurally nonzero entries",
        f"program: {program.size(['F'])} operations for the residual, "
        f"{program.size(['F', 'J'])} with the Jacobian",
        f"derived in {derived.seconds:.2f} s, program built in {seconds:.2f} s"]


@dataclass
class PrintedLatex:
    """The LaTeX of a step, the seconds it took and the abbreviations it did not use."""

    text: str
    seconds: float
    unused: list[str]

    def lines(self) -> list[str]:
        out = [f"LaTeX written in {self.seconds:.2f} s ({len(self.text)} characters)"]
        if self.unused:
            out.append(f"abbreviations not used (not a part of the printed equations): "
                       f"{', '.join(self.unused)}")
        return out


def _latex(derived: Derived, document: bool) -> PrintedLatex:
    """The equations as printed for a paper (``StepEquations.latex``: named pieces, terms
    collected, lines broken to the page, a "where" list; every printed form checked against
    the residuals) with the file's ``ABBREVIATIONS``, the seconds it took and the
    abbreviations that do not occur in it."""
    abbreviations = derived.source.convention("ABBREVIATIONS")
    t0 = time.perf_counter()
    with Task(f"{derived.step.name}: writing the equations as LaTeX"), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UnusedAbbreviationWarning)
        try:
            text = derived.step.latex(document=document, abbreviations=abbreviations)
        except LatexOptionError as err:
            raise LatexOptionError(f"{derived.source.label}: ABBREVIATIONS: {err}") from None
    unused = [name for w in caught if isinstance(w.message, UnusedAbbreviationWarning)
              for name in w.message.names]
    for w in caught:  # other warnings as Python would show them
        if not isinstance(w.message, UnusedAbbreviationWarning):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return PrintedLatex(text, time.perf_counter() - t0, unused)


def _pdflatex(tex: Path, kept: bool = True, shown: Path | None = None) -> Path:
    """Run pdflatex on ``tex`` (in its directory); the PDF's path.  ``kept``: the document
    and its log are kept, as ``shown`` (default ``tex``: where the messages say they are);
    else the messages name neither, and tell how to keep them."""
    shown = shown or tex
    program = shutil.which("pdflatex")
    if program is None:
        where = f"the document is in {shown}" if kept else "use --document OUT.tex to keep it"
        raise ExternalToolError(f"--pdf needs pdflatex on PATH (install a TeX distribution, "
                                f"e.g. TeX Live); {where}")
    cmd = [program, "-interaction=nonstopmode", "-halt-on-error", tex.name]
    try:
        with Task(f"pdflatex {tex.name}"):
            result = subprocess.run(cmd, cwd=tex.parent, stdin=subprocess.DEVNULL,
                                    capture_output=True, text=True, errors="replace",
                                    timeout=PDFLATEX_TIMEOUT)
    except subprocess.TimeoutExpired:
        raise ExternalToolError(f"pdflatex did not finish {shown if kept else tex.name} in "
                                f"{PDFLATEX_TIMEOUT} s") from None
    pdf = tex.with_suffix(".pdf")
    if result.returncode != 0 or not pdf.is_file():
        errors = [line for line in result.stdout.splitlines() if line.startswith("!")]
        reason = errors[0] if errors else f"exit status {result.returncode}"
        see = (f"see {shown.with_suffix('.log')}" if kept else
               "run with --document OUT.tex to keep the document and its log")
        raise ExternalToolError(f"pdflatex failed on {shown if kept else tex.name} ({reason}); "
                                f"{see}")
    check_log(tex, kept, shown)
    return pdf


def _typeset_beside(tex: Path) -> Path:
    """``derive --document OUT.tex --pdf``: pdflatex on a copy of the document in a private
    directory, then its OUT.log and OUT.aux and OUT.pdf beside the document, each through a
    temporary file and a rename; so a run that fails (a full disk, a TeX error) keeps the
    OUT.pdf of an earlier run, with the failed run's log beside it.  A PDF with lost content
    is still written, as the error says."""
    with tempfile.TemporaryDirectory(prefix="symgroupoid-pdf-") as private:
        copy = Path(private) / tex.name
        shutil.copyfile(tex, copy)
        try:
            _pdflatex(copy, shown=tex)
        except LostContentError:
            _bring_back(copy, tex, (".log", ".aux", ".pdf"))
            raise
        except ExternalToolError:
            _bring_back(copy, tex, (".log", ".aux"))
            raise
        _bring_back(copy, tex, (".log", ".aux", ".pdf"))
    return tex.with_suffix(".pdf")


def _bring_back(copy: Path, tex: Path, suffixes: tuple[str, ...]) -> None:
    """The files of ``copy``'s run with these suffixes, written beside ``tex``."""
    for suffix in suffixes:
        made = copy.with_suffix(suffix)
        if made.is_file():
            data = made.read_bytes()
            atomic_write(tex.with_suffix(suffix), lambda f, data=data: f.write(data),
                         binary=True)


def lost_content(log: str, tolerance: float = OVERFULL_TOLERANCE) -> list[str]:
    """What a pdflatex log reports as not placed on the page: overfull boxes beyond
    ``tolerance`` pt (a line wider than the text, a display taller than the page) and
    characters missing from the fonts, one short description each."""
    out = []
    for line in log.splitlines():
        over = _OVERFULL.match(line)
        if over and float(over.group(2)) > tolerance:
            kind, size = over.group(1), float(over.group(2))
            where = over.group(3).strip()
            what = "a line" if kind == "h" else "a page"
            out.append(f"{what} {size:.1f} pt too {'wide' if kind == 'h' else 'high'}"
                       + (f" ({where})" if where.startswith("detected at line")
                          or where.startswith("in ") else ""))
        missing = _MISSING.match(line)
        if missing:
            out.append(f"character {missing.group(1)} missing from font {missing.group(2)}")
    return out


def check_log(tex: Path, kept: bool = True, shown: Path | None = None) -> None:
    """Raise :class:`LostContentError` when the log of ``tex``'s run reports lost content
    (``kept``, ``shown``: as :func:`_pdflatex`)."""
    log_path = tex.with_suffix(".log")
    shown_log = (shown or tex).with_suffix(".log")
    shown = shown or tex
    try:
        log = log_path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise ExternalToolError(f"pdflatex left no readable log {log_path}: {exc}") from None
    lost = lost_content(log)
    if lost:
        more = f" and {len(lost) - 3} more" if len(lost) > 3 else ""
        raise LostContentError(
            f"pdflatex could not fit all of {shown if kept else tex.name} on its pages: "
            f"{'; '.join(lost[:3])}{more} "
            f"({f'see {shown_log}' if kept else 'no PDF written'}); the PDF is incomplete: "
            f"name the long parts with ABBREVIATIONS in the system file (docs/cli.md)")


def run_derive(args: argparse.Namespace) -> int:
    derived = derive(args.system)
    lines = sizes(derived)
    document = args.document or args.pdf
    if not document:
        printed = _latex(derived, document=False)
        for line in [*lines, *printed.lines()]:
            say(f"% {line}")
        say(printed.text)
        return 0
    if not args.document:
        return _pdf_only(derived, lines, Path(f"{file_stem(derived.step.name)}.pdf"))
    tex = Path(args.document)
    if tex.suffix != ".tex":
        raise InputError(f"--document {tex}: the file name must end in .tex")
    problem = output_problem(tex)  # (its directory missing, a directory in its place)
    if problem is not None:
        raise InputError(f"--document {tex}: {problem}")
    printed = _latex(derived, document=True)
    # through a temporary file and a rename: never through a link, never into a FIFO, and a
    # full disk keeps the old document (an OutputError naming the file)
    atomic_write(tex, lambda f: f.write(printed.text), binary=False)
    for line in [*lines, *printed.lines()]:
        say(line)
    say(f"wrote {tex}")
    if args.pdf:
        say(f"wrote {_typeset_beside(tex)}")
    return 0


def _pdf_only(derived: Derived, lines: list[str], pdf: Path) -> int:
    """``derive --pdf`` without ``--document``: the document is typeset in a private
    directory and only ``pdf`` (NAME.pdf in the working directory) is written, through a
    temporary file and a rename; no .tex, .aux or .log file beside it is touched.  A failure
    names the problem and keeps nothing (``--document OUT.tex --pdf`` keeps the document and
    pdflatex's log)."""
    problem = output_problem(pdf)
    if problem is not None:
        raise InputError(f"--pdf {pdf}: {problem}")
    printed = _latex(derived, document=True)
    for line in [*lines, *printed.lines()]:
        say(line)
    with tempfile.TemporaryDirectory(prefix="symgroupoid-pdf-") as private:
        tex = Path(private) / f"{pdf.stem}.tex"
        tex.write_text(printed.text, encoding="utf-8")
        made = _pdflatex(tex, kept=False).read_bytes()
    atomic_write(pdf, lambda f: f.write(made), binary=True)
    say(f"wrote {pdf}")
    return 0


def run_emit(args: argparse.Namespace) -> int:
    if args.name is not None and (not args.name or file_stem(args.name) != args.name):
        raise InputError(f"--name {args.name!r}: the stem of the file names, letters, digits "
                         f"and '_', '.', '-' (not a path, not empty)"
                         + (f"; {file_stem(args.name)!r} would do" if args.name else ""))
    derived = derive(args.system)
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(f"-o {out}: exists and is not a directory")
    made = _new_directories(out)
    base = out / (args.name or file_stem(derived.step.name))
    t0 = time.perf_counter()
    try:
        with Task(f"{derived.step.name}: generating C"):
            paths = derived.step.emit_c(base, prefix=args.prefix, latex=args.latex)
    except BaseException:
        for directory in reversed(made):  # a failure leaves no directory it created
            with contextlib.suppress(OSError):
                directory.rmdir()  # (only while empty)
        raise
    seconds = time.perf_counter() - t0
    say(f"{derived.step.name}: {len(derived.step)} equations, derived in "
        f"{derived.seconds:.2f} s, C generated in {seconds:.2f} s")
    for path in paths:
        lines = path.read_text(encoding="utf-8").count("\n")
        say(f"wrote {path} ({lines} lines)")
    return 0


def _new_directories(out: Path) -> list[Path]:
    """Create ``out`` and its missing parents; return those it created, outermost first."""
    missing = [p for p in (out, *out.parents) if not p.exists()][::-1]
    out.mkdir(parents=True, exist_ok=True)
    return missing
