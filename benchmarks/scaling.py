"""How derivation and code generation scale with the number of bodies, against CasADi.

    python benchmarks/scaling.py [--systems planar,3d,planar-forced,3d-forced]
                                 [--sizes 2,4,8] [--quick]
                                 [--budget SECONDS] [--repeat K] [--output results.json]
                                 [--no-skip]
    python benchmarks/scaling.py --report results.json

Two model systems of ``symgroupoid.systems``, sized by the number of bodies n:

- ``planar``: ``planar_chain(n)``, the planar n-link pendulum in angle coordinates
  (pair groupoid of Rⁿ, midpoint discrete Lagrangian), n = 2, 4, 8, 16, 32, 64;
- ``3d``: ``spherical_chain(n)``, n rigid bodies joined by spherical joints under gravity
  (Lee–Leok–McClamroch Lie group variational integrator on the pair groupoid of SO(3)ⁿ),
  n = 1, 2, 3, 4, 6, 8;
- ``planar-forced``, ``3d-forced``: the same chains with ``forced=True``: a torque input at
  every joint (one per joint for the planar chain, a body-frame vector per joint for the 3D
  chain) and joint damping c = 0.1 (docs/conventions.md §20).  The library runs
  ``sim.simulate(state, N, params, inputs=U)`` with a random but fixed U (normal, scale
  0.2, the same rows for CasADi, whose ``mapaccum`` takes them as per-step parameters).
  The worker also times the unforced chain of the same n in the same process, alternating
  rounds with the forced runs, and prints forced / unforced (target ≤ 1.10) next to
  forced / CasADi-forced (target ≤ 0.6).  The forces change the motion, and with it the
  Newton updates per step; the worker also times the forced chain with u = 0 and c = 0
  (the unforced motion), whose ratio to the unforced chain is the cost of the forces'
  terms and the inputs alone.  List a forced system after its unforced one
  (``--systems planar,planar-forced``): the sizes then alternate between the two.

For each n, through the public API only, in a subprocess with a time budget (``--budget``,
"timeout" is printed when it runs out):

- derive: ``system = constructor(n)`` and ``step = system.euler_lagrange()``;
- compile: ``step.compile(backend="c", cache_dir=<fresh directory>)``, right after the
  derivation (so it pays every first use of the code generator in the process); it runs its
  own code generation;
- emit, after it: ``symgroupoid.codegen.generate_c(step)`` (the C size is that of its
  source, with the LaTeX comments of small kernels); compile − emit is also printed (an
  estimate of the C compiler's share);
  build = derive + compile (what a user waits for to get a simulator); ``--repeat`` cold
  builds (default 3, each in a new process with a fresh cache; not repeated beyond 10 s),
  interleaved with as many cold CasADi builds, and the build ratio compares the medians
  (single builds vary by ±30 % on a small machine);
- µs/step: ``sim.simulate(state, N, params)`` with N chosen so that one run takes ≥ 0.5 s,
  best of 5 (the CasADi stepper is timed the same way); Newton iterations from
  ``traj.newton_iterations``;
- ``step.evaluate(u, known, params)`` at random points, for the residual check below.

In the same run the same discrete equations are built with CasADi
(``benchmarks/_casadi_models.py``: SX graph, AD Jacobian, ``rootfinder('fast_newton')`` with
the library's tolerances and its extrapolated first guess (linear or quadratic by hindsight),
``mapaccum`` over many steps, C generated and compiled at -O3 for the same vector extension
as the library's kernels, loaded with ``casadi.external``).  Every comparison is printed
with its check: the CasADi residual and Jacobian against the library's at random points
(relative difference ≤ 1e-10, else "MISMATCH"), so that both sides are known to solve the same
equations; and the first 100 steps from the same initial state (max difference of the states:
θ for the planar chain, the attitudes R_i and relative rotations F_i for the 3D chain).

After a library timeout at some n, the larger n of that system are skipped (``--no-skip`` runs
them anyway); the CasADi side always runs.  ``--output`` writes every number as JSON;
``--report`` prints the tables and targets of such a file again (to compare runs).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

SIZES = {"planar": (2, 4, 8, 16, 32, 64), "3d": (1, 2, 3, 4, 6, 8)}
SIZES.update({f"{kind}-forced": sizes for kind, sizes in list(SIZES.items())})
CONSTRUCTORS = {"planar": "planar_chain", "3d": "spherical_chain"}
TITLES = {"planar": "planar n-link pendulum", "3d": "3D chain of n rigid bodies",
          "planar-forced": "planar n-link pendulum, joint torques and damping",
          "3d-forced": "3D chain of n rigid bodies, joint torques and damping"}
PARAMS = {"h": 0.01, "g": 9.81}
#: parameters of the forced chains: PARAMS and the joint damping c
FORCED_PARAMS = {**PARAMS, "c": 0.1}
#: the forced chains' inputs: normal, this scale, from this seed (+ n)
INPUT_SCALE = 0.2
INPUT_SEED = 20261126
#: first steps compared between the library and CasADi
COMPARE_STEPS = 100
#: steps per call of the CasADi mapaccum stepper
CASADI_CHUNK = 1000
#: relative agreement required of the two residuals (and Jacobians) at random points
CHECK_TOLERANCE = 1e-10
CHECK_POINTS = 5
#: one timing run lasts at least this long
MIN_RUN_SECONDS = 0.5
#: cold builds per side and n (``--repeat``): the build ratio is the ratio of the medians
BUILD_REPEATS = 3
#: builds slower than this (seconds, first sample) are not repeated
REPEAT_LIMIT = 10.0
#: timing runs per measurement (the best is kept: the machine may be shared)
TIMING_REPEATS = 5
#: largest state history a timing run may hold (bytes)
MAX_HISTORY_BYTES = 200e6

#: the issue's absolute build-time targets, seconds
BUILD_TARGETS = {("planar", 16): 2.0, ("3d", 3): 10.0, ("3d", 8): 60.0, ("planar", 64): 60.0}
STEP_RATIO_TARGET = 0.8
#: the forced chains' targets: step time against the unforced chain's and against CasADi's
FORCED_OVERHEAD_TARGET = 1.10
FORCED_STEP_RATIO_TARGET = 0.6
GROWTH_TARGET = 2.0
GROWTH_SLACK = 0.2


# --- kinds -------------------------------------------------------------------------------------


def base_kind(kind: str) -> str:
    """The unforced chain of a kind: ``planar-forced`` -> ``planar``."""
    return kind.removesuffix("-forced")


def is_forced(kind: str) -> bool:
    return kind.endswith("-forced")


def params_of(kind: str) -> dict:
    return FORCED_PARAMS if is_forced(kind) else PARAMS


def n_inputs(kind: str, n: int) -> int:
    """m: one torque per joint (planar), a body-frame torque vector per joint (3D)."""
    if not is_forced(kind):
        return 0
    return n if base_kind(kind) == "planar" else 3 * n


def bench_inputs(kind: str, n: int, steps: int) -> np.ndarray:
    """The forced chain's inputs, shape (steps, m): random but fixed (each prefix the same
    whatever ``steps``)."""
    rng = np.random.default_rng(INPUT_SEED + n)
    return INPUT_SCALE * rng.standard_normal((steps, n_inputs(kind, n)))


def build_system(kind: str, n: int):
    from symgroupoid import systems

    constructor = getattr(systems, CONSTRUCTORS[base_kind(kind)])
    return constructor(n, forced=True) if is_forced(kind) else constructor(n)


# --- states -----------------------------------------------------------------------------------


def cayley(x: np.ndarray) -> np.ndarray:
    """cay(x) = I + 4/(4 + |x|²)(x̂ + x̂²/2)."""
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)
    return np.eye(3) + 4 / (4 + x @ x) * (X + X @ X / 2)


def initial_state(kind: str, n: int) -> np.ndarray:
    """The flat known state (in ``step.knowns`` order) both sides start from.

    planar: (θ_{−1}, θ_0) with θ_0,j = 0.6 cos(0.9 j), θ̇_0,j = 0.4 sin(1.3 j);
    3d: every body's R_{i,0} = cay(a_i) (a tilted chain), then every body's
    R_{i,1} = R_{i,0} cay(h ω_i), row-major (the arrow of the pair groupoid of SO(3)ⁿ);
    forced: then zero inputs u_0 and an empty slot for u_1 (2m zeros).
    """
    if is_forced(kind):
        return np.concatenate([initial_state(base_kind(kind), n),
                               np.zeros(2 * n_inputs(kind, n))])
    h = PARAMS["h"]
    j = np.arange(1, n + 1)
    if kind == "planar":
        theta = 0.6 * np.cos(0.9 * j)
        return np.concatenate([theta - h * 0.4 * np.sin(1.3 * j), theta])
    R = [cayley(np.array([0.3 * np.cos(i), 0.25 * np.sin(1.7 * i), 0.1 * i])) for i in j]
    F = [cayley(h * np.array([0.6 * np.sin(i), -0.4 * np.cos(2 * i), 0.8])) for i in j]
    return np.concatenate([r.ravel() for r in R] + [(r @ f).ravel() for r, f in zip(R, F)])


def random_point(kind: str, n: int, rng: np.random.Generator):
    """(u, known, params) at which the two residuals are compared: not on a trajectory
    (forced: random inputs of both arrows and a random damping c too)."""
    if is_forced(kind):
        u, known, params = random_point(base_kind(kind), n, rng)
        inputs = rng.normal(size=2 * n_inputs(kind, n))
        return u, np.concatenate([known, inputs]), np.append(params, rng.uniform(0.0, 1.0))
    params = np.array([rng.uniform(0.005, 0.1), rng.uniform(1.0, 10.0)])
    if kind == "planar":
        return rng.uniform(-1.5, 1.5, n), rng.uniform(-1.5, 1.5, 2 * n), params
    R = [cayley(rng.normal(size=3)) for _ in range(n)]
    R1 = [r @ cayley(0.2 * rng.normal(size=3)) for r in R]
    known = np.concatenate([r.ravel() for r in R] + [r.ravel() for r in R1])
    return 0.2 * rng.normal(size=3 * n), known, params


def sizes_of_state(kind: str, n: int) -> tuple[int, int]:
    """(unknowns, knowns) of one step (forced: the knowns end with u_k, u_{k+1})."""
    m = n_inputs(kind, n)
    return (n, 2 * n + 2 * m) if base_kind(kind) == "planar" else (3 * n, 18 * n + 2 * m)


# --- the library side (runs in a subprocess) --------------------------------------------------


def emit(record: dict) -> None:
    print(json.dumps(record), flush=True)


def code_bytes(source: str) -> int:
    """Bytes of C source without comments."""
    return len(re.sub(r"/\*.*?\*/|//[^\n]*", "", source, flags=re.S).encode())


def library_build(kind: str, n: int, cache: str, only: bool = False) -> None:
    """derive → emit → compile → simulate → evaluate, one JSON line per finished phase
    (``only``: derive → compile, a further sample of the build time)."""
    import symgroupoid.codegen

    t0 = time.perf_counter()
    step = build_system(kind, n).euler_lagrange()
    t1 = time.perf_counter()
    emit({"phase": "derive", "seconds": t1 - t0, "equations": len(step),
          "unknowns": len(step.unknowns), "knowns": len(step.knowns)})
    if (len(step.unknowns), len(step.knowns)) != sizes_of_state(kind, n):
        raise SystemExit(f"{step.name}: state layout changed ({len(step.unknowns)} unknowns, "
                         f"{len(step.knowns)} knowns); update benchmarks/_casadi_models.py")
    t1 = time.perf_counter()
    sim = step.compile(backend="c", cache_dir=cache)
    t2 = time.perf_counter()
    emit({"phase": "compile", "seconds": t2 - t1})
    if only:
        return
    kernel = symgroupoid.codegen.generate_c(step)
    t3 = time.perf_counter()
    emit({"phase": "emit", "seconds": t3 - t2, "c_bytes": len(kernel.source.encode()),
          "c_code_bytes": code_bytes(kernel.source), "c_lines": kernel.source.count("\n")})
    if is_forced(kind):
        library_simulate_forced(sim, kind, n, Path(cache).parent / f"twin-{kind}-{n}")
    else:
        library_simulate(sim, kind, n)
    library_check(step, kind, n)


def timed_runs(run, size: int, limit: int) -> tuple[float, int]:
    """Best of TIMING_REPEATS wall times of ``run(size)``, with ``size`` grown until one run
    lasts MIN_RUN_SECONDS (or reaches ``limit``); returns (seconds, size)."""
    while True:
        t0 = time.perf_counter()
        run(size)
        seconds = time.perf_counter() - t0
        if seconds >= MIN_RUN_SECONDS or size >= limit:
            break
        grow = 1.2 * MIN_RUN_SECONDS / max(seconds, 1e-6)
        size = min(limit, max(2 * size, math.ceil(size * grow)))
    best = seconds
    for _ in range(TIMING_REPEATS - 1):
        t0 = time.perf_counter()
        run(size)
        best = min(best, time.perf_counter() - t0)
    return best, size


def library_simulate(sim, kind: str, n: int) -> None:
    from symgroupoid import NewtonDivergenceError

    state = initial_state(kind, n)
    first = sim.simulate(state, COMPARE_STEPS, PARAMS)
    last: list = []

    def run(steps: int) -> None:
        last[:] = [sim.simulate(state, steps, PARAMS)]  # keep one history in memory

    limit = max(COMPARE_STEPS, int(MAX_HISTORY_BYTES / (8 * len(state))))
    solvable = exc_step = None
    try:
        best, steps = timed_runs(run, COMPARE_STEPS, limit)
    except NewtonDivergenceError as exc:
        # a step with no solution near its guess (the long chain's tip whips: at h = 0.01
        # the midpoint equations stop having a nearby root): time the steps before it
        solvable, exc_step = len(exc.trajectory.states) - 1, exc.step
        best, steps = timed_runs(run, COMPARE_STEPS, max(COMPARE_STEPS, solvable))
    iterations = np.asarray(last[0].newton_iterations)
    emit({"phase": "simulate", "us_per_step": best / steps * 1e6, "steps": steps,
          "run_seconds": best, "newton_mean": float(iterations.mean()),
          "newton_max": int(iterations.max()), "states": first.states.tolist(),
          "unsolvable_step": None if solvable is None else exc_step})


def library_simulate_forced(sim, kind: str, n: int, twin_cache: Path) -> None:
    """The forced chain's ``simulate(..., inputs=U)`` timed as :func:`library_simulate`
    times the unforced one, then TIMING_REPEATS further rounds alternating a forced run, a
    run of the unforced chain of the same n (compiled here, ``twin_cache``) and a forced run
    with the inputs held at zero and c = 0 (the unforced chain's motion, so its Newton
    updates), all of as many steps.  Forced / unforced compares the runs as the benchmark
    drives them (the forces change the motion and the Newton updates it takes); at rest /
    unforced is the cost of the forces' terms and the inputs alone."""
    from symgroupoid import NewtonDivergenceError

    state, params = initial_state(kind, n), params_of(kind)
    first = sim.simulate(state, COMPARE_STEPS, params,
                         inputs=bench_inputs(kind, n, COMPARE_STEPS))
    tables: dict = {}
    last: list = []

    def run(steps: int) -> None:
        if steps not in tables:
            tables.clear()  # one table of inputs in memory
            tables[steps] = bench_inputs(kind, n, steps)
        last[:] = [sim.simulate(state, steps, params, inputs=tables[steps])]

    limit = max(COMPARE_STEPS, int(MAX_HISTORY_BYTES / (8 * len(state))))
    solvable = exc_step = None
    try:
        best, steps = timed_runs(run, COMPARE_STEPS, limit)
    except NewtonDivergenceError as exc:
        solvable, exc_step = len(exc.trajectory.states) - 1, exc.step
        best, steps = timed_runs(run, COMPARE_STEPS, max(COMPARE_STEPS, solvable))
    iterations = np.asarray(last[0].newton_iterations)
    twin = build_system(base_kind(kind), n).euler_lagrange().compile(
        backend="c", cache_dir=str(twin_cache))
    twin_state = initial_state(base_kind(kind), n)
    newton: dict = {}  # Newton updates per step of the last run of each (no history kept)
    try:  # the unforced motion may whip where the forced one does not: time what it solves
        twin_steps = len(twin.simulate(twin_state, steps, PARAMS).newton_iterations)
    except NewtonDivergenceError as exc:
        twin_steps = max(1, len(exc.trajectory.states) - 1)
    rest_params = {**params, "c": 0.0}
    rest_inputs = np.zeros((twin_steps, n_inputs(kind, n)))  # a table, as the forced run's

    def unforced() -> None:
        newton["unforced"] = twin.simulate(twin_state, twin_steps, PARAMS).newton_iterations

    def at_rest() -> None:
        newton["at_rest"] = sim.simulate(state, twin_steps, rest_params,
                                         inputs=rest_inputs).newton_iterations

    runs = {"forced": lambda: run(steps), "unforced": unforced, "at_rest": at_rest}
    wall = {"forced": best, "unforced": math.inf, "at_rest": math.inf}
    cpu = dict.fromkeys(runs, math.inf)
    for _ in range(TIMING_REPEATS):  # alternating rounds, wall and CPU time of each run
        for name, go in runs.items():
            t0, c0 = time.perf_counter(), time.process_time()
            go()
            wall[name] = min(wall[name], time.perf_counter() - t0)
            cpu[name] = min(cpu[name], time.process_time() - c0)
    sizes = {"forced": steps, "unforced": twin_steps, "at_rest": twin_steps}
    best, twin_best, rest_best = wall["forced"], wall["unforced"], wall["at_rest"]
    emit({"phase": "simulate", "us_per_step": best / steps * 1e6, "steps": steps,
          "run_seconds": best, "newton_mean": float(iterations.mean()),
          "newton_max": int(iterations.max()), "states": first.states.tolist(),
          "unsolvable_step": None if solvable is None else exc_step,
          "unforced_us_per_step": twin_best / twin_steps * 1e6, "unforced_steps": twin_steps,
          "unforced_newton_mean": float(np.mean(newton["unforced"])),
          "at_rest_us_per_step": rest_best / twin_steps * 1e6,
          "at_rest_newton_mean": float(np.mean(newton["at_rest"])),
          "cpu_us_per_step": {k: v / sizes[k] * 1e6 for k, v in cpu.items()}})


