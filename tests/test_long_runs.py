"""Long runs: computed in chunks (bitwise one run), bounded memory with ``every``, on-the-fly
processing (iterator and callback), the trajectory up to a failure, Ctrl-C, and one rule for
the count arguments."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest
from _systems import FALL_PARAMS, FALL_START, falling
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    BACKENDS,
    SEED_DATA,
    SESSION_CACHE,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
)

import symgroupoid as sg


@pytest.fixture(scope="module")
def fall_step():
    return falling()


class CountingKernel:
    """Wraps a kernel and records the n_steps of every simulate call."""

    def __init__(self, kernel):
        self._kernel, self.calls = kernel, []

    def __getattr__(self, name):
        return getattr(self._kernel, name)

    def simulate(self, known0, p, n_steps, options, warm=None):
        self.calls.append(n_steps)
        return self._kernel.simulate(known0, p, n_steps, options, warm)


def counted(sim) -> tuple[sg.Simulator, CountingKernel]:
    kernel = CountingKernel(sim.kernel)
    return sg.Simulator(sim.equations, kernel, sim.options), kernel


def expected_sample(full: sg.Trajectory, every: int):
    """Kept step indices, and per interval the summed iterations and largest residual, of a
    full (every = 1) run."""
    n = full.steps
    kept = np.unique(np.append(np.arange(0, n + 1, every), n))
    its = np.array([full.newton_iterations[a:b].sum() for a, b in zip(kept[:-1], kept[1:])])
    res = np.array([full.residual_norms[a:b].max() for a, b in zip(kept[:-1], kept[1:])])
    return kept, its, res


# --- chunks give one run ----------------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ["plate_ball", "heavy_top"])
def test_chunked_run_is_bitwise_one_run(backend, name, chunk):
    """The Newton warm start crosses chunk boundaries: states, iterations and residuals
    are bitwise those of one kernel call (the extrapolated guesses continue exactly)."""
    sim = compiled(name, backend=backend)
    params = SEED_DATA[name][0]
    state = initial_state(sim, name)
    steps = 300 if backend == "c" else 40
    one = sim.kernel.simulate(state, sim.parameters(params), steps, sim.options)
    for n in (1, 2, 7, steps):
        chunk(n)
        traj = sim.simulate(state, steps, params)
        assert np.array_equal(traj.states, one.states), n
        assert np.array_equal(traj.newton_iterations, one.iterations), n
        assert np.array_equal(traj.residual_norms, one.residual_norms), n
    # a fresh start of the second half is not the continued run (so the test can fail)
    half = sim.simulate(traj.states[steps // 2], steps - steps // 2, params)
    assert not (np.array_equal(half.states, one.states[steps // 2:])
                and np.array_equal(half.residual_norms, one.residual_norms[steps // 2:]))


@needs_cc
@pytest.mark.parametrize("every", [1, 3, 10, 64, 1000])
def test_every_keeps_state_zero_every_kth_and_the_last(every, chunk):
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    full = sim.simulate(state, 500, params)
    chunk(17)  # chunk boundaries not aligned with every
    traj = sim.simulate(state, 500, params, every=every)
    kept, its, res = expected_sample(full, every)
    assert traj.states.shape == (1 + -(-500 // every), 16) == (len(kept), 16)
    assert np.array_equal(traj.step_indices, kept)
    assert np.array_equal(traj.states, full.states[kept])
    assert np.array_equal(traj.newton_iterations, its)
    assert np.array_equal(traj.residual_norms, res)
    assert traj.steps == 500 and traj.every == every and len(traj) == len(kept)
    assert np.array_equal(traj.final_state(), full.final_state())
    # named views: the older values of the first kept state, then the newest of every one
    assert np.array_equal(traj["x"], np.concatenate([[full["x"][0]], full["x"][kept + 1]]))
    assert traj["g"].shape == (len(kept), 3, 3)
    assert np.array_equal(traj.multipliers, full.multipliers[kept])
    assert f"every {every}" in repr(traj) or every == 1


@needs_cc
def test_memory_is_bounded_by_what_is_kept(chunk):
    """Every kernel call is at most one chunk, and the result holds 1 + ⌈N/k⌉ rows."""
    sim, kernel = counted(compiled("rigid_body"))
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(compiled("rigid_body"), "rigid_body")
    chunk(4096)
    traj = sim.simulate(state, 100_000, params, every=10_000)
    assert traj.states.shape == (11, 9) and traj.newton_iterations.shape == (10,)
    assert max(kernel.calls) == 4096 and sum(kernel.calls) == 100_000
    assert traj.step_indices.tolist() == list(range(0, 100_001, 10_000))


@needs_cc
def test_too_many_kept_states_are_refused_up_front():
    """10⁸ plate-ball states used to be allocated (11.9 GiB) before the first step."""
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    start = time.perf_counter()
    with pytest.raises(sg.SymgroupoidError, match=r"keeping .* states .* every=k") as info:
        sim.simulate(state, 2**53, params)
    assert isinstance(info.value, MemoryError)
    assert time.perf_counter() - start < 1.0
    # the same run streamed: the first piece comes at once
    pieces = sim.stream(state, 2**53, params, every=1000)
    first = next(pieces)
    pieces.close()
    assert first.step_indices[0] == 0 and first.step_indices[1] == 1000


# --- processing on the fly --------------------------------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
def test_stream_and_callback_give_the_pieces_of_simulate(backend, chunk):
    sim = compiled("rigid_body", backend=backend)
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    chunk(25)
    whole = sim.simulate(state, 200, params, every=10)
    pieces = list(sim.stream(state, 200, params, every=10))
    assert len(pieces) == 8
    assert all(isinstance(p, sg.Trajectory) for p in pieces)
    for before, after in zip(pieces, pieces[1:]):
        assert np.array_equal(after.states[0], before.states[-1])
        assert after.step_indices[0] == before.step_indices[-1]
    joined = np.concatenate([pieces[0].states] + [p.states[1:] for p in pieces[1:]])
    assert np.array_equal(joined, whole.states)
    assert np.array_equal(np.concatenate([p.newton_iterations for p in pieces]),
                          whole.newton_iterations)
    assert sum(p.steps for p in pieces) == 200
    seen = []
    again = sim.simulate(state, 200, params, every=10, callback=seen.append)
    assert np.array_equal(again.states, whole.states)
    assert [p.step_indices.tolist() for p in seen] == [p.step_indices.tolist() for p in pieces]


# --- a failure keeps the run up to the failing step -------------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("every", [1, 7])
def test_failure_carries_the_trajectory_up_to_the_failing_step(backend, every, fall_step,
                                                                chunk):
    sim = fall_step.compile(backend=backend, cache_dir=SESSION_CACHE)
    chunk(16)
    with pytest.raises(sg.NewtonDivergenceError) as info:
        sim.simulate(FALL_START, 1000, FALL_PARAMS, every=every)
    err = info.value
    s = err.step
    assert 16 < s < 1000 and "non-finite" in str(err)
    traj = err.trajectory
    assert isinstance(traj, sg.Trajectory) and traj.step_indices[-1] == s
    before = sim.simulate(FALL_START, s, FALL_PARAMS, every=every)
    assert np.array_equal(traj.states, before.states)
    assert np.array_equal(traj.step_indices, before.step_indices)
    assert np.array_equal(traj.newton_iterations, before.newton_iterations)
    assert np.isfinite(traj.states).all()
    q = before["q"]
    assert q[-1] < 0 and (q[:-1] >= 0).all()
    # the iterator raises the same error, carrying the piece since the last one yielded
    kept = []
    with pytest.raises(sg.NewtonDivergenceError) as again:
        for piece in sim.stream(FALL_START, 1000, FALL_PARAMS, every=every):
            kept.append(piece)
    assert again.value.step == s
    tail = again.value.trajectory
    assert tail.step_indices[0] == kept[-1].step_indices[-1] and tail.step_indices[-1] == s


@needs_cc
def test_iteration_cap_failure_keeps_the_steps_before(chunk):
    """A tiny max_iterations fails at a known step: the extrapolated guesses of steps ≥ 2
    converge in one update, the predicted guesses of steps 0 and 1 need more."""
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    full = sim.simulate(state, 50, params)
    assert full.newton_iterations[0] > 1
    chunk(1)
    with pytest.raises(sg.NewtonDivergenceError, match="iteration cap") as info:
        sim.simulate(state, 50, params, options=sg.NewtonOptions(max_iterations=1))
    assert info.value.step == 0 and len(info.value.trajectory) == 1
    assert np.array_equal(info.value.trajectory.states[0], state)


# --- Ctrl-C -----------------------------------------------------------------------------------

@pytest.fixture
def ctrl_c():
    """SIGINT raises KeyboardInterrupt, as in an interactive session: a process started in
    the background by a non-interactive shell inherits SIGINT ignored, and Python then
    leaves it ignored."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@needs_cc
