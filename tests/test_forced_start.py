"""Starting a forced run from a physical momentum: ``from_momentum(..., forced=True)`` solves
the forced discrete Legendre transform F⁻L(g₁) − f⁻(g₁) = p₀ (Marsden–West eq. (3.2.4);
docs/conventions.md §20), checked against the transform written out by hand, and keeps the
order of the forced midpoint rule at 2 (from F⁻L = p₀ it drops to 1)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import symgroupoid as sg

h, k, c = sp.symbols("h k c", positive=True)
u = sp.Symbol("u", real=True)
K, C, U = 2.0, 0.3, 0.7


def _oscillator():
    """A damped, driven linear oscillator: L_d = h/2·(Δq/h)² − h/2·k·q̄², F = −c·v + u."""
    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h / 2 * ((q1 - q0) / h) ** 2 - h * k * ((q0 + q1) / 2) ** 2 / 2

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L,
                             parameters=[h, k, c], time_step=h, inputs=[u], name="driven",
                             forces=sg.midpoint_forces(lambda q, v: [-c * v[0] + u], h))


@pytest.fixture(scope="module")
def sim():
    return _oscillator().euler_lagrange().compile(backend="numpy")


def _forced_minus(q0, q1, dt):
    """−D₁L_d(q₀, q₁) − f⁻(q₀, q₁), by hand."""
    v, mid = (q1 - q0) / dt, (q0 + q1) / 2
    return v + dt * K * mid / 2 - dt / 2 * (-C * v + U)


def test_forced_start_solves_the_forced_transform(sim):
    dt, q0, p0 = 0.05, 1.0, 0.4
    params = {"h": dt, "k": K, "c": C}
    plain = sim.from_momentum({"q": q0}, [p0], params, inputs=[U])
    forced = sim.from_momentum({"q": q0}, [p0], params, inputs=[U], forced=True)
    (a0, a1), (b0, b1) = plain[:2], forced[:2]
    assert a0 == b0 == q0
    assert _forced_minus(b0, b1, dt) == pytest.approx(p0, abs=1e-14)
    v = (a1 - a0) / dt  # without the forces: F⁻L = p₀, off by f⁻ = O(h)
    assert v + dt * K * (a0 + a1) / 4 == pytest.approx(p0, abs=1e-14)
    assert abs(_forced_minus(a0, a1, dt) - p0) > 1e-3 * dt


def test_forced_start_keeps_the_order(sim):
    """Final-time error against DOP853 on q̈ = −k q − c q̇ + u from (q, p) = (1, 0)."""
    T = 1.0
    ref = solve_ivp(lambda t, y: [y[1], -K * y[0] - C * y[1] + U], (0, T), [1.0, 0.0],
                    method="DOP853", rtol=1e-13, atol=1e-13).y[0, -1]
    errors: dict = {False: [], True: []}
    for n in (40, 80, 160):
        params = {"h": T / n, "k": K, "c": C}
        for forced in errors:
            start = sim.from_momentum({"q": 1.0}, [0.0], params, inputs=[U], forced=forced)
            run = sim.simulate(start, n - 1, params, inputs=np.full((n - 1, 1), U))
            errors[forced].append(abs(run.states[-1][1] - ref))
    order = {f: math.log2(e[-2] / e[-1]) for f, e in errors.items()}
    assert abs(order[True] - 2) < 0.1 and abs(order[False] - 1) < 0.15, order


def test_forced_start_arguments(sim):
    with pytest.raises(sg.ShapeError, match="forced must be True or False"):
        sim.from_momentum({"q": 1.0}, [0.0], {"h": 0.1, "k": K, "c": C}, inputs=[U],
                          forced="yes")


@pytest.mark.parametrize("bad", [float("nan"), -0.1, 0, sp.nan])
def test_force_helpers_refuse_a_time_step_that_is_not_positive(bad):
    for helper in (sg.midpoint_forces, sg.trapezoid_forces):
        with pytest.raises(sg.DomainError, match="positive and finite"):
            helper(lambda q, v: [0], bad)


def test_one_step_names_the_shape_it_was_given(sim):
    """(``step(..., inputs=[[u]])`` said "need shape (1, 1) … got shape (1, 1, 1)": the
    shape of the (1, …) table it wraps one step's inputs in.)"""
    params = {"h": 0.05, "k": K, "c": C}
    state = sim.state({"q": (1.0, 1.0), "u": [U]}, params)
    assert np.array_equal(sim.step(state, params, inputs=U), sim.step(state, params, inputs=[U]))
    for bad, shape in (([[U]], "(1, 1)"), ([U, U], "(2,)")):
        with pytest.raises(sg.ShapeError, match=r"one step need shape \(1,\).*got shape "
                           + re.escape(shape)):
            sim.step(state, params, inputs=bad)
