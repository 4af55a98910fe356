"""The root kernels are written to: the configured cache root, marked and laid out, or this
process's private temporary fallback when it cannot be written."""

from __future__ import annotations

import atexit
import contextlib
import errno
import os
import shutil
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

from ..._errors import CacheError
from ._atomic import _exists, write_atomic_private
from ._processes import scratch_prefix, sweep_scratch
from ._roots import _MARKER_TEXT, MARKER, SUBDIRS, foreign_listing, is_cache_root
from ._trust import dir_mode, trusted

_STATE_LOCK = threading.Lock()


#: configured cache root → private temporary root used instead (this process only)
_FALLBACKS: dict[Path, Path] = {}


class ForeignDirectoryError(OSError):
    """The configured cache root is a directory holding other things than a kernel cache."""


class UnloadablePathError(OSError):
    """The configured cache root's path is one no kernel library can be loaded from."""


def _claim(root: Path) -> bool:
    """Mark ``root`` as a kernel cache, unless it holds anything else: then it is never
    written, cleaned or swept (raises :class:`ForeignDirectoryError`).  Whether it was
    unmarked until now."""
    if is_cache_root(root):
        return False
    shown = foreign_listing(root)
    if shown is not None:
        raise ForeignDirectoryError(
            errno.EEXIST, f"it is not a kernel cache: it holds other files ({shown}), which "
            f"symgroupoid leaves alone; a cache goes to an empty or new directory",
            str(root))
    write_atomic_private(root / MARKER, _MARKER_TEXT.encode("ascii"))
    return True


def _prepare(root: Path) -> None:
    """Create the cache layout under ``root`` and check that it is writable (raises OSError;
    :class:`CacheError` when it cannot be trusted, :func:`trusted`).

    The root is marked as a kernel cache first (:func:`_claim`; a directory holding other
    files raises :class:`ForeignDirectoryError` and is left untouched).  A subdirectory
    found as a file is removed and recreated — or, in a root marked just now (whose files
    may not be the cache's), moved aside as ``<name>.displaced-*``; one found as a link is
    refused (:func:`trusted`).
    """
    if not loadable_path(root):
        raise UnloadablePathError(errno.EINVAL, "its path is not valid UTF-8, and a kernel library "
                      "cannot be loaded from such a path", str(root))
    if root.exists() and not root.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "it is not a directory", str(root))
    root.mkdir(mode=dir_mode(), parents=True, exist_ok=True)
    trusted(root)  # (a directory holding other things: refused by _claim, just below)
    adopted = _claim(root)
    for name in SUBDIRS:
        path = root / name
        if not path.is_dir():
            if _exists(path):
                if adopted:
                    os.replace(path, root / f"{name}.displaced-{os.getpid()}-{time.time_ns()}")
                else:
                    with contextlib.suppress(FileNotFoundError):
                        path.unlink()
            path.mkdir(mode=dir_mode(), exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix="probe-", dir=path)
        os.close(fd)
        os.unlink(probe)
    trusted(root)  # nothing changed under us


def loadable_path(path: Path) -> bool:
    """Whether a library under ``path`` can be loaded: the loader takes the path as UTF-8
    text, which a path of other bytes (a name made of Latin-1 bytes) is not."""
    try:
        str(path).encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _caller_stacklevel() -> int:
    """Stack level of the first frame outside this package and ``contextlib`` (warnings)."""
    internal = (str(Path(__file__).resolve().parents[2]), contextlib.__file__)
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_code.co_filename.startswith(internal):
        frame, level = frame.f_back, level + 1
    return level


def _fallback(configured: Path, reason: OSError) -> Path:
    """A private temporary cache root replacing ``configured`` for this process."""
    why = reason.strerror or str(reason)
    if reason.filename and Path(reason.filename) != configured:
        why = f"{why}: {reason.filename}"
    unused = isinstance(reason, (ForeignDirectoryError, UnloadablePathError))
    state = "is not used" if unused else "is not writable"
    try:
        sweep_scratch("cache")
        private = Path(tempfile.mkdtemp(prefix=scratch_prefix("cache")))
        _prepare(private)
    except OSError as exc:
        raise CacheError(
            f"the kernel cache {configured} {state} ({why}) and no private temporary "
            f"directory could be made ({exc}); set SYMGROUPOID_CACHE to a writable "
            f"directory") from reason
    atexit.register(shutil.rmtree, private, True)
    warnings.warn(
        f"the kernel cache {configured} {state} ({why}); kernels built by this process "
        f"go to the private temporary directory {private} (removed at exit). Set "
        f"SYMGROUPOID_CACHE to a writable directory to keep them.",
        RuntimeWarning, stacklevel=_caller_stacklevel())
    return private


def prepared(root: Path) -> bool:
    """Whether ``root`` is (now) a writable, trusted kernel cache: :func:`_prepare` without
    the fallback, for optional writes such as probe results."""
    with _STATE_LOCK:
        if root in _FALLBACKS:
            return False
        try:
            _prepare(root)
        except (OSError, CacheError):
            return False
        return True


def writable_root(configured: Path) -> Path:
    """``configured``, prepared for writing, or this process's private fallback for it
    (:class:`CacheError` when it cannot be trusted)."""
    with _STATE_LOCK:
        fallback = _FALLBACKS.get(configured)
        if fallback is not None:
            return fallback
        try:
            _prepare(configured)
        except OSError as exc:
            _FALLBACKS[configured] = fallback = _fallback(configured, exc)
            return fallback
        return configured
