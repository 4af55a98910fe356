"""The library's compiled stepper against MuJoCo on the 3D chain of n rigid bodies, in one
process and one run.

    python benchmarks/mujoco.py [--sizes 8 16 32 64] [--quick] [--rounds R]
                                [--round-seconds S] [--steps N] [--maximal] [--casadi]
                                [--casadi-max N] [--cache-dir DIR] [--output results.json]

The system is ``symgroupoid.systems.spherical_chain(n)`` (n rigid bodies joined by spherical
joints under gravity, body 1 pinned at the origin, unit masses, inertias
``systems.chain_inertia(i)``; h = 0.01, g = 9.81) and the same chain as a MuJoCo model
(``_chain_models.mjcf_chain``: ball joints, no contact, the same masses, inertias and
geometry; MuJoCo's energy computation off, its default) stepped by ``mujoco.rollout`` with
the integrators implicitfast (the one MuJoCo recommends for new models), Euler and RK4,
single-threaded, as is the library's ``simulate``.

Both sides start from the same state: the library from ``scaling.initial_state("3d", n)``
(R_{i,0} = cay(a_i), R_{i,1} = R_{i,0} cay(h ω_i)), MuJoCo from the attitudes R_{i,0} and
the body velocities ξ_i(0), converted to ball-joint coordinates by
``_chain_models.mujoco_state``.  An arrow's velocity ξ_{i,k+1/2} = cay⁻¹(R_{i,k}ᵀR_{i,k+1})/h
(docs/conventions.md §21; for F = cay(x), x = 2 vee(F − Fᵀ)/(1 + tr F)) is the body velocity
at the middle of the step to O(h²), so the first arrow's alone would start MuJoCo half a step
late and the motions would differ by O(h) (measured at n = 4 over 1 s against RK4: 1.9e-2,
9.4e-3, 4.7e-3, 2.4e-3 at h = 0.02, 0.01, 0.005, 0.0025); MuJoCo starts instead from
ξ_i(0) = (3ξ_{i,1/2} − ξ_{i,3/2})/2, the velocity at t = 0 to O(h²) from the library's first
two arrows, and the difference is O(h²) (8.3e-4, 2.1e-4, 5.3e-5, 1.3e-5).

For each n (``--sizes``, default 8 16 32 64; ``--quick``: 4 8 and fewer rounds):

- build: ``step = spherical_chain(n).euler_lagrange()`` and
  ``sim = step.compile(backend="c", cache_dir=...)`` (a fresh cache unless ``--cache-dir``
  names one), both timed and printed; on the 2-core reference machine a 32-body build took
  22 s and a 64-body one 90 s (derivation 23 s, C compiler 67 s);
- check: the first 100 steps of the library and of each MuJoCo integrator, the largest
  attitude difference max_{k,i} ‖R_i^lib(t_k) − R_i^MuJoCo(t_k)‖_F: a sanity check that the
  two simulate the same chain, not a pass/fail (the integrators differ: RK4 is of order 4
  and the library's of order 2, so their difference is O(h²), 2e-4 for four bodies at
  h = 0.01 and larger for longer chains, whose tips move faster (5e-4 at n = 8, 8e-3 at
  n = 64); MuJoCo's Euler and implicitfast are of order 1);
- timing: on a shared machine a long run's time varies by 1.5× between runs, while the
  minimum over many short rounds is stable to a few per cent.  Every round runs the library
  (``sim.simulate(state, N, params)``) and then each MuJoCo integrator
  (``rollout(model, data, start, nstep=N)``) for the same N steps from the same start;
  ``--rounds`` rounds (default 100) alternate the sides, and each side's minimum, divided
  by N, is its µs/step (the median is kept in ``--output``).  N is chosen so that a library
  round lasts about ``--round-seconds`` (default 0.02 s, at least 50 steps), or set with
  ``--steps``; the same rounds time a one-step call of the library and of MuJoCo
  implicitfast (the fixed cost of a call and a first step, the library's from a guess
  without extrapolation: 390 µs and 170 µs for 8 bodies on a loaded machine, 2 % and 1 % of
  a 20 ms round), printed as it goes and kept in ``--output``.  Every round starts from the same
  state, so the rounds time the first N steps of the motion.  A long chain's step can lose
  its nearby root (its tip whips: ``NewtonDivergenceError``): then only the steps before it
  are timed, and the failing step is reported;
- Newton updates per step (their mean over a timed run), and the growth exponent of µs/step
  between successive sizes, p = log(t_b/t_a)/log(n_b/n_a), for the library and for MuJoCo;
- ``--maximal``: also ``systems.spherical_chain_maximal(n)``, the same chain in maximal
  coordinates (each body's attitude and centre of mass, ball-joint constraints; the same
  discrete Lagrangian on the constraint set, so the same trajectory), built beside the
  minimal one, started from the same arrow and timed in the same rounds as the others
  ("maximal"); its largest attitude difference from the minimal chain's first steps (at
  Newton's tolerance) is printed, and the targets are also judged on it (from 16 bodies
  its step is factored in band form and grows like n, docs/notes/performance.md);
- ``--casadi``: CasADi's generated C on the same discrete equations, through
  ``scaling.casadi_side`` (built at -O3 and timed there: the best of five runs of at least
  0.5 s, not in the rounds above), for n ≤ ``--casadi-max`` (default 32: its build at
  n = 64 takes too long); its largest state difference from the library over the first
  100 steps is printed.

The targets: at n = 16 and n = 32 the library's µs/step at most MuJoCo
implicitfast's, at n = 64 at most half of it; each is printed PASS or FAIL (or "not run").
The load average at the start and the end is printed: compare ratios from the same run.
``--output`` writes every number as JSON.  MuJoCo is in the ``bench`` extra
(``pip install '.[bench]'``); without it the script says so and stops.

(This file is named after the package it measures: a script here, or a test that puts
``benchmarks/`` on ``sys.path``, would find it under ``import mujoco``; imported under that
name it hands the import over to MuJoCo's own package, see :func:`_hand_over`.)
"""

