"""Forces on every kind of first-order system (docs/conventions.md §20): constrained
(``constraints=``), holonomic (``holonomic=``), on a time groupoid, and nonholonomic (the
Hölder step).  For each kind:

(a) the forced residual is the unforced residual plus f⁺_b(g_k) + f⁻_b(g_{k+1}) in the rows
    of the basis sections (combined along D_c for the Hölder step), with f⁻ ≠ f⁺ so that
    their places are tested, and the constraint rows unchanged;
(b) the compiled C step agrees with SymPy at a random point, and its Jacobian with central
    differences;
(c) ``simulate(inputs=U)`` is bitwise a loop of ``sim.step(state, p, inputs=u)``;
(d) a physical check: the constraints hold along a forced run, the forced Noether balance
    with holonomic constraints, the forced energy balance on a time groupoid, and the
    torque balance of the heading of a forced knife edge.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SESSION_CACHE,
    isolated_cache,
    needs_cc,
)

import symgroupoid as sg
from symgroupoid import systems

u, w = sp.symbols("u w", real=True)
h, m, c, ell, kappa, inertia = sp.symbols("h m c ell kappa I", positive=True)
NO_EXTRAPOLATION = sg.NewtonOptions(extrapolate=False)


@dataclass
class Kind:
    """A forced system of one kind, its unforced twin and the data of a short run."""

    forced: object
    plain: object
    forces: object  # the user's f(g) -> (f_minus, f_plus)
    params: dict
    start: object  # a state of the forced system (named parts or flat)
    rows: object = None  # the rows of D_c at a base point (Hölder), or None: the identity
    extra: dict = field(default_factory=dict)


# --- constrained: the plate-ball (seed 000 §6.2) pushed and twisted ----------------------------

def _plate_ball() -> Kind:
    seed = systems.plate_ball()
    hh, r, omega, cc = seed.parameters

    def forces(g):
        """A push u along x and a twist w about E₁, unequal at the two ends; damping of y."""
        (x0, y0), (_, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return ([hh / 2 * u, -cc * (y1 - y0), 0, hh * w * (1 + x0 ** 2) / 2, 0],
                [hh / 2 * u * (1 + y1), -cc * (y1 - y0) / 2, hh * w / 2, 0, W[0, 1] * hh])

    def build(f, inputs):
        return sg.DiscreteSystem(seed.groupoid, seed.lagrangian, constraints=seed.constraints,
                                 parameters=seed.parameters, forces=f, inputs=inputs,
                                 name="pushed_plate_ball" if f else "plate_ball_twin",
                                 time_step=hh)

    params = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02}
    return Kind(build(forces, [u, w]), build(None, []), forces, params,
                start=("momentum", {"x": 0.0, "y": 0.0}, (0.1, 0.05, 0.01, 0.02, 0.01)))


# --- holonomic: a bead on a circle, driven about the centre and damped ------------------------

def _circle_lagrangian(g):
    (x0, y0), (x1, y1) = g.source, g.target
    return m / (2 * h) * ((x1 - x0) ** 2 + (y1 - y0) ** 2)


def _torque_about_the_centre(q, v):
    """F = −c·v + u·(−y, x)/ℓ²: damping and a torque u about the origin."""
    return [-c * v[0] - u * q[1] / ell ** 2, -c * v[1] + u * q[0] / ell ** 2]


def _bead() -> Kind:
    forces = sg.trapezoid_forces(_torque_about_the_centre, h)  # F at either end: f⁻ ≠ f⁺

    def build(f, inputs):
        return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), _circle_lagrangian,
                                 parameters=[h, m, c, ell], name="bead" if f else "bead_twin",
                                 holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - ell ** 2],
                                 forces=f, inputs=inputs, time_step=h)

    a0, a1 = 0.3, 0.3 + 0.02
    start = {"x": (np.cos(a0), np.cos(a1)), "y": (np.sin(a0), np.sin(a1)), "lambda": [0.0],
             "u": 0.4}
    return Kind(build(forces, [u]), build(None, []), forces,
                {"h": 0.01, "m": 1.3, "c": 0.3, "ell": 1.0}, start)


# --- a time groupoid: the adaptive pendulum of seed 000 §6.3, driven in time ------------------

def _pendulum_lagrangian(g):
    dt = g.t1 - g.t0
    (q0,), (q1,) = g.source, g.target
    return dt * (((q1 - q0) / dt) ** 2 / 2 + kappa * sp.cos((q0 + q1) / 2))


def _pendulum_energy(t0, t1, q0, q1):
    """E = ⟨dl(ξ), ξ⟩ − l(ξ) = ½v² − κ cos q̄ (docs/conventions.md §7): −∂L/∂t₁."""
    v = (q1 - q0) / (t1 - t0)
    return v ** 2 / 2 - kappa * sp.cos((q0 + q1) / 2)


def _space_force(t, v):
    """The generalised force −c·v + u·cos t at time t (an input modulated in time)."""
    return -c * v + u * sp.cos(t)


def _time_forces(g):
    """f_q⁻ = (Δt/2)·F(t₀), f_q⁺ = (Δt/2)·F(t₁), and on the time section f_t± = −f_q±·v:
    the virtual work F·(δq − q̇ δt) of a force in the time-extended space, so that the time
    row is the energy balance E(g_{k+1}) − E(g_k) = the forces' work."""
    dt = g.t1 - g.t0
    (q0,), (q1,) = g.source, g.target
    v = (q1 - q0) / dt
    minus, plus = dt / 2 * _space_force(g.t0, v), dt / 2 * _space_force(g.t1, v)
    return [-minus * v, minus], [-plus * v, plus]


