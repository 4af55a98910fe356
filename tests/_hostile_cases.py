"""Cases and argument strategies shared by the hostile-input tests of the runtime.

A :class:`Case` is a simulator with one valid call (named and flat initial states,
parameters, a momentum for ``from_momentum``): three tiny systems on the NumPy backend and
the three seed systems on their C kernels.  The strategies draw malformed versions of each
argument, with the names a clear error about them must mention.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import pytest
from _hostile import (
    accel,
    assert_finite,
    diagonal,
    hostile,
    junk,
    near,
    oscillator,
    scalars,
    verify_trajectory,
)
from hypothesis import strategies as st
from kernel_support import HAVE_CC, SEED_DATA, compiled, initial_state

import symgroupoid as sg
from symgroupoid._arguments import integer_argument

# --- the systems --------------------------------------------------------------------------------


@dataclass
class Case:
    """A simulator with a valid call: named and flat initial states, parameters, and (first
    order) a base point and momentum for ``from_momentum``."""

    sim: sg.Simulator
    named: dict
    flat: np.ndarray
    params: dict
    momentum: tuple | None = None
    names: list = field(default_factory=list)

    @property
    def step(self) -> sg.StepEquations:
        return self.sim.equations


def named_state(sim: sg.Simulator, flat: np.ndarray) -> dict:
    """The named parts of a flat state (the inverse of ``Simulator.state``)."""
    layout = sim.layout
    out = {}
    parts = dict(layout.parts)
    if layout.multiplier_part is not None:
        parts["lambda"] = layout.multiplier_part
    covered: set = set()
    for name, part in parts.items():
        index = set(part.index[part.index >= 0].tolist())
        if index & covered:  # e.g. "Gamma_1" after "Gamma": one of them is enough
            continue
        covered |= index
        value = layout.view(flat[None], name)
        out[name] = value if part.is_sequence else value[0]
    return out


@functools.cache
def tiny_case(name: str) -> Case:
    system = {"oscillator": oscillator, "diagonal": diagonal, "accel": accel}[name]()
    sim = system.euler_lagrange().compile(backend="numpy")
    if name == "oscillator":
        params, momentum = {"h": 0.1, "k": 1.0}, ({"q": 0.1}, [0.5])
        flat = sim.state({"q": (0.1, 0.2)})
    elif name == "diagonal":
        params, momentum = {"h": 0.1, "k": 1.0}, ({"x": 0.0, "y": 0.0}, [0.5, 0.2])
        flat = sim.state({"x": (0.0, 0.1), "y": (0.0, 0.1), "lambda": [0.0]})
    else:
        params, momentum = {"h": 0.1}, None
        flat = sim.state({"q": [0.0, 0.1, 0.21, 0.33], "lambda": [[0.0], [0.0]]})
    return Case(sim, named_state(sim, flat), flat, params, momentum)


@functools.cache
def seed_case(name: str) -> Case:
    sim = compiled(name)
    params, config, momentum = SEED_DATA[name]
    flat = initial_state(sim, name)
    return Case(sim, named_state(sim, flat), flat, dict(params), (config, momentum))


@functools.cache
def increments_case() -> Case:
    """One body of the 3D chain in increment coordinates (TrivialisedPairGroupoid): a
    configuration R1 and an increment F1 stored as F1 − I."""
    from kernel_support import SESSION_CACHE

    from symgroupoid import systems

    sim = systems.spherical_chain_increments(1).euler_lagrange().compile(
        backend="c", cache_dir=SESSION_CACHE)
    params = {"h": 0.01, "g": 9.81}
    R = sg.SO3("R").numeric_tau([0.4, 0.3, 0.2])
    flat = sim.from_momentum({"R1": R}, [0.2, -0.1, 0.3], params)
    return Case(sim, named_state(sim, flat), flat, params, ({"R1": R}, (0.2, -0.1, 0.3)))


CASES = ["oscillator", "diagonal", "accel",
         *(pytest.param(n, marks=pytest.mark.skipif(not HAVE_CC, reason="no C compiler"))
           for n in ("rigid_body", "plate_ball", "heavy_top", "increments"))]


def case_of(name: str) -> Case:
    if name == "increments":
        return increments_case()
    return tiny_case(name) if name in ("oscillator", "diagonal", "accel") else seed_case(name)


# --- strategies of arguments --------------------------------------------------------------------

#: step counts: valid small ones, negative, non-integral, and far beyond memory
counts = st.one_of(st.integers(0, 12), st.integers(-(2**70), -1),
                   st.integers(2**45, 2**90), scalars)


def _count(value) -> int | None:
    try:
        return integer_argument(value, "n")
    except sg.SymgroupoidError:
        return None


def runnable(steps, every=1, *, memory_checked: bool = True):
    """Keep a run short: a step count that would be accepted and is above 50 becomes 12,
    unless the run is refused up front for its memory (every = 1 and 2⁴⁵ steps or more:
    far beyond any machine, :class:`~symgroupoid.TrajectoryTooLargeError`)."""
    n, e = _count(steps), _count(every)
    if n is None or n <= 50:
        return steps
    if memory_checked and n >= 2**45 and e == 1:
        return steps
    return 12


@st.composite
def initial_states(draw, case: Case):
    """(value, names): a malformed initial state near the valid one."""
    how = draw(st.sampled_from(["part", "flat", "unknown", "missing", "junk", "valid"]))
    if how == "part":
        key = draw(st.sampled_from(sorted(case.named)))
        state = dict(case.named)
        state[key] = draw(hostile(case.named[key]))
        return state, [key, "state", "initial"]
    if how == "flat":
        return draw(near(case.flat)), ["state", "known", "initial"]
    if how == "unknown":
        key = draw(st.one_of(st.text(max_size=4), st.integers(), st.none()))
        return {**case.named, key: draw(st.floats())}, ["state", str(key)]
    if how == "missing":
        key = draw(st.sampled_from(sorted(case.named)))
        return {k: v for k, v in case.named.items() if k != key}, [key, "state"]
    if how == "junk":
        return draw(junk()), ["state", "initial"]
    return case.named, ["state"]


@st.composite
def parameter_sets(draw, case: Case):
    """(value, names): malformed parameters — one value, a name, or the whole argument."""
    how = draw(st.sampled_from(["value", "extra", "missing", "sequence", "junk"]))
    if how == "value":
        key = draw(st.sampled_from(sorted(case.params)))
        value = draw(st.one_of(scalars, near(case.params[key]),
                               st.floats(-1e300, 1e300)))
        return {**case.params, key: value}, [key]
    if how == "extra":
        key = draw(st.text(min_size=1, max_size=4))
        return {**case.params, key: 1.0}, [key, "parameter"]
    if how == "missing":
        key = draw(st.sampled_from(sorted(case.params)))
        return {k: v for k, v in case.params.items() if k != key}, [key]
    if how == "sequence":
        values = [case.params[str(s)] for s in case.step.parameters]
        return draw(near(values)), ["parameter", "parameters"]
    return draw(junk()), ["parameter", "parameters"]


OPTION_FIELDS = ["tol_residual", "tol_step", "max_iterations", "floor_factor", "extrapolate",
                 "trust_factor"]


@st.composite
def newton_options(draw):
    """(value, names): a malformed ``options`` argument or NewtonOptions field."""
    if draw(st.booleans()):
        return draw(junk()), ["options"]
    key = draw(st.sampled_from(OPTION_FIELDS))
    value = draw(st.one_of(scalars, st.floats(0, 1e-3), st.integers(0, 60)))
    return OptionFields({key: value}), [key, "NewtonOptions"]


def tolerance_of(options) -> dict:
    """The accuracy a solve with ``options`` promises (user tolerances loosen it)."""
    if not isinstance(options, sg.NewtonOptions):
        return {}
    rel = max(1e-7, 100 * options.tol_step, 4 * options.floor_factor * 2.2e-16)
    return {"rel": rel, "atol": options.tol_residual}


def check_run(case: Case, params, options=None):
    """The verification of a trajectory: finite, every step solving the equations."""
    p = case.sim.parameters(params)
    tol = tolerance_of(options)

    def verify(traj):
        if tol.get("atol", 0) > 0 or tol.get("rel", 1e-7) > 1e-7:
            assert_finite(traj.states, "trajectory")
            return
        verify_trajectory(case.step, traj, p)
    return verify


class OptionFields(dict):
    """Fields of a NewtonOptions drawn by :func:`newton_options`, built inside the call."""


def built_options(value):
    """An :class:`OptionFields` draw becomes ``NewtonOptions(**fields)``; anything else is
    passed on as drawn."""
    if isinstance(value, OptionFields):
        return sg.NewtonOptions(**value)
    return value