def library_check(step, kind: str, n: int) -> None:
    rng = np.random.default_rng(20261122 + n)
    points = []
    for _ in range(CHECK_POINTS):
        u, known, params = random_point(kind, n, rng)
        F, J = step.evaluate(u, known, params)
        points.append({"u": u.tolist(), "known": known.tolist(), "params": params.tolist(),
                       "F": F.tolist(), "J": J.tolist()})
    emit({"phase": "check", "points": points})


def library_check_only(kind: str, n: int) -> None:
    t0 = time.perf_counter()
    step = build_system(kind, n).euler_lagrange()
    emit({"phase": "derive", "seconds": time.perf_counter() - t0, "equations": len(step),
          "unknowns": len(step.unknowns), "knowns": len(step.knowns)})
    library_check(step, kind, n)


@dataclass
class WorkerResult:
    phases: dict
    status: str  # "ok", "timeout" or "error: …"
    seconds: float


def run_worker(mode: str, kind: str, n: int, budget: float, cache: str) -> WorkerResult:
    """Run this script as ``--worker`` in a new process group; kill the group at the budget."""
    command = [sys.executable, str(Path(__file__).resolve()), "--worker", mode, kind, str(n),
               cache]
    phases: dict = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryFile(mode="w+") as errors:
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=errors, text=True,
                                start_new_session=True)

        def read() -> None:
            for line in proc.stdout:
                try:
                    record = json.loads(line)
                except json.JSONDecodeError:
                    continue
                phases[record.pop("phase")] = record

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            proc.wait(timeout=budget)
            status = "ok" if proc.returncode == 0 else "error"
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            status = "timeout"
        reader.join()
        if status == "error":
            errors.seek(0)
            lines = [ln for ln in errors.read().splitlines() if ln.strip()]
            status = "error: " + (lines[-1] if lines else f"exit status {proc.returncode}")
    return WorkerResult(phases, status, time.perf_counter() - t0)


