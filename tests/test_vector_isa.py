"""The instruction set kernels are compiled for (runtime.toolchain, ``_isa``): the widest
vector extension this processor has, never one it lacks, part of every cache key, and the
same bits whichever is chosen."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys

import numpy as np
import pytest
from kernel_support import REPO, needs_cc

import symgroupoid as sg
from symgroupoid.runtime import toolchain
from symgroupoid.systems import spherical_chain

PARAMS = {"h": 0.01, "g": 9.81}
HAS = toolchain.processor_features()
WIDEST = next((flag for feature, flag in toolchain.VECTOR_ISAS if feature in HAS), None)
LACKED = next((flag for feature, flag in toolchain.VECTOR_ISAS if feature not in HAS), None)
needs_vector_isa = pytest.mark.skipif(WIDEST is None, reason="no AVX on this processor")


def flags_on(*features: str, command=("gcc",), words=()) -> tuple[str, ...]:
    """The flag a build adds on a processor with ``features``."""
    return toolchain.vector_flags(list(command), list(words), frozenset(features))


def test_the_widest_the_processor_has(monkeypatch):
    monkeypatch.delenv(toolchain.VECTOR_ISA_ENV, raising=False)
    assert flags_on("sse2", "avx", "avx2", "avx512f") == ("-mavx512f",)
    assert flags_on("sse2", "avx", "avx2") == ("-mavx2",)
    assert flags_on("sse2", "avx", command=["ccache", "x86_64-linux-gnu-gcc-12"]) == ("-mavx",)
    assert flags_on("sse2") == ()
    assert flags_on() == ()  # another architecture: nothing is known, nothing added


def test_nothing_added_where_the_build_chooses_its_target(monkeypatch):
    monkeypatch.delenv(toolchain.VECTOR_ISA_ENV, raising=False)
    for words in (["-march=native"], ["-O3", "-mavx"], ["-mno-avx"], ["-mfma"], ["-msse4.2"]):
        assert flags_on("avx", "avx2", command=["cc"], words=words) == (), words
    assert flags_on("avx", "avx2", command=["cc", "-march=haswell"]) == ()
    assert flags_on("avx", "avx2", command=["tcc"]) == ()  # not known to take them
    assert flags_on("avx", "avx2", command=["/usr/bin/clang-15"]) == ("-mavx2",)


def test_the_environment_overrides_and_is_checked(monkeypatch):
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "none")
    assert flags_on("avx", "avx2") == ()
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, " AVX ")
    assert flags_on("avx", "avx2") == ("-mavx",)
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "avx512f")
    with pytest.raises(toolchain.VectorISAError, match="does not have.*avx2, avx"):
        flags_on("avx", "avx2")
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "sse9")
    with pytest.raises(toolchain.VectorISAError, match="not one of"):
        flags_on("avx", "avx2")
    assert issubclass(toolchain.VectorISAError, sg.SymgroupoidError)


@needs_vector_isa
def test_the_choice_is_part_of_every_cache_key(monkeypatch):
    monkeypatch.setenv("CC", "gcc")
    keys = set()
    for choice in ("none", "auto"):
        monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, choice)
        environment = toolchain.build_environment()
        assert environment[-1].startswith("VECTOR_ISA=")
        keys.add(environment)
    assert len(keys) == 2


def test_missing_instructions_are_named():
    assert toolchain.missing_instructions(["-O1", "-mavx512f", "-mavx"],
                                          frozenset({"avx", "avx2"})) == ["-mavx512f"]
    assert toolchain.missing_instructions(["-mavx512f"], frozenset()) == []  # cannot tell


@needs_cc
@pytest.mark.skipif(LACKED is None, reason="this processor has every extension")
def test_flags_asking_for_missing_instructions_are_refused():
    step = spherical_chain(1).euler_lagrange()
    with pytest.raises(toolchain.VectorISAError, match="does not have"):
        step.compile(backend="c", flags=["-O1", LACKED])


def trajectory(sim, steps: int = 300) -> np.ndarray:
    state = sim.state({"R1": (np.eye(3), _rotation(0.05)), "R2": (np.eye(3), _rotation(-0.02))},
                      PARAMS)
    return np.asarray(sim.simulate(state, steps, PARAMS).states)


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


@needs_cc
@needs_vector_isa
def test_the_same_bits_with_and_without_vector_instructions(monkeypatch, tmp_path):
    """The chain built for the compiler's default target and for the widest extension this
    processor has: two kernels (two cache entries) and the same trajectory to the bit, which
    is also the NumPy backend's."""
    step = spherical_chain(2).euler_lagrange()
    runs, keys = {}, set()
    for choice in ("none", "auto"):
        monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, choice)
        sim = step.compile(backend="c", cache_dir=str(tmp_path))
        keys.add(sim.kernel.source_key)
        runs[choice] = trajectory(sim)
    assert len(keys) == 2
    np.testing.assert_array_equal(runs["none"], runs["auto"])
    np.testing.assert_array_equal(runs["auto"], trajectory(step.compile(backend="numpy")))