def _adaptive_rigid_body() -> Kind:
    """Seed 000 Example 6.1 on SO(3), L = (t₁−t₀)·l(cay⁻¹(W)/(t₁−t₀)), l(ξ) = ½ξᵀIξ,
    with a torque input about the first body axis, modulated in time, and damping."""
    moments = sp.diag(1, 2, 3)

    def velocity(g):
        return g.coordinates / (g.t1 - g.t0)

    def L(g):
        xi = velocity(g)
        return (g.t1 - g.t0) * (xi.T * moments * xi)[0, 0] / 2

    def torque(t, xi):
        return [-c * xi[0] + u * sp.cos(t), -c * xi[1], -c * xi[2]]

    def forces(g):
        """f_W⁻ = (Δt/2)·τ(t₀), f_W⁺ = (Δt/2)·τ(t₁), and f_t± = −f_W±·ξ (the virtual work
        τ·(δθ − ξ δt) of a torque in the time-extended space): the time row is then the
        energy balance E(g_{k+1}) − E(g_k) = the torques' work."""
        xi, dt = velocity(g), g.t1 - g.t0
        minus = [dt / 2 * f for f in torque(g.t0, xi)]
        plus = [dt / 2 * f for f in torque(g.t1, xi)]
        return ([-sum(f * x for f, x in zip(minus, xi)), *minus],
                [-sum(f * x for f, x in zip(plus, xi)), *plus])

    def build(f, inputs):
        return sg.DiscreteSystem(sg.TimeGroupoid(sg.SO3("W")), L, parameters=[c], forces=f,
                                 inputs=inputs, name="driven_in_time" if f else "timed_twin")

    W = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    start = {"t": (0.0, 0.05), "W": W, "u": 0.5}
    return Kind(build(forces, [u]), build(None, []), forces, {"c": 0.2}, start,
                extra={"torque": torque})


def _adaptive_pendulum() -> Kind:
    """The adaptive pendulum of seed 000 Example 6.1 on R×R×(R×R), driven in time (its
    equations; in one dimension the energy row makes the step jump branches within a few
    steps, so the runs are those of the rigid body)."""
    def build(f, inputs):
        return sg.DiscreteSystem(sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q"))),
                                 _pendulum_lagrangian, parameters=[kappa, c], forces=f,
                                 inputs=inputs, name="driven_pendulum" if f else "pendulum")

    start = {"t": (0.0, 0.05), "q": (0.4, 0.43), "u": 0.5}
    return Kind(build(_time_forces, [u]), build(None, []), _time_forces,
                {"kappa": 4.0, "c": 0.2}, start)


# --- nonholonomic: the knife edge (the Hölder step), thrust and steering ---------------------

def _knife_lagrangian(g):
    (x0, y0, a0), (x1, y1, a1) = g.source, g.target
    return (m * ((x1 - x0) ** 2 + (y1 - y0) ** 2) + inertia * (a1 - a0) ** 2) / (2 * h)


def _knife_forces(g):
    """Thrust u along the blade at either end and a steering torque w; damping of Δx."""
    (x0, _, a0), (x1, _, a1) = g.source, g.target
    drag = -c * (x1 - x0) / 2
    return ([h / 2 * u * sp.cos(a0) + drag, h / 2 * u * sp.sin(a0), h / 2 * w],
            [h / 2 * u * sp.cos(a1) + drag, h / 2 * u * sp.sin(a1), h / 2 * w])


def _blade(q):
    """D_c at q: the direction of the blade and the turning."""
    return [[sp.cos(q[2]), sp.sin(q[2]), 0], [0, 0, 1]]


def _knife_edge() -> Kind:
    def Mc(g):
        (x0, y0, a0), (x1, y1, a1) = g.source, g.target
        mid = (a0 + a1) / 2
        return [(x1 - x0) * sp.sin(mid) - (y1 - y0) * sp.cos(mid)]

    def build(f, inputs):
        return sg.NonholonomicSystem(
            sg.PairGroupoid(sg.EuclideanSpace("x y a")), _knife_lagrangian, Mc,
            [lambda q: _blade(q)[0], lambda q: _blade(q)[1]], parameters=[h, m, inertia, c],
            name="knife" if f else "knife_twin", forces=f, inputs=inputs, time_step=h)

    a0, a1, s = 0.2, 0.23, 0.015  # the first arrow on M_c: along the mean heading
    mid = (a0 + a1) / 2
    start = {"x": (0.0, s * np.cos(mid)), "y": (0.0, s * np.sin(mid)), "a": (a0, a1),
             "u": 0.3, "w": -0.1}
    return Kind(build(_knife_forces, [u, w]), build(None, []), _knife_forces,
                {"h": 0.01, "m": 1.5, "I": 0.2, "c": 0.1}, start, rows=_blade)


# --- second order: a pair groupoid of the plane, forces on composable pairs ------------------

def _second_lagrangian(g1, g2):
    """L(q₀, q₁, q₂) = h·(|Δ²q/h²|²/2 + κ·cos(x₁)·|q₂ − q₀|²/(8h²)) (seed 001 §3)."""
    (x0, y0), (x1, y1) = g1.source, g1.target
    (x2, y2) = g2.target
    return h * (((x2 - 2 * x1 + x0) ** 2 + (y2 - 2 * y1 + y0) ** 2) / (2 * h ** 4)
                + kappa * sp.cos(x1) * ((x2 - x0) ** 2 + (y2 - y0) ** 2) / (8 * h ** 2))


