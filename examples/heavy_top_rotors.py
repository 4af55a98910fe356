"""Optimal control of a heavy top with two internal rotors, underactuated (seed 001 §3.3.5).

Continuous model.  Body angular velocity Ω ∈ R³, Γ ∈ S² the upward vertical seen from the body,
rotor angles θ = (θ₁, θ₂) about the first and second principal axes.  With Ī_i the inertias of
top and rotors about the body axes, J_i the rotors' axial inertias, γ_i = Ī_i + J_i and Mgℓ
the gravity torque scale (the seed's "Mgh"; ℓ here, because h is the time step), the reduced
Lagrangian is

    l = ½(γ₁Ω₁² + γ₂Ω₂² + Ī₃Ω₃²) + J₁Ω₁θ̇₁ + J₂Ω₂θ̇₂ + ½(J₁θ̇₁² + J₂θ̇₂²) − MgℓΓ₃.

With Π = ∂l/∂Ω = (γ₁Ω₁ + J₁θ̇₁, γ₂Ω₂ + J₂θ̇₂, Ī₃Ω₃), the controlled equations
Π̇ = Π × Ω + MgℓΓ × e₃, d/dt ∂l/∂θ̇_i = u_i, Γ̇ = Γ × Ω read, written out,

    Φ¹ = γ₁Ω̇₁ + J₁θ̈₁ − (γ₂ − Ī₃)Ω₂Ω₃ − J₂θ̇₂Ω₃ − MgℓΓ₂ = 0,
    Φ² = γ₂Ω̇₂ + J₂θ̈₂ + (γ₁ − Ī₃)Ω₁Ω₃ + J₁θ̇₁Ω₃ + MgℓΓ₁ = 0,
    Φ³ = Ī₃Ω̇₃ − (γ₁ − γ₂)Ω₁Ω₂ − J₁θ̇₁Ω₂ + J₂θ̇₂Ω₁ = 0,
    u₁ = J₁(Ω̇₁ + θ̈₁),   u₂ = J₂(Ω̇₂ + θ̈₂).

The unactuated equations Φ¹, Φ², Φ³ are the second-order constraints, and the cost ½∫(u₁² + u₂²)
becomes L̃ = ½J₁²(Ω̇₁ + θ̈₁)² + ½J₂²(Ω̇₂ + θ̈₂)².  (The seed prints Φ¹ with Ω̇₃Ī₃Ω₂ for Ī₃Ω₂Ω₃
and without −J₂θ̇₂Ω₃, and Φ² with −J₁θ̇₁Ω₃ for +J₁θ̇₁Ω₃ and without −Ī₃Ω₁Ω₃; the forms above
are those of l, and the tests derive them from l again.)

Groupoid.  (S² × SO(3)) × (R² × R²) ⇉ S² × R²: the action groupoid of the heavy top (arrow
(Γ_k, W_k), α = Γ_k, β = W_kᵀΓ_k, seed 002; docs/conventions.md §9) times the pair groupoid of the
unwrapped rotor angles (arrow (θ_k, θ_{k+1})); rank 3 + 2 = 5.  An arrow g_k = ((Γ_k, W_k),
(θ_k, θ_{k+1})) takes the state at t_k to the state at t_{k+1}; on samples of a motion,
W_k = R(t_k)ᵀR(t_{k+1}) and Γ_k = R(t_k)ᵀe₃.

Discretisation (step h, Cayley coordinates x_k = cay⁻¹(W_k) = hξ_k), on the composable pair
(g_k, g_{k+1}), all quantities centred at t_{k+1}:

    Ω     = (x_k + x_{k+1}) / (2h),          Ω̇  = (x_{k+1} − x_k) / h²,
    θ̇     = (θ_{k+2} − θ_k) / (2h),          θ̈  = (θ_{k+2} − 2θ_{k+1} + θ_k) / h²,
    Γ     = Γ_{k+1}  (the source point of g_{k+1}, = W_kᵀΓ_k on composable pairs),
    u_i   = J_i(Ω̇_i + θ̈_i),
    L_d(g_k, g_{k+1})   = h L̃ = (h/2)(u₁² + u₂²),
    Φ_d^A(g_k, g_{k+1}) = h Φ^A(Γ, Ω, Ω̇, θ̇, θ̈),   A = 1, 2, 3,

as in the seed (L_d = hℒ, Φ_d = hΦ̂ with ξ_{k+1/2}, ξ_{k,k+1}, θ_{k,k+2}, θ_{k+2/h²}), except that
Γ is taken at the centre t_{k+1} (the seed's "Y_k" is unreadable).  The optimality conditions
are the discrete constrained second-order Euler–Lagrange equations (seed 001 eq. (18)) of
Σ_k [L_d + λ_k·Φ_d](g_k, g_{k+1}).

Accuracy.  On samples of a smooth motion every centred quantity is second-order accurate at
t_{k+1}: x_k/h = Ω(t_{k+1/2}) + O(h²) (log W_k = hΩ(t_{k+1/2}) + O(h³), and cay⁻¹ = log + O(|·|³)),
the average and the divided difference of two such values are centred at t_{k+1}, the θ
differences are the centred ones and Γ_{k+1} is exact.  So Φ_d/h − Φ(t_{k+1}) and
u_d − u(t_{k+1}) are O(h²): the scheme is consistent of order 2 with the continuous controlled
equations (:func:`consistency_errors` measures it).

Steering problem.  The unactuated directions make the two-point problem delicate: the yaw rate
Ω₃ and the rotation about the body's third axis change only through the bilinear terms of Φ³.
At rest the linearised problem is singular: linearised there, Φ³_d = hĪ₃Ω̇₃, and its sums with
weights a + bk telescope to the yaw rates of the fixed first and last arrows and to the yaw
of the fixed total rotation, so the Jacobian has the null vectors λ₃,k = a + bk (nullity 2).
Away from rest the Jacobian stays nearly singular for slow motions with still rotors — on the
interpolated guess of a rest-to-rest "raise" (tilt 0.34 rad, T = 1) the smallest/largest
singular values are 2e-10, 7e-12, 8e-14 for N = 10, 20, 40 — and from that guess (N = 30) the
Newton directions are ~30 in the Cayley coordinates and ~5·10⁴ in the multipliers, the line
search accepts only small fractions of them and the residual stalls
(:func:`rest_to_rest_attempt`).  What works is an exactly feasible initial guess whose end
state the dynamics reach: :func:`steering_problem` starts from a tilted top spinning about its
axis with both rotors spinning, runs a reference torque program through the discrete
constraints and asks for the cheapest controls reaching the same end state, starting Newton
from the reference motion.  It converges in 6 iterations (N = 30, multipliers |λ| ≤ 130).
Spinning rotors matter (gyroscopic coupling J_iθ̇_iΩ_j): with the rotors still, the same start
and reference program give no convergence in 80 iterations; a milder program (u = (0.3 sin πt/T,
−0.2 sin 2πt/T), no spin) converges in 29, with multipliers λ₃ ≈ −3·10³, the costate of the
nearly uncontrollable yaw rate.  From the interpolated guess even the spinning case fails.

Run:  python examples/heavy_top_rotors.py [--steps 30] [--rest-to-rest]
"""

