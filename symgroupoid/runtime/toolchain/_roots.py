"""Where the kernel cache is (its roots) and what a cache root holds (its layout, its marker)."""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

from ..._errors import CacheError

MANIFEST = "manifest.json"


SUBDIRS = ("index", "kernels", "locks", "tmp")


#: every directory of a cache root (checked for links and owners before any use)
INTERNAL = (*SUBDIRS, "probes", "templates")


#: the file that marks a directory as a kernel cache (the Cache Directory Tagging
#: convention, so backup tools skip it); only a marked root is ever cleaned or swept
MARKER = "CACHEDIR.TAG"


_SIGNATURE = "Signature: 8a477f597d28d172789f06886806bc55"


_MARKER_TEXT = (f"{_SIGNATURE}\n# This directory is a symgroupoid kernel cache: compiled "
                f"kernels, rebuilt on demand.\n# It can be removed at any time.\n")


#: what a cache root holds besides the marker (a root holding only these is adopted)
_CACHE_NAMES = frozenset(INTERNAL)


_KEY = re.compile(r"[0-9a-f]{32}")


_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)


_CLOEXEC = getattr(os, "O_CLOEXEC", 0)

#: opening a FIFO for reading blocks until a writer comes; a file the cache reads is
#: regular, so it is opened without waiting and anything else is then refused by ``fstat``
_NONBLOCK = getattr(os, "O_NONBLOCK", 0)


def cache_root() -> Path:
    """The configured cache directory (not created; see :class:`KernelCache` for fallback)."""
    override = os.environ.get("SYMGROUPOID_CACHE")
    if override:
        return absolute_root(_expanded(override))
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        return absolute_root(_expanded(xdg) / "symgroupoid")
    try:
        home = Path.home()
    except (RuntimeError, KeyError, OSError) as exc:
        raise CacheError(f"no kernel cache directory: the home directory cannot be "
                         f"determined ({exc}); set SYMGROUPOID_CACHE to a directory") from exc
    return home / ".cache" / "symgroupoid"


def shared_root() -> Path | None:
    """The read-only shared cache (``$SYMGROUPOID_SHARED_CACHE``), or None."""
    text = os.environ.get("SYMGROUPOID_SHARED_CACHE")
    return absolute_root(text) if text and text.strip() else None


def absolute_root(path: str | os.PathLike) -> Path:
    """A cache root as an absolute, normalised path (``~`` expanded): a relative one is
    resolved against the working directory once, when it is given, so a later change of
    directory cannot move the cache (or scatter entries over several directories)."""
    return Path(os.path.abspath(_expanded(os.fspath(path))))


def _expanded(text: str) -> Path:
    """``text`` with a leading ``~`` or ``~user`` expanded; kept as written (as a shell
    does) when that user or the home directory is unknown."""
    try:
        return Path(text).expanduser()
    except (RuntimeError, KeyError, OSError):
        return Path(text)


def open_regular(path: Path):
    """``path`` opened for reading (binary) if it is a regular file, never following a
    link or waiting on a FIFO, else None: a directory there is not opened as a file
    (``os.fdopen`` of a directory raises ``IsADirectoryError``)."""
    try:
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | _CLOEXEC | _NONBLOCK)
    except OSError:
        return None
    try:
        regular = stat.S_ISREG(os.fstat(fd).st_mode)
    except OSError:
        regular = False
    if not regular:
        os.close(fd)
        return None
    return os.fdopen(fd, "rb")


def is_cache_root(root: Path) -> bool:
    """Whether ``root`` carries the cache marker (see :data:`MARKER`)."""
    fh = open_regular(root / MARKER)
    if fh is None:
        return False
    with fh:
        try:
            return fh.read(len(_SIGNATURE)) == _SIGNATURE.encode()
        except OSError:
            return False


