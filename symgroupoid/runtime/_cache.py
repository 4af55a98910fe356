"""The on-disk kernel cache.

Layout under the cache root (``$SYMGROUPOID_CACHE``, else ``$XDG_CACHE_HOME/symgroupoid``,
else ``~/.cache/symgroupoid``)::

    index/<input key>.json     symbolic inputs → source key (lets a warm load skip codegen)
    kernels/<source key>/      one built kernel: the shared library, its C source and
                               manifest.json with the SHA-256 of the library file and the
                               library's cffi type table (with its own SHA-256)
    locks/<source key>.lock    held (``flock``) by the one process building that kernel
    tmp/                       build directories ``build-<source key>-*``, renamed into
                               kernels/ when complete
    probes/                    the compiler's OpenMP support, once per compiler
    templates/                 the kernel templates' compiled code (jinja2 bytecode)

The *source key* hashes the generated C, the compiler flags and the Python/cffi ABI; the
*input key* hashes the symbolic step (SymPy ``srepr``), the code generator and the same ABI
and flags.  A kernel directory appears atomically (``rename`` of a finished directory) and is
verified against its manifest before loading; a damaged one is removed and rebuilt.

Concurrency and failures:

* Processes that miss the same kernel serialise on its lock: one compiles, the others wait
  (up to ``SYMGROUPOID_LOCK_TIMEOUT`` seconds, default 600), re-check the manifest and load.
  The kernel releases an ``flock`` when its holder dies, so a killed builder blocks nobody.
* A build directory is only ever written while its key's lock is held, so one whose lock
  is free belongs to a dead process: it is removed on the next use of the cache.
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
import sys
import sysconfig
import tempfile
import threading
import time
import warnings
from collections.abc import Iterable, Iterator
from pathlib import Path

from .._errors import CacheError
from ..codegen._emit import current_umask, write_atomic

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: builds are not serialised
    fcntl = None

MANIFEST = "manifest.json"
#: 2: kernels are shared libraries loaded in cffi's ABI mode (1: Python extension modules)
FORMAT_VERSION = 2
SUBDIRS = ("index", "kernels", "locks", "tmp")
#: the file that marks a directory as a kernel cache (the Cache Directory Tagging
#: convention, so backup tools skip it); only a marked root is ever cleaned or swept
MARKER = "CACHEDIR.TAG"
_SIGNATURE = "Signature: 8a477f597d28d172789f06886806bc55"
_MARKER_TEXT = (f"{_SIGNATURE}\n# This directory is a symgroupoid kernel cache: compiled "
                f"kernels, rebuilt on demand.\n# It can be removed at any time.\n")
#: what a cache root holds besides the marker (a root holding only these is adopted)
_CACHE_NAMES = frozenset(SUBDIRS) | {"probes", "templates"}
#: seconds a process waits for another one building the same kernel
LOCK_TIMEOUT = 600.0
#: age (seconds) after which leftovers that name no kernel (``build-*`` of older versions,
#: ``probe-*``, temporary index files) count as abandoned
GRACE = 3600.0
_KEYED = re.compile(r"(?:build|trash)-([0-9a-f]{32})-")
_STATE_LOCK = threading.Lock()
#: configured cache root → private temporary root used instead (this process only)
_FALLBACKS: dict[Path, Path] = {}
_SWEPT: set[Path] = set()


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


def file_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def write_json_atomic(path: Path, data: dict) -> None:
    """Write JSON (ASCII) through a temporary file in the same directory and an atomic
    rename; the file's mode follows the umask."""
    write_atomic(path, json.dumps(data, sort_keys=True, indent=1))


def read_json(path: Path) -> dict | None:
    """The JSON object in ``path``, or None when missing or unreadable."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _remove(path: Path) -> None:
    """Remove a file, symlink or directory tree (best effort; missing is fine)."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            path.unlink()


def remove_tree(path: Path) -> None:
    """Remove a kernel directory (or whatever occupies its name) without ever exposing a
    half-deleted kernel under its name: it is first renamed into ``tmp/``."""
    if not (path.exists() or path.is_symlink()):
        return
    trash = None
    try:
        tmp = path.parent.parent / "tmp"
        tmp.mkdir(parents=True, exist_ok=True)
        trash = Path(tempfile.mkdtemp(prefix=f"trash-{path.name}-", dir=tmp))
        os.replace(path, trash / "entry")
    except OSError:
        _remove(path)
    if trash is not None:
        _remove(trash)