from __future__ import annotations

import argparse
import functools
import time
from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
gamma1, gamma2, I3bar = sp.symbols("gamma_1 gamma_2 Ibar_3", positive=True)
J1, J2, Mgl = sp.symbols("J_1 J_2 Mgl", positive=True)
PARAMETERS = (h, gamma1, gamma2, I3bar, J1, J2, Mgl)

#: γ₁ = Ī₁ + J₁, γ₂ = Ī₂ + J₂ with Ī = (1.0, 1.2, 0.5), J = (0.1, 0.15); Mgℓ = 1.
PHYSICAL = {"gamma_1": 1.1, "gamma_2": 1.35, "Ibar_3": 0.5, "J_1": 0.1, "J_2": 0.15,
            "Mgl": 1.0}
E3 = np.array([0.0, 0.0, 1.0])


def continuous_constraints(Gamma: Sequence, Omega: Sequence, dOmega: Sequence,
                           dtheta: Sequence, ddtheta: Sequence, p: dict) -> list:
    """Φ¹, Φ², Φ³ (the unactuated controlled equations); ``p`` maps names to values."""
    g1, g2, i3 = p["gamma_1"], p["gamma_2"], p["Ibar_3"]
    j1, j2, c = p["J_1"], p["J_2"], p["Mgl"]
    W, dW, dt, ddt = Omega, dOmega, dtheta, ddtheta
    return [g1 * dW[0] + j1 * ddt[0] - (g2 - i3) * W[1] * W[2] - j2 * dt[1] * W[2] - c * Gamma[1],
            g2 * dW[1] + j2 * ddt[1] + (g1 - i3) * W[0] * W[2] + j1 * dt[0] * W[2] + c * Gamma[0],
            i3 * dW[2] - (g1 - g2) * W[0] * W[1] - j1 * dt[0] * W[1] + j2 * dt[1] * W[0]]


