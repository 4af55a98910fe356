"""``sim.step`` in a control loop: parsed once, checked as ``simulate`` checks, bitwise the
same states (the per-call path of symgroupoid/runtime/_fast_step.py)."""

from __future__ import annotations

import pickle
import threading

import numpy as np
import pytest
from kernel_support import SEED_DATA, SESSION_CACHE, initial_state, needs_cc, seed_step

import symgroupoid as sg
from symgroupoid.runtime import parameter_vector

PARAMS = SEED_DATA["plate_ball"][0]

pytestmark = needs_cc


def _fresh(name: str = "plate_ball", backend: str = "c") -> sg.Simulator:
    """A simulator of its own (an empty table of trusted states)."""
    return seed_step(name).compile(backend=backend, cache_dir=SESSION_CACHE)


def _loop(sim, state, params, steps: int, **options) -> np.ndarray:
    for _ in range(steps):
        state = sim.step(state, params, **options)
    return state


@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("given", ["vector", "dict", "list"])
def test_a_loop_of_steps_is_bitwise_a_run_from_the_prediction(backend, given):
    sim = _fresh(backend=backend)
    state = initial_state(sim, "plate_ball")
    params = {"vector": sim.parameters(PARAMS), "dict": dict(PARAMS),
              "list": [PARAMS[str(s)] for s in sim.equations.parameters]}[given]
    steps = 30 if backend == "c" else 4
    run = sim.simulate(state, steps, PARAMS, options=sg.NewtonOptions(extrapolate=False))
    after = _loop(sim, state, params, steps)
    assert np.array_equal(after, run.states[-1])
    assert np.array_equal(sim.step(state, params), sim.simulate(state, 1, PARAMS).states[1])
    assert after.flags.writeable and after.dtype == np.float64


def test_parameters_and_states_are_parsed_and_checked_once_per_loop(monkeypatch):
    """The cost of a loop was the parsing of the parameters (SymPy's printer on every
    symbol) and the checks of the state on every call (350 µs a step): a loop now parses
    and checks them once; each state it produces is trusted, not checked again."""
    sim = _fresh()
    state, vector = initial_state(sim, "plate_ball"), sim.parameters(PARAMS)
    calls = {"parameter_vector": 0, "state": 0}
    original_vector, original_state = parameter_vector, sg.Simulator.state

    def counting_vector(*args, **kwargs):
        calls["parameter_vector"] += 1
        return original_vector(*args, **kwargs)

    def counting_state(self, *args, **kwargs):
        calls["state"] += 1
        return original_state(self, *args, **kwargs)

    monkeypatch.setattr("symgroupoid.runtime._simulator.parameter_vector", counting_vector)
    monkeypatch.setattr(sg.Simulator, "state", counting_state)
    sim.step(state, vector)
    assert calls["parameter_vector"] >= 1 and calls["state"] == 1  # the first call: checked
    calls.update(parameter_vector=0, state=0)
    _loop(sim, state, vector, 50)
    _loop(sim, state, dict(PARAMS), 50)
    assert calls == {"parameter_vector": 0, "state": 0}


def test_parameters_from_another_process_take_the_fast_path(monkeypatch):
    """An unpickled array (parameters sent from another process, or loaded by the user)
    has a float64 dtype object of its own, which an identity test alone refused: every call
    of such a loop took the checked path (some 600 µs a step); it is parsed once now."""
    sim = _fresh()
    state = initial_state(sim, "plate_ball")
    vector = pickle.loads(pickle.dumps(sim.parameters(PARAMS)))
    assert vector.dtype is not np.dtype(np.float64) and vector.dtype == np.float64
    calls = {"state": 0}
    original_state = sg.Simulator.state

    def counting_state(self, *args, **kwargs):
        calls["state"] += 1
        return original_state(self, *args, **kwargs)

    monkeypatch.setattr(sg.Simulator, "state", counting_state)
    after = _loop(sim, state, vector, 20)
    assert calls["state"] == 1
    run = sim.simulate(state, 20, PARAMS, options=sg.NewtonOptions(extrapolate=False))
    assert np.array_equal(after, run.states[-1])


def test_the_states_of_a_loop_are_arrays_of_their_own():
    """States returned by a loop are handed out from blocks of rows (one C view per
    block): across block boundaries each is the run's state, and writing into one changes
    no other."""
    sim = _fresh()
    state, vector = initial_state(sim, "plate_ball"), sim.parameters(PARAMS)
    states = [state]
    for _ in range(150):
        states.append(sim.step(states[-1], vector))
    run = sim.simulate(state, 150, PARAMS, options=sg.NewtonOptions(extrapolate=False))
    assert all(np.array_equal(a, b) for a, b in zip(states, run.states))
    kept = [s.copy() for s in states]
    states[70][:] = -1.0
    assert all(np.array_equal(a, b) for i, (a, b) in enumerate(zip(states, kept)) if i != 70)
    assert len({id(s) for s in states}) == len(states)