from __future__ import annotations


def _hand_over() -> None:
    """Imported as ``mujoco`` (``benchmarks/`` ahead of site-packages on ``sys.path``): load
    MuJoCo's own package in this module's place in ``sys.modules``, which the import then
    returns, or raise the ``ModuleNotFoundError`` of a missing MuJoCo."""
    import importlib.machinery
    import importlib.util
    import os
    import sys

    here = os.path.dirname(os.path.realpath(__file__))
    path = [p for p in sys.path if os.path.realpath(p or os.curdir) != here]
    spec = importlib.machinery.PathFinder.find_spec("mujoco", path)
    if spec is None:
        raise ModuleNotFoundError("No module named 'mujoco'", name="mujoco")
    module = importlib.util.module_from_spec(spec)
    sys.modules["mujoco"] = module
    spec.loader.exec_module(module)


if __name__ == "mujoco":
    _hand_over()

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import os  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

import _chain_models as models  # noqa: E402
import scaling  # noqa: E402

SIZES = (8, 16, 32, 64)
QUICK_SIZES = (4, 8)
INTEGRATORS = ("implicitfast", "Euler", "RK4")
PARAMS = scaling.PARAMS
#: steps of the check against MuJoCo (and CasADi)
COMPARE_STEPS = scaling.COMPARE_STEPS
ROUNDS, QUICK_ROUNDS = 100, 10
#: a library round lasts about this long (seconds) ...
ROUND_SECONDS = 0.02
#: ... within these numbers of steps
MIN_ROUND_STEPS, MAX_ROUND_STEPS = 50, 5000
#: the largest n CasADi is built for unless --casadi-max says otherwise
CASADI_MAX = 32
#: the issue's targets: the library's µs/step at most this times MuJoCo implicitfast's
TARGETS = {16: 1.0, 32: 1.0, 64: 0.5}
TARGET_PEER = "implicitfast"


# --- states ------------------------------------------------------------------------------------


