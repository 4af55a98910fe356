"""CasADi builds of the discrete equations of ``benchmarks/scaling.py``.

The two model systems of ``symgroupoid.systems`` — ``planar_chain(n)`` and
``spherical_chain(n)`` — are written again here with CasADi's SX graphs, so that the same
discrete Euler–Lagrange step can be built, differentiated (algorithmic differentiation),
solved (``rootfinder('fast_newton')``), accumulated over many steps (``mapaccum``),
code-generated and compiled — a reference for build time, C size and time per step.

Nothing here reads the library's expressions: only the state layout (the order of the unknowns,
the knowns and the parameters) is the library's, so that the residual and the Jacobian can be
compared with ``StepEquations.evaluate`` at the same points.

Planar n-link pendulum (pair groupoid of Rⁿ; unknowns θ_{k+1}, knowns (θ_{k−1}, θ_k),
parameters (h, g)):

    L_d(θ⁰, θ¹) = h L((θ⁰ + θ¹)/2, (θ¹ − θ⁰)/h),  L = Σᵢ ½|vᵢ|² − g Σᵢ yᵢ,
    F = D₂L_d(θ_{k−1}, θ_k) + D₁L_d(θ_k, θ_{k+1})          (Marsden–West).

Spherical chain (the pair groupoid of SO(3)ⁿ: the knowns are every body's R_{i,k−1}, then
every body's R_{i,k}, 9 entries each, row-major; the unknowns are the Cayley coordinates x_i
of the increments, R_{i,k+1} = R_{i,k} cay(x_i), cay(x) = (I − x̂/2)⁻¹(I + x̂/2) =
I + 4/(4 + |x|²)(x̂ + x̂²/2), x̂v = x × v, i.e. x̂ = Σ x_a E_a in the basis E₁, E₂, E₃ of
docs/conventions.md §1).  The residual is the junction variation of docs/conventions.md §2 on
the pair groupoid: for each body i and basis element E_a, the derivative of
L_d(R_{k−1}, R_k) + L_d(R_k, R_{k+1}) along R_{i,k} ↦ R_{i,k}(I + tE_a),

    F_{i,a} = (∂L_d/∂R_b(R_{k−1}, R_k) + ∂L_d/∂R_a(R_k, R_{k+1}))_i ⊙ (R_{i,k} E_a)

(⊙: entrywise product summed).  L_d is the docstring's of
``symgroupoid.systems.spherical_chain``.

The forced variants (``planar-forced``, ``3d-forced``: ``systems.planar_chain(n,
forced=True)``, ``systems.spherical_chain(n, forced=True)``) add the discrete forces
f⁺(g_k) + f⁻(g_{k+1}) to each residual (the forced DEL of Marsden–West eq. (3.2.3),
docs/conventions.md §20); their knowns end with the inputs u_k of the known arrow, then
u_{k+1} of the new one, and their parameters are (h, g, c):

- planar: f⁻ = f⁺ = (h/2)·Q at the arrow's midpoint and rate, Q_j = u_j − u_{j+1} −
  c(θ̇_j − θ̇_{j−1}) + c(θ̇_{j+1} − θ̇_j) (joint torques and joint damping, θ̇₀ = 0);
- 3D: (h/2) R_{i,k}ᵀ(T_i − T_{i+1}) on body i for each of the two arrows, at the junction's
  attitudes R_k, with T_j = R_j u_j − c (ω_j − ω_{j−1}), ω_i = vee(R_{i,b}R_{i,a}ᵀ −
  R_{i,a}R_{i,b}ᵀ)/(2h) over the arrow (R_a, R_b) and R_iᵀR_i u_i written u_i.

In the compiled stepper the new arrow's inputs u_{k+1} are per-step parameters of the
``mapaccum`` (one column per step, after h, g, c); they are written into the known state's
last slot before the step is solved, and the new state carries them in both slots.
"""

from __future__ import annotations

import functools
import os
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import casadi as ca
import numpy as np

from symgroupoid.runtime.toolchain import vector_flags

#: the so(3) basis E₁, E₂, E₃ (x̂ = Σ x_a E_a, x̂v = x × v)
SO3_BASIS = [ca.DM([[0, 0, 0], [0, 0, -1], [0, 1, 0]]),
             ca.DM([[0, 0, 1], [0, 0, 0], [-1, 0, 0]]),
             ca.DM([[0, -1, 0], [1, 0, 0], [0, 0, 0]])]

