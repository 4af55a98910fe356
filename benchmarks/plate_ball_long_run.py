"""The plate-ball (seed 000 §6.2) over long runs: evidence for docs/conventions.md §12.

    python benchmarks/plate_ball_long_run.py [--h 0.01] [--steps 1500000] [--window 3000]
                                             [--figure plate_ball_long_run.png]

Parameters r = 1, Ω = 0.1, c = 0.02 (the seed data of the tests); initial data: base point
q₀ = (0, 0) and discrete momentum p₀ = (0.1, 0.05, 0.01, 0.02, 0.01) (``Simulator.from_momentum``).
Prints five tables:

1. one run of ``--steps`` steps at ``--h`` from (q₀, p₀): distance d from the origin, per-step
   rotation angle θ, multipliers, the adiabatic invariant J, the Casimir |M|, Newton
   iterations and residuals, constraint residuals, conditioning of the step Jacobian; the
   failing step, if any, is examined;
2. convergence to the continuous equations of the model (the vakonomic equations below) for
   t ≤ 200 at h, h/2, h/4, and the growth of a 10⁻⁹ perturbation of the continuous flow;
3. escape times (d > 100) from (q₀, p₀): continuous, h, h/2, h/4;
4. from an escaped state: d(t) for the continuous equations and h, h/2, h/4 over ``--window``
   time units, the averaged radial acceleration against −ΩJ/(r cos θ), then each run up to the
   fold θ = π/2 (predicted at d* = r/(Ωh)) and the growth of d per step after it;
5. the Hölder (nonholonomic) discretization of the ball on the same rotating plate (seed 002,
   docs/conventions.md §10) with a uniform sphere's inertia: a circle of frequency (2/7)Ω.

Continuous equations of the model (the h → 0 limit of the eight equations of seed 000 §6.2):
with Π = (rλ₁, −rλ₂, −λ₃) the body momentum of the constraint forces, p = (ẋ + λ₂, ẏ + λ₁),
ω = ((Ωx − ẏ)/r, (ẋ + Ωy)/r, c),

    ṗ_x = −Ωλ₁,   ṗ_y = Ωλ₂,   Π̇ = Π × ω,

with the Casimir |Π| and the energy E = ½|v|² + (Ω/r)(Π₁x + Π₂y) + cΠ₃ conserved.
The default run takes about a minute and a half (most of it the continuous reference).
"""

from __future__ import annotations

import argparse
import functools
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import sympy as sp

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import symgroupoid as sg  # noqa: E402
from symgroupoid.stepper import Status, lu_solve  # noqa: E402
from symgroupoid.systems import plate_ball  # noqa: E402

SINGULAR_JACOBIAN = Status.SINGULAR_JACOBIAN

R, OMEGA, C = 1.0, 0.1, 0.02
ORIGIN = (0.0, 0.0)
MOMENTUM = (0.1, 0.05, 0.01, 0.02, 0.01)
#: (x, y, p_x, p_y, Π₁, Π₂, Π₃): the continuous flow from (q₀, p₀) at t = 1000, after its escape
ESCAPED = (12.2299343, 23.6146055, 0.0651578527, 0.125625889,
           0.0208214156, -0.010338273, 0.00771937584)
#: uniform sphere for the Hölder discretization: m = 1, I = (2/5) m r²
MASS, INERTIA = 1.0, 0.4
STRIDE = 100
FOLD_COS = 1e-3  # cos θ below this: the per-step rotation is at the fold θ = π/2

E_BASIS = tuple(np.array(E.tolist(), float) for E in sg.SO3.basis_matrices())


def parameters(h: float) -> dict:
    return {"h": h, "r": R, "Omega": OMEGA, "c": C}


@functools.cache
def plate_ball_simulator():
    return plate_ball().euler_lagrange().compile()


# --- the continuous equations of the model ----------------------------------------------------
def vakonomic_rhs(t: float, z: np.ndarray) -> np.ndarray:
    """Right-hand side of the continuous plate-ball equations, z = (x, y, p_x, p_y, Π)."""
    x, y, px, py, P1, P2, P3 = z
    l1, l2 = P1 / R, -P2 / R
    vx, vy = px - l2, py - l1
    w1, w2, w3 = (OMEGA * x - vy) / R, (vx + OMEGA * y) / R, C
    return np.array([vx, vy, -OMEGA * l1, OMEGA * l2,
                     P2 * w3 - P3 * w2, P3 * w1 - P1 * w3, P1 * w2 - P2 * w1])


