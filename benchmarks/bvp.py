"""Benchmark: the second-order rigid-body attitude maneuver as a two-point problem.

The problem is the rest-to-rest maneuver of ``examples/rigid_body_attitude.py`` (seed 001
§3.3.4, eqs. (25)–(28)): L_d(W_k, W_{k+1}) = (h/2)|u_{k+1}|² on SO(3) with the Cayley chart,
R₀ = R₁ = I and R_{N−1} = R_N fixed.  Reported:

1. the window-kernel build (symbolic derivation + code generation, once per system);
2. the N = 1000 solve with the kernel built (target: under 1 s);
3. the time per Newton iteration for N = 250 … 4000 and the fitted exponent of t ∝ N^p
   (the Jacobian is block-banded and solved by a banded LU, so p ≈ 1 is expected);
4. the same equations solved by ``scipy.optimize.root`` (MINPACK ``hybr``, finite-difference
   dense Jacobian): the unknowns are the Cayley coordinates y_k of the interior attitudes,
   R_k = R_k⁰ cay(y_k), k = 2 … N−2 (R⁰ the solver's own initial guess), and the residuals are
   the discrete second-order Euler–Poincaré equations of every junction, the system's
   ``euler_lagrange()`` residuals lambdified and evaluated for all junctions at once.

Tolerance.  The junction residual of L_d = hL̃ contains (x_{k+1} − x_k)/h² with x_k ~ hΩ, so
its rounding floor grows like ε|Ω|/h², i.e. like N² (measured |F|∞ floors: 9e-12 at N = 100,
2e-9 at N = 1000, 5e-8 at N = 4000).  The solver's defaults handle this: it stops at
|F|∞ < 1e-10 or after a Newton update below 1e-9 (quadratic convergence: the iterate is then
at the residual's floor).

Run:  python benchmarks/bvp.py [--profile] [--no-scipy]
"""

from __future__ import annotations

import argparse
import cProfile
import importlib.util
import io
import pathlib
import pstats
import sys
import time

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid.runtime._bvp import interpolate_arrows, window_kernel

ROOT = pathlib.Path(__file__).resolve().parent.parent


