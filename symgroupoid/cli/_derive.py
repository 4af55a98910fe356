"""``derive`` (the equations as LaTeX, sizes and times) and ``emit`` (C source and header)."""

from __future__ import annotations

import argparse
import shutil
import subprocess
import time
from pathlib import Path

from .._progress import Task
from ._common import Derived, derive, file_stem, say
from ._errors import ExternalToolError, InputError

#: seconds pdflatex may run on one document
PDFLATEX_TIMEOUT = 300


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
        f"{step.n_constraints} constraints, {len(step.knowns)} knowns)",
        f"parameters: {params}",
        f"Jacobian {n}×{u}: {nonzero} structurally nonzero entries",
        f"program: {program.size(['F'])} operations for the residual, "
        f"{program.size(['F', 'J'])} with the Jacobian",
        f"derived in {derived.seconds:.2f} s, program built in {seconds:.2f} s"]


def _latex(derived: Derived, document: bool) -> tuple[str, float]:
    t0 = time.perf_counter()
    with Task(f"{derived.step.name}: writing the equations as LaTeX"):
        text = derived.step.latex(document=document)
    return text, time.perf_counter() - t0


def _pdflatex(tex: Path) -> Path:
    """Run pdflatex on ``tex`` (in its directory); the PDF's path."""
    program = shutil.which("pdflatex")
    if program is None:
        raise ExternalToolError(f"--pdf needs pdflatex on PATH (install a TeX distribution, "
                                f"e.g. TeX Live); the document is in {tex}")
    cmd = [program, "-interaction=nonstopmode", "-halt-on-error", tex.name]
    try:
        with Task(f"pdflatex {tex.name}"):
            result = subprocess.run(cmd, cwd=tex.parent, stdin=subprocess.DEVNULL,
                                    capture_output=True, text=True, errors="replace",
                                    timeout=PDFLATEX_TIMEOUT)
    except subprocess.TimeoutExpired:
        raise ExternalToolError(f"pdflatex did not finish {tex} in {PDFLATEX_TIMEOUT} s") \
            from None
    pdf = tex.with_suffix(".pdf")
    if result.returncode != 0 or not pdf.is_file():
        errors = [line for line in result.stdout.splitlines() if line.startswith("!")]
        reason = errors[0] if errors else f"exit status {result.returncode}"
        raise ExternalToolError(f"pdflatex failed on {tex} ({reason}); see "
                                f"{tex.with_suffix('.log')}")
    return pdf


def run_derive(args: argparse.Namespace) -> int:
    derived = derive(args.system)
    lines = sizes(derived)
    document = args.document or args.pdf
    if not document:
        text, seconds = _latex(derived, document=False)
        for line in [*lines, f"LaTeX written in {seconds:.2f} s"]:
            say(f"% {line}")
        say(text)
        return 0
    tex = Path(args.document) if args.document else Path(f"{file_stem(derived.step.name)}.tex")
    if tex.suffix != ".tex":
        raise InputError(f"--document {tex}: the file name must end in .tex")
    if not tex.parent.is_dir():
        raise InputError(f"--document {tex}: the directory {tex.parent} does not exist")
    text, seconds = _latex(derived, document=True)
    tex.write_text(text, encoding="utf-8")
    for line in [*lines, f"LaTeX written in {seconds:.2f} s"]:
        say(line)
    say(f"wrote {tex}")
    if args.pdf:
        say(f"wrote {_pdflatex(tex)}")
    return 0


def run_emit(args: argparse.Namespace) -> int:
    derived = derive(args.system)
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise InputError(f"-o {out}: exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    base = out / file_stem(args.name or derived.step.name)
    t0 = time.perf_counter()
    with Task(f"{derived.step.name}: generating C"):
        paths = derived.step.emit_c(base, prefix=args.prefix)
    seconds = time.perf_counter() - t0
    say(f"{derived.step.name}: {len(derived.step)} equations, derived in "
        f"{derived.seconds:.2f} s, C generated in {seconds:.2f} s")
    for path in paths:
        lines = path.read_text(encoding="utf-8").count("\n")
        say(f"wrote {path} ({lines} lines)")
    return 0
