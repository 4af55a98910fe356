"""Work–precision of the library's variational integrators on the 3D three-body pendulum,
against MuJoCo's RK4 and scipy's DOP853 on the same continuous equations.

    python benchmarks/work_precision.py [--quick] [--figure PATH] [--output results.json]

The system is ``systems.spherical_chain(3)``'s physics written as a continuous Lagrangian on
SO(3)³ (``benchmarks/_chain_models.py``: unit masses, inertias ``chain_inertia(i)``,
ℓ = (0, 0, −1), ρ = (0, 0, −½), g = 9.81, body 1 pinned at the origin), from one initial
configuration and body velocity (R₀, ξ₀), over T = 2 s.  In one run, peers in the same run:

- the reference: scipy's DOP853 at rtol = atol = 1e-12 on the Euler–Poincaré equations of
  the same L, derived symbolically in ``_chain_models.ChainODE`` independently of the
  library; checked: its energy is conserved to 1e-10 over T, its difference from a run at
  1e-13 is printed (the reference's own error), and for one body with ρ = 0 the derived
  equations are Euler's J ξ̇ = Jξ × ξ;
- the library's schemes (``SCHEMES``: ``"midpoint"``, ``"trapezoid"`` and the Galerkin
  members of order 4 and 6), each built once (derivation + compile into a fresh cache; the
  build time is printed) and run over a range of h from the same (R₀, ξ₀): the first arrow
  (R₀, R₁) is ``Simulator.from_velocity``'s, the discrete Legendre transform
  F⁻L_d(R₀, R₁) = p₀ solved for p₀ = ∂L/∂ξ(R₀, ξ₀);
- MuJoCo's RK4 (the chain as an MJCF model with ball joints and no contact, run by
  ``mujoco.rollout``) over a range of h; "not installed" without mujoco;
- scipy's DOP853 at several tolerances on the reference's equations (Python right-hand
  side, so its wall time is mostly Python's).

Error: the final-time attitude error max_i ‖R_i(T) − R_i^ref(T)‖_F.  Work: wall time of the
run (initial-state solves and builds excluded), per simulated second; a run shorter than
0.2 s is repeated and the best time kept.  The midpoint scheme's observed order against the
reference (≈ 2) and MuJoCo's convergence to the reference's final attitudes (order ≈ 4) are
printed: they show that the three sides integrate the same equations.

Targets of the benchmark: (1) at every error level 1e-4, 1e-5, …, 1e-10 the wall time the
library's best scheme needs (log–log interpolation along its points) against RK4's; (2) at
the h where each reaches an error of 1e-6, over 10⁵ steps (10⁴ with ``--quick``), the drift
of the energy (the library: its discrete energy E_d = −∂L_d/∂h; RK4: the continuous energy
of its states; with ``--quick`` at an error of 1e-4) and of the angular momentum about
the vertical (conserved: gravity is
vertical; the library: the Noether momentum of rotations about e₃, from its spatial momenta);
(3) build time and step cost of the order-4 scheme over the midpoint's, when it exists.
``--figure`` saves the log–log work–precision figure (matplotlib).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

import _chain_models as models  # noqa: E402
import sympy as sp  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

import symgroupoid as sg  # noqa: E402

N_BODIES = 3
T_FINAL = 2.0
GRAVITY = models.GRAVITY
#: the initial attitudes (rotation vectors) and body velocities
ROTATION_VECTORS = ([0.6, 0.2, 0.0], [0.9, -0.4, 0.2], [-0.3, 1.0, 0.5])
BODY_VELOCITIES = [0.5, -0.3, 0.8, 1.0, 0.4, -0.6, -0.7, 0.9, 0.2]
REFERENCE_TOLERANCE = 1e-12
#: the library's schemes: (label, scheme, theoretical order)
SCHEMES = (("midpoint", "midpoint", 2), ("trapezoid", "trapezoid", 2),
           ("GaussLegendre(2)", sg.GaussLegendre(2), 4),
           ("GaussLegendre(3)", sg.GaussLegendre(3), 6),
           ("LobattoIIIAB(3)", sg.LobattoIIIAB(3), 4))
STEPS = {2: (25, 50, 100, 200, 400, 800, 1600, 3200, 6400, 12800, 25600, 51200, 102400,
             204800, 409600, 819200),
         4: (25, 50, 100, 200, 400, 800, 1600, 3200, 6400),
         6: (25, 50, 100, 200, 400, 800, 1600)}
QUICK_STEPS = (25, 50, 100, 200, 400, 800)
MUJOCO_STEPS = (50, 100, 200, 400, 800, 1600, 3200, 6400, 12800)
QUICK_MUJOCO_STEPS = (50, 100, 200, 400)
DOP853_TOLERANCES = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
QUICK_DOP853_TOLERANCES = (1e-4, 1e-6)
LEVELS = tuple(10.0 ** -k for k in range(4, 11))
DRIFT_ERROR, QUICK_DRIFT_ERROR = 1e-6, 1e-4
DRIFT_STEPS, QUICK_DRIFT_STEPS = 100_000, 10_000
MIN_TIMED = 0.2


@dataclass
class Point:
    method: str
    setting: str  # h or the tolerance
    steps: int
    error: float
    seconds: float  # wall time of the run
    per_second: float  # wall time per simulated second
    cpu_per_second: float  # CPU time of the process per simulated second
    newton: float | None = None  # mean Newton iterations per step (the library)


@dataclass
class Results:
    machine: str
    date: str
    reference: dict = field(default_factory=dict)
    points: list = field(default_factory=list)
    status: dict = field(default_factory=dict)  # method -> "ok" / "not implemented" / …
    builds: dict = field(default_factory=dict)  # scheme -> build seconds
    orders: dict = field(default_factory=dict)
    levels: list = field(default_factory=list)
    drift: dict = field(default_factory=dict)
    ratios: dict = field(default_factory=dict)
    drift_error: float = DRIFT_ERROR


def initial_data():
    attitudes = [Rotation.from_rotvec(v).as_matrix() for v in ROTATION_VECTORS]
    return attitudes, np.array(BODY_VELOCITIES, float)


def best_time(run, minimum: float = MIN_TIMED):
    """(result, wall seconds, CPU seconds of this process): the best of repeated calls until
    ``minimum`` seconds are spent."""
    spent, best, cpu, out = 0.0, math.inf, math.inf, None
    while spent < minimum or out is None:
        start, start_cpu = time.perf_counter(), time.process_time()
        out = run()
        took = time.perf_counter() - start
        best, spent = min(best, took), spent + took
        cpu = min(cpu, time.process_time() - start_cpu)
        if took > minimum:
            break
    return out, best, cpu


def attitude_error(R: np.ndarray, ref: np.ndarray) -> float:
    return float(max(np.linalg.norm(a - b) for a, b in zip(R, ref)))


# --- the reference ---------------------------------------------------------------------------

def check_rigid_body() -> bool:
    """The derived Euler–Poincaré equations of one body with ρ = 0 are Euler's."""
    R, xi = models._symbols(1)
    J = sp.diag(*sp.symbols("J1:4", positive=True))
    L = models.chain_lagrangian(R, xi, [J], sp.Symbol("g"), centre=(0, 0, 0))
    M, rhs = models.euler_poincare(R, xi, L)
    w = xi[0]
    return sp.simplify(M.solve(rhs) - J.inv() * (J * w).cross(w)) == sp.zeros(3, 1)


