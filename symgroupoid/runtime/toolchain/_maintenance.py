"""Looking into and clearing the kernel cache (``symgroupoid cache info|clear``).

Clearing is safe while other processes use the cache: a kernel whose build lock is held (it
is being built or rebuilt right now) is left alone and reported; every other kernel
directory is removed the way the cache removes a damaged one (renamed away first, so no
process ever sees half a kernel), its index entries with it.  A process that has already
loaded a removed kernel keeps using it; the next one to ask for it builds it again.

Only what the cache itself names is removed (kernel directories named by a 32-hex key,
index files ``<key>.json``, the kernel templates' compiled code an older version kept in
``templates/``, and the leftovers :func:`~._sweep.sweep` removes), never through a link: a
cache whose directories are links, or belong to another user, is refused
(:class:`CacheError`).  ``bad_only``: only the entries that would not be loaded (damaged,
truncated, untrusted: ``CachedKernel.problem``).
"""

from __future__ import annotations

import contextlib
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..._errors import CacheError
from ._atomic import _remove, read_json, remove_tree
from ._entries import entry_defect
from ._locks import key_busy
from ._roots import (
    MANIFEST,
    MARKER,
    _holds_cache_evidence,
    absolute_root,
    cache_root,
    foreign_listing,
    is_cache_root,
)
from ._sweep import sweep
from ._trust import _untrusted_reason, trusted
from ._writable import _claim

_KEY = re.compile(r"[0-9a-f]{32}")
_INDEX = re.compile(r"[0-9a-f]{32}\.json")
_TEMPLATE = re.compile(r"__jinja2_[0-9a-f]{40}\.cache")


@dataclass
class CachedKernel:
    """One kernel directory: its source key, the system it was built for, bytes on disk,
    modification time, whether its manifest verifies (library present, hashes matching,
    a complete ELF library, trusted), and if not, why (``problem``)."""

    key: str
    system: str
    size: int
    modified: float
    complete: bool
    problem: str | None = None


@dataclass
class CacheInfo:
    root: Path
    exists: bool
    kernels: list[CachedKernel] = field(default_factory=list)
    index_entries: int = 0
    leftovers: int = 0
    #: why the cache is not used (a link, another user's directory, writable by others)
    refused: str | None = None
    #: lock files that are links or not regular files (no build opens them: a build that
    #: needs one stops with a CacheError until ``clear_cache`` removes it)
    bad_locks: list[str] = field(default_factory=list)

    @property
    def size(self) -> int:
        return sum(k.size for k in self.kernels)

    @property
    def bad(self) -> list[CachedKernel]:
        """The entries that would not be loaded (rebuilt on use, removed by
        ``clear_cache(bad_only=True)``)."""
        return [k for k in self.kernels if not k.complete]


@dataclass
class ClearedCache:
    root: Path
    removed: int = 0
    freed: int = 0
    busy: list[str] = field(default_factory=list)
    index_entries: int = 0
    failed: list[str] = field(default_factory=list)  # kernels and index files still there
    bad_locks: int = 0  # lock files that were links or not regular files, removed


def _tree_size(path: Path) -> int:
    """The bytes of the files under ``path``; a link (the entry itself, or below it) is
    not followed (os.walk would walk a linked top directory, e.g. to /usr)."""
    if path.is_symlink():
        return 0
    total = 0
    for folder, _, files in os.walk(path):  # never follows links below the top
        for name in files:
            with contextlib.suppress(OSError):
                total += (Path(folder) / name).stat(follow_symlinks=False).st_size
    return total


def _entries(folder: Path, pattern: re.Pattern | None = None) -> list[Path]:
    """The entries of ``folder`` (not followed if it is a link), those whose name matches
    ``pattern`` when given."""
    if folder.is_symlink():
        return []
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return []
    return [folder / n for n in names if pattern is None or pattern.fullmatch(n)]


def _kernel(entry: Path) -> CachedKernel:
    manifest, problem = entry_defect(entry, entry.name)
    if manifest is None:
        manifest = read_json(entry / MANIFEST) or {}
    try:
        modified = entry.lstat().st_mtime
    except OSError:
        modified = 0.0
    return CachedKernel(entry.name, _printable(manifest.get("system", "?")), _tree_size(entry),
                        modified, problem is None, problem)


def _printable(value) -> str:
    """A manifest's text as it may be shown on a terminal: control characters (an escape
    sequence planted in a manifest) replaced by '?', at most 80 characters."""
    text = "".join("?" if not ch.isprintable() else ch for ch in str(value))
    return text if len(text) <= 80 else text[:79] + "…"