# --- the CasADi side ---------------------------------------------------------------------------


def casadi_side(kind: str, n: int, workdir: Path) -> dict:
    import _casadi_models as cm

    model = cm.MODELS[kind](n)
    stepper = cm.compile_stepper(model, CASADI_CHUNK, workdir)
    state = initial_state(kind, n)
    params = np.array(list(params_of(kind).values()))
    inputs = bench_inputs(kind, n, CASADI_CHUNK) if is_forced(kind) else None
    states = stepper.trajectory(state, params, inputs)
    z0, columns = stepper.initial(state), stepper.step_parameters(params, inputs)

    def run(calls: int) -> None:
        for _ in range(calls):
            stepper.run(z0, columns)

    best, calls = timed_runs(run, 1, 10**6)
    return {"build_seconds": stepper.build_seconds,
            "phases": {"model": model.build_seconds, **stepper.seconds},
            "c_bytes": stepper.c_bytes, "us_per_step": best / (calls * CASADI_CHUNK) * 1e6,
            "steps": calls * CASADI_CHUNK, "states": states[: COMPARE_STEPS + 1], "model": model}


def casadi_build_seconds(kind: str, n: int, workdir: Path) -> float:
    """One more cold CasADi build (model graph with AD, stepper, C, cc, load)."""
    import _casadi_models as cm

    return cm.compile_stepper(cm.MODELS[kind](n), CASADI_CHUNK, workdir).build_seconds


