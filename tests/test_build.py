"""Building kernels: shared libraries loaded in cffi's ABI mode, the compile path without the
SymPy residuals, large kernels spread over translation units compiled at the same time."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    compiled,
    isolated_cache,
    needs_cc,
    step_inputs,
)

import symgroupoid as sg
from symgroupoid import Simulator

# white-box: how a kernel is built is checked inside — its split into parts and translation
# units and the templates' compiled code (codegen/_kernel.py, _emit.py), the optimisation
# levels (toolchain/_flags.py), the compiler runs of one build (_cffi_build.py), the kernel
# loaded from its source (runtime/_compile.py), the recipes kept per kernel (_kernels.py) and
# the OpenMP probe (_openmp.py); a user sees only the built kernel, bit for bit the same
from symgroupoid.codegen import _emit, _kernel, generate_c
from symgroupoid.codegen._emit import arithmetic_only
from symgroupoid.codegen._kernel import (
    CLOSE_UNKNOWNS,
    PART_SIZE,
    UNIT_MIN_STATEMENTS,
    UNIT_PART_SIZE,
    UNROLLED_UNKNOWNS,
    Block,
    Part,
    assign_units,
    stepper_statements,
    unit_part_size,
)
from symgroupoid.runtime import CompilationError, _compile, toolchain
from symgroupoid.runtime.toolchain import _cffi_build, _flags, _kernels, _openmp
from symgroupoid.systems import planar_chain, spherical_chain

pytestmark = needs_cc

PARAMS = {"h": 0.01, "g": 9.81}


def chain_state(n: int) -> np.ndarray:
    j = np.arange(1, n + 1)
    theta = 0.6 * np.cos(0.9 * j)
    return np.concatenate([theta - 0.004 * np.sin(1.3 * j), theta])


def _block(*sizes: int) -> Block:
    return Block(parts=[Part(locals=["x;"] * size) for size in sizes])


# --- translation units ------------------------------------------------------------------------

def test_units_balance_the_compiler_work_deterministically():
    blocks = [_block(0), _block(400), _block(500, 500, 80), _block(30), _block(30)]
    assert assign_units(blocks, 2, 12) == 2
    units = [p.unit for b in blocks for p in b.parts]
    loads = [stepper_statements(12), 0]
    for b in blocks:
        for p in b.parts:
            loads[p.unit] += p.statements
    assert max(loads) - min(loads) <= 500, loads  # at most one part apart
    assert blocks[0].parts[0].unit == 0, "an empty function stays in the kernel's source"
    again = [_block(0), _block(400), _block(500, 500, 80), _block(30), _block(30)]
    assign_units(again, 2, 12)
    assert [p.unit for b in again for p in b.parts] == units
    assert assign_units(blocks, 1, 12) == 1 and {p.unit for b in blocks for p in b.parts} == {0}


def test_the_stepper_of_a_small_kernel_compiles_beside_its_functions():
    # the stepper outweighs the straight-line functions of a small kernel: they all go to
    # unit 1, compiled at the same time as the stepper in unit 0
    small = [_block(56), _block(91), _block(4), _block(4)]
    assert stepper_statements(2) > 155
    assert assign_units(small, 2, 2) == 2
    assert {p.unit for b in small for p in b.parts} == {1}
    # except an unrolled stepper of 7 or 8 unknowns beside fewer than UNIT_MIN_STATEMENTS
    # (the plate-ball: 8 unknowns, 379 statements, steps faster in one unit)
    for n, size, kept in ((8, UNIT_MIN_STATEMENTS - 1, True), (7, 300, True),
                          (6, 300, False), (9, 300, False), (8, UNIT_MIN_STATEMENTS, False)):
        close = [_block(size)]
        assert (assign_units(close, 2, n) == 1) == kept, (n, size)
        assert (close[0].parts[0].unit == 0) == kept


def test_the_stepper_cost_grows_with_its_unrolled_size():
    unrolled = [stepper_statements(n) for n in range(1, 9)]
    assert unrolled == sorted(unrolled) and len(set(unrolled)) == 8
    assert stepper_statements(9) == stepper_statements(40) < stepper_statements(8)


def test_a_cold_unit_is_lowered_only_from_the_optimising_levels():
    assert toolchain.unit_flags(("-O3", "-ffp-contract=off"), "cold") == (
        "-O3", "-ffp-contract=off", toolchain.COLD_LEVEL)
    assert toolchain.unit_flags(("-O3", "-fopenmp"), "step") == ("-O3", "-fopenmp")
    for kept in (("-O0",), ("-O2", "-Og"), ("-Os",), ("-march=native",), ()):
        assert toolchain.unit_flags(kept, "cold") == kept
    with pytest.raises(ValueError, match="role"):
        toolchain.unit_flags(("-O3",), "hot")


def test_block_units_are_lowered_from_the_optimising_levels():
    """A block unit is built at BLOCK_LEVEL after the optimising levels (and balanced for
    it); at -O0, -Os or -Og it keeps the build's flags (weight 1)."""
    for operations in (10, toolchain.SMALL_STEP + 1, toolchain.LARGE_PROGRAM + 1):
        for default in (toolchain.optimisation_flags(operations, step=True),
                        (*toolchain.optimisation_flags(operations, step=True), "-fopenmp")):
            assert toolchain.unit_flags(default, "blocks") == (*default, toolchain.BLOCK_LEVEL)
            assert toolchain.unit_flags(default, "step") == default
            level = [f for f in default if f.startswith("-O")][-1]
            assert toolchain.block_weight(default) == _flags.BLOCK_WEIGHTS[level] < 1
    for kept in (("-O0",), ("-Os", "-g"), ("-O3", "-Og"), ("-march=native",), ()):
        assert toolchain.unit_flags(kept, "blocks") == kept
        assert toolchain.block_weight(kept) == 1.0


