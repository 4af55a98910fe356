"""Serialising the builders of one kernel: ``flock`` locks, and ``O_EXCL`` leases where the
file system has no ``flock`` (NFS ``nolock``, Lustre ``noflock``)."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import socket
import stat
import time
from collections.abc import Iterator
from pathlib import Path

from ..._errors import CacheError
from ._atomic import read_private
from ._processes import HOST_TAG, _pid_alive
from ._roots import _CLOEXEC, _NOFOLLOW, _NONBLOCK
from ._trust import dir_mode, file_mode

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: builds are not serialised
    fcntl = None


#: seconds a process waits for another one building the same kernel
LOCK_TIMEOUT = 600.0


def lock_timeout() -> float:
    """Seconds to wait for another process's build (``SYMGROUPOID_LOCK_TIMEOUT``)."""
    return seconds_setting("SYMGROUPOID_LOCK_TIMEOUT", LOCK_TIMEOUT)


def seconds_setting(variable: str, default: float) -> float:
    """The positive number of seconds the environment variable ``variable`` sets, or
    ``default`` when it is unset or empty (:class:`CacheError` for anything else)."""
    text = os.environ.get(variable)
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise CacheError(f"{variable} must be a positive number of seconds, got {text!r}")
    return value


def _open_lock(path: Path) -> int:
    """The lock file ``path``, opened (made if missing) without following a link: a link
    there is ``OSError(ELOOP)``, something else than a regular file ``OSError(EINVAL)``."""
    path.parent.mkdir(mode=dir_mode(), parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | _NOFOLLOW | _CLOEXEC, file_mode())
    except PermissionError:  # another user's lock file in a shared cache: locking only
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | _CLOEXEC | _NONBLOCK)
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise OSError(errno.EINVAL, "not a regular file", str(path))
    return fd


def _try_flock(fd: int) -> bool | None:
    """Take the exclusive lock without waiting: True when taken, False when another
    process holds it, None when the file system has no ``flock`` (ENOLCK, ENOSYS,
    EOPNOTSUPP, or any other failure: never taken for "acquired")."""
    if fcntl is None:
        return None
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False
        except InterruptedError:
            continue
        except OSError as exc:
            if exc.errno in (errno.EAGAIN, errno.EACCES):
                return False
            return None
        return True


def _note_owner(fd: int) -> None:
    """Record who holds the lock (read only for the timeout message)."""
    with contextlib.suppress(OSError, AttributeError):
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode(), 0)


def _lock_error(path: Path, what: str, exc: OSError) -> CacheError:
    if exc.errno == errno.ELOOP:
        return CacheError(f"{what}: the lock file {path} is a symbolic link, which the kernel "
                          f"cache never makes and never follows; remove it (rm {path})")
    return CacheError(f"{what}: cannot open the lock file {path} ({exc}); remove it or set "
                      f"SYMGROUPOID_CACHE to a writable directory")


@contextlib.contextmanager
def exclusive(path: Path, what: str) -> Iterator[None]:
    """Hold the exclusive lock ``path`` (waiting for its holder up to :func:`lock_timeout`);
    where the file system has no ``flock``, the lease ``<key>.lease`` instead
    (:func:`_leased`)."""
    timeout = lock_timeout()
    try:
        fd = _open_lock(path)
    except OSError as exc:
        raise _lock_error(path, what, exc) from exc
    try:
        held = _wait_flock(fd, path, what, timeout)
    except BaseException:
        os.close(fd)
        raise
    if held is None:
        os.close(fd)
        with _leased(path.with_suffix(".lease"), timeout):
            yield
        return
    try:
        _note_owner(fd)
        yield
    finally:
        os.close(fd)  # releases the lock


def _wait_flock(fd: int, path: Path, what: str, timeout: float) -> bool | None:
    """Wait for the ``flock`` of ``fd``: True when held, None when there is no ``flock``."""
    deadline, delay = time.monotonic() + timeout, 0.002
    while True:
        held = _try_flock(fd)
        if held is not False:
            return held
        if time.monotonic() >= deadline:
            owner = (read_private(path) or b"").decode(errors="replace").strip()
            raise CacheError(
                f"{what}: waited {timeout:g} s for the lock {path}, held by another process "
                f"building the same kernel ({owner or 'owner unknown'}); if that process "
                f"hangs, stop it, or raise SYMGROUPOID_LOCK_TIMEOUT")
        time.sleep(delay)
        delay = min(2 * delay, 0.05)


def _lease_holder(path: Path) -> tuple[int, str] | None:
    """(pid, host tag) of the lease ``path``, or None."""
    data = read_private(path)
    match = re.fullmatch(rb"pid ([0-9]+) host ([0-9a-f]{12})\n", data or b"")
    return (int(match.group(1)), match.group(2).decode()) if match else None


def lease_alive(path: Path, timeout: float | None = None) -> bool:
    """Whether the lease ``path`` may belong to a live builder: its process runs on this
    host, or (another host, or unreadable) it is younger than ``timeout``."""
    holder = _lease_holder(path)
    if holder is not None and holder[1] == HOST_TAG:
        return _pid_alive(holder[0])
    try:
        age = time.time() - os.lstat(path).st_mtime
    except OSError:
        return False
    return age < (lock_timeout() if timeout is None else timeout)


@contextlib.contextmanager
def _leased(path: Path, timeout: float) -> Iterator[None]:
    """Serialise builders of one key without ``flock``: the lease file ``path``, created
    with ``O_EXCL`` (never through a link) and holding ``pid N host T``.  A process waits
    while the lease's holder may be alive (:func:`lease_alive`), up to ``timeout``; a lease
    of a dead process is removed.  Afterwards it builds in any case: the lease only saves
    work (builds are private and published by ``rename``), so a lease it cannot take
    never stops it."""
    deadline, delay, owned = time.monotonic() + timeout, 0.002, None
    while owned is None:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC,
                         file_mode())
        except FileExistsError:
            if not lease_alive(path, timeout) and _is_regular(path):
                with contextlib.suppress(OSError):
                    os.unlink(path)  # a dead builder's: at worst two builds at once
                continue
            if time.monotonic() >= deadline:
                break
            time.sleep(delay)
            delay = min(2 * delay, 0.05)
            continue
        except OSError:
            break
        with os.fdopen(fd, "wb") as fh:
            fh.write(f"pid {os.getpid()} host {HOST_TAG}\n".encode())
            owned = os.fstat(fh.fileno())
    try:
        yield
    finally:
        if owned is not None:
            with contextlib.suppress(OSError):
                now = os.lstat(path)
                if (now.st_ino, now.st_dev) == (owned.st_ino, owned.st_dev):
                    os.unlink(path)


def _is_regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


@contextlib.contextmanager
def _held_if_free(path: Path) -> Iterator[bool | None]:
    """Whether the ``flock`` ``path`` was free (then it is held for the block): True, False
    (held by another process, or not openable), or None (no ``flock`` here)."""
    try:
        fd = _open_lock(path)
    except OSError:
        yield False
        return
    try:
        yield _try_flock(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def key_busy(root: Path, key: str) -> Iterator[bool]:
    """Whether a process is building ``key`` in ``root`` right now (its ``flock`` is held,
    or without ``flock`` its lease may be alive); while False, the lock is held here."""
    with _held_if_free(root / "locks" / f"{key}.lock") as free:
        if free is None:
            free = not lease_alive(root / "locks" / f"{key}.lease")
        yield not free
