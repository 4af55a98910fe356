"""Kernels built into the cache and loaded from it: one build per source key (under its lock,
in a private directory, published by a rename), loaded once per process, rebuilt once when
an entry does not load."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
from pathlib import Path

from ..._errors import CacheError
from ...codegen import KernelSource
from ._atomic import write_json_atomic
from ._cffi_build import build_extension, module_name
from ._compiler import NUMPY_HINT, CompilationError, compile_args, find_compiler
from ._digests import abi_tag, file_sha256, table_sha256
from ._kernel_cache import KernelCache
from ._library import load_extension
from ._roots import MANIFEST
from ._step_kernel import input_key, source_key_of, step_kernel

_LOADED: dict[str, object] = {}


#: source key → (kernel, flags, label) of every kernel this process asked to build (lets an
#: entry that fails to load be rebuilt)
_RECIPES: dict[str, tuple[KernelSource, tuple[str, ...], str]] = {}


#: what this process did: C generations, compiler runs, extension loads (cache diagnostics)
STATS = {"codegen": 0, "builds": 0, "loads": 0}


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


def build_step(step, flags: tuple[str, ...], cache: KernelCache, key: str, *,
               discard: dict | None = None, kernel: KernelSource | None = None,
               block_units: bool = True) -> tuple[str, dict]:
    """Build ``step``'s kernel (``kernel``, else its :func:`step_kernel`) into the cache
    (:func:`build_cached`) and record its source key under the input key ``key``."""
    if kernel is None:
        kernel = step_kernel(step, cache, flags, block_units)
        STATS["codegen"] += 1
    source_key, manifest = build_cached(kernel, flags, cache, step.name, discard=discard)
    with _writing(cache, step.name):
        cache.record(key, source_key, manifest["prefix"])
    return source_key, manifest


def load_step(step, flags: tuple[str, ...], cache: KernelCache, *,
              source: KernelSource | None = None, block_units: bool = True
              ) -> tuple[object, dict, str]:
    """(the loaded library, its manifest, its source key) of ``step`` built at ``flags``:
    from the cache by the step's input key, built there on a miss (from ``source``, the
    step's :func:`step_kernel` when already generated).  An entry that does not load is
    rebuilt once (:func:`load_cached`); :class:`CacheError` when it still does not."""
    key = input_key(step, flags, block_units)
    source_key = cache.lookup(key)
    manifest = cache.verified_manifest(source_key) if source_key else None
    if manifest is None:
        source_key, manifest = build_step(step, flags, cache, key, kernel=source,
                                          block_units=block_units)
    try:
        module = load_cached(source_key, manifest, cache)
    except CacheError as error:
        if source_key in _RECIPES:  # built here: load_cached has already rebuilt it once
            raise
        source_key, manifest = build_step(step, flags, cache, key, discard=manifest,
                                          block_units=block_units)
        try:
            module = _load_entry(source_key, manifest, cache)
        except CacheError as again:
            raise _unloadable(again, cache.entry(source_key)) from error
        _LOADED[source_key] = module
    return module, manifest, source_key


def rebuild_step(step, flags: tuple[str, ...], cache: KernelCache, *,
                 source: KernelSource | None = None, block_units: bool = True
                 ) -> tuple[object, dict, str]:
    """:func:`load_step` without the index: ``step``'s kernel built (or found by its source
    key) and recorded under its input key again, for an index entry that named a kernel
    whose sizes or entry points are not the step's (an index file edited by hand, or
    written by a defective version)."""
    key = input_key(step, flags, block_units)
    source_key, manifest = build_step(step, flags, cache, key, kernel=source,
                                      block_units=block_units)
    return load_cached(source_key, manifest, cache), manifest, source_key


def kernel_source_of(kernel, step) -> KernelSource:
    """The generated C of a loaded kernel (a ``CKernel``: its ``source_key``, ``flags`` and
    ``block_units``): from this process's builds, else generated again from ``step``
    (checked to hash to the kernel's source key)."""
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