def test_only_a_kernel_without_library_calls_has_block_units():
    """The 3D chain's program is arithmetic (its further unit is a block unit); the planar
    chain calls sin and cos (-Og would not pair them into sincos): no block units, and
    units balanced at weight 1 whatever ``block_weight`` says."""
    from symgroupoid.systems import spherical_chain

    arithmetic = spherical_chain(2).euler_lagrange()
    assert arithmetic_only(arithmetic.program)
    kernel = generate_c(arithmetic, latex=False, units=2, block_weight=0.5)
    assert kernel.blocks == (f"{kernel.prefix}_unit1.c",)
    assert generate_c(arithmetic, latex=False).blocks == ()  # one file
    assert generate_c(arithmetic, latex=False, units=2).blocks == ()  # not asked for
    trig = planar_chain(16).euler_lagrange()
    assert not arithmetic_only(trig.program)
    half = generate_c(trig, latex=False, units=2, block_weight=0.5)
    assert half.blocks == ()
    assert half == generate_c(trig, latex=False, units=2)
    for bad in (-0.5, float("nan"), "1", [0.5]):
        with pytest.raises(sg.SymgroupoidError, match="block_weight"):
            generate_c(arithmetic, latex=False, units=2, block_weight=bad)
    for bad in (0, 65, 1.5, "2"):
        with pytest.raises(sg.SymgroupoidError, match="units"):
            generate_c(arithmetic, latex=False, units=bad)


def test_a_kernel_in_units_has_smaller_parts_unless_it_may_stay_in_one():
    from symgroupoid.stepper import library_source

    assert UNIT_PART_SIZE < PART_SIZE
    # the build's estimate unrolls where the library does
    assert f"#if SG_N_UNKNOWNS <= {UNROLLED_UNKNOWNS} && " in library_source("stepper.c")
    for n in (1, 6, 9, 48):
        assert unit_part_size(n, 2) == UNIT_PART_SIZE
        assert unit_part_size(n, 1) == PART_SIZE
    for n in range(CLOSE_UNKNOWNS, UNROLLED_UNKNOWNS + 1):  # the plate-ball's kind
        assert unit_part_size(n, 2) == PART_SIZE
    step = planar_chain(6).euler_lagrange()
    one, two = generate_c(step, latex=False), generate_c(step, latex=False, units=2)
    assert "_part0(" not in one.source  # one function per block
    assert "_residual_hoisted_part0(" in two.source  # the residual's parts, called twice


def test_weighted_units_finish_together():
    """With block units at half the cost, unit 0 (stepper and the blocks placed there)
    and unit 1 take about as long: within the weighted size of the largest part."""
    sizes = (700, 650, 600, 500, 400, 300, 120, 80)
    blocks = [_block(size) for size in sizes]
    assert assign_units(blocks, 2, 12, block_weight=0.5) == 2
    loads = [float(stepper_statements(12)), 0.0]
    for b in blocks:
        loads[b.parts[0].unit] += b.parts[0].statements * (1.0 if b.parts[0].unit == 0
                                                            else 0.5)
    assert abs(loads[0] - loads[1]) <= max(sizes), loads
    assert sum(b.parts[0].unit for b in blocks) > len(sizes) // 2  # more code in unit 1
    even = [_block(size) for size in sizes]
    assign_units(even, 2, 12)  # weight 1: the least loaded unit, as before
    assign_units(again := [_block(size) for size in sizes], 2, 12, block_weight=1.0)
    assert [b.parts[0].unit for b in even] == [b.parts[0].unit for b in again]


def test_the_optimisation_level_follows_the_kind_and_size_of_a_kernel():
    small, mid, large = toolchain.SMALL_STEP, toolchain.SMALL_STEP + 1, toolchain.LARGE_PROGRAM + 1
    contract = toolchain.DEFAULT_FLAGS[1:]
    assert toolchain.optimisation_flags(small, step=True) == (*_flags.SMALL_STEP_LEVEL, *contract)
    assert toolchain.optimisation_flags(mid, step=True) == (*toolchain.DEFAULT_FLAGS,
                                                         *_flags.LARGE_STEP_FLAGS)
    assert toolchain.optimisation_flags(large, step=True) == ("-O2", *contract,
                                                           *_flags.LARGE_STEP_FLAGS)
    for operations in (0, small, mid):  # window programs and other kernels: -O3 up to large
        assert toolchain.optimisation_flags(operations) == toolchain.DEFAULT_FLAGS
    assert toolchain.optimisation_flags(large) == ("-O2", *contract)
    step = planar_chain(2).euler_lagrange()
    assert toolchain.step_flags(step, None)[:4] == (*_flags.SMALL_STEP_LEVEL, *contract)
    assert toolchain.unit_flags(toolchain.optimisation_flags(small, step=True), "cold") == (
        *_flags.SMALL_STEP_LEVEL, *contract, toolchain.COLD_LEVEL)