def library_build_seconds(kind: str, n: int, budget: float, tmp: Path, i: int) -> float | None:
    """One more cold library build (derive + compile, fresh cache) in a new process."""
    cache = tmp / f"cache-{kind}-{n}-{i}"
    work = run_worker("buildonly", kind, n, budget, str(cache))
    shutil.rmtree(cache, ignore_errors=True)
    if work.status != "ok":
        return None
    return work.phases["derive"]["seconds"] + work.phases["compile"]["seconds"]


def repeat_builds(row: dict, budget: float, tmp: Path, repeats: int) -> None:
    """Further cold builds of both sides, interleaved, when the first library build took
    under REPEAT_LIMIT; each side's build time becomes the median of its samples."""
    kind, n, lib, cas = row["system"], row["n"], row["library"], row["casadi"]
    lib_samples = [lib["build_seconds"]] if "build_seconds" in lib else []
    cas_samples = [cas["build_seconds"]]
    if lib_samples and lib_samples[0] < REPEAT_LIMIT:
        for i in range(1, repeats):
            sample = library_build_seconds(kind, n, budget, tmp, i)
            if sample is not None:
                lib_samples.append(sample)
            cas_samples.append(casadi_build_seconds(kind, n, tmp / f"casadi-{kind}-{n}-{i}"))
    if lib_samples:
        lib["build_samples"], lib["build_seconds"] = lib_samples, float(np.median(lib_samples))
    cas["build_samples"], cas["build_seconds"] = cas_samples, float(np.median(cas_samples))


