"""Render the C kernel of a step from the jinja2 templates and write ``path.c``/``path.h``.

The templates (``kernel.c.j2``, ``kernel.h.j2``, ``declarations.j2``, ``cdef.j2``) live in
the top-level ``templates/`` directory of the source tree, installed as the package
``symgroupoid.templates``.  Output is deterministic: no timestamps, fixed ordering,
canonical ``cse`` with positional temporary names.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import hashlib
import os
import re
import sys
import tempfile
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jinja2

from .._arguments import (
    flag_argument,
    instance_argument,
    integer_argument,
    name_argument,
    path_argument,
    real_argument,
)
from .._errors import InputTypeError, OutputError, ShapeError
from ..stepper import Inliner, library_digest
from ._band import band_defines
from ._checks import program_argument, step_argument
from ._kernel import (
    COLD_UNIT,
    MAX_PREFIX,
    assign_units,
    c_identifier,
    kernel_blocks,
    program_functions,
    program_helpers,
    unit_part_size,
)
from ._time import time_layout

TEMPLATE_NAMES = ("kernel.c.j2", "kernel.h.j2", "declarations.j2", "cdef.j2", "program.c.j2",
                  "program.h.j2", "functions.j2", "unit.c.j2", "unit_local.j2", "cold.c.j2",
                  "stepper.c.j2")


def template_dir() -> Path:
    """Directory of the kernel templates (installed package data, else the source tree)."""
    try:
        path = Path(str(resources.files("symgroupoid.templates")))
        if (path / TEMPLATE_NAMES[0]).is_file():
            return path
    except (ModuleNotFoundError, TypeError):
        pass
    path = Path(__file__).resolve().parents[2] / "templates"
    if (path / TEMPLATE_NAMES[0]).is_file():
        return path
    raise FileNotFoundError("symgroupoid kernel templates not found (expected the package "
                            "symgroupoid.templates or a templates/ directory in the source tree)")


class CompiledTemplates(jinja2.BytecodeCache):
    """The templates' compiled Python code kept in directories across processes (jinja2's
    bytecode cache: one file per template, keyed by its path and checked against its
    source), so that a process's first kernel compiles no template (about 0.045 s).
    ``directories``: where to look, in order; ``write_to``: where a template compiled here
    is kept (None: nowhere).  An entry that cannot be read is compiled again, one that
    cannot be written is not kept: the generated C never depends on it."""

    def __init__(self, directories: Sequence[str], write_to: str | None = None):
        self.caches = [jinja2.FileSystemBytecodeCache(d) for d in directories]
        self.writer = None if write_to is None else jinja2.FileSystemBytecodeCache(write_to)

    def load_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        for cache in self.caches:
            try:
                cache.load_bytecode(bucket)
            except Exception:  # a damaged or foreign file: compile the template again
                bucket.reset()
            if bucket.code is not None:
                return

    def dump_bytecode(self, bucket: jinja2.bccache.Bucket) -> None:
        if self.writer is not None:
            with contextlib.suppress(OSError):
                self.writer.dump_bytecode(bucket)


def package_template_cache(write: bool = False) -> str | None:
    """``__pycache__/`` of the templates' directory, where Python keeps the bytecode of a
    package's modules: the templates' compiled code for every process and kernel cache
    (:class:`CompiledTemplates`), filled when the package is set up
    (:func:`precompile_templates`).  For reading: when it exists.  For writing (``write``):
    when Python writes bytecode (not under ``python -B`` or ``PYTHONDONTWRITEBYTECODE``)
    and it is a writable directory (made if missing).  Else None."""
    directory = template_dir() / "__pycache__"
    if not write:
        return str(directory) if directory.is_dir() else None
    if sys.dont_write_bytecode:
        return None
    try:
        return str(_writable(directory))
    except OSError:
        return None


def _writable(directory: Path) -> Path:
    """``directory``, made if missing; ``OSError`` when it cannot be made or written."""
    directory.mkdir(exist_ok=True)
    if not os.access(directory, os.W_OK | os.X_OK):
        raise PermissionError(f"{directory} is not writable")
    return directory


@functools.lru_cache(maxsize=8)  # (one per cache directory in use: a few)
def _environment(directory: str, compiled: tuple[str, ...] = (),
                 write_to: str | None = None) -> jinja2.Environment:
    """The templates of ``directory``; their compiled code looked for in the directories
    ``compiled`` and kept in ``write_to`` (:class:`CompiledTemplates`)."""
    cache = CompiledTemplates(compiled, write_to) if compiled or write_to else None
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(directory), undefined=jinja2.StrictUndefined,
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True, autoescape=False,
        bytecode_cache=cache)


def environment(template_cache: str | None = None) -> jinja2.Environment:
    """The kernel templates; their compiled code looked for in
    :func:`package_template_cache`, then in ``template_cache``, and a template compiled
    here kept in the first of the two that can be written."""
    package = package_template_cache()
    compiled = tuple(d for d in (package, template_cache) if d is not None)
    write_to = package_template_cache(write=True) or template_cache
    return _environment(str(template_dir()), compiled, write_to)


def precompile_templates() -> tuple[str, int]:
    """Compile the kernel templates into :func:`package_template_cache` (made if missing,
    whatever ``PYTHONDONTWRITEBYTECODE`` says: as an installer compiles a package's
    modules), so that no process compiles them again; returns the directory and how many
    compiled templates it holds.  An entry of a template changed since is stale (jinja2
    checks the source) and is compiled again when used.  :class:`~symgroupoid.OutputError` when the
    directory cannot be written."""
    directory = template_dir() / "__pycache__"
    try:
        _writable(directory)
    except OSError as exc:
        raise OutputError(f"cannot keep the compiled kernel templates in {directory}: "
                          f"{exc}") from exc
    env = _environment.__wrapped__(str(template_dir()), (str(directory),), str(directory))
    kept = 0  # the entries of today's templates (not those of templates since removed)
    for name in TEMPLATE_NAMES:
        key = env.bytecode_cache.get_cache_key(name, env.get_template(name).filename)
        kept += (directory / f"__jinja2_{key}.cache").is_file()
    return str(directory), kept


def templates_digest() -> str:
    """SHA-256 over the template files and the Newton stepper's C library
    (:func:`symgroupoid.stepper.library_digest`), which make a kernel's C (part of every
    cache key)."""
    directory = template_dir()
    digest = hashlib.sha256()
    for name in TEMPLATE_NAMES:
        digest.update(name.encode())
        digest.update((directory / name).read_bytes())
    digest.update(library_digest().encode())
    return digest.hexdigest()


@dataclass(frozen=True)
class KernelSource:
    """The generated kernel: header, C source, the cffi declarations, and the C prefix;
    ``units``: further translation units (file name, C source) compiled with the source
    into the same library (none for a kernel in one file); ``cold``: the file names among
    ``units`` of code that does no arithmetic of a step, built at a lower optimisation
    level (``symgroupoid.runtime.toolchain.unit_flags``); ``blocks``: the file names among
    ``units`` of straight-line arithmetic that calls no library function (see
    :func:`arithmetic_only`), which a build may compile at a cheaper level; ``stepper``: the
    file name among ``units`` of the Newton stepper compiled on its own (empty when the
    stepper is in the source)."""

    prefix: str
    header_name: str
    header: str
    source: str
    cdef: str
    units: tuple[tuple[str, str], ...] = ()
    cold: tuple[str, ...] = ()
    blocks: tuple[str, ...] = ()
    stepper: tuple[str, ...] = ()


def _ascii(text: str) -> str:
    """Text safe inside a C comment: ASCII only, no comment terminator."""
    out = text.replace("×", "x").replace("⋊", "|x").replace("*/", "* /")
    return out.encode("ascii", "backslashreplace").decode("ascii")


#: residual programs up to this many operations get their LaTeX in the kernel's comment
LATEX_COMMENT_OPS = 300
#: longer LaTeX of one equation is replaced by a short note
LATEX_COMMENT_CHARS = 2000


def residual_comments(step, latex: bool = True) -> list[str]:
    """One comment line per residual: its LaTeX when ``latex`` is set and the system is small
    enough for printing to be cheap and the line short; else a short note (the equations
    stay available from ``StepEquations.latex()``).

    The LaTeX needs the step's SymPy residuals (:attr:`StepEquations.residuals`), built on
    first request: a kernel built only to be compiled skips them (``latex=False``).
    """
    if not latex:
        return [f"equation {i} of the step (print the equations with "
                f"StepEquations.latex())" for i in range(len(step))]
    from ..equations import latex as latex_of

    ops = step.program.size(["F"])
    if ops > LATEX_COMMENT_OPS:
        return [f"equation {i} of the step ({ops} operations in all; print the equations "
                f"with StepEquations.latex())" for i in range(len(step))]
    forms = step.structured if step.structured is not None else step.residuals
    out = []
    for i, r in enumerate(forms):
        text = _ascii(latex_of(r))
        if len(text) > LATEX_COMMENT_CHARS:
            text = (f"equation {i} of the step ({len(text)} characters of LaTeX; print it "
                    f"with StepEquations.latex())")
        out.append(text)
    return out


def arithmetic_only(program) -> bool:
    """Whether ``program`` calls no library function (every elementary function it uses
    is written inline, as ``fabs``; ``FunctionSpec.calls``)."""
    return not any(spec.calls for spec in program_functions(program, list(program.outputs)))


def library_texts(prefix: str, stepper_unit: bool = False) -> dict[str, str]:
    """The Newton stepper's C library (:mod:`symgroupoid.stepper`) with the names of the
    kernel ``prefix``, as the templates place it: ``interface`` (``stepper.h``, in the
    header after the sizes), ``prologue`` and ``stepper`` (``prologue.h``, ``stepper.c``: the
    kernel's source, around its generated functions), ``cold`` (``batch.c`` after them, for a
    kernel in one file), ``cold_prologue`` and ``cold_unit`` (the same in the cold unit of a
    kernel spread over several).  ``stepper_unit``: ``stepper.c`` goes instead into a unit
    of its own (``stepper_prologue``, ``stepper_unit``; ``stepper`` is then empty)."""
    source, cold, stepper = Inliner(prefix), Inliner(prefix), Inliner(prefix)
    texts = {"interface": Inliner(prefix, provided=()).text("stepper.h"),
             "prologue": source.text("prologue.h")}
    texts["stepper"] = "" if stepper_unit else source.text("stepper.c")
    texts["cold"] = source.text("batch.c")
    texts["cold_prologue"], texts["cold_unit"] = cold.text("prologue.h"), cold.text("batch.c")
    if stepper_unit:
        texts["stepper_prologue"] = stepper.text("prologue.h")
        texts["stepper_unit"] = stepper.text("stepper.c")
    return texts


def _context(step, prefix: str, header_name: str, latex: bool, units: int,
             block_weight: float = 1.0, stepper_unit: bool = False) -> dict:
    from .._version import __version__

    blocks = kernel_blocks(step, unit_part_size(len(step.unknowns), units))
    n_units = assign_units([blocks.reconstruct, blocks.hoist, blocks.residual,
                            blocks.residual_jacobian, blocks.predict, blocks.next_knowns,
                            blocks.domain],
                           units, len(step.unknowns), block_weight)
    cold_helpers = program_helpers(step.program, ["F_scale"])
    if units > 1:  # evaluated only when a rounding floor is tested: beside the cold code
        blocks.residual_scale.move_to(COLD_UNIT)
        if blocks.input_jacobian is not None:  # never called by the stepper
            blocks.input_jacobian.move_to(COLD_UNIT)
            cold_helpers = list(dict.fromkeys(cold_helpers + blocks.input_jacobian_helpers))
    fibre = [f for f in step.fibre_unknowns if f in step.reconstruction]
    band, band_order_initialiser = band_defines(step)
    return {
        "band_defines": band, "band_order": band_order_initialiser,
        "p": prefix, "P": prefix.upper(), "header_name": header_name,
        "name": _ascii(step.name), "version": __version__,
        "groupoid": _ascii(step.groupoid.name),
        "n_equations": len(step), "n_unknowns": len(step.unknowns),
        "n_knowns": len(step.knowns), "n_parameters": len(step.parameters),
        "n_fibre": blocks.n_fibre, "n_constraints": step.n_constraints,
        "n_hoisted": blocks.n_hoisted, "hoist": blocks.hoist,
        "n_domain": blocks.n_domain, "domain": blocks.domain,
        "n_inputs": len(getattr(step, "inputs", ())),
        "input_columns": (getattr(step, "order", 1) + 1) * len(getattr(step, "inputs", ())),
        "time_defines": time_layout(step).defines(),
        "input_names": [_ascii(str(u)) for u in getattr(step, "inputs", ())],
        "unknown_names": [_ascii(s.name) for s in step.unknowns],
        "known_names": [_ascii(s.name) for s in step.knowns],
        "parameter_names": [_ascii(s.name) for s in step.parameters],
        "fibre_names": [_ascii(s.name) for s in fibre],
        "residual_latex": residual_comments(step, latex), "helpers": blocks.helpers,
        "cold_helpers": cold_helpers, "input_jacobian": blocks.input_jacobian,
        "reconstruct": blocks.reconstruct, "residual": blocks.residual,
        "residual_jacobian": blocks.residual_jacobian,
        "residual_scale": blocks.residual_scale,
        "predict": blocks.predict,
        "next_knowns": blocks.next_knowns, "library": library_texts(prefix, stepper_unit),
        "n_units": n_units, "cold_unit": units > 1,
    }


#: the most translation units ``generate_c`` spreads a kernel over
MAX_UNITS = 64


def generate_c(step, prefix: str | None = None, header_name: str | None = None, *,
               latex: bool = False, units: int = 1, block_weight: float | None = None,
               stepper_unit: bool = False,
               template_cache: str | os.PathLike | None = None) -> KernelSource:
    """Generate (without writing) the C kernel of ``step``.

    ``prefix`` (default: sanitised ``step.name``) prefixes every C identifier;
    ``header_name`` (default ``<prefix>.h``) is the header the source includes; ``latex``:
    whether the opening comment lists the residuals in LaTeX (for small systems, see
    :func:`residual_comments`; it costs the SymPy residuals, so by default the comment
    only numbers the equations); ``units``: at most this many translation units
    for the stepper and the straight-line functions, spread over them by the compiler's
    time (:func:`assign_units`), and for ``units > 1`` one more, ``<prefix>_cold.c``, of
    the code that does no arithmetic of a step (``symgroupoid/stepper/batch.c``: the batched entry
    point, the status messages; ``KernelSource.cold``), so that they can all be compiled at
    the same time.  ``units=1`` (the default) is one self-contained file.
    ``block_weight``: None (the default), or the further units of a program that calls no
    library function (:func:`arithmetic_only`) are block units (``KernelSource.blocks``),
    which a build compiles at a cheaper level, and a statement there costs the compiler
    ``block_weight`` times one in the source (:func:`assign_units`); the units of other
    kernels are balanced at 1.
    ``stepper_unit``: the Newton stepper (``symgroupoid/stepper/stepper.c``) in a unit of
    its own, ``<prefix>_stepper.c`` (``KernelSource.stepper``), which a build compiles at
    the level of the stepper's loops (``runtime.toolchain.unit_flags``) whatever the level
    of the straight-line functions.
    ``template_cache``: a directory that keeps the templates' compiled code across processes
    (:class:`CompiledTemplates`: Python, so only a directory as trusted as the package; the
    kernel cache keeps none); the C is the same with or without it.
    """
    step_argument(step, "generate_c")
    if prefix is not None:
        prefix = name_argument(prefix, "prefix", owner=step.name)
        if c_identifier(prefix) != prefix:
            raise ShapeError(f"{step.name}: prefix {prefix!r} is not a prefix of C identifiers "
                             f"as written (lower-case ASCII letters, digits and '_', not "
                             f"starting with a digit, not a C keyword): it would be "
                             f"{c_identifier(prefix)!r}; give that, or another"
                             + (f" (at most {MAX_PREFIX} characters: the kernel's files are "
                                f"named after it)" if len(prefix) > MAX_PREFIX else ""))
    prefix = c_identifier(step.name if prefix is None else prefix)
    units = integer_argument(units, "units", minimum=1, maximum=MAX_UNITS, owner=prefix)
    if block_weight is not None:
        block_weight = real_argument(block_weight, "block_weight", minimum=0.0, owner=prefix)
    if len(step) != len(step.unknowns):
        raise ValueError(f"{step.name}: {len(step)} equations in "
                         f"{len(step.unknowns)} unknowns; a Newton kernel needs a square system")
    if template_cache is not None:
        template_cache = str(path_argument(template_cache, "template_cache", owner=prefix))
    env = environment(template_cache)
    header_name = f"{prefix}.h" if header_name is None else _header_argument(header_name,
                                                                             prefix)
    latex = flag_argument(latex, "latex", owner=prefix)
    lowered = block_weight is not None and units > 1 and arithmetic_only(step.program)
    ctx = _context(step, prefix, header_name, latex, units, block_weight if lowered else 1.0,
                   bool(stepper_unit))
    unit_template = env.get_template("unit.c.j2")
    further = [(f"{prefix}_unit{k}.c", unit_template.render(ctx, unit=k))
               for k in range(1, ctx["n_units"])]
    blocks = tuple(name for name, _ in further) if lowered else ()
    cold = (f"{prefix}_cold.c",) if ctx["cold_unit"] else ()
    further += [(name, env.get_template("cold.c.j2").render(ctx)) for name in cold]
    stepper = (f"{prefix}_stepper.c",) if stepper_unit else ()
    further += [(name, env.get_template("stepper.c.j2").render(ctx)) for name in stepper]
    return KernelSource(prefix=prefix, header_name=header_name,
                        header=env.get_template("kernel.h.j2").render(ctx),
                        source=env.get_template("kernel.c.j2").render(ctx),
                        cdef=env.get_template("cdef.j2").render(ctx),
                        units=tuple(further), cold=cold, blocks=blocks, stepper=stepper)


_UMASK_LOCK = threading.Lock()


def current_umask() -> int:
    """The process umask, read without changing it (``/proc/self/status`` on Linux).

    Where that file is unavailable the umask is set and immediately restored (under a
    lock, so concurrent calls here agree; ``os.umask`` has no read-only form).
    """
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a newly created regular file under the current umask (0644 under 022)."""
    return 0o666 & ~current_umask()