@pytest.mark.parametrize("how", ["raise", "signal"])
def test_keyboard_interrupt_in_a_callback_stops_after_that_chunk(how, chunk, ctrl_c):
    sim, kernel = counted(compiled("rigid_body"))
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(compiled("rigid_body"), "rigid_body")
    chunk(100)

    def stop_at_the_third(piece):
        if piece.step_indices[-1] >= 300:
            if how == "raise":
                raise KeyboardInterrupt
            signal.raise_signal(signal.SIGINT)

    with pytest.raises(KeyboardInterrupt) as info:
        sim.simulate(state, 10**6, params, every=50, callback=stop_at_the_third)
    assert kernel.calls == [100, 100, 100]
    traj = info.value.trajectory
    assert traj.step_indices.tolist() == list(range(0, 301, 50))
    full = compiled("rigid_body").simulate(state, 300, params, every=50)
    assert np.array_equal(traj.states, full.states)


@needs_cc
def test_ctrl_c_during_a_long_run_stops_within_a_chunk(ctrl_c):
    """SIGINT while the C kernel runs: the run stops at the end of the current chunk
    (~10 ms) with the states computed so far."""
    sim = compiled("rigid_body")
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    start = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as info:
            sim.simulate(state, 10**8, params, every=1000)
    finally:
        timer.cancel()
    elapsed = time.perf_counter() - start
    assert elapsed < 5.0
    traj = info.value.trajectory
    assert 0 < traj.steps < 10**8 and traj.steps % 1000 == 0
    assert np.isfinite(traj.states).all()


