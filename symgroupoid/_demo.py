"""The tour behind ``make demo`` / ``python -m symgroupoid demo``."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import sympy as sp

from ._lambdify import NUMPY_MODULES
from .groupoids import SO3
from .runtime import solve_boundary_value
from .runtime.toolchain import STATS
from .systems import heavy_top, plate_ball
from .verification import verify_stationary


def _constraint_function(system):
    fs = system.functions
    return sp.lambdify([list(fs.slots[0]), list(system.parameters)], fs.constraints, NUMPY_MODULES)


def _rolling_rotation(x0, y0, x1, y1, h, r, Omega, c) -> np.ndarray:
    """The arrow g = cay(w) solving the plate-ball constraints for the given displacement:
    tr(g E_a) = −8 w_a/(4 + |w|²) (seed 000 §6.2)."""
    t = np.array([2 / r * ((y1 - y0) - h * Omega * (x1 + x0) / 2),
                  -2 / r * ((x1 - x0) + h * Omega * (y1 + y0) / 2), -2 * h * c])
    a = float(t @ t) / 64
    s = ((1 - 8 * a) - np.sqrt((1 - 8 * a) ** 2 - 64 * a * a)) / (2 * a) if a else 0.0
    w = -t * (4 + s) / 8
    return np.array(SO3("g").cayley([sp.Float(v) for v in w]).tolist(), float)


def build_note(builds: int) -> str:
    """What a timing includes: the kernel builds it did (none when the cache had them)."""
    if builds <= 0:
        return ""
    return " (including the one-time kernel build)" if builds == 1 else \
        f" (including {builds} one-time kernel builds)"


def _section(title: str) -> None:
    print(f"\n== {title} " + "=" * max(0, 74 - len(title)))


def plate_ball_tour() -> None:
    _section("plate-ball (seed 000 §6.2): derivation")
    t0 = time.perf_counter()
    system = plate_ball()
    step = system.euler_lagrange()
    J = step.jacobian()
    print(f"{len(step)} equations in {len(step.unknowns)} unknowns, Jacobian {J.shape[0]}×"
          f"{J.shape[1]}, derived in {time.perf_counter() - t0:.2f} s")
    print(step.latex())

    _section("plate-ball: compiled stepper, 10⁴ steps")
    builds = STATS["builds"]
    t0 = time.perf_counter()
    sim = step.compile()
    how = "compiled" if STATS["builds"] > builds else "loaded from the kernel cache"
    print(f"{how} ({sim.backend} backend) in {time.perf_counter() - t0:.2f} s")
    h, r, Om, c = 0.01, 1.0, 0.5, 0.3
    params = {"h": h, "r": r, "Omega": Om, "c": c}
    x0, y0, x1, y1 = 0.0, 0.0, 0.01, 0.004
    W = _rolling_rotation(x0, y0, x1, y1, h, r, Om, c)
    initial = {"x": (x0, x1), "y": (y0, y1), "g": W, "lambda": [0.1, -0.2, 0.05]}
    sim.simulate(initial, 10, params)  # warm-up
    t0 = time.perf_counter()
    traj = sim.simulate(initial, 10_000, params)
    dt = time.perf_counter() - t0
    phi = _constraint_function(system)
    arrows = traj.states[:, :13]
    worst = max(float(np.max(np.abs(phi(a, [h, r, Om, c])))) for a in arrows)
    print(f"10⁴ steps in {dt * 1e3:.1f} ms ({dt / 1e4 * 1e6:.2f} µs/step), "
          f"mean Newton iterations {traj.newton_iterations.mean():.2f}")
    print(f"max |φ| over the trajectory: {worst:.1e}")
    print(f"position after 10⁴ steps: ({traj['x'][-1]:.4f}, {traj['y'][-1]:.4f})")


def heavy_top_tour() -> None:
    _section("heavy top (seed 002, action groupoid S²×SO(3)): 10⁴ steps")
    system = heavy_top()
    sim = system.euler_lagrange().compile()
    params = {"h": 0.01, "mgl": 2.9, "I1": 1.0, "I2": 1.3, "I3": 0.7}
    Gamma = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    W = np.array(SO3("W").cayley([0.02, -0.05, 0.08]).tolist(), float)
    traj = sim.simulate({"Gamma": Gamma, "W": W}, 10_000, params)
    G = traj["Gamma"]
    vertical = system.noether(lambda q: list(q))
    F = np.array([vertical.evaluate(s, [], list(params.values())) for s in traj.states[::100]])
    print(f"|Γ| drift: {np.abs(np.linalg.norm(G, axis=1) - 1).max():.1e}; "
          f"Noether quantity of the vertical rotation (symmetry verified: "
          f"{vertical.is_symmetry}): drift {np.ptp(F):.1e}")


def steering_tour() -> None:
    _section("optimal control: plate-ball steering as a two-point problem")
    system = plate_ball()
    N, r, Om, c = 40, 1.0, 0.5, 0.3
    h = 1.0 / N
    s = np.linspace(0, 1, N + 1)
    x, y = 0.8 * s + 0.1 * np.sin(2 * np.pi * s), 0.5 * np.sin(np.pi * s) + 0.3 * s
    arrows, R = [], np.eye(3)
    for k in range(N):
        W = _rolling_rotation(x[k], y[k], x[k + 1], y[k + 1], h, r, Om, c)
        arrows.append(np.concatenate([[x[k], y[k], x[k + 1], y[k + 1]], W.ravel()]))
        R = R @ W
    builds = STATS["builds"]
    t0 = time.perf_counter()
    sol = solve_boundary_value(system.euler_lagrange(), ((x[0], y[0]), np.eye(3)),
                               ((x[-1], y[-1]), R), N, params=[h, r, Om, c],
                               guess=np.array(arrows))
    print(f"N = {N}: {sol.iterations} Newton iterations, |F|∞ = {sol.residual_norm:.1e}, "
          f"{time.perf_counter() - t0:.2f} s{build_note(STATS['builds'] - builds)}")
    print(f"critical point of the discrete action (independent check): "
          f"{bool(verify_stationary(sol, system))}")


def conservation_figure_tour(path: str | Path = Path("build") / "demo" / "conservation.png"
                             ) -> Path | None:
    """The heavy top over 10⁴ steps: drift of the discrete energy and of the Noether quantity
    of the vertical rotation against the rounding floor, saved as a figure (matplotlib)."""
    from .plotting import MissingDependencyError, plot_conservation

    _section("conservation along a run: heavy top, energy and Noether quantity")
    system = heavy_top()
    sim = system.euler_lagrange().compile()
    params = {"h": 0.01, "mgl": 2.9, "I1": 1.0, "I2": 1.3, "I3": 0.7}
    Gamma = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    W = np.array(SO3("W").cayley([0.02, -0.05, 0.08]).tolist(), float)
    traj = sim.simulate({"Gamma": Gamma, "W": W}, 10_000, params)
    vertical = {"vertical angular momentum": system.noether(lambda q: list(q))}
    print("\n".join(traj.conservation_summary(noether=vertical).lines()))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        plot_conservation(traj, energy=True, momenta=vertical, path=path)
    except MissingDependencyError as err:
        print(f"no figure: {err}")
        return None
    print(f"conservation figure: {path.resolve()}")
    return path


def run_demo() -> int:
    plate_ball_tour()
    heavy_top_tour()
    steering_tour()
    conservation_figure_tour()
    return 0
