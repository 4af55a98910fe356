"""Hostile values in forces, the force helpers and the forced Noether balance.

Each test states the defect it pins (the behaviour before the fix in parentheses).
"""

from __future__ import annotations

import time

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

h, k = sp.symbols("h k", positive=True)
u = sp.Symbol("u", real=True)
LINE = sg.PairGroupoid(sg.EuclideanSpace(["x"]))
PLANE = sg.EuclideanSpace("a b")


def _oscillator(g):
    (x0,), (x1,) = g.source, g.target
    return h * (((x1 - x0) / h) ** 2 / 2 - k / 2 * ((x0 + x1) / 2) ** 2)


def _forced(forces) -> sg.DiscreteSystem:
    return sg.DiscreteSystem(LINE, _oscillator, parameters=[h, k], inputs=[u], time_step=h,
                             name="driven", forces=forces)


def _continuous(F) -> sg.ContinuousSystem:
    return sg.ContinuousSystem(PLANE, lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2,
                               parameters=[h], forces=F, inputs=[u], name="pushed")


def test_a_force_constant_beyond_a_double_is_refused_by_name():
    """(1e400 reached the NumPy program as the literal `inf`: a raw NameError at the first
    step, a compiler error in C.)"""
    big = sp.Float("1e400")
    with pytest.raises(sg.InvalidExpressionError, match="beyond the range of a double"):
        _forced(lambda g: ([big * u], [0])).euler_lagrange()


@pytest.mark.parametrize("step, message", [
    (sp.Float("1e400"), "positive and finite"), (sp.Float("1e-400"), "positive and finite"),
    (-h, "which its symbols' assumptions make negative")])
def test_a_force_helper_refuses_a_step_that_is_not_a_positive_double(step, message):
    """(−h pushed the run backwards; 1e-400 rounded to zero and the forces vanished.)"""
    for helper in (sg.midpoint_forces, sg.trapezoid_forces):
        with pytest.raises(sg.DomainError, match=message):
            helper(lambda q, v: [u], step)


@pytest.mark.parametrize("value", [{0: u, 1: 0}, "12", b"12", {u, 0}],
                         ids=["dict", "str", "bytes", "set"])
def test_a_force_that_is_not_a_list_is_refused(value):
    """(A dict was read as its keys, a string as its digits, bytes as their codes and a set
    in its own order: the run went on with forces nobody wrote.)"""
    with pytest.raises(sg.ShapeError):
        _continuous(lambda q, v: value).discretize(h).euler_lagrange()
    with pytest.raises(sg.ShapeError):
        _plane_system(sg.midpoint_forces(lambda q, v: value, h)).euler_lagrange()


