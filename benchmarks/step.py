"""Per-step cost of the compiled plate-ball stepper, against SciPy and CasADi.

    python benchmarks/step.py [--steps N] [--scipy-steps N]

Measures, for the plate-ball system (seed 000 §6.2) from a consistent initial state (solved
from a position and a discrete momentum, so the rolling constraints hold):

- derive + emit + compile time with a cold kernel cache, and the load time of the cached
  kernel in a new process (the ``compile_step`` call);
- the compiled stepper (``Simulator.simulate``: N steps in one C call), with the default
  extrapolated Newton guess and with every step started from ``step.prediction``;
- the Python overhead of a control loop, ``state = sim.step(state, p)`` with the
  parameters as a vector (``sim.parameters(...)``) and as a dict: µs per call beyond the
  kernel's step (``simulate`` from ``step.prediction``, the same Newton work: the loop's
  states are bitwise those of that run);
- (a) the same residuals and exact Jacobian lambdified with NumPy and solved by
  ``scipy.optimize.root`` (MINPACK ``hybr``) once per step;
- (b) CasADi, if importable: the same residuals as a ``rootfinder('fast_newton')`` step from
  the same prediction, accumulated over N steps with ``mapaccum``, code-generated and compiled
  with ``-O3`` for the same vector extension as the library's kernels.

Every competitor's trajectory is compared with the compiled one over the first 1000 steps
(max deviation printed).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import sympy as sp

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import symgroupoid as sg  # noqa: E402
from symgroupoid.runtime.toolchain import vector_flags  # noqa: E402
from symgroupoid.systems import plate_ball  # noqa: E402

PARAMS = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02}
POSITION = {"x": 0.0, "y": 0.0}
MOMENTUM = (0.1, 0.05, 0.01, 0.02, 0.01)

WARM_SCRIPT = """
import json, sys, time
sys.path.insert(0, {repo!r})
import symgroupoid as sg
from symgroupoid.systems import plate_ball
from symgroupoid.runtime.toolchain import STATS
step = plate_ball().euler_lagrange()
t0 = time.perf_counter()
sim = sg.compile_step(step, cache_dir={cache!r})
print(json.dumps({{"seconds": time.perf_counter() - t0, **STATS}}))
"""


def best_of(fn, repeat: int) -> float:
    """Smallest wall time of ``repeat`` calls."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def cold_build(cache: str):
    t0 = time.perf_counter()
    step = plate_ball().euler_lagrange()
    t1 = time.perf_counter()
    sim = sg.compile_step(step, backend="c", cache_dir=cache)
    t2 = time.perf_counter()
    return step, sim, t1 - t0, t2 - t1


def warm_load(cache: str) -> dict:
    script = WARM_SCRIPT.format(repo=str(REPO), cache=cache)
    loads = []
    for _ in range(3):
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                             check=True).stdout
        loads.append(json.loads(out.strip().splitlines()[-1]))
    return min(loads, key=lambda d: d["seconds"])


def compiled_per_step(sim, state, steps: int, extrapolate: bool) -> tuple[float, object]:
    options = sg.NewtonOptions(extrapolate=extrapolate)
    traj = sim.simulate(state, steps, PARAMS, options=options)
    seconds = best_of(lambda: sim.simulate(state, steps, PARAMS, options=options), 10)
    return seconds / steps, traj


def python_overhead(sim, state, steps: int = 200, repeat: int = 300) -> dict[str, float]:
    """µs per ``sim.step`` call of a loop beyond the kernel's step, parameters given as a
    vector and as a dict: the best of ``repeat`` bursts of ``steps`` calls (short bursts,
    so that the best one ran undisturbed on a busy machine), against the kernel's own run of
    as many steps from ``step.prediction`` (one C call), whose states the loop reproduces
    bitwise."""
    options = sg.NewtonOptions(extrapolate=False)
    vector = sim.parameters(PARAMS)

    def loop(params) -> np.ndarray:
        s = state
        for _ in range(steps):
            s = sim.step(s, params)
        return s

    reference = sim.kernel.simulate(state, vector, steps, options)
    if not np.array_equal(loop(vector), reference.states[-1]):
        raise RuntimeError("sim.step in a loop differs from simulate (prediction guess)")
    runs = {"kernel": lambda: sim.kernel.simulate(state, vector, steps, options),
            "vector": lambda: loop(vector), "dict": lambda: loop(PARAMS)}
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(repeat):  # interleaved: each sees the same load
        for what, run in runs.items():
            best[what] = min(best[what], best_of(run, 1))
    return {what: (best[what] - best["kernel"]) / steps * 1e6 for what in ("vector", "dict")}