def test_a_kernel_in_units_computes_what_the_one_file_kernel_computes(monkeypatch):
    step = planar_chain(2).euler_lagrange()
    one, three = generate_c(step, latex=False), generate_c(step, latex=False, units=2)
    assert one.units == () and one.cold == ()
    prefix = three.prefix
    assert [name for name, _ in three.units] == [f"{prefix}_unit1.c", f"{prefix}_cold.c"]
    assert three.cold == (f"{prefix}_cold.c",)
    assert three.header == one.header and three.cdef == one.cdef
    assert f"{prefix}_simulate_batch(" not in three.source
    assert f"int {prefix}_simulate(" not in three.units[0][1]
    jacobian = (f"void {prefix}_residual_jacobian_hoisted(const double *u, const double *known, "
                "const double *p, const double *h, double *F, double *J)\n{")
    assert jacobian not in three.source and jacobian in three.units[0][1]
    commands: list = []
    run = _cffi_build._run
    monkeypatch.setattr(_cffi_build, "_run", lambda kernel, cmds, *a, **k: (
        commands.extend(cmds), run(kernel, cmds, *a, **k))[1])
    kernel, entry = _compile.load_kernel_source(three, toolchain.default_flags(), step.name,
                                                len(step.unknowns), len(step.knowns))
    assert sorted(p.name for p in entry.iterdir() if p.suffix == ".c") == sorted(
        [f"{prefix}.c", f"{prefix}_cold.c", f"{prefix}_unit1.c"])
    assert not list(entry.glob("*.o"))
    def level(command):
        return [word for word in command if word.startswith("-O")][-1]

    cold_runs = [c for c in commands if f"{prefix}_cold.c" in c]
    assert len(commands) == 4 and len(cold_runs) == 1, commands  # 3 units, 1 link
    assert level(cold_runs[0]) == toolchain.COLD_LEVEL
    assert all(level(c) == "-O3" for c in commands if c not in cold_runs)  # explicit flags
    state = chain_state(2)
    numpy = step.compile(backend="numpy")
    whole = _compile.load_kernel_source(one, toolchain.default_flags(), step.name,
                                        len(step.unknowns), len(step.knowns))[0]
    split = Simulator(step, kernel, numpy.options)
    c = split.simulate(state, 40, PARAMS).states
    assert np.array_equal(c, Simulator(step, whole, numpy.options).simulate(
        state, 40, PARAMS).states)
    assert np.array_equal(c, numpy.simulate(state, 40, PARAMS).states)
    batch = split.simulate_batch(np.stack([state, state]), 40, PARAMS)
    assert np.array_equal(batch.states[1], c)
    library = next(entry.glob("*.so"))
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(library)],
                             capture_output=True, text=True)
    if symbols.returncode == 0:
        assert f"{prefix}_residual_jacobian" in symbols.stdout
        assert f"{prefix}_simulate_batch" in symbols.stdout
        assert "_part" not in symbols.stdout, "parts are not exported"


def _cayley(x) -> np.ndarray:
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)
    return np.eye(3) + 4 / (4 + x @ x) * (X + X @ X / 2)