def _plane_system(forces) -> sg.DiscreteSystem:
    return sg.DiscreteSystem(sg.PairGroupoid(PLANE), lambda g: sum(
        (b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h), parameters=[h],
        inputs=[u], time_step=h, forces=forces, name="plane")


def test_a_dissipation_function_that_is_a_string_or_not_finite_is_refused():
    """(A string's symbols were not the velocities and NaN differentiated to zero: both runs
    were the undamped one, bit for bit.)"""
    text = sg.rayleigh_damping(lambda q, v: "(v0**2 + v1**2)/2", h)
    with pytest.raises(sg.ShapeError, match="string"):
        _plane_system(text).euler_lagrange()
    nan = sg.rayleigh_damping(lambda q, v: sp.nan * (v[0] ** 2 + v[1] ** 2), h)
    with pytest.raises(sg.InvalidExpressionError, match="nan|NaN"):
        _plane_system(nan).euler_lagrange()


def test_a_joint_torque_of_absurd_rank_is_refused_at_once():
    """(Any rank up to 2**53 was accepted and a list of that many zeros built at the first
    call: 27 s at 1e7, a MemoryError at 2**40.)"""
    start = time.perf_counter()
    with pytest.raises(sg.ShapeError, match="rank must be at most"):
        sg.joint_torque(10 ** 9, [0], [1], [u], h)
    assert time.perf_counter() - start < 1.0


def test_a_joint_torque_on_one_section_twice_is_refused():
    """+τ and −τ on the same section cancel: the force was identically zero, accepted."""
    with pytest.raises(sg.ShapeError, match=r"section\(s\) \[0\] are on both bodies"):
        sg.joint_torque(3, [0, 1], [0, 2], [u, u], h)


@pytest.mark.parametrize("step", [0.01, sp.Symbol("c", positive=True)])
def test_a_force_helper_written_for_another_time_step_is_refused(step):
    """midpoint_forces(F, 0.01) in a system whose time step is h: at h = 0.05 every force
    was a fifth of what it should be, without a word."""
    with pytest.raises(sg.DomainError, match="written for the time step"):
        _forced(sg.midpoint_forces(lambda q, v: [u], step))
    _forced(sg.midpoint_forces(lambda q, v: [u], h))  # its own time step: accepted


def _free_run(start, inputs, section):
    def L(g):
        (x0,), (x1,) = g.source, g.target
        return (x1 - x0) ** 2 / (2 * h)

    system = sg.DiscreteSystem(LINE, L, parameters=[h], inputs=[u], time_step=h, name="free",
                               forces=lambda g: ([h / 2 * u], [h / 2 * u]))
    sim = system.euler_lagrange().compile(backend="numpy")
    run = sim.simulate({"x": start, "u": inputs}, 2, {"h": 1.0}, inputs=[[inputs]] * 2)
    return system.noether(section), run


def test_an_impulse_that_overflows_is_an_error_not_inf():
    """(impulse returned [inf, inf] and [nan, nan] on finite runs where along() refused.)"""
    nq, run = _free_run((1e10, 1e10), 1e300, lambda q: [q[0]])
    assert np.isfinite(run.states).all()
    with pytest.raises(sg.DomainError, match="impulse is not finite at step 0"):
        nq.impulse(run)
    nq, run = _free_run((1e200, 1e200), 0.0, lambda q: [q[0] ** 2])
    with pytest.raises(sg.DomainError, match="not finite at step 0"):
        nq.impulse(run)


@pytest.mark.parametrize("value, error, message", [
    ("abc", sg.ParameterError, "not a number"), (float("nan"), sg.DomainError, "finite"),
    (-1.0, sg.DomainError, "declared positive")])
def test_the_parameters_a_trajectory_carries_are_checked(value, error, message):
    """(A NaN or negative h gave a NaN or wrong impulse silently, a string a raw
    ValueError.)"""
    nq, run = _free_run((0.0, 0.1), 1.0, lambda q: [1])
    run.parameters["h"] = value
    for entry in (nq.impulse, nq.along):
        with pytest.raises(error, match=message):
            entry(run)


def test_the_messages_about_inputs_say_where_an_input_belongs():
    """(An input in L was told to be declared a parameter, which was then refused as both;
    a continuous system with inputs and no forces was told the discrete forces' signature;
    a force with an undeclared input was pointed to parameters only.)"""
    plane = lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2  # noqa: E731
    in_L = sg.ContinuousSystem(PLANE, lambda q, v: plane(q, v) - u * q[0], parameters=[h],
                               forces=lambda q, v: [u, 0], inputs=[u], name="in_L")
    with pytest.raises(sg.UndeclaredSymbolError, match="declared as input.*use it in forces="):
        in_L.discretize(h).euler_lagrange()
    with pytest.raises(sg.UnsupportedFeatureError, match=r"forces=F with F\(q, v\)"):
        sg.ContinuousSystem(PLANE, plane, parameters=[h], inputs=[u], name="no_forces")
    undeclared = sg.ContinuousSystem(PLANE, plane, parameters=[h],
                                     forces=lambda q, v: [u, 0], name="undeclared")
    with pytest.raises(sg.UndeclaredSymbolError, match=r"in inputs=\[\.\.\.\]"):
        undeclared.discretize(h).euler_lagrange()
