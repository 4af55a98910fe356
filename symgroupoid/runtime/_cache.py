"""The on-disk kernel cache.

Layout under the cache root (``$SYMGROUPOID_CACHE``, else ``$XDG_CACHE_HOME/symgroupoid``,
else ``~/.cache/symgroupoid``)::

    index/<input key>.json     symbolic inputs → source key (lets a warm load skip codegen)
    kernels/<source key>/      one built kernel: the shared library, its C source and
                               manifest.json with the SHA-256 of the library file and the
                               library's cffi type table (data, with its own SHA-256)
    locks/<source key>.lock    held (``flock``) by the one process building that kernel
    locks/<source key>.lease   the same where the file system has no ``flock`` (``O_EXCL``)
    tmp/                       build directories ``build-<source key>-<pid>-<host>-*``,
                               renamed into kernels/ when complete
    probes/                    the compiler's OpenMP support, once per compiler

The *source key* hashes the generated C, the compiler flags, the build environment
(``$CC``, ``$CPPFLAGS``, ``$CFLAGS``, ``$LDFLAGS``) and the Python/cffi ABI; the *input key*
hashes the symbolic step (SymPy ``srepr``), the code generator and the same ABI, flags and
environment.  A kernel directory appears atomically (``rename`` of a finished directory)
and is verified against its manifest before loading; a damaged one is removed and rebuilt.

What is trusted (the cache holds code this process runs, so it is checked as ssh checks
its keys):

* The root, and each of its directories (``index``, ``kernels``, ``locks``, ``tmp``,
  ``probes``), must belong to this user (or to root) and must not be writable by group or
  others; its directories must not be symbolic links (the root itself may be reached
  through one).  Otherwise the cache is refused with a :class:`CacheError` naming the path,
  the reason and the fix.  Files and directories the cache makes get the umask's mode less
  group and other write permission.
* A kernel directory, its manifest and its library must be of the same owners, not
  writable by others, and no links; the library must be a complete ELF shared object
  (``_build.library_defect``).  Anything else is a bad entry: never loaded, rebuilt.
* No cache file holds Python: the manifest is JSON, the type table plain data (bytes and
  integers) that cffi's ``FFI`` constructor takes; the index and probes hold names and
  booleans.  The kernel templates' compiled code is kept with the package, not here.
* ``SYMGROUPOID_SHARED_CACHE`` names a read-only cache another account provides (a kernel
  cache that account built): it is read after this user's own cache, never written, swept
  or cleared; it is trusted when it and everything read from it belongs to the owner of its
  root (or to root) and nobody else can write it.

Concurrency and failures:

* Processes that miss the same kernel serialise on its lock: one compiles, the others wait
  (up to ``SYMGROUPOID_LOCK_TIMEOUT`` seconds, default 600), re-check the manifest and load.
  The kernel releases an ``flock`` when its holder dies, so a killed builder blocks nobody.
* Where ``flock`` fails (NFS mounted ``nolock``: ENOLCK; Lustre ``noflock``: ENOSYS;
  EOPNOTSUPP), the lock is a lease file created with ``O_EXCL`` holding the builder's pid
  and host: others wait while that process lives (on another host: up to the timeout),
  then build too.  No lock is needed for correctness: every process builds in its own
  directory and publishes it with one ``rename``, keeping an entry another process
  published first.
* A build directory is named after its key, process and host.  It is removed on a later
  use of the cache only when its builder is certainly gone: its key's ``flock`` is free, or
  (without ``flock``) its process no longer runs on this host, or it is older than an hour.
* Only names the cache makes are ever removed (32-hex keys, ``build-``/``trash-``/
  ``probe-`` leftovers, its temporary files), and only after an ``lstat``: a link is
  removed as a link, never followed.
* The root is marked as a kernel cache (``CACHEDIR.TAG``) when it is created, or when
  found empty or holding only a cache layout (the directories above with hash-named
  entries: a cache written before roots were marked); a directory holding anything else
  is never written into, swept or cleared (it is treated as unwritable, below), so a cache
  variable pointed at ``$HOME`` or a project cannot delete a file.
* ``index``, ``kernels``, ``locks`` or ``tmp`` found as a file is removed and recreated (in
  a root marked just now: moved aside as ``<name>.displaced-*``).
  A cache root that cannot be written (read-only, not a directory, ``$HOME`` unwritable)
  is still read, and kernels built by this process go to a private temporary directory
  (one :class:`RuntimeWarning` naming the path and the reason; removed at exit).
* A write that fails (a full disk) is a :class:`CacheError` naming the cache directory.
"""

