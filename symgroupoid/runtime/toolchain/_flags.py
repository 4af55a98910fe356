"""The compiler flags of a kernel: optimisation levels by size, per translation unit (cold and
block units), and how many units a kernel is spread over."""

from __future__ import annotations

import os
from collections.abc import Sequence

#: flags appended to the compiler command line (after Python's own CFLAGS, so they decide the
#: optimisation level).  -ffp-contract=off keeps a*b+c as two roundings, as in the NumPy backend.
DEFAULT_FLAGS: tuple[str, ...] = ("-O3", "-ffp-contract=off")


#: a program of more operations than this is compiled at -O2 instead of -O3: as fast to run
#: (measured: the planar 32-link chain's step, 3.16e5 against 3.10e5 instructions), and
#: compiled faster (the 64-link chain's 1 MB kernel: 21.9 s against 25.6 s of CPU)
LARGE_PROGRAM = 15_000


#: a step kernel (Newton stepper and its functions) of at most this many operations is
#: compiled at :data:`SMALL_STEP_LEVEL` instead of -O3: in half to three quarters of the
#: compiler's time, and up to 4000 operations as fast to step.  Measured per build (CPU
#: seconds of the stepper unit, -O3 -> small-step level; machine instructions per step from
#: a Newton loop in C): plate-ball 0.85 -> 0.43 s, 4635 -> 4610; planar chain of 8 links
#: 0.36 -> 0.18 s, 27950 -> 27799; 16 links 0.79 -> 0.33 s, 95570 -> 102165 (and 4 % faster
#: per step); 3D chain of 2 bodies 0.26 -> 0.16 s, 7647 -> 7551; of 4 bodies 0.47 -> 0.26 s,
#: 11 % faster per step.  Above 4000 operations the level trades step time for build time
#: (wall seconds of the whole compile, µs per step): 3D chain of 6 bodies (5822 operations)
#: 0.75 -> 0.54 s, 3.75 -> 4.05 µs (+8 %); of 8 bodies (8331) 1.10 -> 0.81 s, 5.95 -> 6.75 µs
#: (+13 %), still under half of CasADi's generated step (``benchmarks/scaling.py``).  For a
#: long simulation, ``compile(flags=["-O3", "-ffp-contract=off"])`` builds at -O3.  The
#: planar chain of 32 links (12337 operations) and larger keep -O3 (-O2 above
#: LARGE_PROGRAM).
SMALL_STEP = 9_000


#: -O1 with complete peeling of loops of a few constant iterations (the stepper's loops over
#: the unknowns, which -O3 unrolls), and loops aligned to 32 bytes: the level of a small
#: step's kernel.  Without the alignment the step time depends on where the linker happens to
#: place the Newton loop (the plate-ball's 0.28 to 0.33 µs for the same C under different
#: layouts); with it, measured in one run each (µs per step, without -> with): plate-ball
#: 0.32 -> 0.28, 3D chain of 2 bodies 0.95 -> 0.81, of 6 bodies 4.26 -> 4.18, planar chain of
#: 8 links 2.28 -> 2.28.
SMALL_STEP_LEVEL: tuple[str, ...] = ("-O1", "-fpeel-loops", "-falign-loops=32")


#: what a larger step kernel (more than :data:`SMALL_STEP` operations) adds to its level:
#: no superword-level (SLP) vectorisation of straight-line code, whose cost grows faster
#: than the code.  Measured (wall seconds of the whole compile, µs per step, in one run):
#: planar chain of 32 links (-O3) 2.09 -> 1.42 s, 24.9 -> 26.0 µs; of 64 links (-O2)
#: 17.8 -> 6.0 s, 122 -> 129 µs (one of its units: 17.0 -> 4.6 s of CPU, of which SLP
#: vectorisation itself was 5.1 s and the passes after it most of the rest); 3D chain of 16
#: bodies (-O2) 1.86 -> 1.45 s, 27.7 -> 27.4 µs.
LARGE_STEP_FLAGS: tuple[str, ...] = ("-fno-tree-slp-vectorize",)