def generate_program_c(label: str, program, inputs: str, outputs: str) -> KernelSource:
    """C99 of a batched program: ``<prefix>_eval(n, n_in, n_out, in, out)`` applies the
    program's output ``outputs`` to n items, each the input array ``inputs`` (row k of
    ``in``).  Used for the boundary-value solver's window kernels; deterministic for equal
    programs."""
    from .._version import __version__
    from ._kernel import build_block, program_helpers

    label = name_argument(label, "label", owner="generate_program_c")
    program_argument(program, f"generate_program_c ({label})", outputs=[outputs],
                     inputs=[inputs])
    prefix = "sgw_" + c_identifier(label)
    block = build_block(program, [("o", outputs)], input_names={inputs: "a"})
    ctx = {"p": prefix, "P": prefix.upper(), "label": _ascii(label), "version": __version__,
           "header_name": f"{prefix}.h", "n_in": len(program.inputs[inputs]),
           "n_out": len(program.outputs[outputs]), "block": block,
           "helpers": program_helpers(program, [outputs])}
    env = environment()
    signature = f"void {prefix}_eval(int n, int n_in, int n_out, const double *in, double *out);"
    return KernelSource(prefix=prefix, header_name=f"{prefix}.h",
                        header=env.get_template("program.h.j2").render(ctx),
                        source=env.get_template("program.c.j2").render(ctx), cdef=signature)


