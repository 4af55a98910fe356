"""Hostile input at the runtime entry points: ``Simulator.simulate``, ``stream``, ``step``,
``solve``, ``from_momentum``, ``state``, ``NewtonOptions`` and ``compile_step``.

Each example takes a valid call on one of six systems (three tiny ones on the NumPy backend,
the three seed systems on their C kernels) and replaces one argument — or, in the chaos
property, every argument — by a malformed value: the wrong type, shape, dtype or value
(NaN, ±inf, huge, negative, booleans, strings, nested lists, complex numbers, dates, a matrix
off its group, a state off the constraints, unknown or missing names).  The invariant
(tests/_hostile.py, :func:`judge`): a correct, finite result — every step's equations
checked through ``StepEquations.evaluate``, the momentum of ``from_momentum`` through the
system's Legendre transform — or a SymgroupoidError naming the argument.  The C kernels are
called in-process here (every buffer is checked before the call, tests/test_c_boundary.py);
tests/test_hostile_isolated.py runs a property against a C kernel in a child process, where
a crash would show as a signal instead of killing the test run.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import pytest
from _hostile import (
    PROFILES,
    accel,
    assert_finite,
    diagonal,
    hostile,
    judge,
    junk,
    near,
    oscillator,
    profile,
    scalars,
    step_residual_ok,
    verify_trajectory,
)
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    HAVE_CC,
    SEED_DATA,
    compiled,
    initial_state,
    isolated_cache,
    seed_step,
)

import symgroupoid as sg
from symgroupoid.runtime._validate import integer_argument

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


CASES = ["oscillator", "diagonal", "accel",
         *(pytest.param(n, marks=pytest.mark.skipif(not HAVE_CC, reason="no C compiler"))
           for n in ("rigid_body", "plate_ball", "heavy_top"))]


def case_of(name: str) -> Case:
    return tiny_case(name) if name in ("oscillator", "diagonal", "accel") else seed_case(name)


# --- strategies of arguments --------------------------------------------------------------------

#: step counts: valid small ones, negative, non-integral, and far beyond memory
counts = st.one_of(st.integers(0, 12), st.integers(-(2**70), -1),
                   st.integers(2**45, 2**90), scalars)


def bounded(value):
    """Keep a run short: a count that would be accepted but is large becomes 12."""
    try:
        n = integer_argument(value, "n")
    except sg.SymgroupoidError:
        return value
    return 12 if 50 < n < 2**45 else value


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


OPTION_FIELDS = ["tol_residual", "tol_step", "max_iterations", "floor_factor", "extrapolate"]


@st.composite
def newton_options(draw):
    """(value, names): a malformed ``options`` argument or NewtonOptions field."""
    if draw(st.booleans()):
        return draw(junk()), ["options"]
    key = draw(st.sampled_from(OPTION_FIELDS))
    value = draw(st.one_of(scalars, st.floats(0, 1e-3), st.integers(0, 60)))
    return ("fields", {key: value}), [key, "NewtonOptions"]


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


# --- simulate / stream / step: one argument malformed -------------------------------------------

@st.composite
def simulate_calls(draw, case: Case, chaos: bool = False):
    """(kwargs, names) of a simulate call with one argument (or, with ``chaos``, every
    argument) malformed."""
    args = {"initial": case.named, "steps": 3, "params": case.params, "every": 1,
            "options": None, "callback": None}
    names: list[str] = []
    which = (["initial", "steps", "params", "every", "options", "callback"] if chaos
             else [draw(st.sampled_from(["initial", "steps", "params", "every", "options",
                                         "callback"]))])
    for arg in which:
        if arg == "initial":
            args["initial"], more = draw(initial_states(case))
        elif arg in ("steps", "every"):
            args[arg], more = bounded(draw(counts)), [arg]
        elif arg == "params":
            args["params"], more = draw(parameter_sets(case))
        elif arg == "options":
            args["options"], more = draw(newton_options())
        else:
            args["callback"] = draw(st.one_of(junk(), st.just(lambda piece: None)))
            more = ["callback"]
        names += more
    return args, names


def _options(value):
    """A ("fields", {...}) draw becomes NewtonOptions(**fields) (built inside the call)."""
    if isinstance(value, tuple) and len(value) == 2 and value[0] == "fields":
        return sg.NewtonOptions(**value[1])
    return value


def run_simulate(case: Case, args: dict, names: list, entry: str, how: str):
    sim = case.sim

    def call():
        options = _options(args["options"])
        if how == "simulate":
            return sim.simulate(args["initial"], args["steps"], args["params"],
                                every=args["every"], callback=args["callback"],
                                options=options)
        if how == "stream":
            return list(sim.stream(args["initial"], args["steps"], args["params"],
                                   every=args["every"], options=options))
        return sim.step(args["initial"], args["params"], options=options)

    def verify(result):
        if _params_or_none(case, args["params"]) is None:
            raise AssertionError(f"{entry} accepted malformed parameters {args['params']!r}")
        check = check_run(case, args["params"], _options(args["options"]))
        if how == "simulate":
            check(result)
        elif how == "stream":
            for piece in result:
                check(piece)
        else:
            assert_finite(result, "the next state")

    judge(entry, call, names, owner=sim.name, verify=verify)


def _params_or_none(case: Case, params):
    try:
        return case.sim.parameters(params)
    except sg.SymgroupoidError:
        return None


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
@pytest.mark.parametrize("how", ["simulate", "stream", "step"])
def test_simulate_with_one_malformed_argument(name, how, run):
    case = case_of(name)
    examples = {"simulate": 14, "stream": 5, "step": 5}[how]

    @profile(run, examples)
    @given(call=simulate_calls(case))
    def prop(call):
        args, names = call
        if how == "step":
            names = [n for n in names if n not in ("steps", "every", "callback")] or ["state"]
        run_simulate(case, args, names, f"Simulator.{how}", how)

    prop()


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_simulate_with_every_argument_malformed(name, run):
    case = case_of(name)

    @profile(run, 6)
    @given(call=simulate_calls(case, chaos=True))
    def prop(call):
        args, names = call
        run_simulate(case, args, names, "Simulator.simulate (chaos)", "simulate")

    prop()


# --- solve ------------------------------------------------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_solve_with_malformed_arguments(name, run):
    case = case_of(name)
    sim, step = case.sim, case.step
    p0 = sim.parameters(case.params)
    u0 = sim.kernel.predict(case.flat, p0)

    @profile(run, 10)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["state", "params", "guess", "options"]))
        state, params, guess, options, names = case.flat, case.params, None, None, []
        if which == "state":
            state, names = data.draw(initial_states(case))
        elif which == "params":
            params, names = data.draw(parameter_sets(case))
        elif which == "guess":
            guess, names = data.draw(st.one_of(near(u0), junk())), ["guess"]
        else:
            options, names = data.draw(newton_options())

        def verify(result):
            u, iterations, norm = result
            assert_finite(u, "solve: u")
            p = sim.parameters(params)
            known = sim.state(state)
            tol = tolerance_of(_options(options))
            if not tol or (tol["atol"] == 0 and tol["rel"] <= 1e-7):
                step_residual_ok(step, u, known, p)

        judge("Simulator.solve", lambda: sim.solve(state, params, guess=guess,
                                                   options=_options(options)),
              names, owner=sim.name, verify=verify)

    prop()


# --- from_momentum ----------------------------------------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_from_momentum_with_malformed_arguments(name, run):
    case = case_of(name)
    sim = case.sim
    if case.momentum is None:  # second order: the first arrow g₀ and a momentum
        G = case.step.groupoid
        arrow0 = case.flat[sim.layout.arrow_index[-1]]
        valid = (arrow0, [0.1, 0.2])
    else:
        valid = case.momentum
    config0, momentum0 = valid

    @profile(run, 10)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["configuration", "momentum", "params"]))
        config, momentum, params, names = config0, momentum0, case.params, []
        if which == "configuration":
            if isinstance(config0, dict) and config0 and data.draw(st.booleans()):
                key = data.draw(st.sampled_from(sorted(config0)))
                config = {**config0, key: data.draw(hostile(config0[key]))}
                names = [key, "configuration"]
            else:
                config = data.draw(st.one_of(junk(), near(np.zeros(1)) if config0 is None
                                             else near(np.asarray(
                                                 list(config0.values()) if isinstance(
                                                     config0, dict) else config0,
                                                 dtype=float))))
                names = ["configuration", "arrow", "g₀", "base point"]
        elif which == "momentum":
            momentum, names = data.draw(hostile(momentum0)), ["momentum"]
        else:
            params, names = data.draw(parameter_sets(case))

        def verify(state):
            assert_finite(state, "from_momentum: the state")
            p = sim.parameters(params)
            sim.state(state, p)  # a consistent initial state
            if case.step.order != 1:
                return
            system = case.step.system
            layout = sim.layout
            arrow = layout.arrows(np.asarray(state)[None])[-1]
            lam = layout.view(np.asarray(state)[None], "lambda")[-1]
            minus, _ = system.legendre().evaluate(arrow, lam, p)
            target = np.asarray(momentum, float).ravel()
            assert np.allclose(np.asarray(minus, float).ravel(), target, rtol=1e-7,
                               atol=1e-7 * (1 + np.abs(target).max())), (minus, target)

        judge("Simulator.from_momentum",
              lambda: sim.from_momentum(config, momentum, params), names, owner=sim.name,
              verify=verify)

    prop()


# --- Simulator.state and NewtonOptions and compile_step ------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_state_with_malformed_parts(name, run):
    case = case_of(name)

    @profile(run, 10)
    @given(initial=initial_states(case))
    def prop(initial):
        value, names = initial

        def verify(state):
            assert_finite(state, "state")
            assert np.shape(state) == case.flat.shape

        judge("Simulator.state", lambda: case.sim.state(value, case.params), names,
              owner=case.sim.name, verify=verify)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_newton_options_fields(run):
    @profile(run, 25)
    @given(key=st.sampled_from(OPTION_FIELDS), value=st.one_of(scalars, junk()))
    def prop(key, value):
        def verify(options):
            got = getattr(options, key)
            if key == "max_iterations":
                assert isinstance(got, int) and 0 <= got <= 2**31 - 1
            elif key == "extrapolate":
                assert isinstance(got, bool)
            else:
                assert isinstance(got, float) and np.isfinite(got) and got >= 0

        judge("NewtonOptions", lambda: sg.NewtonOptions(**{key: value}), [key],
              verify=verify)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_compile_step_arguments(run):
    """backend, flags, cache_dir and the Newton options of ``compile_step`` (NumPy backend
    or a flag set that needs no build: a malformed argument must be refused up front)."""
    step = tiny_case("oscillator").step

    @profile(run, 25)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["backend", "flags", "cache_dir", "tol_residual",
                                           "tol_step", "max_iterations", "floor_factor"]))
        value = data.draw(st.one_of(scalars, junk(), st.sampled_from(
            ["numpy", "c", "auto", "C", " numpy", "-O2", ["-O2"], [3], ["-O2", None],
             ["a\0b"], "a\0b"])))
        kwargs = {"backend": "numpy", which: value}
        if which in ("flags", "cache_dir"):
            kwargs["backend"] = "numpy"  # the value is checked even where it is not used

        def verify(sim):
            assert isinstance(sim, sg.Simulator)
            if which == "backend":
                assert value in ("numpy", "c", "auto")
            traj = sim.simulate({"q": (0.1, 0.2)}, 2, {"h": 0.1, "k": 1.0})
            verify_trajectory(step, traj, sim.parameters({"h": 0.1, "k": 1.0}))

        if which == "backend" and value in ("c", "auto"):
            kwargs["backend"] = "numpy"  # a valid choice; building C is tested elsewhere
        judge("compile_step", lambda: sg.compile_step(step, **kwargs), [which],
              verify=verify)

    prop()

