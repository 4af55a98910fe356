"""A step's kernel: its C (``generate_c`` at the step's flags), and its cache keys (the input
key of the symbolic step, the source key of the generated C)."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import sympy as sp

from ...codegen import KernelSource, generate_c, templates_digest
from ._compiler import build_environment
from ._digests import abi_tag, sha256_of
from ._flags import block_weight, optimisation_flags, stepper_unit, translation_units
from ._kernel_cache import KernelCache
from ._openmp import OPENMP_FLAG, _compiler_identity, default_flags

#: the toolchain's modules that decide how a kernel is built (see :func:`codegen_sources`)
BUILD_SOURCES = ("_cffi_build.py", "_compiler.py", "_flags.py", "_step_kernel.py")


def codegen_sources() -> list[Path]:
    """The package sources that decide a kernel's C and how it is built: the code generator,
    the expression graph, and the toolchain's :data:`BUILD_SOURCES`: this module
    (:func:`step_kernel`'s options), the flags (the translation units; the per-unit flags,
    e.g. the cold unit's level, are not all part of a cache key's flags), the compiler's
    command lines and the build of the units."""
    here = Path(__file__).resolve().parent
    package = here.parents[1]
    return sorted([*(package / "codegen").glob("*.py"), *(package / "ir").glob("*.py"),
                   *(here / name for name in BUILD_SOURCES)])


@functools.cache
def codegen_digest() -> str:
    """Hash of everything that turns a step into a built kernel: templates and
    :func:`codegen_sources`."""
    from ..._version import __version__

    return sha256_of([__version__, templates_digest(),
                      *(f.read_bytes() for f in codegen_sources())])


def step_operations(step) -> int:
    """The operations of a step's hot code, which decide its optimisation level: the
    program's outputs but the residual's scale (``F_scale``, evaluated only when a rounding
    floor is tested, and compiled in the cold unit)."""
    program = step.program
    return program.size([name for name in program.outputs if name != "F_scale"])


def step_flags(step, cache_dir) -> tuple[str, ...]:
    """:func:`default_flags`; without a compiler, the default build of ``step`` that is in
    the cache (with OpenMP or without), which needs no compiler to load."""
    base = optimisation_flags(step_operations(step), step=True)
    if _compiler_identity() is not None:
        return default_flags(cache_dir, step_operations(step), step=True)
    cache = KernelCache(Path(cache_dir) if cache_dir is not None else None)
    for flags in ((*base, OPENMP_FLAG), tuple(base)):
        source_key = cache.lookup(input_key(step, flags))
        if source_key and cache.verified_manifest(source_key) is not None:
            return flags
    return tuple(base)


def _atom_token(node, symbols: dict) -> str:
    if isinstance(node, sp.Symbol):
        if node not in symbols:
            assumptions = sorted((k, v) for k, v in node.assumptions0.items())
            extra = f":{node.dummy_index}" if isinstance(node, sp.Dummy) else ""
            symbols[node] = f"{type(node).__name__}:{node.name}{extra}:{assumptions}"
        return symbols[node]
    if isinstance(node, sp.Float):
        return f"Float:{node._mpf_}:{node._prec}"
    if isinstance(node, sp.Rational):
        return f"Rational:{node.p}/{node.q}"
    return sp.srepr(node)


def fingerprint(exprs, symbols: dict | None = None) -> str:
    """An exact, injective text of expressions: their trees in preorder (type and arity of
    every node, exact atoms).  SymPy keeps ``Add``/``Mul`` arguments in canonical order, so
    equal expressions give equal text in every process; it is much cheaper than ``srepr``.
    """
    symbols = {} if symbols is None else symbols
    out: list[str] = []
    stack = list(reversed([sp.sympify(e) for e in exprs]))
    while stack:
        node = stack.pop()
        if node.args:
            out.append(f"({type(node).__name__}/{len(node.args)}")
            stack.extend(reversed(node.args))
        else:
            out.append(_atom_token(node, symbols))
    return " ".join(out)


def input_key(step, flags: Sequence[str], block_units: bool = True) -> str:
    """Cache key of the step (cheap: the exact text of its program, no C generation) built
    at ``flags`` in this build environment (:func:`~._compiler.build_environment`), with block
    units or without (:func:`step_kernel`)."""
    symbols: dict = {}
    parts = [step.name, str(step.n_constraints), step.program.fingerprint()]
    for seq in (step.unknowns, step.knowns, step.parameters):
        parts.append(fingerprint(list(seq), symbols))
    units = "block units" if block_units else "no block units"
    return sha256_of([*parts, codegen_digest(), abi_tag(), units, *build_environment(),
                      "flags", *flags])[:32]


def step_kernel(step, cache: KernelCache | None = None, flags: Sequence[str] | None = None,
                block_units: bool = True) -> KernelSource:
    """The C that :func:`compile_step` builds for ``step`` at ``flags`` (default: the
    step's :func:`~._flags.optimisation_flags`): :func:`generate_c` without the residuals'
    LaTeX in its opening comment (which needs the SymPy residuals; a compiled kernel never
    shows it, and :func:`emit_c` writes it); a large kernel's functions in
    :func:`~._flags.translation_units` files compiled at the same time; with
    ``block_units`` (a build at the library's default flags), the units of straight-line
    arithmetic are block units (``KernelSource.blocks``), balanced for their level
    (:func:`~._flags.block_weight`), and a large kernel's stepper is a unit of its own
    (:func:`~._flags.stepper_unit`).  The templates' compiled code (Python) comes from the
    package (``templates/__pycache__``, ``symgroupoid cache templates``), never from the
    kernel cache (which holds no Python): where the package has none, the templates are
    compiled in this process (0.045 s, once); ``cache`` is not used."""
    del cache
    if flags is None:
        flags = optimisation_flags(step_operations(step), step=True)
    return generate_c(step, latex=False, units=translation_units(),
                      block_weight=block_weight(flags) if block_units else None,
                      stepper_unit=block_units and stepper_unit(flags, len(step.unknowns)))


def source_key_of(kernel: KernelSource, flags: Sequence[str]) -> str:
    """Cache key of a generated kernel: its header, source, further translation units (and
    which are cold and which block units) and cdef, the ABI, the build environment
    (:func:`~._compiler.build_environment`: ``$CC``, ``$CPPFLAGS``, ``$CFLAGS``,
    ``$LDFLAGS``) and the flags."""
    units = [part for unit in kernel.units for part in unit]
    return sha256_of([kernel.header, kernel.source, str(len(units)), *units,
                      str(len(kernel.cold)), *kernel.cold, str(len(kernel.blocks)),
                      *kernel.blocks, str(len(kernel.stepper)), *kernel.stepper,
                      kernel.cdef, abi_tag(), *build_environment(),
                      "flags", *flags])[:32]