def test_the_loop_keeps_every_check():
    sim = _fresh()
    state, vector = initial_state(sim, "plate_ball"), sim.parameters(PARAMS)
    after = _loop(sim, state, vector, 5)
    moved = after.copy()
    moved[0] += 1e-3  # x moved: the rolling constraints no longer hold
    with pytest.raises(sg.DomainError, match="violates the constraints"):
        sim.step(moved, vector)
    after[0] += 1e-3  # the same, in place, on a state the loop produced
    with pytest.raises(sg.DomainError, match="violates the constraints"):
        sim.step(after, vector)
    state = _loop(sim, state, vector, 5)
    bad = vector.copy()
    bad[0] = -0.01
    with pytest.raises(sg.ParameterError, match="h is declared positive"):
        sim.step(state, bad)
    bad[0] = np.nan
    with pytest.raises(sg.ParameterError, match="non-finite parameter h"):
        sim.step(state, bad)
    with pytest.raises(sg.ParameterError, match="non-finite parameter r"):
        sim.step(state, {**PARAMS, "r": float("inf")})
    with pytest.raises(sg.ParameterError, match="h is declared positive"):
        sim.step(state, {**PARAMS, "h": 0})
    with pytest.raises(sg.ParameterError, match="parameter h must be a real number"):
        sim.step(state, {**PARAMS, "h": [0.01]})  # unhashable: no lookup, the checked path
    other = vector.copy()
    other[1] = 2.0  # r: the constraints use it, so the state is checked again, and fails
    with pytest.raises(sg.DomainError, match="violates the constraints"):
        sim.step(state, other)
    nan_state = state.copy()
    nan_state[3] = np.nan
    with pytest.raises(sg.DomainError, match="non-finite"):
        sim.step(nan_state, vector)
    with pytest.raises(sg.InputTypeError, match="options"):
        sim.step(state, vector, options="fast")
    assert np.array_equal(sim.step(state, vector), sim.simulate(state, 1, PARAMS).states[1])


def test_a_link_of_the_chain_sees_every_change_made_in_place():
    """A call that passes back the array the last call returned, with the same parameters
    object and options, is the kernel's entry and a few comparisons; whatever was changed
    in place since (the parameter vector, the dict, the simulator's options) is seen: here
    Omega, which the rolling constraints use, so the state fails them under the new value."""
    sim = _fresh()
    state, vector = initial_state(sim, "plate_ball"), sim.parameters(PARAMS)
    expected = _loop(_fresh(), state, vector.copy(), 5)
    for params in (vector, dict(PARAMS)):
        looped = _loop(sim, state, params, 3)
        key = 2 if params is vector else "Omega"
        params[key] *= 1.5
        with pytest.raises(sg.DomainError, match="violates the constraints"):
            sim.step(looped, params)
        params[key] = PARAMS["Omega"]
        assert np.array_equal(_loop(sim, looped, params, 2), expected)
    params = dict(PARAMS)
    looped = _loop(sim, state, params, 2)
    params["h"] = np.array([0.01, 0.01])  # in place: no single truth value when compared
    with pytest.raises(sg.ParameterError, match="parameter h must be a real number"):
        sim.step(looped, params)
    looped = _loop(sim, state, vector, 2)
    sim.options = sg.NewtonOptions(max_iterations=0)  # replaced between two links
    with pytest.raises(sg.NewtonDivergenceError, match="step 0 failed"):
        sim.step(looped, vector)


def test_interleaved_loops_and_a_return_to_an_earlier_state_stay_exact(monkeypatch):
    """Two loops on one simulator break each other's chain at every call: the state a
    chain ends with joins the table, so neither is checked again; a state from inside a
    chain is checked once, and every state is bitwise the lone loop's."""
    sim = _fresh()
    p = sim.parameters(PARAMS)
    starts = [sim.from_momentum({"x": 0.1 * i, "y": 0.0}, (0.1, 0.05 * i, 0.01, 0.02, 0.01),
                                PARAMS) for i in range(2)]
    expected = [_loop(_fresh(), s, p, 20) for s in starts]
    a, b = sim.step(starts[0], p), sim.step(starts[1], p)
    checks = {"state": 0}
    original_state = sg.Simulator.state

    def counting_state(self, *args, **kwargs):
        checks["state"] += 1
        return original_state(self, *args, **kwargs)

    monkeypatch.setattr(sg.Simulator, "state", counting_state)
    for _ in range(14):
        a, b = sim.step(a, p), sim.step(b, p)
    chain = [a]
    for _ in range(5):  # a lone loop: one chain
        chain.append(sim.step(chain[-1], p))
    assert np.array_equal(chain[-1], expected[0]) and np.array_equal(_loop(sim, b, p, 5),
                                                                     expected[1])
    assert checks["state"] == 0
    again = _loop(sim, chain[2], p, 3)  # from inside the chain: checked once
    assert np.array_equal(again, expected[0]) and checks["state"] == 1


