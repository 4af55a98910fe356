"""Building a kernel into a Python extension with cffi (API mode, out of line)."""

from __future__ import annotations

import contextlib
import importlib.util
import os
import shlex
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import ModuleType

from .._errors import SymgroupoidError
from ..codegen import KernelSource

#: flags appended to the compiler command line (after Python's own CFLAGS, so they decide the
#: optimisation level).  -ffp-contract=off keeps a*b+c as two roundings, as in the NumPy backend.
DEFAULT_FLAGS: tuple[str, ...] = ("-O3", "-ffp-contract=off")
#: a program of more operations than this is compiled at -O2 instead of -O3: as fast to run
#: (measured: the planar 32-link chain's step, 3.16e5 against 3.10e5 instructions), and
#: compiled faster (the 64-link chain's 1 MB kernel: 21.9 s against 25.6 s of CPU)
LARGE_PROGRAM = 15_000


def optimisation_flags(operations: int) -> tuple[str, ...]:
    """The compiler flags of a kernel of ``operations`` operations (deterministic)."""
    if operations > LARGE_PROGRAM:
        return ("-O2",) + DEFAULT_FLAGS[1:]
    return DEFAULT_FLAGS

#: how to do without a compiler (appended to every compiler error)
NUMPY_HINT = ('To use the NumPy backend instead (same results, slower), pass backend="numpy" '
              '(compile_step, DiscreteSystem.compile) or set SYMGROUPOID_BACKEND=numpy.')


#: one build at a time per process: cffi changes the working directory and the build
#: captures file descriptors 1 and 2, both process-wide
_BUILD_LOCK = threading.Lock()


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


@contextlib.contextmanager
def captured_output() -> Iterator[list[str]]:
    """Capture everything written to file descriptors 1 and 2 (compiler subprocesses too).

    The captured text is appended to the yielded list when the block exits.
    """
    holder: list[str] = []
    with tempfile.TemporaryFile() as tmp:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            yield holder
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            holder.append(tmp.read().decode("utf-8", errors="replace"))


def module_name(source_key: str) -> str:
    return f"_sgk_{source_key[:24]}"


def compile_args(flags: Sequence[str]) -> list[str]:
    """The extra compiler arguments of a build: ``flags``, after ``-g0`` unless they ask
    for debug information themselves (``-g``, ``-ggdb``, ...).

    Python's own CFLAGS (which cffi passes first) usually contain ``-g``; debug information
    more than doubles the module size and slows the build; it changes no generated code.
    """
    flags = list(flags)
    return flags if any(f.startswith("-g") for f in flags) else ["-g0", *flags]


def link_args(flags: Sequence[str]) -> list[str]:
    """The extra linker arguments of a build: ``-fopenmp`` when the kernel is compiled with
    it (the OpenMP runtime must be linked into the module too)."""
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


def _failure(kernel: KernelSource, failure: Exception, output: str) -> CompilationError:
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


def build_extension(kernel: KernelSource, build_dir: Path, name: str,
                    flags: Sequence[str]) -> Path:
    """Compile ``kernel`` into ``build_dir`` as extension module ``name``; return its path.

    The generated ``<prefix>.c`` is included into cffi's wrapper translation unit, so the
    kernel and its Python bindings are one object.  Compiler output is captured and shown
    in :class:`CompilationError` on failure; intermediate files are removed on success.
    """
    import cffi

    (build_dir / kernel.header_name).write_text(kernel.header, encoding="ascii")
    (build_dir / f"{kernel.prefix}.c").write_text(kernel.source, encoding="ascii")
    ffi = cffi.FFI()
    ffi.cdef(kernel.cdef)
    ffi.set_source(name, f'#include "{kernel.prefix}.c"\n', include_dirs=[str(build_dir)],
                   extra_compile_args=compile_args(flags), extra_link_args=link_args(flags))
    with _BUILD_LOCK, captured_output() as out:
        try:
            library = Path(ffi.compile(tmpdir=str(build_dir), verbose=False))
        except Exception as exc:  # noqa: BLE001 - cffi/setuptools raise various types
            failure = exc
        else:
            failure = None
    if failure is not None:
        raise _failure(kernel, failure, out[0].strip() if out else "") from failure
    for path in build_dir.iterdir():
        if path.is_dir():
            shutil.rmtree(path)
        elif path.suffix in (".o", ".obj") or path.name == f"{name}.c":
            path.unlink()
    return library


def load_extension(path: Path, name: str) -> ModuleType:
    """Import an extension module from a file."""
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load the kernel module {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