# --- one rule for counts ----------------------------------------------------------------------

@pytest.mark.parametrize("bad, text", [
    (float("nan"), "must be a finite integer"), (float("inf"), "must be a finite integer"),
    (2.5, "must be an integer, got 2.5"), (-5, "must be at least 0, got -5"),
    (True, "must be an integer, got the boolean True"), ("10", "must be an integer, got str"),
    (np.float64(-1.0), "must be at least 0"), (2**60, "must be at most")])
def test_steps_is_checked_with_one_message(bad, text):
    sim = compiled("rigid_body", backend="numpy")
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    with pytest.raises(sg.ShapeError, match=f"rigid_body: steps {text}"):
        sim.simulate(state, bad, params)
    with pytest.raises(sg.ShapeError, match=f"rigid_body: steps {text}"):
        sim.stream(state, bad, params)
    with pytest.raises(sg.ShapeError, match="rigid_body: every must be at least 1"):
        sim.simulate(state, 10, params, every=0)


def test_integral_float_steps_are_accepted():
    sim = compiled("rigid_body", backend="numpy")
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    assert sim.simulate(state, 5.0, params).steps == 5
    assert sim.simulate(state, np.float64(12), params, every=4.0).step_indices.tolist() == [
        0, 4, 8, 12]
    pieces = sim.stream(state, 1e7, params, every=1e6)
    assert pieces is not None
    pieces.close()


def test_max_iterations_is_checked_with_the_same_rule():
    assert sg.NewtonOptions(max_iterations=1e3).max_iterations == 1000
    assert sg.NewtonOptions(max_iterations=2**31 - 1).max_iterations == 2**31 - 1
    for bad, text in [(2**31, "at most 2147483647"), (10**30, "at most"),
                      (float("nan"), "finite integer"), (2.5, "an integer"),
                      (True, "boolean"), (-1, "at least 0")]:
        with pytest.raises(sg.ShapeError, match=f"NewtonOptions: max_iterations must .*{text}"):
            sg.NewtonOptions(max_iterations=bad)


@needs_cc
def test_largest_iteration_cap_reaches_c_without_overflow():
    sim = compiled("rigid_body")
    assert sim.backend == "c"
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    big = sg.NewtonOptions(max_iterations=2**31 - 1)
    a = sim.simulate(state, 20, params, options=big)
    b = sim.simulate(state, 20, params)
    assert np.array_equal(a.states, b.states)
