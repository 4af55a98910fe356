"""Window programs never wait for the compiler (symgroupoid/runtime/_programs.py).

A program whose kernel is not cached is evaluated in NumPy while the kernel is built in a
background thread, then by the kernel; the two compute the same bits, so a result never
shows which evaluated it.  A background build that fails leaves NumPy in use, with a
warning; a cached kernel is used from the first call.  (The evaluator's choice from
``SYMGROUPOID_BACKEND`` and its chunks of rows: tests/test_bvp.py.)
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from kernel_support import isolated_cache, needs_cc  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid.ir import Graph, Program, from_sympy
from symgroupoid.runtime import CompilationError, ProgramEvaluator, toolchain, wait_for_kernels

x, y = sp.symbols("x y", real=True)


def _program(scale: int = 1) -> Program:
    g = Graph()
    nodes = {s: g.input(s) for s in (x, y)}
    exprs = [sp.exp(x * scale) * sp.atan2(y, x) + sp.cos(y) ** 3,
             x ** sp.Rational(5, 2) / (1 + y ** 2)]
    return Program(g, {"a": [x, y]}, {"out": [from_sympy(g, e, nodes) for e in exprs]})


VALUES = np.random.default_rng(5).uniform(0.1, 2.0, (64, 2))


@needs_cc
def test_cold_evaluator_answers_at_once_and_switches_to_the_kernel():
    builds = toolchain.STATS["builds"]
    evaluator = ProgramEvaluator("evaluator cold", _program(), "a", "out")
    first = evaluator(VALUES)  # before the build ends, or after: the same bits
    assert evaluator.wait(120) and evaluator.backend == "c"
    assert toolchain.STATS["builds"] == builds + 1
    assert np.array_equal(evaluator(VALUES), first)
    again = ProgramEvaluator("evaluator cold", _program(), "a", "out")
    assert again.backend == "c", "a cached kernel is loaded at once"
    assert toolchain.STATS["builds"] == builds + 1


@needs_cc
def test_two_evaluators_of_one_kernel_build_it_once():
    builds = toolchain.STATS["builds"]
    a = ProgramEvaluator("evaluator twice", _program(2), "a", "out")
    b = ProgramEvaluator("evaluator twice", _program(2), "a", "out")
    assert wait_for_kernels(120)
    assert a.backend == b.backend == "c"
    assert toolchain.STATS["builds"] == builds + 1
    assert np.array_equal(a(VALUES), b(VALUES))


def test_failed_background_build_warns_and_stays_in_numpy(monkeypatch):
    def fail(*args, **kwargs):
        raise CompilationError("the compiler said no")

    monkeypatch.setattr("symgroupoid.runtime._programs.build_cached", fail)
    evaluator = ProgramEvaluator("evaluator failing", _program(3), "a", "out")
    assert not evaluator.wait(120) and evaluator.backend == "numpy"
    with pytest.warns(RuntimeWarning, match="the compiler said no"):
        out = evaluator(VALUES)
    reference = ProgramEvaluator("evaluator failing", _program(3), "a", "out", backend="numpy")
    assert np.array_equal(out, reference(VALUES))
    evaluator(VALUES)  # warned once


@needs_cc
def test_backend_c_builds_before_returning():
    evaluator = ProgramEvaluator("evaluator sync", _program(4), "a", "out", backend="c")
    assert evaluator.backend == "c"


def test_malformed_values_are_refused_by_either_form():
    evaluator = ProgramEvaluator("evaluator shapes", _program(), "a", "out", backend="numpy")
    with pytest.raises(sg.ShapeError, match=r"\(W, 2\)"):
        evaluator(np.zeros((3, 3)))
    with pytest.raises(sg.ShapeError, match=r"\(W, 2\)"):
        evaluator(np.zeros(2))


def test_wait_for_kernels_with_nothing_building_returns_at_once():
    assert wait_for_kernels(0) is True