def residual_check(model, points: list[dict]) -> dict:
    """Max relative differences of the residuals and Jacobians at the library's points."""
    worst_F = worst_J = 0.0
    for pt in points:
        args = (pt["u"], pt["known"], pt["params"])
        F = np.array(model.residual(*args)).ravel()
        J = np.array(model.jacobian(*args))
        F_lib, J_lib = np.array(pt["F"]), np.array(pt["J"])
        worst_F = max(worst_F, float(np.abs(F - F_lib).max() / np.abs(F_lib).max()))
        worst_J = max(worst_J, float(np.abs(J - J_lib).max() / np.abs(J_lib).max()))
    return {"points": len(points), "residual": worst_F, "jacobian": worst_J,
            "passed": max(worst_F, worst_J) <= CHECK_TOLERANCE}


# --- one size ----------------------------------------------------------------------------------


def run_size(kind: str, n: int, budget: float, skip_reason: str | None, tmp: Path,
             repeats: int = BUILD_REPEATS) -> dict:
    row: dict = {"system": kind, "n": n}
    if skip_reason is None:
        cache = tmp / f"cache-{kind}-{n}"
        work = run_worker("build", kind, n, budget, str(cache))
        shutil.rmtree(cache, ignore_errors=True)
        row["library"] = {"status": work.status, "wall_seconds": work.seconds, **work.phases}
        if "check" not in work.phases and "derive" in work.phases:
            check = run_worker("check", kind, n, budget, str(tmp / "unused"))
            row["library"]["check_worker"] = {"status": check.status,
                                              "wall_seconds": check.seconds}
            if "check" in check.phases:
                row["library"]["check"] = check.phases["check"]
    else:
        row["library"] = {"status": skip_reason}
    cas = casadi_side(kind, n, tmp / f"casadi-{kind}-{n}")
    model, cas_states = cas.pop("model"), cas.pop("states")
    row["casadi"] = cas
    lib = row["library"]
    if "check" in lib:
        row["residual_check"] = residual_check(model, lib.pop("check")["points"])
    if "simulate" in lib:
        lib_states = np.array(lib["simulate"].pop("states"))
        row["max_deviation_100_steps"] = float(np.abs(lib_states - cas_states).max())
    if "derive" in lib and "compile" in lib:
        lib["build_seconds"] = lib["derive"]["seconds"] + lib["compile"]["seconds"]
    repeat_builds(row, budget, tmp, repeats)
    if "build_seconds" in lib:
        row["build_ratio"] = lib["build_seconds"] / cas["build_seconds"]
    if "simulate" in lib:
        row["step_ratio"] = lib["simulate"]["us_per_step"] / cas["us_per_step"]
        if "unforced_us_per_step" in lib["simulate"]:
            sim = lib["simulate"]
            row["forced_overhead"] = sim["us_per_step"] / sim["unforced_us_per_step"]
            if "at_rest_us_per_step" in sim:
                row["at_rest_overhead"] = sim["at_rest_us_per_step"] / sim["unforced_us_per_step"]
            if "cpu_us_per_step" in sim:
                cpu = sim["cpu_us_per_step"]
                row["cpu_overhead"] = cpu["forced"] / cpu["unforced"]
                row["cpu_at_rest_overhead"] = cpu["at_rest"] / cpu["unforced"]
    return row


# --- printing ----------------------------------------------------------------------------------


def fmt(value, spec: str = ".2f", missing: str = "-") -> str:
    return missing if value is None else format(value, spec)


def phase(lib: dict, name: str, key: str):
    return lib.get(name, {}).get(key)


def library_cells(row: dict) -> list[str]:
    lib = row["library"]
    status = lib["status"]
    lost = "timeout" if status == "timeout" else "-"
    derive = phase(lib, "derive", "seconds")
    emit_s = phase(lib, "emit", "seconds")
    compile_s = phase(lib, "compile", "seconds")
    c_kb = phase(lib, "emit", "c_bytes")
    code_kb = phase(lib, "emit", "c_code_bytes")
    sim = lib.get("simulate", {})
    cells = [fmt(derive, ".2f", lost), fmt(emit_s, ".2f", lost),
             "-" if c_kb is None else f"{c_kb / 1e3:.0f} ({code_kb / 1e3:.0f})",
             fmt(compile_s, ".2f", lost),
             fmt(None if compile_s is None else compile_s - emit_s, ".2f", lost),
             fmt(lib.get("build_seconds"), ".2f", lost),
             fmt(sim.get("us_per_step"), ".2f", lost),
             "-" if not sim else f"{sim['newton_mean']:.2f}/{sim['newton_max']}"]
    return cells


