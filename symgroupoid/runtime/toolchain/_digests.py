"""Digests of the kernel cache: the cache keys' hash, file and type-table hashes, the ABI."""

from __future__ import annotations

import hashlib
import json
import sys
import sysconfig
from collections.abc import Iterable
from pathlib import Path

#: 2: kernels are shared libraries loaded in cffi's ABI mode (1: Python extension modules);
#: 3: the type table is data (``types``), not Python source
FORMAT_VERSION = 3


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