from __future__ import annotations

import atexit
import contextlib
import errno
import hashlib
import json
import os
import re
import shutil
import socket
import stat
import sys
import sysconfig
import tempfile
import threading
import time
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path

from .._errors import CacheError
from ..codegen._emit import current_umask

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: builds are not serialised
    fcntl = None

MANIFEST = "manifest.json"
#: 2: kernels are shared libraries loaded in cffi's ABI mode (1: Python extension modules);
#: 3: the type table is data (``types``), not Python source
FORMAT_VERSION = 3
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
#: seconds a process waits for another one building the same kernel
LOCK_TIMEOUT = 600.0
#: age (seconds) after which leftovers that name no live process (``build-*`` of other
#: hosts where ``flock`` is missing, ``probe-*``, temporary index files) count as abandoned
GRACE = 3600.0
#: the random part ``tempfile`` gives a name
_RANDOM = r"[a-z0-9_]{8}"
_KEY = re.compile(r"[0-9a-f]{32}")
#: ``tmp/`` leftovers: build and trash directories (of a key, and since format 3 of a
#: process and host), probes
_TMP_ENTRY = re.compile(r"(?P<kind>build|trash)-(?P<name>[0-9a-f]{32}(?:\.json)?)-"
                        r"(?:(?P<pid>[0-9]+)-(?P<host>[0-9a-f]{12})-)?[a-z0-9_]+"
                        r"|(?P<legacy>build-[A-Za-z0-9_.-]+)|probe-" + _RANDOM)
#: a temporary file of an atomic write, or a writability probe (any cache directory)
_TEMPORARY = re.compile(r"\.(?:[0-9a-f]{32}\.json|openmp-[0-9a-f]{32}\.json|" + MARKER
                        + r")\." + _RANDOM + r"|probe-" + _RANDOM)
_MODULE = re.compile(r"_sgk_[0-9a-f]{24}")
_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_STATE_LOCK = threading.Lock()
#: configured cache root → private temporary root used instead (this process only)
_FALLBACKS: dict[Path, Path] = {}
_SWEPT: set[Path] = set()
_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


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


def abi_tag() -> str:
    """What a built kernel depends on besides its source (the interpreter and cffi, which
    wrote its type table; the cache's format)."""
    import cffi

    return "|".join([sys.implementation.cache_tag or "", sysconfig.get_config_var("EXT_SUFFIX")
                     or "", sysconfig.get_platform(), cffi.__version__, str(FORMAT_VERSION)])


def sha256_of(parts: Iterable[str | bytes]) -> str:
    """SHA-256 over a sequence of parts (each length-prefixed, so boundaries matter)."""
    digest = hashlib.sha256()
    for part in parts:
        data = part.encode() if isinstance(part, str) else part
        digest.update(len(data).to_bytes(8, "little"))
        digest.update(data)
    return digest.hexdigest()


def table_sha256(table: dict) -> str:
    """SHA-256 of a type table's canonical JSON text."""
    return sha256_of([json.dumps(table, sort_keys=True, separators=(",", ":"))])


def file_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


# -- modes, trust -------------------------------------------------------------------------------

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