def reference(results: Results):
    start = time.perf_counter()
    ode = models.ChainODE.build(N_BODIES, GRAVITY)
    derive = time.perf_counter() - start
    attitudes, xi0 = initial_data()
    y0 = ode.state(attitudes, xi0)
    runs = {}
    for tol in (REFERENCE_TOLERANCE, REFERENCE_TOLERANCE / 10):
        sol = solve_ivp(ode.rhs, (0, T_FINAL), y0, method="DOP853", rtol=tol, atol=tol)
        runs[tol] = sol.y[:, -1]
    yT = runs[REFERENCE_TOLERANCE]
    energy_change = abs(ode.energy(yT) - ode.energy(y0))
    results.reference = {
        "derivation_seconds": derive,
        "energy": ode.energy(y0),
        "energy_change": energy_change,
        "momentum_change": abs(ode.vertical_momentum(yT) - ode.vertical_momentum(y0)),
        "against_1e-13": attitude_error(ode.attitudes(yT),
                                        ode.attitudes(runs[REFERENCE_TOLERANCE / 10])),
        "rigid_body_check": check_rigid_body()}
    print(f"reference: DOP853 at {REFERENCE_TOLERANCE:g}, E = {ode.energy(y0):.6f}, "
          f"|ΔE| over T = {energy_change:.1e} "
          f"({'ok' if energy_change <= 1e-10 else 'FAILS 1e-10'}), |ΔJ₃| = "
          f"{results.reference['momentum_change']:.1e}, difference from 1e-13: "
          f"{results.reference['against_1e-13']:.1e}; one body with ρ = 0 gives Euler's "
          f"equations: {results.reference['rigid_body_check']}")
    return ode, ode.attitudes(yT)


