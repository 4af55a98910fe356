"""Private, atomic file operations of the kernel cache: writes through a temporary file and a
rename, reads that never follow a link, removals of what the cache made."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import stat
import tempfile
from pathlib import Path

from ._processes import owner_tag
from ._roots import open_regular
from ._trust import _owners, dir_mode, distrust, file_mode


def write_atomic_private(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a new temporary file in the same directory
    (``O_EXCL``, never a link) and an atomic rename (which replaces a link at ``path``,
    never follows it); the file's mode is :func:`file_mode`."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            with contextlib.suppress(AttributeError):
                os.fchmod(fh.fileno(), file_mode())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON (ASCII) through a temporary file in the same directory and an atomic
    rename (:func:`write_atomic_private`)."""
    write_atomic_private(path, json.dumps(data, sort_keys=True, indent=1).encode("ascii"))


def read_private(path: Path, owners: frozenset[int] | None = None) -> bytes | None:
    """The bytes of the regular file ``path`` if it is trusted (opened without following a
    link; of ``owners``, not writable by others, :func:`distrust`), else None."""
    owners = _owners() if owners is None else owners
    fh = open_regular(path)
    if fh is None:
        return None
    with fh:
        if distrust(os.fstat(fh.fileno()), owners) is not None:
            return None
        try:
            return fh.read()
        except OSError:
            return None


def read_json(path: Path, owners: frozenset[int] | None = None) -> dict | None:
    """The JSON object in ``path``, or None when missing, unreadable or not trusted
    (:func:`read_private`)."""
    data = read_private(path, owners)
    if data is None:
        return None
    try:
        value = json.loads(data.decode("utf-8"))
    except (ValueError, RecursionError):  # (not JSON; nested beyond the parser's depth)
        return None
    return value if isinstance(value, dict) else None


def _remove(path: Path) -> None:
    """Remove a file, link or directory tree (best effort; missing is fine).  A link is
    removed as a link (``lstat``), never followed; ``shutil.rmtree`` follows no link
    inside the tree."""
    try:
        info = os.lstat(path)
    except OSError:
        return
    if stat.S_ISDIR(info.st_mode):
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _exists(path: Path) -> bool:
    """Whether anything (even a dangling link) is at ``path``."""
    return os.path.lexists(path)


def remove_tree(path: Path) -> None:
    """Remove a kernel directory (or whatever occupies its name) without ever exposing a
    half-deleted kernel under its name: it is first renamed into ``tmp/``."""
    if not _exists(path):
        return
    trash = None
    try:
        tmp = path.parent.parent / "tmp"
        tmp.mkdir(mode=dir_mode(), parents=True, exist_ok=True)
        trash = Path(tempfile.mkdtemp(prefix=f"trash-{path.name}-{owner_tag()}-", dir=tmp))
        os.replace(path, trash / "entry")
    except OSError:
        _remove(path)
    if trash is not None:
        _remove(trash)
