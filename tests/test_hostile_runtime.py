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
tests/test_hostile_isolated.py runs hostile calls against a C kernel in a child process,
where a crash would show as a signal instead of killing the test run.
"""

from __future__ import annotations

import numpy as np
import pytest
from _hostile import (
    PROFILES,
    assert_finite,
    hostile,
    judge,
    junk,
    near,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
    step_residual_ok,
)
from _hostile_cases import (
    CASES,
    OPTION_FIELDS,
    Case,
    built_options,
    case_of,
    check_run,
    counts,
    initial_states,
    newton_options,
    parameter_sets,
    runnable,
    tiny_case,
    tolerance_of,
)
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg

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
            args[arg], more = draw(counts), [arg]
        elif arg == "params":
            args["params"], more = draw(parameter_sets(case))
        elif arg == "options":
            args["options"], more = draw(newton_options())
        else:
            args["callback"] = draw(st.one_of(junk(), st.just(lambda piece: None)))
            more = ["callback"]
        names += more
    args["steps"] = runnable(args["steps"], args["every"])
    return args, names


def run_simulate(case: Case, args: dict, names: list, entry: str, how: str):
    sim = case.sim

    def call():
        options = built_options(args["options"])
        if how == "simulate":
            return sim.simulate(args["initial"], args["steps"], args["params"],
                                every=args["every"], callback=args["callback"],
                                options=options)
        if how == "stream":  # nothing is kept: every accepted count runs
            steps = runnable(args["steps"], memory_checked=False)
            return list(sim.stream(args["initial"], steps, args["params"],
                                   every=args["every"], options=options))
        return sim.step(args["initial"], args["params"], options=options)

    def verify(result):
        if _params_or_none(case, args["params"]) is None:
            raise AssertionError(f"{entry} accepted malformed parameters {args['params']!r}")
        check = check_run(case, args["params"], built_options(args["options"]))
        if how == "simulate":
            check(result)
        elif how == "stream":
            for piece in result:
                check(piece)
        else:
            assert_finite(result, "the next state")
            options = built_options(args["options"])
            run = sim.simulate(args["initial"], 1, args["params"], options=options)
            assert np.array_equal(result, run.states[1]), "step differs from a run of one"

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
    examples = {"simulate": 10, "stream": 4, "step": 4}[how]

    @profile(run, examples, 10 * examples)
    @given(call=simulate_calls(case))
    def prop(call):
        args, names = call
        if how == "step":
            names = [n for n in names if n not in ("steps", "every", "callback")] or ["state"]
        run_simulate(case, args, names, f"Simulator.{how}", how)

    prop()


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_step_in_a_loop_with_malformed_arguments(name, run):
    """``state = sim.step(state, p)``: after a loop has made its states trusted (checked
    once, symgroupoid/runtime/_fast_step.py), a state changed in place, a parameter vector
    changed in place, or any other malformed argument is checked as ``simulate`` checks it;
    an accepted call is bitwise the run of one step."""
    case = case_of(name)
    sim = case.sim
    p = sim.parameters(case.params)

    @profile(run, 6, 60)
    @given(data=st.data())
    def prop(data):
        state, vector = case.flat, p.copy()
        for _ in range(2):
            state = sim.step(state, vector)
        which = data.draw(st.sampled_from(["state in place", "vector in place", "state",
                                           "params", "options"]))
        params, options, names = vector, None, []
        if which == "state in place":
            i = data.draw(st.integers(0, len(state) - 1))
            state[i] = data.draw(st.sampled_from([np.nan, np.inf, 1e300, state[i] + 1e-3,
                                                  -state[i], state[i] * (1 + 1e-15)]))
            names = ["state", "constraints", "known", "initial", "group"]
        elif which == "vector in place":
            i = data.draw(st.integers(0, len(vector) - 1))
            vector[i] = data.draw(st.sampled_from([np.nan, -np.inf, 0.0, -vector[i], 1e300,
                                                   vector[i] * 2]))
            names = ["parameter", str(case.step.parameters[i]), "constraints"]
        elif which == "state":
            state, names = data.draw(st.one_of(initial_states(case).map(tuple),
                                               near(state).map(lambda v: (v, ["state"]))))
            names = list(names) + ["state", "known", "initial"]
        elif which == "params":
            params, names = data.draw(parameter_sets(case))
        else:
            options, names = data.draw(newton_options())

        def verify(after):
            assert_finite(after, "the next state")
            one = sim.simulate(state, 1, params, options=built_options(options))
            assert np.array_equal(after, one.states[1]), "step differs from a run of one"

        judge("Simulator.step (loop)",
              lambda: sim.step(state, params, options=built_options(options)), names,
              owner=sim.name, verify=verify)

    prop()


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_simulate_with_every_argument_malformed(name, run):
    case = case_of(name)

    @profile(run, 6, 60)
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

    @profile(run, 7, 100)
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
            tol = tolerance_of(built_options(options))
            if not tol or (tol["atol"] == 0 and tol["rel"] <= 1e-7):
                step_residual_ok(step, u, known, p)

        judge("Simulator.solve", lambda: sim.solve(state, params, guess=guess,
                                                   options=built_options(options)),
              names, owner=sim.name, verify=verify)

    prop()


# --- from_momentum ----------------------------------------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_from_momentum_with_malformed_arguments(name, run):
    case = case_of(name)
    sim = case.sim
    if case.momentum is None:  # second order: the first arrow g₀ and a momentum
        arrow0 = case.flat[sim.layout.arrow_index[-1]]
        valid = (arrow0, [0.1, 0.2])
    else:
        valid = case.momentum
    config0, momentum0 = valid

    @profile(run, 7, 100)
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
            legendre = system.legendre()
            minus = np.asarray(legendre.evaluate(arrow, lam, p)[0], float).ravel()
            target = np.asarray(momentum, float).ravel()
            # F⁻L is known to the rounding of its terms: their size is its sensitivity to a
            # relative change of each coordinate of the arrow
            scale = np.zeros_like(minus)
            for j in range(len(arrow)):
                moved = np.array(arrow, float)
                moved[j] += 1e-6 * (1.0 + abs(moved[j]))
                change = np.asarray(legendre.evaluate(moved, lam, p)[0], float).ravel()
                scale += np.abs(change - minus) / 1e-6
            bound = 1e-7 * np.abs(target) + 1e-12 + 1e3 * np.finfo(float).eps * scale
            assert (np.abs(minus - target) <= bound).all(), (minus, target, bound)

        judge("Simulator.from_momentum",
              lambda: sim.from_momentum(config, momentum, params), names, owner=sim.name,
              verify=verify)

    prop()


# --- Simulator.state and NewtonOptions and compile_step ------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_state_with_malformed_parts(name, run):
    case = case_of(name)

    @profile(run, 7, 100)
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
    @profile(run, 15, 250)
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

    @profile(run, 15, 250)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["backend", "flags", "cache_dir", "tol_residual",
                                           "tol_step", "max_iterations", "floor_factor",
                                           "trust_factor"]))
        value = data.draw(st.one_of(scalars, junk(), st.sampled_from(
            ["numpy", "c", "auto", "C", " numpy", "-O2", ["-O2"], [3], ["-O2", None],
             ["a\0b"], "a\0b", ["-mavx512f"], ["-O2", "-mavx2", "-mavx"]])))
        kwargs = {"backend": "numpy", which: value}
        if which in ("flags", "cache_dir"):
            kwargs["backend"] = "numpy"  # the value is checked even where it is not used

        def verify(sim):
            assert isinstance(sim, sg.Simulator)
            if which == "backend":
                assert isinstance(value, str) and value in ("numpy", "c", "auto")
            try:
                traj = sim.simulate({"q": (0.1, 0.2)}, 2, {"h": 0.1, "k": 1.0})
            except (sg.NewtonDivergenceError, sg.SingularJacobianError):
                assert sim.options.max_iterations < 3, sim.options  # a cap that is too low
                return
            check_run(tiny_case("oscillator"), {"h": 0.1, "k": 1.0}, sim.options)(traj)

        if which == "backend" and isinstance(value, str) and value in ("c", "auto"):
            kwargs["backend"] = "numpy"  # a valid choice; building C is tested elsewhere
        judge("compile_step", lambda: sg.compile_step(step, **kwargs), [which],
              verify=verify)

    prop()



def test_a_nan_configuration_is_non_finite_not_missing():
    """A NaN value in a configuration given by name was taken for a missing coordinate (NaN
    marked what was not given): "the configuration needs x" for a configuration that
    names x.  It is a DomainError like inf; a missing name is still named."""
    case = case_of("oscillator")
    config0, momentum0 = case.momentum
    for value in (np.nan, np.inf):
        with pytest.raises(sg.DomainError, match="non-finite configuration"):
            case.sim.from_momentum({k: value for k in config0}, momentum0, case.params)
    with pytest.raises(sg.InputNameError, match="the configuration needs"):
        case.sim.from_momentum({}, momentum0, case.params)


def test_from_momentum_where_its_terms_overflow_is_refused():
    """Found by the thorough profile: at a configuration of 1e308 (h = 0.1) the terms of
    F⁻L exceed the largest double and the momentum 0.5 lies below their rounding; Newton
    stopped on its relative update and returned a state whose F⁻L was 6.9e291.  Refused
    now, naming the configuration; a large but representable one is still solved."""
    case = case_of("oscillator")
    config0, momentum0 = case.momentum
    with pytest.raises(sg.DomainError, match="at this configuration the terms of F⁻L overflow"):
        case.sim.from_momentum({k: 1e308 for k in config0}, momentum0, case.params)
    state = case.sim.from_momentum({k: 1e6 for k in config0}, momentum0, case.params)
    minus = case.sim.simulate(state, 0, case.params).momenta().minus[0]
    assert abs(minus[0] - momentum0[0]) <= 1e-6