@needs_cc
@needs_vector_isa
def test_flags_of_ones_own_keep_the_bits_with_the_added_extension(monkeypatch, tmp_path):
    """``compile(flags=["-O3"])``: with the AVX-512 the build adds, gcc 12 fused a*b + c
    (AVX-512F brings its fused multiply-adds), and 381 entries of a plate-ball run differed
    from the NumPy backend's.  The build adds ``-ffp-contract=off`` with the extension,
    unless the flags choose a contraction themselves."""
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "auto")
    step = spherical_chain(2).euler_lagrange()
    sim = step.compile(backend="c", cache_dir=str(tmp_path), flags=["-O3"])
    np.testing.assert_array_equal(trajectory(sim), trajectory(step.compile(backend="numpy")))


@needs_cc
@needs_vector_isa
def test_a_simulator_sent_elsewhere_is_built_for_that_processor(monkeypatch, tmp_path):
    """A pickled simulator restored where the processor lacks the sender's extension (here:
    the variable set to none) is built again for it, with the same results."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "auto")
    sim = spherical_chain(2).euler_lagrange().compile(backend="c")
    sent = pickle.dumps(sim)
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "none")
    restored = pickle.loads(sent)
    assert restored.kernel.source_key != sim.kernel.source_key
    np.testing.assert_array_equal(trajectory(restored), trajectory(sim))


def test_an_invalid_choice_ends_a_command_with_its_name(tmp_path):
    """The command line reports the variable, not a traceback, and exits with an error."""
    env = {**os.environ, toolchain.VECTOR_ISA_ENV: "sse9",
           "SYMGROUPOID_CACHE": str(tmp_path / "cache")}
    done = subprocess.run([sys.executable, "-m", "symgroupoid", "simulate",
                           str(REPO / "examples" / "cli" / "spring.py"), "--steps", "2",
                           "--backend", "c"],
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode != 0
    assert "SYMGROUPOID_VECTOR_ISA='sse9' is not one of" in done.stderr
    assert "Traceback" not in done.stderr


@needs_cc
@needs_vector_isa
def test_a_failed_build_names_the_way_back_to_the_default_target(monkeypatch, tmp_path):
    """A compiler that rejects the extension the build added (an old compiler may not know
    it) is reported with how to build without it; a build that fails for another reason
    (an unknown option of the user's, the unsafe-math guards) is not: that advice misled."""
    monkeypatch.setenv(toolchain.VECTOR_ISA_ENV, "auto")
    step = spherical_chain(1).euler_lagrange()
    old = tmp_path / "old-cc"
    old.write_text(f'#!/bin/sh\nfor a in "$@"; do [ "$a" = "{WIDEST}" ] && {{ echo "cc: error: '
                   f'unrecognized command-line option \'{WIDEST}\'" >&2; exit 1; }}; done\n'
                   f'exec cc "$@"\n')
    old.chmod(0o755)
    with monkeypatch.context() as patch:
        patch.setenv("CC", str(old))
        with pytest.raises(sg.CompilationError, match=f"compiled with {WIDEST}.*"
                           f"SYMGROUPOID_VECTOR_ISA=none"):
            step.compile(backend="c", cache_dir=str(tmp_path / "cache"), flags=["-O1"])
    with pytest.raises(sg.CompilationError) as info:
        step.compile(backend="c", cache_dir=str(tmp_path / "cache"),
                     flags=["-O1", "-fno-such-option-for-symgroupoid"])
    assert "SYMGROUPOID_VECTOR_ISA" not in str(info.value)
    with pytest.raises(sg.CompilationError) as info:  # a target of its own: none added
        step.compile(backend="c", cache_dir=str(tmp_path / "cache"),
                     flags=["-O1", "-march=x86-64", "-fno-such-option-for-symgroupoid"])
    assert "SYMGROUPOID_VECTOR_ISA" not in str(info.value)