def dir_mode() -> int:
    """Mode of a new directory under the current umask (0755 under 022)."""
    return 0o777 & ~current_umask()


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
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except PermissionError:  # another user's lock file in a shared cache: locking only
        return os.open(path, os.O_RDONLY)


def _try_flock(fd: int) -> bool:
    """Take the exclusive lock without waiting.  Where the file system has no ``flock``
    (some network file systems) the build proceeds unserialised: still safe, since a
    kernel is installed by one atomic rename."""
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EACCES):
            return False
        return True
    return True


def _note_owner(fd: int) -> None:
    """Record who holds the lock (read only for the timeout message)."""
    with contextlib.suppress(OSError, AttributeError):
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode(), 0)


@contextlib.contextmanager
def exclusive(path: Path, what: str) -> Iterator[None]:
    """Hold the exclusive lock ``path`` (waiting for its holder up to :func:`lock_timeout`)."""
    timeout = lock_timeout()
    try:
        fd = _open_lock(path)
    except OSError as exc:
        raise CacheError(f"{what}: cannot open the lock file {path} ({exc}); remove it or set "
                         f"SYMGROUPOID_CACHE to a writable directory") from exc
    try:
        deadline, delay = time.monotonic() + timeout, 0.002
        while not _try_flock(fd):
            if time.monotonic() >= deadline:
                owner = path.read_text(errors="replace").strip() if path.is_file() else ""
                raise CacheError(
                    f"{what}: waited {timeout:g} s for the lock {path}, held by another process "
                    f"building the same kernel ({owner or 'owner unknown'}); if that process "
                    f"hangs, stop it, or raise SYMGROUPOID_LOCK_TIMEOUT")
            time.sleep(delay)
            delay = min(2 * delay, 0.05)
        _note_owner(fd)
        yield
    finally:
        os.close(fd)  # releases the lock


@contextlib.contextmanager
def _held_if_free(path: Path) -> Iterator[bool]:
    """Whether the lock ``path`` was free (then it is held for the block)."""
    try:
        fd = _open_lock(path)
    except OSError:
        yield False
        return
    try:
        yield fcntl is not None and _try_flock(fd)
    finally:
        os.close(fd)


# -- writable root, fallback and sweeping ------------------------------------------------------

class ForeignDirectoryError(OSError):
    """The configured cache root is a directory holding other things than a kernel cache."""


def is_cache_root(root: Path) -> bool:
    """Whether ``root`` carries the cache marker (see :data:`MARKER`)."""
    try:
        with open(root / MARKER, encoding="ascii", errors="replace") as fh:
            return fh.read(len(_SIGNATURE)) == _SIGNATURE
    except OSError:
        return False


#: what each directory of a cache holds (an unmarked root is adopted only if its
#: directories hold nothing else: a cache layout written before roots were marked)
_CACHE_CONTENT = {
    "index": re.compile(r"\.?[0-9a-f]{32}\.json.*"),
    "kernels": re.compile(r"[0-9a-f]{32}"),
    "locks": re.compile(r"[0-9a-f]{32}\.lock"),
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
    write_atomic(root / MARKER, _MARKER_TEXT)
    return True


def _prepare(root: Path) -> None:
    """Create the cache layout under ``root`` and check that it is writable (raises OSError).

    The root is marked as a kernel cache first (:func:`_claim`; a directory holding other
    files raises :class:`ForeignDirectoryError` and is left untouched).  A subdirectory
    found as a file (or a dangling link) is removed and recreated — or, in a root marked
    just now (whose files may not be the cache's), moved aside as ``<name>.displaced-*``.
    """
    if root.exists() and not root.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, "it is not a directory", str(root))
    root.mkdir(parents=True, exist_ok=True)
    adopted = _claim(root)
    for name in SUBDIRS:
        path = root / name
        if not path.is_dir():
            if path.exists() or path.is_symlink():
                if adopted:
                    os.replace(path, root / f"{name}.displaced-{os.getpid()}-{time.time_ns()}")
                else:
                    with contextlib.suppress(FileNotFoundError):
                        path.unlink()
            path.mkdir(exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix="probe-", dir=path)
        os.close(fd)
        os.unlink(probe)


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
    """Whether ``root`` is (now) a writable kernel cache: :func:`_prepare` without the
    fallback, for optional writes such as probe results."""
    with _STATE_LOCK:
        if root in _FALLBACKS:
            return False
        try:
            _prepare(root)
        except OSError:
            return False
        return True