def inverse_cayley(F: np.ndarray) -> np.ndarray:
    """cay⁻¹(F) = 2 vee(F − Fᵀ)/(1 + tr F), the x with cay(x) = F (``scaling.cayley``):
    for cay(x) = I + c(x̂ + x̂²/2), c = 4/(4 + |x|²), F − Fᵀ = 2c x̂ and 1 + tr F = 4c."""
    A = F - F.T
    return 2 * np.array([A[2, 1], A[0, 2], A[1, 0]]) / (1 + np.trace(F))


def attitudes_of(state: np.ndarray, n: int) -> np.ndarray:
    """R_{i,k} (n, 3, 3) of a library state (R_{i,k} row-major for every body, then
    R_{i,k+1})."""
    return np.asarray(state[:9 * n], float).reshape(n, 3, 3)


def body_velocities(state: np.ndarray, n: int, h: float) -> np.ndarray:
    """ξ_i = cay⁻¹(R_{i,0}ᵀR_{i,1})/h of the first arrow, flat (3n,)."""
    R0 = attitudes_of(state, n)
    R1 = np.asarray(state[9 * n:18 * n], float).reshape(n, 3, 3)
    return np.concatenate([inverse_cayley(a.T @ b) / h for a, b in zip(R0, R1)])


def start_velocities(states: np.ndarray, n: int, h: float) -> np.ndarray:
    """ξ_i(0) = (3ξ_{i,1/2} − ξ_{i,3/2})/2 (3n,), the body velocities at t = 0 to O(h²), from
    the library's first two states (each an arrow (R_k, R_{k+1})), by linear extrapolation
    of the arrows' mid-step velocities ξ_{i,k+1/2} = cay⁻¹(R_{i,k}ᵀR_{i,k+1})/h."""
    return 1.5 * body_velocities(states[0], n, h) - 0.5 * body_velocities(states[1], n, h)


def attitudes_from_qpos(qpos: np.ndarray, n: int) -> np.ndarray:
    """R_i = R_{i−1}Q_i (K, n, 3, 3) from the ball joints' quaternions Q_i (w, x, y, z)."""
    from scipy.spatial.transform import Rotation

    qpos = np.atleast_2d(qpos)
    out = np.empty((qpos.shape[0], n, 3, 3))
    parent = np.broadcast_to(np.eye(3), out[:, 0].shape)
    for i in range(n):
        Q = Rotation.from_quat(qpos[:, 4 * i:4 * i + 4][:, [1, 2, 3, 0]]).as_matrix()
        parent = out[:, i] = parent @ Q
    return out


def attitude_difference(a: np.ndarray, b: np.ndarray) -> float:
    """max over steps and bodies of ‖a − b‖_F, for (K, n, 3, 3) arrays."""
    return float(np.sqrt(((a - b) ** 2).sum(axis=(-2, -1))).max())


# --- MuJoCo ------------------------------------------------------------------------------------


def mujoco_module():
    """MuJoCo's package with its rollout module, or None when it is not installed."""
    try:
        import mujoco
        import mujoco.rollout  # noqa: F401
    except ImportError:
        return None
    return mujoco


class MujocoChain:
    """The chain as a MuJoCo model with one integrator, at (R_{i,0}, ξ_i); ``run(N)`` rolls
    N steps out from there (``mujoco.rollout``, one thread) and returns the N states after
    the start (MuJoCo's full physics state: time, qpos, qvel, …)."""

    def __init__(self, mujoco, n: int, integrator: str, attitudes, xi: np.ndarray):
        self.n, self.integrator = n, integrator
        xml = models.mjcf_chain(n, PARAMS["h"], PARAMS["g"], integrator=integrator)
        self.model = mujoco.MjModel.from_xml_string(xml)
        self.model.opt.enableflags &= ~int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        self.data = mujoco.MjData(self.model)
        self.data.qpos[:], self.data.qvel[:] = models.mujoco_state(attitudes, xi)
        spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.start = np.empty(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, self.start, spec)
        self._rollout = mujoco.rollout.rollout

    def run(self, steps: int) -> np.ndarray:
        return self._rollout(self.model, self.data, self.start[None, :], nstep=steps)[0][0]

    def attitudes(self, states: np.ndarray) -> np.ndarray:
        return attitudes_from_qpos(states[:, 1:1 + self.model.nq], self.n)


