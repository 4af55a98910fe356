"""sg.sweep and sg.sweep_boundary_value: in this process, on a local process pool, and on a
real Dask cluster (LocalCluster with worker processes), including a worker killed
mid-sweep; the results equal the serial ones exactly."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    SESSION_CACHE,
    compiled,
    isolated_cache,
    needs_cc,
    seed_step,
)

import symgroupoid as sg

pytestmark = needs_cc

RIGID = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
TABLE = {"h": [0.01, 0.02, 0.005], "I1": [1.0, 1.5, 1.0], "I2": [2.0] * 3, "I3": [3.0] * 3}


def rotation(theta: float, axis=(1.0, 2.0, 3.0)) -> np.ndarray:
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(theta) * K + (1 - np.cos(theta)) * K @ K


def states(thetas) -> np.ndarray:
    sim = compiled("rigid_body")
    return np.array([sim.state({"W": rotation(t)}) for t in thetas])


#: 1.5 and 1.9 fail (singular Jacobians at steps 1 and 0); the others complete
THETAS = [0.1, 1.5, 0.4, 1.9, 0.8, 0.2]


def serial_value(sim, S, params, steps, options=None):
    """What each run gives with Simulator.simulate: the last x-entry of W, or None."""
    try:
        return sim.simulate(S, steps, params, options=options).states[-1, 0]
    except (sg.SingularJacobianError, sg.NewtonDivergenceError):
        return None


def check_against_simulate(result, sim, S, steps, options=None) -> None:
    assert result.shape == (len(S), 3)
    for i in range(len(S)):
        for j in range(3):
            params = {k: v[j] for k, v in TABLE.items()}
            expected = serial_value(sim, S[i], params, steps, options)
            if expected is None:
                assert result.status[i, j] != 0 and np.isnan(result.values[i, j])
                assert "failed" in result.messages[i, j]
            else:
                assert result.status[i, j] == 0 and result.values[i, j] == expected
                assert result.messages[i, j] is None and result.failed_step[i, j] == -1


def test_sweep_in_process_product_zip_and_failures():
    sim = compiled("rigid_body")
    S = states(THETAS)
    res = sg.sweep(sim, initial=S, params=TABLE, steps=60, reduce=lambda t: t.states[-1, 0],
                   workers=1)
    check_against_simulate(res, sim, S, 60)
    assert (~res.ok).sum() == 6 and res.failed_step[1, 0] == 1 and res.failed_step[3, 0] == 0
    assert np.ma.count_masked(res.masked()) == 6
    zipped = sg.sweep(sim, S[:3], [RIGID, RIGID, {**RIGID, "h": 0.02}], 60, combine="zip",
                      reduce=lambda t: t.states[-1, :3], workers=1)
    assert zipped.shape == (3,) and zipped.values.shape == (3, 3)
    assert np.array_equal(zipped.values[2], sim.simulate(S[2], 60, {**RIGID, "h": 0.02})
                          .states[-1, :3])
    # without reduce: the trajectories, a failed run up to its failure
    full = sg.sweep(sim, S[:2], RIGID, 30, every=4, workers=1)
    assert full.shape == (2,) and full.values is None
    assert np.array_equal(full.trajectories[0].states,
                          sim.simulate(S[0], 30, RIGID, every=4).states)
    with pytest.raises(sg.SingularJacobianError) as err:
        sim.simulate(S[1], 30, RIGID, every=4)
    assert np.array_equal(full.trajectories[1].states, err.value.trajectory.states)
    # reduce_failures: the partial trajectory of a failed run is reduced too
    lengths = sg.sweep(sim, S, RIGID, 30, reduce=len, reduce_failures=True, workers=1)
    assert lengths.values.tolist() == [31, 2, 31, 1, 31, 31]


def test_sweep_checks_every_input_before_running():
    sim = compiled("rigid_body")
    S = states(THETAS[:3])
    with pytest.raises(sg.ParameterError, match="parameter set 1: .*I1 is declared positive"):
        sg.sweep(sim, S, {**TABLE, "I1": [1.0, -1.0, 1.0]}, 10, workers=1)
    with pytest.raises(sg.ShapeError, match="combine='zip'"):
        sg.sweep(sim, S, [RIGID] * 2, 10, combine="zip", workers=1)
    with pytest.raises(ValueError, match="combine must be one of"):
        sg.sweep(sim, S, RIGID, 10, combine="outer", workers=1)
    plate = compiled("plate_ball")
    from kernel_support import SEED_DATA, initial_state

    params = SEED_DATA["plate_ball"][0]
    good = initial_state(plate, "plate_ball")
    with pytest.raises(sg.ShapeError, match="initial state 0 with parameter set 1: .*"
                                            "violates the constraints"):
        sg.sweep(plate, [good], [params, {**params, "c": 0.05}], 10, workers=1)


def test_sweep_to_dataframe():
    pd = pytest.importorskip("pandas")
    sim = compiled("rigid_body")
    res = sg.sweep(sim, states(THETAS[:2]), TABLE, 20, reduce=lambda t: t.states[-1, 0],
                   workers=1)
    frame = res.to_dataframe()
    assert isinstance(frame, pd.DataFrame) and len(frame) == 6
    assert list(frame.columns) == ["initial", "parameters", "h", "I1", "I2", "I3", "status",
                                   "failed_step", "message", "value"]
    assert frame["h"].tolist() == TABLE["h"] * 2
    assert frame["value"].iloc[4] == res.values[1, 1] or np.isnan(res.values[1, 1])


def _dask_cluster():
    distributed = pytest.importorskip("distributed")
    cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                                       dashboard_address=None)
    return cluster, distributed.Client(cluster)


def test_dask_sweep_equals_the_serial_one():
    sim = compiled("rigid_body")
    S = states(THETAS)
    serial = sg.sweep(sim, S, TABLE, 60, reduce=lambda t: t.states[-1, 0], workers=1)
    cluster, client = _dask_cluster()
    with cluster, client:
        res = sg.sweep(sim, S, TABLE, 60, reduce=lambda t: t.states[-1, 0], client=client,
                       chunk_size=4)
    assert res.tasks == 5
    assert np.array_equal(res.values, serial.values, equal_nan=True)
    assert np.array_equal(res.status, serial.status)
    assert np.array_equal(res.failed_step, serial.failed_step)
    check_against_simulate(res, sim, S, 60)


@pytest.mark.slow
def test_dask_sweep_survives_a_killed_worker():
    """One worker process is killed after the first results arrive; Dask reschedules its
    tasks and the result is complete, each run once, equal to the serial sweep."""
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 1.2, 12))
    steps = 150_000
    serial = sg.sweep(sim, S, TABLE, steps, reduce=lambda t: t.states[-1, 0], workers=1)
    cluster, client = _dask_cluster()
    killed: list = []
    lock = threading.Lock()
    with cluster, client:
        pids = client.run(os.getpid)

        def progress(done, total):
            with lock:
                if not killed and 0 < done < total:
                    victim = sorted(pids.values())[0]
                    os.kill(victim, signal.SIGKILL)
                    killed.append(victim)

        res = sg.sweep(sim, S, TABLE, steps, reduce=lambda t: t.states[-1, 0],
                       client=client, chunk_size=2, progress=progress)
    assert killed and res.tasks == 18
    assert np.array_equal(res.values, serial.values, equal_nan=True)
    assert np.array_equal(res.status, serial.status)


@pytest.mark.parametrize("executor", ["thread", pytest.param("process",
                                                               marks=pytest.mark.slow)])
def test_local_workers_equal_the_serial_sweep(executor, monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(SESSION_CACHE))  # (for worker processes)
    sim = compiled("rigid_body")
    S = states(THETAS)
    serial = sg.sweep(sim, S, TABLE, 500, reduce=lambda t: t.states[-1, 0], workers=1)
    pooled = sg.sweep(sim, S, TABLE, 500, reduce=lambda t: t.states[-1, 0], workers=2,
                      chunk_size=3, executor=executor)
    assert pooled.tasks == 6
    assert np.array_equal(pooled.values, serial.values, equal_nan=True)
    assert np.array_equal(pooled.failed_step, serial.failed_step)


h = sp.Symbol("h", positive=True)


def _so3_control():
    inertia = sp.diag(1, 2, 3)

    def L(g):
        xi = g.coordinates / h
        return h * (xi.T * inertia * xi)[0, 0] / 2

    return sg.DiscreteSystem(sg.SO3("g"), L, parameters=[h], name="so3_sweep")


@pytest.mark.slow
def test_boundary_value_sweep_with_continuation(monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")  # window kernels in NumPy: no build
    system = _so3_control()
    step = system.euler_lagrange()
    ends = [rotation(a, (0.5, -0.3, 0.8)) for a in (0.3, 0.6)]
    hs = [{"h": v} for v in (0.02, 0.025, 0.03)]
    res = sg.sweep_boundary_value(step, [np.eye(3)], ends, 12, params=hs, combine="product",
                                  workers=1)
    assert res.shape == (1, 2, 3) and res.ok.all()
    for j, end in enumerate(ends):
        for k, p in enumerate(hs):
            direct = sg.solve_boundary_value(step, np.eye(3), end, 12, params=p)
            assert np.array_equal(res.solutions[0, j, k].arrows, direct.arrows)
    threaded = sg.sweep_boundary_value(step, [np.eye(3)], ends, 12, params=hs,
                                       combine="product", workers=2)
    assert threaded.ok.all() and all(
        np.array_equal(a.arrows, b.arrows) for a, b in zip(threaded.solutions.ravel(),
                                                           res.solutions.ravel()))
    chained = sg.sweep_boundary_value(step, [np.eye(3)], ends, 12, params=hs,
                                      combine="product", continuation=True, workers=1,
                                      reduce=lambda s: s.iterations)
    assert chained.ok.all() and chained.values.shape == (1, 2, 3)
    # each continuation step starts from its neighbour's solution: fewer Newton iterations
    assert chained.values[0, :, 1:].sum() <= np.vectorize(lambda s: s.iterations)(
        res.solutions[0, :, 1:]).sum()


# --- plain scripts, bounded memory, Ctrl-C, timeouts, dying workers -------------------------------

def _child_env() -> dict:
    """A child process's environment: the session's kernels, this checkout importable."""
    env = dict(os.environ, SYMGROUPOID_CACHE=str(SESSION_CACHE), PYTHONHASHSEED="0",
               PYTHONPATH=os.pathsep.join([str(REPO), *filter(None, [os.environ.get(
                   "PYTHONPATH")])]))
    env.pop("SYMGROUPOID_BACKEND", None)
    return env


def _script(tmp_path, body: str) -> Path:
    """A user's script: the rigid body, compiled, and ``body`` at module level (no
    ``if __name__ == "__main__":`` guard)."""
    path = tmp_path / "user_script.py"
    path.write_text(textwrap.dedent("""\
        import json, os, signal, sys, time
        import numpy as np
        import symgroupoid as sg
        from symgroupoid.systems import SEED_SYSTEMS
        sim = SEED_SYSTEMS["rigid_body"]().euler_lagrange().compile()
        params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
        R = [np.array(sg.SO3("W").cayley([0.02 * b, 0.05, -0.03]).tolist(), float)
             for b in range(8)]
        states = np.array([sim.state({"W": W}) for W in R])
        """) + textwrap.dedent(body))
    return path


def test_a_plain_script_sweeps_on_threads_and_processes_without_a_main_guard(tmp_path):
    """The README's sweep pasted into a script and run with ``python script.py``: the
    workers (threads, and processes) never run the script again; a lambda and a function
    of the script serve as reduce."""
    script = _script(tmp_path, """\
        def last(traj):
            return traj.states[-1, 0]
        table = {"h": [0.01] * 3, "I1": [1.0] * 3, "I2": [2.0] * 3, "I3": [3.0, 3.5, 4.0]}
        out = {}
        for executor in ("thread", "process"):
            for reduce in (last, lambda traj: traj.states[-1, 0]):
                res = sg.sweep(sim, states, table, steps=300, reduce=reduce, workers=2,
                               chunk_size=5, executor=executor)
                out.setdefault(executor, []).append(res.values.tolist())
        print("RESULT", json.dumps(out))
        """)
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_child_env(),
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-4000:]
    out = json.loads(done.stdout.split("RESULT", 1)[1])
    sim = compiled("rigid_body")
    S = states_of_script(sim)
    expected = [[sim.simulate(S[i], 300, {**RIGID, "I3": I3}).states[-1, 0]
                 for I3 in (3.0, 3.5, 4.0)] for i in range(8)]
    for executor in ("thread", "process"):
        assert out[executor] == [expected, expected], executor


def states_of_script(sim) -> np.ndarray:
    R = [np.array(sg.SO3("W").cayley([0.02 * b, 0.05, -0.03]).tolist(), float)
         for b in range(8)]
    return np.array([sim.state({"W": W}) for W in R])


def test_processes_without_cloudpickle_refuse_a_function_of_the_script(tmp_path):
    script = _script(tmp_path, """\
        sys.modules["cloudpickle"] = None  # (as if not installed)
        try:
            sg.sweep(sim, states, params, 10, reduce=lambda t: 1.0, workers=2,
                     executor="process")
        except sg.SymgroupoidError as err:
            print("ERROR", type(err).__name__, err)
        """)
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=_child_env(),
                          capture_output=True, text=True, timeout=600)
    assert "ERROR NotPortableError" in done.stdout, done.stderr[-4000:]
    assert "install cloudpickle" in done.stdout and "executor='thread'" in done.stdout


@pytest.mark.parametrize("workers", [1, 2])
def test_reduce_holds_the_states_of_one_part_of_a_task_at_a_time(workers, monkeypatch):
    """200 runs × 5000 steps, every state kept, reduced to a view of the last state: the
    sweep's traced memory peaks at a few parts (of at most BATCH_BYTES), not at the
    states of all runs (before: all of a task's runs until the reduce, here 88 MB); the
    values are copies."""
    import tracemalloc

    monkeypatch.setattr("symgroupoid.runtime._memory.BATCH_BYTES", 1 << 20)
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 200))
    total = 200 * 5001 * 8 * sim.layout.n_known
    tracemalloc.start()
    try:
        res = sg.sweep(sim, S, RIGID, 5000, reduce=lambda t: {"last": t.states[-1]},
                       workers=workers)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    held = 2 * workers + 1 if workers > 1 else 1  # parts simulated, waiting, being reduced
    bound = (held + 1) * (1 << 20)  # (and 1 MiB for the rest of the sweep)
    assert res.ok.all() and bound < total / 8
    assert peak < bound, f"peak {peak / 2**20:.1f} MiB (all states: {total / 2**20:.0f} MiB)"
    for r in (0, 117, 199):
        last = res.values[r]["last"]
        assert last.base is None and np.array_equal(last, sim.simulate(S[r], 5000,
                                                                       RIGID).states[-1])


MEMORY_LIMIT = """
import resource
import numpy as np
import symgroupoid as sg
from symgroupoid.systems import SEED_SYSTEMS
from unittest import mock
sim = SEED_SYSTEMS["rigid_body"]().euler_lagrange().compile()
params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
S = np.array([sim.state({"W": np.eye(3)})] * 2000)
with open("/proc/self/statm") as f:
    used = int(f.read().split()[0]) * resource.getpagesize()
limit = used + (1 << 28)  # 256 MiB to spare
resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
def attempt(label, call):
    try:
        call()
        print(label, "ran")
    except MemoryError as err:
        print(label, type(err).__name__, isinstance(err, sg.TrajectoryTooLargeError), err)
# every trajectory back: 2000 x 20001 states (1.4 GB) are refused up front
attempt("all", lambda: sg.sweep(sim, S, params, 20000, workers=1))
# with reduce each run is reduced as it comes: the sweep fits
attempt("reduced", lambda: sg.sweep(sim, S[:40], params, 20000,
                                    reduce=lambda t: t.states[-1, 0], workers=2))
# one run alone over the limit: refused up front, naming the run's states
attempt("one_run", lambda: sg.sweep(sim, S[:2], params, 4_000_000,
                                    reduce=lambda t: 0.0, workers=1))
# one simulate over the limit: refused up front too (it compared with physical memory only)
attempt("simulate", lambda: sim.simulate(S[0], 4_000_000, params))
# within the limit by the count, but not in the address space left: no raw MemoryError
mock.patch("symgroupoid.runtime._memory.available_memory", lambda: 1 << 40).start()
attempt("allocation", lambda: sim.simulate_batch(S[:1000], 20000, params))
"""


def test_a_memory_limit_gives_trajectory_too_large_not_memory_error(tmp_path):
    """Under ``ulimit -v`` (RLIMIT_AS) a sweep's up-front check counts the states it
    keeps (all of them without reduce, the parts in flight with it) against the limit,
    and an allocation that fails all the same is a TrajectoryTooLargeError (before: a raw
    MemoryError from NumPy)."""
    done = subprocess.run([sys.executable, "-c", MEMORY_LIMIT], cwd=tmp_path,
                          env=_child_env(), capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-4000:]
    lines = dict(line.split(" ", 1) for line in done.stdout.splitlines())
    assert lines["all"].startswith("TrajectoryTooLargeError True")
    assert "more than this process may allocate" in lines["all"], lines["all"]
    assert lines["reduced"] == "ran"
    assert lines["one_run"].startswith("TrajectoryTooLargeError True")
    assert "held at once" in lines["one_run"]
    assert lines["allocation"].startswith("TrajectoryTooLargeError True"), lines["allocation"]
    assert lines["simulate"].startswith("TrajectoryTooLargeError True"), lines["simulate"]
    assert "more than this process may allocate" in lines["simulate"], lines["simulate"]


def _sigint_after(seconds: float, event: threading.Event | None = None
                  ) -> tuple[threading.Thread, list]:
    """SIGINT to this process ``seconds`` after the start (or after ``event`` is set: the
    moment a test waits for, whatever the machine's load)."""
    sent: list = []

    def fire():
        if event is not None:
            event.wait(120)
        time.sleep(seconds)
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Thread(target=fire, daemon=True)
    timer.start()
    return timer, sent


def _sweep_threads() -> list:
    return [t for t in threading.enumerate() if t.name.startswith("symgroupoid-")]


@pytest.mark.parametrize("hang", [False, True], ids=["healthy", "hanging reduce"])
def test_ctrl_c_stops_a_threaded_sweep_within_a_second_keeping_what_is_done(hang):
    """SIGINT after 1 s of a sweep of several seconds of work (or 0.2 s after reduce hangs,
    on the first run it gets): a KeyboardInterrupt within a second, carrying ``.result``:
    the runs done, bitwise simulate's, and the others INTERRUPTED; no worker thread left."""
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 64))
    hung: list = []
    hanging = threading.Event()

    def last(traj):
        if hang:
            hung.append(True)
            hanging.set()
            time.sleep(1000)
        return traj.states[-1, 0]

    timer, sent = _sigint_after(0.2, hanging) if hang else _sigint_after(1.0)
    with pytest.raises(KeyboardInterrupt) as caught:
        sg.sweep(sim, S, RIGID, 200_000, reduce=last, workers=2, chunk_size=2)
    latency = time.perf_counter() - sent[0]
    timer.join()
    res = caught.value.result
    assert isinstance(res, sg.SweepResult) and res.shape == (64,)
    stopped = res.status == sg.Status.INTERRUPTED
    assert stopped.any() and (res.ok | stopped).all()
    assert not hang or (hung and not res.ok.any())
    for r in np.flatnonzero(res.ok)[:1]:
        assert res.values[r] == sim.simulate(S[r], 200_000, RIGID).states[-1, 0]
    assert "interrupted" in res.messages[np.flatnonzero(stopped)[0]]
    assert latency < 1.0, f"Ctrl-C took {latency:.2f} s"
    time.sleep(0.2)
    assert _sweep_threads() == []