def test_a_failed_step_in_the_loop_raises_as_simulate_does():
    sim = _fresh()
    state = _loop(sim, initial_state(sim, "plate_ball"), sim.parameters(PARAMS), 3)
    with pytest.raises(sg.NewtonDivergenceError, match="step 0 failed") as info:
        sim.step(state, sim.parameters(PARAMS), options=sg.NewtonOptions(max_iterations=0))
    assert np.array_equal(info.value.trajectory.states[0], state)


def test_threads_stepping_one_simulator_get_their_own_states():
    sim = _fresh()
    p = sim.parameters(PARAMS)
    starts = [sim.from_momentum({"x": 0.1 * i, "y": 0.0}, (0.1, 0.05 * i, 0.01, 0.02, 0.01),
                                PARAMS) for i in range(4)]
    expected = [_loop(_fresh(), s, p, 200) for s in starts]
    got = [None] * 4

    def work(i):
        got[i] = _loop(sim, starts[i], dict(PARAMS) if i % 2 else p, 200)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(got, expected):
        assert np.array_equal(a, b)


def test_a_restored_simulator_steps_as_the_original():
    sim = _fresh()
    restored = pickle.loads(pickle.dumps(sim))
    state, p = initial_state(sim, "plate_ball"), sim.parameters(PARAMS)
    assert np.array_equal(_loop(restored, state, p, 10), _loop(sim, state, p, 10))


def test_simulate_checks_a_state_once_and_keeps_every_check():
    """``simulate`` shares the table: a state it checked or ended with starts the next run
    unchecked (a run continued from its last state is bitwise one run), and a state changed
    in place, or one under other values of the parameters its constraints use, or other
    parameters that fail their checks, is checked again."""
    sim = _fresh()
    state, vector = initial_state(sim, "plate_ball"), sim.parameters(PARAMS)
    whole = sim.simulate(state, 40, PARAMS)
    half = sim.simulate(state, 20, vector)
    calls = {"state": 0}
    original_state = sg.Simulator.state

    def counting_state(self, *args, **kwargs):
        calls["state"] += 1
        return original_state(self, *args, **kwargs)

    sg_state = pytest.MonkeyPatch()
    sg_state.setattr(sg.Simulator, "state", counting_state)
    try:
        end = half.states[-1]
        rest = sim.simulate(end, 20, vector, options=sg.NewtonOptions(extrapolate=False))
        assert calls["state"] == 0
        again = sim.simulate(end, 20, dict(PARAMS))
        assert calls["state"] == 0 and np.array_equal(again.states[0], end)
    finally:
        sg_state.undo()
    assert np.array_equal(whole.states[:21], half.states)
    assert np.array_equal(rest.states[0], whole.states[20])
    moved = half.states[-1].copy()
    sim.simulate(moved, 5, vector)  # (trusted: the bytes of a state the table holds)
    moved[0] += 1e-3  # in place: the rolling constraints no longer hold
    with pytest.raises(sg.DomainError, match="violates the constraints"):
        sim.simulate(moved, 5, vector)
    other = vector.copy()
    other[1] = 2.0  # r, which the constraints use
    with pytest.raises(sg.DomainError, match="violates the constraints"):
        sim.simulate(whole.states[-1], 5, other)
    with pytest.raises(sg.ParameterError, match="non-finite parameter r"):
        sim.simulate(whole.states[-1], 5, {**PARAMS, "r": float("inf")})
    bad = vector.copy()
    bad[0] = np.nan
    with pytest.raises(sg.ParameterError, match="non-finite parameter h"):
        sim.simulate(whole.states[-1], 5, bad)


def test_a_parameter_changed_to_a_bool_mid_loop_is_refused():
    """A dict whose value became True between calls equalled its kept copy (True == 1), so
    the loop's shortcut stepped with it where a fresh call refuses a bool."""
    sim = _fresh("rigid_body")
    state = sim.state({"W": [[1.0, 0, 0], [0, 0.8, -0.6], [0, 0.6, 0.8]]})
    params = {"h": 0.01, "I1": 1, "I2": 2.0, "I3": 3.0}
    state = sim.step(sim.step(state, params), params)
    params["I1"] = True
    with pytest.raises(sg.ParameterError, match="parameter I1 must be a real number, got bool"):
        sim.step(state, params)
