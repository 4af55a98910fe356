"""Looking into and clearing the kernel cache (``symgroupoid cache info|clear``).

Clearing is safe while other processes use the cache: a kernel whose build lock is held (it
is being built or rebuilt right now) is left alone and reported; every other kernel
directory is removed the way the cache removes a damaged one (renamed away first, so no
process ever sees half a kernel), its index entries with it.  A process that has already
loaded a removed kernel keeps using it; the next one to ask for it builds it again.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

from .._errors import CacheError
from ._cache import (
    MANIFEST,
    MARKER,
    _foreign_entries,
    _held_if_free,
    _verified,
    absolute_root,
    cache_root,
    is_cache_root,
    read_json,
    remove_tree,
    sweep,
)


@dataclass
class CachedKernel:
    """One kernel directory: its source key, the system it was built for, bytes on disk,
    modification time, and whether its manifest verifies (module present, hash matching)."""

    key: str
    system: str
    size: int
    modified: float
    complete: bool


@dataclass
class CacheInfo:
    root: Path
    exists: bool
    kernels: list[CachedKernel] = field(default_factory=list)
    index_entries: int = 0
    leftovers: int = 0

    @property
    def size(self) -> int:
        return sum(k.size for k in self.kernels)


@dataclass
class ClearedCache:
    root: Path
    removed: int = 0
    freed: int = 0
    busy: list[str] = field(default_factory=list)
    index_entries: int = 0


def _tree_size(path: Path) -> int:
    total = 0
    for folder, _, files in os.walk(path):
        for name in files:
            with contextlib.suppress(OSError):
                total += (Path(folder) / name).stat(follow_symlinks=False).st_size
    return total


def _entries(folder: Path) -> list[Path]:
    try:
        return sorted(folder.iterdir())
    except OSError:
        return []


def _kernel(entry: Path) -> CachedKernel:
    manifest = read_json(entry / MANIFEST) or {}
    try:
        modified = entry.stat().st_mtime
    except OSError:
        modified = 0.0
    return CachedKernel(entry.name, str(manifest.get("system", "?")), _tree_size(entry),
                        modified, _verified(entry, entry.name) is not None)


def cache_info(root: Path | None = None) -> CacheInfo:
    """What the cache at ``root`` (default: the configured cache) holds."""
    root = absolute_root(root) if root is not None else cache_root()
    info = CacheInfo(root, root.is_dir())
    if not info.exists:
        return info
    info.kernels = [_kernel(e) for e in _entries(root / "kernels") if e.is_dir()]
    info.index_entries = sum(1 for e in _entries(root / "index") if e.suffix == ".json")
    info.leftovers = len(_entries(root / "tmp"))
    return info


def clear_cache(root: Path | None = None) -> ClearedCache:
    """Remove every kernel not being built right now, and the index (see the module
    docstring)."""
    root = absolute_root(root) if root is not None else cache_root()
    result = ClearedCache(root)
    if not root.is_dir():
        return result
    if not is_cache_root(root):
        foreign = _foreign_entries(root)
        if foreign:
            raise CacheError(f"{root} is not a symgroupoid kernel cache (no {MARKER}; it "
                             f"holds {', '.join(foreign[:3])}{', …' if len(foreign) > 3 else ''}"
                             f"): nothing was removed")
        return result  # empty, or only an unmarked cache layout: nothing of ours to remove
    for entry in _entries(root / "kernels"):
        with _held_if_free(root / "locks" / f"{entry.name}.lock") as free:
            if not free:
                result.busy.append(entry.name)
                continue
            size = _tree_size(entry)
            remove_tree(entry)
            if not (entry.exists() or entry.is_symlink()):
                result.removed += 1
                result.freed += size
    for entry in _entries(root / "index"):
        if entry.suffix == ".json":
            with contextlib.suppress(OSError):
                entry.unlink()
                result.index_entries += 1
    sweep(root)
    return result