# --- the library -------------------------------------------------------------------------------

def build_scheme(scheme):
    """(simulator, build seconds): derivation and compile into a fresh cache."""
    start = time.perf_counter()
    step = models.continuous_chain(N_BODIES).discretize("h", scheme).euler_lagrange()
    with tempfile.TemporaryDirectory() as cache:
        sim = step.compile(cache_dir=cache)
    return sim, time.perf_counter() - start


def first_arrow(sim, h: float) -> np.ndarray:
    """The state (R₀, R₁) with F⁻L_d(R₀, R₁) = ∂L/∂ξ(R₀, ξ₀) (``from_velocity``)."""
    attitudes, xi0 = initial_data()
    configuration = {f"R{i}": R for i, R in enumerate(attitudes, start=1)}
    return sim.from_velocity(configuration, np.ravel(xi0), {"h": h, "g": GRAVITY})


def run_library(sim, state: np.ndarray, steps: int, h: float):
    return sim.simulate(state, steps, {"h": h, "g": GRAVITY}, every=steps)


def library_points(results: Results, ref: np.ndarray, quick: bool):
    sims = {}
    for label, scheme, order in SCHEMES:
        try:
            sim, built = build_scheme(scheme)
        except sg.UnsupportedFeatureError:
            results.status[label] = "not implemented"
            print(f"{label}: not implemented")
            continue
        results.status[label] = "ok"
        results.builds[label] = built
        sims[label] = (sim, order)
        print(f"{label}: built in {built:.2f} s")
        for n in (QUICK_STEPS if quick else STEPS[order]):
            h = T_FINAL / n
            state = first_arrow(sim, h)
            traj, took, cpu = best_time(lambda m=sim, s=state, n=n, h=h:
                                        run_library(m, s, n, h))
            R = traj.states[-1][:9 * N_BODIES].reshape(N_BODIES, 3, 3)
            newton = float(traj.newton_iterations.sum() / n)
            point = Point(label, f"h={h:.3g}", n, attitude_error(R, ref), took,
                          took / T_FINAL, cpu / T_FINAL, newton)
            results.points.append(point)
            print(f"  N = {n:7d}  error {point.error:.3e}  {point.per_second:.3e} s/s")
            if past_floor(results.points, label):
                print(f"  (the error grew: {label} is at its rounding floor)")
                break
    return sims


# --- MuJoCo ------------------------------------------------------------------------------------

