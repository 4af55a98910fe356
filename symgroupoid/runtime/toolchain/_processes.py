"""Whose build is it: the process and host named in build and trash directories and leases."""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import socket
import stat
import tempfile
from pathlib import Path


def _boot_id() -> str:
    try:
        with open("/proc/sys/kernel/random/boot_id", encoding="ascii") as fh:
            return fh.read().strip()
    except OSError:
        return ""


#: this host (and boot) in the names of build and trash directories
HOST_TAG = hashlib.sha256(f"{socket.gethostname()}|{_boot_id()}".encode()).hexdigest()[:12]


def owner_tag() -> str:
    """``<pid>-<host>``: the part of a build or trash directory's name naming its maker."""
    return f"{os.getpid()}-{HOST_TAG}"


def _pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` runs on this host (any user's; zombies count as gone)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True  # another user's process
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def scratch_prefix(kind: str) -> str:
    """``symgroupoid-<kind>-<pid>-<host>-``: the name of a directory this process makes in
    the system's temporary directory (a compiler probe, a private fallback cache), so that
    a later process can tell, once this one is gone, that nobody will remove it."""
    return f"symgroupoid-{kind}-{owner_tag()}-"


def sweep_scratch(kind: str) -> None:
    """Remove this user's ``symgroupoid-<kind>-…`` directories in the system's temporary
    directory whose process on this host is gone: a process killed (SIGKILL) while its probe
    ran, or while it used a private fallback cache, could not remove its own.  Only
    directories (never links) of this user; the removal follows no link."""
    base = Path(tempfile.gettempdir())
    pattern = re.compile(rf"symgroupoid-{re.escape(kind)}-(\d+)-{HOST_TAG}-")
    try:
        entries = list(os.scandir(base))
    except OSError:
        return
    for entry in entries:
        match = pattern.match(entry.name)
        if match is None or int(match.group(1)) == os.getpid():
            continue
        try:
            info = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() \
                or _pid_alive(int(match.group(1))):
            continue
        shutil.rmtree(entry.path, ignore_errors=True)