#: what each directory of a cache holds (an unmarked root is adopted only if its
#: directories hold nothing else: a cache layout written before roots were marked)
_CACHE_CONTENT = {
    "index": re.compile(r"\.?[0-9a-f]{32}\.json.*"),
    "kernels": re.compile(r"[0-9a-f]{32}"),
    "locks": re.compile(r"[0-9a-f]{32}\.(lock|lease)"),
    "tmp": re.compile(r"(build|trash)-[0-9a-f]{32}(\.json)?-([0-9]+-[0-9a-f]{12}-)?[a-z0-9_]+"
                      r"|(build|probe)-[a-z0-9_]{8}"),
    "probes": re.compile(r"\.?openmp-[0-9a-f]{32}\.json.*"),
    "templates": re.compile(r"__jinja2_[0-9a-f]{40}\.cache.*"),
}


#: the temporary file of a marker being written (``write_atomic_private``: ".NAME.xxxxxxxx")
_MARKER_BEING_WRITTEN = re.compile(r"\." + re.escape(MARKER) + r"\.[A-Za-z0-9_]+")


#: the directories whose names no user's files plausibly have (a lock, a probe, a compiled
#: template): one of them is evidence of a cache as a kernel is; index/ and tmp/ names
#: (<32 hex>.json, build-20240101) are not
_DISTINCT = ("locks", "probes", "templates")


def _holds_cache_evidence(root: Path) -> bool:
    """Whether ``root`` holds what only a cache writes: a kernel as a cache writes one (a
    directory ``kernels/<key>``, not a link, with a regular file ``MANIFEST``) or an entry
    of :data:`_DISTINCT` — the evidence an unmarked root needs before the names of its
    index/ and tmp/ entries are read as the cache's (a user's ``tmp/build-20240101`` or
    ``index/<32 hex>.json`` are names a cache could have written)."""
    for folder in _DISTINCT:
        path = root / folder
        if path.is_dir() and not path.is_symlink() and any(
                _CACHE_CONTENT[folder].fullmatch(n) for n in _names(path)):
            return True
    kernels = root / "kernels"
    if kernels.is_symlink():
        return False
    for name in _names(kernels):
        entry = kernels / name
        if _CACHE_CONTENT["kernels"].fullmatch(name) and not entry.is_symlink():
            try:
                if stat.S_ISREG(os.lstat(entry / MANIFEST).st_mode):
                    return True
            except OSError:
                continue
    return False


def _names(folder: Path) -> list[str]:
    try:
        return os.listdir(folder)
    except OSError:
        return []


def _foreign_entries(root: Path) -> list[str]:
    """What in ``root`` a kernel cache does not hold (empty: the root is, or can become, a
    cache): names other than the cache's, and entries of its directories that no cache
    writes — every entry of them unless the root holds evidence of a cache
    (:func:`_holds_cache_evidence`): an unmarked root is adopted when it is empty or an
    unmarked cache layout, never for index/ and tmp/ names alone."""
    try:
        entries = list(os.scandir(root))
    except FileNotFoundError:
        return []
    evidence = _holds_cache_evidence(root)
    out = []
    for e in entries:
        if e.name == MARKER or _MARKER_BEING_WRITTEN.fullmatch(e.name):
            continue  # (another process marking the root: its temporary file, renamed next)
        if e.name not in _CACHE_NAMES:
            out.append(e.name)
        elif e.is_dir(follow_symlinks=False):
            try:
                names = os.listdir(e.path)
            except OSError:
                names = []
            out += [f"{e.name}/{n}" for n in names
                    if not (evidence and _CACHE_CONTENT[e.name].fullmatch(n))]
    return sorted(out)


def foreign_listing(root: Path) -> str | None:
    """The first things in ``root`` that no kernel cache holds, for messages ("a, b, c, …"),
    or None when ``root`` is a cache or can become one (:func:`_foreign_entries`)."""
    if is_cache_root(root):
        return None
    foreign = _foreign_entries(root)
    if not foreign:
        return None
    return ", ".join(foreign[:3]) + (", …" if len(foreign) > 3 else "")
