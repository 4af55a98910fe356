"""Building a kernel into a shared library and loading it with cffi (ABI mode, out of line).

A kernel is plain C99 without Python headers: it is compiled and linked by one run of the C
compiler into ``<module>.so`` and loaded with ``ffi.dlopen``.  Its cffi type table (the
declarations of ``cdef.j2``, parsed once when the kernel is built) is kept as data: the
literal arguments of cffi's out-of-line ABI constructor ``_cffi_backend.FFI`` (bytes,
integers and tuples of them, :func:`type_table`), checked and passed to it on load
(:func:`ffi_of`), so loading a built kernel parses no C and runs no code from the cache.
A library is checked before it is installed or loaded (:func:`library_defect`: a complete
ELF shared object whose segments and sections lie inside the file), so a truncated one is
never mapped (which would end the process with SIGBUS).
Compared with a Python extension (API mode), a build needs no Python headers, no setuptools
and no wrapper translation unit (about 0.5 s less at small kernels); a call costs about 1 µs
more, which no entry point notices (each call does at least a Newton step).
"""

from __future__ import annotations

import ast
import base64
import json
import os
import shlex
import shutil
import struct
import subprocess
import sys
import sysconfig
import tempfile
import types
from collections.abc import Callable, Sequence
from pathlib import Path

from .._errors import SymgroupoidError
from ..codegen import KernelSource
from ._cache import file_mode

#: flags appended to the compiler command line (after Python's own CFLAGS, so they decide the
#: optimisation level).  -ffp-contract=off keeps a*b+c as two roundings, as in the NumPy backend.
DEFAULT_FLAGS: tuple[str, ...] = ("-O3", "-ffp-contract=off")
#: a program of more operations than this is compiled at -O2 instead of -O3: as fast to run
#: (measured: the planar 32-link chain's step, 3.16e5 against 3.10e5 instructions), and
#: compiled faster (the 64-link chain's 1 MB kernel: 21.9 s against 25.6 s of CPU)
LARGE_PROGRAM = 15_000


#: a step kernel (Newton stepper and its functions) of at most this many operations is
#: compiled at :data:`SMALL_STEP_LEVEL` instead of -O3: in half to three quarters of the
#: compiler's time, and up to 4000 operations as fast to step.  Measured per build (CPU
#: seconds of the stepper unit, -O3 -> small-step level; machine instructions per step from
#: a Newton loop in C): plate-ball 0.85 -> 0.43 s, 4635 -> 4610; planar chain of 8 links
#: 0.36 -> 0.18 s, 27950 -> 27799; 16 links 0.79 -> 0.33 s, 95570 -> 102165 (and 4 % faster
#: per step); 3D chain of 2 bodies 0.26 -> 0.16 s, 7647 -> 7551; of 4 bodies 0.47 -> 0.26 s,
#: 11 % faster per step.  Above 4000 operations the level trades step time for build time
#: (wall seconds of the whole compile, µs per step): 3D chain of 6 bodies (5822 operations)
#: 0.75 -> 0.54 s, 3.75 -> 4.05 µs (+8 %); of 8 bodies (8331) 1.10 -> 0.81 s, 5.95 -> 6.75 µs
#: (+13 %), still under half of CasADi's generated step (``benchmarks/scaling.py``).  For a
#: long simulation, ``compile(flags=["-O3", "-ffp-contract=off"])`` builds at -O3.  The
#: planar chain of 32 links (12337 operations) and larger keep -O3 (-O2 above
#: LARGE_PROGRAM).
SMALL_STEP = 9_000
#: -O1 with complete peeling of loops of a few constant iterations (the stepper's loops over
#: the unknowns, which -O3 unrolls), and loops aligned to 32 bytes: the level of a small
#: step's kernel.  Without the alignment the step time depends on where the linker happens to
#: place the Newton loop (the plate-ball's 0.28 to 0.33 µs for the same C under different
#: layouts); with it, measured in one run each (µs per step, without -> with): plate-ball
#: 0.32 -> 0.28, 3D chain of 2 bodies 0.95 -> 0.81, of 6 bodies 4.26 -> 4.18, planar chain of
#: 8 links 2.28 -> 2.28.
SMALL_STEP_LEVEL: tuple[str, ...] = ("-O1", "-fpeel-loops", "-falign-loops=32")