PROCESS_SWEEP = """
import os, sys, time
import numpy as np
import symgroupoid as sg
from symgroupoid.systems import SEED_SYSTEMS
sim = SEED_SYSTEMS["rigid_body"]().euler_lagrange().compile()
params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
S = np.array([sim.state({"W": np.eye(3)})] * 16)
HANG = sys.argv[1] == "hang"
def last(traj):
    print("REDUCING", os.getpid(), flush=True)
    if HANG:
        time.sleep(1000)
    return traj.states[-1, 0]
try:
    sg.sweep(sim, S, params, 300_000 if HANG else 3_000_000, reduce=last, workers=2,
             chunk_size=1, executor="process")
except KeyboardInterrupt as interrupt:
    print("INTERRUPTED", int(interrupt.result.ok.sum()), len(interrupt.result), flush=True)
"""


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (from /proc)."""
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                out.append(int(entry))
    return out


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
@pytest.mark.parametrize("hang", [pytest.param(False, marks=pytest.mark.slow), True],
                         ids=["healthy", "hanging reduce"])
def test_ctrl_c_stops_a_process_sweep_and_ends_its_workers(hang, tmp_path):
    """A script sweeping on worker processes gets Ctrl-C as from a terminal (SIGINT to its
    process group) while a reduce hangs (or the workers simulate): it stops within about a
    second, keeps its partial result, and leaves no worker process behind."""
    child = subprocess.Popen([sys.executable, "-c", PROCESS_SWEEP,
                              "hang" if hang else "run"], cwd=tmp_path, env=_child_env(),
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    try:
        line = child.stdout.readline()
        assert line.startswith("REDUCING"), child.stderr.read()[-4000:]
        if not hang:  # the first results are in: the workers simulate the next runs
            time.sleep(1.0)
        workers = _children(child.pid)
        assert len(workers) == 2
        t0 = time.perf_counter()
        os.killpg(child.pid, signal.SIGINT)
        out, err = child.communicate(timeout=30)
        latency = time.perf_counter() - t0
    finally:
        _end_group(child)
    assert "INTERRUPTED" in out, err[-4000:]
    done, total = map(int, out.split("INTERRUPTED", 1)[1].split())
    assert total == 16 and done < 16
    assert latency < 2.0, f"the script took {latency:.2f} s to stop"  # (its exit included)
    assert [pid for pid in workers if _alive(pid)] == []


def _end_group(child: subprocess.Popen) -> None:
    """(cleanup) SIGKILL to the child's process group, whatever is left of it."""
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    child.wait()


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


