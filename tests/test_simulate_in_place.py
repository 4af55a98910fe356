"""A run that keeps every state is written by the kernel straight into the arrays of the
result, chunk by chunk: bitwise the run of one kernel call, of chunks of one step, of the
NumPy backend and of the streamed pieces (which are copied), also when it fails mid-run or
is interrupted; and the kernel's in-place entry point writes nothing outside its buffers."""

from __future__ import annotations

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
from symgroupoid.stepper import Status

INVALID_ARGUMENT, OK = Status.INVALID_ARGUMENT, Status.OK


@pytest.fixture(scope="module")
def fall_step():
    return falling("fall_in_place")


def same_run(a: sg.Trajectory, b: sg.Trajectory) -> None:
    assert np.array_equal(a.states, b.states)
    assert np.array_equal(a.step_indices, b.step_indices)
    assert np.array_equal(a.newton_iterations, b.newton_iterations)
    assert np.array_equal(a.residual_norms, b.residual_norms)
    assert a.newton_iterations.dtype == b.newton_iterations.dtype == np.int64
    assert a.states.dtype == np.float64 and a.every == b.every


def joined(pieces: list[sg.Trajectory]) -> tuple[np.ndarray, ...]:
    """The streamed pieces (copied by the sampler) joined into one run."""
    states = np.concatenate([pieces[0].states] + [p.states[1:] for p in pieces[1:]])
    indices = np.concatenate([pieces[0].step_indices] + [p.step_indices[1:]
                                                         for p in pieces[1:]])
    its = np.concatenate([p.newton_iterations for p in pieces])
    norms = np.concatenate([p.residual_norms for p in pieces])
    return states, indices, its, norms


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_state_kept_is_bitwise_the_chunk_size_one_run(backend, chunk):
    sim = compiled("plate_ball", backend=backend)
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    steps = 200 if backend == "c" else 30
    one = sim.kernel.simulate(state, sim.parameters(params), steps, sim.options)
    chunk(1)
    reference = sim.simulate(state, steps, params)
    assert np.array_equal(reference.states, one.states)
    assert np.array_equal(reference.newton_iterations, one.iterations)
    for n in (7, steps - 1, 1 << 14):
        chunk(n)
        traj = sim.simulate(state, steps, params)
        same_run(traj, reference)
        assert not traj.states.flags.writeable and not traj.residual_norms.flags.writeable
    states, indices, its, norms = joined(list(sim.stream(state, steps, params)))
    assert np.array_equal(states, reference.states)
    assert np.array_equal(indices, np.arange(steps + 1))
    assert np.array_equal(its, reference.newton_iterations)
    assert np.array_equal(norms, reference.residual_norms)


@needs_cc
def test_compiled_run_is_bitwise_the_numpy_run(chunk):
    c_sim, np_sim = compiled("plate_ball"), compiled("plate_ball", backend="numpy")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(c_sim, "plate_ball")
    chunk(4)
    a, b = c_sim.simulate(state, 30, params), np_sim.simulate(state, 30, params)
    same_run(a, b)
    assert a.backend == "c" and b.backend == "numpy"


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("every", [1, 3])
def test_failure_mid_run_is_the_same_for_every_chunk_size(backend, every, fall_step, chunk):
    """The failing step, its data and the trajectory up to it do not depend on the chunks;
    the streamed pieces (a separate path, copying) end at the same state."""
    sim = fall_step.compile(backend=backend, cache_dir=SESSION_CACHE)
    results = []
    for n in (1, 5, 16, 1 << 14):
        chunk(n)
        with pytest.raises(sg.NewtonDivergenceError) as info:
            sim.simulate(FALL_START, 1000, FALL_PARAMS, every=every)
        results.append(info.value)
    first = results[0]
    assert 16 < first.step < 1000 and first.trajectory.step_indices[-1] == first.step
    for err in results[1:]:
        assert err.step == first.step and str(err) == str(first)
        assert err.residual_norm == first.residual_norm or (
            np.isnan(err.residual_norm) and np.isnan(first.residual_norm))
        assert np.array_equal(err.iterate, first.iterate, equal_nan=True)
        same_run(err.trajectory, first.trajectory)
    assert np.isfinite(first.trajectory.states).all()
    chunk(16)
    pieces = []
    with pytest.raises(sg.NewtonDivergenceError) as streamed:
        for piece in sim.stream(FALL_START, 1000, FALL_PARAMS, every=every):
            pieces.append(piece)
    pieces.append(streamed.value.trajectory)
    states, indices, its, norms = joined(pieces)
    assert streamed.value.step == first.step
    assert np.array_equal(states, first.trajectory.states)
    assert np.array_equal(indices, first.trajectory.step_indices)
    assert np.array_equal(its, first.trajectory.newton_iterations)
    assert np.array_equal(norms, first.trajectory.residual_norms)


@needs_cc
@pytest.mark.parametrize("every", [1, 4])
def test_every_kth_state_is_the_whole_run_sampled(every, chunk):
    sim = compiled("rigid_body")
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    chunk(1)
    whole = sim.simulate(state, 50, params)
    chunk(6)
    traj = sim.simulate(state, 50, params, every=every)
    kept = np.unique(np.append(np.arange(0, 51, every), 50))
    assert np.array_equal(traj.step_indices, kept)
    assert np.array_equal(traj.states, whole.states[kept])
    sums = [whole.newton_iterations[a:b].sum() for a, b in zip(kept[:-1], kept[1:])]
    assert np.array_equal(traj.newton_iterations, sums)