#: what a larger step kernel (more than :data:`SMALL_STEP` operations) adds to its level:
#: no superword-level (SLP) vectorisation of straight-line code, whose cost grows faster
#: than the code.  Measured (wall seconds of the whole compile, µs per step, in one run):
#: planar chain of 32 links (-O3) 2.09 -> 1.42 s, 24.9 -> 26.0 µs; of 64 links (-O2)
#: 17.8 -> 6.0 s, 122 -> 129 µs (one of its units: 17.0 -> 4.6 s of CPU, of which SLP
#: vectorisation itself was 5.1 s and the passes after it most of the rest); 3D chain of 16
#: bodies (-O2) 1.86 -> 1.45 s, 27.7 -> 27.4 µs.
LARGE_STEP_FLAGS: tuple[str, ...] = ("-fno-tree-slp-vectorize",)


def optimisation_flags(operations: int, *, step: bool = False) -> tuple[str, ...]:
    """The compiler flags of a kernel of ``operations`` operations (deterministic); a Newton
    step's kernel (``step``) of at most :data:`SMALL_STEP` operations at
    :data:`SMALL_STEP_LEVEL`, a larger one with :data:`LARGE_STEP_FLAGS`."""
    if step and operations <= SMALL_STEP:
        return SMALL_STEP_LEVEL + DEFAULT_FLAGS[1:]
    level = ("-O2",) + DEFAULT_FLAGS[1:] if operations > LARGE_PROGRAM else DEFAULT_FLAGS
    return level + LARGE_STEP_FLAGS if step else level

#: the optimisation level of a kernel's cold unit (``KernelSource.cold``: the batched entry
#: point with its OpenMP region, the status messages): 0.036 s of the compiler at -Og,
#: against 0.047 s at -O1 and 0.11 s at -O3 (CPU time, any system; 0.015 s of it starts
#: the compiler), run beside the other units
COLD_LEVEL = "-Og"
#: the levels a cold unit is lowered from (a build at -O0, -Og or -Os keeps its own)
LOWERED_LEVELS = frozenset({"-O", "-O1", "-O2", "-O3"})
#: the optimisation level of a kernel's block units (``KernelSource.blocks``: straight-line
#: arithmetic that calls no library function -- parts of the residual and its Jacobian, the
#: chart, the prediction, the state update), which a build at the library's default flags
#: has.  -Og is -O1 without the passes that matter for loops, branches and library calls
#: (if-conversion, loop invariant motion, scalar replacement of aggregates, pairing sin and
#: cos into sincos ...), which such code does not have.  Measured (gcc 12, CPU seconds of a
#: block unit, -O1 -> -Og): 3D chain of 4 bodies 0.35 -> 0.18, of 8 bodies 0.69 -> 0.45;
#: at -O3 -> -Og, of 8 bodies 1.04 -> 0.45.  Steps take as long (µs per step, at the
#: default flags without -> with, in one run): 3D chain of 3 bodies 1.38 -> 1.37, of 4
#: bodies 2.13 -> 2.17, of 6 bodies 4.42 -> 4.40, of 8 bodies 7.40 -> 7.37, of 16 bodies
#: 28.3 -> 27.3 (``benchmarks/scaling.py`` for whole builds).  The planar chains' blocks
#: call sin and cos: at -Og they step up to 30 % slower and build no faster, so they are
#: not block units.
BLOCK_LEVEL = "-Og"
#: the compiler's time on a block unit at :data:`BLOCK_LEVEL` relative to the same code at
#: the build's level (the weight ``codegen.assign_units`` balances the units by), from the
#: measurements above; at other levels a block unit keeps the build's flags
BLOCK_WEIGHTS = {"-O": 0.6, "-O1": 0.6, "-O2": 0.45, "-O3": 0.45}