def continuous_controls(dOmega: Sequence, ddtheta: Sequence, p: dict) -> list:
    """u_i = d/dt ∂l/∂θ̇_i = J_i(Ω̇_i + θ̈_i)."""
    return [p["J_1"] * (dOmega[0] + ddtheta[0]), p["J_2"] * (dOmega[1] + ddtheta[1])]


def _symbolic() -> dict:
    return {str(s): s for s in PARAMETERS}


def discrete_state(a: sg.Arrow, b: sg.Arrow) -> tuple:
    """(Γ, Ω, Ω̇, θ̇, θ̈) centred at t_{k+1} from a composable pair (g_k, g_{k+1})."""
    xa, xb = list(a[0].coordinates), list(b[0].coordinates)
    th0, th1 = a[1].source, a[1].target
    th2 = b[1].target
    Omega = [(p + q) / (2 * h) for p, q in zip(xa, xb)]
    dOmega = [(q - p) / h ** 2 for p, q in zip(xa, xb)]
    dtheta = [(th2[i] - th0[i]) / (2 * h) for i in range(2)]
    ddtheta = [(th2[i] - 2 * th1[i] + th0[i]) / h ** 2 for i in range(2)]
    return list(b[0].point), Omega, dOmega, dtheta, ddtheta


def groupoid() -> sg.Groupoid:
    """(S² × SO(3), Γ·W = WᵀΓ) × pair groupoid of (θ₁, θ₂)."""
    top = sg.ActionGroupoid(sg.EuclideanSpace.vector("Gamma", 3), sg.SO3("W"),
                            lambda p, W: tuple(W.T * sp.Matrix(p)))
    return top * sg.PairGroupoid(sg.EuclideanSpace("theta1 theta2"))


def discrete_controls_expr(a: sg.Arrow, b: sg.Arrow) -> list:
    """u₁, u₂ of the pair (g_k, g_{k+1}) as expressions."""
    _, _, dOmega, _, ddtheta = discrete_state(a, b)
    return continuous_controls(dOmega, ddtheta, _symbolic())


@functools.cache
def heavy_top_system() -> sg.SecondOrderSystem:
    """L_d = (h/2)(u₁² + u₂²), Φ_d = hΦ(centred state) on composable pairs."""

    def L(a, b):
        u = discrete_controls_expr(a, b)
        return h * (u[0] ** 2 + u[1] ** 2) / 2

    def phi(a, b):
        return [h * c for c in continuous_constraints(*discrete_state(a, b), _symbolic())]

    return sg.SecondOrderSystem(groupoid(), L, constraints=phi, parameters=list(PARAMETERS),
                                name="heavy_top_rotors")


def parameter_values(step: float, physical: dict | None = None) -> list[float]:
    """Values in the order of :data:`PARAMETERS`."""
    p = {**PHYSICAL, **(physical or {})}
    return [step] + [p[str(s)] for s in PARAMETERS[1:]]