@pytest.mark.skipif(not os.path.isdir("/proc"), reason="reads /proc")
def test_worker_processes_end_when_their_script_is_killed(tmp_path):
    """SIGKILL to a script sweeping on worker processes (no chance to clean up): its
    workers notice that their parent is gone and end within about a second."""
    child = subprocess.Popen([sys.executable, "-c", PROCESS_SWEEP, "hang"], cwd=tmp_path,
                             env=_child_env(), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        line = child.stdout.readline()
        assert line.startswith("REDUCING"), child.stderr.read()[-4000:]
        workers = _children(child.pid)
        assert len(workers) == 2
        child.kill()
        child.wait()
        deadline = time.monotonic() + 5.0
        while any(_alive(pid) for pid in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert [pid for pid in workers if _alive(pid)] == []
    finally:
        _end_group(child)
        child.stdout.close()
        child.stderr.close()


def test_a_task_over_its_timeout_is_recorded_and_the_sweep_goes_on():
    """timeout= on threads: the runs of a task still simulating are TIMED_OUT (with the
    step they reached), the sweep returns."""
    sim = compiled("rigid_body")
    S = states([0.1, 0.2, 0.3, 0.4])
    t0 = time.perf_counter()
    res = sg.sweep(sim, S, RIGID, 10_000_000, reduce=lambda t: t.states[-1, 0], workers=2,
                   chunk_size=1, timeout=0.3)
    assert time.perf_counter() - t0 < 5.0
    assert (res.status == sg.Status.TIMED_OUT).all()
    assert (res.failed_step > 0).all() and all(v is None for v in res.values)
    assert "timeout" in res.messages[0]
    for bad in (0, -1, math.inf, math.nan):  # (−1, inf and nan were a ShapeError, 0 not)
        with pytest.raises(sg.DomainError, match="timeout must be a positive"):
            sg.sweep(sim, S, RIGID, 10, timeout=bad)


def _exits_on(fatal: float):
    """A reduce that ends its worker process (os._exit(3)) on the run starting at ``fatal``
    and returns the final angle of every other run (a closure: sent by value)."""

    def exits(traj):
        if traj.states[0, 0] == fatal:
            os._exit(3)
        return traj.states[-1, 0]

    return exits


def test_a_run_that_ends_its_worker_process_is_recorded_the_others_returned(monkeypatch):
    """executor='process': a reduce that calls os._exit on run 4 ends its worker; the task
    (runs 3–5) is run again run by run on fresh workers, run 4 recorded WORKER_DIED, the
    others returned (before: a raw BrokenProcessPool, no result)."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(SESSION_CACHE))
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 6))
    res = sg.sweep(sim, S, RIGID, 50, reduce=_exits_on(S[4, 0]), workers=2, chunk_size=3,
                   executor="process")
    assert res.status.tolist() == [0, 0, 0, 0, sg.Status.WORKER_DIED, 0]
    assert res.messages[4] == ("run 4: its worker process died while running it "
                               "(exit code 3)")
    for r in (0, 3, 5):
        assert res.values[r] == sim.simulate(S[r], 50, RIGID).states[-1, 0]


@pytest.mark.slow
def test_a_worker_that_dies_on_one_run_costs_only_that_run(monkeypatch):
    """executor='process': a reduce that ends its worker (os._exit on run 5, SIGKILL on
    run 9): those runs are recorded (WORKER_DIED, with how the worker died), every other
    run is returned, equal to the serial sweep (before: a raw BrokenProcessPool and no
    result)."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(SESSION_CACHE))
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 12))
    run_5, run_9 = S[5, 0], S[9, 0]

    def dies_on_5_and_9(traj):  # (a closure: sent by value)
        first = traj.states[0, 0]
        if first == run_5:
            os._exit(3)
        if first == run_9:
            os.kill(os.getpid(), signal.SIGKILL)
        return traj.states[-1, 0]

    res = sg.sweep(sim, S, RIGID, 200, reduce=dies_on_5_and_9, workers=2, chunk_size=4,
                   executor="process")
    serial = sg.sweep(sim, S, RIGID, 200, reduce=lambda t: t.states[-1, 0], workers=1)
    died = sg.Status.WORKER_DIED
    assert res.status[5] == died and "exit code 3" in res.messages[5]
    assert res.status[9] == died and "SIGKILL" in res.messages[9]
    others = np.ones(12, bool)
    others[[5, 9]] = False
    assert res.ok[others].all() and np.array_equal(res.values[others], serial.values[others])


