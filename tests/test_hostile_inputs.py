"""Hostile input sequences at every entry point of a forced system (docs/conventions.md
§20): ``Simulator.simulate(..., inputs=)``, ``Simulator.step(..., inputs=)``,
``Simulator.simulate_batch(..., inputs=)`` and ``sg.sweep(..., inputs=)``.

Each example takes a valid input sequence of a damped oscillator driven by an input u and
makes it malformed (tests/_hostile.py: an entry non-finite, huge, complex, a string or None;
an entry dropped or added; the shape or dtype changed; nested; scaled to overflow; or one of
the spellings that must be accepted), or is anything at all.  The invariant
(:func:`_hostile.judge`): a SymgroupoidError naming the inputs (or, for a numerical failure,
the system), or a run whose inputs are the values given and whose every step solves the
forced step equations.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from _hostile import PROFILES, judge, junk, near, profile, step_residual_ok
from _systems import driven_oscillator
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg

PARAMS = {"h": 0.05, "k": 2.0, "c": 0.3}
START = {"x": (0.2, 0.21), "u": 0.1}
STEPS = 6
NAMES = ("inputs", "input", "u")


@functools.cache
def driven():
    """The damped oscillator on R driven by u (midpoint forces), on the NumPy backend (a
    hostile example is one derivation and no C build)."""
    return driven_oscillator("driven").euler_lagrange().compile(backend="numpy")


def _meant(value, steps: int) -> np.ndarray:
    """The inputs a value that was accepted stands for: one value for every step, or the
    first ``steps`` of a sequence."""
    arr = np.asarray(value, dtype=float).reshape(-1)
    return np.full(steps, arr[0]) if arr.size == 1 else arr[:steps]


def _check_run(traj, inputs: np.ndarray) -> None:
    """The run took ``inputs`` and every step solves the forced step equations (the known
    state of step j carries the inputs of the arrow it computes in its last slot)."""
    sim = driven()
    assert np.array_equal(traj["u"][1:], inputs)
    p = sim.parameters(PARAMS)
    for j in range(len(traj.states) - 1):
        known = traj.states[j].copy()
        known[-1] = inputs[j]
        x1_next = traj.states[j + 1][1]
        step_residual_ok(sim.equations, np.array([x1_next]), known, p)


def _valid_sequence() -> np.ndarray:
    return np.linspace(-0.5, 0.5, STEPS)[:, None]


@pytest.mark.parametrize("run", PROFILES)
def test_simulate_inputs(run):
    sim = driven()

    @profile(run, 25)
    @given(st.one_of(near(_valid_sequence()), near([0.3]), junk()))
    def check(value):
        traj = judge("simulate(inputs=)",
                     lambda: sim.simulate(START, STEPS, PARAMS, inputs=value), NAMES,
                     owner=sim.name)
        if traj is not None:
            _check_run(traj, _meant(value, STEPS))

    check()


@pytest.mark.parametrize("run", PROFILES)
def test_step_inputs(run):
    sim = driven()
    state = sim.state(START, PARAMS)

    @profile(run, 25)
    @given(st.one_of(near([0.3]), junk()))
    def check(value):
        after = judge("step(inputs=)", lambda: sim.step(state, PARAMS, inputs=value), NAMES,
                      owner=sim.name)
        if after is not None:
            meant = _meant(value, 1)
            expected = sim.simulate(START, 1, PARAMS, inputs=meant[:, None]).states[1]
            assert np.array_equal(after[:-1], expected[:-1])

    check()


@pytest.mark.parametrize("run", PROFILES)
def test_batch_and_sweep_inputs(run):
    sim = driven()
    starts = [START, {"x": (0.1, 0.12), "u": 0.0}]
    valid = np.stack([_valid_sequence(), -_valid_sequence()])

    @profile(run, 20)
    @given(st.one_of(near(valid), near(_valid_sequence()), junk()),
           st.sampled_from(["batch", "sweep"]))
    def check(value, entry):
        if entry == "batch":
            call = lambda: sim.simulate_batch(starts, STEPS, PARAMS, inputs=value)  # noqa: E731
        else:
            call = lambda: sg.sweep(sim, starts, PARAMS, STEPS, inputs=value,  # noqa: E731
                                    workers=1, progress=False)
        result = judge(f"{entry}(inputs=)", call, NAMES, owner=sim.name)
        if result is None:
            return
        runs = list(result) if entry == "batch" else list(result.trajectories)
        arr = np.asarray(value, dtype=float)
        for b, traj in enumerate(runs):  # (a failed run: the steps before its failure)
            meant = _meant(arr[b] if arr.ndim == 3 else arr, STEPS)
            _check_run(traj, meant[:len(traj.states) - 1])

    check()


#: a valid point of the step equations' NumPy evaluations: the new arrow's x_{k+1}, the known
#: state (x_{k−1}, x_k, u_k, u_{k+1}) and the parameters (h, k, c) in order
POINT = {"unknowns": [0.22], "knowns": [0.2, 0.21, 0.1, -0.1], "params": [0.05, 2.0, 0.3]}
EVALUATIONS = {"evaluate": lambda eq, u, k, p: eq.evaluate(u, k, p),
               "advance": lambda eq, u, k, p: eq.advance(u, k, p),
               "input_jacobian": lambda eq, u, k, p: eq.input_jacobian(u, k, p)}


@pytest.mark.parametrize("run", PROFILES)
def test_step_equation_evaluations(run):
    """``step.evaluate``, ``step.advance`` and ``step.input_jacobian`` (the Python route to
    ∂F/∂u a controller takes) with one argument made hostile: a bare IndexError for short
    knowns, a silent result for long ones, NaN matrices from NaN entries, a KeyError for a
    missing parameter; now a named error, or the values at the arguments as floats."""
    equations = driven().equations
    names = {"unknowns": ("unknowns",), "knowns": ("knowns",),
             "params": ("parameter", "parameters")}

    @profile(run, 30)
    @given(st.sampled_from(sorted(EVALUATIONS)), st.sampled_from(sorted(POINT)),
           st.data())
    def check(entry, argument, data):
        value = data.draw(st.one_of(near(POINT[argument]), junk()))
        given_point = {**POINT, argument: value}
        call = EVALUATIONS[entry]
        result = judge(f"step.{entry}", lambda: call(equations, *given_point.values()),
                       names[argument])
        if result is None:
            return
        as_floats = {**POINT, argument: np.asarray(value, dtype=float)}
        expected = call(equations, *as_floats.values())
        for got, want in zip(np.atleast_1d(result) if entry != "evaluate" else result,
                             np.atleast_1d(expected) if entry != "evaluate" else expected):
            assert np.all(np.isfinite(got)) and np.array_equal(got, want)

    check()


@pytest.mark.parametrize("value", [[True] + [0.2] * (STEPS - 1), (0.1, False, 0.0, 0.1, 0.2, 0.3),
                                   [[0.3]] * (STEPS - 1) + [[np.True_]]])
def test_a_bool_in_a_list_of_numbers_is_refused(value):
    """NumPy reads [True, 0.2] as [1.0, 0.2]; a bool array and an object array holding True
    were already refused, a list was not (nor a state given as a list)."""
    sim = driven()
    with pytest.raises(sg.ShapeError, match="a bool among them"):
        sim.simulate(START, STEPS, PARAMS, inputs=value)
    with pytest.raises(sg.ShapeError, match="a bool among them"):
        sim.simulate({"x": [True, 0.21], "u": 0.1}, STEPS, PARAMS, inputs=_valid_sequence())
