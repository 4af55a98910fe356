"""Building a kernel into a shared library: its files written, its translation units compiled
at the same time, linked, and checked."""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from ...codegen import KernelSource
from ._compiler import (
    NUMPY_HINT,
    CompilationError,
    _failure,
    build_command,
    compiler_command,
    compiler_environment,
    compiler_flags_of,
    link_tail,
)
from ._flags import unit_flags
from ._library import library_defect
from ._locks import seconds_setting
from ._trust import file_mode
from ._type_table import type_table


def module_name(source_key: str) -> str:
    return f"_sgk_{source_key[:24]}"


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
        _run(kernel, [build_command(sources[0][0], library.name, flags)], build_dir, flags,
             make_table)
    else:  # the units at the same time, then one link
        objects = [f"{Path(file_name).stem}.o" for file_name, _ in sources]
        _run(kernel, [[*compiler_flags_of(unit_flags(flags, _role(kernel, file_name))),
                       "-c", file_name, "-o", obj]
                      for (file_name, _), obj in zip(sources, objects)], build_dir, flags,
             make_table)
        _run(kernel, [[*compiler_flags_of(flags), "-shared", *objects, "-o", library.name,
                       *link_tail(flags)]], build_dir, flags)
        for obj in objects:
            (build_dir / obj).unlink(missing_ok=True)
    if not library.is_file() or library.is_symlink():
        raise _failure(kernel, "the compiler wrote no library", "", flags)
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
    if file_name in kernel.stepper:
        return "stepper"
    return "blocks" if file_name in kernel.blocks else "step"


#: compiler runs get process groups of their own (POSIX), killed whole on an interruption
_OWN_GROUPS = hasattr(os, "killpg")


@contextlib.contextmanager
def _interrupts_held():
    """A Ctrl-C (SIGINT) held back while the compiler runs are started, in the main thread:
    inside ``Popen`` — between the fork and the object that names the child — it would leave
    a compiler nobody can stop; held, it is raised right after, with every run in
    ``processes``.  (A handler, not a signal mask: the children would inherit a mask; a
    handler is reset by exec.)"""
    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGINT) is None:  # (a handler set outside Python)
        yield
        return
    caught: list = []
    previous = signal.signal(signal.SIGINT, lambda *received: caught.append(received))
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
    if caught and previous is not signal.SIG_IGN:
        if callable(previous):
            previous(*caught[0])  # the default handler raises KeyboardInterrupt
        raise KeyboardInterrupt


#: seconds a compiler run may take before it is stopped (``SYMGROUPOID_BUILD_TIMEOUT``): the
#: largest kernels the benchmarks build (chains of 64 bodies) compile in minutes; a compiler
#: that hangs would otherwise hold the build, and the lock every other process waits on
BUILD_TIMEOUT = 1800.0


def build_timeout() -> float:
    """Seconds a compiler run of a kernel build may take (``SYMGROUPOID_BUILD_TIMEOUT``)."""
    return seconds_setting("SYMGROUPOID_BUILD_TIMEOUT", BUILD_TIMEOUT)


def _parent_death_signal() -> Callable[[], None] | None:
    """On Linux, a function for the forked child that has the kernel kill it when the
    process that started it ends (``prctl(PR_SET_PDEATHSIG, SIGKILL)``): a compiler then
    never outlives a Python process stopped by SIGTERM or SIGKILL, which no handler sees.
    Prepared here, so that the child only makes one system call."""
    if not sys.platform.startswith("linux"):  # pragma: no cover - other systems
        return None
    try:
        prctl = ctypes.CDLL(ctypes.util.find_library("c") or None, use_errno=True).prctl
    except (OSError, AttributeError):  # pragma: no cover - no prctl in this C library
        return None
    prctl.argtypes = (ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong,
                      ctypes.c_ulong)
    prctl.restype = ctypes.c_int
    pr_set_pdeathsig, kill = 1, int(signal.SIGKILL)

    def set_signal() -> None:
        prctl(pr_set_pdeathsig, kill, 0, 0, 0)
    return set_signal


_CHILD_SETUP = _parent_death_signal()


def _child_setup() -> Callable[[], None] | None:
    """The pre-exec hook of a compiler run: the parent-death signal in the main thread
    only.  A hook makes Python fork (not vfork), and fork runs the process's fork
    handlers: OpenBLAS's stops its threads, so a build in a background thread (a
    boundary-value solve's kernels, built while NumPy solves) left the main thread waiting
    in OpenBLAS for minutes when its LAPACK call ran at that moment.  From another thread
    the compiler is started without one (and, like the OpenMP probe's, is not killed with
    a process stopped by SIGKILL)."""
    return _CHILD_SETUP if threading.current_thread() is threading.main_thread() else None


def _run(kernel: KernelSource, commands: list[list[str]], cwd: Path, flags: Sequence[str],
         meanwhile: Callable[[], None] | None = None) -> None:
    """Run compiler ``commands`` of a build at ``flags`` at the same time in ``cwd`` (and
    ``meanwhile()`` while they run); :class:`CompilationError` with the output of every
    failed one."""
    processes: list = []

    def stop() -> None:
        """Kill every compiler run with the processes it started (cc1, as): each runs in a
        process group of its own, so a Ctrl-C that reaches Python alone (a notebook's
        interrupt) leaves no compiler behind writing into the removed build directory."""
        for _, process in processes:
            with contextlib.suppress(OSError):
                if _OWN_GROUPS:
                    os.killpg(process.pid, signal.SIGKILL)
                else:  # pragma: no cover - no process groups
                    process.kill()
            process.communicate()

    environment = compiler_environment(cwd)
    limit = build_timeout()
    try:
        with _interrupts_held():
            for command in commands:
                processes.append((command, subprocess.Popen(
                    command, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                    stderr=subprocess.STDOUT, text=True, errors="replace", env=environment,
                    start_new_session=_OWN_GROUPS, preexec_fn=_child_setup())))
    except OSError as exc:
        stop()
        raise _failure(kernel, f"cannot run {commands[0][0]!r}: {exc}", str(exc),
                       flags) from exc
    except BaseException:  # (Ctrl-C between two starts)
        stop()
        raise
    failures = []
    deadline = time.monotonic() + limit
    try:
        if meanwhile is not None:
            meanwhile()
        for command, process in processes:
            output, _ = process.communicate(timeout=max(deadline - time.monotonic(), 0.0))
            if process.returncode != 0:
                failures.append((command, process.returncode, output.strip()))
    except subprocess.TimeoutExpired as exc:
        stop()
        raise CompilationError(
            f"{kernel.prefix}: the C compiler {exc.cmd[0]!r} did not finish within {limit:g} "
            f"s and was stopped; a kernel this large may need more time "
            f"(SYMGROUPOID_BUILD_TIMEOUT, in seconds), or the compiler hangs.\n{NUMPY_HINT}"
        ) from None
    except BaseException:
        stop()
        raise
    if failures:
        command, status, _ = failures[0]
        raise _failure(kernel, f"command {command[0]!r} failed with exit status {status}",
                       "\n".join(output for _, _, output in failures), flags)