def cache_info(root: Path | None = None) -> CacheInfo:
    """What the cache at ``root`` (default: the configured cache) holds; a cache that is
    not used (:func:`~._trust.trusted`) says why in ``refused`` and lists nothing."""
    root = absolute_root(root) if root is not None else cache_root()
    info = CacheInfo(root, root.is_dir())
    if not info.exists:
        if os.path.lexists(root):  # a file, a FIFO or a link where the directory would be
            info.exists = True
            info.refused = "it is not a directory"
        return info
    info.refused = _untrusted_reason(root)
    foreign = foreign_listing(root) if info.refused is None else None
    if foreign is not None:  # (compile() does not use it either)
        info.refused = f"it is not a kernel cache (no {MARKER}; it holds {foreign})"
    if info.refused is not None:
        return info
    info.kernels = [_kernel(e) for e in _entries(root / "kernels", _KEY)]
    info.index_entries = len(_entries(root / "index", _INDEX))
    info.leftovers = len(_entries(root / "tmp"))
    info.bad_locks = [e.name for e in _bad_locks(root)]
    return info


def _bad_locks(root: Path) -> list[Path]:
    """The lock files of ``root`` that are links or not regular files (never followed)."""
    locks = root / "locks"
    if not locks.is_dir() or locks.is_symlink():
        return []
    return [entry for entry in sorted(locks.iterdir())
            if entry.is_symlink() or not entry.is_file()]


def clear_cache(root: Path | None = None, *, bad_only: bool = False) -> ClearedCache:
    """Remove every kernel not being built right now, and the index (see the module
    docstring); ``bad_only``: only the kernels that would not be loaded, and the index
    entries pointing nowhere."""
    root = absolute_root(root) if root is not None else cache_root()
    result = ClearedCache(root)
    if not root.is_dir():
        if os.path.lexists(root):  # as cache_info says: NOT USED
            raise CacheError(f"{root} is not a directory (a file, a FIFO or a link where the "
                             f"kernel cache would be): nothing was removed")
        return result
    if not is_cache_root(root):
        foreign = foreign_listing(root)
        if foreign is not None:
            raise CacheError(f"{root} is not a symgroupoid kernel cache (no {MARKER}; it "
                             f"holds {foreign}): nothing was removed")
        if not _holds_cache_evidence(root):
            return result  # empty: nothing to remove
    trusted(root, modes=False)  # links, other users' directories: CacheError
    if not is_cache_root(root):  # an unmarked cache layout, which info lists and compile
        try:  # loads from: marked as the cache it is, then cleared
            _claim(root)
        except OSError as exc:
            raise CacheError(f"{root} is an unmarked kernel cache that cannot be marked "
                             f"({exc.strerror or exc}): nothing was removed") from exc
    locks = root / "locks"
    if os.path.lexists(locks) and not locks.is_dir():  # (a link: refused by trusted above)
        raise CacheError(f"{locks} is not a directory, so no lock tells a kernel being built "
                         f"from one that is not: nothing was removed (remove that file; the "
                         f"next build recreates the directory)")
    for entry in _bad_locks(root):  # (a link is removed itself, never what it points to)
        _remove(entry)
        if not os.path.lexists(entry):
            result.bad_locks += 1
        else:
            result.failed.append(f"locks/{entry.name}")
    # a read-only cache: its locks cannot be opened, which is not a build in progress
    changeable = all(os.access(root / name, os.W_OK) for name in ("kernels", "locks"))
    for entry in _entries(root / "kernels", _KEY):
        if bad_only and entry_defect(entry, entry.name)[0] is not None:
            continue
        if not changeable:
            result.failed.append(entry.name)
            continue
        with key_busy(root, entry.name) as busy:
            if busy:
                result.busy.append(entry.name)
                continue
            size = _tree_size(entry)
            remove_tree(entry)
            if not os.path.lexists(entry):
                result.removed += 1
                result.freed += size
            else:  # (an unwritable cache, an immutable file)
                result.failed.append(entry.name)
    for entry in _entries(root / "index", _INDEX):
        if bad_only:
            data = read_json(entry) or {}
            key = data.get("source_key")
            if isinstance(key, str) and _KEY.fullmatch(key) and (root / "kernels" / key).is_dir():
                continue
        _remove(entry)
        if not os.path.lexists(entry):
            result.index_entries += 1
        else:
            result.failed.append(f"index/{entry.name}")
    if not bad_only:
        for entry in _entries(root / "templates", _TEMPLATE):  # Python, of older versions
            _remove(entry)
    sweep(root)
    return result
