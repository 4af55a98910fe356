"""Verifying a kernel directory before it is loaded: trusted owners and modes, a manifest of
this key, a library matching its SHA-256 and complete, a type table of cffi's data."""

from __future__ import annotations

import hashlib
import json
import os
import re
import stat
from pathlib import Path

from ._atomic import read_private
from ._digests import table_sha256
from ._library import library_defect
from ._roots import MANIFEST
from ._trust import _owners, distrust
from ._type_table import TYPE_TABLE_KEYWORDS

_MODULE = re.compile(r"_sgk_[0-9a-f]{24}")


_C_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


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
    except RecursionError:
        return None, "the manifest is nested beyond any manifest's depth"
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
    # the shape only (its values are checked when the table is used: ``_type_table.ffi_of``)
    types = table.get("_types")
    if (table.get("name") != module or set(table) - TYPE_TABLE_KEYWORDS - {"name"}
            or not isinstance(types, dict) or not isinstance(types.get("b64"), str)):
        return "the type table is not cffi's data"
    return None


def _verified(entry: Path, source_key: str, owners: frozenset[int] | None = None
              ) -> dict | None:
    return entry_defect(entry, source_key, owners)[0]