def _pair_forces(g1, g2):
    """f⁰, f¹, f² at the pair's three base points, all different (their places are tested):
    a drive u and a turning w at the middle point, damping and couplings at the ends."""
    (x0, y0), (x1, y1) = g1.source, g1.target
    (x2, y2) = g2.target
    return ([c * x0 * y2 + u, -c * (y1 - y0)],
            [h * u * sp.cos(y1), h * w * x1],
            [c * (x2 - x0) * y1 ** 2, w - c * (y2 - y1)])


def _second_order() -> Kind:
    def build(f, inputs):
        return sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")),
                                    _second_lagrangian, parameters=[h, kappa, c], forces=f,
                                    inputs=inputs, name="pair_forced" if f else "pair_twin")

    start = {"x": (0.0, 0.1, 0.21, 0.33), "y": (1.0, 0.98, 0.95, 0.91), "u": (0.2, -0.1),
             "w": (0.0, 0.1)}
    return Kind(build(_pair_forces, [u, w]), build(None, []), _pair_forces,
                {"h": 0.1, "kappa": 0.5, "c": 0.3}, start)


def _second_order_attitude() -> Kind:
    """Seed 001 §3.3.4's shape on SO(3) (Cayley): L = h·|Δξ|²/2, ξ = cay⁻¹(W)/h, with body
    torques τ at each pair's middle and damping and coupling at its ends."""
    taus = sp.symbols("tau1:4", real=True)

    def L(a, b):
        xa, xb = a.coordinates / h, b.coordinates / h
        return h * sum((xb[i] - xa[i]) ** 2 for i in range(3)) / (2 * h ** 2)

    def forces(a, b):
        xa, xb = a.coordinates / h, b.coordinates / h
        return ([-c * h * xa[i] for i in range(3)], [h * t for t in taus],
                [c * h * xb[i] * b.matrix[0, 1] for i in range(3)])

    def build(f, inputs):
        return sg.SecondOrderSystem(sg.SO3("W"), L, parameters=[h, c], forces=f,
                                    inputs=inputs, name="attitude" if f else "attitude_twin")

    R = [np.array(sg.SO3("W").cayley(x).tolist(), float)
         for x in ([0.02, 0.05, -0.03], [0.025, 0.04, -0.02], [0.03, 0.03, -0.01])]
    start = {"W": np.stack(R), **{str(t): (0.1, -0.1) for t in taus}}
    return Kind(build(forces, list(taus)), build(None, []), forces, {"h": 0.1, "c": 0.2},
                start)


KINDS = {"constrained": _plate_ball, "holonomic": _bead, "time": _adaptive_pendulum,
         "time_rigid_body": _adaptive_rigid_body, "nonholonomic": _knife_edge,
         "second_order": _second_order, "second_order_so3": _second_order_attitude}
#: the kinds whose equations are checked (the rigid body's SymPy residuals take ~8 s: slow)
EQUATIONS = ["constrained", "holonomic", "time", "nonholonomic", "second_order",
             pytest.param("time_rigid_body", marks=pytest.mark.slow),
             pytest.param("second_order_so3", marks=pytest.mark.slow)]
#: the kinds that run (the time groupoid's: the rigid body)
RUNS = ["constrained", "holonomic", "time_rigid_body", "nonholonomic", "second_order",
        pytest.param("second_order_so3", marks=pytest.mark.slow)]


@functools.cache
def kind(name: str) -> Kind:
    return KINDS[name]()


@functools.cache
def steps_of(name: str):
    k = kind(name)
    return k.forced.euler_lagrange(), k.plain.euler_lagrange()


@functools.cache
def simulator(name: str):
    return steps_of(name)[0].compile(backend="c", cache_dir=SESSION_CACHE)


def initial(name: str) -> np.ndarray:
    k, sim = kind(name), simulator(name)
    if isinstance(k.start, tuple):
        _, configuration, momentum = k.start
        return sim.from_momentum(configuration, momentum, k.params, inputs=[0.3, -0.2])
    return sim.state(k.start, k.params)


def _plain(expr):
    """The expression with every symbol replaced by a real symbol of the same name (the
    library's and the test's symbols may differ in their assumptions only)."""
    expr = sp.sympify(expr)
    return expr.xreplace({s: sp.Symbol(str(s), real=True) for s in expr.free_symbols})


def _vanishes(expr) -> bool:
    expr = sp.expand(_plain(expr))
    return expr == 0 or sp.simplify(expr) == 0


# --- (a) the forced residual, symbolically -----------------------------------------------------