def input_overhead(step, sim, state, steps: int = 200, repeat: int = 300
                   ) -> dict[str, float]:
    """µs per ``sim.step(state, p, inputs=u)`` call of a loop beyond the kernel's step (u an
    array, and a new list each call), on
    the plate-ball driven by two inputs (a force on the ball's first two sections,
    ``sg.body_torque``, docs/conventions.md §20), against the driven kernel's own run of as
    many steps with the same inputs (one C call); and the driven kernel's µs per step
    against the plate-ball's (what the force terms and the inputs' slots cost in C).  The
    inputs are held at zero, so the loop's arrows are bitwise those of the plate-ball's
    own kernel run, which is checked."""
    base = step.system
    u = sp.symbols("u1 u2", real=True)
    rank = base.groupoid.rank
    driven = sg.DiscreteSystem(
        base.groupoid, base.lagrangian, base.constraints, base.parameters,
        name="plate_ball_driven", time_step=base.time_step, inputs=list(u),
        forces=sg.body_torque([u[0], u[1]] + [0] * (rank - 2), base.time_step))
    forced = driven.euler_lagrange().compile()
    vector = sim.parameters(PARAMS)
    start = forced.state(np.r_[state, 0.0, 0.0, 0.0, 0.0], PARAMS)
    zero = np.zeros(2)
    zeros = np.zeros((steps, 2))
    options = sg.NewtonOptions(extrapolate=False)
    kernel, layout = forced.kernel, forced.layout

    def loop() -> np.ndarray:
        s = start
        for _ in range(steps):
            s = forced.step(s, vector, inputs=zero)
        return s

    def list_loop() -> np.ndarray:  # a controller's inputs=[u1, u2], a new list each call
        s = start
        for _ in range(steps):
            s = forced.step(s, vector, inputs=[0.0, 0.0])
        return s

    def driven_run():
        states = np.empty((steps + 1, layout.n_known))
        states[0] = start
        iterations, norms = np.zeros(steps, np.intc), np.zeros(steps)
        kernel.simulate_inputs(states, iterations, norms, vector, zeros,
                               layout.upcoming_index, options, kernel.warm_start())
        return states

    reference = sim.kernel.simulate(state, vector, steps, options)
    n = len(state)
    if not (np.array_equal(loop()[:n], reference.states[-1])
            and np.array_equal(list_loop()[:n], reference.states[-1])
            and np.array_equal(driven_run()[-1, :n], reference.states[-1])):
        raise RuntimeError("the driven plate-ball's step loop differs from the plate-ball's run")
    runs = {"kernel": lambda: sim.kernel.simulate(state, vector, steps, options),
            "driven kernel": driven_run, "inputs": loop, "list inputs": list_loop}
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(repeat):
        for what, run in runs.items():
            best[what] = min(best[what], best_of(run, 1))
    return {"overhead": (best["inputs"] - best["driven kernel"]) / steps * 1e6,
            "list overhead": (best["list inputs"] - best["driven kernel"]) / steps * 1e6,
            "driven kernel": best["driven kernel"] / steps * 1e6,
            "kernel": best["kernel"] / steps * 1e6}


def scipy_per_step(step, state, steps: int) -> tuple[float, np.ndarray]:
    from scipy.optimize import root

    args = [list(step.unknowns), list(step.knowns), list(step.parameters)]
    F = sp.lambdify(args, step.residuals_in_unknowns(), "numpy", cse=True)
    J = sp.lambdify(args, step.jacobian(substitute=True), "numpy", cse=True)
    nxt = sp.lambdify(args, step.next_knowns, "numpy", cse=True)
    pred = sp.lambdify(args[1:], step.prediction, "numpy", cse=True)
    p = np.array([PARAMS[str(s)] for s in step.parameters])

    def run():
        known = np.array(state, float)
        states = [known]
        for _ in range(steps):
            sol = root(lambda u, k=known: (np.asarray(F(u, k, p), float),
                                           np.asarray(J(u, k, p), float)),
                       np.asarray(pred(known, p), float), jac=True, method="hybr",
                       options={"xtol": 1e-12})
            if not sol.success:
                raise RuntimeError(f"scipy.optimize.root failed: {sol.message}")
            known = np.asarray(nxt(sol.x, known, p), float)
            states.append(known)
        return np.array(states)

    states = run()
    return best_of(run, 2) / steps, states


