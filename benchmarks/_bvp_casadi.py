"""CasADi transcriptions of the boundary-value benchmark problems (written independently of
the library: only the discrete problem is shared, not its equations).

Every problem is a sequence of arrows g_k = cay(x_k) of a matrix Lie group (SO(3), SE(2)) with
the Cayley chart, some fixed at both ends (second order: the first and the last), joining two
configurations.  The transcription is the same for Ipopt and for the rootfinder:

- variables: the Cayley coordinates x_k of the free arrows but the last, and the
  configurations R_k in between (the free entries of the matrices: all nine on SO(3), the top
  two rows on SE(2));
- dynamics: R_{k+1} = R_k·cay(x_k);
- the last free arrow closes the path: x_last = cay⁻¹(R⁻¹·R_end), so the end configuration is
  met exactly and the equality constraints have full rank;
- cost: Σ of the problem's terms on consecutive arrows; control constraints ψ(x_k) = 0 on
  every free arrow.

``solve_ipopt`` solves the NLP with Ipopt through ``Opti``; ``solve_rootfinder`` solves its
first-order necessary conditions ∇_w ℒ = 0, g = 0 (ℒ = f + νᵀg, g all equality constraints,
∇ by reverse AD on an MX graph) with CasADi's Newton rootfinder and the sparse ``qr`` linear
solver.  Both start from the same path as the library (its default geodesic guess) and zero
multipliers.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

# --- group operations in CasADi (SX) ---------------------------------------------------------


def _hat3(x):
    return ca.vertcat(ca.horzcat(0, -x[2], x[1]), ca.horzcat(x[2], 0, -x[0]),
                      ca.horzcat(-x[1], x[0], 0))


class SO3Ops:
    """SO(3): all nine entries free, row-major."""

    n, free_rows = 3, 3

    @staticmethod
    def cay(x):
        X = _hat3(x)
        return ca.SX.eye(3) + 4 / (4 + ca.dot(x, x)) * (X + X @ X / 2)

    @staticmethod
    def cay_inverse(F):
        return 2 * ca.vertcat(F[2, 1] - F[1, 2], F[0, 2] - F[2, 0], F[1, 0] - F[0, 1]) / (
            1 + F[0, 0] + F[1, 1] + F[2, 2])

    @staticmethod
    def inverse(R):
        return R.T


class SE2Ops:
    """SE(2) = {[[R, t], [0, 1]]}, x = (ω, v₁, v₂) with x̂ = [[0, −ω, v₁], [ω, 0, v₂], [0, 0, 0]];
    the top two rows are free."""

    n, free_rows = 3, 2

    @staticmethod
    def cay(x):
        a = x[0] / 2
        d = 1 + a * a
        rot = ca.vertcat(ca.horzcat(1 - a * a, -2 * a), ca.horzcat(2 * a, 1 - a * a)) / d
        t = ca.vertcat(x[1] - a * x[2], a * x[1] + x[2]) / d
        return ca.vertcat(ca.horzcat(rot, t), ca.horzcat(0, 0, 1))

    @staticmethod
    def cay_inverse(F):
        a = F[1, 0] / (1 + F[0, 0])  # tan(θ/2)
        t1, t2 = F[0, 2], F[1, 2]
        return ca.vertcat(2 * a, t1 + a * t2, -a * t1 + t2)

    @staticmethod
    def inverse(F):
        R = F[:2, :2]
        t = F[:2, 2]
        return ca.vertcat(ca.horzcat(R.T, -R.T @ t), ca.horzcat(0, 0, 1))


def _full(ops, free):
    """The matrix from its free entries (row-major)."""
    rows = [ca.horzcat(*[free[ops.n * i + j] for j in range(ops.n)]) for i in range(ops.free_rows)]
    if ops.free_rows < ops.n:
        rows.append(ca.horzcat(*([0] * (ops.n - 1) + [1])))
    return ca.vertcat(*rows)


def _free(ops, F):
    return ca.vertcat(*[F[i, j] for i in range(ops.free_rows) for j in range(ops.n)])


# --- the problems ------------------------------------------------------------------------------


@dataclass
class Transcription:
    """What the solvers need: the group, the boundary, the guess and the cost and constraint
    terms as SX functions of the Cayley coordinates (and the parameters)."""

    ops: type
    start: np.ndarray  # configuration before the first free arrow
    end: np.ndarray  # configuration after the last free arrow
    x_before: np.ndarray  # (arity − 1, rank) fixed arrows before the free ones (chart)
    x_after: np.ndarray  # the fixed arrows after them
    guess: np.ndarray  # (n_free, rank) Cayley coordinates of the free arrows
    term: ca.Function  # (x_k, …, x_{k+arity−1}, p) -> cost of one term
    arity: int
    constraint: ca.Function | None  # (x, p) -> ψ, on every free arrow
    params: np.ndarray


def first_order(kind: str, end: np.ndarray, params, guess_chart: np.ndarray) -> Transcription:
    """``so3`` (ψ = x₃ − u x₁), ``so3_free`` and ``se2`` (ψ = v₂) of ``_bvp_problems``."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", len(params))
    hh = p[0]
    if kind == "se2":
        ops, cost = SE2Ops, hh * (p[1] * x[0] ** 2 + p[2] * x[1] ** 2) / (2 * hh ** 2)
        psi = x[2]
    else:
        ops = SO3Ops
        cost = hh * (p[1] * x[0] ** 2 + p[2] * x[1] ** 2 + p[3] * x[2] ** 2) / (2 * hh ** 2)
        psi = x[2] - p[4] * x[0] if kind == "so3" else None
    term = ca.Function("term", [x, p], [cost])
    constraint = None if psi is None else ca.Function("psi", [x, p], [psi])
    none = np.zeros((0, 3))
    return Transcription(ops, np.eye(3), np.asarray(end, float), none, none,
                         np.asarray(guess_chart, float), term, 1, constraint,
                         np.asarray(params, float))


