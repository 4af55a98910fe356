"""The sweep of what dead processes left in a cache root (abandoned build and trash
directories, probes, temporary files of interrupted writes): only names the cache makes."""

from __future__ import annotations

import contextlib
import os
import re
import time
from pathlib import Path

from ._atomic import _remove
from ._locks import _held_if_free
from ._processes import HOST_TAG, _pid_alive
from ._roots import _KEY, INTERNAL, MARKER, is_cache_root
from ._trust import _untrusted_reason
from ._writable import _STATE_LOCK

#: age (seconds) after which leftovers that name no live process (``build-*`` of other
#: hosts where ``flock`` is missing, ``probe-*``, temporary index files) count as abandoned
GRACE = 3600.0


#: the random part ``tempfile`` gives a name
_RANDOM = r"[a-z0-9_]{8}"


#: ``tmp/`` leftovers: build and trash directories (of a key, and since format 3 of a
#: process and host; before keys, ``tempfile``'s "build-" and its eight random characters,
#: exactly: a user's build-2024.log or build-artifacts is not one), probes
_TMP_ENTRY = re.compile(r"(?P<kind>build|trash)-(?P<name>[0-9a-f]{32}(?:\.json)?)-"
                        r"(?:(?P<pid>[0-9]+)-(?P<host>[0-9a-f]{12})-)?[a-z0-9_]+"
                        r"|(?P<legacy>build-" + _RANDOM + r")|probe-" + _RANDOM)


#: a temporary file of an atomic write, or a writability probe (any cache directory)
_TEMPORARY = re.compile(r"\.(?:[0-9a-f]{32}\.json|openmp-[0-9a-f]{32}\.json|" + MARKER
                        + r")\." + _RANDOM + r"|probe-" + _RANDOM)


_SWEPT: set[Path] = set()


def _abandoned(path: Path, match: re.Match, free: bool | None) -> bool:
    """Whether the build or trash directory ``path`` (named ``match``) has no live maker:
    its key's ``flock`` was ``free`` (True: free, False: held, None: no ``flock``)."""
    if free is False:
        return False
    pid, host = match.group("pid"), match.group("host")
    if host == HOST_TAG:
        return not _pid_alive(int(pid))
    if free:
        return True
    with contextlib.suppress(OSError):
        return time.time() - os.lstat(path).st_mtime > GRACE
    return False


def sweep(root: Path) -> None:
    """Remove what dead processes left in ``root`` (best effort, never blocks).

    In ``tmp/``: build and trash directories whose maker is gone (:func:`_abandoned`:
    their key's lock is free, or without ``flock`` their process has ended on this host,
    or they are older than ``GRACE``); unkeyed ones of older versions and probes once
    older than ``GRACE``.  In every cache directory: temporary files of interrupted
    writes once older than ``GRACE``.  Only names the cache makes; only a marked, trusted
    cache root (:func:`is_cache_root`, :func:`trusted`).
    """
    if not is_cache_root(root) or _untrusted_reason(root) is not None:
        return
    now = time.time()
    for sub in INTERNAL:
        try:
            entries = list(os.scandir(root / sub))
        except OSError:
            continue
        for entry in entries:
            path = Path(entry.path)
            match = _TMP_ENTRY.fullmatch(entry.name) if sub == "tmp" else None
            if match and match.group("kind") and _KEY.fullmatch(match.group("name")[:32]):
                key = match.group("name")[:32]
                with _held_if_free(root / "locks" / f"{key}.lock") as free:
                    if _abandoned(path, match, free):
                        _remove(path)
            elif match or _TEMPORARY.fullmatch(entry.name):
                with contextlib.suppress(OSError):
                    if now - entry.stat(follow_symlinks=False).st_mtime > GRACE:
                        _remove(path)


def sweep_once(root: Path) -> None:
    """:func:`sweep` on the first use of a writable ``root`` in this process."""
    with _STATE_LOCK:
        if root in _SWEPT:
            return
        _SWEPT.add(root)
    if os.access(root / "tmp", os.W_OK | os.X_OK):
        sweep(root)
