"""Many plate-ball trajectories: per trajectory-step cost of four ways of running them.

    python benchmarks/ensemble.py [--runs B] [--steps N] [--memory-runs M]

B initial conditions (consecutive states of one consistent run, so the rolling constraints
hold) × N steps each, keeping every 10th state:

1. a Python loop of ``Simulator.simulate``;
2. ``Simulator.simulate_batch`` on one thread;
3. ``simulate_batch`` on all cores (one thread per core; the kernel releases the GIL);
4. ``sg.sweep`` with a scalar ``reduce`` on its default executor, threads (the calling
   thread reduces), and on worker processes (``executor="process"``, their start included);
5. ``sg.sweep`` on a ``dask.distributed.LocalCluster`` (one single-threaded worker process
   per core); the cluster start and the first (warm-up) sweep, which brings the kernel to
   the workers, are timed separately.

Prints each cost in µs per trajectory-step and the ratios, checks that the batched runs are
bitwise those of the loop, and measures the peak memory of a sweep of M runs with a scalar
reduce (in a fresh process, so the figure is that sweep's own).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import symgroupoid as sg  # noqa: E402
from symgroupoid.systems import plate_ball  # noqa: E402

PARAMS = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02}
POSITION = {"x": 0.0, "y": 0.0}
MOMENTUM = (0.1, 0.05, 0.01, 0.02, 0.01)

MEMORY_SCRIPT = """
import json, resource, sys
sys.path.insert(0, {repo!r})
import numpy as np
import symgroupoid as sg
from symgroupoid.systems import plate_ball
sim = plate_ball().euler_lagrange().compile()
s0 = sim.from_momentum({position!r}, {momentum!r}, {params!r})
S = sim.simulate(s0, 1000, {params!r}).states
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
res = sg.sweep(sim, S[np.arange({runs}) % len(S)], {params!r}, {steps},
               reduce=lambda t: t.states[-1, 0], workers=1)
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(json.dumps({{"runs": len(res), "ok": int(res.ok.sum()), "peak_mib": peak / 1024,
                   "before_mib": before / 1024, "seconds": res.seconds}}))
"""


def last_x(traj) -> float:
    return float(traj.states[-1, 0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--loop-runs", type=int, default=1000,
                        help="runs timed in the Python loop (its cost is per run)")
    parser.add_argument("--memory-runs", type=int, default=1_000_000)
    parser.add_argument("--memory-steps", type=int, default=10)
    args = parser.parse_args()
    B, N, every = args.runs, args.steps, 10

    sim = plate_ball().euler_lagrange().compile(backend="c")
    s0 = sim.from_momentum(POSITION, MOMENTUM, PARAMS)
    S = sim.simulate(s0, 5 * B, PARAMS, every=5).states[:B].copy()
    cores = os.cpu_count() or 1
    print(f"plate-ball: {B} initial conditions x {N} steps (every {every}); {cores} cores; "
          f"OpenMP kernel: {sim.kernel.openmp}")

    n_loop = min(B, args.loop_runs)
    t0 = time.perf_counter()
    loop = [sim.simulate(S[b], N, PARAMS, every=every) for b in range(n_loop)]
    t_loop = (time.perf_counter() - t0) / (n_loop * N)

    t0 = time.perf_counter()
    one = sim.simulate_batch(S, N, PARAMS, every=every, threads=1)
    t_one = (time.perf_counter() - t0) / (B * N)
    t0 = time.perf_counter()
    every_core = sim.simulate_batch(S, N, PARAMS, every=every)
    t_all = (time.perf_counter() - t0) / (B * N)
    same = all(np.array_equal(loop[b].states, one[b].states) for b in range(n_loop))
    same = same and np.array_equal(one.states, every_core.states)

    t0 = time.perf_counter()
    threaded = sg.sweep(sim, S, PARAMS, N, every=every, reduce=last_x)
    t_threads = (time.perf_counter() - t0) / (B * N)
    t0 = time.perf_counter()
    processes = sg.sweep(sim, S, PARAMS, N, every=every, reduce=last_x, executor="process")
    t_processes = (time.perf_counter() - t0) / (B * N)
    same = same and np.array_equal(threaded.values, one.states[:, -1, 0])
    same = same and np.array_equal(processes.values, one.states[:, -1, 0])

    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    with LocalCluster(n_workers=cores, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        t_cluster = time.perf_counter() - t0
        t0 = time.perf_counter()
        sg.sweep(sim, S[:2 * cores], PARAMS, 10, reduce=last_x, client=client)
        t_warm = time.perf_counter() - t0
        t0 = time.perf_counter()
        swept = sg.sweep(sim, S, PARAMS, N, every=every, reduce=last_x, client=client)
        t_dask = (time.perf_counter() - t0) / (B * N)
    same = same and np.array_equal(swept.values, one.states[:, -1, 0])

    print(f"  Python loop of simulate      {t_loop * 1e6:7.3f} µs per trajectory-step")
    print(f"  simulate_batch, one thread   {t_one * 1e6:7.3f} µs   "
          f"({t_loop / t_one:.2f}x the loop)")
    print(f"  simulate_batch, all cores    {t_all * 1e6:7.3f} µs   "
          f"({t_one / t_all:.2f}x one thread)")
    print(f"  sweep on threads (default)   {t_threads * 1e6:7.3f} µs   "
          f"({t_threads / t_all:.2f}x simulate_batch on all cores; {threaded.tasks} tasks)")
    print(f"  sweep on worker processes    {t_processes * 1e6:7.3f} µs   "
          f"({t_processes / t_threads:.2f}x threads, their start included; "
          f"{processes.tasks} tasks)")
    print(f"  sweep on a Dask LocalCluster {t_dask * 1e6:7.3f} µs   ({t_dask / t_all:.2f}x "
          f"simulate_batch on all cores; {swept.tasks} tasks)")
    print(f"    start-up: cluster {t_cluster:.2f} s, kernel to the workers (first sweep) "
          f"{t_warm:.2f} s")
    print(f"  all results bitwise equal: {same}")

    script = MEMORY_SCRIPT.format(repo=str(REPO), position=POSITION, momentum=MOMENTUM,
                                  params=PARAMS, runs=args.memory_runs,
                                  steps=args.memory_steps)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True)
    mem = json.loads(out.stdout.strip().splitlines()[-1])
    print(f"  memory: {mem['runs']} runs x {args.memory_steps} steps with a scalar reduce: "
          f"peak RSS {mem['peak_mib']:.0f} MiB (before the sweep {mem['before_mib']:.0f} MiB; "
          f"{mem['seconds']:.1f} s)")


if __name__ == "__main__":
    main()