# -- files --------------------------------------------------------------------------------------

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
    try:
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | _CLOEXEC)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        if not stat.S_ISREG(info.st_mode) or distrust(info, owners) is not None:
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
    except ValueError:
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


# -- whose build is it ---------------------------------------------------------------------------

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


# -- locks ------------------------------------------------------------------------------------

def lock_timeout() -> float:
    """Seconds to wait for another process's build (``SYMGROUPOID_LOCK_TIMEOUT``)."""
    text = os.environ.get("SYMGROUPOID_LOCK_TIMEOUT")
    if not text:
        return LOCK_TIMEOUT
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise CacheError(f"SYMGROUPOID_LOCK_TIMEOUT must be a positive number of seconds, "
                         f"got {text!r}")
    return value


def _open_lock(path: Path) -> int:
    """The lock file ``path``, opened (made if missing) without following a link: a link
    there is ``OSError(ELOOP)``, something else than a regular file ``OSError(EINVAL)``."""
    path.parent.mkdir(mode=dir_mode(), parents=True, exist_ok=True)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | _NOFOLLOW | _CLOEXEC, file_mode())
    except PermissionError:  # another user's lock file in a shared cache: locking only
        fd = os.open(path, os.O_RDONLY | _NOFOLLOW | _CLOEXEC)
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


# -- writable root, fallback and sweeping ------------------------------------------------------

class ForeignDirectoryError(OSError):
    """The configured cache root is a directory holding other things than a kernel cache."""


def is_cache_root(root: Path) -> bool:
    """Whether ``root`` carries the cache marker (see :data:`MARKER`)."""
    try:
        fd = os.open(root / MARKER, os.O_RDONLY | _NOFOLLOW | _CLOEXEC)
    except OSError:
        return False
    with os.fdopen(fd, "rb") as fh:
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
    "tmp": re.compile(r"(build|trash|probe)-.*"),
    "probes": re.compile(r"\.?openmp-[0-9a-f]{32}\.json.*"),
    "templates": re.compile(r"__jinja2_[0-9a-f]{40}\.cache.*"),
}


def _foreign_entries(root: Path) -> list[str]:
    """What in ``root`` a kernel cache does not hold (empty: the root is, or can become, a
    cache): names other than the cache's, and entries of its directories that no cache
    writes."""
    try:
        entries = list(os.scandir(root))
    except FileNotFoundError:
        return []
    out = []
    for e in entries:
        if e.name == MARKER:
            continue
        if e.name not in _CACHE_NAMES:
            out.append(e.name)
        elif e.is_dir(follow_symlinks=False):
            try:
                names = os.listdir(e.path)
            except OSError:
                names = []
            out += [f"{e.name}/{n}" for n in names if not _CACHE_CONTENT[e.name].fullmatch(n)]
    return sorted(out)


def _claim(root: Path) -> bool:
    """Mark ``root`` as a kernel cache, unless it holds anything else: then it is never
    written, cleaned or swept (raises :class:`ForeignDirectoryError`).  Whether it was
    unmarked until now."""
    if is_cache_root(root):
        return False
    foreign = _foreign_entries(root)
    if foreign:
        shown = ", ".join(foreign[:3]) + (", …" if len(foreign) > 3 else "")
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


def _caller_stacklevel() -> int:
    """Stack level of the first frame outside this package and ``contextlib`` (warnings)."""
    internal = (str(Path(__file__).resolve().parents[1]), contextlib.__file__)
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_code.co_filename.startswith(internal):
        frame, level = frame.f_back, level + 1
    return level


def _fallback(configured: Path, reason: OSError) -> Path:
    """A private temporary cache root replacing ``configured`` for this process."""
    why = reason.strerror or str(reason)
    if reason.filename and Path(reason.filename) != configured:
        why = f"{why}: {reason.filename}"
    state = "is not used" if isinstance(reason, ForeignDirectoryError) else "is not writable"
    try:
        private = Path(tempfile.mkdtemp(prefix="symgroupoid-cache-"))
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