@pytest.mark.parametrize("name", EQUATIONS)
def test_the_forced_residual_adds_the_forces_in_the_section_rows(name):
    """F_forced − F_plain = f⁺_b(g_k) + f⁻_b(g_{k+1}) in row b (second order: f²_b(g_{k−1},
    g_k) + f¹_b(g_k, g_{k+1}) + f⁰_b(g_{k+1}, g_{k+2}); along D_c: row a gets
    Σ_b c_a^b(β(g_k))·(f⁺_b + f⁻_b)); the constraint rows are unchanged.  The forces are
    the user's function called here on the step's named arrows, with u ↦ u_{k+s} on the
    term starting at g_{k+s}."""
    k = kind(name)
    forced, plain = steps_of(name)
    G, mi, order = k.forced.groupoid, len(k.forced.inputs), forced.order
    starts = range(1 - order, 2)  # the terms of the window, by the offset of their start
    n = len(forced.knowns) - len(starts) * mi
    inputs = {s: forced.knowns[n + i * mi:n + (i + 1) * mi] for i, s in enumerate(starts)}
    for s in starts:
        if all(len(str(v)) == 1 for v in k.forced.inputs):
            label = "k" if s == 0 else f"k{s:+d}"
            assert [str(x) for x in inputs[s]] == [f"{v}_{{{label}}}" for v in k.forced.inputs]
    assert forced.knowns[:n] == plain.knowns and forced.unknowns == plain.unknowns
    junction = [sp.S.Zero] * G.rank
    for s in starts:  # the term starting at s meets the junction node at its point 1 − s
        covectors = k.forces(*[G.view(forced.arrows[s + i]) for i in range(order)])
        sub = dict(zip(k.forced.inputs, inputs[s]))
        junction = [a + sp.sympify(f).xreplace(sub) for a, f in zip(junction, covectors[1 - s])]
    covectors = k.forces(*[G.view(forced.arrows[i]) for i in range(order)])
    assert all(any(not _vanishes(a - b) for a, b in zip(covectors[i], covectors[j]))
               for i in range(order + 1) for j in range(i))  # f⁻ ≠ f⁺ (f⁰, f¹, f² apart)
    if k.rows is None:
        expected = junction
    else:  # the Hölder step's rows: the junction residuals along D_c at β(g_k)
        q = G.target(forced.arrows[0])
        expected = [sum((sp.sympify(a) * f for a, f in zip(row, junction)), sp.S.Zero)
                    for row in k.rows(q)]
    assert len(forced.residuals) == len(plain.residuals)
    for i, (F, F0) in enumerate(zip(forced.residuals, plain.residuals)):
        want = expected[i] if i < len(expected) else 0
        assert _vanishes(F - F0 - want), (name, i)


def test_the_time_row_is_the_forced_energy_balance():
    """On the time groupoid (docs/conventions.md §7) the time row is
    E(g_{k+1}) − E(g_k) + f_t⁺(g_k) + f_t⁻(g_{k+1}); with f_t± = −f_q±·v it reads
    E(g_{k+1}) − E(g_k) = f_q⁺(g_k)·v_k + f_q⁻(g_{k+1})·v_{k+1}, the work of the forces —
    written here by hand from the energy of seed 000 Example 6.1."""
    forced, _ = steps_of("time")
    t = {o: forced.symbol("t", o) for o in (-1, 0, 1)}
    q = {o: forced.symbol("q", o) for o in (-1, 0, 1)}
    u_k, u_next = forced.knowns[-2:]
    E = {o: _pendulum_energy(t[o - 1], t[o], q[o - 1], q[o]) for o in (0, 1)}
    v = {o: (q[o] - q[o - 1]) / (t[o] - t[o - 1]) for o in (0, 1)}
    work = ((t[0] - t[-1]) / 2 * _space_force(t[0], v[0]).subs(u, u_k) * v[0]
            + (t[1] - t[0]) / 2 * _space_force(t[0], v[1]).subs(u, u_next) * v[1])
    assert _vanishes(forced.residuals[0] - (E[1] - E[0] - work))


@pytest.mark.parametrize("name", [
    "holonomic", "second_order", pytest.param("nonholonomic", marks=pytest.mark.slow),
    pytest.param("constrained", marks=pytest.mark.slow),
    pytest.param("time", marks=pytest.mark.slow)])
def test_the_latex_names_the_forces_of_every_kind(name):
    """The printed equations name f⁺_b(g_k) and f⁻_b(g_{k+1}) and define them after
    "where" (each printed equation is checked by the printer to be the residual).  With
    f⁻ ≠ f⁺ the printer named f⁻(g_k) as f⁺(g_k), and its check refused the form: the
    forced equations could not be printed (LatexVerificationError); the Hölder step printed
    no names."""
    forced, _ = steps_of(name)
    tex = forced.latex()
    assert r"\intertext{where}" in tex
    names = (["f^{+}_{%d}(g_{k})", "f^{-}_{%d}(g_{k+1})"] if forced.order == 1 else
             ["f^{2}_{%d}(g_{k-1}, g_{k})", "f^{1}_{%d}(g_{k}, g_{k+1})",
              "f^{0}_{%d}(g_{k+1}, g_{k+2})"])
    for b in range(1, forced.groupoid.rank + 1):
        assert all(n % b in tex for n in names), (name, b)


# --- (b) C against SymPy, the Jacobian against differences ------------------------------------

def _random_point(name: str, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random parameters, a random perturbation of the run's first state (its arrows near
    their group, so that the differences are well conditioned) with random inputs, and a
    random perturbation of the step's prediction there."""
    forced, _ = steps_of(name)
    p = rng.uniform(0.5, 2, size=len(forced.parameters))
    known = initial(name) + 0.05 * rng.normal(size=len(forced.knowns))
    columns = (forced.order + 1) * len(forced.inputs)
    known[-columns:] = rng.normal(size=columns)
    x = simulator(name).kernel.predict(known, p) + 0.05 * rng.normal(size=len(forced.unknowns))
    return x, known, p


