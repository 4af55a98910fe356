"""Whose build is it: the process and host named in build and trash directories and leases."""

from __future__ import annotations

import hashlib
import os
import socket


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
