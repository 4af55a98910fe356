"""sg.sweep and sg.sweep_boundary_value: in this process, on a local process pool, and on a
real Dask cluster (LocalCluster with worker processes), including a worker killed
mid-sweep; the results equal the serial ones exactly."""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    compiled,
    isolated_cache,
    needs_cc,
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


@pytest.mark.slow
def test_local_process_pool_equals_the_serial_sweep():
    sim = compiled("rigid_body")
    S = states(THETAS)
    serial = sg.sweep(sim, S, TABLE, 500, reduce=lambda t: t.states[-1, 0], workers=1)
    pooled = sg.sweep(sim, S, TABLE, 500, reduce=lambda t: t.states[-1, 0], workers=2,
                      chunk_size=3)
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
    chained = sg.sweep_boundary_value(step, [np.eye(3)], ends, 12, params=hs,
                                      combine="product", continuation=True, workers=1,
                                      reduce=lambda s: s.iterations)
    assert chained.ok.all() and chained.values.shape == (1, 2, 3)
    # each continuation step starts from its neighbour's solution: fewer Newton iterations
    assert chained.values[0, :, 1:].sum() <= np.vectorize(lambda s: s.iterations)(
        res.solutions[0, :, 1:]).sum()
