"""Calls of the public face that cannot bind their arguments — a misspelled keyword, a
missing argument — are an InputNameError naming the function and its arguments, never
Python's TypeError (an API fuzzer found 43 entry points that raised TypeError: compile,
simulate, latex, solve_boundary_value, the systems' and groupoids' constructors, …)."""

from __future__ import annotations

import enum
import inspect

import numpy as np
import pytest
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid import systems


def _public(kind):
    for name in sg.__all__:
        value = getattr(sg, name)
        if kind == "class" and inspect.isclass(value) and not issubclass(
                value, (BaseException, Warning, enum.Enum)):
            yield pytest.param(value, id=name)
        if kind == "function" and inspect.isfunction(value):
            yield pytest.param(value, id=name)


def _takes_any_keyword(func) -> bool:
    return any(p.kind is inspect.Parameter.VAR_KEYWORD
               for p in inspect.signature(func).parameters.values())


@pytest.mark.parametrize("func", list(_public("function")))
def test_a_misspelled_keyword_of_a_public_function_is_named(func):
    if _takes_any_keyword(func):
        pytest.skip("takes any keyword")
    with pytest.raises(sg.InputNameError, match="zzz_misspelled.*its arguments are"):
        func(zzz_misspelled=1)


@pytest.mark.parametrize("cls", list(_public("class")))
def test_a_misspelled_keyword_of_a_public_constructor_is_named(cls):
    if _takes_any_keyword(cls.__init__) or cls.__init__ is object.__init__:
        pytest.skip("takes any keyword, or no arguments")
    with pytest.raises(sg.InputNameError, match="zzz_misspelled"):
        cls(zzz_misspelled=1)


def test_the_methods_of_a_run_name_their_arguments():
    step = systems.rigid_body().euler_lagrange()
    sim = step.compile(backend="numpy")
    params = {"h": 0.1, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    traj = sim.simulate({"W": np.eye(3)}, 2, params)
    calls = [
        (lambda: step.compile(extrapolat=False), "compile_step", "extrapolate"),
        (lambda: sim.simulate({"W": np.eye(3)}, 2, params, evry=2), "Simulator.simulate",
         "every"),
        (lambda: sim.solve(), "Simulator.solve", "missing 2 required"),
        (lambda: step.latex(widht=300), "StepEquations.latex", "width"),
        (lambda: traj.save(), "Trajectory.save", "missing 1 required"),
        (lambda: sg.Trajectory.load("run.npz"), "Trajectory.load", "simulator"),
        (lambda: systems.rigid_body().noether(0).along(), "NoetherQuantity.along", "traj"),
    ]
    for call, owner, hint in calls:
        with pytest.raises(sg.InputNameError, match=owner) as info:
            call()
        assert hint in str(info.value)
    assert step.compile(backend="numpy", extrapolate=False).options.extrapolate is False

