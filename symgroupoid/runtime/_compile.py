"""compile_step: a step's C kernel, built as a shared library loaded with cffi and cached on
disk, or the NumPy backend."""

from __future__ import annotations

import contextlib
import ctypes
import errno
import functools
import os
import shutil
import subprocess
import tempfile
import threading
import warnings
from collections.abc import Sequence
from pathlib import Path

import sympy as sp

from .._arguments import (
    choice_argument,
    instance_argument,
    name_argument,
    path_argument,
    sequence_argument,
)
from .._collector import collector_paused
from .._errors import CacheError, InputTypeError
from .._progress import reported
from ..codegen import generate_c, templates_digest
from ..codegen._emit import KernelSource
from ._backends import NumpyKernel
from ._build import (
    NUMPY_HINT,
    CompilationError,
    CompilerNotFoundError,
    block_weight,
    build_environment,
    build_extension,
    compile_args,
    compiler_command,
    find_compiler,
    load_extension,
    module_name,
    optimisation_flags,
    translation_units,
)
from ._cache import (
    MANIFEST,
    KernelCache,
    abi_tag,
    absolute_root,
    dir_mode,
    file_sha256,
    prepared,
    read_json,
    sha256_of,
    table_sha256,
    write_json_atomic,
)
from ._ckernel import CKernel
from ._options import NewtonOptions
from ._simulator import Simulator

BACKENDS = ("auto", "c", "numpy")
_LOADED: dict[str, object] = {}
#: source key → (kernel, flags, label) of every kernel this process asked to build (lets an
#: entry that fails to load be rebuilt)
_RECIPES: dict[str, tuple[KernelSource, tuple[str, ...], str]] = {}
#: what this process did: C generations, compiler runs, extension loads (cache diagnostics)
STATS = {"codegen": 0, "builds": 0, "loads": 0}


def codegen_sources() -> list[Path]:
    """The package sources that decide a kernel's C and how it is built: the code generator,
    the expression graph, this module (:func:`step_kernel`'s options) and
    ``runtime/_build.py`` (the translation units; the per-unit flags, e.g. the cold unit's
    level, are not all part of a cache key's flags)."""
    package = Path(__file__).resolve().parents[1]
    return sorted([*(package / "codegen").glob("*.py"), *(package / "ir").glob("*.py"),
                   package / "runtime" / "_build.py", Path(__file__).resolve()])


@functools.cache
def codegen_digest() -> str:
    """Hash of everything that turns a step into a built kernel: templates and
    :func:`codegen_sources`."""
    from .._version import __version__

    return sha256_of([__version__, templates_digest(),
                      *(f.read_bytes() for f in codegen_sources())])


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


@functools.cache
def _openmp_probe(command: tuple[str, ...]) -> bool:
    """Whether ``command -fopenmp`` builds a shared object that loads (OpenMP runtime found)."""
    with tempfile.TemporaryDirectory(prefix="symgroupoid-openmp-") as tmp:
        source, library = Path(tmp) / "probe.c", Path(tmp) / "probe.so"
        source.write_text(_OPENMP_PROBE, encoding="ascii")
        try:
            result = subprocess.run(
                [*command, OPENMP_FLAG, "-shared", "-fPIC", str(source), "-o", str(library)],
                stdin=subprocess.DEVNULL, capture_output=True, timeout=120)
            if result.returncode != 0 or not library.is_file():
                return False
            return ctypes.CDLL(str(library)).symgroupoid_openmp_probe() > 0
        except (OSError, subprocess.SubprocessError):
            return False