# --- the library -------------------------------------------------------------------------------


def build_library(n: int, cache_dir: Path, maximal: bool = False):
    """(step, simulator, derive seconds, compile seconds) of ``spherical_chain(n)``, or of
    ``spherical_chain_maximal(n)``."""
    from symgroupoid.systems import spherical_chain, spherical_chain_maximal

    t0 = time.perf_counter()
    step = (spherical_chain_maximal if maximal else spherical_chain)(n).euler_lagrange()
    t1 = time.perf_counter()
    sim = step.compile(backend="c", cache_dir=str(cache_dir))
    return step, sim, t1 - t0, time.perf_counter() - t1


def maximal_state(state: np.ndarray, n: int) -> dict:
    """The maximal chain's named start from the minimal chain's flat one: every body's
    attitudes (R_{i,0}, R_{i,1}) and the centres of mass they put it at."""
    link, centre = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, -0.5])
    before, after = attitudes_of(state, n), attitudes_of(state[9 * n:], n)
    named: dict = {}
    for which, attitudes in enumerate((before, after)):
        joint = np.zeros(3)
        for i, R in enumerate(attitudes):
            c = joint + R @ centre
            joint = joint + R @ link
            for a, axis in enumerate("xyz"):
                named.setdefault(f"{axis}{i + 1}", [0.0, 0.0])[which] = float(c[a])
            named.setdefault(f"R{i + 1}", [None, None])[which] = R
    return {k: tuple(v) for k, v in named.items()}


def maximal_attitudes(states: np.ndarray, n: int) -> np.ndarray:
    """Every state's source attitudes, as :func:`attitudes_of` (body i's 24 entries: the
    arrow's R_i at its source and its target, then c_i at both)."""
    return np.array([[s[24 * i:24 * i + 9].reshape(3, 3) for i in range(n)]
                     for s in states])


def solvable_run(sim, state: np.ndarray, steps: int):
    """(trajectory, steps done, failing step or None): ``simulate`` over ``steps``, or over
    the steps before the first one without a nearby root (``NewtonDivergenceError``)."""
    from symgroupoid import NewtonDivergenceError

    try:
        return sim.simulate(state, steps, PARAMS), steps, None
    except NewtonDivergenceError as exc:
        done = len(exc.trajectory.states) - 1
        if done == 0:
            return None, 0, exc.step
        return sim.simulate(state, done, PARAMS), done, exc.step


def round_steps(seconds_per_step: float, limit: int, fixed: int | None,
                target: float = ROUND_SECONDS) -> int:
    """Steps per round: ``fixed`` if given, else about ``target`` seconds of the library's
    stepping, between MIN_ROUND_STEPS and MAX_ROUND_STEPS; never more than ``limit`` (the
    steps the library can take from the start)."""
    if fixed is None:
        fixed = math.ceil(target / max(seconds_per_step, 1e-9))
        fixed = min(MAX_ROUND_STEPS, max(MIN_ROUND_STEPS, fixed))
    return max(1, min(fixed, limit))


# --- one size ----------------------------------------------------------------------------------


def time_rounds(runs: dict, rounds: int) -> dict[str, list[float]]:
    """Wall seconds of every run in every round, the runs alternating within a round."""
    times: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(rounds):
        for name, go in runs.items():
            t0 = time.perf_counter()
            go()
            times[name].append(time.perf_counter() - t0)
    return times