@functools.cache
def _numeric() -> tuple[Callable, Callable, Callable]:
    """Φ_d, (u₁, u₂) and L_d of a window (g_k, g_{k+1}) from the system's own expressions."""
    system = heavy_top_system()
    fs = system._fs
    coords = [c for s in fs.slots for c in s]
    views = [system.groupoid.view(s) for s in fs.slots]
    args = [coords, list(system.parameters)]
    return (sp.lambdify(args, fs.constraints, "numpy"),
            sp.lambdify(args, discrete_controls_expr(*views), "numpy"),
            sp.lambdify(args, fs.lagrangian, "numpy"))


def window_values(arrows: np.ndarray, params: Sequence[float]) -> tuple[np.ndarray, ...]:
    """Φ_d, u and L_d for every pair (g_k, g_{k+1}) of an arrow sequence (rows k)."""
    phi, controls, lagrangian = _numeric()
    pairs = [np.concatenate([a, b]) for a, b in zip(arrows[:-1], arrows[1:])]
    return (np.array([np.asarray(phi(w, params), float) for w in pairs]),
            np.array([np.asarray(controls(w, params), float) for w in pairs]),
            np.array([float(lagrangian(w, params)) for w in pairs]))


def cayley(x: Sequence) -> np.ndarray:
    """cay(x̂) (seed 001 eq. (63))."""
    x = np.asarray(x, float)
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])
    return np.eye(3) + 4.0 / (4.0 + x @ x) * (X + X @ X / 2)


def arrow(Gamma: Sequence, W: np.ndarray, theta0: Sequence, theta1: Sequence) -> np.ndarray:
    """Coordinates of ((Γ, W), (θ_k, θ_{k+1}))."""
    return np.concatenate([np.ravel(np.asarray(v, float)) for v in (Gamma, W, theta0, theta1)])


# --- consistency with the continuous controlled equations ---------------------------------

def reference_motion() -> Callable:
    """A smooth motion: R(t) = R_z(φ)R_y(ψ)R_x(χ), θ(t); returns t ↦ (R, Γ, Ω, Ω̇, θ, θ̇, θ̈)
    with every derivative exact (SymPy)."""
    t = sp.Symbol("t", real=True)
    phi, psi, chi = sp.sin(2 * t) + t / 2, sp.cos(3 * t) / 2 - t ** 2, t + t ** 3 / 3
    theta = sp.Matrix([3 * t + sp.sin(t), sp.cos(2 * t) - t ** 2])

    def axis(i, a):
        c, s = sp.cos(a), sp.sin(a)
        M = sp.eye(3)
        j, k = [m for m in range(3) if m != i]
        M[j, j], M[j, k], M[k, j], M[k, k] = c, -s, s, c
        return M

    R = axis(2, phi) * axis(1, psi) * axis(0, chi)
    S = R.T * R.diff(t)
    Omega = sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])
    parts = [R, R.T * sp.Matrix([0, 0, 1]), Omega, Omega.diff(t), theta, theta.diff(t),
             theta.diff(t, 2)]
    f = sp.lambdify(t, parts, "numpy")
    return lambda s: [np.array(v, float).reshape(np.shape(v)) for v in f(s)]


def consistency_errors(steps: Sequence[int] = (20, 40, 80), duration: float = 1.0) -> dict:
    """Sample the reference motion at t_k = kh (arrows g_k as in the module docstring) and
    compare, at the centres t_{k+1}, the system's discrete constraints Φ_d/h with Φ(t) and
    the discrete controls with u(t).  Returns max errors per N and the observed orders."""
    motion = reference_motion()
    errors: dict = {"steps": list(steps), "phi": [], "u": []}
    for n in steps:
        dt = duration / n
        states = [motion(k * dt) for k in range(n + 2)]
        arrows = np.array([arrow(s[1], s[0].T @ q[0], s[4].ravel(), q[4].ravel())
                           for s, q in zip(states[:-1], states[1:])])
        params = parameter_values(dt)
        phi, u, Ld = window_values(arrows, params)
        if not np.allclose(Ld, dt * np.sum(u ** 2, axis=1) / 2, rtol=1e-10, atol=1e-14):
            raise AssertionError("the controls do not reproduce the system's Lagrangian")
        exact_phi, exact_u = [], []
        for s in states[1:n + 1]:
            _, Gamma, Omega, dOmega, _, dtheta, ddtheta = (v.ravel() for v in s)
            exact_phi.append(continuous_constraints(Gamma, Omega, dOmega, dtheta, ddtheta,
                                                    PHYSICAL))
            exact_u.append(continuous_controls(dOmega, ddtheta, PHYSICAL))
        errors["phi"].append(float(np.max(np.abs(phi / dt - np.array(exact_phi)))))
        errors["u"].append(float(np.max(np.abs(u - np.array(exact_u)))))
    for key in ("phi", "u"):
        e = errors[key]
        errors[f"{key}_orders"] = [float(np.log2(a / b)) for a, b in zip(e[:-1], e[1:])]
    return errors