def continuous(z0: Sequence, times: Sequence, rtol: float = 1e-12,
               event: float | None = None):
    """The continuous flow (DOP853) at ``times``; with ``event``, stop when d reaches it."""
    from scipy.integrate import solve_ivp

    events = None
    if event is not None:
        def escaped(t, z):
            return np.hypot(z[0], z[1]) - event
        escaped.terminal = True
        events = escaped
    return solve_ivp(vakonomic_rhs, (0.0, float(times[-1])), np.asarray(z0, float),
                     method="DOP853", rtol=rtol, atol=rtol * 1e-2, t_eval=times, events=events)


def continuous_energy(z: np.ndarray) -> np.ndarray:
    x, y, px, py, P1, P2, P3 = z
    vx, vy = px + P2 / R, py - P1 / R
    return 0.5 * (vx ** 2 + vy ** 2) + OMEGA / R * (P1 * x + P2 * y) + C * P3


# --- diagnostics of discrete states ---------------------------------------------------------
def diagnostics(states: np.ndarray, h: float) -> dict:
    """Per state.  State j of a run holds q_j, q_{j+1} (at t = jh, (j+1)h), the arrow g
    between them and its multipliers λ (the knowns x_{k−1}, y_{k−1}, x_k, y_k, g_k, λ_k):

    - d = |q_{j+1}|, d0 = |q_j|; cos θ and θ, the rotation angle of g (tr g = 1 + 2 cos θ);
    - M = X⃗[λ·φ](g) in the basis E₁..E₃, the Lie–Poisson momentum of the constraint forces
      (L does not depend on g, so the rotational DEL read M_{k+1} = g_kᵀ M_k and |M| is a
      Casimir); J = M·n with n the axis of g (the adiabatic invariant of the escaped regime);
    - the constraint residual max|φ(g)| and the tangential speed over Ωd ("co-rotation").
    """
    S = np.atleast_2d(states)
    x0, y0, x1, y1 = S[:, 0], S[:, 1], S[:, 2], S[:, 3]
    g = S[:, 4:13].reshape(-1, 3, 3)
    lam = S[:, 13:16]
    E1, E2, E3 = E_BASIS
    trace = functools.partial(np.trace, axis1=1, axis2=2)
    cos_theta = (trace(g) - 1) / 2
    coef = np.stack([-R * lam[:, 0] / 2, R * lam[:, 1] / 2, lam[:, 2] / 2], 1)
    M = np.stack([sum(coef[:, a] * trace(Ei @ g @ E_BASIS[a]) for a in range(3))
                  for Ei in E_BASIS], 1)
    axis = np.stack([g[:, 2, 1] - g[:, 1, 2], g[:, 0, 2] - g[:, 2, 0], g[:, 1, 0] - g[:, 0, 1]], 1)
    axis /= np.maximum(np.linalg.norm(axis, axis=1), 1e-300)[:, None]
    phi = np.stack([(y1 - y0) - R / 2 * trace(g @ E1) - h * OMEGA * (x1 + x0) / 2,
                    (x1 - x0) + R / 2 * trace(g @ E2) + h * OMEGA * (y1 + y0) / 2,
                    h * C + trace(g @ E3) / 2], 1)
    d = np.hypot(x1, y1)  # |q_{k+1}|: the state k holds q_k, q_{k+1} (t = kh, (k+1)h)
    v_tan = (x1 * (y1 - y0) - y1 * (x1 - x0)) / h / np.maximum(d, 1e-300)
    theta = np.degrees(np.arccos(np.clip(cos_theta, -1, 1)))
    return {"d": d, "d0": np.hypot(x0, y0), "cos": cos_theta, "theta": theta,
            "lam": np.abs(lam).max(1), "casimir": np.linalg.norm(M, axis=1),
            "J": (M * axis).sum(1), "phi": np.abs(phi).max(1),
            "co_rotation": v_tan / (OMEGA * np.maximum(d, 1e-300))}


def cayley_chart(g: np.ndarray) -> np.ndarray:
    """τ⁻¹(g) for the Cayley retraction: ξ̂ = 2(g − I)(g + I)⁻¹."""
    X = 2 * (g - np.eye(3)) @ np.linalg.inv(g + np.eye(3))
    return np.array([X[2, 1], X[0, 2], X[1, 0]])