def casadi_per_step(step, state, steps: int, workdir: Path) -> tuple[float, np.ndarray, str]:
    import casadi as ca

    n_u, n_k, n_p = len(step.unknowns), len(step.knowns), len(step.parameters)
    u, k, p = ca.SX.sym("u", n_u), ca.SX.sym("k", n_k), ca.SX.sym("p", n_p)
    flat = [*step.unknowns, *step.knowns, *step.parameters]
    values = [u[i] for i in range(n_u)] + [k[i] for i in range(n_k)] + [p[i] for i in range(n_p)]

    def to_casadi(exprs):
        fn = sp.lambdify(flat, list(exprs), modules=[{"sqrt": ca.sqrt, "sin": ca.sin,
                                                      "cos": ca.cos}])
        return ca.vertcat(*fn(*values))

    residual = ca.Function("residual", [u, ca.vertcat(k, p)],
                           [to_casadi(step.residuals_in_unknowns())])
    newton = ca.rootfinder("newton", "fast_newton", residual,
                           {"abstol": 1e-12, "abstolStep": 1e-12, "max_iter": 50})
    guess = ca.Function("guess", [k, p], [to_casadi(step.prediction)])
    nxt = ca.Function("nxt", [u, k, p], [to_casadi(step.next_knowns)])
    solved = newton(guess(k, p), ca.vertcat(k, p))
    one_step = ca.Function("one_step", [k, p], [nxt(solved, k, p)])
    trajectory = one_step.mapaccum("trajectory", steps)
    source = "casadi_plate_ball.c"
    cwd = os.getcwd()
    try:
        os.chdir(workdir)
        trajectory.generate(source)
    finally:
        os.chdir(cwd)
    library = workdir / "casadi_plate_ball.so"
    subprocess.run(["cc", "-O3", *vector_flags(["cc"], []), "-shared", "-fPIC",
                    str(workdir / source), "-o", str(library), "-lm"],
                   check=True, capture_output=True)
    run_c = ca.external(trajectory.name(), str(library))  # mapaccum nests acc10 blocks
    k0 = ca.DM(np.asarray(state, float))
    pp = ca.repmat(ca.DM([PARAMS[str(s)] for s in step.parameters]), 1, steps)
    out = np.array(run_c(k0, pp))
    seconds = best_of(lambda: run_c(k0, pp), 10)
    return seconds / steps, np.column_stack([np.asarray(state, float), out]).T, ca.__version__


#: trajectories are compared over their first steps only: this plate-ball motion amplifies
#: perturbations (a change of 1e-12 in x_1 grows to O(1) within 1e5 steps), so solutions that
#: agree to rounding at every step still separate over long runs.
COMPARE_STEPS = 1000


def deviation(a: np.ndarray, b: np.ndarray) -> float:
    """Max |a − b| over the first COMPARE_STEPS states."""
    n = min(len(a), len(b), COMPARE_STEPS + 1)
    return float(np.abs(a[:n] - b[:n]).max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=100_000)
    parser.add_argument("--scipy-steps", type=int, default=2_000)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        cache = str(Path(tmp) / "cache")
        step, sim, derive_s, compile_s = cold_build(cache)
        warm = warm_load(cache)
        print("plate-ball: 8 equations in 8 unknowns; "
              f"{args.steps} steps of h = {PARAMS['h']}")
        print(f"cold cache: derive {derive_s:.2f} s + emit & compile {compile_s:.2f} s = "
              f"{derive_s + compile_s:.2f} s (target < 5 s)")
        print(f"warm cache: compile_step in a new process {warm['seconds'] * 1e3:.1f} ms "
              f"(codegen runs: {warm['codegen']}, builds: {warm['builds']}; target < 50 ms)")

        state = sim.from_momentum(POSITION, MOMENTUM, PARAMS)
        ours, traj = compiled_per_step(sim, state, args.steps, extrapolate=True)
        plain, traj_plain = compiled_per_step(sim, state, args.steps, extrapolate=False)
        iters = np.bincount(traj.newton_iterations)
        print(f"compiled (extrapolated guess):  {ours * 1e6:8.3f} us/step  "
              f"(Newton updates per step: {dict(enumerate(iters.tolist()))}; target <= 1 us)")
        print(f"compiled (prediction guess):    {plain * 1e6:8.3f} us/step  "
              f"(max deviation from the above {deviation(traj.states, traj_plain.states):.1e})")
        overhead = python_overhead(sim, state)
        print(f"Python overhead of sim.step:    {overhead['vector']:8.3f} us/call with a "
              f"parameter vector, {overhead['dict']:.3f} with a dict (target <= 2 us)")
        driven = input_overhead(step, sim, state)
        print(f"  ... with inputs, sim.step(s, p, inputs=u): {driven['overhead']:.3f} us/call "
              f"(plate-ball driven by 2 inputs; target <= 2 us); inputs=[u1, u2] as a "
              f"list: {driven['list overhead']:.3f} us/call")
        print(f"  driven kernel (prediction guess): {driven['driven kernel']:.3f} us/step "
              f"against {driven['kernel']:.3f} without inputs "
              f"(ratio {driven['driven kernel'] / driven['kernel']:.2f})")

        n_scipy = min(args.scipy_steps, args.steps)
        sci, sci_states = scipy_per_step(step, state, n_scipy)
        print(f"(a) scipy.optimize.root:        {sci * 1e6:8.1f} us/step  "
              f"({n_scipy} steps; max deviation {deviation(sci_states, traj.states):.1e}); "
              f"ratio {sci / ours:7.0f}x (target >= 300x)")

        try:
            import casadi  # noqa: F401
        except ImportError:
            print("(b) CasADi: not installed (pip install '.[bench]'); skipped")
            return
        cas, cas_states, version = casadi_per_step(step, state, args.steps, Path(tmp))
        print(f"(b) CasADi {version} fast_newton+mapaccum, generated C -O3: "
              f"{cas * 1e6:.3f} us/step (max deviation {deviation(cas_states, traj.states):.1e})")
        print(f"    ratio CasADi / compiled: {cas / ours:.1f}x (target >= 5x); "
              f"like for like (both from step.prediction): {cas / plain:.1f}x")


if __name__ == "__main__":
    main()