def mujoco_module():
    try:
        import mujoco
        import mujoco.rollout  # noqa: F401
    except ImportError:
        return None
    return mujoco


def mujoco_run(mujoco, h: float, steps: int):
    """(model, data, initial full-physics state, rollout callable) at step h."""
    model = mujoco.MjModel.from_xml_string(models.mjcf_chain(N_BODIES, h, GRAVITY))
    data = mujoco.MjData(model)
    attitudes, xi0 = initial_data()
    data.qpos[:], data.qvel[:] = models.mujoco_state(attitudes, xi0)
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    start = np.empty(mujoco.mj_stateSize(model, spec))
    mujoco.mj_getState(model, data, start, spec)

    def run():
        return mujoco.rollout.rollout(model, data, start[None, :], nstep=steps)[0][0]

    return model, data, run


def mujoco_qpos_qvel(model, states: np.ndarray):
    """qpos, qvel of rollout states (full physics: time, qpos, qvel, …)."""
    states = np.atleast_2d(states)
    return states[:, 1:1 + model.nq], states[:, 1 + model.nq:1 + model.nq + model.nv]


def attitudes_from_qpos(qpos: np.ndarray) -> np.ndarray:
    """R_i = R_{i−1}Q_i from the ball joints' quaternions, (K, n, 3, 3)."""
    K = qpos.shape[0]
    out = np.empty((K, N_BODIES, 3, 3))
    parent = np.broadcast_to(np.eye(3), (K, 3, 3))
    for i in range(N_BODIES):
        wxyz = qpos[:, 4 * i:4 * i + 4]
        Q = Rotation.from_quat(wxyz[:, [1, 2, 3, 0]]).as_matrix()  # scipy: (x, y, z, w)
        parent = out[:, i] = parent @ Q
    return out


def chain_states(qpos: np.ndarray, qvel: np.ndarray) -> np.ndarray:
    """The ODE states y = (R, ξ) of MuJoCo states, (36, K) (vectorised)."""
    R = attitudes_from_qpos(qpos)
    xi, parent_xi = [], np.zeros((qpos.shape[0], 3))
    for i in range(N_BODIES):
        Q = R[:, i] if i == 0 else np.einsum("kba,kbc->kac", R[:, i - 1], R[:, i])
        w = np.einsum("kba,kb->ka", Q, parent_xi) + qvel[:, 3 * i:3 * i + 3]
        xi.append(w)
        parent_xi = w
    return np.concatenate([R.reshape(-1, 9 * N_BODIES), *xi], axis=1).T


def mujoco_points(results: Results, ref: np.ndarray, quick: bool, mujoco):
    if mujoco is None:
        results.status["MuJoCo RK4"] = "not installed"
        print("MuJoCo RK4: not installed (pip install mujoco)")
        return
    results.status["MuJoCo RK4"] = f"ok (mujoco {mujoco.__version__})"
    for n in (QUICK_MUJOCO_STEPS if quick else MUJOCO_STEPS):
        h = T_FINAL / n
        model, _, run = mujoco_run(mujoco, h, n)
        states, took, cpu = best_time(run)
        qpos, _ = mujoco_qpos_qvel(model, states[-1])
        error = attitude_error(attitudes_from_qpos(qpos)[0], ref)
        results.points.append(Point("MuJoCo RK4", f"h={h:.3g}", n, error, took, took / T_FINAL,
                                    cpu / T_FINAL))
        print(f"  MuJoCo RK4 N = {n:6d}  error {error:.3e}  {took / T_FINAL:.3e} s/s")


# --- DOP853 --------------------------------------------------------------------------------------