_OPENMP: dict[str, bool] = {}
#: probes running in a background thread (compiler key → the thread's result holder)
_PENDING: dict[str, tuple[threading.Thread, list]] = {}


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
    warm start compiles nothing.  ``SYMGROUPOID_OPENMP=0`` turns OpenMP off."""
    identity = _probe_identity()
    if identity is None:
        return False
    command, key = identity
    if key in _OPENMP:
        return _OPENMP[key]
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    name = f"openmp-{key}.json"
    known = _cached_probe(cache, name)
    if known is not None:
        _OPENMP[key] = known
        return known
    pending = _PENDING.pop(key, None)
    if pending is not None:  # started by start_openmp_probe: wait for its answer
        pending[0].join()
        result = pending[1][0] if pending[1] else False
    else:
        result = _openmp_probe(command)
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
    if key in _OPENMP or key in _PENDING:
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


def step_operations(step) -> int:
    """The operations of a step's hot code, which decide its optimisation level: the
    program's outputs but the residual's scale (``F_scale``, evaluated only when a rounding
    floor is tested, and compiled in the cold unit)."""
    program = step.program
    return program.size([name for name in program.outputs if name != "F_scale"])


def _step_flags(step, cache_dir) -> tuple[str, ...]:
    """:func:`default_flags`; without a compiler, the default build of ``step`` that is in
    the cache (with OpenMP or without), which needs no compiler to load."""
    base = optimisation_flags(step_operations(step), step=True)
    if _compiler_identity() is not None:
        return default_flags(cache_dir, step_operations(step), step=True)
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    for flags in ((*base, OPENMP_FLAG), tuple(base)):
        source_key = cache.lookup(input_key(step, flags))
        if source_key and cache.verified_manifest(source_key) is not None:
            return flags
    return tuple(base)


def _atom_token(node, symbols: dict) -> str:
    if isinstance(node, sp.Symbol):
        if node not in symbols:
            assumptions = sorted((k, v) for k, v in node.assumptions0.items())
            extra = f":{node.dummy_index}" if isinstance(node, sp.Dummy) else ""
            symbols[node] = f"{type(node).__name__}:{node.name}{extra}:{assumptions}"
        return symbols[node]
    if isinstance(node, sp.Float):
        return f"Float:{node._mpf_}:{node._prec}"
    if isinstance(node, sp.Rational):
        return f"Rational:{node.p}/{node.q}"
    return sp.srepr(node)


def fingerprint(exprs, symbols: dict | None = None) -> str:
    """An exact, injective text of expressions: their trees in preorder (type and arity of
    every node, exact atoms).  SymPy keeps ``Add``/``Mul`` arguments in canonical order, so
    equal expressions give equal text in every process; it is much cheaper than ``srepr``.
    """
    symbols = {} if symbols is None else symbols
    out: list[str] = []
    stack = list(reversed([sp.sympify(e) for e in exprs]))
    while stack:
        node = stack.pop()
        if node.args:
            out.append(f"({type(node).__name__}/{len(node.args)}")
            stack.extend(reversed(node.args))
        else:
            out.append(_atom_token(node, symbols))
    return " ".join(out)


def input_key(step, flags: Sequence[str], block_units: bool = True) -> str:
    """Cache key of the step (cheap: the exact text of its program, no C generation) built
    at ``flags`` in this build environment (:func:`~._build.build_environment`), with block
    units or without (:func:`step_kernel`)."""
    symbols: dict = {}
    parts = [step.name, str(step.n_constraints), step.program.fingerprint()]
    for seq in (step.unknowns, step.knowns, step.parameters):
        parts.append(fingerprint(list(seq), symbols))
    units = "block units" if block_units else "no block units"
    return sha256_of([*parts, codegen_digest(), abi_tag(), units, *build_environment(),
                      "flags", *flags])[:32]


def step_kernel(step, cache: KernelCache | None = None, flags: Sequence[str] | None = None,
                block_units: bool = True) -> KernelSource:
    """The C that :func:`compile_step` builds for ``step`` at ``flags`` (default: the
    step's :func:`~._build.optimisation_flags`): :func:`generate_c` without the residuals'
    LaTeX in its opening comment (which needs the SymPy residuals; a compiled kernel never
    shows it, and :func:`emit_c` writes it); a large kernel's functions in
    :func:`~._build.translation_units` files compiled at the same time; with
    ``block_units`` (a build at the library's default flags), the units of straight-line
    arithmetic are block units (``KernelSource.blocks``), balanced for their level
    (:func:`~._build.block_weight`).  The templates' compiled code (Python) comes from the
    package (``templates/__pycache__``, ``symgroupoid cache templates``), never from the
    kernel cache (which holds no Python): where the package has none, the templates are
    compiled in this process (0.045 s, once); ``cache`` is not used."""
    del cache
    if flags is None:
        flags = optimisation_flags(step_operations(step), step=True)
    return generate_c(step, latex=False, units=translation_units(),
                      block_weight=block_weight(flags) if block_units else None)


def source_key_of(kernel: KernelSource, flags: Sequence[str]) -> str:
    """Cache key of a generated kernel: its header, source, further translation units (and
    which are cold and which block units) and cdef, the ABI, the build environment
    (:func:`~._build.build_environment`: ``$CC``, ``$CPPFLAGS``, ``$CFLAGS``,
    ``$LDFLAGS``) and the flags."""
    units = [part for unit in kernel.units for part in unit]
    return sha256_of([kernel.header, kernel.source, str(len(units)), *units,
                      str(len(kernel.cold)), *kernel.cold, str(len(kernel.blocks)),
                      *kernel.blocks, kernel.cdef, abi_tag(), *build_environment(),
                      "flags", *flags])[:32]


def _same_entry(manifest: dict, stale: dict | None) -> bool:
    return stale is not None and manifest.get("sha256") == stale.get("sha256")


def build_cached(kernel: KernelSource, flags: tuple[str, ...], cache: KernelCache,
                 label: str, *, discard: dict | None = None) -> tuple[str, dict]:
    """Build ``kernel`` into the cache unless a verified entry exists; (source key, manifest).

    The entry is keyed by a hash of the generated source and flags.  On a miss the key's
    lock is taken (other processes missing the same kernel wait, then find it built); the
    build happens in a temporary directory renamed into place, and a damaged entry is
    rebuilt.  ``discard``: the manifest of an entry that verified but failed to load; it is
    removed and rebuilt unless another process has replaced it meanwhile.
    """
    flags = tuple(flags)
    source_key = source_key_of(kernel, flags)
    _RECIPES[source_key] = (kernel, flags, label)
    stale = discard if discard and discard.get("source_key") == source_key else None
    manifest = cache.verified_manifest(source_key)
    if manifest is None or _same_entry(manifest, stale):
        find_compiler()
        with _writing(cache, label), cache.build_lock(source_key, label):
            manifest = cache.verified_manifest(source_key)  # built while this one waited?
            if manifest is None or _same_entry(manifest, stale):
                manifest = _build_entry(kernel, flags, cache, label, source_key,
                                        stale.get("sha256") if stale else None)
    return source_key, manifest


#: what the C compiler says when it cannot write its output (a full disk)
_DISK_FULL = (os.strerror(errno.ENOSPC), "No space left on device", "Disk quota exceeded")
#: the errors of a write to a full disk or beyond a quota
_FULL = frozenset({errno.ENOSPC, getattr(errno, "EDQUOT", errno.ENOSPC)})


@contextlib.contextmanager
def _writing(cache: KernelCache, label: str):
    """Writing into the kernel cache: an ``OSError`` (a full disk, an I/O error) or a
    compiler that could not write its output becomes a :class:`CacheError` naming the
    cache directory and what to do."""
    try:
        yield
    except CompilationError as exc:
        if not any(text in exc.output for text in _DISK_FULL):
            raise
        raise CacheError(f"{label}: the kernel cache {cache.written_root()} has no space "
                         f"left for the kernel (the C compiler could not write its output); "
                         f"free space there, or set SYMGROUPOID_CACHE to a directory on "
                         f"another file system") from exc
    except OSError as exc:
        where = f" ({exc.filename})" if exc.filename else ""
        if exc.errno in _FULL:
            what = f"has no space left for the kernel{where}: {exc.strerror}"
            fix = "free space there, or set SYMGROUPOID_CACHE to a directory on another file "
            fix += "system"
        else:
            what = f"cannot be written{where}: {exc.strerror or exc}"
            fix = "check it, or set SYMGROUPOID_CACHE to another directory"
        raise CacheError(f"{label}: the kernel cache {cache.written_root()} {what}; {fix}"
                         ) from exc


def _build_entry(kernel: KernelSource, flags: tuple[str, ...], cache: KernelCache, label: str,
                 source_key: str, stale: str | None = None) -> dict:
    """Compile into a fresh build directory of this process and publish it (by one
    ``rename``, :meth:`KernelCache.install`: an entry another process published meanwhile
    is kept, unless its library's SHA-256 is ``stale``)."""
    build_dir = cache.new_build_dir(source_key)
    try:
        name = module_name(source_key)
        STATS["builds"] += 1
        library, table = build_extension(kernel, build_dir, name, flags)
        write_json_atomic(build_dir / MANIFEST, {
            "source_key": source_key, "module": name, "library": library.name,
            "sha256": file_sha256(library), "prefix": kernel.prefix,
            "types": table, "types_sha256": table_sha256(table),
            "flags": list(flags), "compile_args": compile_args(flags), "abi": abi_tag(),
            "system": label})
    except BaseException:
        shutil.rmtree(build_dir, ignore_errors=True)
        raise
    entry = cache.install(build_dir, source_key, stale)
    manifest = cache.verified_manifest(source_key)
    if manifest is None or cache.entry(source_key) != entry:
        raise CacheError(f"{label}: the kernel cache entry {entry} could not be installed "
                         f"(something is in its way); remove it, or set SYMGROUPOID_CACHE to "
                         f"another directory")
    return manifest


def _load_entry(source_key: str, manifest: dict, cache: KernelCache):
    path = cache.entry(source_key) / str(manifest.get("library", ""))
    try:
        module = load_extension(path, str(manifest.get("module", "")), manifest["types"])
    except (ImportError, OSError) as exc:
        raise CacheError(f"cannot load the cached kernel module {path}: {exc}") from exc
    STATS["loads"] += 1
    return module


def _unloadable(error: CacheError, entry: Path) -> CacheError:
    return CacheError(
        f"{error}\nIt was rebuilt and still cannot be loaded: the kernel cache {entry.parent} "
        f"may be on a file system that forbids executable code (noexec). Set "
        f"SYMGROUPOID_CACHE to another directory. {NUMPY_HINT}")


def load_cached(source_key: str, manifest: dict, cache: KernelCache):
    """The loaded library (``ffi``, ``lib``) of a verified cache entry (loaded once per
    process).

    An entry that verifies but does not load (its module file and manifest replaced
    consistently by something else) is rebuilt once if this process has passed the kernel
    to :func:`build_cached`; otherwise, or if it still fails, :class:`CacheError`.
    """
    module = _LOADED.get(source_key)
    if module is None:
        try:
            module = _load_entry(source_key, manifest, cache)
        except CacheError as error:
            recipe = _RECIPES.get(source_key)
            if recipe is None:
                raise
            kernel, flags, label = recipe
            _, manifest = build_cached(kernel, flags, cache, label, discard=manifest)
            try:
                module = _load_entry(source_key, manifest, cache)
            except CacheError as again:
                raise _unloadable(again, cache.entry(source_key)) from error
        _LOADED[source_key] = module
    return module


def _build(step, flags: tuple[str, ...], cache: KernelCache, key: str, *,
           discard: dict | None = None, kernel: KernelSource | None = None,
           block_units: bool = True) -> tuple[str, dict]:
    if kernel is None:
        kernel = step_kernel(step, cache, flags, block_units)
        STATS["codegen"] += 1
    source_key, manifest = build_cached(kernel, flags, cache, step.name, discard=discard)
    with _writing(cache, step.name):
        cache.record(key, source_key, manifest["prefix"])
    return source_key, manifest


def load_c_kernel(step, flags: Sequence[str] | None = None,
                  cache_dir: str | os.PathLike | None = None, *,
                  source: KernelSource | None = None,
                  block_units: bool | None = None) -> tuple[CKernel, Path]:
    """The compiled kernel of ``step`` from the cache, building it on a miss (from
    ``source``, the step's :func:`step_kernel` when already generated).

    ``block_units`` (default: whether ``flags`` is None, the library's default flags): the
    kernel's straight-line arithmetic in block units, compiled at a cheaper level
    (:func:`~._build.unit_flags`); without, every unit but the cold one is compiled at
    ``flags``.  Raises :class:`CompilerNotFoundError` when a build is needed and no
    compiler exists, :class:`CompilationError` when the compiler fails (the cache is left
    unchanged), :class:`CacheError` when the cache cannot serve the kernel (see
    :mod:`._cache`).
    """
    if block_units is None:
        block_units = flags is None
    flags = tuple(_step_flags(step, cache_dir) if flags is None else flags)
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    key = input_key(step, flags, block_units)
    source_key = cache.lookup(key)
    manifest = cache.verified_manifest(source_key) if source_key else None
    if manifest is None:
        source_key, manifest = _build(step, flags, cache, key, kernel=source,
                                      block_units=block_units)
    try:
        module = load_cached(source_key, manifest, cache)
    except CacheError as error:
        if source_key in _RECIPES:  # built here: load_cached has already rebuilt it once
            raise
        source_key, manifest = _build(step, flags, cache, key, discard=manifest,
                                      block_units=block_units)
        try:
            module = _load_entry(source_key, manifest, cache)
        except CacheError as again:
            raise _unloadable(again, cache.entry(source_key)) from error
        _LOADED[source_key] = module
    entry = cache.entry(source_key)
    kernel = CKernel(module, manifest["prefix"], len(step.unknowns), len(step.knowns))
    kernel.source_key, kernel.flags, kernel.block_units = source_key, flags, block_units
    return kernel, entry


def compiler_flags(flags, owner: str = "") -> tuple[str, ...] | None:
    """``flags`` as a tuple of compiler arguments, or None (the step's
    :func:`default_flags`, chosen when it is built): a list of strings without NUL
    characters.  A single string is refused: it would be taken letter by letter (``"-O2"``
    as ``"-"``, ``"O"``, ``"2"``); pass ``["-O2"]``."""
    if flags is None:
        return None
    if isinstance(flags, str):
        raise InputTypeError(f"{owner}: flags must be a list of compiler arguments, got the "
                             f"string {flags!r}; pass [{flags!r}]")
    items = sequence_argument(flags, "flags", owner=owner)
    return tuple(name_argument(f, f"flags[{i}]", owner=owner) for i, f in enumerate(items))


def kernel_source_of(kernel: CKernel, step) -> KernelSource:
    """The generated C of a loaded kernel: from this process's builds, else generated again
    from ``step`` (checked to hash to the kernel's source key)."""
    recipe = _RECIPES.get(kernel.source_key)
    if recipe is not None:
        return recipe[0]
    source = step_kernel(step, flags=kernel.flags,
                         block_units=getattr(kernel, "block_units", True))
    STATS["codegen"] += 1
    if source_key_of(source, kernel.flags) != kernel.source_key:
        raise CacheError(f"{step.name}: the kernel in the cache ({kernel.source_key}) is not "
                         f"the C this step generates now; compile the step again")
    _RECIPES[kernel.source_key] = (source, tuple(kernel.flags), step.name)
    return source


def load_kernel_source(kernel: KernelSource, flags: Sequence[str], label: str,
                       n_unknowns: int, n_knowns: int,
                       cache_dir: str | os.PathLike | None = None) -> tuple[CKernel, Path]:
    """The compiled kernel of generated C ``kernel``: loaded from the cache by its source
    key (a hash of the C, the flags and the ABI), built there on a miss (see
    :func:`build_cached`).  What a process that never saw the step needs to run it."""
    flags = tuple(flags)
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    source_key, manifest = build_cached(kernel, flags, cache, label)
    module = load_cached(source_key, manifest, cache)
    loaded = CKernel(module, manifest["prefix"], n_unknowns, n_knowns)
    loaded.source_key, loaded.flags = source_key, flags
    loaded.block_units = bool(kernel.blocks)
    return loaded, cache.entry(source_key)


@reported(lambda step, **options: f"{step.name}: building the kernel")
@collector_paused
def compile_step(step, *, backend: str = "auto", flags: Sequence[str] | None = None,
                 cache_dir: str | os.PathLike | None = None, tol_residual: float | None = None,
                 tol_step: float | None = None, max_iterations: int | None = None,
                 floor_factor: float | None = None,
                 trust_factor: float | None = None) -> Simulator:
    """A :class:`Simulator` for ``step``: its C kernel (cffi, cached) or the NumPy backend.

    Every argument is checked before anything is built, whichever backend is used
    (:class:`~symgroupoid.DomainError` for a backend that is not one of ``BACKENDS``,
    :class:`~symgroupoid.InputTypeError` or :class:`~symgroupoid.ShapeError` for malformed
    flags or paths).

    Parameters
    ----------
    backend : ``"auto"`` (C if a compiler is available, else NumPy with a warning), ``"c"``
        or ``"numpy"``.  The environment variable ``SYMGROUPOID_BACKEND`` overrides
        ``"auto"``.
    flags : compiler flags, a list of strings (default :func:`default_flags`:
        ``DEFAULT_FLAGS``, at -O2 above ``LARGE_PROGRAM`` operations and at -O1 up to
        ``SMALL_STEP``, which compile in half to three quarters of the time and step at
        most 13 % slower, above it without SLP vectorisation (``LARGE_STEP_FLAGS``), plus
        ``-fopenmp`` when the compiler supports it; the straight-line
        functions of a kernel that calls no library function at -Og,
        ``runtime._build.BLOCK_LEVEL``); part of the cache key.  Explicit ``flags`` apply to
        every unit but the cold one.  Builds carry no debug information unless ``flags``
        ask for it (``-g``).
    cache_dir : cache root, a path (default ``$SYMGROUPOID_CACHE``,
        ``$XDG_CACHE_HOME/symgroupoid`` or ``~/.cache/symgroupoid``); a relative path is
        taken relative to the working directory of this call.  If it cannot be written,
        kernels are built in a private temporary directory for this process (with a
        ``RuntimeWarning``).
    tol_residual, tol_step, max_iterations, floor_factor, trust_factor : Newton options (see
        :class:`NewtonOptions`).
    progress : report code generation and compilation taking longer than 2 s (see
        :mod:`symgroupoid._progress`; a cached kernel loads in milliseconds).
    """
    from ..equations import StepEquations

    instance_argument(step, StepEquations, "step", "the StepEquations of a system (from "
                      "system.euler_lagrange())", owner="compile_step")
    owner = step.name
    backend = choice_argument(backend, BACKENDS, "backend", owner=owner)
    if backend == "auto":
        backend = os.environ.get("SYMGROUPOID_BACKEND", "auto") or "auto"
        choice_argument(backend, BACKENDS, "SYMGROUPOID_BACKEND", owner=owner)
    flags = compiler_flags(flags, owner)
    if cache_dir is not None:  # resolved now: a later chdir cannot move the cache
        cache_dir = absolute_root(path_argument(cache_dir, "cache_dir", owner=owner))
    given = {"tol_residual": tol_residual, "tol_step": tol_step,
             "max_iterations": max_iterations, "floor_factor": floor_factor,
             "trust_factor": trust_factor}
    options = NewtonOptions(**{k: v for k, v in given.items() if v is not None})
    if backend == "numpy":
        return Simulator(step, NumpyKernel(step), options)
    try:
        source = None
        if flags is None and start_openmp_probe(cache_dir):
            # a first build here (the compiler's OpenMP support is not known yet): the C is
            # generated while the probe runs, instead of after it
            source = step_kernel(step, KernelCache(
                Path(cache_dir) if cache_dir is not None else None))
            STATS["codegen"] += 1
        chosen = _step_flags(step, cache_dir) if flags is None else flags
        kernel, entry = load_c_kernel(step, chosen, cache_dir, source=source,
                                      block_units=flags is None)
    except CompilerNotFoundError as exc:
        if backend == "c":
            raise
        warnings.warn(f"{step.name}: {exc}; using the NumPy backend (same results, slower)",
                      RuntimeWarning, stacklevel=2)
        return Simulator(step, NumpyKernel(step), options)
    return Simulator(step, kernel, options, cache_entry=entry)
