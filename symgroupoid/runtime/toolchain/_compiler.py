"""The C compiler: which one (``$CC``, else Python's), its command lines, the build
environment that reaches it, and its errors."""

from __future__ import annotations

import json
import os
import shlex
import shutil
import subprocess
import sysconfig
import tempfile
from collections.abc import Sequence
from pathlib import Path

from ..._errors import SymgroupoidError
from ...codegen import KernelSource
from ._isa import vector_flags
from ._processes import scratch_prefix, sweep_scratch

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


def _compiler_text() -> str:
    """``$CC``, else Python's configured ``CC``, else ``cc``: the compiler command's text."""
    return os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"


def compiler_command() -> list[str]:
    """The C compiler command cffi will use: ``$CC``, else Python's configured ``CC``."""
    command = _compiler_text()
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


def compile_args(flags: Sequence[str]) -> list[str]:
    """The extra compiler arguments of a build: ``flags``, after ``-g0`` unless they ask
    for debug information themselves (``-g``, ``-ggdb``, ...), then the vector extension
    the build adds (:func:`added_vector_flags`) with ``-ffp-contract=off`` unless the flags
    choose a contraction.

    Python's own CFLAGS (passed first, see :func:`build_command`) usually contain ``-g``;
    debug information more than doubles the library's size and slows the build; it changes
    no generated code.
    """
    flags = list(flags)
    args = flags if any(f.startswith("-g") for f in flags) else ["-g0", *flags]
    isa = added_vector_flags(flags)
    chosen = any(f.startswith("-ffp-contract") for f in [*flags, *_environment_flags()])
    # an extension the build adds may bring fused multiply-adds (AVX-512F does to gcc 12):
    # no contraction then, unless the flags choose one (the NumPy twin rounds every product)
    return [*args, *isa, *(() if not isa or chosen else ("-ffp-contract=off",))]


def added_vector_flags(flags: Sequence[str]) -> tuple[str, ...]:
    """The instruction-set flag :func:`compile_args` adds to a build at ``flags``
    (:func:`~._isa.vector_flags` of the compiler, ``flags``, ``$CPPFLAGS`` and ``$CFLAGS``)."""
    return vector_flags(_words(_compiler_text()), [*flags, *_environment_flags()])


def _environment_flags() -> list[str]:
    """The words of ``$CPPFLAGS`` and ``$CFLAGS``."""
    return [*_words(os.environ.get("CPPFLAGS")), *_words(os.environ.get("CFLAGS"))]


def link_args(flags: Sequence[str]) -> list[str]:
    """The extra linker arguments of a build: ``-fopenmp`` when the kernel is compiled with
    it (the OpenMP runtime must be linked into the library too)."""
    return ["-fopenmp"] if "-fopenmp" in flags else []


def compiler_environment(directory: Path) -> dict[str, str]:
    """This process's environment with ``TMPDIR`` (and ``TMP``, ``TEMP``) set to
    ``directory``, the build's own: the compiler's temporary files (``cc*.s``) are made
    there, so a build killed mid-way leaves them where the cache sweeps, never in the
    system's temporary directory."""
    return {**os.environ, "TMPDIR": str(directory), "TMP": str(directory),
            "TEMP": str(directory)}


def probe_compiler(command: Sequence[str]) -> str | None:
    """None if ``command`` compiles a trivial C file; otherwise what went wrong."""
    sweep_scratch("probe")
    with tempfile.TemporaryDirectory(prefix=scratch_prefix("probe")) as tmp:
        source, obj = Path(tmp) / "probe.c", Path(tmp) / "probe.o"
        source.write_text("int symgroupoid_probe(void) { return 0; }\n", encoding="ascii")
        try:
            result = subprocess.run([*command, "-c", str(source), "-o", str(obj)],
                                    stdin=subprocess.DEVNULL, capture_output=True,
                                    text=True, errors="replace", timeout=120,
                                    env=compiler_environment(Path(tmp)))
        except (OSError, subprocess.SubprocessError) as exc:
            return str(exc)
        if result.returncode == 0 and obj.is_file():
            return None
        output = (result.stdout + result.stderr).strip()
        return output or f"exit status {result.returncode}, no output"