def _example():
    spec = importlib.util.spec_from_file_location(
        "rigid_body_attitude", ROOT / "examples" / "rigid_body_attitude.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


rb = _example()


def solve(steps: int) -> tuple[sg.BoundaryValueSolution, float]:
    """The maneuver with N = ``steps``; returns the solution and the wall time of the call."""
    start, end = rb.boundary_data(steps)
    t0 = time.perf_counter()
    sol = sg.solve_boundary_value(rb.attitude_system(), start, end, steps,
                                  params=rb.parameter_values(steps))
    return sol, time.perf_counter() - t0


def _run(steps: int, iterations: int) -> float:
    """Wall time of a solve stopped after exactly ``iterations`` Newton iterations."""
    start, end = rb.boundary_data(steps)
    t0 = time.perf_counter()
    try:
        sg.solve_boundary_value(rb.attitude_system(), start, end, steps,
                                params=rb.parameter_values(steps), tol=0.0, tol_step=0.0,
                                max_iterations=iterations)
    except sg.NewtonDivergenceError:
        pass
    return time.perf_counter() - t0


def per_iteration(steps: int, repeats: int = 5) -> float:
    """Seconds per Newton iteration (banded solve, update, residual and Jacobian assembly):
    (t(3 iterations) − t(1 iteration))/2, best of ``repeats``; the first three iterations of
    this maneuver take full Newton steps, far above the rounding floor."""
    return min((_run(steps, 3) - _run(steps, 1)) / 2 for _ in range(repeats))


# --- the dense comparison ---------------------------------------------------------------------

class StackedResidual:
    """The junction equations of the whole maneuver as one function of the interior attitudes.

    Unknowns y_k ∈ R³ (k = 2 … N−2): R_k = R_k⁰ cay(y_k).  Residual rows: the second-order DEL
    at junction j = 1 … N−3 (between W_j and W_{j+1}), from ``euler_lagrange().residuals``
    evaluated on the arrows W_{j−1}, W_j, W_{j+1}, W_{j+2}.
    """

    def __init__(self, steps: int):
        system = rb.attitude_system()
        step = system.euler_lagrange()
        self.steps = steps
        self.params = [rb.parameter_values(steps)[s] for s in step.parameters]
        self._f = sp.lambdify([step.knowns, step.fibre_unknowns, step.parameters],
                              step.residuals, "numpy", cse=True)
        (R0, R1), (RN1, RN) = rb.boundary_data(steps)
        inner = interpolate_arrows(system.groupoid, np.linalg.solve(R1, RN1).ravel(),
                                   steps - 2)
        R = [R0, R1]
        for a in inner:
            R.append(R[-1] @ a.reshape(3, 3))
        self.reference = np.array(R[:-1] + [RN1, RN])  # R⁰_k, k = 0 … N

    def attitudes(self, y: np.ndarray) -> np.ndarray:
        R = self.reference.copy()
        C = np.array([rb.cayley(v) for v in y.reshape(-1, 3)])
        R[2:self.steps - 1] = np.einsum("kij,kjl->kil", R[2:self.steps - 1], C)
        return R

    def __call__(self, y: np.ndarray) -> np.ndarray:
        R = self.attitudes(y)
        W = np.einsum("kji,kjl->kil", R[:-1], R[1:]).reshape(self.steps, 9)  # R_kᵀR_{k+1}
        j = np.arange(1, self.steps - 2)
        knowns = np.hstack([W[j - 1], W[j], W[j + 1]]).T
        out = self._f(knowns, W[j + 2].T, self.params)
        return np.array([np.broadcast_to(np.asarray(r, float), j.shape) for r in out]).T.ravel()


def scipy_solve(steps: int) -> dict:
    from scipy.optimize import root

    F = StackedResidual(steps)
    y0 = np.zeros(3 * (steps - 3))
    t0 = time.perf_counter()
    res = root(F, y0, method="hybr", options={"xtol": 1e-13, "maxfev": 200 * (len(y0) + 1)})
    seconds = time.perf_counter() - t0
    return {"seconds": seconds, "nfev": res.nfev, "success": res.success,
            "residual": float(np.abs(F(res.x)).max()), "attitudes": F.attitudes(res.x)}


# --- main --------------------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--profile", action="store_true", help="cProfile the N = 1000 solve")
    parser.add_argument("--no-scipy", action="store_true", help="skip the dense comparison")
    args = parser.parse_args(argv)

    system = rb.attitude_system()
    t0 = time.perf_counter()
    window_kernel(system)
    build = time.perf_counter() - t0
    print(f"window kernel build (once per system): {build:.2f} s")

    solve(100)  # warm-up: structure maps, banded solver import
    sol, wall = solve(1000)
    verdict = "met" if wall < 1.0 else "MISSED"
    print(f"N = 1000: {wall:.3f} s wall ({sol.iterations} Newton iterations, |F|∞ = "
          f"{sol.residual_norm:.1e}); target < 1 s {verdict}")

    print("\n     N   iterations   s/iteration   solve wall s")
    sizes = [250, 500, 1000, 2000, 4000]
    times, solutions = [], {}
    for n in sizes:
        per = per_iteration(n)
        s, wall = min((solve(n) for _ in range(3)), key=lambda pair: pair[1])
        times.append(per)
        solutions[n] = (s, wall)
        print(f"  {n:5d}   {s.iterations:5d}       {per * 1e3:8.2f} ms   {wall:6.3f}")
    slope = np.polyfit(np.log(sizes), np.log(times), 1)[0]
    upper = np.polyfit(np.log(sizes[2:]), np.log(times[2:]), 1)[0]
    b, a = np.polyfit(sizes, times, 1)
    print(f"  fitted exponent p (s/iteration ∝ N^p): {slope:.2f} over N = 250 … 4000, "
          f"{upper:.2f} over N = 1000 … 4000")
    print(f"  affine fit s/iteration = a + bN: a = {a * 1e3:.1f} ms (fixed cost per "
          f"iteration), b = {b * 1e6:.1f} µs per step")

    if not args.no_scipy:
        print("\n  scipy.optimize.root (hybr, finite-difference dense Jacobian), same equations:")
        for n in (250, 500):
            out = scipy_solve(n)
            bvp, ours = solutions[n]
            diff = np.abs(out["attitudes"] - np.array(bvp.configurations)).max()
            print(f"  N = {n}: scipy {out['seconds']:.2f} s ({out['nfev']} evaluations, "
                  f"success {out['success']}, |F|∞ = {out['residual']:.1e}); banded Newton "
                  f"{ours:.3f} s; ratio {out['seconds'] / ours:.0f}×; max attitude difference "
                  f"{diff:.1e}")

    if args.profile or verdict == "MISSED":
        profiler = cProfile.Profile()
        profiler.enable()
        solve(1000)
        profiler.disable()
        stream = io.StringIO()
        pstats.Stats(profiler, stream=stream).sort_stats("tottime").print_stats(12)
        print("\ncProfile of the N = 1000 solve (by internal time):")
        print(stream.getvalue())


if __name__ == "__main__":
    sys.exit(main())
