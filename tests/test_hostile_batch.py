"""Hostile input at the batch entry points: ``Simulator.simulate_batch`` and ``sg.sweep``.

Each example takes a valid batch on one of the six systems of tests/_hostile_cases.py — a
table of valid initial states (consecutive states of a run, so constrained systems stay on
their constraints) and one parameter set or a table of them — and makes one argument
malformed: an entry of the state table or of a parameter table (NaN, ±inf, a string, a
complex number, None, a boolean, a value that violates a declared assumption), a ragged or
three-dimensional table, a table of the wrong width, mismatched counts of states and sets,
columns of different lengths, an unknown or missing parameter name, a table of the wrong
dtype (booleans, strings, dates, complex), junk; or a count, ``options``, ``threads``,
``combine``, ``reduce``, ``client``, ``progress`` of the wrong kind.

The invariant (tests/_hostile.py, :func:`judge`): a SymgroupoidError naming the argument (or
the row and the part), or a batch that is correct run by run — every accepted row passes
the scalar checks of ``Simulator.state`` and ``Simulator.parameters``, every completed run
is bitwise the trajectory ``Simulator.simulate`` computes from that row and solves the step
equations (checked through ``StepEquations.evaluate``), and every failed run reports the
error ``simulate`` raises, at the same step.
"""

from __future__ import annotations

import functools

import numpy as np
import pandas as pd
import pytest
import sympy as sp
from _hostile import (
    PROFILES,
    assert_finite,
    judge,
    junk,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
    verify_trajectory,
)
from _hostile_cases import (
    CASES,
    Case,
    built_options,
    case_of,
    counts,
    initial_states,
    newton_options,
    parameter_sets,
    runnable,
    tolerance_of,
)
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid.runtime import TrajectoryBatch

#: the systems on the NumPy backend (the others step through their C kernels)
TINY = ("oscillator", "diagonal", "accel")

#: values put into one entry of a numeric table
BAD_ENTRIES = [np.nan, np.inf, -np.inf, 1e308, -1e308, 1e-320, "a", "1.0", None, True, 1j,
               complex(1, 0), [1.0], (), sp.nan, 10**400, -0.0]


@functools.cache
def valid_rows(name: str) -> np.ndarray:
    """Five valid flat states of the case: the first states of a short run."""
    case = case_of(name)
    return case.sim.simulate(case.flat, 4, case.params).states.copy()


def state_names(case: Case) -> list[str]:
    return ["state", "states", "initial", *case.named]


def parameter_names(case: Case) -> list[str]:
    return ["parameter", "parameters", "parameter set", *case.params]


@st.composite
def state_tables(draw, name: str):
    """(value, names): a table of initial states with one malformation, or a valid one."""
    case, rows = case_of(name), valid_rows(name)
    n = draw(st.integers(1, 4))
    table = rows[:n].copy()
    how = draw(st.sampled_from(["valid", "entry", "named", "named part", "one state",
                                "one flat", "empty", "3-D", "width", "dtype", "ragged",
                                "junk"]))
    names = state_names(case)
    if how == "valid":
        return table, names
    if how == "entry":
        out = table.astype(object)
        out[draw(st.integers(0, n - 1)), draw(st.integers(0, table.shape[1] - 1))] = \
            draw(st.sampled_from(BAD_ENTRIES))
        return (out.tolist() if draw(st.booleans()) else out), names
    if how == "named":
        return [case.named] * n, names
    if how == "named part":
        value, more = draw(initial_states(case))
        return [case.named, value][: max(n, 2)], names + more
    if how == "one state":
        return draw(initial_states(case))[0], names
    if how == "one flat":
        return table[0], names
    if how == "empty":
        return draw(st.sampled_from([[], np.zeros((0, table.shape[1])), np.zeros(0)])), names
    if how == "3-D":
        return table[None], names
    if how == "width":
        return np.hstack([table, table[:, :1]]) if draw(st.booleans()) else table[:, 1:], names
    if how == "dtype":
        dtype = draw(st.sampled_from([bool, complex, str, "M8[D]", object]))
        return (table.astype(np.int64).astype(dtype) if dtype == "M8[D]"
                else table.astype(dtype)), names
    if how == "ragged":
        return [table[0].tolist(), table[0][:-1].tolist()], names
    return draw(junk()), names


