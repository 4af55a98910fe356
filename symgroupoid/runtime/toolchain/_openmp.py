"""Whether kernels are built with OpenMP (probed once per compiler, kept in the cache), and
the default flags of a kernel."""

from __future__ import annotations

import contextlib
import ctypes
import os
import subprocess
import tempfile
import threading
from pathlib import Path

from ._atomic import read_json, write_json_atomic
from ._compiler import (
    CompilerNotFoundError,
    compiler_command,
    compiler_environment,
    find_compiler,
)
from ._digests import abi_tag, sha256_of
from ._flags import optimisation_flags
from ._kernel_cache import KernelCache
from ._library import library_defect
from ._processes import scratch_prefix, sweep_scratch
from ._trust import dir_mode
from ._writable import prepared

#: the flag that compiles (and links) a kernel's batched entry point with OpenMP threads
OPENMP_FLAG = "-fopenmp"


_OPENMP_PROBE = """#include <omp.h>
int symgroupoid_openmp_probe(void)
{
    int n = 0;
#pragma omp parallel reduction(+ : n)
    n += 1;
    return n > 0 ? omp_get_max_threads() : 0;
}
"""


def _openmp_probe(command: tuple[str, ...]) -> bool | None:
    """Whether ``command -fopenmp`` builds a shared object that loads (OpenMP runtime found);
    None when the probe could not tell: the compiler was killed (Ctrl-C reaches it too) or
    timed out, its output is not a complete shared object (checked before it is mapped, as
    a kernel is: a truncated file would kill the process with SIGBUS), or the object does not
    load for another reason than the OpenMP runtime (a temporary directory mounted noexec).
    Only a definite answer is kept (:func:`openmp_available`)."""
    sweep_scratch("openmp")
    with tempfile.TemporaryDirectory(prefix=scratch_prefix("openmp")) as tmp:
        source, library = Path(tmp) / "probe.c", Path(tmp) / "probe.so"
        source.write_text(_OPENMP_PROBE, encoding="ascii")
        try:
            result = subprocess.run(
                [*command, OPENMP_FLAG, "-shared", "-fPIC", str(source), "-o", str(library)],
                stdin=subprocess.DEVNULL, capture_output=True, timeout=120,
                env=compiler_environment(Path(tmp)))
        except (OSError, subprocess.SubprocessError):
            return None
        if result.returncode < 0:  # killed by a signal: no answer
            return None
        if result.returncode != 0 or not library.is_file():
            return False
        try:
            if library_defect(library.read_bytes()) is not None:
                return None
            return ctypes.CDLL(str(library)).symgroupoid_openmp_probe() > 0
        except OSError as exc:
            return False if "omp" in str(exc).lower() else None


_OPENMP: dict[str, bool] = {}


#: probes running in a background thread (compiler key → the thread's result holder)
_PENDING: dict[str, tuple[threading.Thread, list]] = {}

#: probes that could not tell, per compiler key, in this process: after
#: :data:`UNDETERMINED_TRIES` of them the process builds without OpenMP and probes no more
#: (an environment where the probe never loads, e.g. a noexec ``$TMPDIR``, paid for a
#: probe at every build); nothing is recorded in the cache
_UNDETERMINED: dict[str, int] = {}
UNDETERMINED_TRIES = 2


def _compiler_identity() -> tuple[tuple[str, ...], str] | None:
    """(compiler command, a key naming that compiler binary as installed), or None."""
    try:
        command = tuple(compiler_command())
        path = Path(find_compiler())
        stat = path.stat()
    except (CompilerNotFoundError, OSError):
        return None
    key = sha256_of([*command, str(path.resolve()), str(stat.st_mtime_ns), str(stat.st_size),
                     abi_tag()])[:32]
    return command, key


def _probe_identity() -> tuple[tuple[str, ...], str] | None:
    """:func:`_compiler_identity`, or None when ``SYMGROUPOID_OPENMP=0`` (never probe)."""
    if os.environ.get("SYMGROUPOID_OPENMP", "1").strip() == "0":
        return None
    return _compiler_identity()