def print_row(row: dict) -> None:
    kind, n = row["system"], row["n"]
    lib, cas = row["library"], row["casadi"]
    print(f"\n{TITLES[kind]}, n = {n}: library {lib['status']}", flush=True)
    eqs = phase(lib, "derive", "equations")
    cells = library_cells(row)
    print(f"  library: {fmt(eqs, 'd')} equations; derive {cells[0]} s, emit {cells[1]} s "
          f"(C {cells[2]} kB with (without) comments), compile {cells[3]} s "
          f"(compile - emit {cells[4]} s), build {cells[5]} s; {cells[6]} us/step, "
          f"Newton {cells[7]} (mean/max)")
    unsolvable = lib.get("simulate", {}).get("unsolvable_step")
    if unsolvable:
        print(f"  (library: step {unsolvable} from the benchmark's state has no Newton solution "
              f"near its guess at this h — the chain's tip whips; the steps before it are timed)")
    ph = cas["phases"]
    print(f"  CasADi:  build {cas['build_seconds']:.2f} s (graph+AD {ph['model'] + ph['graph']:.2f}"
          f", generate {ph['generate']:.2f}, cc -O3 {ph['cc']:.2f}, load {ph['load']:.3f}); "
          f"C {cas['c_bytes'] / 1e3:.0f} kB; {cas['us_per_step']:.2f} us/step")
    samples = lib.get("build_samples", []), cas.get("build_samples", [])
    if max(len(samples[0]), len(samples[1])) > 1:
        print("  cold builds: " + "; ".join(
            f"{side} {', '.join(f'{v:.2f}' for v in values)} s (median {np.median(values):.2f})"
            for side, values in zip(("library", "CasADi"), samples) if values))
    check = row.get("residual_check")
    if check:
        verdict = "ok" if check["passed"] else "MISMATCH: the comparison below is not fair"
        print(f"  residual check at {check['points']} random points: max relative difference "
              f"F {check['residual']:.1e}, dF/du {check['jacobian']:.1e} "
              f"(<= {CHECK_TOLERANCE:.0e}: {verdict})")
    else:
        print("  residual check: not run (the library did not derive within the budget)")
    if "max_deviation_100_steps" in row:
        print(f"  first {COMPARE_STEPS} steps from the same state: max |library - CasADi| = "
              f"{row['max_deviation_100_steps']:.1e}")
    ratios = [f"build {row['build_ratio']:.2f}x" if "build_ratio" in row else None,
              f"step {row['step_ratio']:.2f}x" if "step_ratio" in row else None]
    if any(ratios):
        print("  library / CasADi: " + ", ".join(r for r in ratios if r))
    if "forced_overhead" in row:
        sim = lib["simulate"]
        print(f"  forced / unforced chain (same process, alternating rounds): "
              f"{sim['us_per_step']:.2f} / {sim['unforced_us_per_step']:.2f} us/step = "
              f"{row['forced_overhead']:.2f}x (target <= {FORCED_OVERHEAD_TARGET:.2f}); "
              f"Newton mean {sim['newton_mean']:.2f} forced, "
              f"{sim['unforced_newton_mean']:.2f} unforced")
        if "at_rest_overhead" in row:
            print(f"  forced with u = 0, c = 0 (the unforced motion) / unforced: "
                  f"{sim['at_rest_us_per_step']:.2f} / {sim['unforced_us_per_step']:.2f} "
                  f"us/step = {row['at_rest_overhead']:.2f}x; Newton mean "
                  f"{sim['at_rest_newton_mean']:.2f}")
        if "cpu_overhead" in row:
            cpu = sim["cpu_us_per_step"]
            print(f"  CPU time (the same rounds): forced {cpu['forced']:.2f}, unforced "
                  f"{cpu['unforced']:.2f}, at rest {cpu['at_rest']:.2f} us/step; forced / "
                  f"unforced {row['cpu_overhead']:.2f}x, at rest / unforced "
                  f"{row['cpu_at_rest_overhead']:.2f}x")


HEADER_LIB = (f"{'system':<14}{'n':>4}{'eqs':>5} | {'derive':>8}{'emit':>8}{'C kB (code)':>15}"
              f"{'compile':>9}{'cc est':>8}{'build':>9} | {'us/step':>9}{'Newton':>9}")
HEADER_CAS = (f"{'system':<14}{'n':>4} | {'build':>8}{'C kB':>8}{'us/step':>9} | "
              f"{'build x':>8}{'step x':>8} | {'dev 100':>8}{'check F':>9}{'check J':>9}")


def print_tables(rows: list[dict]) -> None:
    print("\n=== library (seconds; build = derive + compile; 'cc est' = compile - emit: compile "
          "runs its own code generation, so this estimates the C compiler's share, and is near "
          "0 or negative when code generation dominates; C kB of the emitted source, without "
          "comments in parentheses) ===")
    print(HEADER_LIB)
    for row in rows:
        eqs = phase(row["library"], "derive", "equations")
        c = library_cells(row)
        note = "" if row["library"]["status"] == "ok" else f"  [{row['library']['status']}]"
        print(f"{row['system']:<14}{row['n']:>4}{fmt(eqs, 'd'):>5} | {c[0]:>8}{c[1]:>8}{c[2]:>15}"
              f"{c[3]:>9}{c[4]:>8}{c[5]:>9} | {c[6]:>9}{c[7]:>9}{note}")
    print("\n=== CasADi (build = SX graph + AD + C generation + cc -O3 + load) and comparison "
          "(x = library / CasADi; dev 100 = max state difference over the first 100 steps; "
          "check = max relative residual/Jacobian difference at random points) ===")
    print(HEADER_CAS)
    for row in rows:
        cas, check = row["casadi"], row.get("residual_check", {})
        print(f"{row['system']:<14}{row['n']:>4} | {cas['build_seconds']:>8.2f}"
              f"{cas['c_bytes'] / 1e3:>8.0f}{cas['us_per_step']:>9.2f} | "
              f"{fmt(row.get('build_ratio')):>8}{fmt(row.get('step_ratio')):>8} | "
              f"{fmt(row.get('max_deviation_100_steps'), '.1e'):>8}"
              f"{fmt(check.get('residual'), '.1e'):>9}{fmt(check.get('jacobian'), '.1e'):>9}")


HEADER_FORCED = (f"{'system':<14}{'n':>4} | {'unforced':>9}{'forced':>9}{'ratio':>7}"
                 f"{'at rest':>9}{'ratio':>7} | {'CasADi':>9}{'step x':>8} | "
                 f"{'CPU ratios':>11} | {'Newton f/u/rest':>16}")


def print_forced_table(rows: list[dict]) -> None:
    forced = [r for r in rows if is_forced(r["system"])]
    if not forced:
        return
    print(f"\n=== forced chains (us/step; unforced: the same n's unforced chain timed in the "
          f"forced worker, alternating rounds; ratio = forced / unforced, target <= "
          f"{FORCED_OVERHEAD_TARGET:.2f}; CasADi: the same forced equations, step x = "
          f"forced / CasADi, target <= {FORCED_STEP_RATIO_TARGET}; at rest: the forced "
          f"chain with u = 0 and c = 0, the unforced motion, and its ratio to the unforced; "
          f"CPU ratios: forced and at rest / unforced in CPU time, less sensitive to a "
          f"loaded machine) ===")
    print(HEADER_FORCED)
    for row in forced:
        sim = row["library"].get("simulate", {})
        newton = ("-" if not sim else
                  f"{sim['newton_mean']:.2f}/{sim.get('unforced_newton_mean', math.nan):.2f}"
                  f"/{sim.get('at_rest_newton_mean', math.nan):.2f}")
        print(f"{row['system']:<14}{row['n']:>4} | {fmt(sim.get('unforced_us_per_step')):>9}"
              f"{fmt(sim.get('us_per_step')):>9}{fmt(row.get('forced_overhead')):>7}"
              f"{fmt(sim.get('at_rest_us_per_step')):>9}{fmt(row.get('at_rest_overhead')):>7} | "
              f"{row['casadi']['us_per_step']:>9.2f}{fmt(row.get('step_ratio')):>8} | "
              f"{fmt(row.get('cpu_overhead')):>5}/{fmt(row.get('cpu_at_rest_overhead')):<5} | "
              f"{newton:>16}")