@needs_cc
def test_callback_pieces_and_interrupt_of_a_whole_run(chunk):
    sim = compiled("rigid_body")
    params = SEED_DATA["rigid_body"][0]
    state = initial_state(sim, "rigid_body")
    chunk(10)
    whole = sim.simulate(state, 95, params)
    seen = []
    again = sim.simulate(state, 95, params, callback=seen.append)
    same_run(again, whole)
    assert [p.step_indices[0] for p in seen] == list(range(0, 95, 10))
    assert all(not p.states.flags.writeable for p in seen)
    states, indices, its, norms = joined(seen)
    assert np.array_equal(states, whole.states) and np.array_equal(indices, np.arange(96))
    assert np.array_equal(its, whole.newton_iterations)

    def stop(piece):
        if piece.step_indices[-1] >= 30:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt) as info:
        sim.simulate(state, 10**6, params, callback=stop)
    traj = info.value.trajectory
    assert traj.steps == 30 and np.array_equal(traj.states, whole.states[:31])
    assert np.array_equal(traj.newton_iterations, whole.newton_iterations[:30])


# --- the in-place entry point of the kernels --------------------------------------------------

def buffers(n_known: int, rows: int, pad: int = 2):
    """Run buffers of ``rows`` states inside larger arrays filled with a sentinel."""
    big = np.full((rows + 2 * pad, n_known), 7.25)
    its = np.full(rows - 1 + 2 * pad, -5, dtype=np.intc)
    norms = np.full(rows - 1 + 2 * pad, 7.25)
    return (big, its, norms), (big[pad:pad + rows], its[pad:pad + rows - 1],
                               norms[pad:pad + rows - 1])


@pytest.mark.parametrize("backend", BACKENDS)
def test_simulate_into_writes_only_its_rows(backend):
    sim = compiled("rigid_body", backend=backend)
    params = sim.parameters(SEED_DATA["rigid_body"][0])
    state = initial_state(sim, "rigid_body")
    reference = sim.kernel.simulate(state, params, 12, sim.options)
    (big, big_its, big_norms), (states, its, norms) = buffers(sim.layout.n_known, 13)
    states[0] = state
    warm = sim.kernel.warm_start()
    for start, n in ((0, 5), (5, 0), (5, 7)):  # the last call ends at the last row
        out = sim.kernel.simulate_into(states, its, norms, start, n, params, sim.options, warm)
        assert out.status == OK and out.completed == n and out.failed_step == -1
    assert np.array_equal(states, reference.states)
    assert np.array_equal(its, reference.iterations)
    assert np.array_equal(norms, reference.residual_norms)
    for outside in (big[:2], big[-2:], big_norms[:2], big_norms[-2:]):
        assert (outside == 7.25).all()
    assert (big_its[:2] == -5).all() and (big_its[-2:] == -5).all()


@pytest.mark.parametrize("backend", BACKENDS)
def test_simulate_into_refuses_buffers_that_do_not_hold_the_run(backend):
    sim = compiled("rigid_body", backend=backend)
    kernel, options = sim.kernel, sim.options
    params = sim.parameters(SEED_DATA["rigid_body"][0])
    n_k = sim.layout.n_known
    states, its, norms = np.zeros((6, n_k)), np.zeros(5, np.intc), np.zeros(5)
    states[0] = initial_state(sim, "rigid_body")
    bad = [
        ((states, its, norms, 0, 6), "n_steps must be at most 5"),
        ((states, its, norms, 3, 3), "n_steps must be at most 2"),
        ((states, its, norms, 6, 0), "start must be at most 5"),
        ((states, its, norms, -1, 1), "start must be at least 0"),
        ((states, its.astype(np.int64), norms, 0, 1), "iterations: .* dtype int32"),
        ((states, its, norms[:4], 0, 1), r"residual_norms: .* shape \(5,\)"),
        ((states, its[:4], norms, 0, 1), r"iterations: .* shape \(5,\)"),
        ((states[:, :-1].copy(), its, norms, 0, 1), r"states: .* shape \(R, "),
        ((np.asfortranarray(states), its, norms, 0, 1), "states: .* C-contiguous"),
        ((states[::2], its[:2], norms[:2], 0, 1), "states: .*not C-contiguous"),
        ((states.astype(np.float32), its, norms, 0, 1), "states: .* float64"),
        ((states.tolist(), its, norms, 0, 1), "states: .* got list"),
        ((np.zeros((0, n_k)), np.zeros(0, np.intc), np.zeros(0), 0, 0),
         "R >= 1"),
    ]
    frozen = states.copy()
    frozen.setflags(write=False)
    bad.append(((frozen, its, norms, 0, 1), "states: .* read-only"))
    if np.dtype(np.intc) != np.dtype(np.int32):  # pragma: no cover (no such platform here)
        bad = [b for b in bad if "int32" not in b[1]]
    for (s, i, r, start, n), text in bad:
        with pytest.raises(sg.ShapeError, match=text):
            kernel.simulate_into(s, i, r, start, n, params, options, kernel.warm_start())
    assert np.array_equal(its, np.zeros(5)) and np.array_equal(norms, np.zeros(5))
    assert (states[1:] == 0).all()
    with pytest.raises(sg.ShapeError, match="p must have shape"):
        kernel.simulate_into(states, its, norms, 0, 1, params[:-1], options, None)
    with pytest.raises(sg.ShapeError, match="warm start"):
        kernel.simulate_into(states, its, norms, 0, 1, params, options, object())
    # a non-finite first state is refused with nothing written
    states[2] = np.nan
    out = kernel.simulate_into(states, its, norms, 2, 3, params, options, None)
    assert out.status == INVALID_ARGUMENT and out.completed == 0
    assert (states[3:] == 0).all() and (its == 0).all()
