"""The values of the known arrow, computed once per Newton step (``<prefix>_hoist``).

Newton evaluates F at several iterates of one step and J once; the terms of F and J that
read no unknown (X⃖L(g_k), f⁺(g_k), the known factors of products with the new arrow) are
computed by ``<prefix>_hoist`` once per step and read by ``<prefix>_residual_hoisted``.
The same operations on the same values: the C stays the NumPy twin's bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SESSION_CACHE,
    compiled,
    isolated_cache,
    needs_cc,
    seed_step,
)

import symgroupoid as sg
from symgroupoid.codegen import generate_c, hoisted_values
from symgroupoid.systems import spherical_chain


def _moving(program) -> set:
    g = program.graph
    unknowns = [g.inputs[s] for s in program.inputs["u"] if s in g.inputs]
    return g.dependents(unknowns, program.nodes(["F", "J"]))


def test_hoisted_values_read_no_unknown_and_are_what_the_moving_nodes_read():
    """Every hoisted value reads no unknown; every known-only operation a node that reads
    the unknowns uses directly is hoisted (the frontier), and none is hoisted twice."""
    program = spherical_chain(2).euler_lagrange().program
    g = program.graph
    hoisted = hoisted_values(program)
    moving = _moving(program)
    assert hoisted and hoisted == sorted(set(hoisted))
    assert not moving & set(hoisted)
    for n in program.nodes(["F", "J"]):
        if n in moving:
            assert all(a in moving or not g.args[a] or a in hoisted for a in g.args[n])


def test_the_residual_computes_no_known_only_operation():
    """The residual's C reads the hoisted values (h[i]) and computes only what reads the
    unknowns: on the 3D two-body chain a third of F's operations read no unknown, and
    the residual's function holds fewer statements than F has operations by about that."""
    step = spherical_chain(2).euler_lagrange()
    text = generate_c(step, "chain").source
    residual = text.split("void chain_residual_hoisted(")[1].split("\n}\n")[0]
    hoist = text.split("void chain_hoist(")[1].split("\n}\n")[0]
    n_hoisted = len(hoisted_values(step.program))
    assert residual.count("h[") > 0 and hoist.count("h[") == n_hoisted
    moving = _moving(step.program)
    reading = sum(1 for n in step.program.nodes(["F"])
                  if n in moving and step.program.graph.args[n])
    assert residual.count("const double t") <= reading < 0.8 * step.program.size(["F"])


@needs_cc
@pytest.mark.parametrize("name", ["plate_ball", "heavy_top"])
def test_hoist_then_residual_is_the_residual_and_the_twins_bits(name):
    """<p>_hoist then <p>_residual_hoisted gives <p>_residual's bits and the NumPy
    program's, at random points."""
    step = seed_step(name)
    kernel = compiled(name).kernel
    twin = compiled(name, backend="numpy").kernel
    lib, ffi, prefix = kernel.lib, kernel.ffi, kernel.prefix
    n_h = getattr(lib, f"{prefix.upper()}_N_HOISTED")
    assert n_h == len(hoisted_values(step.program)) > 0
    rng = np.random.default_rng(5)
    G = step.groupoid
    view = lambda a: ffi.from_buffer("double[]", a)  # noqa: E731
    for _ in range(5):
        arrow = np.asarray(G.random_arrow(rng), dtype=float)
        known = np.concatenate([arrow, rng.uniform(-1, 1, len(step.knowns) - arrow.size)])
        u = rng.uniform(-0.5, 0.5, len(step.unknowns))
        p = rng.uniform(0.5, 2.0, len(step.parameters))
        h, F = np.empty(n_h), np.empty(len(u))
        getattr(lib, f"{prefix}_hoist")(view(known), view(p), view(h))
        getattr(lib, f"{prefix}_residual_hoisted")(view(u), view(known), view(p), view(h),
                                                   view(F))
        assert np.array_equal(F, kernel.residual(u, known, p))
        assert np.array_equal(F, twin.residual(u, known, p))


@needs_cc
def test_a_step_without_known_only_terms_hoists_nothing_and_steps(tmp_path):
    """L_d(q₀, q₁) = q₀q₁: F = q_{k−1} + q_{k+1}, one sum that reads the unknown, so
    nothing is hoisted: the header says 0, the placeholder array has one entry, and the
    compiled step gives the exact q_{k+1} = −q_{k−1}."""
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))
    step = sg.DiscreteSystem(G, lambda g: g.source[0] * g.target[0],
                             name="nothing hoisted").euler_lagrange()
    assert hoisted_values(step.program) == []
    assert "#define NOTHING_HOISTED_N_HOISTED 0" in generate_c(step).header
    sim = step.compile(cache_dir=tmp_path / "cache")
    run = sim.simulate(np.array([0.25, -1.5]), 3, {})
    assert np.array_equal(run.states[:, 1], [-1.5, -0.25, 1.5, 0.25])


def test_golden_kernels_declare_their_hoisted_values():
    """The shipped kernels' headers give the number of hoisted values."""
    from kernel_support import REPO

    header = (REPO / "generated" / "plate_ball.h").read_text()
    assert "#define PLATE_BALL_N_HOISTED " in header
    assert "plate_ball_hoist(const double *known, const double *p, double *h)" in header