@pytest.mark.slow
def test_block_units_at_their_level_compute_what_every_other_build_computes(monkeypatch):
    """The 3D chain of 2 bodies at the default flags: its block unit is compiled at
    BLOCK_LEVEL, the source at the step level.  Explicit flags, even the default ones,
    apply to every unit (another cache entry).  40 steps of either equal, bit for bit, those
    of the one-file kernel and of NumPy."""
    from symgroupoid.systems import spherical_chain

    step = spherical_chain(2).euler_lagrange()
    commands: list = []
    run = _cffi_build._run
    monkeypatch.setattr(_cffi_build, "_run", lambda kernel, cmds, *a, **k: (
        commands.extend(cmds), run(kernel, cmds, *a, **k))[1])

    def levels():
        prefix = step.name
        out = {}
        for c in commands:
            for unit in (f"{prefix}.c", f"{prefix}_unit1.c"):
                if unit in c:
                    out[unit] = [w for w in c if w.startswith("-O")][-1]
        commands.clear()
        return out

    lowered = step.compile(backend="c")
    assert lowered.kernel.block_units
    assert levels() == {f"{step.name}.c": _flags.SMALL_STEP_LEVEL[0],
                        f"{step.name}_unit1.c": toolchain.BLOCK_LEVEL}
    explicit = step.compile(backend="c", flags=list(lowered.kernel.flags))
    assert not explicit.kernel.block_units
    assert explicit.kernel.source_key != lowered.kernel.source_key
    assert levels() == {f"{step.name}.c": _flags.SMALL_STEP_LEVEL[0],
                        f"{step.name}_unit1.c": _flags.SMALL_STEP_LEVEL[0]}
    one = generate_c(step, latex=False)
    whole = _compile.load_kernel_source(one, ["-O3", "-ffp-contract=off"], step.name,
                                        len(step.unknowns), len(step.knowns))[0]
    h = PARAMS["h"]
    R = [_cayley(np.array([0.3, 0.2 * i, 0.1])) for i in (1, 2)]
    R1 = [r @ _cayley(h * np.array([0.6, -0.4 * i, 0.8])) for i, r in zip((1, 2), R)]
    state = np.concatenate([r.ravel() for r in R] + [r.ravel() for r in R1])
    states = lowered.simulate(state, 40, PARAMS).states
    assert np.isfinite(states).all()
    assert np.array_equal(states, explicit.simulate(state, 40, PARAMS).states)
    assert np.array_equal(states, Simulator(step, whole, lowered.options).simulate(
        state, 40, PARAMS).states)
    assert np.array_equal(states, step.compile(backend="numpy").simulate(
        state, 40, PARAMS).states)
    for sim in (lowered, explicit):  # generated again alike (source key checked)
        _kernels._RECIPES.pop(sim.kernel.source_key)
        assert bool(toolchain.kernel_source_of(sim.kernel, step).blocks) == \
            sim.kernel.block_units


def test_a_large_kernel_splits_its_functions_over_units_too(monkeypatch):
    monkeypatch.setattr(_kernel, "PART_SIZE", 40)  # parts to spread over both units
    monkeypatch.setattr(_kernel, "UNIT_PART_SIZE", 40)
    monkeypatch.setattr(_kernel, "stepper_statements", lambda n: 0)
    step = planar_chain(4).euler_lagrange()
    two = generate_c(step, latex=False, units=2)
    assert [name for name, _ in two.units] == [f"{two.prefix}_unit1.c", f"{two.prefix}_cold.c"]
    assert re.search(r"static void \w+_part\d+\(", two.source)
    assert re.search(r"_UNIT_LOCAL void \w+_part\d+\(", two.units[0][1])
    kernel, _ = _compile.load_kernel_source(two, toolchain.default_flags(), step.name,
                                            len(step.unknowns), len(step.knowns))
    numpy = step.compile(backend="numpy")
    state = chain_state(4)
    assert np.array_equal(Simulator(step, kernel, numpy.options).simulate(state, 40,
                                                                          PARAMS).states,
                          numpy.simulate(state, 40, PARAMS).states)


def test_a_unit_the_compiler_rejects_is_a_compilation_error():
    step = planar_chain(2).euler_lagrange()
    two = generate_c(step, latex=False, units=2)
    with pytest.raises(CompilationError) as info:
        _compile.load_kernel_source(two, ["-fno-such-option-for-symgroupoid"], step.name,
                                    len(step.unknowns), len(step.knowns))
    assert "-fno-such-option-for-symgroupoid" in info.value.output
    assert not list((toolchain.cache_root() / "kernels").glob("*"))


# --- the compile path -------------------------------------------------------------------------

def test_compiling_builds_no_sympy_residuals_and_emitting_keeps_the_latex():
    step = planar_chain(1).euler_lagrange()
    sim = sg.compile_step(step, backend="c")
    assert step._d.residuals is None, "compile_step built the SymPy residuals"
    source = (sim.cache_entry / f"{sim.kernel.prefix}.c").read_text()
    assert "print the equations with StepEquations.latex()" in source
    assert "\\theta" not in source
    assert "\\theta" not in generate_c(step).source  # by default: numbered equations
    emitted = generate_c(step, latex=True).source
    assert "\\theta" in emitted  # emit_c(latex=True) lists the residuals in LaTeX


# --- ABI mode ---------------------------------------------------------------------------------

_LAYOUT = r"""
#include <stddef.h>
#include <stdio.h>
#include "{header}"
int main(void)
{{
    printf("%zu %zu %zu %zu %zu %zu %zu %zu %zu %zu\n", sizeof({p}_options),
           sizeof({p}_warm_start), offsetof({p}_options, tol_step),
           offsetof({p}_options, max_iterations), offsetof({p}_options, extrapolate),
           offsetof({p}_warm_start, quadratic), offsetof({p}_warm_start, u_last),
           offsetof({p}_warm_start, u_before), offsetof({p}_warm_start, u_earlier),
           (size_t){P}_N_KNOWNS);
    return 0;
}}
"""