@needs_cc
@pytest.mark.parametrize("name", EQUATIONS)
def test_the_compiled_step_agrees_with_sympy_and_differences(name):
    forced, _ = steps_of(name)
    kernel = simulator(name).kernel
    assert simulator(name).backend == "c"
    rng = np.random.default_rng(sum(map(ord, name)))
    x, known, p = _random_point(name, rng)
    F, J = kernel.residual_jacobian(x, known, p)
    values = {**dict(zip(forced.unknowns, x)), **dict(zip(forced.knowns, known)),
              **dict(zip(forced.parameters, p))}
    values.update({f: sp.sympify(e).xreplace(values)  # the new arrow from its chart
                   for f, e in forced.reconstruction.items()})
    want = np.array([float(r.xreplace(values)) for r in forced.residuals])
    np.testing.assert_allclose(F, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    assert np.abs(F).max() > 1e-3
    eps = 1e-6
    J = np.asarray(J).reshape(len(F), len(x))
    for j in range(len(x)):
        d = np.zeros_like(x)
        d[j] = eps
        fd = (kernel.residual(x + d, known, p) - kernel.residual(x - d, known, p)) / (2 * eps)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-7 * (1 + np.abs(J).max()))
    Ju = forced.input_jacobian(x, known, p)  # ∂F/∂(inputs) exactly, and by differences
    columns = (forced.order + 1) * len(forced.inputs)  # (u_{k-1},) u_k, u_{k+1}
    assert Ju.shape == (len(F), columns)
    for j, i in enumerate(range(len(known) - columns, len(known))):
        d = np.zeros_like(known)
        d[i] = eps
        fd = (kernel.residual(x, known + d, p) - kernel.residual(x, known - d, p)) / (2 * eps)
        np.testing.assert_allclose(Ju[:, j], fd, rtol=1e-6, atol=1e-8)
    assert np.abs(Ju).max() > 1e-3


# --- (c) simulate with inputs is a loop of steps, bitwise ------------------------------------

STEPS = 25


def _inputs(name: str) -> np.ndarray:
    rng = np.random.default_rng(7)
    return 0.5 * rng.normal(size=(STEPS, len(kind(name).forced.inputs)))


@functools.cache
def forced_run(name: str):
    return simulator(name).simulate(initial(name), STEPS, kind(name).params,
                                    inputs=_inputs(name), options=NO_EXTRAPOLATION)


@needs_cc
@pytest.mark.parametrize("name", RUNS)
def test_simulate_with_inputs_is_a_loop_of_steps_bitwise(name):
    sim, params, U = simulator(name), kind(name).params, _inputs(name)
    traj = forced_run(name)
    assert len(traj.states) == STEPS + 1
    state = initial(name)
    for j in range(STEPS):
        state = sim.step(state, params, inputs=U[j], options=NO_EXTRAPOLATION)
        assert np.array_equal(state, traj.states[j + 1]), (name, j)
    first = sim.equations.order  # the state's own inputs come first (second order: two)
    for i, input_name in enumerate(kind(name).forced.inputs):
        assert np.array_equal(traj[str(input_name)][first:], U[:, i])
    start = initial(name)  # simulate_batch: each run bitwise its own simulate
    runs = sim.simulate_batch([start, start], STEPS, params, inputs=np.stack([U, U[::-1]]))
    for run, inputs in zip(runs, (U, U[::-1])):
        alone = sim.simulate(start, STEPS, params, inputs=inputs)
        assert np.array_equal(run.states, alone.states), name


# --- (d) physics ------------------------------------------------------------------------------

def _on_the_states(step, exprs):
    """A NumPy function of (states, parameters) evaluating ``exprs`` in the step's knowns."""
    return sp.lambdify([step.knowns, step.parameters], exprs, "numpy")


@needs_cc
def test_the_rolling_constraints_hold_along_a_forced_plate_ball_run():
    k, (forced, _) = kind("constrained"), steps_of("constrained")
    traj = forced_run("constrained")
    G = k.forced.groupoid
    phi = _on_the_states(forced, k.forced.constraints(G.view(forced.arrows[0])))
    p = simulator("constrained").parameters(k.params)
    values = np.array([phi(s, p) for s in traj.states], float)
    assert np.abs(values).max() < 1e-13
    unforced = simulator("constrained").simulate(traj.states[0], STEPS, k.params,
                                                 inputs=np.zeros((STEPS, 2)))
    assert np.abs(unforced["x"][-1] - traj["x"][-1]).max() > 1e-6  # the forces act


@needs_cc
def test_the_forced_bead_stays_on_its_circle_and_balances_its_angular_momentum():
    """ψ(q_k) = 0 along the run, and the angular momentum J of the rotation X = (−y, x)
    (tangent to the circle: a symmetry on N = G|_M) changes by exactly the forces' impulse
    along X (the forced Noether theorem with holonomic constraints)."""
    k = kind("holonomic")
    traj = forced_run("holonomic")
    radius = np.hypot(traj["x"], traj["y"])
    np.testing.assert_allclose(radius, 1.0, rtol=0, atol=4e-16)
    nq = k.forced.noether(lambda q: [-q[1], q[0]])
    assert nq.is_symmetry
    J, impulse = nq.along(traj), nq.impulse(traj)
    assert np.ptp(J) > 1e-3  # the torque and the damping do change J
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-13 * np.abs(J).max())


