"""Whom the kernel cache trusts: owners and modes of its files and directories, checked as
ssh checks its keys (see :mod:`symgroupoid.runtime.toolchain`)."""

from __future__ import annotations

import contextlib
import os
import stat
from pathlib import Path

from ..._errors import CacheError
from ...codegen import current_umask
from ._roots import INTERNAL, _foreign_entries, is_cache_root


def dir_mode() -> int:
    """Mode of a new cache directory: the umask's, less group and other write (0755 under
    022 and 002, 0750 under 027)."""
    return 0o777 & ~current_umask() & ~0o022


def file_mode() -> int:
    """Mode of a new cache file: the umask's, less group and other write."""
    return 0o666 & ~current_umask() & ~0o022


def _owners(*extra: int) -> frozenset[int]:
    """The users whose files the cache trusts: this one, root, and ``extra``."""
    return frozenset({os.geteuid(), 0, *extra}) if hasattr(os, "geteuid") else frozenset()


def distrust(info: os.stat_result, owners: frozenset[int]) -> str | None:
    """Why the cache does not trust a file of status ``info`` (from ``lstat``), or None:
    a symbolic link, an owner not in ``owners``, or write permission for group or others.
    (No checks where there are no POSIX owners.)"""
    if stat.S_ISLNK(info.st_mode):
        return "it is a symbolic link, which the cache never makes and never follows"
    if not owners:
        return None
    if info.st_uid not in owners:
        return f"it belongs to another user (uid {info.st_uid})"
    if info.st_mode & 0o022:
        who = "group and others" if info.st_mode & 0o022 == 0o022 else (
            "its group" if info.st_mode & 0o020 else "others")
        return f"it is writable by {who} (mode {stat.S_IMODE(info.st_mode):04o})"
    return None


def _refusal(root: Path, path: Path, reason: str, shared: bool = False) -> CacheError:
    """The error for an untrusted cache: what, why, and what to do."""
    what = "the shared kernel cache" if shared else "the kernel cache"
    if "symbolic link" in reason:
        fix = (f"remove the link (rm {path}); to keep the cache elsewhere, set "
               f"SYMGROUPOID_CACHE to that directory")
    elif "another user" in reason:
        fix = ("remove it, or set SYMGROUPOID_CACHE to a directory of your own (a cache "
               "another account provides is read with SYMGROUPOID_SHARED_CACHE)")
    elif shared:
        fix = (f"its owner can make it private (chmod go-w {path}); or point "
               f"SYMGROUPOID_SHARED_CACHE to a cache that is, or unset it")
    else:
        fix = f"make it private (chmod go-w {path}), or set SYMGROUPOID_CACHE elsewhere"
    return CacheError(f"{what} {root} is not used: {path} cannot be trusted ({reason}; "
                      f"others could plant code this process would run); {fix}")


def trusted(root: Path, owners: frozenset[int] | None = None, *, modes: bool = True,
            shared: bool = False) -> bool:
    """Check the cache ``root`` and its directories (:data:`INTERNAL`) before any use:
    :class:`CacheError` when one of them cannot be trusted (see the module docstring;
    ``modes=False``: write permission of others is tolerated, for removing only).  False
    when there is no cache directory there (missing, not a directory, or a directory
    holding other things, which is never used as a cache), else True."""
    owners = _owners() if owners is None else owners
    try:
        info = os.stat(root)  # the root may be reached through a link of the user's
    except OSError:
        return False
    if not stat.S_ISDIR(info.st_mode) or (not is_cache_root(root) and _foreign_entries(root)):
        return False
    reason = distrust(info, owners)
    if reason is not None and (modes or "writable" not in reason):
        raise _refusal(root, root, reason, shared)
    for name in INTERNAL:
        path = root / name
        try:
            info = os.lstat(path)
        except OSError:
            continue
        if not (stat.S_ISDIR(info.st_mode) or stat.S_ISLNK(info.st_mode)):
            continue  # a file in the way: replaced when the cache is prepared
        reason = distrust(info, owners)
        if reason is not None and (modes or "writable" not in reason):
            if stat.S_ISLNK(info.st_mode):
                with contextlib.suppress(OSError):
                    reason += f" (to {os.readlink(path)})"
            raise _refusal(root, path, reason, shared)
    return True


def _untrusted_reason(root: Path) -> str | None:
    """:func:`trusted`'s refusal of ``root`` as text, or None (never raises)."""
    try:
        trusted(root)
    except CacheError as exc:
        return str(exc)
    return None