def test_the_type_table_agrees_with_the_compiled_header(tmp_path):
    """cffi's ABI mode lays out structures from the declarations: they must be the C
    compiler's layout of the header the library was compiled with."""
    sim = compiled("rigid_body")
    p, ffi = sim.kernel.prefix, sim.kernel.ffi
    program = tmp_path / "layout.c"
    program.write_text(_LAYOUT.format(header=sim.cache_entry / f"{p}.h", p=p, P=p.upper()))
    exe = tmp_path / "layout"
    subprocess.run(["cc", str(program), "-o", str(exe)], check=True)
    got = [int(v) for v in subprocess.run([str(exe)], capture_output=True, text=True,
                                          check=True).stdout.split()]
    assert got == [ffi.sizeof(f"{p}_options"), ffi.sizeof(f"{p}_warm_start"),
                   ffi.offsetof(f"{p}_options", "tol_step"),
                   ffi.offsetof(f"{p}_options", "max_iterations"),
                   ffi.offsetof(f"{p}_options", "extrapolate"),
                   ffi.offsetof(f"{p}_warm_start", "quadratic"),
                   ffi.offsetof(f"{p}_warm_start", "u_last"),
                   ffi.offsetof(f"{p}_warm_start", "u_before"),
                   ffi.offsetof(f"{p}_warm_start", "u_earlier"),
                   int(getattr(sim.kernel.lib, f"{p.upper()}_N_KNOWNS"))]


def test_a_damaged_type_table_is_detected_and_rebuilt():
    step = planar_chain(1).euler_lagrange()
    flags = toolchain.step_flags(step, None)
    cache = toolchain.KernelCache(toolchain.cache_root())
    key = toolchain.input_key(step, flags)
    source_key, manifest = toolchain.build_step(step, flags, cache, key)
    path = cache.entry(source_key) / toolchain.MANIFEST
    table = manifest["types"]
    damaged = {**manifest, "types": {**table, "_version": table["_version"] + 1}}
    path.write_text(json.dumps(damaged))
    assert cache.verified_manifest(source_key) is None
    builds = toolchain.STATS["builds"]
    sim = sg.compile_step(step, backend="c")
    assert toolchain.STATS["builds"] == builds + 1
    assert sim.simulate(chain_state(1), 5, PARAMS).states.shape == (6, 2)


BLOCKED = """
import sys
for name in ("setuptools", "distutils", "_distutils_hack"):
    sys.modules[name] = None  # importing them fails
from symgroupoid.systems import planar_chain
sim = planar_chain(1).euler_lagrange().compile(backend="c")
print(sim.backend)
"""


def test_building_needs_neither_setuptools_nor_python_headers(tmp_path):
    import sysconfig

    from symgroupoid.runtime.toolchain import build_command

    include = sysconfig.get_paths()["include"]
    assert not any(include in word for word in build_command("k.c", "k.so", ["-O2"]))
    result = subprocess.run([sys.executable, "-c", BLOCKED], capture_output=True, text=True,
                            env={**os.environ, "PYTHONPATH": str(REPO),
                                 "SYMGROUPOID_CACHE": str(tmp_path / "cache")})
    assert result.returncode == 0, result.stderr
    assert result.stdout.split()[-1] == "c"


@needs_cc
def test_the_openmp_probe_runs_while_the_c_is_generated(monkeypatch, tmp_path):
    """A first build in a process whose compiler's OpenMP support is not known starts the
    probe in the background (start_openmp_probe), generates the C meanwhile and builds from
    that C; the answer is the probe's, kept in the process and in the cache; a known answer
    starts nothing, and SYMGROUPOID_OPENMP=0 never probes."""
    monkeypatch.setattr(_openmp, "_OPENMP", {})
    monkeypatch.setattr(_openmp, "_PENDING", {})
    calls = []
    real = _openmp._openmp_probe

    def probe(command):
        calls.append(tuple(command))
        return real(command)

    monkeypatch.setattr(_openmp, "_openmp_probe", probe)
    step = planar_chain(2).euler_lagrange()
    before = toolchain.STATS["codegen"]
    sim = sg.compile_step(step, backend="c", cache_dir=tmp_path)
    assert len(calls) == 1 and toolchain.STATS["codegen"] == before + 1  # C generated once
    answer = real(calls[0])
    assert toolchain.openmp_available(tmp_path) is answer
    assert ("-fopenmp" in sim.kernel.flags) is answer
    assert list((tmp_path / "probes").glob("openmp-*.json"))
    assert not toolchain.start_openmp_probe(tmp_path)  # known in this process
    monkeypatch.setattr(_openmp, "_OPENMP", {})
    assert not toolchain.start_openmp_probe(tmp_path)  # known in the cache
    assert not toolchain.start_openmp_probe(tmp_path / "fresh") or toolchain.openmp_available(
        tmp_path / "fresh") is answer
    monkeypatch.setenv("SYMGROUPOID_OPENMP", "0")
    monkeypatch.setattr(_openmp, "_OPENMP", {})
    assert not toolchain.start_openmp_probe(tmp_path / "other")
    assert len(calls) <= 2