def optimisation_flags(operations: int, *, step: bool = False) -> tuple[str, ...]:
    """The compiler flags of a kernel of ``operations`` operations (deterministic); a Newton
    step's kernel (``step``) of at most :data:`SMALL_STEP` operations at
    :data:`SMALL_STEP_LEVEL`, a larger one with :data:`LARGE_STEP_FLAGS`."""
    if step and operations <= SMALL_STEP:
        return SMALL_STEP_LEVEL + DEFAULT_FLAGS[1:]
    level = ("-O2",) + DEFAULT_FLAGS[1:] if operations > LARGE_PROGRAM else DEFAULT_FLAGS
    return level + LARGE_STEP_FLAGS if step else level


#: the optimisation level of a kernel's cold unit (``KernelSource.cold``: the batched entry
#: point with its OpenMP region, the status messages): 0.036 s of the compiler at -Og,
#: against 0.047 s at -O1 and 0.11 s at -O3 (CPU time, any system; 0.015 s of it starts
#: the compiler), run beside the other units
COLD_LEVEL = "-Og"


#: the levels a cold unit is lowered from (a build at -O0, -Og or -Os keeps its own)
LOWERED_LEVELS = frozenset({"-O", "-O1", "-O2", "-O3"})


#: the optimisation level of a kernel's block units (``KernelSource.blocks``: straight-line
#: arithmetic that calls no library function -- parts of the residual and its Jacobian, the
#: chart, the prediction, the state update), which a build at the library's default flags
#: has.  -Og is -O1 without the passes that matter for loops, branches and library calls
#: (if-conversion, loop invariant motion, scalar replacement of aggregates, pairing sin and
#: cos into sincos ...), which such code does not have.  Measured (gcc 12, CPU seconds of a
#: block unit, -O1 -> -Og): 3D chain of 4 bodies 0.35 -> 0.18, of 8 bodies 0.69 -> 0.45;
#: at -O3 -> -Og, of 8 bodies 1.04 -> 0.45.  Steps take as long (µs per step, at the
#: default flags without -> with, in one run): 3D chain of 3 bodies 1.38 -> 1.37, of 4
#: bodies 2.13 -> 2.17, of 6 bodies 4.42 -> 4.40, of 8 bodies 7.40 -> 7.37, of 16 bodies
#: 28.3 -> 27.3 (``benchmarks/scaling.py`` for whole builds).  The planar chains' blocks
#: call sin and cos: at -Og they step up to 30 % slower and build no faster, so they are
#: not block units.
BLOCK_LEVEL = "-Og"


#: the compiler's time on a block unit at :data:`BLOCK_LEVEL` relative to the same code at
#: the build's level (the weight ``codegen.assign_units`` balances the units by), from the
#: measurements above; at other levels a block unit keeps the build's flags
BLOCK_WEIGHTS = {"-O": 0.6, "-O1": 0.6, "-O2": 0.45, "-O3": 0.45}


def _level(flags: Sequence[str]) -> str | None:
    """The last ``-O`` option of ``flags`` (the one the compiler obeys), or None."""
    levels = [f for f in flags if f.startswith("-O")]
    return levels[-1] if levels else None


def block_weight(flags: Sequence[str]) -> float:
    """The compiler's time on a block unit of a build at ``flags`` relative to the same
    code at ``flags``: :data:`BLOCK_WEIGHTS` where the unit is lowered to
    :data:`BLOCK_LEVEL` (:func:`unit_flags`), else 1."""
    return BLOCK_WEIGHTS.get(_level(flags), 1.0)


#: the optimisation level of a large kernel's stepper unit (``KernelSource.stepper``: the
#: Newton stepper's loops -- the LU's panel updates, the substitutions, the rounding floors
#: -- compiled on their own), whatever the level of its straight-line functions: at -O3 the
#: compiler vectorises the loops over a row, which -O2 leaves mostly scalar, and without
#: -ffast-math no level reorders an operation, so every result keeps its bits.  Measured
#: (µs per step, in one run, the whole kernel at -O2 -> -O3): the 3D chain of 32 bodies
#: 124 -> 105, with the same bits.
STEPPER_LEVEL = "-O3"