def _body_velocity(states: np.ndarray) -> np.ndarray:
    """ξ = cay⁻¹(W)/(t₁ − t₀) of each state's arrow (t₀, t₁, W, …), shape (R, 3)."""
    dt, W = states[:, 1] - states[:, 0], states[:, 2:11].reshape(-1, 3, 3)
    X = 2 * (W - W.transpose(0, 2, 1)) / (1 + np.trace(W, axis1=1, axis2=2))[:, None, None]
    return np.stack([X[:, 2, 1], X[:, 0, 2], X[:, 1, 0]], axis=1) / dt[:, None]


@needs_cc
def test_the_adaptive_rigid_body_balances_energy_and_work():
    """E(g_{k+1}) − E(g_k) = f_W⁺(g_k)·ξ_k + f_W⁻(g_{k+1})·ξ_{k+1} along a run of the
    time-adaptive rigid body (E = ½ξᵀIξ, docs/conventions.md §7), computed here from the
    states; every step is forward in time, the step varies and the energy changes."""
    traj, k = forced_run("time_rigid_body"), kind("time_rigid_body")
    states = traj.states
    xi = _body_velocity(states)
    E = 0.5 * np.einsum("ri,i,ri->r", xi, [1.0, 2.0, 3.0], xi)
    t0, t1, U = states[:, 0], states[:, 1], traj["u"]
    cc, dt = k.params["c"], t1 - t0

    def torque(t, v, inp):
        return np.stack([-cc * v[:, 0] + inp * np.cos(t), -cc * v[:, 1], -cc * v[:, 2]], 1)

    plus = dt[:-1, None] / 2 * torque(t1[:-1], xi[:-1], U[:-1])  # f⁺(g_k), input u_k
    minus = dt[1:, None] / 2 * torque(t0[1:], xi[1:], U[1:])  # f⁻(g_{k+1}), input u_{k+1}
    work = np.einsum("ri,ri->r", plus, xi[:-1]) + np.einsum("ri,ri->r", minus, xi[1:])
    np.testing.assert_allclose(np.diff(E), work, rtol=0, atol=1e-12 * np.abs(E).max())
    assert dt.min() > 0 and np.ptp(dt) > 1e-3 * dt.mean() and np.ptp(E) > 1e-3


@needs_cc
def test_the_forced_knife_edge_keeps_to_its_blade_and_turns_by_the_torque_impulse():
    """M_c holds along the run, and the row of the turning section ∂_a ∈ D_c reads
    I·(Δa_{k+1} − Δa_k)/h = (h/2)·(w_k + w_{k+1}): the heading's angular momentum changes
    by the steering torque's impulse (the Hölder step's rows are the forced junction
    residuals along D_c, docs/conventions.md §10, §20)."""
    traj, k = forced_run("nonholonomic"), kind("nonholonomic")
    x, y, a, W = traj["x"], traj["y"], traj["a"], traj["w"]
    mid = (a[:-1] + a[1:]) / 2
    np.testing.assert_allclose(np.diff(x) * np.sin(mid), np.diff(y) * np.cos(mid), rtol=0,
                               atol=1e-16)
    hh, moment = k.params["h"], k.params["I"]
    momentum = moment * np.diff(a) / hh
    np.testing.assert_allclose(np.diff(momentum), hh / 2 * (W[:-1] + W[1:]), rtol=0,
                               atol=1e-13)
    assert np.ptp(momentum) > 1e-3 and np.ptp(mid) > 1e-2


# --- regressions ------------------------------------------------------------------------------

@needs_cc
def test_a_forced_state_from_a_momentum_takes_the_inputs_of_its_arrow():
    """``from_momentum`` of a system with inputs: it left the input slots of the state
    unset (np.empty), so the state carried garbage inputs or was refused with a misleading
    "no consistent initial state" error.  The inputs u_1 of the arrow g_1 are now given as
    ``inputs=``, required, and the forces do not change (g_1, λ_1): F⁻L has no forces."""
    k, sim = kind("constrained"), simulator("constrained")
    _, configuration, momentum = k.start
    one = sim.from_momentum(configuration, momentum, k.params, inputs=[0.3, -0.2])
    two = sim.from_momentum(configuration, momentum, k.params, inputs=np.array([1.5, 2.5]))
    n = sim.layout.n_known - 4
    assert np.array_equal(one[:n], two[:n]) and np.isfinite(one).all()
    assert np.array_equal(one[n:], [0.3, -0.2, 0.3, -0.2])
    assert np.array_equal(two[n:], [1.5, 2.5, 1.5, 2.5])
    for bad, error in [(None, sg.ShapeError), ([1.0], sg.ShapeError),
                       ([np.nan, 0.0], sg.DomainError)]:
        with pytest.raises(error, match="input"):
            sim.from_momentum(configuration, momentum, k.params, inputs=bad)
    plain = kind("holonomic").plain.euler_lagrange().compile(backend="c",
                                                             cache_dir=SESSION_CACHE)
    with pytest.raises(sg.ShapeError, match="no inputs"):  # a system without inputs
        plain.from_momentum({"x": 1.0, "y": 0.0}, (0.0, 0.1), kind("holonomic").params,
                            inputs=[0.1])