def run_size(n: int, mujoco, args, cache_root: Path, tmp: Path) -> dict:
    """Build (kernel cache under ``cache_root``), check and time one n (CasADi's files
    under ``tmp``); the row of the table, also printed as it goes."""
    row: dict = {"n": n}
    slow = " (a kernel this large takes a minute or more)" if n >= 48 else ""
    print(f"\nn = {n}: deriving and compiling the library's kernel{slow} ...", flush=True)
    step, sim, derive_s, compile_s = build_library(n, cache_root / f"chain-{n}")
    row.update(derive_seconds=derive_s, compile_seconds=compile_s,
               build_seconds=derive_s + compile_s, unknowns=len(step.unknowns))
    print(f"  build {derive_s + compile_s:.1f} s (derive {derive_s:.1f} s, compile "
          f"{compile_s:.1f} s); {len(step.unknowns)} unknowns", flush=True)
    state = scaling.initial_state("3d", n)
    first, checked, failed = solvable_run(sim, state, COMPARE_STEPS)
    if first is None:
        row["error"] = f"the library's first step has no nearby root (step {failed})"
        print(f"  {row['error']}")
        return row
    steps = round_steps(warm_seconds_per_step(sim, state, checked),
                        checked if failed is not None else MAX_ROUND_STEPS, args.steps,
                        args.round_seconds)
    lib_run, steps, failed_round = solvable_run(sim, state, steps)
    row.update(steps=steps, unsolvable_step=failed if failed is not None else failed_round,
               newton_mean=float(np.mean(lib_run.newton_iterations)),
               newton_max=int(np.max(lib_run.newton_iterations)))
    chains = {name: MujocoChain(mujoco, n, name, list(attitudes_of(state, n)),
                                start_velocities(first.states, n, PARAMS["h"]))
              for name in INTEGRATORS}
    row.update(check(first, checked, chains, n))
    extra = {}
    if args.maximal:
        extra["maximal"] = maximal_side(n, first, checked, steps, state, cache_root, row)
    row.update(timings(sim, state, steps, chains, args.rounds, extra))
    if args.casadi and n <= args.casadi_max:
        row["casadi"] = casadi_row(n, first, tmp)
    print_progress(row)
    return row


def maximal_side(n: int, first, checked: int, steps: int, state: np.ndarray,
                 cache_root: Path, row: dict):
    """Build ``spherical_chain_maximal(n)``, check it against the minimal chain's first
    ``checked`` steps (recorded in ``row``) and return its timed run of ``steps`` steps."""
    step, sim, derive_s, compile_s = build_library(n, cache_root / f"maximal-{n}", True)
    start = sim.state(maximal_state(state, n), PARAMS)
    run = sim.simulate(start, max(checked, steps), PARAMS)
    lib_R = np.array([attitudes_of(s, n) for s in first.states[1:checked + 1]])
    row["maximal"] = {
        "build_seconds": derive_s + compile_s, "unknowns": len(step.unknowns),
        "newton_mean": float(np.mean(run.newton_iterations[:steps])),
        "difference": attitude_difference(maximal_attitudes(run.states[1:checked + 1], n),
                                          lib_R)}
    print(f"  maximal coordinates: build {derive_s + compile_s:.1f} s, "
          f"{len(step.unknowns)} unknowns, largest attitude difference from the minimal "
          f"chain {row['maximal']['difference']:.1e}", flush=True)
    return lambda: sim.simulate(start, steps, PARAMS)


def warm_seconds_per_step(sim, state: np.ndarray, steps: int) -> float:
    """Seconds per step of the fastest of three further runs of ``steps`` (the first call
    of a simulator pays one-time costs)."""
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        sim.simulate(state, steps, PARAMS)
        best = min(best, time.perf_counter() - t0)
    return best / steps


def check(first, checked: int, chains: dict, n: int) -> dict:
    """The largest attitude difference between the library's first ``checked`` steps and
    each MuJoCo integrator's."""
    lib_R = np.array([attitudes_of(s, n) for s in first.states[1:checked + 1]])
    return {"check_steps": checked,
            "difference": {name: attitude_difference(chain.attitudes(chain.run(checked)),
                                                     lib_R)
                           for name, chain in chains.items()}}