def openmp_available(cache_dir: str | os.PathLike | None = None) -> bool:
    """Whether kernels are built with OpenMP: the C compiler accepts ``-fopenmp`` and its
    runtime loads.  Probed once per compiler: the answer is kept in this process and in the
    cache (``probes/openmp-<compiler key>.json``, when the cache is writable), so a
    warm start compiles nothing.  A probe that cannot tell (killed, or its library does not
    load for another reason) is not kept: the build goes without OpenMP and the next one
    probes again, up to :data:`UNDETERMINED_TRIES` times in a process.
    ``SYMGROUPOID_OPENMP=0`` turns OpenMP off."""
    identity = _probe_identity()
    if identity is None:
        return False
    command, key = identity
    if key in _OPENMP:
        return _OPENMP[key]
    if _UNDETERMINED.get(key, 0) >= UNDETERMINED_TRIES:
        return False
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    name = f"openmp-{key}.json"
    known = _cached_probe(cache, name)
    if known is not None:
        _OPENMP[key] = known
        return known
    pending = _PENDING.pop(key, None)
    if pending is not None:  # started by start_openmp_probe: wait for its answer
        pending[0].join()
        result = pending[1][0] if pending[1] else None
    else:
        result = _openmp_probe(command)
    if result is None:  # no answer this time: built without OpenMP, probed again next time
        _UNDETERMINED[key] = _UNDETERMINED.get(key, 0) + 1
        return False
    _OPENMP[key] = result
    probes = cache.root / "probes"
    # kept only in a writable kernel cache (never in a foreign or read-only directory)
    with contextlib.suppress(OSError):
        if prepared(cache.root):
            probes.mkdir(mode=dir_mode(), exist_ok=True)
            write_json_atomic(probes / name, {"openmp": result, "compiler": list(command)})
    return result


def _cached_probe(cache: KernelCache, name: str) -> bool | None:
    """The OpenMP answer kept in the cache (``probes/<name>``), or None."""
    for root, owners in cache.trusted_roots():
        data = read_json(root / "probes" / name, owners)
        if data is not None and isinstance(data.get("openmp"), bool):
            return data["openmp"]
    return None


def start_openmp_probe(cache_dir: str | os.PathLike | None = None) -> bool:
    """Start the OpenMP probe of :func:`openmp_available` in a background thread when its
    answer is not known yet (neither in this process nor in the cache), so that it runs
    while the kernel's C is generated; True if a probe was started.  The answer is
    collected (and kept) by the next :func:`openmp_available`."""
    identity = _probe_identity()
    if identity is None:
        return False
    command, key = identity
    if key in _OPENMP or key in _PENDING or _UNDETERMINED.get(key, 0) >= UNDETERMINED_TRIES:
        return False
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    if _cached_probe(cache, f"openmp-{key}.json") is not None:
        return False
    holder: list = []
    thread = threading.Thread(target=lambda: holder.append(_openmp_probe(command)),
                              name="symgroupoid-openmp-probe", daemon=True)
    thread.start()
    _PENDING[key] = (thread, holder)
    return True


def default_flags(cache_dir: str | os.PathLike | None = None,
                  operations: int = 0, *, step: bool = False) -> tuple[str, ...]:
    """The compiler flags of a kernel of ``operations`` operations built without explicit
    ``flags``: :func:`optimisation_flags` (``DEFAULT_FLAGS``, at -O2 for large programs, at
    -O1 for a small Newton step's kernel when ``step``), and
    ``-fopenmp`` when :func:`openmp_available` (the batched entry point
    ``<prefix>_simulate_batch`` then shares trajectories among threads; nothing else in the
    kernel changes).  Flags are part of the cache key, so both builds can be cached side by
    side."""
    flags = optimisation_flags(operations, step=step)
    if openmp_available(cache_dir):
        return (*flags, OPENMP_FLAG)
    return tuple(flags)
