"""Benchmark: 20 random two-point problems on SO(3) and SE(2), the library against Ipopt.

The problems of ``_bvp_problems.random_problems`` (end rotations up to 150°, random inertias,
N in [100, 2000]), each from the default geodesic guess: the library with default options
(Newton fast path, globalised iteration when needed) and Ipopt on the CasADi ``Opti``
transcription of ``_bvp_casadi.py`` from the same path (at most 500 iterations: where it
fails, it fails by wandering off, e.g. 3000 iterations and 520 s on problem 19).  The target:
on every problem Ipopt solves, the library converges to the same stationary point
(max |Δξ| < 1e-8) or to one of lower cost.  Printed per problem: N, the library's
iterations, method, time, cost and second-order condition; Ipopt's status, iterations,
time and cost; the agreement.

Run:  python benchmarks/bvp_random.py [--count 20] [--seed 20240609]
"""

from __future__ import annotations

import argparse
import sys
import time

import _bvp_casadi as casadi_models
import numpy as np
from _bvp_problems import random_problems

import symgroupoid as sg
from symgroupoid.runtime._bvp import interpolate_arrows


def compare(p) -> dict:
    """Solve ``p`` with both; the library's failure is reported, not raised."""
    G = p.system.groupoid
    guess = interpolate_arrows(G, G.arrow_between(p.start, p.end), p.steps)
    chart = np.array([G.fibre_chart_inverse(a) for a in guess])
    ipopt = casadi_models.solve_ipopt(casadi_models.first_order(p.kind, p.end, p.params, chart),
                                      max_iter=500)
    t = time.perf_counter()
    try:
        sol = p.solve()
    except sg.SymgroupoidError as exc:
        return {"ipopt": ipopt, "error": f"{type(exc).__name__}: {str(exc)[:80]}",
                "seconds": time.perf_counter() - t}
    seconds = time.perf_counter() - t
    h = p.params[0]
    diff = float(np.abs(sol.controls - ipopt.chart).max()) / h
    if not ipopt.success:
        verdict = "Ipopt failed"
    elif diff < 1e-8:
        verdict = "same point"
    elif sol.cost < ipopt.cost - 1e-9:
        verdict = "lower cost"
    else:
        verdict = "MISSED"
    return {"ipopt": ipopt, "sol": sol, "seconds": seconds, "diff": diff, "verdict": verdict}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--seed", type=int, default=20240609)
    args = parser.parse_args(argv)
    problems = random_problems(args.count, args.seed)
    window = {p.kind: p for p in problems}
    for p in window.values():  # build each family's kernels before timing
        sg.solve_boundary_value(p.system, p.start, p.start, 10,
                                params=[0.1, *p.params[1:]])
    print(f"{'problem':46s} {'N':>5s} | {'it':>3s} {'s':>6s} {'cost':>10s} {'minimum':>7s} "
          f"{'phases':>9s} | {'Ipopt':>7s} {'it':>4s} {'s':>6s} {'cost':>10s} | "
          f"{'|Δξ|':>8s} verdict")
    missed = 0
    for p in problems:
        r = compare(p)
        ip = r["ipopt"]
        ipopt = (f"{'ok' if ip.success else 'FAIL':>7s} {ip.iterations:4d} "
                 f"{ip.solver_seconds:6.2f} {ip.cost:10.6f}")
        if "error" in r:
            missed += ip.success
            print(f"{p.label:46s} {p.steps:5d} | {r['error']} | {ipopt}")
            continue
        sol = r["sol"]
        phases = "Newton" if sol.method == "Newton" else "+global"
        missed += r["verdict"] == "MISSED"
        print(f"{p.label:46s} {p.steps:5d} | {sol.iterations:3d} {r['seconds']:6.2f} "
              f"{sol.cost:10.6f} {str(sol.is_local_minimum):>7s} {phases:>9s} | {ipopt} | "
              f"{r['diff']:8.1e} {r['verdict']}")
    print(f"\n{len(problems) - missed} of {len(problems)}: success on every problem Ipopt "
          f"solves (same stationary point or lower cost)" if not missed else
          f"\n{missed} problem(s) Ipopt solves where the library does not reach the same point "
          f"or a lower cost")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
