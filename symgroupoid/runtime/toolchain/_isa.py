"""The vector instruction set a kernel is compiled for.

On x86-64 the compiler's default target is the 2003 instruction set (SSE2).  A kernel compiled
for the wider instruction sets this processor has steps faster with the same bits: the
straight-line arithmetic of the residual and the Jacobian is written in the three-operand
VEX/EVEX forms (fewer register copies), and the compiler's vectorised loops use wider
registers.  No flag chosen here enables fused multiply-adds (``-mavx2`` and ``-mavx512f``
do not imply ``-mfma``), and without ``-ffast-math`` no instruction set changes the order or
the rounding of an operation, so every result keeps its bits: the NumPy twin, and a kernel
built on another processor, compute the same numbers (``tests/test_vector_isa.py``).

Measured (µs per step inside ``simulate``, 3D chain, h = 0.01, one run, the default build
without -> with ``-mavx2``; AVX-512 processor): n = 2 0.54 -> 0.47, n = 4 1.88 -> 1.58,
n = 8 5.50 -> 4.99, n = 16 13.8 -> 12.1 (``-mavx512f``: 11.5), n = 32 65.1 -> 48.7; the
builds take as long.

The choice is part of every cache key (:func:`~._compiler.build_environment`), so a cache
shared by machines of different processors never serves one's kernel to the other, and a
simulator sent to another process (``pickle``, a process pool, Dask) is built there for that
processor.  ``SYMGROUPOID_VECTOR_ISA`` overrides it: ``none`` (the compiler's default
target), ``avx``, ``avx2``, ``avx512f`` or ``auto`` (the default: the widest this processor
has).  Nothing is added when the build's own flags or ``$CFLAGS``/``$CPPFLAGS``/``$CC``
choose a target themselves (``-march=``, ``-mavx…``, ``-mno-avx…``, ``-mfma``, ``-msse…``),
nor on another architecture or with a compiler not known to take these flags (GCC, Clang).
"""

from __future__ import annotations

import functools
import os
import platform
import re
from collections.abc import Sequence
from pathlib import Path

from ..._errors import SymgroupoidError

#: the environment variable that overrides the choice
VECTOR_ISA_ENV = "SYMGROUPOID_VECTOR_ISA"

#: (processor feature in /proc/cpuinfo, compiler flag), widest first
VECTOR_ISAS: tuple[tuple[str, str], ...] = (
    ("avx512f", "-mavx512f"), ("avx2", "-mavx2"), ("avx", "-mavx"))

#: the values of SYMGROUPOID_VECTOR_ISA
CHOICES = ("auto", "none", *(feature for feature, _ in VECTOR_ISAS))

#: words of a build that choose the target themselves (then nothing is added)
OWN_TARGET = ("-march=", "-mavx", "-mno-avx", "-mfma", "-mno-fma", "-msse", "-mno-sse")

#: compilers known to take the flags (by the name of the command or of a word of it)
KNOWN_COMPILERS = re.compile(r"^(.*-)?(gcc|clang|cc)(-[0-9.]+)?$")


class VectorISAError(SymgroupoidError, ValueError):
    """``SYMGROUPOID_VECTOR_ISA`` is not one of its values, or names an instruction set
    this processor does not have (a kernel built for it would stop at its first such
    instruction)."""


@functools.cache
def processor_features() -> frozenset[str]:
    """The instruction-set features of this processor that the operating system enables
    (the ``flags`` line of ``/proc/cpuinfo``); empty elsewhere than on x86-64 Linux."""
    if platform.machine().lower() not in ("x86_64", "amd64"):
        return frozenset()
    try:
        text = Path("/proc/cpuinfo").read_text(encoding="ascii", errors="replace")
    except OSError:
        return frozenset()
    for line in text.splitlines():
        name, _, value = line.partition(":")
        if name.strip() == "flags":
            return frozenset(value.split())
    return frozenset()


def _choice() -> str:
    value = os.environ.get(VECTOR_ISA_ENV, "").strip().lower() or "auto"
    if value not in CHOICES:
        raise VectorISAError(f"{VECTOR_ISA_ENV}={value!r} is not one of {', '.join(CHOICES)}")
    return value


def _known_compiler(command: Sequence[str]) -> bool:
    return any(KNOWN_COMPILERS.match(Path(word).name) for word in command
               if not word.startswith("-"))


def vector_flags(command: Sequence[str], words: Sequence[str],
                 features: frozenset[str] | None = None) -> tuple[str, ...]:
    """The instruction-set flag a build adds (none, or one of :data:`VECTOR_ISAS`): the
    widest this processor has, or the one ``SYMGROUPOID_VECTOR_ISA`` names; nothing when
    ``words`` (the build's flags, ``$CFLAGS`` and ``$CPPFLAGS``) or the compiler ``command``
    choose a target, on another architecture, or with a compiler other than GCC or Clang.
    :class:`VectorISAError` for an unknown value of the variable, or an instruction set
    this processor lacks.  ``features``: the processor's (default
    :func:`processor_features`)."""
    choice = _choice()
    features = processor_features() if features is None else features
    if choice == "none" or not features or not _known_compiler(command):
        return ()
    if any(w.startswith(OWN_TARGET) for w in (*command, *words)):
        return ()
    for feature, flag in VECTOR_ISAS:
        if choice == feature:
            if feature not in features:
                raise VectorISAError(
                    f"{VECTOR_ISA_ENV}={choice} names an instruction set this processor "
                    f"does not have; the kernel would stop at its first such instruction "
                    f"(this processor has: "
                    f"{', '.join(f for f, _ in VECTOR_ISAS if f in features) or 'none'})")
            return (flag,)
        if choice == "auto" and feature in features:
            return (flag,)
    return ()


def missing_instructions(flags: Sequence[str],
                         features: frozenset[str] | None = None) -> list[str]:
    """The instruction-set flags among ``flags`` (of :data:`VECTOR_ISAS`) whose instructions
    this processor (or one of ``features``) lacks, on x86-64 Linux (elsewhere: none can be
    told)."""
    features = processor_features() if features is None else features
    if not features:
        return []
    return [flag for feature, flag in VECTOR_ISAS if flag in flags and feature not in features]