def dop853_points(results: Results, ode, ref: np.ndarray, quick: bool):
    attitudes, xi0 = initial_data()
    y0 = ode.state(attitudes, xi0)
    for tol in (QUICK_DOP853_TOLERANCES if quick else DOP853_TOLERANCES):
        sol, took, cpu = best_time(lambda tol=tol: solve_ivp(ode.rhs, (0, T_FINAL), y0,
                                                       method="DOP853", rtol=tol, atol=tol))
        error = attitude_error(ode.attitudes(sol.y[:, -1]), ref)
        results.points.append(Point("DOP853", f"tol={tol:g}", int(sol.nfev), error, took,
                                    took / T_FINAL, cpu / T_FINAL))
        print(f"  DOP853 tol {tol:g}  error {error:.3e}  {took / T_FINAL:.3e} s/s "
              f"({sol.nfev} evaluations)")


# --- analysis ----------------------------------------------------------------------------------

def past_floor(points: list, method: str) -> bool:
    """Whether the method's error grew at its last, smaller step (its rounding floor)."""
    e = [p.error for p in points if p.method == method]
    return len(e) >= 2 and e[-1] > e[-2]


def observed_order(points: list, method: str, margin: float = 100.0) -> float | None:
    """The least-squares slope of log error against log h over the points whose error is
    above ``margin`` times the method's smallest (clear of its rounding floor)."""
    errors = [p.error for p in points if p.method == method]
    if not errors:
        return None
    rows = [(T_FINAL / p.steps, p.error) for p in points
            if p.method == method and p.error > margin * min(errors)]
    if len(rows) < 2:
        return None
    h, e = np.log(np.array(rows)).T
    return float(np.polyfit(h, e, 1)[0])


def front(points: list, method: str, cost: str = "per_second") -> list[tuple[float, float]]:
    """(error, ``cost``: wall or CPU seconds per simulated second) of the method's points,
    the Pareto front, in decreasing error."""
    rows = [(p.error, getattr(p, cost)) for p in points if p.method == method]
    out: list = []
    for e, t in sorted(rows, key=lambda r: r[1]):  # by cost: keep each new best error
        if not out or e < out[-1][0]:
            out.append((e, t))
    return out


def time_at(points: list, method: str, level: float, cost: str = "per_second"
            ) -> float | None:
    """The wall (or ``cost``) time per simulated second the method needs for ``level``
    (log–log interpolation on its front), None when its points do not reach it."""
    rows = front(points, method, cost)
    if not rows or rows[-1][0] > level:
        return None
    if rows[0][0] <= level:
        return rows[0][1]
    for (e0, t0), (e1, t1) in zip(rows, rows[1:]):
        if e1 <= level <= e0:
            s = (math.log(level) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + s * (math.log(t1) - math.log(t0)))
    return None


def step_at(points: list, method: str, level: float) -> float | None:
    """The h at which the method's error is ``level`` (log–log interpolation)."""
    rows = sorted(((T_FINAL / p.steps, p.error) for p in points if p.method == method),
                  key=lambda r: -r[0])
    for (h0, e0), (h1, e1) in zip(rows, rows[1:]):
        if e1 <= level <= e0 and e0 > e1:
            s = (math.log(level) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(h0) + s * (math.log(h1) - math.log(h0)))
    return None


def levels(results: Results, library: list[str]):
    """Target (1): time to reach each error level, the library's best against RK4."""
    for level in LEVELS:
        row = {"level": level}
        for cost, key in (("per_second", ""), ("cpu_per_second", "_cpu")):
            ours = {m: time_at(results.points, m, level, cost) for m in library}
            reached = {m: t for m, t in ours.items() if t is not None}
            best = min(reached, key=reached.get) if reached else None
            row.update({f"best{key}": best, f"best_time{key}": reached.get(best),
                        f"rk4_time{key}": time_at(results.points, "MuJoCo RK4", level, cost)})
        results.levels.append(row)


