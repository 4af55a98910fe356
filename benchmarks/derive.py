"""Wall time of the symbolic derivation: StepEquations and their exact Jacobian.

    python benchmarks/derive.py [--sizes 1 2 4 8 16] [--repeat 3] [--profile N]

Measures

- the plate-ball system (seed 000 §6.2): DiscreteSystem + ``euler_lagrange()`` (the eight
  equations), then ``jacobian()``;
- a chain of n planar pendula as a constrained pair groupoid R^{2n} × R^{2n} ⇉ R^{2n}:
  coordinates x_i, y_i (i = 1..n, pivot x_0 = y_0 = 0), midpoint discrete Lagrangian

      L = h [ Σ_i (m/2)(((x_i¹ − x_i⁰)/h)² + ((y_i¹ − y_i⁰)/h)²) − Σ_i m g (y_i⁰ + y_i¹)/2 ],

  and rod-length constraints at the target point (x_i − x_{i−1})² + (y_i − y_{i−1})² − ℓ² = 0,
  i.e. 3n equations in 3n unknowns per step;

and the growth exponent p of the pendulum-chain times, t ≈ C nᵖ (least-squares fit of
log t against log n).  Each time is the minimum over ``--repeat`` fresh derivations; the plate-
ball time of the first derivation in the process (cold caches) is also printed.
``--profile N`` prints the cProfile hot spots of deriving the chain with N pendula.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import sympy as sp

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import symgroupoid as sg  # noqa: E402
from symgroupoid.systems import plate_ball  # noqa: E402

# --- systems -----------------------------------------------------------------------------------


def pendulum_chain(n: int) -> sg.DiscreteSystem:
    """n planar pendula linked by rods of length ℓ, as a constrained pair groupoid."""
    h, m, grav, ell = sp.symbols("h m g ell", positive=True)
    names = [f"{c}{i}" for i in range(1, n + 1) for c in ("x", "y")]
    G = sg.PairGroupoid(sg.EuclideanSpace(names))

    def points(q):
        return [(0, 0)] + [(q[2 * i], q[2 * i + 1]) for i in range(n)]

    def L(g):
        q0, q1 = g.source, g.target
        kinetic = sum(m / 2 * ((b - a) / h) ** 2 for a, b in zip(q0, q1))
        potential = sum(m * grav * (q0[2 * i + 1] + q1[2 * i + 1]) / 2 for i in range(n))
        return h * (kinetic - potential)

    def phi(g):
        p = points(g.target)
        return [(p[i][0] - p[i - 1][0]) ** 2 + (p[i][1] - p[i - 1][1]) ** 2 - ell**2
                for i in range(1, n + 1)]

    return sg.DiscreteSystem(G, L, constraints=phi, parameters=[h, m, grav, ell],
                             name=f"pendulum_chain_{n}")


# --- timing ------------------------------------------------------------------------------------


def time_derivation(build: Callable[[], sg.DiscreteSystem]) -> tuple[float, float, int]:
    """Seconds to build the StepEquations, seconds for their Jacobian, and the equation count."""
    t0 = time.perf_counter()
    step = build().euler_lagrange()
    t1 = time.perf_counter()
    J = step.jacobian()
    t2 = time.perf_counter()
    assert J.shape == (len(step), len(step.unknowns))
    return t1 - t0, t2 - t1, len(step)


def best_of(build: Callable[[], sg.DiscreteSystem], repeat: int) -> tuple[float, float, int]:
    runs = [time_derivation(build) for _ in range(repeat)]
    return min(r[0] for r in runs), min(r[1] for r in runs), runs[0][2]


def growth_exponent(ns: list[int], times: list[float]) -> float:
    """Slope of the least-squares line through (log n, log t)."""
    return float(np.polyfit(np.log(ns), np.log(times), 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--profile", type=int, default=0, metavar="N")
    args = parser.parse_args()

    cold_step, cold_jac, _ = time_derivation(plate_ball)
    step_s, jac_s, neq = best_of(plate_ball, args.repeat)
    print(f"plate-ball ({neq} equations): first derivation {cold_step:.3f} s "
          f"+ Jacobian {cold_jac:.3f} s (cold caches)")
    print(f"plate-ball ({neq} equations): StepEquations {step_s:.3f} s, Jacobian {jac_s:.3f} s, "
          f"total {step_s + jac_s:.3f} s (best of {args.repeat})")

    print(f"\n{'n':>4} {'equations':>10} {'StepEquations [s]':>18} {'Jacobian [s]':>13} "
          f"{'total [s]':>10}")
    totals, steps = [], []
    for n in args.sizes:
        s, j, neq = best_of(lambda n=n: pendulum_chain(n), args.repeat)
        steps.append(s)
        totals.append(s + j)
        print(f"{n:>4} {neq:>10} {s:>18.3f} {j:>13.3f} {s + j:>10.3f}")
    if len(args.sizes) >= 2:
        p_total = growth_exponent(args.sizes, totals)
        p_step = growth_exponent(args.sizes, steps)
        tail = [n for n in args.sizes if n >= 4]
        print(f"\ngrowth exponent (t ~ n^p, all n): total p = {p_total:.2f}, "
              f"StepEquations alone p = {p_step:.2f}")
        if len(tail) >= 2:
            k = len(args.sizes) - len(tail)
            print(f"growth exponent for n >= 4: total p = "
                  f"{growth_exponent(tail, totals[k:]):.2f}")

    if args.profile:
        print(f"\ncProfile: pendulum chain, n = {args.profile}")
        profiler = cProfile.Profile()
        profiler.enable()
        time_derivation(lambda: pendulum_chain(args.profile))
        profiler.disable()
        pstats.Stats(profiler).sort_stats("cumulative").print_stats(25)


if __name__ == "__main__":
    main()