#: body-frame vectors of the spherical chain (as in symgroupoid.systems)
LINK = ca.DM([0, 0, -1])
CENTRE = ca.DM([0, 0, -0.5])


def chain_inertia(i: int) -> np.ndarray:
    """Principal moments of body i (1-based), as in ``symgroupoid.systems.chain_inertia``."""
    return np.array([1 + i / 10, 6 / 5 + i / 10, 1 / 2 + i / 20])


@dataclass
class StepModel:
    """One DEL step as CasADi functions of (u, known, p).

    ``chart(known)`` is the chart of the current arrow (the unknowns that would repeat it) and
    ``prediction(known)`` the first guess; the stepper extrapolates the charts of the last
    arrows as the library's stepper does (``<prefix>_extrapolate``): linearly,
    u_k ≈ 2u_{k−1} − u_{k−2}, or quadratically, 3(u_{k−1} − u_{k−2}) + u_{k−3}, whichever
    would have guessed the last solution more closely.
    """

    name: str
    n_unknown: int
    n_known: int
    n_param: int
    residual: ca.Function  # (u, known, p) -> F
    jacobian: ca.Function  # (u, known, p) -> ∂F/∂u
    advance: ca.Function  # (u, known) -> next known
    chart: ca.Function  # known -> chart coordinates of the current arrow
    prediction: ca.Function  # known -> first guess
    build_seconds: float = 0.0
    n_input: int = 0  # m: the knowns end with u_k, then u_{k+1} (m each)


def _finish(name: str, u, known, p, F, nxt, chart, prediction, t0: float,
            n_input: int = 0) -> StepModel:
    model = StepModel(
        name=name, n_unknown=u.numel(), n_known=known.numel(), n_param=p.numel(),
        n_input=n_input,
        residual=ca.Function(f"{name}_residual", [u, known, p], [F]),
        jacobian=ca.Function(f"{name}_jacobian", [u, known, p], [ca.jacobian(F, u)]),
        advance=ca.Function(f"{name}_advance", [u, known], [nxt]),
        chart=ca.Function(f"{name}_chart", [known], [chart]),
        prediction=ca.Function(f"{name}_prediction", [known], [prediction]))
    model.build_seconds = time.perf_counter() - t0
    return model


# --- planar n-link pendulum ----------------------------------------------------------------------


def planar_lagrangian(q0, q1, h, g):
    """L_d(θ⁰, θ¹) = h L((θ⁰+θ¹)/2, (θ¹−θ⁰)/h) with running sums for the tip velocities."""
    mid, rate = (q0 + q1) / 2, (q1 - q0) / h
    vx = vy = y = kinetic = potential = 0
    for j in range(q0.numel()):
        vx = vx + rate[j] * ca.cos(mid[j])
        vy = vy + rate[j] * ca.sin(mid[j])
        y = y - ca.cos(mid[j])
        kinetic = kinetic + (vx**2 + vy**2) / 2
        potential = potential + g * y
    return h * (kinetic - potential)


def planar_forces(q0, q1, u, h, c):
    """(h/2)·Q((q0 + q1)/2, (q1 − q0)/h, u): joint torques and joint damping."""
    n = q0.numel()
    v = (q1 - q0) / h
    rel = [v[j] - (v[j - 1] if j else 0) for j in range(n)]  # θ̇_j − θ̇_{j−1}
    Q = [u[j] - (u[j + 1] if j + 1 < n else 0) - c * rel[j]
         + (c * rel[j + 1] if j + 1 < n else 0) for j in range(n)]
    return h / 2 * ca.vertcat(*Q)


