"""A built kernel library: checked before it is mapped (a complete ELF shared object), then
loaded with cffi in ABI mode."""

from __future__ import annotations

import json
import os
import struct
import sys
import types
from pathlib import Path

from ._type_table import ffi_of

_ELF_MAGIC = b"\x7fELF"


#: (ELF header after e_ident, program header, section header) of ELFCLASS32 and ELFCLASS64
_ELF_LAYOUTS = {1: ("HHIIIIIHHHHHH", "IIIIIIII", "IIIIIIIIII"),
                2: ("HHIQQQIHHHHHH", "IIQQQQQQ", "IIQQQQIIQQ")}


_ET_DYN, _PT_LOAD, _SHT_NOBITS = 3, 1, 8


def library_defect(data: bytes) -> str | None:
    """What makes ``data`` (a kernel library's bytes) unfit to load, or None.

    On ELF systems: it must be an ELF shared object (``ET_DYN``) whose program header
    table, loaded segments (``PT_LOAD``: what ``dlopen`` maps), section header table and
    sections lie inside the file.  Mapping a segment that extends past the end of a
    truncated file kills the process with SIGBUS on first access, so this is checked
    before a library is installed or loaded.  Elsewhere (macOS, Windows): only that it is
    not empty.  About 20 µs.
    """
    if sys.platform == "darwin" or os.name == "nt":
        return None if data else "the file is empty"
    size = len(data)
    if size < 52 or data[:4] != _ELF_MAGIC:
        return f"not an ELF shared object ({size} bytes)"
    layout, order = _ELF_LAYOUTS.get(data[4]), {1: "<", 2: ">"}.get(data[5])
    if layout is None or order is None:
        return "an ELF file of unknown class or byte order"
    header, program, section = (struct.Struct(order + f) for f in layout)
    if size < 16 + header.size:
        return f"the ELF header is cut off ({size} bytes)"
    (e_type, _, _, _, phoff, shoff, _, _, phentsize, phnum, shentsize, shnum,
     _) = header.unpack_from(data, 16)
    if e_type != _ET_DYN:
        return f"an ELF file of type {e_type}, not a shared object"
    if phnum == 0 or phentsize < program.size or phoff + phnum * phentsize > size:
        return f"its program header table lies outside the file ({size} bytes)"
    for i in range(phnum):
        entry = program.unpack_from(data, phoff + i * phentsize)
        p_type, p_offset, p_filesz = ((entry[0], entry[1], entry[4]) if data[4] == 1
                                      else (entry[0], entry[2], entry[5]))
        if p_type == _PT_LOAD and p_offset + p_filesz > size:
            return (f"a loaded segment ends at byte {p_offset + p_filesz}, past the end of "
                    f"the file ({size} bytes): it is truncated")
    if shnum and (shentsize < section.size or shoff + shnum * shentsize > size):
        return (f"its section header table ends at byte {shoff + shnum * shentsize}, past "
                f"the end of the file ({size} bytes): it is truncated")
    for i in range(shnum):
        entry = section.unpack_from(data, shoff + i * shentsize)
        sh_type, sh_offset, sh_size = entry[1], entry[4], entry[5]
        if sh_type != _SHT_NOBITS and sh_offset + sh_size > size:
            return (f"a section ends at byte {sh_offset + sh_size}, past the end of the file "
                    f"({size} bytes): it is truncated")
    return None


def load_extension(path: Path, name: str, table: dict | None = None
                   ) -> types.SimpleNamespace:
    """Load the kernel library ``path``: a namespace with its ``ffi`` and ``lib`` (the
    entry points and constants of ``cdef.j2``).

    ``table``: the type table :func:`build_extension` returned; default: the ``types`` of
    the manifest of the cache entry holding ``path``.  The library is checked
    (:func:`library_defect`) before it is mapped.  Raises ``ImportError`` or ``OSError``
    when the library or its type table cannot be loaded.
    """
    if table is None:
        table = _manifest_types(Path(path))
    ffi = ffi_of(table, name)
    try:
        with open(path, "rb", opener=_nofollow) as fh:
            defect = library_defect(fh.read())
    except OSError as exc:
        raise ImportError(f"cannot read the kernel library {path}: {exc}") from exc
    if defect is not None:
        raise ImportError(f"the kernel library {path} is damaged: {defect}")
    try:
        lib = ffi.dlopen(str(path))
    except UnicodeEncodeError as exc:  # a cache root of bytes that are not UTF-8
        raise ImportError(f"the kernel library {path!r} cannot be loaded: its path is not "
                          f"valid UTF-8") from exc
    for symbol in dir(lib):  # every entry point and constant it declares: resolved now
        try:
            getattr(lib, symbol)
        except (ffi.error, AttributeError, NotImplementedError) as exc:  # (a bad opcode)
            ffi.dlclose(lib)  # or a rebuilt library at this path would get this one again
            raise ImportError(f"the kernel library {path} lacks {symbol!r}, which its type "
                              f"table declares: it is not the library built for it "
                              f"({exc})") from exc
    return types.SimpleNamespace(__name__=name, __file__=str(path), ffi=ffi, lib=lib)


def _nofollow(path: str, flags: int) -> int:
    """``open``'s opener that never follows a link at the last component."""
    return os.open(path, flags | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))


def _manifest_types(path: Path) -> dict:
    """The type table recorded in the manifest next to the library ``path``."""
    try:
        with open(path.parent / "manifest.json", encoding="utf-8", opener=_nofollow) as fh:
            table = json.load(fh)["types"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError) as exc:
        raise ImportError(f"no cffi type table for {path} in its manifest: {exc}") from exc
    if not isinstance(table, dict):
        raise ImportError(f"no cffi type table for {path} in its manifest")
    return table