def write_atomic(path: Path, text: str) -> None:
    """Write ASCII ``text`` to ``path`` through a temporary file and an atomic rename.

    The file gets the mode an ordinary ``open`` would give it (``0o666`` less the umask),
    not the private ``0o600`` of the temporary file; readers never see a partial file.
    """
    write_atomic_files([(path, text)])


@contextlib.contextmanager
def _naming(path: Path):
    """An OSError raised within, as one naming ``path``."""
    try:
        yield
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, str(path)) from exc


def write_atomic_files(files: Sequence[tuple[Path, str]]) -> None:
    """Write each ASCII text to its path as :func:`write_atomic` does, all or none: every
    text goes to a temporary file first (a path that is a directory is refused before
    anything is written), then the renames; a rename that fails removes the files this
    call created before it."""
    for path, _ in files:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:  # (e.g. a file where a directory would go): name the file
            raise OSError(exc.errno, exc.strerror, str(path)) from exc
        if path.is_dir() and not path.is_symlink():
            raise IsADirectoryError(errno.EISDIR, "a directory is in the way", str(path))
    temporary: list[str] = []
    created: list[Path] = []
    try:
        for path, text in files:
            with _naming(path):  # (not the temporary file's name)
                fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
                temporary.append(tmp)
                with os.fdopen(fd, "wb") as fh:
                    fh.write(text.encode("ascii"))
                os.chmod(tmp, file_mode())
        for (path, _), tmp in zip(files, temporary):
            new = not os.path.lexists(path)
            with _naming(path):
                os.replace(tmp, path)
            if new:
                created.append(path)
    except BaseException:
        for tmp in temporary:
            Path(tmp).unlink(missing_ok=True)
        for path in created:
            path.unlink(missing_ok=True)
        raise


