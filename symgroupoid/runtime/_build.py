"""Building a kernel into a Python extension with cffi (API mode, out of line)."""

from __future__ import annotations

import contextlib
import importlib.util
import os
import shlex
import shutil
import sys
import sysconfig
import tempfile
from collections.abc import Iterator, Sequence
from pathlib import Path
from types import ModuleType

from .._errors import SymgroupoidError
from ..codegen import KernelSource

#: flags appended to the compiler command line (after Python's own CFLAGS).
#: -ffp-contract=off keeps a*b+c as two roundings, as in the NumPy backend.
DEFAULT_FLAGS: tuple[str, ...] = ("-O3", "-ffp-contract=off")


class CompilationError(SymgroupoidError, RuntimeError):
    """The C compiler rejected a generated kernel; ``.output`` holds its messages."""

    def __init__(self, message: str, output: str = ""):
        super().__init__(message)
        self.output = output


class CompilerNotFoundError(SymgroupoidError, RuntimeError):
    """No C compiler could be found (``$CC`` or Python's configured compiler)."""


def find_compiler() -> str:
    """Path of the C compiler cffi will use: ``$CC``, else Python's configured ``CC``."""
    command = os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    try:
        exe = shlex.split(command)[0]
    except (ValueError, IndexError):
        raise CompilerNotFoundError(f"cannot parse the compiler command {command!r}") from None
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
                   extra_compile_args=list(flags))
    with captured_output() as out:
        try:
            library = Path(ffi.compile(tmpdir=str(build_dir), verbose=False))
        except Exception as exc:  # noqa: BLE001 - cffi/setuptools raise various types
            failure = exc
        else:
            failure = None
    if failure is not None:
        text = out[0].strip() if out else ""
        raise CompilationError(
            f"{kernel.prefix}: the C compiler failed ({failure}).\nCompiler output:\n{text}",
            output=text) from failure
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