def test_a_probe_that_cannot_tell_is_tried_twice_in_a_process(monkeypatch, tmp_path):
    """(An environment where the OpenMP probe never answers — its library does not load
    for a reason other than OpenMP, e.g. a noexec $TMPDIR — probed again at every build,
    about 0.3 s each.)  Undetermined answers are not recorded; after two of them the
    process builds without OpenMP and probes no more."""
    monkeypatch.delenv("SYMGROUPOID_OPENMP", raising=False)
    monkeypatch.setattr(_openmp, "_OPENMP", {})
    monkeypatch.setattr(_openmp, "_PENDING", {})
    monkeypatch.setattr(_openmp, "_UNDETERMINED", {})
    if _openmp._probe_identity() is None:
        pytest.skip("no C compiler")
    calls = []

    def probe(command):
        calls.append(tuple(command))
        return None

    monkeypatch.setattr(_openmp, "_openmp_probe", probe)
    answers = [toolchain.openmp_available(tmp_path) for _ in range(4)]
    assert answers == [False] * 4 and len(calls) == 2
    assert not toolchain.start_openmp_probe(tmp_path) and len(calls) == 2
    assert not list(tmp_path.glob("probes/openmp-*.json"))


@pytest.mark.slow
@needs_cc
def test_the_templates_compiled_code_never_changes_the_c(tmp_path, monkeypatch):
    """The templates' compiled code, kept in a directory given to ``generate_c`` (the
    package's ``templates/__pycache__``; never the kernel cache, which holds no Python:
    ``test_cache_safety``), is loaded by a later process instead of compiling; a damaged
    entry or a missing directory only costs a compilation: the C is the same in every
    case."""
    monkeypatch.setattr(_emit, "package_template_cache", lambda write=False: None)
    step = planar_chain(2).euler_lagrange()
    kept_in = tmp_path / "compiled"
    kept_in.mkdir()
    plain = generate_c(step, latex=False, units=2, template_cache=kept_in)
    kept = sorted(kept_in.glob("__jinja2_*.cache"))
    assert kept
    probe = _template_probe(package=False)
    run = subprocess.run([sys.executable, "-c", probe, str(kept_in)],
                         capture_output=True, text=True, check=True, cwd=REPO)
    count, source = run.stdout.split("\n", 1)
    assert count == "0" and source == plain.source  # loaded, not compiled
    for path in kept:
        path.write_bytes(b"not a compiled template")
    run = subprocess.run([sys.executable, "-c", probe, str(kept_in)],
                         capture_output=True, text=True, check=True, cwd=REPO)
    count, source = run.stdout.split("\n", 1)
    assert int(count) > 0 and source == plain.source  # compiled again
    missing = tmp_path / "no" / "such" / "directory"
    assert generate_c(step, latex=False, units=2, template_cache=missing).source == plain.source
    assert not missing.exists()
    sim = sg.compile_step(step, backend="c", cache_dir=tmp_path / "cache")
    assert sim.backend == "c" and not (tmp_path / "cache" / "templates").exists()


def _template_probe(package: bool = True) -> str:
    """A Python program generating the planar 2-link chain's kernel in units, with the
    templates' compiled code in the directory argv[1] (and, unless ``package`` is False,
    in the package's): prints how many templates it compiled, a newline, the C source."""
    return ("import sys, jinja2; from symgroupoid.codegen import _emit; "
            + ("" if package else "_emit.package_template_cache = lambda write=False: None; ")
            + "compiled = []; real = jinja2.Environment.compile; "
            "jinja2.Environment.compile = lambda self, *a, **k: compiled.append(1) or "
            "real(self, *a, **k); "
            "from symgroupoid.systems import planar_chain; "
            "step = planar_chain(2).euler_lagrange(); "
            "k = _emit.generate_c(step, latex=False, units=2, template_cache=sys.argv[1]); "
            "sys.stdout.write(str(len(compiled)) + '\\n' + k.source)")