@needs_cc
def test_solve_takes_the_inputs_of_the_new_arrow():
    """``Simulator.solve`` of a system with inputs solved with whatever the state's slot for
    the new arrow's inputs held (its own inputs, for a state from ``sim.state`` or a run):
    the inputs silently held constant.  It takes ``inputs=`` now, required as for
    :meth:`step`, and its solution is the step's."""
    k, sim = kind("holonomic"), simulator("holonomic")
    state = sim.state(k.start, k.params)
    with pytest.raises(sg.ShapeError, match="inputs"):
        sim.solve(state, k.params)
    x, _, _ = sim.solve(state, k.params, inputs=[-2.0], options=NO_EXTRAPOLATION)
    known = state.copy()
    known[sim.layout.upcoming_index] = -2.0
    p = sim.parameters(k.params)
    assert np.abs(sim.kernel.residual(x, known, p)).max() < 1e-13
    after = sim.step(state, k.params, inputs=[-2.0], options=NO_EXTRAPOLATION)
    np.testing.assert_allclose(sim.kernel.next_knowns(x, known, p), after, rtol=0,
                               atol=1e-15)
    held, _, _ = sim.solve(state, k.params, inputs=[0.4])  # the state's own input, 0.4
    assert np.abs(held - x).max() > 1e-6


# --- second order (docs/conventions.md §20) ------------------------------------------------------

def test_the_forced_second_order_step_is_the_direct_variation_of_the_forced_sum():
    """On the pair groupoid of the plane, the forced sum Σ_j L(q_{j−1}, q_j, q_{j+1}) with
    the virtual work Σ_j Σ_i f^i(q_{j−1}, q_j, q_{j+1}; u_j)·δq_{j−1+i} of the pair forces,
    varied by hand in q_k: the step's residual b is ∂/∂(q_k)_b of the sum plus the
    coefficient of δ(q_k)_b in the work — D₃L + D₂L + D₁L + f² + f¹ + f⁰, the pair
    centred at q_j carrying the input u_j."""
    forced, plain = steps_of("second_order")
    G = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    q = {o: [forced.symbol(n, o) for n in ("x", "y")] for o in range(-2, 3)}
    inputs = {o: sp.symbols(f"u_{{k{o:+d}}} w_{{k{o:+d}}}".replace("k+0", "k"), real=True)
              for o in (-1, 0, 1)}
    dq = {o: sp.symbols(f"dx{o + 2} dy{o + 2}", real=True) for o in range(-2, 3)}
    action, work = sp.S.Zero, sp.S.Zero
    for j in (-1, 0, 1):  # the pairs whose points include q_k
        g1, g2 = G.view((*q[j - 1], *q[j])), G.view((*q[j], *q[j + 1]))
        action += _second_lagrangian(g1, g2)
        for i, covector in enumerate(_pair_forces(g1, g2)):
            work += sum(sp.sympify(f).subs({u: inputs[j][0], w: inputs[j][1]}) * d
                        for f, d in zip(covector, dq[j - 1 + i]))
    for b in range(2):
        by_hand = sp.diff(action, q[0][b]) + sp.diff(work, dq[0][b])
        assert _vanishes(forced.residuals[b] - by_hand), b
    assert [str(s) for s in forced.knowns[-6:]] == [
        "u_{k-1}", "w_{k-1}", "u_{k}", "w_{k}", "u_{k+1}", "w_{k+1}"]
    assert all(_vanishes(a - b) for a, b in zip(forced.residuals[2:], plain.residuals[2:]))


def _spline(forces=None, inputs=()):
    """L = h·(Δ²q/h²)²/2 on the pair groupoid of R, the discrete ∫q̈²/2 dt."""
    def L(g1, g2):
        (q0,), (q1,) = g1.source, g1.target
        return (g2.target[0] - 2 * q1 + q0) ** 2 / (2 * h ** 3)

    return sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h],
                                forces=forces, inputs=inputs, name="spline")


@needs_cc
def test_a_driven_spline_follows_the_quartic_of_its_euler_lagrange_equation():
    """The force F = u at each pair's middle point (f¹ = h·u) on the spline L: the step is
    Δ⁴q_k = −h⁴·u_k, whose solutions with u held are the quartics of q'''' = −u (the forced
    Euler–Lagrange equation of ∫q̈²/2 dt) exactly; with inputs varying each fourth
    difference is −h⁴ times the input of the pair centred there."""
    system = _spline(lambda g1, g2: ([0], [h * u], [0]), [u])
    sim = system.euler_lagrange().compile(backend="c", cache_dir=SESSION_CACHE)
    hh, uu, steps = 0.05, 3.0, 60

    def quartic(t):
        return -uu * t ** 4 / 24 + t ** 3 / 6 - t / 2 + 0.3

    t = hh * np.arange(steps + 4)
    traj = sim.simulate({"q": quartic(t[:4]), "u": (uu, uu)}, steps, {"h": hh}, inputs=[uu])
    # the recurrence has the fourfold root 1: a rounding ε·|q| of one step grows like n³
    bound = np.finfo(float).eps * np.abs(quartic(t)).max() * steps ** 3
    np.testing.assert_allclose(traj["q"], quartic(t), rtol=0, atol=bound)
    assert np.ptp(traj["q"]) > 1
    U = np.sin(np.arange(steps))
    run = sim.simulate({"q": quartic(t[:4]), "u": (0.5, -0.5)}, steps, {"h": hh}, inputs=U)
    q, centred = run["q"], run["u"]  # the input of the pair centred at q_j is centred[j − 1]
    fourth = q[4:] - 4 * q[3:-1] + 6 * q[2:-2] - 4 * q[1:-3] + q[:-4]  # centred at q_2, …
    np.testing.assert_allclose(fourth, -hh ** 4 * centred[1:-1], rtol=1e-9, atol=1e-15)