def planar_chain(n: int, forced: bool = False) -> StepModel:
    """The Marsden–West step of the planar n-link pendulum (``forced``: with joint torques
    u_k, u_{k+1} at the end of the knowns and joint damping c, the third parameter)."""
    t0 = time.perf_counter()
    m = n if forced else 0
    u, known, p = ca.SX.sym("u", n), ca.SX.sym("known", 2 * n + 2 * m), ca.SX.sym("p", 2 + forced)
    a, b = ca.SX.sym("a", n), ca.SX.sym("b", n)
    Ld = planar_lagrangian(a, b, p[0], p[1])
    D1 = ca.Function("D1", [a, b, p], [ca.gradient(Ld, a)])
    D2 = ca.Function("D2", [a, b, p], [ca.gradient(Ld, b)])
    qm, qk = known[:n], known[n:2 * n]
    F = D2(qm, qk, p) + D1(qk, u, p)
    nxt = ca.vertcat(qk, u)
    if forced:
        uk, up = known[2 * n:3 * n], known[3 * n:]
        F = F + planar_forces(qm, qk, uk, p[0], p[2]) + planar_forces(qk, u, up, p[0], p[2])
        nxt = ca.vertcat(nxt, up, up)
    name = f"planar_{'forced_' if forced else ''}{n}"
    return _finish(name, u, known, p, F, nxt, qk, 2 * qk - qm, t0, m)


# --- spherical chain (the pair groupoid of SO(3)ⁿ) ----------------------------------------------


def row_major(v) -> ca.SX:
    """A 3×3 matrix from its 9 entries in row-major order."""
    return ca.reshape(v, 3, 3).T


def entries(M) -> ca.SX:
    """The 9 entries of a 3×3 matrix in row-major order."""
    return ca.reshape(M.T, 9, 1)


def hat(x) -> ca.SX:
    return ca.vertcat(ca.horzcat(0, -x[2], x[1]), ca.horzcat(x[2], 0, -x[0]),
                      ca.horzcat(-x[1], x[0], 0))


def cayley(x) -> ca.SX:
    """cay(x) = I + 4/(4 + |x|²)(x̂ + x̂²/2)."""
    X = hat(x)
    return ca.SX.eye(3) + 4 / (4 + ca.dot(x, x)) * (X + X @ X / 2)


def cayley_inverse(F) -> ca.SX:
    """cay⁻¹(F) = 2 vee(F − Fᵀ)/(1 + tr F)."""
    return 2 * ca.vertcat(F[2, 1] - F[1, 2], F[0, 2] - F[2, 0], F[1, 0] - F[0, 1]) / (
        1 + ca.trace(F))


def centres_of_mass(R: list) -> list:
    """c_i = Σ_{j<i} R_j ℓ + R_i ρ."""
    out, joint = [], 0
    for Ri in R:
        out.append(joint + Ri @ CENTRE)
        joint = joint + Ri @ LINK
    return out


def spherical_lagrangian(Ra: list, Rb: list, h, g):
    """L_d = Σᵢ (1/h) tr((I − R_{a,i}ᵀR_{b,i})J_{d,i}) + |Δc_i|²/(2h) − (h/2) g e₃·(c_i + c_i⁺)."""
    before, after = centres_of_mass(Ra), centres_of_mass(Rb)
    total = 0
    for i, (A, B, a, b) in enumerate(zip(Ra, Rb, before, after), start=1):
        J = chain_inertia(i)
        Jd = ca.DM(np.diag(J.sum() / 2 - J))
        total = total + ca.trace((ca.SX.eye(3) - A.T @ B) @ Jd) / h
        total = total + ca.dot(b - a, b - a) / (2 * h)
        total = total - h / 2 * g * (a[2] + b[2])
    return total


def _attitudes(z, n: int) -> list:
    return [row_major(z[9 * i: 9 * i + 9]) for i in range(n)]


def _frobenius(A, B):
    return ca.sum1(ca.sum2(A * B))


def vee_spin(A, B, h) -> ca.SX:
    """ω = vee(B Aᵀ − A Bᵀ)/(2h): the spatial angular velocity over the arrow (A, B)."""
    S = B @ A.T - A @ B.T
    return ca.vertcat(S[2, 1], S[0, 2], S[1, 0]) / (2 * h)


def spherical_forces(Ra: list, Rb: list, R: list, u, h, c) -> list:
    """(h/2) R_iᵀ(T_i − T_{i+1}) for every body, T_j = R_j u_j − c(ω_j − ω_{j−1}) with ω
    over the arrow (Ra, Rb) and R_j at R (R_iᵀR_i u_i written u_i)."""
    n = len(R)
    w = [vee_spin(A, B, h) for A, B in zip(Ra, Rb)]
    damping = [-c * (w[j] - (w[j - 1] if j else 0)) for j in range(n)]
    out = []
    for i in range(n):
        net = u[3 * i: 3 * i + 3] + R[i].T @ damping[i]
        if i + 1 < n:
            net = net - R[i].T @ (R[i + 1] @ u[3 * i + 3: 3 * i + 6] + damping[i + 1])
        out += [h / 2 * net[a] for a in range(3)]
    return out