def timings(sim, state: np.ndarray, steps: int, chains: dict, rounds: int,
            extra: dict | None = None) -> dict:
    """µs/step of every side (the minimum over the rounds, and the median), the library's
    ratios to MuJoCo's, and the time of a one-step call of the library and of MuJoCo
    implicitfast (the fixed cost of a call and a first step), timed in the same rounds;
    ``extra`` runs (the maximal chain) in the same rounds, with their ratio to MuJoCo
    implicitfast."""
    runs = {"library": lambda: sim.simulate(state, steps, PARAMS), **(extra or {})}
    runs.update({name: (lambda c=chain: c.run(steps)) for name, chain in chains.items()})
    calls = {"library": lambda: sim.simulate(state, 1, PARAMS),
             TARGET_PEER: lambda: chains[TARGET_PEER].run(1)}
    times = time_rounds({**runs, **{f"{k} call": go for k, go in calls.items()}}, rounds)
    us = {k: min(times[k]) / steps * 1e6 for k in runs}
    return {"rounds": rounds, "us_per_step": us,
            "median_us_per_step": {k: float(np.median(times[k])) / steps * 1e6 for k in runs},
            "one_step_call_us": {k: min(times[f"{k} call"]) * 1e6 for k in calls},
            "ratio": {name: us["library"] / us[name] for name in INTEGRATORS},
            "extra_ratio": {k: us[k] / us[TARGET_PEER] for k in extra or {}}}


def casadi_row(n: int, first, tmp: Path) -> dict:
    """CasADi's µs/step and build time (``scaling.casadi_side``), and its largest state
    difference from the library's over the first steps."""
    try:
        import casadi  # noqa: F401
    except ImportError:
        return {"status": "not installed"}
    print(f"  CasADi: building and timing n = {n} ...", flush=True)
    cas = scaling.casadi_side("3d", n, tmp / f"casadi-{n}")
    cas.pop("model")
    states = np.asarray(cas.pop("states"))
    k = min(len(states), len(first.states))
    return {"status": "ok", "us_per_step": cas["us_per_step"],
            "build_seconds": cas["build_seconds"], "steps": cas["steps"],
            "state_difference": float(np.abs(states[:k] - first.states[:k]).max())}


# --- printing ----------------------------------------------------------------------------------


def fmt_us(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.2f}" if value < 10 else f"{value:.1f}" if value < 1000 else f"{value:.0f}"


def fmt(value, spec: str = ".2f") -> str:
    return "-" if value is None else format(value, spec)


def print_progress(row: dict) -> None:
    us = row["us_per_step"]
    fail = ("" if row["unsolvable_step"] is None else
            f"; the library's step {row['unsolvable_step']} has no nearby root: "
            f"{row['steps']} steps timed")
    print(f"  {row['rounds']} rounds of {row['steps']} steps{fail}; Newton "
          f"{row['newton_mean']:.2f} updates/step; us/step: library {fmt_us(us['library'])}, "
          + ", ".join(f"{k} {fmt_us(us[k])}" for k in INTEGRATORS)
          + "; a one-step call: " + ", ".join(f"{k} {fmt_us(v)} us" for k, v in
                                             row["one_step_call_us"].items()), flush=True)
    if "maximal" in us:
        print(f"  maximal coordinates: {fmt_us(us['maximal'])} us/step, "
              f"{row['extra_ratio']['maximal']:.2f} x MuJoCo {TARGET_PEER}'s", flush=True)


def add_growth(rows: list[dict]) -> None:
    """p between each size and the previous one (successive sizes), per side."""
    timed = [r for r in rows if "us_per_step" in r]
    for a, b in zip(timed, timed[1:]):
        b["growth"] = {side: scaling.growth_exponent([a["n"], b["n"]],
                                                     [a["us_per_step"][side],
                                                      b["us_per_step"][side]])
                       for side in ("library", *INTEGRATORS)}


