"""The on-disk kernel cache.

Layout under the cache root (``$SYMGROUPOID_CACHE``, else ``$XDG_CACHE_HOME/symgroupoid``,
else ``~/.cache/symgroupoid``)::

    index/<input key>.json     symbolic inputs → source key (lets a warm load skip codegen)
    kernels/<source key>/      one built kernel: the extension module, its C source and
                               manifest.json with the SHA-256 of the module file
    tmp/                       private build directories, renamed into kernels/ when complete

The *source key* hashes the generated C, the compiler flags and the Python/cffi ABI; the
*input key* hashes the symbolic step (SymPy ``srepr``), the code generator and the same ABI
and flags.  A kernel directory appears atomically (``rename`` of a finished directory) and is
verified against its manifest before loading; a damaged one is removed and rebuilt.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import sysconfig
import tempfile
from collections.abc import Iterable
from pathlib import Path

MANIFEST = "manifest.json"
FORMAT_VERSION = 1


def cache_root() -> Path:
    """The cache directory (not created)."""
    override = os.environ.get("SYMGROUPOID_CACHE")
    if override:
        return Path(override).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "symgroupoid"


def abi_tag() -> str:
    """What a built extension module depends on besides its source."""
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
    """Write JSON through a temporary file in the same directory and an atomic rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            json.dump(data, fh, sort_keys=True, indent=1)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def read_json(path: Path) -> dict | None:
    """The JSON object in ``path``, or None when missing or unreadable."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def remove_tree(path: Path) -> None:
    """Remove a directory without ever exposing a half-deleted kernel under its name."""
    if not path.exists():
        return
    trash = path.parent.parent / "tmp" / f"trash-{path.name}-{os.getpid()}"
    try:
        trash.parent.mkdir(parents=True, exist_ok=True)
        os.replace(path, trash)
    except OSError:
        trash = path
    shutil.rmtree(trash, ignore_errors=True)


class KernelCache:
    """Index and kernel directories under a cache root."""

    def __init__(self, root: Path | None = None):
        self.root = Path(root) if root is not None else cache_root()

    @property
    def index_dir(self) -> Path:
        return self.root / "index"

    @property
    def kernels_dir(self) -> Path:
        return self.root / "kernels"

    @property
    def tmp_dir(self) -> Path:
        return self.root / "tmp"

    def lookup(self, input_key: str) -> str | None:
        """Source key recorded for an input key, if any."""
        data = read_json(self.index_dir / f"{input_key}.json")
        key = data.get("source_key") if data else None
        return key if isinstance(key, str) else None

    def record(self, input_key: str, source_key: str, prefix: str) -> None:
        write_json_atomic(self.index_dir / f"{input_key}.json",
                          {"source_key": source_key, "prefix": prefix})

    def entry(self, source_key: str) -> Path:
        return self.kernels_dir / source_key

    def verified_manifest(self, source_key: str) -> dict | None:
        """The manifest of a complete, undamaged kernel directory; None otherwise."""
        entry = self.entry(source_key)
        manifest = read_json(entry / MANIFEST)
        if not manifest or manifest.get("source_key") != source_key:
            return None
        library = entry / str(manifest.get("library", ""))
        try:
            if not library.is_file() or file_sha256(library) != manifest.get("sha256"):
                return None
        except OSError:
            return None
        return manifest

    def new_build_dir(self) -> Path:
        self.tmp_dir.mkdir(parents=True, exist_ok=True)
        return Path(tempfile.mkdtemp(prefix="build-", dir=self.tmp_dir))

    def install(self, build_dir: Path, source_key: str) -> None:
        """Move a finished build directory into place (atomic; first writer wins)."""
        self.kernels_dir.mkdir(parents=True, exist_ok=True)
        target = self.entry(source_key)
        try:
            os.rename(build_dir, target)
        except OSError:
            # another process installed the same kernel first (or a damaged copy is in
            # the way: the caller verifies and, if needed, removes it and retries)
            shutil.rmtree(build_dir, ignore_errors=True)