@st.composite
def parameter_tables(draw, name: str, n_states: int):
    """(value, names): one parameter set or a table of sets, with one malformation or
    valid."""
    case = case_of(name)
    keys = [str(s) for s in case.step.parameters]
    base = np.array([case.params[k] for k in keys], float)
    m = draw(st.sampled_from([1, n_states, n_states + 1]))
    names = parameter_names(case)
    how = draw(st.sampled_from(["one", "one malformed", "sets", "set malformed", "array",
                                "array entry", "columns", "columns ragged", "columns entry",
                                "columns names", "frame", "junk"]))
    if how == "one":
        return dict(case.params), names
    if how == "one malformed":
        value, more = draw(parameter_sets(case))
        return value, names + more
    if how == "sets":
        return [dict(case.params)] * m, names
    if how == "set malformed":
        value, more = draw(parameter_sets(case))
        return [dict(case.params), value][:max(m, 2)], names + more
    table = np.tile(base, (m, 1))
    if how == "array":
        return table, names
    if how == "array entry":
        out = table.astype(object)
        out[draw(st.integers(0, m - 1)), draw(st.integers(0, len(keys) - 1))] = draw(
            st.sampled_from(BAD_ENTRIES + [-1.0, 0.0]))
        return (out if draw(st.booleans()) else out.tolist()), names
    columns = {k: table[:, j].tolist() for j, k in enumerate(keys)}
    if how == "columns":
        return columns, names
    if how == "columns ragged" and keys:
        columns[keys[0]] = columns[keys[0]] + [1.0]
        return columns, names
    if how == "columns entry" and keys:
        key = draw(st.sampled_from(keys))
        columns[key][draw(st.integers(0, m - 1))] = draw(st.sampled_from(BAD_ENTRIES
                                                                         + [-1.0]))
        return columns, names
    if how == "columns names":
        extra = draw(st.sampled_from(["zeta", "H", ""]))
        columns[extra] = [1.0] * m
        return columns, names + [extra]
    if how == "frame":
        frame = pd.DataFrame(columns)
        if keys and draw(st.booleans()):
            frame.iloc[0, 0] = draw(st.sampled_from([np.nan, -1.0, np.inf]))
        return frame, names
    return draw(junk()), names


def expected_run(case: Case, state0, params: dict, steps: int, every: int, options):
    """What ``simulate`` does with one row: (trajectory, None) or (None, error)."""
    try:
        return case.sim.simulate(state0, steps, params, every=every, options=options), None
    except (sg.SingularJacobianError, sg.NewtonDivergenceError) as err:
        return None, err


def check_batch_run(case: Case, batch: TrajectoryBatch, b: int, steps: int, every: int,
                    options) -> None:
    """Run b of a batch against the scalar path (see the module docstring)."""
    keys = [str(s) for s in case.step.parameters]
    named = dict(zip(keys, batch.parameters[b].tolist()))
    k = int(batch.kept[b])
    assert_finite(batch.states[b, :k], f"run {b}")
    state0 = batch.states[b, 0]
    try:
        case.sim.state(state0, named)
    except sg.SymgroupoidError as err:
        raise AssertionError(f"run {b}: the batch accepted a state or parameter set that "
                             f"simulate refuses: {err}") from err
    traj, err = expected_run(case, state0, named, steps, every, options)
    if err is not None:
        assert not batch.ok[b], f"run {b}: simulate fails ({err}), the batch completed it"
        got = batch.error(b)
        assert type(got) is type(err) and got.step == err.step, (got, err)
        return
    assert batch.ok[b], f"run {b}: the batch failed ({batch.error(b)}), simulate did not"
    assert np.array_equal(batch[b].states, traj.states), f"run {b} differs from simulate"
    tol = tolerance_of(options)
    if every == 1 and (not tol or (tol["atol"] == 0 and tol["rel"] <= 1e-7)):
        verify_trajectory(case.step, batch[b], batch.parameters[b])


@st.composite
def batch_calls(draw, name: str):
    """(kwargs, names): a simulate_batch call with one argument malformed (or none)."""
    case = case_of(name)
    which = draw(st.sampled_from(["states", "params", "steps", "every", "options", "threads",
                                  "none"]))
    states, names = valid_rows(name)[:3], []
    params = dict(case.params)
    args = {"steps": 3, "every": 1, "options": None, "threads": None}
    if which == "states":
        states, names = draw(state_tables(name))
    elif which == "params":
        params, names = draw(parameter_tables(name, 3))
    elif which in ("steps", "every"):
        args[which], names = draw(counts), [which]
    elif which == "threads":
        args["threads"], names = draw(st.one_of(scalars, st.integers(-2, 4))), ["threads"]
    elif which == "options":
        args["options"], names = draw(newton_options())
    args["steps"] = runnable(args["steps"], args["every"])
    if which != "threads" and isinstance(args["threads"], int) and args["threads"] > 4:
        args["threads"] = 2
    return states, params, args, names or ["states"]


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_simulate_batch(name, run):
    case = case_of(name)

    @profile(run, 4 if name in TINY else 3, 80)
    @given(call=batch_calls(name))
    def prop(call):
        states, params, args, names = call

        def verify(batch):
            assert isinstance(batch, TrajectoryBatch)
            options = built_options(args["options"]) or case.sim.options
            for b in range(min(len(batch), 3)):
                check_batch_run(case, batch, b, batch.steps, batch.every, options)

        judge("Simulator.simulate_batch",
              lambda: case.sim.simulate_batch(states, args["steps"], params,
                                              every=args["every"],
                                              options=built_options(args["options"]),
                                              threads=args["threads"]),
              names, owner=case.sim.name, verify=verify)

    prop()