HEADER = (f"{'n':>3} {'build s':>8} {'Newton':>6} {'steps':>5} | {'library':>8} "
          f"{'implfast':>8} {'Euler':>8} {'RK4':>8} {'CasADi':>8} | {'x impl':>6} "
          f"{'x Euler':>7} {'x RK4':>6} | {'p lib':>5} {'p impl':>6} | {'dR RK4':>7} "
          f"{'dR impl':>7}")


def print_table(rows: list[dict]) -> None:
    print("\n=== the 3D chain of n bodies, h = 0.01: us/step (minimum over the rounds); "
          "x = library / MuJoCo; p = growth exponent of us/step from the previous n; "
          "dR = max attitude difference from the library over the first "
          f"{COMPARE_STEPS} steps; CasADi timed apart (scaling.py's runs) ===")
    print(HEADER)
    for row in rows:
        if "us_per_step" not in row:
            print(f"{row['n']:>3} {row['build_seconds']:>8.1f}  {row.get('error', '')}")
            continue
        us, x = row["us_per_step"], row["ratio"]
        growth, diff = row.get("growth", {}), row["difference"]
        cas = row.get("casadi", {})
        print(f"{row['n']:>3} {row['build_seconds']:>8.1f} {row['newton_mean']:>6.2f} "
              f"{row['steps']:>5} | {fmt_us(us['library']):>8} {fmt_us(us['implicitfast']):>8} "
              f"{fmt_us(us['Euler']):>8} {fmt_us(us['RK4']):>8} "
              f"{fmt_us(cas.get('us_per_step')):>8} | {x['implicitfast']:>6.2f} "
              f"{x['Euler']:>7.2f} {x['RK4']:>6.2f} | {fmt(growth.get('library')):>5} "
              f"{fmt(growth.get('implicitfast')):>6} | {diff['RK4']:>7.1e} "
              f"{diff['implicitfast']:>7.1e}")
    failed = [r for r in rows if r.get("unsolvable_step") is not None]
    for row in failed:
        print(f"  n = {row['n']}: the library's step {row['unsolvable_step']} from the start "
              f"has no nearby root; the rounds time the {row['steps']} steps before it")
    for row in rows:
        cas = row.get("casadi")
        if cas and cas["status"] == "ok":
            print(f"  CasADi n = {row['n']}: build {cas['build_seconds']:.1f} s, "
                  f"{fmt_us(cas['us_per_step'])} us/step (library / CasADi "
                  f"{row['us_per_step']['library'] / cas['us_per_step']:.2f}), max state "
                  f"difference from the library over the first {COMPARE_STEPS} steps "
                  f"{cas['state_difference']:.1e}")
        elif cas:
            print(f"  CasADi n = {row['n']}: {cas['status']}")


def targets(rows: list[dict], side: str = "library") -> list[dict]:
    """The issue's targets: at each n of TARGETS, µs/step of ``side`` (the library's minimal
    chain, or ``"maximal"``) ≤ factor × implicitfast's."""
    by_n = {r["n"]: r for r in rows}
    out = []
    label = "library" if side == "library" else f"library ({side} coordinates)"
    for n, factor in TARGETS.items():
        name = (f"n = {n}: {label} us/step <= "
                f"{'' if factor == 1 else f'{factor:g} x '}MuJoCo {TARGET_PEER}'s")
        row = by_n.get(n)
        if row is None or side not in row.get("us_per_step", {}):
            out.append({"target": name, "met": None,
                        "value": "not run" if row is None else row.get("error", "no timing")})
            continue
        lib, peer = row["us_per_step"][side], row["us_per_step"][TARGET_PEER]
        out.append({"target": name, "met": lib <= factor * peer,
                    "value": f"{fmt_us(lib)} vs {fmt_us(peer)} us (ratio {lib / peer:.2f})"})
    return out


def print_targets(items: list[dict]) -> None:
    print("\n=== targets ===")
    for t in items:
        mark = {True: "PASS", False: "FAIL", None: "-"}[t["met"]]
        print(f"  [{mark:>4}] {t['target']}: {t['value']}")


