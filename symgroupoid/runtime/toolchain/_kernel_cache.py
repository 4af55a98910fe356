"""``KernelCache``: the index and kernel directories under a cache root, read from the
fallback, configured and shared roots, written to the writable one."""

from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ._atomic import _remove, read_json, remove_tree, write_json_atomic
from ._entries import _verified, _without_others_write
from ._locks import exclusive
from ._processes import owner_tag
from ._roots import _KEY, absolute_root, cache_root, shared_root
from ._sweep import sweep, sweep_once
from ._trust import _owners, dir_mode, trusted
from ._writable import _FALLBACKS, writable_root


class KernelCache:
    """Index and kernel directories under a cache root.

    Reads look in this process's private fallback (if the root turned out unwritable), in
    the configured root and in the shared read-only cache (:func:`shared_root`); writes go
    to :meth:`write_root`.  Every read checks its root first (:func:`trusted`).
    """

    def __init__(self, root: Path | None = None):
        self.root = absolute_root(root) if root is not None else cache_root()
        self._located: dict[str, Path] = {}

    def read_roots(self) -> tuple[Path, ...]:
        fallback = _FALLBACKS.get(self.root)
        roots = (fallback, self.root) if fallback is not None else (self.root,)
        shared = shared_root()
        return roots if shared is None or shared in roots else (*roots, shared)

    def trusted_roots(self) -> Iterator[tuple[Path, frozenset[int]]]:
        """(root, trusted owners) of each read root that exists (:class:`CacheError` for
        one that cannot be trusted)."""
        shared = shared_root()
        for root in self.read_roots():
            owners = _owners()
            if root == shared and root != self.root:
                try:
                    owners = _owners(os.stat(root).st_uid)
                except OSError:
                    continue
            if trusted(root, owners, shared=root == shared and root != self.root):
                yield root, owners

    def write_root(self) -> Path:
        """The root new entries go to (created; may warn and fall back, see module doc)."""
        return writable_root(self.root)

    def written_root(self) -> Path:
        """Where entries are written: the configured root, or this process's fallback for
        it (nothing is created)."""
        return _FALLBACKS.get(self.root, self.root)

    def lookup(self, input_key: str) -> str | None:
        """Source key recorded for an input key, if any."""
        sweep_once(self.root)
        for root, owners in self.trusted_roots():
            data = read_json(root / "index" / f"{input_key}.json", owners)
            key = data.get("source_key") if data else None
            if isinstance(key, str) and _KEY.fullmatch(key):
                return key
        return None

    def record(self, input_key: str, source_key: str, prefix: str) -> None:
        path = self.write_root() / "index" / f"{input_key}.json"
        data = {"source_key": source_key, "prefix": prefix}
        try:
            write_json_atomic(path, data)
        except IsADirectoryError:  # a directory in the way of the index file
            remove_tree(path)
            write_json_atomic(path, data)

    def entry(self, source_key: str) -> Path:
        """Directory of the kernel (where it was last verified, else where it would go)."""
        located = self._located.get(source_key)
        return located if located is not None else self.read_roots()[0] / "kernels" / source_key

    def verified_manifest(self, source_key: str) -> dict | None:
        """The manifest of a complete, undamaged, trusted kernel directory; None otherwise."""
        if not _KEY.fullmatch(source_key):
            return None
        for root, owners in self.trusted_roots():
            entry = root / "kernels" / source_key
            manifest = _verified(entry, source_key, owners)
            if manifest is not None:
                self._located[source_key] = entry
                return manifest
        return None

    @contextlib.contextmanager
    def build_lock(self, source_key: str, label: str) -> Iterator[None]:
        """Hold the lock of ``source_key`` in the writable root (after sweeping it)."""
        root = self.write_root()
        sweep(root)
        with exclusive(root / "locks" / f"{source_key}.lock", label):
            yield

    def new_build_dir(self, source_key: str) -> Path:
        """A fresh ``tmp/build-<source key>-<pid>-<host>-*`` directory of this process."""
        tmp = self.write_root() / "tmp"
        tmp.mkdir(mode=dir_mode(), parents=True, exist_ok=True)
        path = Path(tempfile.mkdtemp(prefix=f"build-{source_key}-{owner_tag()}-", dir=tmp))
        os.chmod(path, dir_mode())
        return path

    def install(self, build_dir: Path, source_key: str, stale: str | None = None) -> Path:
        """Publish a finished build directory as the kernel ``source_key`` by one atomic
        ``rename``.  An entry already there that verifies (another process published it
        first) is kept and the build dropped, unless its library's SHA-256 is ``stale``
        (an entry that failed to load); a damaged one is replaced."""
        self._located.pop(source_key, None)
        try:
            _without_others_write(build_dir)
            target = self.write_root() / "kernels" / source_key
            target.parent.mkdir(mode=dir_mode(), parents=True, exist_ok=True)
        except BaseException:
            _remove(build_dir)
            raise
        for _ in range(3):
            current = _verified(target, source_key, _owners())
            if current is not None and current.get("sha256") != stale:
                break
            remove_tree(target)
            try:
                os.rename(build_dir, target)
                return target
            except OSError as exc:
                if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY, errno.ENOTDIR,
                                     errno.EISDIR):
                    _remove(build_dir)
                    raise
            stale = None  # another process published meanwhile: its entry is new
        # what is there now is the caller's to verify and report
        _remove(build_dir)
        return target