def _level(flags: Sequence[str]) -> str | None:
    """The last ``-O`` option of ``flags`` (the one the compiler obeys), or None."""
    levels = [f for f in flags if f.startswith("-O")]
    return levels[-1] if levels else None


def block_weight(flags: Sequence[str]) -> float:
    """The compiler's time on a block unit of a build at ``flags`` relative to the same
    code at ``flags``: :data:`BLOCK_WEIGHTS` where the unit is lowered to
    :data:`BLOCK_LEVEL` (:func:`unit_flags`), else 1."""
    return BLOCK_WEIGHTS.get(_level(flags), 1.0)


#: the roles of a translation unit (see :func:`unit_flags`)
UNIT_ROLES = ("step", "blocks", "cold")


def unit_flags(flags: Sequence[str], role: str = "step") -> tuple[str, ...]:
    """The flags of one translation unit of a build at ``flags`` (deterministic).

    ``role``: ``"cold"`` (``KernelSource.cold``) gets :data:`COLD_LEVEL` after ``flags``
    when their last ``-O`` option is one of :data:`LOWERED_LEVELS`; ``"blocks"``
    (``KernelSource.blocks``, which only a kernel generated for the library's default
    flags has) gets :data:`BLOCK_LEVEL` after them when their last ``-O`` option is one of
    :data:`BLOCK_WEIGHTS`; ``"step"`` (the kernel's source, and any other unit) keeps
    them.  Neither level changes a result: a cold unit does no floating-point arithmetic
    of a step, and no level reorders a block's floating-point operations (no -ffast-math;
    -ffp-contract=off keeps every rounding).
    """
    flags = tuple(flags)
    if role not in UNIT_ROLES:
        raise ValueError(f"unknown translation unit role {role!r}")
    level = _level(flags)
    if role == "cold" and level in LOWERED_LEVELS:
        return (*flags, COLD_LEVEL)
    if role == "blocks" and level in BLOCK_WEIGHTS:
        return (*flags, BLOCK_LEVEL)
    return flags

#: how to do without a compiler (appended to every compiler error)
NUMPY_HINT = ('To use the NumPy backend instead (same results, slower), pass backend="numpy" '
              '(compile_step, DiscreteSystem.compile) or set SYMGROUPOID_BACKEND=numpy.')


class CompilationError(SymgroupoidError, RuntimeError):
    """The C compiler rejected a generated kernel; ``.output`` holds its messages."""

    def __init__(self, message: str, output: str = ""):
        super().__init__(message)
        self.output = output


class CompilerNotFoundError(SymgroupoidError, RuntimeError):
    """No C compiler could be found (``$CC`` or Python's configured compiler)."""


def compiler_command() -> list[str]:
    """The C compiler command cffi will use: ``$CC``, else Python's configured ``CC``."""
    command = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    try:
        words = shlex.split(command)
    except ValueError:
        words = []
    if not words:
        raise CompilerNotFoundError(f"cannot parse the compiler command {command!r}")
    return words


def find_compiler() -> str:
    """Path of the C compiler cffi will use: ``$CC``, else Python's configured ``CC``."""
    words = compiler_command()
    command, exe = " ".join(words), words[0]
    path = shutil.which(exe)
    if path is None:
        raise CompilerNotFoundError(f"C compiler {exe!r} not found (from CC={command!r})")
    return path


def module_name(source_key: str) -> str:
    return f"_sgk_{source_key[:24]}"


def compile_args(flags: Sequence[str]) -> list[str]:
    """The extra compiler arguments of a build: ``flags``, after ``-g0`` unless they ask
    for debug information themselves (``-g``, ``-ggdb``, ...).

    Python's own CFLAGS (passed first, see :func:`build_command`) usually contain ``-g``;
    debug information more than doubles the library's size and slows the build; it changes
    no generated code.
    """
    flags = list(flags)
    return flags if any(f.startswith("-g") for f in flags) else ["-g0", *flags]