#: a step kernel compiled at -O2 (more than ``LARGE_PROGRAM`` operations) or at the small
#: step's -O1 (at most ``SMALL_STEP``) with at least this many unknowns has its stepper in a
#: unit of its own at :data:`STEPPER_LEVEL` (the LU's panels begin at the same size,
#: ``SG_LU_PANEL_FROM`` in ``stepper.c``)
STEPPER_UNIT_FROM = 24

#: the levels a stepper unit is raised from.  -O1 too: a small kernel with many unknowns
#: spends half its step in the LU and the substitutions, which -O1 leaves scalar.  Measured
#: (µs per step inside ``simulate``, alternating builds, same bits): the 3D chain of 8
#: bodies (24 unknowns, 7,139 operations) 4.71, 4.72 -> 3.46, 3.47
RAISED_LEVELS = frozenset({"-O1", "-O2"})


def stepper_unit(flags: Sequence[str], n_unknowns: int) -> bool:
    """Whether a step kernel of ``n_unknowns`` unknowns built at the library's ``flags``
    (its :func:`optimisation_flags`) has its stepper in a unit of its own."""
    return _level(flags) in RAISED_LEVELS and n_unknowns >= STEPPER_UNIT_FROM


#: the roles of a translation unit (see :func:`unit_flags`)
UNIT_ROLES = ("step", "blocks", "cold", "stepper")


def unit_flags(flags: Sequence[str], role: str = "step") -> tuple[str, ...]:
    """The flags of one translation unit of a build at ``flags`` (deterministic).

    ``role``: ``"cold"`` (``KernelSource.cold``) gets :data:`COLD_LEVEL` after ``flags``
    when their last ``-O`` option is one of :data:`LOWERED_LEVELS`; ``"blocks"``
    (``KernelSource.blocks``, which only a kernel generated for the library's default
    flags has) gets :data:`BLOCK_LEVEL` after them when their last ``-O`` option is one of
    :data:`BLOCK_WEIGHTS`; ``"stepper"`` (``KernelSource.stepper``, likewise) gets
    :data:`STEPPER_LEVEL` after them, without :data:`LARGE_STEP_FLAGS`, when their last
    ``-O`` option is one of :data:`RAISED_LEVELS`; ``"step"`` (the kernel's source, and any
    other unit) keeps them.  No level changes a result: a cold unit does no floating-point
    arithmetic of a step, and no level reorders a floating-point operation (no -ffast-math;
    -ffp-contract=off keeps every rounding).
    """
    flags = tuple(flags)
    if role not in UNIT_ROLES:
        raise ValueError(f"unknown translation unit role {role!r}")
    level = _level(flags)
    if role == "cold" and level in LOWERED_LEVELS:
        return (*flags, COLD_LEVEL)
    if role == "blocks" and level in BLOCK_WEIGHTS:
        return (*flags, BLOCK_LEVEL)
    if role == "stepper" and level in RAISED_LEVELS:
        return (*(f for f in flags if f not in LARGE_STEP_FLAGS), STEPPER_LEVEL)
    return flags


#: the kernels compile_step builds are spread over at most this many translation units
#: (by size, see ``codegen.generate_c``), compiled at the same time, where at least
#: PARALLEL_CPUS processors are usable (see :func:`translation_units`)
TRANSLATION_UNITS = 2


PARALLEL_CPUS = 2


def usable_cpus() -> int:
    """The processors this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def translation_units() -> int:
    """How many translation units a kernel's stepper and straight-line functions are built
    from: ``TRANSLATION_UNITS`` on a machine of ``PARALLEL_CPUS`` usable processors or more
    (and then one more, the cold unit, see ``codegen.generate_c``), else one file.

    Measured on two processors with the second one free (wall seconds of the compiler, one
    unit → two): planar 8-link chain 0.62 → 0.47, 3D chain of 3 bodies 0.73 → 0.46, of 8
    bodies 1.78 → 0.93; the compiler's total time grows by about 10 %, so where the second
    processor is busy the build takes that much longer.  Small kernels too: their stepper
    takes the compiler longer than their straight-line functions
    (``codegen._kernel.assign_units``).  The kernel's C then depends on the machine (its
    source key too); what it computes does not.
    """
    return TRANSLATION_UNITS if usable_cpus() >= PARALLEL_CPUS else 1
