"""The C sources of the Newton stepper library, and their text with a kernel's prefix.

The library (``stepper.h``, ``prologue.h``, ``options.h``, ``stepper.c``, ``batch.c`` in this
directory) is real C: every name goes through the prefix macros of ``sg_prefix.h``
(``SG_NAME(simulate)`` is ``<prefix>_simulate``, ``SG_OK`` the kernel's ``<PREFIX>_OK``), so
it compiles on its own for any prefix (``cc -DSG_PREFIX=toy -DSG_PREFIX_UPPER=TOY ...``).  A
generated kernel holds the library's text instead, with the names spelt out as the
preprocessor would spell them (:func:`spelt`), so that it stays one self-contained file that
reads like plain C.  :class:`Inliner` writes the files into one translation unit as the
preprocessor would include them: a file's own opening comment and include guard are left
out, ``sg_prefix.h`` is left out (the names are spelt out), and a library file included
(``#include "options.h"``) is written in its place the first time and left out after that.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

#: the library's files (``sg_prefix.h``: the prefix macros, never part of a kernel)
SOURCES = ("sg_prefix.h", "stepper.h", "prologue.h", "options.h", "stepper.c", "batch.c")
#: the macros of ``sg_prefix.h``, which spelt text never holds
_MACHINERY = re.compile(r"\bSG_(?:CAT_?|PREFIX(?:_UPPER|_H)?)\b")
_NAME = re.compile(r"\bSG_NAME\((\w+)\)")
_MACRO = re.compile(r"\bSG_(\w+)")
_INCLUDE = re.compile(r'#include "([\w.]+)"\n')
#: more than one blank line (where an included file's text meets its includer's)
_BLANK_LINES = re.compile(r"\n{3,}")


def library_dir() -> Path:
    """The directory of the library's C sources (installed with the package)."""
    return Path(__file__).resolve().parent


def library_source(name: str) -> str:
    """The text of the library file ``name`` (one of :data:`SOURCES`)."""
    if name not in SOURCES:
        raise ValueError(f"{name!r} is not a file of the stepper library {SOURCES}")
    return (library_dir() / name).read_text(encoding="ascii")


def library_digest() -> str:
    """SHA-256 over the library's files and this module (what a kernel's C depends on)."""
    digest = hashlib.sha256()
    for name in SOURCES:
        digest.update(name.encode())
        digest.update((library_dir() / name).read_bytes())
    digest.update(Path(__file__).read_bytes())
    return digest.hexdigest()


def spelt(text: str, prefix: str) -> str:
    """``text`` with the prefix macros spelt out for the kernel ``prefix``: ``SG_NAME(x)``
    → ``<prefix>_x``, ``SG_X`` → ``<PREFIX>_X`` (what the preprocessor makes of them with
    ``SG_PREFIX=<prefix>``, ``SG_PREFIX_UPPER=<PREFIX>``)."""
    if _MACHINERY.search(text):
        raise ValueError(f"library text uses the prefix machinery itself: "
                         f"{_MACHINERY.search(text).group(0)}")
    text = _NAME.sub(lambda m: f"{prefix}_{m.group(1)}", text)
    return _MACRO.sub(lambda m: f"{prefix.upper()}_{m.group(1)}", text)


def _body(name: str) -> str:
    """The text of ``name`` without its opening comment and include guard."""
    text = library_source(name)
    if text.startswith("/*"):
        text = text[text.index("*/\n") + 3:]
    if name.endswith(".h"):
        guard = "SG_" + re.sub(r"\W", "_", name[:-2]).upper() + "_H"
        opening = f"#ifndef {guard}\n#define {guard}\n"
        closing = f"#endif /* {guard} */\n"
        if opening not in text or not text.endswith(closing):
            raise ValueError(f"{name}: the library header has no include guard {guard}")
        text = text.replace(opening, "", 1)[:-len(closing)]
    return text


class Inliner:
    """The library's files written into one translation unit of the kernel ``prefix``,
    each at most once (as their include guards make the preprocessor include them).

    ``provided``: the files the unit has already (a kernel's units include its header,
    which holds ``stepper.h``)."""

    def __init__(self, prefix: str, provided: tuple[str, ...] = ("stepper.h",)):
        self.prefix = prefix
        self.seen = {"sg_prefix.h", *provided}

    def text(self, name: str) -> str:
        """The spelt text of ``name`` and of the library files it includes, each written
        where it is first included (empty when the unit has ``name`` already), without blank
        lines at either end."""
        return spelt(self._inline(name), self.prefix)

    def _inline(self, name: str) -> str:
        if name in self.seen:
            return ""
        self.seen.add(name)
        body = _body(name)
        parts, at = [], 0
        for m in _INCLUDE.finditer(body):
            parts.append(body[at:m.start()])
            included = self._inline(m.group(1))
            parts.append(included + "\n" if included else "")
            at = m.end()
        parts.append(body[at:])
        text = _BLANK_LINES.sub("\n\n", "".join(parts)).strip("\n")
        return text + "\n" if text else ""


__all__ = ["Inliner", "SOURCES", "library_digest", "library_dir", "library_source", "spelt"]