def drift(results: Results, sims: dict, ode, mujoco, quick: bool):
    """Target (2): energy and vertical momentum over many steps at the h of error 1e-6."""
    steps = QUICK_DRIFT_STEPS if quick else DRIFT_STEPS
    level = QUICK_DRIFT_ERROR if quick else DRIFT_ERROR
    results.drift_error = level
    for label, (sim, _) in sims.items():
        h = step_at(results.points, label, level)
        if h is None:
            results.drift[label] = {"steps": steps, "h": None}
            continue
        traj = sim.simulate(first_arrow(sim, h), steps, {"h": h, "g": GRAVITY})
        E = traj.energy()
        spatial = traj.spatial_momenta()
        J3 = spatial[:, 2::3].sum(axis=1)
        results.drift[label] = summary(steps, h, E, J3)
    if mujoco is None:
        return
    h = step_at(results.points, "MuJoCo RK4", level)
    if h is None:
        results.drift["MuJoCo RK4"] = {"steps": steps, "h": None}
        return
    model, _, run = mujoco_run(mujoco, h, steps)
    states = run()
    attitudes, xi0 = initial_data()
    y = np.concatenate([ode.state(attitudes, xi0)[:, None],
                        chain_states(*mujoco_qpos_qvel(model, states))], axis=1)
    results.drift["MuJoCo RK4"] = summary(steps, h, np.asarray(ode._energy(y), float),
                                          np.asarray(ode._momentum(y), float))