def unknowns_of(state_next: np.ndarray) -> np.ndarray:
    """The step's unknowns (x_{k+1}, y_{k+1}, τ⁻¹g_{k+1}, λ_{k+1}) read off the next state."""
    return np.concatenate([state_next[2:4], cayley_chart(state_next[4:13].reshape(3, 3)),
                           state_next[13:16]])


def equilibrate(J: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Row then column max-norm scaling: (D_r J D_c, D_r, D_c)."""
    Dr = 1 / np.abs(J).max(1)
    Jr = Dr[:, None] * J
    Dc = 1 / np.abs(Jr).max(0)
    return Jr * Dc, Dr, Dc


def conditioning(known: np.ndarray, u: np.ndarray, h: float) -> tuple[float, float]:
    """2-norm condition numbers of the step Jacobian at (known, u): raw and equilibrated."""
    _, J = plate_ball_simulator().kernel.residual_jacobian(u, known, _pvec(h))
    return float(np.linalg.cond(J)), float(np.linalg.cond(equilibrate(J)[0]))


def _pvec(h: float) -> np.ndarray:
    return plate_ball_simulator().parameters(parameters(h))


def equilibrated_newton(known: np.ndarray, u: np.ndarray, h: float,
                        iterations: int = 8) -> tuple[np.ndarray, float]:
    """Newton on the equilibrated Jacobian (a reference solve); returns (u, |F|_∞)."""
    kernel, p = plate_ball_simulator().kernel, _pvec(h)
    for _ in range(iterations):
        F, J = kernel.residual_jacobian(u, known, p)
        Je, Dr, Dc = equilibrate(J)
        u = u - Dc * np.linalg.solve(Je, Dr * F)
    return u, float(np.abs(kernel.residual(u, known, p)).max())


def global_pivot_singular(J: np.ndarray) -> bool:
    """The former pivot test, pivot ≤ n·ε·max|J| over the whole Jacobian (not invariant under
    scaling an equation), which rejected the regular step at 1 340 697."""
    return bool(np.abs(kernel_pivots(J)).min() <= len(J) * np.finfo(float).eps
                * np.abs(J).max())


def kernel_pivots(J: np.ndarray) -> np.ndarray:
    """The pivots of LU with partial pivoting (the kernel's elimination order)."""
    A = np.array(J, dtype=float)
    n = len(A)
    for k in range(n):
        piv = k + int(np.argmax(np.abs(A[k:, k])))
        A[[k, piv]] = A[[piv, k]]
        A[k + 1:, k:] -= np.outer(A[k + 1:, k] / A[k, k], A[k, k:])
    return np.diag(A).copy()


# --- long runs ----------------------------------------------------------------------------------
@dataclass
class LongRun:
    """A decimated run: every ``stride``-th state (and its successor), per-window solver data."""

    h: float
    stride: int
    states: np.ndarray  # states k = 0, stride, 2·stride, …
    successors: np.ndarray  # states k + 1
    iterations: np.ndarray  # max Newton iterations over each stride window
    residuals: np.ndarray  # max |F|_∞ over each stride window
    steps: int  # steps completed
    failure: sg.SymgroupoidError | None = None
    failing_state: np.ndarray | None = None  # the state from which the failing step starts
    previous: np.ndarray | None = None  # the two states before it (for the extrapolated guess)
    extra: dict = field(default_factory=dict)

    @property
    def k(self) -> np.ndarray:
        return np.arange(len(self.states)) * self.stride

    @property
    def t(self) -> np.ndarray:
        return self.k * self.h


def long_run(state: np.ndarray, steps: int, h: float, *, stride: int = STRIDE,
             chunk: int = 2_000_000, stop=None) -> LongRun:
    """Simulate ``steps`` steps in chunks of ``chunk`` (one ``simulate`` call per chunk; a new
    chunk restarts the extrapolated Newton guess).  ``stop(diag)`` ends the run early."""
    sim, p = plate_ball_simulator(), parameters(h)
    kept, succ, its, res = [], [], [], []
    done, failure, failing, previous = 0, None, None, None
    current = np.asarray(state, float)
    while done < steps:
        n = min(chunk, steps - done)
        n -= n % stride if n >= stride else 0
        try:
            traj = sim.simulate(current, n, p)
        except (sg.SingularJacobianError, sg.NewtonDivergenceError) as exc:
            failure = exc
            n = exc.step
            traj = sim.simulate(current, n, p) if n else None
        if traj is not None:
            S = traj.states
            kept.append(S[:-1:stride])
            succ.append(S[1::stride])
            windows = -(-traj.steps // stride)
            pad = windows * stride - traj.steps
            its.append(np.pad(traj.newton_iterations, (0, pad)).reshape(windows, stride).max(1))
            res.append(np.pad(traj.residual_norms, (0, pad)).reshape(windows, stride).max(1))
            current = traj.final_state()
            previous = S[-3:-1].copy() if len(S) >= 3 else None
        done += n
        if failure is not None:
            failing = current
            break
        if stop is not None and stop(diagnostics(current, h)):
            break
    return LongRun(h, stride, np.concatenate(kept), np.concatenate(succ), np.concatenate(its),
                   np.concatenate(res), done, failure, failing, previous)


def from_momentum(h: float, configuration: Sequence = ORIGIN,
                  momentum: Sequence = MOMENTUM) -> np.ndarray:
    """The discrete initial state with base point q₀ and momentum p₀ (the discrete Legendre
    transform F⁻L: the same continuous data (q(0), p(0)) for every h)."""
    x, y = configuration
    return plate_ball_simulator().from_momentum({"x": x, "y": y}, momentum, parameters(h))


# --- 1. the run from the origin --------------------------------------------------------------
def first_index(mask: np.ndarray) -> int | None:
    hits = np.flatnonzero(mask)
    return int(hits[0]) if hits.size else None


def origin_run(h: float, steps: int) -> LongRun:
    run = long_run(from_momentum(h), steps, h)
    D = diagnostics(run.states, h)
    run.extra["diag"] = D
    run.extra["escape"] = first_index(D["d"] > 100)
    run.extra["fold"] = first_index(D["cos"] < FOLD_COS)
    return run


def failure_analysis(run: LongRun) -> dict:
    """At the failing step: the kernel's pivot test against the equilibrated problem."""
    h, known = run.h, run.failing_state
    sim, p = plate_ball_simulator(), _pvec(run.h)
    guess = sim.kernel.predict(known, p)
    if run.previous is not None:
        guess = 2 * unknowns_of(known) - unknowns_of(run.previous[-1])
    F, J = sim.kernel.residual_jacobian(guess, known, p)
    scale = float(np.abs(J).max())
    pivots = np.abs(kernel_pivots(J))
    u, residual = equilibrated_newton(known, guess, h)
    cond_raw, cond_eq = conditioning(known, u, h)
    nxt = sim.kernel.next_knowns(u, known, p)
    status, _ = lu_solve(J, F)
    return {"step": run.steps, "global_pivot_singular": global_pivot_singular(J),
            "kernel_singular": status == SINGULAR_JACOBIAN,
            "smallest_pivot": float(pivots.min()),
            "threshold": len(F) * np.finfo(float).eps * scale,
            "cond_raw": cond_raw, "cond_eq": cond_eq, "residual": residual,
            "cos_theta": float(diagnostics(nxt, h)["cos"][0]),
            "multipliers": float(np.abs(u[5:]).max())}


def end_slope(run: LongRun, D: dict, steps: int = 1000) -> tuple[float, float]:
    """Growth of d per step over the last ``steps`` steps of a run, and the mean d there."""
    b = len(run.states) - 1
    a = max(0, b - steps // run.stride)
    return (D["d"][b] - D["d"][a]) / (run.k[b] - run.k[a]), (D["d"][b] + D["d"][a]) / 2


def print_origin_run(run: LongRun) -> None:
    h, D = run.h, run.extra["diag"]
    print(f"\n[1] one run from (q₀, p₀): h = {h}, r = {R}, Ω = {OMEGA}, c = {C}; "
          f"{run.steps} steps completed")
    upto = min(len(D["d"]), 100_000 // run.stride + 1)
    print(f"    max d over the first 10⁵ steps: {D['d'][:upto].max():.2f}")
    rows = [m * 100_000 // run.stride for m in (1, 2, 3, 4, 5, 6, 8, 10, 12, 13)
            if m * 100_000 < run.steps]
    for key in ("escape", "fold"):
        if run.extra[key] is not None:
            rows.append(run.extra[key])
    rows.append(len(run.states) - 1)
    C0 = D["casimir"][0]
    print("         k        d   θ (deg)   cos θ   co-rot.  max|λ|         J   Δ|M|/|M|  "
          "Newton  max|F|   max|φ|   cond(J)  cond(DJD)")
    for i in sorted(set(rows)):
        cr, ce = conditioning(run.states[i], unknowns_of(run.successors[i]), h)
        w = slice(max(0, i - 10), i + 10)
        print(f"  {run.k[i]:8d} {D['d'][i]:9.4g} {D['theta'][i]:8.3f} {D['cos'][i]:8.1e} "
              f"{D['co_rotation'][i]:8.5f} {D['lam'][i]:8.2e} {D['J'][i]:+9.2e} "
              f"{abs(D['casimir'][i] - C0) / C0:9.1e} {run.iterations[w].max():6d} "
              f"{run.residuals[w].max():8.1e} {D['phi'][i]:8.1e} {cr:9.2e} {ce:9.2e}")
    esc, fold = run.extra["escape"], run.extra["fold"]
    if esc is not None:
        print(f"    escape (d > 100) at k ≈ {run.k[esc]}; fold (cos θ < {FOLD_COS}) at "
              f"k ≈ {run.k[fold] if fold is not None else '-'}"
              + (f", d = {D['d'][fold]:.0f} (r/(Ωh) = {R / (OMEGA * h):.0f})"
                 if fold is not None else ""))
    if fold is not None and len(run.states) - fold > 20:
        slope, d_end = end_slope(run, D)
        print(f"    after the fold: d grows by {slope:.6f} per step at d = {d_end:.4g} "
              f"(1 − 2(d*/d)² = {1 - 2 * (R / (OMEGA * h * d_end)) ** 2:.6f}, d* = r/(Ωh))")
    if run.failure is not None:
        A = failure_analysis(run)
        print(f"    failure at step {run.steps}: {type(run.failure).__name__}: {run.failure}")
        print(f"      former global pivot test: smallest pivot {A['smallest_pivot']:.3e} vs "
              f"n·ε·max|J| = {A['threshold']:.3e} -> singular: {A['global_pivot_singular']}; "
              f"kernel (per-equation scaled) test -> singular: {A['kernel_singular']}")
        print(f"      equilibrated Newton from the same guess: |F|_∞ = {A['residual']:.1e}, "
              f"cond(J) = {A['cond_raw']:.2e}, cond(D_r J D_c) = {A['cond_eq']:.2f}, "
              f"cos θ = {A['cos_theta']:.2e}, max|λ| = {A['multipliers']:.2e}")


# --- 2. convergence to the continuous equations and sensitivity -------------------------------
def convergence(h: float, times: Sequence = (50.0, 100.0, 200.0)) -> dict:
    """|q_h(t) − q(t)| at ``times`` for h, h/2, h/4 from the same (q₀, p₀)."""
    z0 = np.array([*ORIGIN, *MOMENTUM])
    ref = continuous(z0, times, rtol=1e-13).y
    out = {}
    sim = plate_ball_simulator()
    for hh in (h, h / 2, h / 4):
        n = int(round(times[-1] / hh))
        traj = sim.simulate(from_momentum(hh), n, parameters(hh))
        x, y = traj["x"], traj["y"]  # q_j at t = j·hh
        idx = [int(round(T / hh)) for T in times]
        out[hh] = np.hypot(x[idx] - ref[0], y[idx] - ref[1])
    return out


def sensitivity(times: Sequence = (200.0, 400.0, 600.0, 800.0, 1000.0), eps: float = 1e-9):
    """Growth of a perturbation eps of p_x(0) under the continuous flow."""
    z0 = np.array([*ORIGIN, *MOMENTUM])
    z1 = z0.copy()
    z1[2] += eps
    a, b = continuous(z0, times).y, continuous(z1, times).y
    return np.abs(a - b).max(0)


# --- 3. escape times --------------------------------------------------------------------------
def escape_time_continuous(t_max: float = 20000.0) -> float | None:
    sol = continuous(np.array([*ORIGIN, *MOMENTUM]), [t_max], rtol=1e-11, event=100.0)
    return float(sol.t_events[0][0]) if sol.t_events[0].size else None


def escape_time(h: float, t_max: float = 20000.0) -> float | None:
    run = long_run(from_momentum(h), int(t_max / h), h, chunk=int(200 / h),
                   stop=lambda D: D["d"][0] > 100)
    i = first_index(diagnostics(run.states, h)["d"] > 100)
    return None if i is None else float(run.t[i])


# --- 4. from an escaped state -------------------------------------------------------------------
def escaped_state(h: float) -> np.ndarray:
    return from_momentum(h, ESCAPED[:2], ESCAPED[2:])


def escaped_runs(h: float, beyond: float = 30.0, t_max: float = 30000.0) -> dict:
    """From ``ESCAPED`` for h, h/2, h/4: each run up to its fold and on until d exceeds
    ``beyond``·r/(Ωh) (checked every 10⁴ steps)."""
    runs = {}
    for hh in (h, h / 2, h / 4):
        def stop(D, hh=hh):
            return D["cos"][0] < FOLD_COS and D["d"][0] > beyond * R / (OMEGA * hh)
        run = long_run(escaped_state(hh), int(t_max / hh), hh, chunk=10_000, stop=stop)
        D = diagnostics(run.states, hh)
        run.extra.update(diag=D, fold=first_index(D["cos"] < FOLD_COS))
        runs[hh] = run
    return runs


def radial_acceleration(run: LongRun, t0: float, width: float = 200.0) -> tuple[float, float]:
    """Measured mean radial acceleration over [t0, t0 + width] (quadratic fit of d(t)) and the
    averaged prediction −ΩJ/(r cos θ) over the same window."""
    D, t = run.extra["diag"], run.t
    sel = (t >= t0) & (t <= t0 + width)
    fit = np.polyfit(t[sel] - t0, D["d"][sel], 2)
    return 2 * fit[0], float(np.mean(-OMEGA * D["J"][sel] / (R * D["cos"][sel])))


def print_escaped(runs: dict, window: float, ode: bool) -> None:
    hs = sorted(runs, reverse=True)
    unit = STRIDE * max(runs)  # a time at which every run has a stored state
    times = np.arange(0.0, window + 1e-9, max(unit, round(window / 6 / unit) * unit))
    print(f"\n[4] from an escaped state (the continuous flow from (q₀, p₀) at t = 1000, "
          f"d = {np.hypot(*ESCAPED[:2]):.2f})")
    ref = None
    if ode:
        t0 = time.perf_counter()
        sol = continuous(ESCAPED, times, rtol=1e-9)
        ref = np.hypot(sol.y[0], sol.y[1])
        E = continuous_energy(sol.y)
        print(f"    continuous reference: DOP853, rtol 1e-9, {time.perf_counter() - t0:.0f} s; "
              f"energy drift {np.ptp(E):.1e}, Casimir drift "
              f"{np.ptp(np.linalg.norm(sol.y[4:], axis=0)):.1e}")
    head = "        t" + ("   continuous" if ode else "") + "".join(
        f"   d (h={hh:g})" for hh in hs)
    print(head + ("   d_h − d (h, h/2, h/4)" if ode else ""))
    for j, T in enumerate(times):
        ds = []
        for hh in hs:
            run = runs[hh]
            k = int(round(T / hh))
            i = k // run.stride
            ds.append(run.extra["diag"]["d0"][i] if i < len(run.states) else np.nan)
        line = f"  {T:7.0f}" + (f" {ref[j]:12.5f}" if ode else "")
        line += "".join(f" {v:13.5f}" for v in ds)
        if ode:
            line += "   " + " ".join(f"{v - ref[j]:+.2e}" for v in ds)
        print(line)
    run = runs[hs[0]]
    print(f"    averaged radial acceleration at h = {hs[0]:g}: measured vs −ΩJ/(r cos θ) "
          f"(continuous limit −ΩJ/r)")
    D = run.extra["diag"]
    fold = run.extra["fold"] or len(run.states)
    for frac in (0.1, 0.4, 0.7, 0.85):
        target = frac * D["d"][fold - 1]
        i = first_index(D["d"] >= target)
        if i is None or run.t[i] + 200 > run.t[fold - 1]:
            continue
        measured, predicted = radial_acceleration(run, run.t[i])
        sel = slice(i, i + int(200 / (run.h * run.stride)))
        J = D["J"][sel].mean()
        print(f"      d ≈ {D['d'][i]:7.1f}: θ = {D['theta'][i]:5.1f}°, J = {J:+.3e}, "
              f"measured {measured:.3e}, predicted {predicted:.3e}, −ΩJ/r = {-OMEGA * J / R:.3e}")
    print("    fold (cos θ < 1e-3):      h   d at fold  d*=r/(Ωh)  step at fold   then: steps"
          "   d/d* at end   Δd per step   1 − 2(d*/d)²   co-rotation   max|λ|")
    for hh in hs:
        run = runs[hh]
        D, f = run.extra["diag"], run.extra["fold"]
        if f is None:
            print(f"      {hh:8g}  no fold within the run")
            continue
        dstar = R / (OMEGA * hh)
        slope, d_end = end_slope(run, D)
        print(f"      {hh:16g} {D['d'][f]:11.1f} {dstar:10.0f} {run.k[f]:13d} "
              f"{run.steps - run.k[f]:12d} {d_end / dstar:13.1f} {slope:13.6f} "
              f"{1 - 2 * (dstar / d_end) ** 2:14.6f} {D['co_rotation'][-1]:13.6f} "
              f"{D['lam'][-1]:8.2e}")


# --- 5. the Hölder discretization of the rolling ball ------------------------------------------
def rolling_ball_step() -> sg.StepEquations:
    """The ball on the rotating table of seed 002 (docs/conventions.md §10) with the discrete
    Lagrangian (m/2)|Δq/h|² − I/(2h²) tr W, M_c and D_c of the plate-ball's rolling."""
    h, m, inertia, r, om = sp.symbols("h m I r Omega", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("W")
    E1, E2, _ = sg.SO3.basis_matrices()

    def L(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        return (m / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)
                - inertia / (2 * h ** 2) * g[1].matrix.trace())

    def Mc(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return [(x1 - x0) / h + r / (2 * h) * (W * E2).trace() + om * (y1 + y0) / 2,
                (y1 - y0) / h - r / (2 * h) * (W * E1).trace() - om * (x1 + x0) / 2]

    Dc = [[0, 0, 0, 0, 1], [r, 0, 0, 1, 0], [0, r, -1, 0, 0]]
    system = sg.NonholonomicSystem(G, L, Mc, Dc, parameters=[h, m, inertia, r, om],
                                   name="rolling_ball")
    return system.euler_lagrange()


@functools.cache
def rolling_ball_simulator():
    return rolling_ball_step().compile()


def rolling_rotation(q0: Sequence, q1: Sequence, h: float) -> np.ndarray:
    """The arrow W on M_c for the displacement q₀ → q₁ with vertical spin c: tr(W E_a) =
    −2 sin θ n_a, so sin θ·n = b is read off the constraints (principal branch cos θ > 0)."""
    (x0, y0), (x1, y1) = q0, q1
    b = np.array([-((y1 - y0) - h * OMEGA * (x1 + x0) / 2) / R,
                  ((x1 - x0) + h * OMEGA * (y1 + y0) / 2) / R, h * C])
    s = float(np.linalg.norm(b))
    n = b / s
    N = sum(n[a] * E_BASIS[a] for a in range(3))
    return np.eye(3) + s * N + (1 - np.sqrt(1 - s * s)) * N @ N


def rolling_run(h: float, steps: int) -> dict:
    """The Hölder ball from the plate-ball's first arrow (same q₀, q₁, vertical spin c)."""
    first = from_momentum(h)
    q0, q1 = first[0:2], first[2:4]
    W1 = rolling_rotation(q0, q1, h)
    sim = rolling_ball_simulator()
    p = {"h": h, "m": MASS, "I": INERTIA, "r": R, "Omega": OMEGA}
    traj = sim.simulate({"x": (q0[0], q1[0]), "y": (q0[1], q1[1]), "W": W1}, steps, p)
    z = traj["x"] + 1j * traj["y"]
    kappa = INERTIA * OMEGA / (INERTIA + MASS * R ** 2)
    mu = (1 + 0.5j * kappa * h) / (1 - 0.5j * kappa * h)
    B = (z[1] - z[0]) / (mu - 1)
    A = z[0] - B
    radius = np.abs(z - A)
    turns = np.unwrap(np.angle(z - A))
    return {"steps": steps, "max_d": float(np.abs(z).max()), "predicted_max_d": abs(A) + abs(B),
            "radius": abs(B), "radius_drift": float(np.abs(radius - abs(B)).max()),
            "frequency": float((turns[-1] - turns[0]) / ((len(z) - 1) * h)),
            "kappa": kappa, "discrete_frequency": 2 * np.arctan(kappa * h / 2) / h,
            "continuous_radius": abs(z[1] - z[0]) / h / kappa,
            "newton": int(traj.newton_iterations.max())}


# --- main ---------------------------------------------------------------------------------------
def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--h", type=float, default=0.01, help="base step (h/2 and h/4 also run)")
    ap.add_argument("--steps", type=int, default=1_500_000, help="steps of the run from q₀")
    ap.add_argument("--window", type=float, default=3000.0,
                    help="time window compared with the continuous flow after the escape")
    ap.add_argument("--no-ode", action="store_true",
                    help="skip the (slow) continuous reference in the escaped window")
    ap.add_argument("--figure", type=Path, help="save d(t) plots (needs matplotlib)")
    args = ap.parse_args(argv)
    h, t_start = args.h, time.perf_counter()

    run = origin_run(h, args.steps)
    print_origin_run(run)

    print("\n[2] convergence to the continuous equations from (q₀, p₀): |q_h(t) − q(t)|")
    errors = convergence(h)
    hs = sorted(errors, reverse=True)
    for hh in hs:
        print(f"    h = {hh:<8g}" + "".join(f"  t={T:.0f}: {e:.3e}" for T, e in
                                           zip((50, 100, 200), errors[hh])))
    print("    observed order at t = 200: "
          + ", ".join(f"{np.log2(errors[a][-1] / errors[b][-1]):.3f}"
                      for a, b in zip(hs, hs[1:])))
    growth = sensitivity()
    print("    continuous flow, p_x(0) perturbed by 1e-9: |Δz| at t = 200..1000: "
          + ", ".join(f"{g:.1e}" for g in growth))

    print("\n[3] escape time (first t with d > 100) from (q₀, p₀)")
    print(f"    continuous: {escape_time_continuous():.0f}")
    for hh in hs:
        te = escape_time(hh)
        print(f"    h = {hh:<8g} {te if te is None else round(te)} (chunks of 200 time units)")

    runs = escaped_runs(h)
    print_escaped(runs, args.window, ode=not args.no_ode)

    print("\n[5] Hölder discretization (seed 002) of the ball rolling on the same plate: "
          f"m = {MASS}, I = {INERTIA} (uniform sphere), h = {h}")
    hold = rolling_run(h, args.steps)
    print(f"    {hold['steps']} steps: max d = {hold['max_d']:.6f} (circle: "
          f"{hold['predicted_max_d']:.6f}); radius {hold['radius']:.6f} (continuous "
          f"|v₀|/κ = {hold['continuous_radius']:.6f}), drift {hold['radius_drift']:.1e}")
    print(f"    angular frequency {hold['frequency']:.8f} (2 arctan(κh/2)/h = "
          f"{hold['discrete_frequency']:.8f}, κ = IΩ/(I + mr²) = {hold['kappa']:.8f}); "
          f"max Newton iterations {hold['newton']}")

    if args.figure is not None:
        save_figure(args.figure, run, runs)
    print(f"\n(total {time.perf_counter() - t_start:.0f} s)")
    return 0


def save_figure(path: Path, run: LongRun, runs: dict) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    D = run.extra["diag"]
    a.semilogy(run.t, np.maximum(D["d"], 1e-3), lw=0.6)
    a.axhline(R / (OMEGA * run.h), ls="--", c="gray")
    a.set(xlabel="t", ylabel="d", title=f"from (q₀, p₀), h = {run.h}")
    for hh, r in sorted(runs.items(), reverse=True):
        b.semilogy(r.t, r.extra["diag"]["d"], lw=0.8, label=f"h = {hh:g}")
        b.axhline(R / (OMEGA * hh), ls=":", c="gray")
    b.set(xlabel="t", ylabel="d", title="from the escaped state; r/(Ωh) dotted")
    b.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"figure: {path}")


if __name__ == "__main__":
    raise SystemExit(main())