def spherical_chain(n: int, forced: bool = False) -> StepModel:
    """The pair-groupoid DEL step of the spherical chain on SO(3)ⁿ (see the module docstring):
    for every body i and basis element E, the derivative of L_d(R_{k−1}, R_k) + L_d(R_k, R_{k+1})
    along R_{i,k} ↦ R_{i,k}(I + tE), with R_{i,k+1} = R_{i,k} cay(u_i) (``forced``: plus the
    joint torques of both arrows, inputs u_k, u_{k+1} at the end of the knowns, damping c)."""
    t0 = time.perf_counter()
    m = 3 * n if forced else 0
    u, known = ca.SX.sym("u", 3 * n), ca.SX.sym("known", 18 * n + 2 * m)
    p = ca.SX.sym("p", 2 + forced)
    za, zb = ca.SX.sym("za", 9 * n), ca.SX.sym("zb", 9 * n)
    Ld = spherical_lagrangian(_attitudes(za, n), _attitudes(zb, n), p[0], p[1])
    grad = ca.Function("dL", [za, zb, p], [ca.gradient(Ld, za), ca.gradient(Ld, zb)])
    prev, cur = known[:9 * n], known[9 * n:18 * n]
    Rk = _attitudes(cur, n)
    Rnext = [Ri @ cayley(u[3 * i: 3 * i + 3]) for i, Ri in enumerate(Rk)]
    nxt = ca.vertcat(*[entries(Ri) for Ri in Rnext])
    _, d_target = grad(prev, cur, p)
    d_source, _ = grad(cur, nxt, p)
    dt, ds = _attitudes(d_target, n), _attitudes(d_source, n)
    rows = [_frobenius(dt[i] + ds[i], Rk[i] @ E) for i in range(n) for E in SO3_BASIS]
    advance = ca.vertcat(cur, nxt)
    if forced:
        uk, up = known[18 * n:21 * n], known[21 * n:]
        Rprev = _attitudes(prev, n)
        plus = spherical_forces(Rprev, Rk, Rk, uk, p[0], p[2])
        minus = spherical_forces(Rk, Rnext, Rk, up, p[0], p[2])
        rows = [r + a + b for r, a, b in zip(rows, plus, minus)]
        advance = ca.vertcat(advance, up, up)
    chart = ca.vertcat(*[cayley_inverse(A.T @ B)
                         for A, B in zip(_attitudes(prev, n), Rk)])
    name = f"spherical_{'forced_' if forced else ''}{n}"
    return _finish(name, u, known, p, ca.vertcat(*rows), advance, chart, chart, t0, m)


# --- the compiled N-step stepper -----------------------------------------------------------------


@dataclass
class CompiledStepper:
    """A ``mapaccum`` of ``steps`` Newton steps, generated as C, compiled at -O3 and loaded."""

    model: StepModel
    steps: int
    run: ca.Function
    seconds: dict = field(default_factory=dict)  # graph, generate, cc, load
    c_bytes: int = 0

    @property
    def build_seconds(self) -> float:
        """Model graph (with AD) + stepper graph + C generation + cc + load."""
        return self.model.build_seconds + sum(self.seconds.values())

    def initial(self, known0: np.ndarray) -> ca.DM:
        """The accumulated state (known, before, earlier, steps, quadratic) with before =
        2·chart − prediction (so that the first guess is the prediction), no hindsight yet."""
        k = ca.DM(np.asarray(known0, float))
        return ca.vertcat(k, 2 * self.model.chart(k) - self.model.prediction(k),
                          ca.DM.zeros(self.model.n_unknown), 0, 0)

    def step_parameters(self, params: np.ndarray, inputs: np.ndarray | None = None) -> ca.DM:
        """The mapaccum's per-step parameters: ``params`` (one column, broadcast), or for a
        forced model one column (params, u_{k+1}) per step, ``inputs`` of shape
        (steps, m)."""
        params = np.asarray(params, float)
        if not self.model.n_input:
            return ca.DM(params)
        inputs = np.asarray(inputs, float)
        if inputs.shape != (self.steps, self.model.n_input):
            raise ValueError(f"inputs must have shape ({self.steps}, {self.model.n_input}), "
                             f"got {inputs.shape}")
        return ca.DM(np.vstack([np.repeat(params[:, None], self.steps, axis=1), inputs.T]))

    def trajectory(self, known0: np.ndarray, params: np.ndarray,
                   inputs: np.ndarray | None = None) -> np.ndarray:
        """The ``steps + 1`` known states from ``known0`` (rows)."""
        out = np.array(self.run(self.initial(known0), self.step_parameters(params, inputs)))
        states = out[: self.model.n_known].T
        return np.vstack([np.asarray(known0, float), states])