def writable_root(configured: Path) -> Path:
    """``configured``, prepared for writing, or this process's private fallback for it."""
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


def sweep(root: Path) -> None:
    """Remove what dead processes left in ``root/tmp`` (best effort, never blocks).

    ``build-<key>-*``/``trash-<key>-*`` directories are removed while holding their key's
    lock, which a live builder holds for as long as its directory exists; other leftovers
    (no key: older versions, probes, temporary index files) once older than ``GRACE``.
    Only a marked cache root (:func:`is_cache_root`) is swept.
    """
    if not is_cache_root(root):
        return
    now = time.time()
    for sub in ("tmp", "index"):
        try:
            entries = list(os.scandir(root / sub))
        except OSError:
            continue
        for entry in entries:
            path = Path(entry.path)
            match = _KEYED.match(entry.name) if sub == "tmp" else None
            if match:
                with _held_if_free(root / "locks" / f"{match.group(1)}.lock") as free:
                    if free:
                        _remove(path)
            elif entry.name.startswith(("build-", "trash-", "probe-", ".")):
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

    Reads look in this process's private fallback (if the root turned out unwritable) and
    in the configured root; writes go to :meth:`write_root`.
    """

    def __init__(self, root: Path | None = None):
        self.root = absolute_root(root) if root is not None else cache_root()
        self._located: dict[str, Path] = {}

    def read_roots(self) -> tuple[Path, ...]:
        fallback = _FALLBACKS.get(self.root)
        return (fallback, self.root) if fallback is not None else (self.root,)

    def write_root(self) -> Path:
        """The root new entries go to (created; may warn and fall back, see module doc)."""
        return writable_root(self.root)

    def lookup(self, input_key: str) -> str | None:
        """Source key recorded for an input key, if any."""
        sweep_once(self.root)
        for root in self.read_roots():
            data = read_json(root / "index" / f"{input_key}.json")
            key = data.get("source_key") if data else None
            if isinstance(key, str):
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
        """The manifest of a complete, undamaged kernel directory; None otherwise."""
        for root in self.read_roots():
            entry = root / "kernels" / source_key
            manifest = _verified(entry, source_key)
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

    def discard(self, source_key: str) -> None:
        """Remove the writable root's entry of ``source_key`` (hold its lock)."""
        self._located.pop(source_key, None)
        remove_tree(self.write_root() / "kernels" / source_key)

    def new_build_dir(self, source_key: str) -> Path:
        """A fresh ``tmp/build-<source key>-*`` directory (hold the key's lock)."""
        tmp = self.write_root() / "tmp"
        tmp.mkdir(parents=True, exist_ok=True)
        path = Path(tempfile.mkdtemp(prefix=f"build-{source_key}-", dir=tmp))
        os.chmod(path, dir_mode())
        return path

    def install(self, build_dir: Path, source_key: str) -> Path:
        """Move a finished build directory into place (atomic; hold the key's lock)."""
        target = self.write_root() / "kernels" / source_key
        target.parent.mkdir(parents=True, exist_ok=True)
        try:
            os.rename(build_dir, target)
        except OSError:
            # something is in the way (e.g. a damaged entry another user owns): the caller
            # verifies the entry and reports it
            shutil.rmtree(build_dir, ignore_errors=True)
        return target


def _verified(entry: Path, source_key: str) -> dict | None:
    manifest = read_json(entry / MANIFEST)
    if not manifest or manifest.get("source_key") != source_key:
        return None
    ffi = manifest.get("ffi")
    if not isinstance(ffi, str) or sha256_of([ffi]) != manifest.get("ffi_sha256"):
        return None
    library = entry / str(manifest.get("library", ""))
    try:
        if not library.is_file() or file_sha256(library) != manifest.get("sha256"):
            return None
    except OSError:
        return None
    return manifest