@pytest.mark.slow
def test_a_hanging_reduce_on_a_process_is_stopped_by_the_timeout(monkeypatch):
    """executor='process' with timeout=: the task whose reduce hangs has its worker killed
    and its run recorded TIMED_OUT; the others complete."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(SESSION_CACHE))
    sim = compiled("rigid_body")
    S = states([0.1, 0.2, 0.3, 0.4])
    stuck = S[2, 0]

    def hangs_on_2(traj):
        if traj.states[0, 0] == stuck:
            time.sleep(1000)
        return traj.states[-1, 0]

    res = sg.sweep(sim, S, RIGID, 100, reduce=hangs_on_2, workers=2, chunk_size=1,
                   executor="process", timeout=3.0)
    assert res.status.tolist() == [0, 0, sg.Status.TIMED_OUT, 0]
    assert "timeout=3 s" in res.messages[2]


def test_what_cannot_travel_to_worker_processes_is_refused_before_any_start():
    sim = compiled("rigid_body")
    S = states([0.1, 0.2])
    lock = threading.Lock()
    with pytest.raises(sg.runtime.NotPortableError, match="executor='thread'"):
        sg.sweep(sim, S, RIGID, 10, reduce=lambda t: (lock, 1.0), workers=2,
                 executor="process")
    numpy_sim = seed_step("rigid_body").compile(backend="numpy")
    with pytest.raises(sg.runtime.NotPortableError, match="backend='c'"):
        sg.sweep(numpy_sim, S, RIGID, 10, workers=2, executor="process")
    with pytest.raises(ValueError, match="executor must be one of"):
        sg.sweep(sim, S, RIGID, 10, executor="processes")
    # the NumPy backend holds the GIL: its sweeps run in the calling thread
    res = sg.sweep(numpy_sim, S, RIGID, 5, reduce=lambda t: t.states[-1, 0], workers=2)
    assert res.ok.all() and res.tasks >= 1


@pytest.mark.parametrize("failure", ["unpicklable", "sys.exit"])
def test_a_reduce_failing_on_a_worker_process_is_a_reduce_error_naming_the_run(
        monkeypatch, failure):
    """A reduce whose value does not pickle raised a raw TypeError in the client, one that
    calls sys.exit raised SystemExit there (ending the user's program); both are a
    ReduceError naming the run, as a reduce that raises on a thread."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(SESSION_CACHE))
    sim = compiled("rigid_body")
    S = states([0.1, 0.2, 0.3])
    bad = S[1, 0]

    def fails_on_1(traj):  # (a closure: sent by value)
        if traj.states[0, 0] == bad:
            if failure == "sys.exit":
                sys.exit(5)
            return threading.Lock()
        return traj.states[-1, 0]

    message = "run 1: SystemExit" if failure == "sys.exit" else "value on run 1 cannot be sent"
    with pytest.raises(sg.runtime.ReduceError, match=message):
        sg.sweep(sim, S, RIGID, 20, reduce=fails_on_1, workers=2, chunk_size=1,
                 executor="process")
    if failure == "sys.exit":  # the same on threads (it ended the sweep's thread before)
        with pytest.raises(sg.runtime.ReduceError, match="run 1: SystemExit"):
            sg.sweep(sim, S, RIGID, 20, reduce=fails_on_1, workers=1)


@pytest.mark.slow
def test_dask_records_only_the_run_that_kills_its_worker():
    """Runs that shared a worker with the one whose reduce kills it (os._exit) were
    sometimes recorded WORKER_DIED too (1 sweep in 2): a single run ended by KilledWorker is
    run once more on its own.  A value that does not pickle is a ReduceError naming its run
    (Dask's own error named none)."""
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 6))
    fatal = S[0, 0]
    exits_on_0 = _exits_on(fatal)

    def lock_on_0(traj):
        return threading.Lock() if traj.states[0, 0] == fatal else traj.states[-1, 0]

    serial = sg.sweep(sim, S, RIGID, 50, reduce=lambda t: t.states[-1, 0], workers=1)
    cluster, client = _dask_cluster()
    with cluster, client:
        for _ in range(2):
            res = sg.sweep(sim, S, RIGID, 50, reduce=exits_on_0, client=client, chunk_size=1)
            assert res.status.tolist() == [sg.Status.WORKER_DIED] + [0] * 5
            assert np.array_equal(res.values[1:], serial.values[1:])
        with pytest.raises(sg.runtime.ReduceError, match="value on run 0 cannot be sent"):
            sg.sweep(sim, S, RIGID, 50, reduce=lock_on_0, client=client, chunk_size=1)