def growth_exponent(ns: list[int], values: list[float]) -> float | None:
    """Slope of the least-squares line through (log n, log value); None below two points."""
    if len(ns) < 2:
        return None
    return float(np.polyfit(np.log(ns), np.log(values), 1)[0])


def targets(rows: list[dict], budget: float) -> list[dict]:
    """The issue's targets, each with the measured value and whether it is met."""
    out = []

    def lib_build(row):
        return row["library"].get("build_seconds")

    def unmet_reason(row):
        status = row["library"]["status"]
        return f"{status} (> {budget:.0f} s)" if status == "timeout" else status

    every = []
    for row in rows:
        b = lib_build(row)
        every.append(b is not None and b <= row["casadi"]["build_seconds"])
    out.append({"target": "build <= CasADi's build at every n", "met": bool(rows) and all(every),
                "value": ", ".join(
                    f"{r['system']} {r['n']}: "
                    + (f"{r['build_ratio']:.2f}x" if "build_ratio" in r else unmet_reason(r))
                    for r in rows)})
    by_key = {(r["system"], r["n"]): r for r in rows}
    for (kind, n), limit in BUILD_TARGETS.items():
        row = by_key.get((kind, n))
        if row is None:
            out.append({"target": f"{kind} n = {n}: build <= {limit:.0f} s", "met": None,
                        "value": "not run"})
            continue
        b = lib_build(row)
        out.append({"target": f"{kind} n = {n}: build <= {limit:.0f} s",
                    "met": b is not None and b <= limit,
                    "value": f"{b:.2f} s" if b is not None else unmet_reason(row)})
    for forced, limit in ((False, STEP_RATIO_TARGET), (True, FORCED_STEP_RATIO_TARGET)):
        mine = [r for r in rows if is_forced(r["system"]) == forced]
        if not mine:
            continue
        steps = [(r, r.get("step_ratio")) for r in mine]
        ran = [(r, s) for r, s in steps if s is not None]
        out.append({"target": f"{'forced ' if forced else ''}step <= {limit}x CasADi's "
                              f"us/step at every n",
                    "met": len(ran) == len(mine) and all(s <= limit for _, s in ran),
                    "value": ", ".join(f"{r['system']} {r['n']}: "
                                       + (f"{s:.2f}x" if s is not None else unmet_reason(r))
                                       for r, s in steps)})
    forced_rows = [r for r in rows if is_forced(r["system"])]
    if forced_rows:
        ratios = [(r, r.get("forced_overhead")) for r in forced_rows]
        out.append({"target": f"forced step <= {FORCED_OVERHEAD_TARGET:.2f}x the unforced "
                              f"chain's at every n",
                    "met": all(x is not None and x <= FORCED_OVERHEAD_TARGET for _, x in ratios),
                    "value": ", ".join(f"{r['system']} {r['n']}: "
                                       + (f"{x:.2f}x" if x is not None else unmet_reason(r))
                                       for r, x in ratios)})
        rest = [(r, r.get("at_rest_overhead")) for r in forced_rows]
        out.append({"target": f"forced step with u = 0, c = 0 (the unforced motion) <= "
                              f"{FORCED_OVERHEAD_TARGET:.2f}x the unforced chain's at every n",
                    "met": all(x is not None and x <= FORCED_OVERHEAD_TARGET for _, x in rest),
                    "value": ", ".join(f"{r['system']} {r['n']}: "
                                       + (f"{x:.2f}x" if x is not None else unmet_reason(r))
                                       for r, x in rest)})
    for kind in SIZES:
        mine = [r for r in rows if r["system"] == kind]
        if mine:
            out += growth_targets(kind, mine)
    return out


def growth_targets(kind: str, rows: list[dict]) -> list[dict]:
    """Growth exponents of build time and C size over the sizes that completed.

    p fits all of them; the tail exponent is the slope between the two largest (fixed costs
    dominate the small sizes, so the tail shows the asymptotic growth and decides the target).
    A size without a result (timeout, skip) fails the target: the fastest growth is missing.
    """
    out = []
    for label, side, get in (
            ("library build", "library", lambda r: r["library"].get("build_seconds")),
            ("library C size (without comments)", "library",
             lambda r: phase(r["library"], "emit", "c_code_bytes")),
            ("CasADi build", "casadi", lambda r: r["casadi"]["build_seconds"]),
            ("CasADi C size", "casadi", lambda r: r["casadi"]["c_bytes"])):
        pts = [(r["n"], get(r)) for r in rows if get(r) is not None]
        lost = [r["n"] for r in rows if get(r) is None]
        ns, values = [a for a, _ in pts], [b for _, b in pts]
        p_all = growth_exponent(ns, values)
        p_tail = growth_exponent(ns[-2:], values[-2:])
        entry = {"target": f"{kind}: {label} grows like n^p, p ~ {GROWTH_TARGET:.0f}",
                 "met": None, "p": p_all, "p_tail": p_tail}
        if p_all is None:
            entry["value"] = "fewer than two sizes"
        else:
            entry["value"] = (f"p = {p_all:.2f} over n = {', '.join(map(str, ns))}; "
                              f"tail p = {p_tail:.2f} (n = {ns[-2]} -> {ns[-1]})")
            if side == "library":
                entry["met"] = not lost and p_tail <= GROWTH_TARGET + GROWTH_SLACK
                if lost:
                    entry["value"] += f"; no result at n = {', '.join(map(str, lost))}"
        out.append(entry)
    return out


