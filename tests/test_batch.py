"""Simulator.simulate_batch: B runs in one kernel call, bitwise the runs of simulate.

Also the batched C entry point's own argument checks, the vectorised input checks (an error
names the row), the kernel built with and without OpenMP, and the pickling of a simulator
into a fresh process with an empty kernel cache.
"""

from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    SEED_DATA,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
    seed_step,
)

import symgroupoid as sg
from symgroupoid.runtime import DetachedStepError, NotPortableError, toolchain
from symgroupoid.runtime.toolchain import DEFAULT_FLAGS

pytestmark = needs_cc

RIGID = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}


def rotation(theta: float, axis=(1.0, 2.0, 3.0)) -> np.ndarray:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


def plate_ball_states(sim, n: int) -> np.ndarray:
    """n consistent plate-ball states: every 7th state of one run."""
    params = SEED_DATA["plate_ball"][0]
    return sim.simulate(initial_state(sim, "plate_ball"), 7 * n, params, every=7).states[:n].copy()


def assert_same_run(batch_run: sg.Trajectory, single: sg.Trajectory) -> None:
    for name in ("states", "newton_iterations", "residual_norms", "step_indices"):
        assert np.array_equal(getattr(batch_run, name), getattr(single, name)), name
    assert batch_run.parameters == single.parameters and batch_run.every == single.every