# --- steering ------------------------------------------------------------------------------

def _newton(f: Callable, z: np.ndarray, tol: float = 1e-13, maxit: int = 40) -> np.ndarray:
    """Newton with a central-difference Jacobian for the small step systems."""
    for _ in range(maxit):
        F = f(z)
        if np.max(np.abs(F)) < tol:
            return z
        eps = 1e-7 * (1 + np.abs(z))
        J = np.array([(f(z + e) - f(z - e)) / (2 * e[i])
                      for i, e in enumerate(np.diag(eps))]).T
        z = z - np.linalg.solve(J, F)
    raise RuntimeError(f"step solve did not converge: |F| = {np.max(np.abs(f(z))):.2e}")


def simulate(steps: int, duration: float, R0: np.ndarray, omega0: Sequence,
             theta0: Sequence, dtheta0: Sequence, torque: Callable[[float], Sequence],
             physical: dict | None = None) -> np.ndarray:
    """A discrete motion driven by rotor torques ``torque(t)``: for k = 0 … N−2 solve
    Φ_d(g_k, g_{k+1}) = 0 and u(g_k, g_{k+1}) = torque(t_{k+1}) for g_{k+1} (its Cayley
    coordinates and θ_{k+2}).  Returns the N arrows; they satisfy the constraints exactly."""
    dt = duration / steps
    params = parameter_values(dt, physical)
    phi, controls, _ = _numeric()
    theta0 = np.asarray(theta0, float)
    x = dt * np.asarray(omega0, float)
    arrows = [arrow(R0.T @ E3, cayley(x), theta0, theta0 + dt * np.asarray(dtheta0, float))]
    for k in range(steps - 1):
        a = arrows[-1]
        Gamma = a[3:12].reshape(3, 3).T @ a[:3]
        target = np.asarray(torque((k + 1) * dt), float)

        def residual(z, a=a, Gamma=Gamma, target=target):
            w = np.concatenate([a, arrow(Gamma, cayley(z[:3]), a[14:16], z[3:])])
            return np.concatenate([np.asarray(phi(w, params), float) / dt,
                                   np.asarray(controls(w, params), float) - target])

        z = _newton(residual, np.concatenate([x, 2 * a[14:16] - a[12:14]]))
        x = z[:3]
        arrows.append(arrow(Gamma, cayley(x), a[14:16], z[3:]))
    return np.array(arrows)


def configurations(R0: np.ndarray, theta0: Sequence, arrows: np.ndarray) -> list:
    """((Γ_k, R_k), θ_k) for k = 0 … N."""
    G = heavy_top_system().groupoid
    out = [((tuple(R0.T @ E3), R0), tuple(float(v) for v in theta0))]
    for a in arrows:
        out.append(G.configuration_after(out[-1], a))
    return out