def _exits_on_any(fatal):
    """A reduce that ends its worker process on the runs starting at the angles ``fatal``."""
    fatal = {float(x) for x in fatal}

    def exits(traj):
        if float(traj.states[0, 0]) in fatal:
            os._exit(3)
        return traj.states[-1, 0]

    return exits


class _Hang(Exception):
    pass


def _within(seconds: int, work):
    """``work()`` in this thread; a failure naming the hang after ``seconds`` (SIGALRM)."""

    def alarm(signum, frame):
        raise _Hang(f"the sweep still runs after {seconds} s")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        return work()
    except _Hang as hang:
        pytest.fail(str(hang))
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.slow  # (18 worker deaths and restarts: 25–90 s on a 2-core machine, with the
# other tests beside it once longer than the cluster's wait for a worker to come back)
def test_dask_runs_that_share_workers_with_several_killers_are_all_returned():
    """Three runs of twelve end their worker (os._exit in reduce), in tasks of three and of
    five runs, on two workers of two threads.  Before, the deaths were charged to every task
    on the dying workers: innocent runs were recorded WORKER_DIED, or the nannies,
    restarting workers that died as they started, left the cluster without workers and the
    sweep waited for ever.  Then, a cancelled task that ran on (Dask does not stop it) or a
    result fetch that waited while Dask ran a culprit again could still blame an innocent
    run alone on the cluster.  Now exactly the three are recorded, the others equal the
    serial sweep, in each sweep on the same cluster, none waiting for ever: each within
    150 s (a hang's bound, not a speed: every death costs a worker restart, which imports
    the library anew, and a culprit dies twice, in its task and alone; on a 2-core machine
    the three sweeps took 24–37 s in all, and one sweep once took more than 60 s)."""
    distributed = pytest.importorskip("distributed")
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 12))
    killers = [1, 4, 10]
    exits = _exits_on_any(S[killers, 0])
    serial = sg.sweep(sim, S, RIGID, 50, reduce=lambda t: t.states[-1, 0], workers=1)
    expected = [sg.Status.WORKER_DIED if r in killers else 0 for r in range(12)]
    innocent = [r for r in range(12) if r not in killers]
    cluster = distributed.LocalCluster(n_workers=2, processes=True, threads_per_worker=2,
                                       dashboard_address=None)
    with cluster, distributed.Client(cluster) as client:
        for chunk_size in (3, 5, 3):
            res = _within(150, lambda c=chunk_size: sg.sweep(sim, S, RIGID, 50, reduce=exits,
                                                             client=client, chunk_size=c))
            assert res.status.tolist() == expected, chunk_size
            assert np.array_equal(res.values[innocent], serial.values[innocent])
            assert all("alone on the cluster" in res.messages[r] for r in killers)