def _without_others_write(directory: Path) -> None:
    """Take group and other write permission from the files the compiler wrote into the
    build directory ``directory`` (it follows the umask, which may grant them)."""
    for entry in os.scandir(directory):
        info = entry.stat(follow_symlinks=False)
        if stat.S_ISREG(info.st_mode) and info.st_mode & 0o022:
            os.chmod(entry.path, stat.S_IMODE(info.st_mode) & ~0o022)


def entry_defect(entry: Path, source_key: str, owners: frozenset[int] | None = None
                 ) -> tuple[dict | None, str | None]:
    """(manifest, None) for a complete, undamaged, trusted kernel directory, else (None,
    what is wrong with it)."""
    owners = _owners() if owners is None else owners
    try:
        info = os.lstat(entry)
    except OSError:
        return None, "missing"
    reason = distrust(info, owners)
    if reason is not None:
        return None, f"the directory cannot be trusted: {reason}"
    if not stat.S_ISDIR(info.st_mode):
        return None, "not a directory"
    data, problem = _trusted_bytes(entry / MANIFEST, owners)
    if data is None:
        return None, f"the manifest {problem}"
    try:
        manifest = json.loads(data.decode("utf-8"))
    except ValueError:
        return None, "the manifest is not JSON"
    if not isinstance(manifest, dict):
        return None, "the manifest is not a JSON object"
    problem = _manifest_problem(manifest, source_key)
    if problem is not None:
        return None, problem
    data, problem = _trusted_bytes(entry / manifest["library"], owners)
    if data is None:
        return None, f"the library {problem}"
    if hashlib.sha256(data).hexdigest() != manifest.get("sha256"):
        return None, "the library does not match its manifest's SHA-256"
    from ._build import library_defect

    defect = library_defect(data)
    if defect is not None:
        return None, f"the library is damaged: {defect}"
    return manifest, None


def _trusted_bytes(path: Path, owners: frozenset[int]) -> tuple[bytes | None, str | None]:
    """(the bytes of the regular file ``path``, None) when it is trusted, else (None, why
    not): never through a link."""
    try:
        info = os.lstat(path)
    except OSError:
        return None, "is missing"
    reason = distrust(info, owners)
    if reason is not None:
        return None, f"cannot be trusted: {reason}"
    if not stat.S_ISREG(info.st_mode):
        return None, "is not a regular file"
    data = read_private(path, owners)
    return (data, None) if data is not None else (None, "cannot be read")


def _manifest_problem(manifest: dict, source_key: str) -> str | None:
    """What makes a manifest unusable for ``source_key``, or None."""
    if manifest.get("source_key") != source_key:
        return "the manifest is of another kernel"
    module = manifest.get("module")
    if not (isinstance(module, str) and _MODULE.fullmatch(module)
            and module == f"_sgk_{source_key[:24]}" and manifest.get("library") == f"{module}.so"):
        return "the manifest names another library"
    if not (isinstance(manifest.get("prefix"), str) and _C_NAME.fullmatch(manifest["prefix"])):
        return "the manifest's prefix is not a C name"
    table = manifest.get("types")
    if not isinstance(table, dict) or table_sha256(table) != manifest.get("types_sha256"):
        return "the type table is missing or does not match its SHA-256"
    from ._build import TYPE_TABLE_KEYWORDS

    # the shape only (its values are checked when the table is used: ``_build.ffi_of``)
    types = table.get("_types")
    if (table.get("name") != module or set(table) - TYPE_TABLE_KEYWORDS - {"name"}
            or not isinstance(types, dict) or not isinstance(types.get("b64"), str)):
        return "the type table is not cffi's data"
    return None


def _verified(entry: Path, source_key: str, owners: frozenset[int] | None = None
              ) -> dict | None:
    return entry_defect(entry, source_key, owners)[0]