def rotation(axis_angle: Sequence) -> np.ndarray:
    """exp(ω̂) (Rodrigues)."""
    w = np.asarray(axis_angle, float)
    th = float(np.linalg.norm(w))
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / th
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def steering_problem(steps: int = 30, duration: float = 1.5) -> dict:
    """Start: tilted by 0.27 rad, spinning at Ω₃ = 2 with both rotors at 20 rad/s.  Reference
    program u(t) = (0.4 sin 3πt/T, −0.3 sin 4πt/T).  End: the state the reference reaches."""
    R0 = rotation([0.25, 0.1, 0.0])
    theta0 = (0.0, 0.0)

    def reference_torque(t: float) -> tuple:
        return (0.4 * np.sin(3 * np.pi * t / duration), -0.3 * np.sin(4 * np.pi * t / duration))

    guess = simulate(steps, duration, R0, (0.0, 0.0, 2.0), theta0, (20.0, 20.0),
                     reference_torque)
    c = configurations(R0, theta0, guess)
    params = parameter_values(duration / steps)
    _, u, _ = window_values(guess, params)
    return {"start": (c[0], c[1]), "end": (c[-2], c[-1]), "guess": guess, "params": params,
            "reference_cost": float(params[0] * np.sum(u ** 2) / 2), "steps": steps}


def solve_steering(steps: int = 30, duration: float = 1.5) -> tuple:
    """The minimum-effort controls between the ends of :func:`steering_problem`."""
    problem = steering_problem(steps, duration)
    sol = sg.solve_boundary_value(heavy_top_system(), problem["start"], problem["end"], steps,
                                  guess=problem["guess"], params=problem["params"])
    return sol, problem


def rest_to_rest_attempt(steps: int = 30, duration: float = 1.0,
                         max_iterations: int = 40) -> str:
    """Try the rest-to-rest raise from a 0.34 rad tilt to upright (rotors still, θ back to 0)
    from the default interpolated guess; returns the solver's message (it does not converge,
    see the module docstring)."""
    R0 = rotation([0.3, 0.15, 0.0])
    rest = (0.0, 0.0)
    start = (((tuple(R0.T @ E3), R0), rest),) * 2
    end = (((tuple(E3), np.eye(3)), rest),) * 2
    try:
        sol = sg.solve_boundary_value(heavy_top_system(), start, end, steps,
                                      params=parameter_values(duration / steps),
                                      max_iterations=max_iterations)
    except sg.SymgroupoidError as exc:
        return f"{type(exc).__name__}: {exc}"
    return f"converged: {sol}"


def cost(sol: sg.BoundaryValueSolution) -> float:
    """Σ L_d = Σ (h/2)(u₁² + u₂²) along a solution."""
    params = [sol.parameters[str(s)] for s in PARAMETERS]
    return float(window_values(sol.arrows, params)[2].sum())


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=30, help="number of arrows N")
    parser.add_argument("--rest-to-rest", action="store_true",
                        help="also try the rest-to-rest raise (does not converge)")
    args = parser.parse_args(argv)

    errors = consistency_errors()
    print("consistency with the continuous controlled equations (smooth reference motion):")
    for key, label in (("phi", "max |Φ_d/h − Φ(t_{k+1})|"), ("u", "max |u_d − u(t_{k+1})|")):
        print(f"  {label}: N = {errors['steps']}: "
              f"{', '.join(f'{e:.2e}' for e in errors[key])}; observed orders "
              f"{', '.join(f'{o:.2f}' for o in errors[key + '_orders'])}")

    t0 = time.perf_counter()
    sol, problem = solve_steering(args.steps)
    seconds = time.perf_counter() - t0
    system = heavy_top_system()
    phi, u, _ = window_values(sol.arrows, problem["params"])
    print(f"\nsteering, N = {args.steps}: {sol.iterations} Newton iterations, "
          f"|F|∞ = {sol.residual_norm:.2e}, {seconds:.2f} s (kernel build included)")
    print(f"  max |Φ_d| = {np.abs(phi).max():.1e}, stationary: "
          f"{bool(sg.verify_stationary(sol, system))}")
    print(f"  cost {cost(sol):.6f} (reference program {problem['reference_cost']:.6f})")
    print("     k   u1         u2")
    for k, row in enumerate(u, start=1):
        print(f"  {k:4d} {row[0]:9.5f} {row[1]:9.5f}")
    if args.rest_to_rest:
        print(f"\nrest-to-rest raise, N = {args.steps}: {rest_to_rest_attempt(args.steps)}")


if __name__ == "__main__":
    main()