def rigid_body(start_pair, end_pair, params, guess_chart: np.ndarray) -> Transcription:
    """The second-order attitude problem of examples/rigid_body_attitude.py (seed 001 eq.
    (27)): L_d(x_k, x_{k+1}) = (h/2)|u|², u = Ω̇ − (P₁Ω₂Ω₃, P₂Ω₁Ω₃, P₃Ω₁Ω₂) with
    Ω = (x_k + x_{k+1})/2h, Ω̇ = (x_{k+1} − x_k)/h²; the first and last arrows fixed."""
    a, b, p = ca.SX.sym("a", 3), ca.SX.sym("b", 3), ca.SX.sym("p", 4)
    hh, i1, i2, i3 = p[0], p[1], p[2], p[3]
    P = ((i2 - i3) / i1, (i3 - i1) / i2, (i1 - i2) / i3)
    w = (a + b) / (2 * hh)
    dw = (b - a) / hh ** 2
    uu = ca.vertcat(dw[0] - P[0] * w[1] * w[2], dw[1] - P[1] * w[0] * w[2],
                    dw[2] - P[2] * w[0] * w[1])
    term = ca.Function("term", [a, b, p], [hh * ca.dot(uu, uu) / 2])
    (R0, R1), (RN1, RN) = start_pair, end_pair
    F = ca.SX.sym("F", 3, 3)
    chart = ca.Function("chart", [F], [SO3Ops.cay_inverse(F)])
    first = np.array(chart(R0.T @ R1)).ravel()
    last = np.array(chart(RN1.T @ RN)).ravel()
    return Transcription(SO3Ops, np.asarray(R1, float), np.asarray(RN1, float),
                         first[None, :], last[None, :], np.asarray(guess_chart, float), term, 2,
                         None, np.asarray(params, float))


# --- the NLP -------------------------------------------------------------------------------------


class _NLP:
    """Variables X (rank × (n_free − 1)), S (free entries × (n_free − 1)); the cost, the
    dynamics and the control constraints as MX expressions of them."""

    def __init__(self, tr: Transcription, X, S):
        ops, n_free = tr.ops, len(tr.guess)
        nf = ops.free_rows * ops.n
        self.tr = tr
        xs, rs = ca.SX.sym("x", 3), ca.SX.sym("r", nf)
        r1 = ca.SX.sym("r1", nf)
        step = ca.Function("step", [rs, xs, r1], [_free(ops, _full(ops, rs) @ ops.cay(xs)) - r1])
        close = ca.Function("close", [rs], [ops.cay_inverse(ops.inverse(_full(ops, rs))
                                                             @ ca.DM(tr.end))])
        start = ca.DM(np.asarray(tr.start, float)[:ops.free_rows].ravel())
        prev = ca.horzcat(start, S[:, :-1]) if n_free > 1 else start
        self.dynamics = ca.vec(step.map(n_free - 1)(prev, X, S))
        x_last = close(S[:, -1])
        free = ca.horzcat(X, x_last)
        full = ca.horzcat(ca.DM(tr.x_before.T), free, ca.DM(tr.x_after.T)) \
            if tr.arity > 1 else free
        total = full.shape[1]
        p = ca.DM(tr.params)
        args = [full[:, i:total - tr.arity + 1 + i] for i in range(tr.arity)]
        terms = tr.term.map(total - tr.arity + 1)(*args, ca.repmat(p, 1, total - tr.arity + 1))
        self.cost = ca.sum2(terms)
        self.control = (ca.vec(tr.constraint.map(n_free)(free, ca.repmat(p, 1, n_free)))
                        if tr.constraint is not None else ca.MX(0, 1))
        self.free = free

    def initial(self) -> tuple[np.ndarray, np.ndarray]:
        """(X₀, S₀) from the guess: the configurations along the guessed arrows."""
        tr, ops = self.tr, self.tr.ops
        xs = ca.SX.sym("x", 3)
        cay = ca.Function("cay", [xs], [ops.cay(xs)])
        R = np.asarray(tr.start, float)
        states = []
        for x in tr.guess[:-1]:
            R = R @ np.array(cay(x))
            states.append(R[:ops.free_rows].ravel())
        return tr.guess[:-1].T, np.array(states).T