def _failure(kernel: KernelSource, failure: str, output: str,
             flags: Sequence[str] = ()) -> CompilationError:
    """The error for a failed build at ``flags``, telling a broken compiler from a rejected
    kernel, and naming the instruction-set flag the build added (an old compiler may not
    know it)."""
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
    isa = added_vector_flags(flags)
    if isa and any(flag in output or flag.removeprefix("-m") in output for flag in isa):
        head += (f" The kernel was compiled with {' '.join(isa)} for this processor; "
                 f"SYMGROUPOID_VECTOR_ISA=none builds for the compiler's default target.")
    return CompilationError(f"{head}\nCompiler output:\n{output}\n{NUMPY_HINT}", output=output)


def _words(text: str | None) -> list[str]:
    """Shell words of a flags variable (split at white space when it does not parse)."""
    if not text:
        return []
    try:
        return shlex.split(text)
    except ValueError:
        return text.split()


def compiler_flags_of(flags: Sequence[str]) -> list[str]:
    """The compiler and its flags for every run of a build, in the order a Python extension
    build uses: Python's configured ``CFLAGS`` and ``CCSHARED`` (position-independent
    code), then ``$CPPFLAGS`` and ``$CFLAGS`` from the environment, then
    :func:`compile_args` (so ``flags`` decide the optimisation level; they end with the
    instruction-set flag of :func:`~._isa.vector_flags`)."""
    config = sysconfig.get_config_var
    return [*compiler_command(), *_words(config("CFLAGS")), *_words(config("CCSHARED")),
            *_environment_flags(), *compile_args(flags), "-fPIC"]


def link_tail(flags: Sequence[str]) -> list[str]:
    """What ends a link: ``$LDFLAGS``, :func:`link_args` and the maths library."""
    return [*_words(os.environ.get("LDFLAGS")), *link_args(flags), "-lm"]


def build_environment() -> tuple[str, ...]:
    """What reaches every compiler run of a build besides a kernel's own flags, one labelled
    part each (part of every cache key): the words of ``$CC`` (else Python's configured
    ``CC``), Python's ``CFLAGS`` and ``CCSHARED``, and ``$CPPFLAGS``, ``$CFLAGS`` and
    ``$LDFLAGS``.  Any of them can change a kernel's bits (``-m32``, ``-mfpmath=387``,
    ``-fexcess-precision=fast``, ...), so a kernel built under one environment is never
    served to another.  Last, the instruction-set flag this processor gets
    (:func:`~._isa.vector_flags`): a kernel built for one processor is never served to a
    processor without its instructions.  An unparsable variable counts by its words; raises
    only :class:`~._isa.VectorISAError` (``SYMGROUPOID_VECTOR_ISA`` invalid)."""
    config = sysconfig.get_config_var
    parts = {"CC": _compiler_text(), "PY_CFLAGS": config("CFLAGS"),
             "PY_CCSHARED": config("CCSHARED"), "CPPFLAGS": os.environ.get("CPPFLAGS"),
             "CFLAGS": os.environ.get("CFLAGS"), "LDFLAGS": os.environ.get("LDFLAGS")}
    isa = added_vector_flags(())
    return (*(f"{name}={json.dumps(_words(value))}" for name, value in parts.items()),
            f"VECTOR_ISA={json.dumps(list(isa))}")


def build_command(source: str, library: str, flags: Sequence[str]) -> list[str]:
    """The one compiler run that compiles ``source`` and links it into the shared library
    ``library`` (:func:`compiler_flags_of`, then :func:`link_tail`)."""
    return [*compiler_flags_of(flags), "-shared", source, "-o", library, *link_tail(flags)]
