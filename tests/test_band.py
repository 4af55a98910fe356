"""Band factors of a step whose Jacobian is banded once reordered (a chain in maximal
coordinates): the order found from the program's sparsity (reverse Cuthill–McKee), the
kernel's header, and runs that equal the NumPy twin bit for bit and the dense factors to
rounding."""

from __future__ import annotations

import numpy as np
import pytest
from kernel_support import needs_cc

from symgroupoid import codegen, systems
from symgroupoid.stepper import LU_PANEL_FROM, BandOrder


def chain_state(n: int, h: float = 0.01) -> np.ndarray:
    """The link chain hanging at angles θ_i = 0.5 + 0.1 i and swinging: (q_{k−1}, q_k, λ)."""
    theta = 0.5 + 0.1 * np.arange(n)
    points = np.cumsum(np.stack([np.sin(theta), -np.cos(theta)], 1), 0)
    moved = theta + h * (0.8 - 0.05 * np.arange(n))
    later = np.cumsum(np.stack([np.sin(moved), -np.cos(moved)], 1), 0)
    return np.concatenate([points.ravel(), later.ravel(), np.zeros(n)])


def chain_params(n: int) -> dict:
    return {"h": 0.01, "g": 9.81, **{f"l{i}": 1.0 for i in range(1, n + 1)}}


@pytest.fixture(scope="module")
def chain10():
    return systems.link_chain(10).euler_lagrange()


def test_the_band_order_of_a_link_chain_is_narrow_and_a_permutation(chain10):
    band = codegen.band_order(chain10)
    n = len(chain10.unknowns)
    assert isinstance(band, BandOrder) and sorted(band.order) == list(range(n))
    assert (band.kl, band.ku) == (2, 2)
    pattern = codegen.jacobian_pattern(chain10)
    i, j = np.nonzero(pattern[np.ix_(band.order, band.order)])
    assert (j - i).min() == -band.kl and (j - i).max() == band.ku
    assert codegen.band_order(chain10) == band  # deterministic


def test_dense_jacobians_and_small_steps_keep_dense_factors():
    assert codegen.band_order(systems.spherical_chain(8).euler_lagrange()) is None  # dense
    small = systems.link_chain(LU_PANEL_FROM // 3 - 1).euler_lagrange()
    assert len(small.unknowns) < LU_PANEL_FROM and codegen.band_order(small) is None
    assert "BAND" not in codegen.generate_c(small).header


def test_the_header_carries_the_band(chain10):
    band = codegen.band_order(chain10)
    kernel = codegen.generate_c(chain10)
    prefix = kernel.prefix.upper()
    assert f"#define {prefix}_BANDED 1" in kernel.header
    assert f"#define {prefix}_BAND_KL {band.kl}" in kernel.header
    assert f"#define {prefix}_BAND_ORDER {{{', '.join(map(str, band.order))}}}" in kernel.header
    assert "BAND_ORDER" not in kernel.cdef  # C only: cffi reads numbers
    assert f"{kernel.prefix}_band_eliminate(" in kernel.source


@needs_cc
def test_band_runs_equal_the_twin_bit_for_bit_and_dense_factors_to_rounding(chain10,
                                                                             monkeypatch):
    state, params = chain_state(10), chain_params(10)
    c = chain10.compile(backend="c").simulate(state, 30, params)
    numpy = chain10.compile(backend="numpy").simulate(state, 30, params)
    assert c.states.tobytes() == numpy.states.tobytes()
    assert list(c.newton_iterations) == list(numpy.newton_iterations)
    assert np.max(np.abs(c.constraint_residuals())) <= 1e-14
    # the dense factors for comparison: the NumPy backend's band order switched off (no
    # public switch exists, nor should one: the band changes no result beyond rounding)
    from symgroupoid.runtime import _backends

    monkeypatch.setattr(_backends, "band_order", lambda step: None)
    dense = chain10.compile(backend="numpy").simulate(state, 30, params)
    np.testing.assert_allclose(c.states, dense.states, rtol=0, atol=1e-12)


@needs_cc
def test_the_whole_jacobian_of_a_band_kernel_is_the_programs(chain10):
    """``<prefix>_residual_jacobian`` of a band kernel (the library's, from the kernel's band
    form) gives the whole matrix, zeros included, bit for bit as the program's NumPy form."""
    c = chain10.compile(backend="c").kernel
    numpy = chain10.compile(backend="numpy").kernel
    rng = np.random.default_rng(3)
    u = rng.normal(size=len(chain10.unknowns))
    known = chain_state(10) + 1e-3 * rng.normal(size=len(chain10.knowns))
    p = np.array([0.01, 9.81] + [1.0] * 10)
    F, J = c.residual_jacobian(u, known, p)
    nF, nJ = numpy.residual_jacobian(u, known, p)
    assert F.tobytes() == nF.tobytes() and J.tobytes() == nJ.tobytes()
    assert np.count_nonzero(J) == np.count_nonzero(codegen.jacobian_pattern(chain10))


@needs_cc
@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_a_band_kernel_refuses_bad_input_by_name(chain10, backend):
    """Hostile input to a band kernel's simulator gets the named errors before any step: a
    non-finite parameter, a link of length 0 (declared positive: the constraint's gradient
    would vanish), a state off the constraints, a state of the wrong length."""
    import symgroupoid as sg

    sim = chain10.compile(backend=backend)
    params, state = chain_params(10), chain_state(10)
    with pytest.raises(sg.SymgroupoidError, match="finite"):
        sim.simulate(state, 5, {**params, "g": float("nan")})
    with pytest.raises(sg.ParameterError, match="l2"):
        sim.simulate(state, 5, {**params, "l2": 0.0})
    off = state.copy()
    off[22] += 0.1  # point 2 at q_k moves off its link
    with pytest.raises(sg.SymgroupoidError, match="constraint"):
        sim.simulate(off, 5, params)
    with pytest.raises(sg.ShapeError):
        sim.simulate(state[:-1], 5, params)
    assert np.isfinite(sim.simulate(state, 5, params).states).all()


def test_a_step_on_a_time_groupoid_keeps_dense_factors(monkeypatch):
    """Its fixed-step phase replaces a row of the Jacobian, which a band form cannot hold:
    even with every band accepted, the time step gets no band order, the same chain of
    springs without time does (the stepper's C refuses the combination too, #error)."""
    import sympy as sp

    import symgroupoid as sg

    names = " ".join(f"q{i}" for i in range(1, 25))
    kappa = sp.Symbol("kappa", positive=True)

    def springs(source, target, dt):
        mid = [(a + b) / 2 for a, b in zip(source, target)]
        kinetic = sum((b - a) ** 2 for a, b in zip(source, target)) / (2 * dt)
        return kinetic - dt * kappa * sum((y - x) ** 2 for x, y in zip(mid, mid[1:])) / 2

    timed = sg.DiscreteSystem(sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace(names))),
                              lambda a: springs(a.source, a.target, a.t1 - a.t0),
                              parameters=[kappa], name="timed_springs").euler_lagrange()
    h = sp.Symbol("h", positive=True)
    plain = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace(names)),
                              lambda a: springs(a.source, a.target, h),
                              parameters=[kappa, h], name="springs").euler_lagrange()
    # every band accepted (the test's only reason to reach inside): the time is the reason
    from symgroupoid.codegen import _band

    monkeypatch.setattr(_band, "BAND_WIDTH_FRACTION", 10.0)
    assert codegen.band_order(plain) is not None
    assert codegen.band_order(timed) is None