# --- main --------------------------------------------------------------------------------------


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=None,
                        help=f"numbers of bodies (default {' '.join(map(str, SIZES))}; "
                             f"--quick: {' '.join(map(str, QUICK_SIZES))})")
    parser.add_argument("--quick", action="store_true",
                        help=f"n = {', '.join(map(str, QUICK_SIZES))} (unless --sizes) and "
                             f"{QUICK_ROUNDS} rounds (unless --rounds): a smoke test")
    parser.add_argument("--rounds", type=int, default=None,
                        help=f"timing rounds per n (default {ROUNDS})")
    parser.add_argument("--round-seconds", type=float, default=ROUND_SECONDS,
                        help=f"about how long a library round lasts (default {ROUND_SECONDS})")
    parser.add_argument("--steps", type=int, default=None,
                        help="steps per round (default: from --round-seconds)")
    parser.add_argument("--maximal", action="store_true",
                        help="also the chain in maximal coordinates "
                             "(systems.spherical_chain_maximal), in the same rounds")
    parser.add_argument("--casadi", action="store_true",
                        help="also CasADi's generated C (scaling.casadi_side)")
    parser.add_argument("--casadi-max", type=int, default=CASADI_MAX,
                        help=f"largest n built with CasADi (default {CASADI_MAX})")
    parser.add_argument("--cache-dir", type=Path, default=None,
                        help="the library's kernel cache (default: a fresh temporary one)")
    parser.add_argument("--output", type=Path, default=None, help="write the results as JSON")
    args = parser.parse_args(argv)
    if args.sizes is None:
        args.sizes = list(QUICK_SIZES if args.quick else SIZES)
    if min(args.sizes) < 1:
        parser.error("--sizes must be positive integers")
    if args.rounds is None:
        args.rounds = QUICK_ROUNDS if args.quick else ROUNDS
    if args.rounds < 1:
        parser.error("--rounds must be at least 1")
    if args.steps is not None and args.steps < 1:
        parser.error("--steps must be at least 1")
    if not args.round_seconds > 0:
        parser.error("--round-seconds must be positive")
    return args


def metadata(mujoco, args) -> dict:
    import sympy

    import symgroupoid

    return {"python": platform.python_version(), "mujoco": mujoco.__version__,
            "sympy": sympy.__version__, "symgroupoid": symgroupoid.__version__,
            "machine": platform.machine(), "cpus": os.cpu_count(), "params": PARAMS,
            "rounds": args.rounds, "round_seconds": args.round_seconds,
            "load_average": scaling.load_average(), "date": time.strftime("%Y-%m-%dT%H:%M:%S%z")}


def main(argv=None) -> list[dict]:
    args = parse_args(argv)
    mujoco = mujoco_module()
    if mujoco is None:
        raise SystemExit("MuJoCo is not installed: pip install '.[bench]' (or pip install "
                         "mujoco) to run this benchmark")
    meta = metadata(mujoco, args)
    print(f"the library against MuJoCo {meta['mujoco']} on spherical_chain(n): h = "
          f"{PARAMS['h']}, g = {PARAMS['g']}; {args.rounds} rounds per n; {meta['cpus']} CPUs, "
          f"load average {meta['load_average']}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="sg-mujoco-") as tmp:
        cache_root = args.cache_dir if args.cache_dir is not None else Path(tmp)
        for n in args.sizes:
            rows.append(run_size(n, mujoco, args, cache_root, Path(tmp)))
    add_growth(rows)
    meta["load_average_end"] = scaling.load_average()
    print_table(rows)
    print(f"\nload average at the start {meta['load_average']}, at the end "
          f"{meta['load_average_end']} ({meta['cpus']} CPUs): compare ratios from the same run")
    items = targets(rows) + (targets(rows, "maximal") if args.maximal else [])
    print_targets(items)
    if args.output is not None:
        args.output.write_text(json.dumps({"meta": meta, "results": rows, "targets": items},
                                          indent=1))
        print(f"\nwrote {args.output}")
    return rows


if __name__ == "__main__":
    main()