# --- sweeps ---------------------------------------------------------------------------------------

def _last(trajectory):
    return trajectory.states[-1]


REDUCERS = {
    "none": None,
    "last state": _last,
    "first entry": lambda t: float(t.states[-1, 0]),
    "raises": lambda t: 1 / 0,
    "string": lambda t: "text",
    "ragged": lambda t: np.zeros(len(t.states) % 2 + 1),
}


@st.composite
def sweep_calls(draw, name: str):
    """(sim, states, params, kwargs, names) of a sweep with one argument malformed."""
    case = case_of(name)
    which = draw(st.sampled_from(["sim", "states", "params", "steps", "combine", "reduce",
                                  "options", "reduce_failures", "workers", "chunk_size",
                                  "client", "progress", "every", "executor", "timeout",
                                  "none"]))
    sim, states, params = case.sim, valid_rows(name)[:2], dict(case.params)
    kwargs = {"steps": 3, "combine": "product", "reduce": None, "every": 1,
              "options": None, "reduce_failures": False, "workers": 1, "chunk_size": None,
              "client": None, "progress": False}
    names = [which]
    if which == "sim":
        sim = draw(junk())
        names = ["sim", "Simulator"]
    elif which == "states":
        states, names = draw(state_tables(name))
    elif which == "params":
        params, names = draw(parameter_tables(name, 2))
    elif which in ("steps", "every", "chunk_size"):
        kwargs[which] = draw(st.one_of(counts, st.none()))
    elif which == "combine":
        kwargs["combine"] = draw(st.one_of(st.sampled_from(["zip", "product", "Zip", ""]),
                                           scalars))
        names += ["zip", "parameter sets"]
    elif which == "reduce":
        kwargs["reduce"] = REDUCERS[draw(st.sampled_from(sorted(REDUCERS)))] \
            if draw(st.booleans()) else draw(junk())
    elif which == "options":
        kwargs["options"], names = draw(newton_options())
    elif which == "reduce_failures":
        kwargs["reduce_failures"] = draw(st.one_of(scalars, st.booleans()))
    elif which == "workers":
        value = draw(st.one_of(scalars, st.integers(-2, 1)))
        kwargs["workers"] = 1 if isinstance(value, int) and value > 1 else value
    elif which == "client":
        kwargs["client"] = draw(junk())
    elif which == "progress":
        kwargs["progress"] = draw(st.one_of(scalars, st.just(lambda done, total: None)))
    elif which == "executor":  # (no worker processes here: "process" is not drawn)
        kwargs["executor"] = draw(st.one_of(scalars, st.sampled_from(
            ["thread", "Thread", "", "processes", None])))
        names += ["thread", "process"]
    elif which == "timeout":
        kwargs["timeout"] = draw(st.one_of(scalars, st.just(None), st.just(1e6)))
    kwargs["steps"] = runnable(kwargs["steps"], kwargs["every"])
    if isinstance(kwargs["chunk_size"], int) and kwargs["chunk_size"] > 2**40:
        kwargs["chunk_size"] = 1
    return sim, states, params, kwargs, names


def check_sweep(case: Case, result, kwargs: dict) -> None:
    """A sweep's runs against ``simulate`` (the first few)."""
    assert isinstance(result, sg.SweepResult)
    options = built_options(kwargs["options"]) or case.sim.options
    keys = [str(s) for s in case.step.parameters]
    status = result.status.reshape(-1)
    for r in range(min(len(result), 3)):
        if kwargs.get("timeout") is not None and status[r] == sg.Status.TIMED_OUT:
            continue  # (a valid timeout may stop a task: recorded, not a defect)
        i, j = result.index(r)
        state0 = np.asarray(result.initial)[i]
        named = dict(zip(keys, result.parameters[j].tolist()))
        traj, err = expected_run(case, state0, named, int(kwargs["steps"]),
                                 int(kwargs["every"]), options)
        assert (status[r] == 0) == (err is None), (r, status[r], err)
        if err is not None:
            continue
        reduce = kwargs["reduce"]
        if reduce is None:
            got = result.trajectories.reshape(-1)[r]
            assert np.array_equal(got.states, traj.states), f"run {r} differs from simulate"
        else:
            got = result.values.reshape(len(result), -1)[r] if result.values.dtype != object \
                else result.values.reshape(-1)[r]
            want = reduce(traj)
            assert np.array_equal(np.asarray(got, dtype=object).ravel(),
                                  np.asarray(want, dtype=object).ravel()), (got, want)


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_sweep(name, run):
    case = case_of(name)

    @profile(run, 3 if name in TINY else 2, 60)
    @given(call=sweep_calls(name))
    def prop(call):
        sim, states, params, kwargs, names = call
        judge("sweep", lambda: sg.sweep(sim, states, params, **kwargs), names,
              owner=case.sim.name, verify=lambda result: check_sweep(case, result, kwargs))

    prop()