#: CasADi's generated C at -O3 for the same vector extension as the library's kernels
#: (``runtime.toolchain.vector_flags``): both sides compiled for the same processor
CASADI_FLAGS: tuple[str, ...] = ("-O3", *vector_flags(["cc"], []))


def compile_stepper(model: StepModel, steps: int, workdir: Path, *,
                    tol_residual: float = 1e-12, tol_step: float = 1e-10,
                    max_iterations: int = 50, flags: tuple[str, ...] | None = None
                    ) -> CompiledStepper:
    """Newton (fast_newton) + mapaccum over ``steps`` steps, C at ``flags`` (default
    :data:`CASADI_FLAGS`), loaded back."""
    flags = CASADI_FLAGS if flags is None else flags
    t0 = time.perf_counter()
    nu, nk, npar, m = model.n_unknown, model.n_known, model.n_param, model.n_input
    u, known, p = ca.SX.sym("u", nu), ca.SX.sym("k", nk), ca.SX.sym("p", npar)
    G = ca.Function("G", [u, ca.vertcat(known, p)], [model.residual(u, known, p)])
    newton = ca.rootfinder("newton", "fast_newton", G,
                           {"abstol": tol_residual, "abstolStep": tol_step,
                            "max_iter": max_iterations})
    state, step_p = ca.MX.sym("state", nk + 2 * nu + 2), ca.MX.sym("p", npar + m)
    pp = step_p[:npar]
    k, before, earlier = state[:nk], state[nk:nk + nu], state[nk + nu:nk + 2 * nu]
    if m:  # the new arrow's inputs, from this step's column, into the known state's slot
        k = ca.vertcat(k[:nk - m], step_p[npar:])
    steps_done, quadratic = state[nk + 2 * nu], state[nk + 2 * nu + 1]
    current = model.chart(k)
    linear_guess = 2 * current - before
    quadratic_guess = 3 * (current - before) + earlier
    solved = newton(ca.if_else(quadratic, quadratic_guess, linear_guess), ca.vertcat(k, pp))

    def miss(guess):  # max_j |u_j − guess_j| / (1 + |u_j|)
        return ca.mmax(ca.fabs(solved - guess) / (1 + ca.fabs(solved)))

    hindsight = ca.if_else(steps_done >= 2, miss(quadratic_guess) < miss(linear_guess), 0)
    one = ca.Function("one", [state, step_p], [ca.vertcat(
        model.advance(solved, k), current, before, ca.fmin(steps_done + 1, 2), hindsight)])
    name = f"casadi_{model.name}"
    accumulated = one.mapaccum(name, steps)
    t1 = time.perf_counter()
    workdir.mkdir(parents=True, exist_ok=True)
    cwd = os.getcwd()
    try:
        os.chdir(workdir)
        accumulated.generate(f"{name}.c")
    finally:
        os.chdir(cwd)
    t2 = time.perf_counter()
    library = workdir / f"{name}.so"
    subprocess.run(["cc", *flags, "-shared", "-fPIC", str(workdir / f"{name}.c"), "-o",
                    str(library), "-lm"], check=True, capture_output=True)
    t3 = time.perf_counter()
    run = ca.external(accumulated.name(), str(library))  # mapaccum names its nested blocks
    t4 = time.perf_counter()
    return CompiledStepper(model, steps, run,
                           {"graph": t1 - t0, "generate": t2 - t1, "cc": t3 - t2, "load": t4 - t3},
                           (workdir / f"{name}.c").stat().st_size)


MODELS = {"planar": planar_chain, "3d": spherical_chain,
          "planar-forced": functools.partial(planar_chain, forced=True),
          "3d-forced": functools.partial(spherical_chain, forced=True)}