def link_args(flags: Sequence[str]) -> list[str]:
    """The extra linker arguments of a build: ``-fopenmp`` when the kernel is compiled with
    it (the OpenMP runtime must be linked into the library too)."""
    return ["-fopenmp"] if "-fopenmp" in flags else []


def probe_compiler(command: Sequence[str]) -> str | None:
    """None if ``command`` compiles a trivial C file; otherwise what went wrong."""
    with tempfile.TemporaryDirectory(prefix="symgroupoid-probe-") as tmp:
        source, obj = Path(tmp) / "probe.c", Path(tmp) / "probe.o"
        source.write_text("int symgroupoid_probe(void) { return 0; }\n", encoding="ascii")
        try:
            result = subprocess.run([*command, "-c", str(source), "-o", str(obj)],
                                    stdin=subprocess.DEVNULL, capture_output=True,
                                    text=True, errors="replace", timeout=120)
        except (OSError, subprocess.SubprocessError) as exc:
            return str(exc)
        if result.returncode == 0 and obj.is_file():
            return None
        output = (result.stdout + result.stderr).strip()
        return output or f"exit status {result.returncode}, no output"


def _failure(kernel: KernelSource, failure: str, output: str) -> CompilationError:
    """The error for a failed build, telling a broken compiler from a rejected kernel."""
    try:
        command = compiler_command()
        broken = probe_compiler(command)
    except CompilerNotFoundError:
        command, broken = [], None
    if broken is not None:
        head = (f"{kernel.prefix}: the C compiler {' '.join(command)!r} fails even on a "
                f"trivial C file ({broken}), so it cannot build kernels; set CC to a working "
                f"C compiler.")
    else:
        head = f"{kernel.prefix}: the C compiler failed ({failure})."
    return CompilationError(f"{head}\nCompiler output:\n{output}\n{NUMPY_HINT}", output=output)


def _words(text: str | None) -> list[str]:
    """Shell words of a flags variable (split at white space when it does not parse)."""
    if not text:
        return []
    try:
        return shlex.split(text)
    except ValueError:
        return text.split()


#: the kernels compile_step builds are spread over at most this many translation units
#: (by size, see ``codegen.generate_c``), compiled at the same time, where at least
#: PARALLEL_CPUS processors are usable (see :func:`translation_units`)
TRANSLATION_UNITS = 2
PARALLEL_CPUS = 2