#: file names ``emit_c`` writes: the portable file name characters, as an ``#include "…"``
#: names them on every system
_PORTABLE_NAME = re.compile(r"[A-Za-z0-9_.+-]+")


def _header_argument(header_name, owner: str) -> str:
    """The name the source includes its header by: a portable file name
    (:data:`_PORTABLE_NAME`), so that ``#include "…"`` is that file and nothing else (a
    quote or a newline in it would end the directive and start another line of C)."""
    if not isinstance(header_name, str):
        raise InputTypeError(f"{owner}: header_name must be a file name (a string such as "
                             f"'{owner}.h'), got {type(header_name).__name__}")
    if not _PORTABLE_NAME.fullmatch(header_name) or header_name in (".", ".."):
        raise ShapeError(f"{owner}: header_name {header_name!r} must be a file name of ASCII "
                         f"letters, digits, '.', '_', '+' and '-' (the source includes the "
                         f"header by it)")
    return header_name


def emit_c(step, path: str | os.PathLike, prefix: str | None = None, *,
           latex: bool = False) -> tuple[Path, Path]:
    """Write ``path.c`` and ``path.h`` for ``step``; return their paths.

    C identifiers are prefixed by the sanitised ``prefix`` (default: ``step.name``), e.g.
    ``plate_ball_simulate``; the source includes the header by its file name.  Both files are
    written atomically; missing directories are created.  ``step``: the
    :class:`~symgroupoid.StepEquations` of a system; ``path``: a ``str`` or ``os.PathLike``
    naming a file (not a directory such as ``/`` or ``.``) whose name is portable (ASCII
    letters, digits, ``._+-``: the source includes the header by it); ``prefix``: None or a
    string; ``latex``: whether the source's opening comment lists each residual in LaTeX
    (for small systems: :func:`residual_comments`; this builds the step's SymPy residuals,
    which takes as long as the derivation); by default it numbers the equations only.
    A file that cannot be written is an :class:`~symgroupoid.OutputError` naming it.
    """
    from ..equations import StepEquations

    instance_argument(step, StepEquations, "step", "the StepEquations of a system (from "
                      "system.euler_lagrange())", owner="emit_c")
    base = path_argument(path, "path", owner=step.name)
    if prefix is not None:
        prefix = name_argument(prefix, "prefix", owner=step.name, empty=True)
    if base.suffix in (".c", ".h"):
        base = base.with_suffix("")
    if base.name in ("", ".", "..") or os.fspath(path).endswith(("/", os.sep)):
        raise ShapeError(f"{step.name}: path must name the files to write (path.c and "
                         f"path.h), got the directory {str(path)!r}")
    if not _PORTABLE_NAME.fullmatch(base.name):
        raise ShapeError(f"{step.name}: path: the file name {base.name!r} must consist of "
                         f"ASCII letters, digits, '.', '_', '+' and '-' (the source includes "
                         f"the header by this name)")
    c_path, h_path = base.with_name(base.name + ".c"), base.with_name(base.name + ".h")
    if not isinstance(latex, bool):
        raise InputTypeError(f"{step.name}: emit_c: latex must be True or False, got "
                             f"{type(latex).__name__}")
    folder = next((p for p in base.parents if os.path.lexists(p)), None)
    if folder is not None and not folder.is_dir():
        raise OutputError(f"{step.name}: path {str(path)!r}: {folder} is not a directory, so "
                          f"nothing can be written below it")
    kernel = generate_c(step, prefix, header_name=h_path.name, latex=latex)
    try:
        write_atomic_files([(h_path, kernel.header), (c_path, kernel.source)])
    except OSError as exc:
        target = exc.filename or path
        raise OutputError(f"{step.name}: path {str(path)!r}: cannot write {target}: "
                          f"{exc.strerror or exc}") from exc
    return c_path, h_path