def test_dask_cluster_that_loses_its_workers_is_an_error_with_the_runs_done(monkeypatch):
    """A reduce that kills a worker nothing restarts (``dask worker --no-nanny``) leaves the
    cluster without workers: the sweep raised nothing and waited for ever.  Now,
    NO_WORKERS_WAIT (here 1 s) after, a ClusterLostError carries the partial result: the
    runs done, the others "not run" with the reason."""
    monkeypatch.setattr("symgroupoid.runtime._dask.NO_WORKERS_WAIT", 1.0)
    distributed = pytest.importorskip("distributed")
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 6))
    exits = _exits_on_any(S[[3], 0])
    serial = sg.sweep(sim, S, RIGID, 50, reduce=lambda t: t.states[-1, 0], workers=1)
    cluster = distributed.LocalCluster(n_workers=0, processes=True, dashboard_address=None)
    client = distributed.Client(cluster)
    worker = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker",
                               cluster.scheduler_address, "--no-nanny", "--nthreads", "1"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        client.wait_for_workers(1, timeout=60)
        with pytest.raises(sg.runtime.ClusterLostError,
                           match="no workers for 1 s since it lost those") as info:
            _within(60, lambda: sg.sweep(sim, S, RIGID, 50, reduce=exits, client=client,
                                         chunk_size=1))
    finally:
        worker.kill()
        worker.wait()
        client.close()
        cluster.close()
    partial = info.value.result
    assert partial.status[3] == sg.Status.INTERRUPTED
    assert "lost its workers" in partial.messages[3]
    done = np.flatnonzero(partial.status == 0)
    assert np.array_equal(partial.values[done], serial.values[done])


@pytest.mark.slow
def test_dask_cluster_without_workers_is_waited_for_with_a_warning(monkeypatch):
    """A cluster with no workers yet (an adaptive one, a queue) is waited for: after
    NO_WORKERS_WAIT a RuntimeWarning, and the sweep completes when a worker comes."""
    monkeypatch.setattr("symgroupoid.runtime._dask.NO_WORKERS_WAIT", 0.5)
    distributed = pytest.importorskip("distributed")
    sim = compiled("rigid_body")
    S = states(np.linspace(0.05, 0.6, 4))
    serial = sg.sweep(sim, S, RIGID, 50, reduce=lambda t: t.states[-1, 0], workers=1)
    cluster = distributed.LocalCluster(n_workers=0, processes=True, threads_per_worker=1,
                                       dashboard_address=None)
    with cluster, distributed.Client(cluster) as client:
        threading.Timer(2.0, lambda: cluster.scale(1)).start()
        with pytest.warns(RuntimeWarning, match="no workers for 0.5 s; waiting"):
            res = _within(60, lambda: sg.sweep(sim, S, RIGID, 50,
                                               reduce=lambda t: t.states[-1, 0],
                                               client=client))
    assert np.array_equal(res.values, serial.values)