def usable_cpus() -> int:
    """The processors this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def translation_units() -> int:
    """How many translation units a kernel's stepper and straight-line functions are built
    from: ``TRANSLATION_UNITS`` on a machine of ``PARALLEL_CPUS`` usable processors or more
    (and then one more, the cold unit, see ``codegen.generate_c``), else one file.

    Measured on two processors with the second one free (wall seconds of the compiler, one
    unit → two): planar 8-link chain 0.62 → 0.47, 3D chain of 3 bodies 0.73 → 0.46, of 8
    bodies 1.78 → 0.93; the compiler's total time grows by about 10 %, so where the second
    processor is busy the build takes that much longer.  Small kernels too: their stepper
    takes the compiler longer than their straight-line functions
    (``codegen._kernel.assign_units``).  The kernel's C then depends on the machine (its
    source key too); what it computes does not.
    """
    return TRANSLATION_UNITS if usable_cpus() >= PARALLEL_CPUS else 1


def compiler_flags_of(flags: Sequence[str]) -> list[str]:
    """The compiler and its flags for every run of a build, in the order a Python extension
    build uses: Python's configured ``CFLAGS`` and ``CCSHARED`` (position-independent
    code), then ``$CPPFLAGS`` and ``$CFLAGS`` from the environment, then
    :func:`compile_args` (so ``flags`` decide the optimisation level)."""
    config = sysconfig.get_config_var
    return [*compiler_command(), *_words(config("CFLAGS")), *_words(config("CCSHARED")),
            *_words(os.environ.get("CPPFLAGS")), *_words(os.environ.get("CFLAGS")),
            *compile_args(flags), "-fPIC"]


def link_tail(flags: Sequence[str]) -> list[str]:
    """What ends a link: ``$LDFLAGS``, :func:`link_args` and the maths library."""
    return [*_words(os.environ.get("LDFLAGS")), *link_args(flags), "-lm"]


def build_environment() -> tuple[str, ...]:
    """What reaches every compiler run of a build besides a kernel's own flags, one labelled
    part each (part of every cache key): the words of ``$CC`` (else Python's configured
    ``CC``), Python's ``CFLAGS`` and ``CCSHARED``, and ``$CPPFLAGS``, ``$CFLAGS`` and
    ``$LDFLAGS``.  Any of them can change a kernel's bits (``-m32``, ``-mfpmath=387``,
    ``-fexcess-precision=fast``, ...), so a kernel built under one environment is never
    served to another.  Never raises: an unparsable variable counts by its words."""
    config = sysconfig.get_config_var
    command = os.environ.get("CC") or config("CC") or "cc"
    parts = {"CC": command, "PY_CFLAGS": config("CFLAGS"), "PY_CCSHARED": config("CCSHARED"),
             "CPPFLAGS": os.environ.get("CPPFLAGS"), "CFLAGS": os.environ.get("CFLAGS"),
             "LDFLAGS": os.environ.get("LDFLAGS")}
    return tuple(f"{name}={json.dumps(_words(value))}" for name, value in parts.items())


def build_command(source: str, library: str, flags: Sequence[str]) -> list[str]:
    """The one compiler run that compiles ``source`` and links it into the shared library
    ``library`` (:func:`compiler_flags_of`, then :func:`link_tail`)."""
    return [*compiler_flags_of(flags), "-shared", source, "-o", library, *link_tail(flags)]


def ffi_module_source(kernel: KernelSource, name: str, directory: Path) -> str:
    """The source of cffi's out-of-line ABI module of ``kernel``'s declarations (``cdef``):
    Python that builds the ``ffi`` object (types, functions, constants) without parsing C.
    Only read, by :func:`type_table`; never run.

    Written through a scratch file in ``directory``, removed again.  A malformed ``cdef``
    raises :class:`CompilationError`.
    """
    import cffi
    from cffi.recompiler import make_py_source

    ffi = cffi.FFI()
    try:
        ffi.cdef(kernel.cdef)
    except cffi.CDefError as exc:
        raise CompilationError(f"{kernel.prefix}: the kernel's cffi declarations do not "
                               f"parse ({exc})", output=str(exc)) from exc
    path = directory / f"{name}.py"
    try:
        make_py_source(ffi, name, str(path))
        return path.read_text(encoding="ascii")
    finally:
        path.unlink(missing_ok=True)


#: the keyword arguments of ``_cffi_backend.FFI`` a kernel's type table may hold (cffi's
#: out-of-line ABI module; never ``_includes``, which would name other modules)
TYPE_TABLE_KEYWORDS = frozenset({"_version", "_types", "_globals", "_struct_unions",
                                 "_enums", "_typenames"})
#: how deeply the values of a type table nest (cffi's: a tuple of tuples of fields)
_TABLE_DEPTH = 4


def type_table(kernel: KernelSource, name: str, directory: Path) -> dict:
    """The cffi type table of ``kernel`` as JSON data: ``{"name": name, "<keyword>":
    value, ...}``, the literal arguments of the ``_cffi_backend.FFI(...)`` call of its
    out-of-line ABI module (:func:`ffi_module_source`), read with :func:`ast.literal_eval`
    (which evaluates literals only), bytes as ``{"b64": ...}``, tuples as lists."""
    source = ffi_module_source(kernel, name, directory)
    try:
        call = _ffi_call(ast.parse(source))
        arguments = {kw.arg: ast.literal_eval(kw.value) for kw in call.keywords}
        module = ast.literal_eval(call.args[0])
        if len(call.args) != 1 or module != name or set(arguments) - TYPE_TABLE_KEYWORDS:
            raise ValueError("unexpected arguments")
        table = {"name": module, **{k: _encoded(v, 0) for k, v in sorted(arguments.items())}}
        checked_table(table, name)
    except (SyntaxError, ValueError, TypeError, IndexError) as exc:
        raise CompilationError(f"{kernel.prefix}: cffi's type table of the kernel is not in "
                               f"the form this version reads ({exc}); cffi "
                               f"{_cffi_version()} may be too new", output=source) from exc
    return table


def _cffi_version() -> str:
    import cffi

    return cffi.__version__


def _ffi_call(tree: ast.Module) -> ast.Call:
    """The ``ffi = _cffi_backend.FFI(...)`` call of an out-of-line ABI module."""
    for node in tree.body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name) and node.targets[0].id == "ffi"
                and isinstance(node.value, ast.Call)):
            func = node.value.func
            if (isinstance(func, ast.Attribute) and func.attr == "FFI"
                    and isinstance(func.value, ast.Name) and func.value.id == "_cffi_backend"):
                return node.value
        elif not isinstance(node, ast.Import | ast.Expr):
            break
    raise ValueError("no ffi = _cffi_backend.FFI(...) call")


def _encoded(value, depth: int):
    """A literal of a type table as JSON data (see :func:`type_table`)."""
    if depth > _TABLE_DEPTH:
        raise ValueError("nested too deeply")
    if isinstance(value, bytes):
        return {"b64": base64.b64encode(value).decode("ascii")}
    if isinstance(value, tuple):
        return [_encoded(v, depth + 1) for v in value]
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    raise ValueError(f"a value of type {type(value).__name__}")


def _decoded(value, depth: int):
    """The inverse of :func:`_encoded`, accepting nothing else (``ValueError``)."""
    if depth > _TABLE_DEPTH:
        raise ValueError("nested too deeply")
    if isinstance(value, list):
        return tuple(_decoded(v, depth + 1) for v in value)
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, dict) and set(value) == {"b64"} and isinstance(value["b64"], str):
        return base64.b64decode(value["b64"].encode("ascii"), validate=True)
    raise ValueError(f"a value of type {type(value).__name__}")


def checked_table(table, name: str) -> dict:
    """The keyword arguments of ``_cffi_backend.FFI`` in a type table (data only, checked:
    ``ValueError`` for anything else)."""
    if not isinstance(table, dict) or table.get("name") != name:
        raise ValueError(f"not the type table of {name}")
    keywords = {k: _decoded(v, 0) for k, v in table.items() if k != "name"}
    if set(keywords) - TYPE_TABLE_KEYWORDS or "_types" not in keywords:
        raise ValueError(f"unexpected entries {sorted(set(keywords) - TYPE_TABLE_KEYWORDS)}")
    if not isinstance(keywords["_types"], bytes) or not isinstance(keywords.get("_version"), int):
        raise ValueError("_types must be bytes and _version an integer")
    return keywords


def ffi_of(table, name: str):
    """cffi's ``ffi`` object of a type table (:func:`type_table`), made by
    ``_cffi_backend.FFI`` from its checked data; ``ImportError`` when malformed."""
    import _cffi_backend

    try:
        return _cffi_backend.FFI(name, **checked_table(table, name))
    except Exception as exc:  # noqa: BLE001 - anything wrong in the type table
        raise ImportError(f"the cffi type table of {name} does not load: {exc}") from exc


def create_file(path: Path, text: str) -> None:
    """Write ASCII ``text`` to the new file ``path`` (``O_EXCL``: never through a link or
    into a file that exists), with the mode an ordinary file gets less group and other
    write permission."""
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0), file_mode())
    with os.fdopen(fd, "wb") as fh:
        fh.write(text.encode("ascii"))


def build_extension(kernel: KernelSource, build_dir: Path, name: str,
                    flags: Sequence[str]) -> tuple[Path, dict]:
    """Compile ``kernel`` into ``build_dir`` as the shared library ``<name>.so``; return its
    path and its cffi type table (:func:`type_table`, for :func:`load_extension`).

    The header and sources are written next to the library (and stay there); a kernel in
    several units is compiled by one compiler run per unit, all at the same time (each with
    :func:`unit_flags` of its role), then linked by one more; the type table is made while
    the compiler runs.  Compiler output is captured and shown in
    :class:`CompilationError` on failure, which is also raised when the compiler reports
    success but the library is damaged (:func:`library_defect`).
    """
    create_file(build_dir / kernel.header_name, kernel.header)
    sources = [(f"{kernel.prefix}.c", kernel.source), *kernel.units]
    for file_name, text in sources:
        create_file(build_dir / file_name, text)
    library = build_dir / f"{name}.so"
    table: list[dict] = []

    def make_table() -> None:  # Python work done while the compiler runs
        table.append(type_table(kernel, name, build_dir))

    if len(sources) == 1:
        _run(kernel, [build_command(sources[0][0], library.name, flags)], build_dir,
             make_table)
    else:  # the units at the same time, then one link
        objects = [f"{Path(file_name).stem}.o" for file_name, _ in sources]
        _run(kernel, [[*compiler_flags_of(unit_flags(flags, _role(kernel, file_name))),
                       "-c", file_name, "-o", obj]
                      for (file_name, _), obj in zip(sources, objects)], build_dir,
             make_table)
        _run(kernel, [[*compiler_flags_of(flags), "-shared", *objects, "-o", library.name,
                       *link_tail(flags)]], build_dir)
        for obj in objects:
            (build_dir / obj).unlink(missing_ok=True)
    if not library.is_file() or library.is_symlink():
        raise _failure(kernel, "the compiler wrote no library", "")
    defect = library_defect(library.read_bytes())
    if defect is not None:
        raise CompilationError(
            f"{kernel.prefix}: the C compiler reported success but wrote a damaged library "
            f"({defect}); it was not installed. Check the compiler ({' '.join(compiler_command())}"
            f") and the free space of {build_dir.parent}.\n{NUMPY_HINT}", output=defect)
    return library, table[0]


def _role(kernel: KernelSource, file_name: str) -> str:
    """The role of a translation unit of ``kernel`` (see :func:`unit_flags`)."""
    if file_name in kernel.cold:
        return "cold"
    return "blocks" if file_name in kernel.blocks else "step"


def _run(kernel: KernelSource, commands: list[list[str]], cwd: Path,
         meanwhile: Callable[[], None] | None = None) -> None:
    """Run compiler ``commands`` at the same time in ``cwd`` (and ``meanwhile()`` while they
    run); :class:`CompilationError` with the output of every failed one."""
    processes: list = []

    def stop() -> None:
        for _, process in processes:
            process.kill()
            process.communicate()

    try:
        for command in commands:
            processes.append((command, subprocess.Popen(
                command, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT, text=True, errors="replace")))
    except OSError as exc:
        stop()
        raise _failure(kernel, f"cannot run {commands[0][0]!r}: {exc}", str(exc)) from exc
    try:
        if meanwhile is not None:
            meanwhile()
    except BaseException:
        stop()
        raise
    failures = []
    for command, process in processes:
        output, _ = process.communicate()
        if process.returncode != 0:
            failures.append((command, process.returncode, output.strip()))
    if failures:
        command, status, _ = failures[0]
        raise _failure(kernel, f"command {command[0]!r} failed with exit status {status}",
                       "\n".join(output for _, _, output in failures))


# -- checking a library before it is mapped ---------------------------------------------------

_ELF_MAGIC = b"\x7fELF"
#: (ELF header after e_ident, program header, section header) of ELFCLASS32 and ELFCLASS64
_ELF_LAYOUTS = {1: ("HHIIIIIHHHHHH", "IIIIIIII", "IIIIIIIIII"),
                2: ("HHIQQQIHHHHHH", "IIQQQQQQ", "IIQQQQIIQQ")}
_ET_DYN, _PT_LOAD, _SHT_NOBITS = 3, 1, 8


def library_defect(data: bytes) -> str | None:
    """What makes ``data`` (a kernel library's bytes) unfit to load, or None.

    On ELF systems: it must be an ELF shared object (``ET_DYN``) whose program header
    table, loaded segments (``PT_LOAD``: what ``dlopen`` maps), section header table and
    sections lie inside the file.  Mapping a segment that extends past the end of a
    truncated file kills the process with SIGBUS on first access, so this is checked
    before a library is installed or loaded.  Elsewhere (macOS, Windows): only that it is
    not empty.  About 20 µs.
    """
    if sys.platform == "darwin" or os.name == "nt":
        return None if data else "the file is empty"
    size = len(data)
    if size < 52 or data[:4] != _ELF_MAGIC:
        return f"not an ELF shared object ({size} bytes)"
    layout, order = _ELF_LAYOUTS.get(data[4]), {1: "<", 2: ">"}.get(data[5])
    if layout is None or order is None:
        return "an ELF file of unknown class or byte order"
    header, program, section = (struct.Struct(order + f) for f in layout)
    if size < 16 + header.size:
        return f"the ELF header is cut off ({size} bytes)"
    (e_type, _, _, _, phoff, shoff, _, _, phentsize, phnum, shentsize, shnum,
     _) = header.unpack_from(data, 16)
    if e_type != _ET_DYN:
        return f"an ELF file of type {e_type}, not a shared object"
    if phnum == 0 or phentsize < program.size or phoff + phnum * phentsize > size:
        return f"its program header table lies outside the file ({size} bytes)"
    for i in range(phnum):
        entry = program.unpack_from(data, phoff + i * phentsize)
        p_type, p_offset, p_filesz = ((entry[0], entry[1], entry[4]) if data[4] == 1
                                      else (entry[0], entry[2], entry[5]))
        if p_type == _PT_LOAD and p_offset + p_filesz > size:
            return (f"a loaded segment ends at byte {p_offset + p_filesz}, past the end of "
                    f"the file ({size} bytes): it is truncated")
    if shnum and (shentsize < section.size or shoff + shnum * shentsize > size):
        return (f"its section header table ends at byte {shoff + shnum * shentsize}, past "
                f"the end of the file ({size} bytes): it is truncated")
    for i in range(shnum):
        entry = section.unpack_from(data, shoff + i * shentsize)
        sh_type, sh_offset, sh_size = entry[1], entry[4], entry[5]
        if sh_type != _SHT_NOBITS and sh_offset + sh_size > size:
            return (f"a section ends at byte {sh_offset + sh_size}, past the end of the file "
                    f"({size} bytes): it is truncated")
    return None


def load_extension(path: Path, name: str, table: dict | None = None
                   ) -> types.SimpleNamespace:
    """Load the kernel library ``path``: a namespace with its ``ffi`` and ``lib`` (the
    entry points and constants of ``cdef.j2``).

    ``table``: the type table :func:`build_extension` returned; default: the ``types`` of
    the manifest of the cache entry holding ``path``.  The library is checked
    (:func:`library_defect`) before it is mapped.  Raises ``ImportError`` or ``OSError``
    when the library or its type table cannot be loaded.
    """
    if table is None:
        table = _manifest_types(Path(path))
    ffi = ffi_of(table, name)
    try:
        with open(path, "rb", opener=_nofollow) as fh:
            defect = library_defect(fh.read())
    except OSError as exc:
        raise ImportError(f"cannot read the kernel library {path}: {exc}") from exc
    if defect is not None:
        raise ImportError(f"the kernel library {path} is damaged: {defect}")
    lib = ffi.dlopen(str(path))
    return types.SimpleNamespace(__name__=name, __file__=str(path), ffi=ffi, lib=lib)


def _nofollow(path: str, flags: int) -> int:
    """``open``'s opener that never follows a link at the last component."""
    return os.open(path, flags | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))


def _manifest_types(path: Path) -> dict:
    """The type table recorded in the manifest next to the library ``path``."""
    try:
        with open(path.parent / "manifest.json", encoding="utf-8", opener=_nofollow) as fh:
            table = json.load(fh)["types"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise ImportError(f"no cffi type table for {path} in its manifest: {exc}") from exc
    if not isinstance(table, dict):
        raise ImportError(f"no cffi type table for {path} in its manifest")
    return table