def _templates_copy(tmp_path, monkeypatch):
    """A copy of the templates (without compiled code) that ``template_dir`` names."""
    import shutil

    copy = tmp_path / "templates"
    shutil.copytree(_emit.template_dir(), copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(_emit, "template_dir", lambda: copy)
    _emit._environment.cache_clear()
    return copy


@pytest.mark.slow
def test_the_templates_compiled_beside_them_serve_every_process_and_cache(tmp_path):
    """``cache templates`` (make's setup) compiles every template into the templates'
    __pycache__/: a process with a new, empty kernel cache compiles none, even where Python
    writes no bytecode; nothing goes into that kernel cache."""
    run = subprocess.run([sys.executable, "-m", "symgroupoid", "cache", "templates"],
                         capture_output=True, text=True, check=True, cwd=REPO)
    directory = _emit.template_dir() / "__pycache__"
    assert f"{len(_emit.TEMPLATE_NAMES)} in {directory}" in run.stdout
    assert len(list(directory.glob("__jinja2_*.cache"))) >= len(_emit.TEMPLATE_NAMES)
    assert _emit.package_template_cache() == str(directory)
    for env in ({"PYTHONDONTWRITEBYTECODE": "1"}, {}):
        fresh = tmp_path / f"cache{len(env)}"
        fresh.mkdir()
        count = subprocess.run([sys.executable, "-c", _template_probe(), str(fresh)],
                               capture_output=True, text=True, check=True, cwd=REPO,
                               env={**os.environ, **env}).stdout.split("\n", 1)[0]
        assert count == "0" and not list(fresh.iterdir())


def test_a_changed_template_is_compiled_again(tmp_path, monkeypatch):
    """An entry of the package's compiled templates whose template changed since is stale:
    jinja2 compares the source, compiles the template again, and the C follows the new
    template; a process that may write bytecode replaces the entry."""
    copy = _templates_copy(tmp_path, monkeypatch)
    directory, kept = _emit.precompile_templates()
    assert directory == str(copy / "__pycache__") and kept == len(_emit.TEMPLATE_NAMES)
    step = planar_chain(1).euler_lagrange()
    before = generate_c(step, latex=False).source
    header = copy / "kernel.c.j2"
    header.write_text("/* a changed template */\n" + header.read_text())
    entries = {p: p.read_bytes() for p in (copy / "__pycache__").glob("__jinja2_*.cache")}
    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    _emit._environment.cache_clear()
    after = generate_c(step, latex=False).source
    assert after == "/* a changed template */\n" + before
    changed = [p for p, data in entries.items() if p.read_bytes() != data]
    assert len(changed) == 1  # kernel.c.j2's entry, rewritten
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    assert _emit.package_template_cache(write=True) is None
    _emit._environment.cache_clear()


def test_templates_that_cannot_be_kept_beside_them_are_an_output_error(tmp_path, monkeypatch):
    """``cache templates`` where templates/__pycache__ is in the way (a file): an
    OutputError naming the directory, from the library and from the command line (exit
    status 1, one line); kernels are still generated, their templates compiled per
    process."""
    copy = _templates_copy(tmp_path, monkeypatch)
    (copy / "__pycache__").write_text("in the way")
    with pytest.raises(sg.OutputError, match="__pycache__"):
        _emit.precompile_templates()
    assert _emit.package_template_cache() is None
    monkeypatch.setattr(sys, "dont_write_bytecode", False)
    assert _emit.package_template_cache(write=True) is None
    _emit._environment.cache_clear()
    assert generate_c(planar_chain(1).euler_lagrange(), latex=False).source
    from symgroupoid.cli import main

    assert main(["cache", "templates"]) == 1
    _emit._environment.cache_clear()


@needs_cc
def test_a_kernel_whose_residual_parts_are_shared_computes_what_numpy_computes(monkeypatch):
    monkeypatch.setattr("symgroupoid.codegen._kernel.PART_SIZE", 60)
    step = spherical_chain(2).euler_lagrange()
    kernel = generate_c(step, latex=False, units=2)
    p = kernel.prefix
    text = kernel.source + "".join(unit for _, unit in kernel.units)
    assert f"{p}_residual_hoisted_part0(u, known, p, h, F, w);" in text
    definitions = re.findall(rf"void ({p}_residual\w*_part\d+)\([^)]*\)\n{{", text)
    assert len(definitions) == len(set(definitions)), "every part is defined once"
    assert f"{p}_residual_hoisted_part0" in definitions
    assert f"{p}_residual_jacobian_hoisted_part0" not in definitions, "F's parts are the residual's"
    c_kernel, _ = _compile.load_kernel_source(kernel, toolchain.default_flags(), step.name,
                                              len(step.unknowns), len(step.knowns))
    numpy = step.compile(backend="numpy").kernel
    rng = np.random.default_rng(5)
    for _ in range(3):
        x = step_inputs(step, rng)
        u, known, par = x["u"][:, 0], x["known"][:, 0], x["p"][:, 0]
        F, J = c_kernel.residual_jacobian(u, known, par)
        F0, J0 = numpy.residual_jacobian(u, known, par)
        assert np.array_equal(F, F0) and np.array_equal(J, J0)
        assert np.array_equal(c_kernel.residual(u, known, par), F0)


def test_a_stepper_unit_is_raised_only_from_the_small_and_large_kernels_levels():
    large = toolchain.optimisation_flags(toolchain.LARGE_PROGRAM + 1, step=True)
    assert toolchain.unit_flags(large, "stepper") == ("-O2", *toolchain.DEFAULT_FLAGS[1:],
                                                      _flags.STEPPER_LEVEL)
    assert toolchain.unit_flags((*large, "-fopenmp"), "stepper")[-2:] == ("-fopenmp", "-O3")
    small = toolchain.optimisation_flags(toolchain.SMALL_STEP, step=True)
    assert toolchain.unit_flags(small, "stepper") == (*small, _flags.STEPPER_LEVEL)
    for kept in (toolchain.DEFAULT_FLAGS, ("-O0",), ("-Os",), ()):
        assert toolchain.unit_flags(kept, "stepper") == kept
    for flags in (large, small):
        assert _flags.stepper_unit(flags, _flags.STEPPER_UNIT_FROM)
        assert not _flags.stepper_unit(flags, _flags.STEPPER_UNIT_FROM - 1)
    mid = toolchain.optimisation_flags(toolchain.SMALL_STEP + 1, step=True)
    assert not _flags.stepper_unit(mid, 100)  # already -O3
    from symgroupoid.stepper import LU_PANEL_FROM

    assert _flags.STEPPER_UNIT_FROM == LU_PANEL_FROM


def test_a_stepper_unit_at_its_level_computes_what_numpy_computes(monkeypatch):
    """The 3D chain of 8 bodies (24 unknowns: the LU in panels) with its stepper in a unit
    of its own, built at the flags of a large kernel: the stepper unit at -O3 without
    LARGE_STEP_FLAGS, the others at -O2; 20 steps and a batch equal, bit for bit, the NumPy
    backend's."""
    step = spherical_chain(8).euler_lagrange()
    kernel = generate_c(step, latex=False, units=2, stepper_unit=True)
    prefix = kernel.prefix
    assert kernel.stepper == (f"{prefix}_stepper.c",)
    stepper_text = dict(kernel.units)[f"{prefix}_stepper.c"]
    assert f"int {prefix}_simulate(" in stepper_text and f"{prefix}_eliminate(" in stepper_text
    assert f"{prefix}_newton(" not in kernel.source
    assert f"{prefix}_residual_jacobian(" in kernel.source
    commands: list = []
    run = _cffi_build._run
    monkeypatch.setattr(_cffi_build, "_run", lambda kernel, cmds, *a, **k: (
        commands.extend(cmds), run(kernel, cmds, *a, **k))[1])
    flags = toolchain.optimisation_flags(toolchain.LARGE_PROGRAM + 1, step=True)
    loaded, _ = _compile.load_kernel_source(kernel, flags, step.name, len(step.unknowns),
                                            len(step.knowns))

    def level(command):
        return [word for word in command if word.startswith("-O")][-1]

    compiled = {c[c.index("-c") + 1]: c for c in commands if "-c" in c}
    assert level(compiled[f"{prefix}_stepper.c"]) == "-O3"
    assert "-fno-tree-slp-vectorize" not in compiled[f"{prefix}_stepper.c"]
    assert level(compiled[f"{prefix}.c"]) == "-O2"
    numpy = step.compile(backend="numpy")
    h, bodies = PARAMS["h"], range(1, 9)
    R = [_cayley(np.array([0.3, 0.2 * i, 0.1])) for i in bodies]
    R1 = [r @ _cayley(h * np.array([0.6, -0.4 * i, 0.8])) for i, r in zip(bodies, R)]
    state = np.concatenate([r.ravel() for r in R] + [r.ravel() for r in R1])
    split = Simulator(step, loaded, numpy.options)
    c = split.simulate(state, 20, PARAMS)
    assert np.array_equal(c.states, numpy.simulate(state, 20, PARAMS).states)
    assert np.array_equal(split.simulate_batch(np.stack([state, state]), 20, PARAMS).states[0],
                          c.states)


def test_a_killed_probe_s_directory_is_removed_by_the_next_probe(monkeypatch, tmp_path):
    """(A process killed while its OpenMP probe ran left ``symgroupoid-openmp-*`` in the
    system's temporary directory for good.)  Probe directories name their process and host;
    the next probe removes this user's whose process is gone — never a live process's, another
    host's, or a link."""
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(_openmp, "_OPENMP", {})
    monkeypatch.setattr(_openmp, "_PENDING", {})
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    host = _openmp.scratch_prefix("openmp").split("-")[-2]
    stale = tmp_path / f"symgroupoid-openmp-{dead}-{host}-abc"
    live = tmp_path / f"symgroupoid-openmp-{os.getppid()}-{host}-abc"
    other = tmp_path / f"symgroupoid-openmp-{dead}-0123456789ab-abc"
    for d in (stale, live, other):
        d.mkdir()
        (d / "probe.c").write_text("int x;\n")
    kept = tmp_path / "kept"
    kept.mkdir()
    (tmp_path / f"symgroupoid-openmp-{dead}-{host}-link").symlink_to(kept)
    toolchain.openmp_available(tmp_path / "cache")
    assert not stale.exists() and live.exists() and other.exists() and kept.exists()
    assert (tmp_path / f"symgroupoid-openmp-{dead}-{host}-link").is_symlink()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(
        _openmp.scratch_prefix("openmp"))], "the probe removes its own"


def test_a_build_in_a_background_thread_does_not_fork_with_a_hook():
    """A pre-exec hook makes Python fork, and fork runs OpenBLAS's fork handler, which
    stops its threads: a boundary-value solve whose kernels were built in a background
    thread left the main thread waiting in OpenBLAS's exec_blas (LAPACK's eigh) for minutes,
    in about half the runs.  The hook (the parent-death signal) is the main thread's only."""
    import threading

    seen = []
    worker = threading.Thread(target=lambda: seen.append(_cffi_build._child_setup()))
    worker.start()
    worker.join()
    assert seen == [None]
    assert _cffi_build._child_setup() is _cffi_build._CHILD_SETUP