@dataclass
class CasadiResult:
    success: bool
    build_seconds: float  # the MX graph (and, for the rootfinder, the solver object)
    solve_seconds: float  # the solve call (Opti: also its nlpsol construction)
    iterations: int
    chart: np.ndarray  # (n_free, rank) Cayley coordinates of the free arrows
    cost: float
    status: str
    solver_seconds: float = float("nan")  # Ipopt's own wall time (stats t_wall_total)


def solve_ipopt(tr: Transcription, tol: float = 1e-10, max_iter: int = 3000) -> CasadiResult:
    """Ipopt (exact Hessian, MUMPS) on the Opti transcription."""
    t0 = time.perf_counter()
    n_free, nf = len(tr.guess), tr.ops.free_rows * tr.ops.n
    opti = ca.Opti()
    X = opti.variable(3, n_free - 1)
    S = opti.variable(nf, n_free - 1)
    nlp = _NLP(tr, X, S)
    opti.minimize(nlp.cost)
    opti.subject_to(nlp.dynamics == 0)
    if nlp.control.numel():
        opti.subject_to(nlp.control == 0)
    X0, S0 = nlp.initial()
    opti.set_initial(X, X0)
    opti.set_initial(S, S0)
    opti.solver("ipopt", {"print_time": False, "record_time": True},
                {"print_level": 0, "tol": tol, "max_iter": max_iter, "sb": "yes"})
    build = time.perf_counter() - t0
    t1 = time.perf_counter()
    try:
        sol = opti.solve()
        ok, source = True, sol
    except RuntimeError:
        ok, source = False, opti.debug
    seconds = time.perf_counter() - t1
    stats = opti.stats()
    chart = np.array(source.value(nlp.free)).reshape(3, -1).T
    return CasadiResult(ok and stats.get("success", False), build, seconds,
                        int(stats.get("iter_count", -1)), chart,
                        float(source.value(nlp.cost)), str(stats.get("return_status")),
                        float(stats.get("t_wall_total", float("nan"))))


def solve_rootfinder(tr: Transcription, rtol: float = 1e-13, max_iter: int = 50
                     ) -> CasadiResult:
    """CasADi's Newton rootfinder (sparse ``qr``) on ∇_w ℒ = 0, g = 0 (MX graph, AD), to
    |F|∞ ≤ max(1e-10, ``rtol``·|F(z₀)|∞) (the rigid body's conditions scale like 1/h³, so a
    fixed tolerance is below their rounding floor at large N)."""
    t0 = time.perf_counter()
    n_free, nf = len(tr.guess), tr.ops.free_rows * tr.ops.n
    X = ca.MX.sym("X", 3, n_free - 1)
    S = ca.MX.sym("S", nf, n_free - 1)
    nlp = _NLP(tr, X, S)
    g = ca.vertcat(nlp.dynamics, nlp.control)
    nu = ca.MX.sym("nu", g.numel())
    w = ca.vertcat(ca.vec(X), ca.vec(S))
    lagrangian = nlp.cost + ca.dot(nu, g)
    z = ca.vertcat(w, nu)
    F = ca.Function("kkt", [z], [ca.vertcat(ca.gradient(lagrangian, w), g)])
    X0, S0 = nlp.initial()
    z0 = np.concatenate([X0.T.ravel(), S0.T.ravel(), np.zeros(g.numel())])
    abstol = max(1e-10, rtol * float(np.abs(np.array(F(z0))).max()))
    solver = ca.rootfinder("newton", "newton", F,
                           {"linear_solver": "qr", "abstol": abstol, "abstolStep": 1e-14,
                            "max_iter": max_iter, "error_on_fail": False})
    free = ca.Function("free", [z], [nlp.free, nlp.cost])
    build = time.perf_counter() - t0
    t1 = time.perf_counter()
    out = solver(z0)
    seconds = time.perf_counter() - t1
    stats = solver.stats()
    chart, cost = free(out)
    residual = float(np.abs(np.array(F(out))).max())
    ok = bool(stats.get("success", False)) and np.isfinite(residual)
    return CasadiResult(ok, build, seconds, int(stats.get("iter_count", -1)),
                        np.array(chart).reshape(3, -1).T, float(cost),
                        f"{stats.get('return_status')}, |F|inf = {residual:.1e}")
