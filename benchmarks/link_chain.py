"""Per-step cost of a chain in maximal coordinates against its length: the band LU.

    python benchmarks/link_chain.py [--sizes 8 16 32 64 128] [--rounds R] [--output results.json]

``systems.link_chain(n)``: n unit point masses in the plane joined by rigid links of length
1 (holonomic constraints, one multiplier each), so a step has 3n unknowns and a Jacobian in
KKT form whose couplings run between neighbouring links only.  The code generator finds the
order in which it is banded (``codegen.band_order``: reverse Cuthill–McKee, kl = ku = 2) and
the stepper factors it in band storage (``symgroupoid/stepper/stepper.c``, ``SG_BANDED``), in
O(n) per factorisation instead of O(n³); the rounding floors read only the band too.

The chain starts straight, tilted by 0.3 rad, swinging as a rigid body at 0.5 rad/s (the
same motion at every n for the first steps, so that Newton's work per step does not depend on
n).  Per size, in one process: the build (derivation + code generation + compiler, with an
empty kernel cache), µs per step (the best of ``--rounds`` runs of 30 steps less the best
1-step run, so the fixed cost of a ``simulate`` call is left out), Newton updates per step and
µs per update, and the band; then the growth exponents between successive sizes (the issue's
target: per-step cost growing like n^1.2 or less up to n = 128).  The residual and Jacobian
themselves still write the dense n × n Jacobian (its zeros included), which is what the
exponent above 1 measures at the largest sizes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from symgroupoid import codegen, systems  # noqa: E402

SIZES = (8, 16, 32, 64, 128)
H = 0.01


def chain_state(n: int) -> np.ndarray:
    """(q_{k−1}, q_k, λ_k = 0): the straight chain at 0.3 rad, then rotated by h·0.5 rad."""
    def points(angle: float) -> np.ndarray:
        step = np.array([math.sin(angle), -math.cos(angle)])
        return (np.arange(1, n + 1)[:, None] * step).ravel()

    return np.concatenate([points(0.3), points(0.3 + H * 0.5), np.zeros(n)])


def chain_params(n: int) -> dict:
    return {"h": H, "g": 9.81, **{f"l{i}": 1.0 for i in range(1, n + 1)}}


def best(run, rounds: int) -> float:
    fastest = math.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        run()
        fastest = min(fastest, time.perf_counter() - t0)
    return fastest


def measure(n: int, rounds: int, cache: str) -> dict:
    t0 = time.perf_counter()
    step = systems.link_chain(n).euler_lagrange()
    sim = step.compile(backend="c", cache_dir=cache)
    build = time.perf_counter() - t0
    band = codegen.band_order(step)
    state, params = chain_state(n), chain_params(n)
    run = sim.simulate(state, 30, params)
    many = best(lambda: sim.simulate(state, 30, params), rounds)
    one = best(lambda: sim.simulate(state, 1, params), rounds)
    per_step = (many - one) / 29
    updates = float(np.mean(run.newton_iterations[1:]))
    return {"n": n, "unknowns": len(step.unknowns), "build_s": build,
            "us_per_step": per_step * 1e6, "newton_per_step": updates,
            "us_per_update": per_step * 1e6 / updates, "fixed_us": one * 1e6,
            "band": None if band is None else [band.kl, band.ku],
            "constraint": float(np.max(np.abs(run.constraint_residuals())))}


def exponent(a: dict, b: dict, key: str) -> float:
    return math.log(b[key] / a[key]) / math.log(b["n"] / a["n"])


def main(argv=None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES))
    parser.add_argument("--rounds", type=int, default=200)
    parser.add_argument("--output", type=Path, default=None)
    args = parser.parse_args(argv)
    print(f"link_chain(n), h = {H}; load average {os.getloadavg()[0]:.2f}")
    print(f"{'n':>4} {'unknowns':>8} {'band':>8} {'build s':>8} {'µs/step':>9} "
          f"{'updates':>8} {'µs/update':>10} {'exp step':>9} {'exp update':>10}")
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="symgroupoid-link-chain-") as cache:
        for n in sorted(args.sizes):
            row = measure(n, args.rounds, cache)
            growth = (exponent(rows[-1], row, "us_per_step"),
                      exponent(rows[-1], row, "us_per_update")) if rows else (None, None)
            row["exponent_step"], row["exponent_update"] = growth
            rows.append(row)
            band = "dense" if row["band"] is None else f"{row['band'][0]},{row['band'][1]}"
            cells = ["-" if g is None else f"{g:.2f}" for g in growth]
            print(f"{n:>4} {row['unknowns']:>8} {band:>8} {row['build_s']:>8.2f} "
                  f"{row['us_per_step']:>9.2f} {row['newton_per_step']:>8.2f} "
                  f"{row['us_per_update']:>10.2f} {cells[0]:>9} {cells[1]:>10}", flush=True)
    if len(rows) > 1:
        whole = exponent(rows[0], rows[-1], "us_per_step")
        verdict = "PASS" if whole <= 1.2 else "FAIL"
        print(f"growth of µs/step from n = {rows[0]['n']} to {rows[-1]['n']}: n^{whole:.2f} "
              f"(target n^1.2 or less: {verdict})")
    if args.output is not None:
        args.output.write_text(json.dumps(rows, indent=1))
    return rows


if __name__ == "__main__":
    main()