@pytest.mark.parametrize("every", [1, 7, 1000])
def test_batch_is_bitwise_separate_simulate_calls(every):
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    S = plate_ball_states(sim, 12)
    batch = sim.simulate_batch(S, 300, params, every=every)
    assert batch.ok.all() and batch.states.shape == (12, 1 + -(-300 // every), 16)
    for b in range(12):
        assert_same_run(batch[b], sim.simulate(S[b], 300, params, every=every))
    one_thread = sim.simulate_batch(S, 300, params, every=every, threads=1)
    assert np.array_equal(one_thread.states, batch.states)
    assert np.array_equal(batch.final_states, S[:, :0].shape and batch.states[:, -1])


@pytest.mark.parametrize("options, statuses", [
    (sg.NewtonOptions(), {0, 1}),  # singular Jacobians at steps 0 and 1
    # the iteration cap at several steps (large turns may also meet a singular Jacobian)
    (sg.NewtonOptions(max_iterations=8), {0, 2}),
])
def test_failed_runs_stop_alone_with_the_error_simulate_raises(options, statuses):
    """Runs that fail at different steps are recorded with their status and failing step
    and end as simulate's error trajectory ends; the others complete."""
    sim = compiled("rigid_body")
    thetas = [0.1, 1.0, 1.5, 0.3, 1.9, 1.2, 0.05]
    S = np.array([sim.state({"W": rotation(t)}) for t in thetas])
    batch = sim.simulate_batch(S, 200, RIGID, every=3, options=options)
    assert 0 < batch.ok.sum() < len(thetas)
    assert statuses <= {int(s) for s in batch.status} <= {0, 1, 2}
    for b, theta in enumerate(thetas):
        try:
            single = sim.simulate({"W": rotation(theta)}, 200, RIGID, every=3, options=options)
        except (sg.SingularJacobianError, sg.NewtonDivergenceError) as err:
            failed = batch.error(b)
            assert type(failed) is type(err) and str(failed) == str(err)
            assert failed.step == err.step == batch.failed_step[b]
            assert np.array_equal(failed.iterate, err.iterate)
            assert_same_run(batch[b], err.trajectory)
            assert_same_run(failed.trajectory, err.trajectory)
            k = batch.kept[b]
            assert np.isnan(batch.states[b, k:]).all() and (batch.newton_iterations[b, k - 1:]
                                                            == -1).all()
        else:
            assert batch.status[b] == 0 and batch.failed_step[b] == -1
            assert batch.error(b) is None
            assert_same_run(batch[b], single)
    assert any(batch.failed_step[b] > 0 for b in range(len(thetas)))


def test_parameter_tables_pair_row_by_row():
    sim = compiled("rigid_body")
    S = np.array([sim.state({"W": rotation(t)}) for t in (0.1, 0.2, 0.3)])
    table = {"h": [0.01, 0.02, 0.005], "I1": [1.0, 1.0, 2.0], "I2": [2.0] * 3, "I3": [3.0] * 3}
    batch = sim.simulate_batch(S, 50, table)
    rows = sim.simulate_batch(S, 50, [[0.01, 1, 2, 3], [0.02, 1, 2, 3], [0.005, 2, 2, 3]])
    assert np.array_equal(batch.states, rows.states)
    for b in range(3):
        params = {k: v[b] for k, v in table.items()}
        assert_same_run(batch[b], sim.simulate(S[b], 50, params))


def test_batch_inputs_are_checked_and_the_bad_row_named():
    sim = compiled("rigid_body")
    S = np.array([sim.state({"W": rotation(t)}) for t in (0.1, 0.2, 0.3, 0.4)])
    bad = S.copy()
    bad[2, :9] = (2 * rotation(0.3)).ravel()  # not a rotation
    with pytest.raises(sg.DomainError, match="initial state 2: .*not in SO"):
        sim.simulate_batch(bad, 10, RIGID)
    bad = S.copy()
    bad[3, 4] = np.nan
    with pytest.raises(sg.ShapeError, match="initial state 3: .*non-finite"):
        sim.simulate_batch(bad, 10, RIGID)
    table = [dict(RIGID), dict(RIGID), {**RIGID, "I2": -1.0}, dict(RIGID)]
    with pytest.raises(sg.ParameterError, match="parameter set 2: .*I2 is declared positive"):
        sim.simulate_batch(S, 10, table)
    columns = {k: [v] * 4 for k, v in RIGID.items()}
    columns["h"] = [0.01, 0.01, 0.01, 0.0]
    with pytest.raises(sg.ParameterError, match="parameter set 3: .*h is declared positive"):
        sim.simulate_batch(S, 10, columns)
    with pytest.raises(sg.ShapeError, match="4 initial states but 3 parameter sets"):
        sim.simulate_batch(S, 10, [dict(RIGID)] * 3)
    with pytest.raises(sg.ShapeError, match=r"shape \(B, 9\)"):
        sim.simulate_batch(S[:, :5], 10, RIGID)
    with pytest.raises(sg.ShapeError, match="every"):
        sim.simulate_batch(S, 10, RIGID, every=0)


def test_constraints_of_each_row_are_checked():
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    S = plate_ball_states(sim, 5)
    S[4, 0] += 1e-3  # x_{k-1} moved: the rolling constraints no longer hold
    with pytest.raises(sg.DomainError,
                       match="initial state 4: .*violates the constraints"):
        sim.simulate_batch(S, 10, params)


def test_openmp_and_serial_builds_agree_bitwise():
    if not toolchain.openmp_available():
        pytest.skip("the C compiler does not support OpenMP")
    threaded = compiled("rigid_body")
    serial = seed_step("rigid_body").compile(backend="c", flags=DEFAULT_FLAGS)
    assert threaded.kernel.openmp and not serial.kernel.openmp
    assert threaded.cache_entry != serial.cache_entry  # the flag is part of the cache key
    S = np.array([threaded.state({"W": rotation(t)}) for t in np.linspace(0.05, 1.4, 16)])
    a = threaded.simulate_batch(S, 150, RIGID, threads=2)
    b = serial.simulate_batch(S, 150, RIGID)
    assert np.array_equal(a.states, b.states, equal_nan=True)
    assert np.array_equal(a.status, b.status)


def test_numpy_backend_batches_alike_and_does_not_pickle():
    sim = seed_step("rigid_body").compile(backend="numpy")
    S = np.array([sim.state({"W": rotation(t)}) for t in (0.1, 1.5)])
    batch = sim.simulate_batch(S, 5, RIGID, every=2)
    assert_same_run(batch[0], sim.simulate(S[0], 5, RIGID, every=2))
    assert batch.status[1] == 1 and batch.failed_step[1] == 1
    with pytest.raises(NotPortableError, match="backend='c'"):
        pickle.dumps(sim)


def test_c_entry_point_checks_its_arguments():
    sim = compiled("rigid_body")
    kernel = sim.kernel
    lib, ffi, P = kernel.lib, kernel.ffi, kernel.prefix
    fn = getattr(lib, f"{P}_simulate_batch")
    known = np.array([sim.state({"W": rotation(0.1)})] * 2)
    p = sim.parameters(RIGID)
    states = np.zeros(2 * 3 * 9)
    its = np.zeros(2 * 2, np.longlong)
    norms = np.zeros(4)
    kept = np.zeros(2, np.dtype("l"))
    status = np.zeros(2, np.intc)

    def call(n_steps=4, every=2, rows=3, p_stride=0):
        return fn(2, ffi.from_buffer("double[]", known), ffi.from_buffer("double[]", p),
                  p_stride, ffi.NULL, 0, n_steps, every, ffi.NULL,
                  ffi.from_buffer("double[]", states), rows,
                  ffi.from_buffer("long long[]", its), ffi.from_buffer("double[]", norms),
                  ffi.from_buffer("long[]", kept), ffi.from_buffer("int[]", status),
                  ffi.NULL, ffi.NULL, ffi.NULL, ffi.NULL, 1)

    assert call() == 0 and list(kept) == [3, 3] and list(status) == [0, 0]
    states[:] = -7.0
    assert call(rows=2) == 4  # 1 + ceil(4 / 2) rows needed
    assert call(every=0) == 4 and call(n_steps=-1) == 4 and call(p_stride=3) == 4
    assert (states == -7.0).all()  # nothing written
    known[1, 0] = np.inf
    assert call() == 0 and list(status) == [0, 4] and kept[1] == 0


FRESH = """
import json, pickle, sys
import numpy as np
sim = pickle.load(open(sys.argv[1], "rb"))
data = np.load(sys.argv[2])
traj = sim.simulate(data["S"][0], 200, data["p"], every=3)
batch = sim.simulate_batch(data["S"], 200, data["p"], every=3)
try:
    sim.from_momentum(None, (0.1, 0.2, 0.3), data["p"])
    detached = "no error"
except Exception as exc:
    detached = type(exc).__name__
np.savez(sys.argv[3], single=traj.states, batch=batch.states, status=batch.status)
print(json.dumps({"name": sim.name, "backend": sim.backend, "detached": detached,
                  "entry": str(sim.cache_entry), "parts": list(sim.layout.names)}))
"""


def test_a_pickled_simulator_runs_in_a_fresh_process_with_an_empty_cache(tmp_path):
    sim = compiled("rigid_body")
    S = np.array([sim.state({"W": rotation(t)}) for t in (0.1, 0.6, 1.0, 1.5)])
    p = sim.parameters(RIGID)
    blob = pickle.dumps(sim)
    assert b"sympy" not in blob  # plain data: no symbolic expression inside
    (tmp_path / "sim.pkl").write_bytes(blob)
    np.savez(tmp_path / "in.npz", S=S, p=p)
    fresh = tmp_path / "fresh-cache"
    env = {**os.environ, "SYMGROUPOID_CACHE": str(fresh), "PYTHONPATH": str(REPO)}
    run = subprocess.run([sys.executable, "-c", FRESH, str(tmp_path / "sim.pkl"),
                          str(tmp_path / "in.npz"), str(tmp_path / "out.npz")],
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr
    info = json.loads(run.stdout.splitlines()[-1])
    assert info["name"] == "rigid_body" and info["backend"] == "c"
    assert info["detached"] == "DetachedStepError" and info["parts"] == ["W"]
    assert info["entry"].startswith(str(fresh))  # built into the fresh, empty cache
    out = np.load(tmp_path / "out.npz")
    assert np.array_equal(out["single"], sim.simulate(S[0], 200, p, every=3).states)
    local = sim.simulate_batch(S, 200, p, every=3)
    assert np.array_equal(out["batch"], local.states, equal_nan=True)
    assert np.array_equal(out["status"], local.status)


def test_an_unpickled_simulator_checks_states_and_parameters_as_the_original():
    sim = compiled("rigid_body")
    copy = pickle.loads(pickle.dumps(sim))
    assert type(copy.equations).__name__ == "DetachedStep"
    with pytest.raises(sg.DomainError, match="not in SO"):
        copy.simulate({"W": 2 * np.eye(3)}, 2, RIGID)
    with pytest.raises(sg.ParameterError, match="declared positive"):
        copy.simulate({"W": rotation(0.1)}, 2, {**RIGID, "h": -0.1})
    with pytest.raises(DetachedStepError, match="without the symbolic step"):
        copy.equations.groupoid  # noqa: B018
    again = pickle.loads(pickle.dumps(copy))  # a restored simulator pickles again
    assert np.array_equal(again.simulate({"W": rotation(0.2)}, 20, RIGID).states,
                          sim.simulate({"W": rotation(0.2)}, 20, RIGID).states)


def test_embedded_batch_program_reproduces_simulate_batch(tmp_path):
    """examples/embed/batch.c: plate_ball_simulate_batch from plain C (no OpenMP)."""
    exe = tmp_path / "batch_demo"
    build = subprocess.run(
        ["cc", "-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror",
         f"-I{REPO / 'generated'}", str(REPO / "examples" / "embed" / "batch.c"),
         str(REPO / "generated" / "plate_ball.c"), "-lm", "-o", str(exe)],
        capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    stdin = (" ".join(repr(float(v)) for v in sim.parameters(params)) + "\n"
             + " ".join(repr(float(v)) for v in state) + "\n")
    run = subprocess.run([str(exe), "5", "120", "7"], input=stdin, capture_output=True,
                         text=True, check=True)
    table = np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])
    starts = sim.simulate(state, 4, params).states
    batch = sim.simulate_batch(starts, 120, params, every=7)
    assert np.array_equal(table[:, 1], batch.status) and np.array_equal(table[:, 3], batch.kept)
    assert np.abs(table[:, 4:] - batch.final_states).max() <= 1e-12 * max(
        1.0, np.abs(batch.final_states).max())
    # counts that are not whole numbers in range are a usage error, and sizes past the
    # address space an out-of-memory message: RUNS = 2^62 wrapped every buffer to
    # malloc(0) and the start states overran them (heap corruption, abort)
    for args in (["4611686018427387904", "1", "1"], ["10abc", "1", "1"], ["0", "1", "1"],
                 ["2", "-1", "1"], ["2", "1", "0"], ["2", "99999999999999999999", "1"]):
        run = subprocess.run([str(exe), *args], input=stdin, capture_output=True, text=True,
                             timeout=60)
        assert run.returncode == 2 and "usage" in run.stderr, (args, run.stderr)
    run = subprocess.run([str(exe), "2000000000", "9000000000000000000", "1"], input=stdin,
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 1 and "out of memory" in run.stderr, run.stderr


# --- installments: long runs split across kernel calls; Ctrl-C ---------------------------------

def test_the_installment_entry_point_checks_its_cursors():
    sim = compiled("rigid_body")
    kernel = sim.kernel
    S = np.array([sim.state({"W": rotation(0.1)})] * 2)
    p = sim.parameters(RIGID)
    out = kernel._batch_buffers(2, 10, 2)
    cursors = kernel.batch_cursors(2)
    kernel.batch_until(cursors, S, p, 10, 2, 5, sim.options, out)
    assert list(out.status) == [0, 0] and list(out.kept) == [3, 3]
    assert cursors[0].done == 5 and cursors[0].last_kept == 4
    cursors[1].last_kept = 3  # not a kept step: this cursor does not describe its run
    kernel.batch_until(cursors, S, p, 10, 2, 10, sim.options, out)
    assert list(out.status) == [0, 4] and out.kept[0] == 6
    with pytest.raises(sg.ShapeError, match="batch_cursors"):
        kernel.batch_until(kernel.batch_cursors(1), S, p, 10, 2, 10, sim.options, out)
    fn = getattr(kernel.lib, f"{kernel.prefix}_simulate_batch_until")
    assert fn(2, kernel.ffi.NULL, *[kernel.ffi.NULL] * 2, 0, kernel.ffi.NULL, 0, 10, 2, 10,
              *[kernel.ffi.NULL] * 2, 6, *[kernel.ffi.NULL] * 8, 1) == 4


def _interrupt_after(seconds: float) -> tuple[threading.Thread, list]:
    """SIGINT to this process after ``seconds`` (from a timer thread); the time it was sent."""
    sent: list = []

    def fire():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(seconds, fire)
    timer.start()
    return timer, sent


def test_ctrl_c_stops_a_batch_within_a_kernel_call_with_the_partial_batch():
    """A batch of some 20 s of work: SIGINT after 0.3 s raises KeyboardInterrupt within a
    call of about 0.05 s, carrying ``.batch``: every run up to the step it reached,
    bitwise what simulate gives for those steps."""
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    S = plate_ball_states(sim, 8)
    timer, sent = _interrupt_after(0.3)
    with pytest.raises(KeyboardInterrupt) as caught:
        sim.simulate_batch(S, 2_000_000, params, every=1000)
    latency = time.perf_counter() - sent[0]
    timer.join()
    batch = caught.value.batch
    assert (batch.status == sg.Status.INTERRUPTED).all()
    reached = batch.failed_step
    assert (reached > 0).all() and (reached < 2_000_000).all()
    for b in (0, 7):
        assert_same_run(batch[b], sim.simulate(S[b], int(reached[b]), params, every=1000))
    # calls of about 0.05 s of work: typically 0.02–0.08 s; the bound leaves room for a
    # machine shared with other jobs (before: the whole batch, here some 20 s)
    assert latency < 0.5, f"Ctrl-C took {latency:.3f} s"