def summary(steps: int, h: float, E: np.ndarray, J3: np.ndarray) -> dict:
    """Max |E − E₀| over the first and the last tenth of the run, the whole run, and the
    same for J₃; relative to |E₀| and max(1, |J₃,₀|)."""
    tenth = max(len(E) // 10, 1)
    dE = np.abs(E - E[0]) / abs(E[0])
    dJ = np.abs(J3 - J3[0]) / max(1.0, abs(J3[0]))
    return {"steps": steps, "h": h, "energy_first": float(dE[:tenth].max()),
            "energy_last": float(dE[-tenth:].max()), "energy_max": float(dE.max()),
            "momentum_first": float(dJ[:tenth].max()), "momentum_last": float(dJ[-tenth:].max()),
            "momentum_max": float(dJ.max())}


def ratios(results: Results, sims: dict):
    """Target (3): the order-4 scheme's build time and step cost over the midpoint's."""
    if "GaussLegendre(2)" not in sims:
        results.ratios = {"status": "GaussLegendre(2) not implemented"}
        return
    per_step, n, h = {}, 2000, 1e-3
    for label in ("midpoint", "GaussLegendre(2)"):
        sim, _ = sims[label]
        state = first_arrow(sim, h)
        _, took, _ = best_time(lambda m=sim, s=state: run_library(m, s, n, h), 0.5)
        per_step[label] = took / n
    results.ratios = {"build": results.builds["GaussLegendre(2)"] / results.builds["midpoint"],
                      "step": per_step["GaussLegendre(2)"] / per_step["midpoint"],
                      "us_per_step": {k: v * 1e6 for k, v in per_step.items()}}


# --- output --------------------------------------------------------------------------------------

def print_tables(results: Results):
    print(f"\nwork–precision, 3D chain of {N_BODIES} bodies, T = {T_FINAL} s "
          f"({results.date}, {results.machine})")
    print(f"{'method':18s} {'setting':14s} {'steps/evals':>11s} {'error':>10s} "
          f"{'wall s/sim s':>12s} {'CPU s/sim s':>12s} {'Newton':>7s}")
    for p in results.points:
        newton = f"{p.newton:7.2f}" if p.newton is not None else ""
        print(f"{p.method:18s} {p.setting:14s} {p.steps:11d} {p.error:10.2e} "
              f"{p.per_second:12.3e} {p.cpu_per_second:12.3e} {newton}")
    for method, status in results.status.items():
        if status != "ok" and not status.startswith("ok "):
            print(f"{method:18s} {status}")
    print("\nobserved orders (slope of log error against log h, errors above 100× the "
          "method's smallest): "
          + ", ".join(f"{k} {v:.2f}" for k, v in results.orders.items() if v is not None))
    print("\ntarget 1: wall (CPU) time per simulated second to reach each error level")
    print(f"{'error':>8s} {'library best':>18s} {'wall s/s':>11s} {'RK4 wall':>11s} "
          f"{'CPU s/s':>11s} {'RK4 CPU':>11s}  ours ≤ RK4? (wall, CPU)")
    for row in results.levels:
        cells, verdicts = [], []
        for key in ("", "_cpu"):
            ours, rk4 = row[f"best_time{key}"], row[f"rk4_time{key}"]
            cells += [f"{t:.3e}" if t is not None else "not reached" for t in (ours, rk4)]
            verdicts.append(("yes" if ours <= rk4 else "NO") if None not in (ours, rk4)
                            else "n/a")
        print(f"{row['level']:8.0e} {row['best'] or '-':>18s} "
              + " ".join(f"{c:>11s}" for c in cells) + f"  {', '.join(verdicts)}")
    print(f"\ntarget 2: drift at the h of error {results.drift_error:g} (relative |E − E₀|, "
          f"|J₃ − J₃,₀|; first tenth / last tenth / whole run)")
    for method, d in results.drift.items():
        if d.get("h") is None:
            print(f"  {method}: error {results.drift_error:g} not bracketed by its points")
            continue
        print(f"  {method}: h = {d['h']:.3e}, {d['steps']} steps: energy {d['energy_first']:.1e}"
              f" / {d['energy_last']:.1e} / {d['energy_max']:.1e}; momentum "
              f"{d['momentum_first']:.1e} / {d['momentum_last']:.1e} / {d['momentum_max']:.1e}")
    print("\ntarget 3: order 4 against the midpoint: "
          + (results.ratios["status"] if "status" in results.ratios else
             f"build {results.ratios['build']:.2f}x, step {results.ratios['step']:.2f}x"))
    print("builds (derivation + compile, fresh cache): "
          + ", ".join(f"{k} {v:.2f} s" for k, v in results.builds.items()))


def save_figure(results: Results, path: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    methods = list(dict.fromkeys(p.method for p in results.points))
    for method in methods:
        rows = [(p.per_second, p.error) for p in results.points if p.method == method]
        t, e = zip(*rows)
        ax.loglog(t, e, "o-", label=method, ms=4)
    ax.set_xlabel("wall time per simulated second (s)")
    ax.set_ylabel(r"final-time error $\max_i \|R_i - R_i^{\mathrm{ref}}\|_F$")
    ax.set_title(f"3D chain of {N_BODIES} bodies, T = {T_FINAL} s ({results.date})")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure: {path}")


def main(argv=None) -> Results:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--figure", help="save the log–log figure here (matplotlib)")
    parser.add_argument("--output", help="write every number as JSON here")
    parser.add_argument("--no-mujoco", action="store_true", help="leave MuJoCo out")
    args = parser.parse_args(argv)
    results = Results(machine=f"{platform.machine()}, {os.cpu_count()} cores, "
                              f"load {os.getloadavg()[0]:.1f}",
                      date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()))
    ode, ref = reference(results)
    sims = library_points(results, ref, args.quick)
    mujoco = None if args.no_mujoco else mujoco_module()
    mujoco_points(results, ref, args.quick, mujoco)
    dop853_points(results, ode, ref, args.quick)
    results.orders = {m: observed_order(results.points, m) for m in (*sims, "MuJoCo RK4")
                      if any(p.method == m for p in results.points)}
    levels(results, list(sims))
    drift(results, sims, ode, mujoco, args.quick)
    ratios(results, sims)
    print_tables(results)
    if args.figure:
        save_figure(results, args.figure)
    if args.output:
        Path(args.output).write_text(json.dumps(asdict(results), indent=1))
    return results


if __name__ == "__main__":
    main()