def test_second_order_forces_are_checked():
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    for bad in (lambda g1, g2: ([0], [0]), lambda g1, g2: ([0], [0], [0, 1]),
                lambda g1, g2: ([0], [u], [0])):
        with pytest.raises((sg.ShapeError, sg.UndeclaredSymbolError)):
            _spline(bad)
    assert G.rank == 1


@needs_cc
def test_a_forced_second_order_state_from_a_momentum():
    """``from_momentum`` of a second-order system with inputs: the momentum program
    compared the step's knowns with the window's and stopped at the inputs after them
    (RuntimeError "layout mismatch").  The state holds the given inputs for both known
    pairs, and the window is the unforced one's (F⁻L has no forces)."""
    k, sim = kind("second_order"), simulator("second_order")
    g0, momentum = [0.0, 1.0, 0.1, 0.98], [0.1, 0.2, 0.0, 0.1]
    state = sim.from_momentum(g0, momentum, k.params, inputs=[0.3, 0.4])
    assert np.array_equal(state[-6:], [0.3, 0.4, 0.3, 0.4, 0.3, 0.4])
    other = sim.from_momentum(g0, momentum, k.params, inputs=[-1.0, 2.0])
    assert np.array_equal(state[:-6], other[:-6]) and np.isfinite(state).all()
    run = sim.simulate(state, 3, k.params, inputs=[0.3, 0.4])
    assert np.array_equal(run["u"], np.full(5, 0.3))
    with pytest.raises(sg.UnsupportedFeatureError, match="forced=True.* first-order"):
        sim.from_momentum(g0, momentum, k.params, inputs=[0.3, 0.4], forced=True)


@needs_cc
def test_a_driven_continuous_system_starts_from_a_velocity_with_its_inputs():
    """``from_velocity`` of a discretised ContinuousSystem with inputs went through
    ``from_momentum``, which left the state's input slots unset (np.empty); it takes the
    inputs of the first arrow now, required as for ``from_momentum``."""
    g0 = sp.Symbol("g", positive=True)
    pendulum = sg.ContinuousSystem(
        sg.EuclideanSpace("theta"), lambda q, v: v[0] ** 2 / 2 + g0 * sp.cos(q[0]),
        parameters=[h, g0, c], forces=lambda q, v: [-c * v[0] + u], inputs=[u],
        name="driven_pendulum")
    sim = pendulum.discretize(step=h, scheme="midpoint").euler_lagrange().compile(
        backend="c", cache_dir=SESSION_CACHE)
    p = {"h": 0.01, "g": 9.81, "c": 0.1}
    with pytest.raises(sg.ShapeError, match="inputs"):
        sim.from_velocity({"theta": 0.3}, [0.5], p)
    state = sim.from_velocity({"theta": 0.3}, [0.5], p, inputs=[0.25])
    assert np.array_equal(sim.layout.view(state[None], "u"), [0.25])
    assert state[-1] == 0.25 and np.isfinite(state).all()


def test_reduction_never_drops_the_forces():
    """``reduce`` and ``check_system_morphism`` related the Lagrangians and the constraints
    only: the reduced system of a forced one lost its forces and derived the unforced
    equations, silently.  A forced system reduces with its reduced forces given (their
    relation checked: tests/test_forced_reduction.py); without them, or against a system
    without forces, it is refused."""
    from _lie_pairs import LieGroupPair

    rb = systems.rigid_body()
    hh, (I1, I2, I3) = rb.parameters[0], rb.parameters[1:]
    Jd = sp.Matrix(systems.discrete_inertia(I1, I2, I3))
    P = LieGroupPair(sg.SO3)

    def ends(coords):
        return P.group.matrix(P.source(coords)), P.group.matrix(P.target(coords))

    def L(g):
        g0, g1 = ends(g.coords)
        return -(Jd * g0.T * g1).trace() / hh

    def to_group(g):
        g0, g1 = ends(g.coords)
        return g0.T * g1

    unit = P.group.entries(sp.eye(3))
    phi = sg.GroupoidMorphism(P, rb.groupoid, to_group,
                              section=lambda w: P.arrow_from(unit, w.coords))
    torque = sg.body_torque([u, 0, 0], hh)
    forced = sg.DiscreteSystem(P, L, parameters=rb.parameters, forces=torque, inputs=[u])
    with pytest.raises(sg.ShapeError, match="forced; give its reduced forces"):
        forced.reduce(phi)
    with pytest.raises(sg.ShapeError, match="one has forces, the other not"):
        sg.check_system_morphism(phi, forced, rb)
    driven = sg.DiscreteSystem(rb.groupoid, rb.lagrangian, parameters=rb.parameters,
                               forces=torque, inputs=[u])
    plain = sg.DiscreteSystem(P, L, parameters=rb.parameters)
    with pytest.raises(sg.ShapeError, match="one has forces, the other not"):
        sg.check_system_morphism(phi, plain, driven)


@needs_cc
def test_verify_stationary_checks_a_forced_run_with_the_forces_work():
    """A forced trajectory is a critical point of the Lagrange–d'Alembert principle, not of
    the action: ``verify_stationary`` checked the action alone and reported a correct forced
    run "not stationary" (then refused forced systems).  It adds the forces' virtual work
    along the variation now (tests/test_forced_verify.py checks every kind)."""
    from symgroupoid.verification import verify_stationary

    report = verify_stationary(forced_run("holonomic"), kind("holonomic").forced)
    assert report.stationary and report.work != 0.0