def print_targets(items: list[dict]) -> None:
    print("\n=== targets ===")
    for t in items:
        mark = {True: "met", False: "NOT MET", None: "-"}[t["met"]]
        print(f"  [{mark:>7}] {t['target']}: {t['value']}")


# --- main --------------------------------------------------------------------------------------


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--systems", default="planar,3d",
                        help="comma-separated: planar, 3d, planar-forced, 3d-forced "
                             "(default planar,3d)")
    parser.add_argument("--sizes", default=None,
                        help="comma-separated n (default: planar 2..64, 3d 1..8)")
    parser.add_argument("--quick", action="store_true", help="only n <= 4")
    parser.add_argument("--budget", type=float, default=300.0,
                        help="seconds for each library subprocess (default 300)")
    parser.add_argument("--output", type=Path, default=None, help="write the results as JSON")
    parser.add_argument("--report", type=Path, default=None, metavar="JSON",
                        help="print the tables and targets of an earlier --output file")
    parser.add_argument("--repeat", type=int, default=BUILD_REPEATS,
                        help=f"cold builds per side and n; the build ratio compares the "
                             f"medians (default {BUILD_REPEATS}; builds over "
                             f"{REPEAT_LIMIT:.0f} s are not repeated)")
    parser.add_argument("--no-skip", action="store_true",
                        help="run the library at every n even after a timeout")
    parser.add_argument("--worker", nargs=4, metavar=("MODE", "SYSTEM", "N", "CACHE"),
                        help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    kinds = [k.strip() for k in args.systems.split(",") if k.strip()]
    unknown = [k for k in kinds if k not in SIZES]
    if unknown:
        parser.error(f"unknown system(s) {', '.join(unknown)}; choose from "
                     f"{', '.join(SIZES)}")
    args.kinds = kinds
    if args.sizes is not None:
        try:
            args.size_list = [int(s) for s in args.sizes.split(",") if s.strip()]
        except ValueError:
            parser.error(f"--sizes must be comma-separated integers, got {args.sizes!r}")
        if not args.size_list or min(args.size_list) < 1:
            parser.error("--sizes must be positive integers")
    else:
        args.size_list = None
    if not args.budget > 0:
        parser.error("--budget must be positive")
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    return args


def plan(args) -> list[tuple[str, int]]:
    """(kind, n) in order: each chain's sizes, its forced variant's (if listed) alternating
    with them (n, then n forced), so that both see the machine's load alike."""
    out = []
    for base in dict.fromkeys(base_kind(k) for k in args.kinds):
        kinds = [k for k in (base, f"{base}-forced") if k in args.kinds]
        sizes = args.size_list if args.size_list is not None else SIZES[base]
        out += [(kind, n) for n in sizes if not (args.quick and n > 4) for kind in kinds]
    return out


def load_average() -> list[float] | None:
    """1-, 5- and 15-minute load averages (timings on a loaded machine are inflated)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def metadata(args) -> dict:
    import casadi
    import sympy

    import symgroupoid

    return {"python": platform.python_version(), "sympy": sympy.__version__,
            "casadi": casadi.__version__, "symgroupoid": symgroupoid.__version__,
            "machine": platform.machine(), "cpus": os.cpu_count(), "budget_seconds": args.budget,
            "params": PARAMS, "casadi_chunk": CASADI_CHUNK, "load_average": load_average(),
            "date": time.strftime("%Y-%m-%dT%H:%M:%S%z")}


def main(argv=None) -> None:
    args = parse_args(argv)
    if args.worker:
        mode, kind, n, cache = args.worker
        if mode in ("build", "buildonly"):
            library_build(kind, int(n), cache, only=mode == "buildonly")
        else:
            library_check_only(kind, int(n))
        return
    if args.report is not None:
        saved = json.loads(args.report.read_text())
        print(f"results of {args.report} ({saved['meta'].get('date')}, load average "
              f"{saved['meta'].get('load_average')})")
        print_tables(saved["results"])
        print_forced_table(saved["results"])
        print_targets(targets(saved["results"], saved["meta"]["budget_seconds"]))
        return
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    try:
        import casadi  # noqa: F401
    except ImportError:
        raise SystemExit("CasADi is required: pip install '.[bench]'") from None
    meta = metadata(args)
    print(f"scaling benchmark: h = {PARAMS['h']}, g = {PARAMS['g']}; library budget "
          f"{args.budget:.0f} s per subprocess; CasADi {meta['casadi']}, SymPy {meta['sympy']}, "
          f"{meta['cpus']} CPUs, load average {meta['load_average']}", flush=True)
    rows: list[dict] = []
    timed_out: dict[str, int] = {}
    with tempfile.TemporaryDirectory(prefix="sg-scaling-") as tmp:
        for kind, n in plan(args):
            skip = None
            if kind in timed_out and not args.no_skip:
                skip = f"skipped (timeout at n = {timed_out[kind]}; --no-skip runs it)"
            row = run_size(kind, n, args.budget, skip, Path(tmp), args.repeat)
            if row["library"]["status"] == "timeout":
                timed_out.setdefault(kind, n)
            rows.append(row)
            print_row(row)
    meta["load_average_end"] = load_average()
    print_tables(rows)
    print_forced_table(rows)
    print(f"\nload average at the start {meta['load_average']}, at the end "
          f"{meta['load_average_end']} ({meta['cpus']} CPUs): timings on a loaded machine are "
          "inflated; compare ratios from the same run")
    items = targets(rows, args.budget)
    print_targets(items)
    if args.output is not None:
        args.output.write_text(json.dumps({"meta": meta, "results": rows, "targets": items},
                                          indent=1))
        print(f"\nwrote {args.output}")


if __name__ == "__main__":
    main()
