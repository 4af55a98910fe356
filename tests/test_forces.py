"""Forced and controlled systems: the discrete Lagrange–d'Alembert principle
(docs/conventions.md §20) — the forced DEL against Marsden–West on Q × Q, the forced Noether
balance on a pair groupoid and on a Lie group, inputs through every entry point, the
continuous limit against an ODE solution, and hostile inputs."""

import re

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import (
    CallableError,
    DomainError,
    InputNameError,
    InputTypeError,
    ShapeError,
    UndeclaredSymbolError,
    UnsupportedFeatureError,
    systems,
)

h, m, k, c = sp.symbols("h m k c", positive=True)
u, w = sp.symbols("u w", real=True)


def _plane_system(forces=None, inputs=(), name="plane"):
    """A point in the plane with a central potential (rotation is a symmetry of L)."""
    G = sg.PairGroupoid(sg.EuclideanSpace(["x", "y"]))

    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        return h * (m / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)
                    - k / 2 * (xm ** 2 + ym ** 2) - (xm ** 2 + ym ** 2) ** 2 / 4)

    return sg.DiscreteSystem(G, L, parameters=[h, m, k, c], forces=forces, inputs=inputs,
                             name=name, time_step=h)


def _torque_and_damping(g):
    """f⁻ = f⁺ = (h/2)·F at the midpoint: a torque input u about the origin and linear
    damping −c·v (the midpoint rule's discrete forces)."""
    (x0, y0), (x1, y1) = g.source, g.target
    xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
    r2 = xm ** 2 + ym ** 2 + 1
    F = [-c * (x1 - x0) / h - u * ym / r2, -c * (y1 - y0) / h + u * xm / r2]
    half = [h / 2 * f for f in F]
    return half, half


# --- the mathematics ---------------------------------------------------------------------------

def test_forced_del_is_marsden_west_on_the_pair_groupoid():
    """D₂L(q_{k−1}, q_k) + f⁺(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) + f⁻(q_k, q_{k+1}) = 0
    (Marsden–West eq. (3.2.3)), with f⁻ ≠ f⁺ so that their places are checked."""

    def forces(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return ([u * x0 * y1 + c * x1, w * sp.sin(y0)], [c * x0 * x1 ** 2, u * w + y0 * y1])

    system = _plane_system(forces, [u, w])
    step = system.euler_lagrange()
    q = {o: [step.symbol(n, o) for n in ("x", "y")] for o in ("k-1", "k", "k+1")}
    a0, a1 = [sp.Dummy() for _ in range(2)], [sp.Dummy() for _ in range(2)]
    b0, b1 = [sp.Dummy() for _ in range(2)], [sp.Dummy() for _ in range(2)]

    def Ld(p0, p1):
        G = system.groupoid
        return system.lagrangian(G.view(tuple(p0) + tuple(p1)))

    u_k, w_k, u_k1, w_k1 = sp.symbols("u_{k} w_{k} u_{k+1} w_{k+1}", real=True)

    def f(p0, p1, which, inputs):
        G = system.groupoid
        value = forces(G.view(tuple(p0) + tuple(p1)))[which]
        return [sp.sympify(e).subs({u: inputs[0], w: inputs[1]}) for e in value]

    L1 = Ld(a0, a1)
    L2 = Ld(b0, b1)
    sub1 = dict(zip(a0 + a1, q["k-1"] + q["k"]))
    sub2 = dict(zip(b0 + b1, q["k"] + q["k+1"]))
    fplus = f(q["k-1"], q["k"], 1, (u_k, w_k))
    fminus = f(q["k"], q["k+1"], 0, (u_k1, w_k1))
    for i in range(2):
        expected = (sp.diff(L1, a1[i]).xreplace(sub1) + sp.diff(L2, b0[i]).xreplace(sub2)
                    + fplus[i] + fminus[i])
        got = step.residuals[i].xreplace({s: sp.Symbol(str(s), real=True)
                                          for s in step.residuals[i].free_symbols})
        expected = expected.xreplace({s: sp.Symbol(str(s), real=True)
                                      for s in expected.free_symbols})
        assert sp.simplify(got - expected) == 0


def test_the_program_evaluates_the_symbolic_residual_with_the_inputs():
    """The step program (what C and NumPy evaluate) against the SymPy residuals at random
    points, the inputs of both arrows varying."""
    step = _plane_system(_torque_and_damping, [u]).euler_lagrange()
    rng = np.random.default_rng(3)
    assert [str(s) for s in step.knowns[-2:]] == ["u_{k}", "u_{k+1}"]
    for _ in range(3):
        x = rng.normal(size=len(step.unknowns))
        known = rng.normal(size=len(step.knowns))
        p = rng.uniform(0.5, 2, size=len(step.parameters))
        F, J = step.evaluate(x, known, p)
        sub = {**dict(zip(step.unknowns, x)), **dict(zip(step.knowns, known)),
               **dict(zip(step.parameters, p))}
        want = [float(r.subs(step.reconstruction).subs(sub)) for r in step.residuals]
        np.testing.assert_allclose(F, want, rtol=1e-12, atol=1e-12)
        eps = 1e-6  # the exact Jacobian (unknowns) against central differences
        for j in range(len(x)):
            d = np.zeros_like(x)
            d[j] = eps
            fd = (step.evaluate(x + d, known, p)[0] - step.evaluate(x - d, known, p)[0]) / (2 * eps)
            np.testing.assert_allclose(J[:, j], fd, rtol=1e-6, atol=1e-7)


PLANE_PARAMS = {"h": 0.01, "m": 1.3, "k": 2.0, "c": 0.4}


@pytest.fixture(scope="module")
def plane():
    return _plane_system(_torque_and_damping, [u]).euler_lagrange().compile()


def test_forced_noether_balance_on_the_pair_groupoid(plane):
    """The angular momentum J of the rotation X = (−y, x) changes by exactly the forces'
    impulse along X (torque input and damping), to rounding."""
    system = plane.equations.system
    nq = system.noether(lambda q: [-q[1], q[0]])
    assert nq.is_symmetry
    steps = 400
    U = np.sin(0.05 * np.arange(steps))[:, None]
    traj = plane.simulate({"x": (1.0, 1.0), "y": (0.0, 0.012), "u": [0.3]}, steps,
                          PLANE_PARAMS, inputs=U)
    J = nq.along(traj)
    impulse = nq.impulse(traj)
    assert np.ptp(J) > 1e-2  # the forces change J, so the balance is not trivial
    scale = np.abs(J).max()
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-13 * scale * 10)


def _internal_pair():
    """Two particles on a line, a spring between them and an internal force ±u (equal and
    opposite): translation X = (1, 1) is a symmetry and the forces cancel along it."""
    G = sg.PairGroupoid(sg.EuclideanSpace(["a", "b"]))

    def L(g):
        (a0, b0), (a1, b1) = g.source, g.target
        d = (a0 + a1 - b0 - b1) / 2
        return h * (m / 2 * (((a1 - a0) / h) ** 2 + ((b1 - b0) / h) ** 2) - k / 2 * d ** 2)

    def forces(g):
        (a0, b0), (a1, b1) = g.source, g.target
        push = u - c * ((a1 - a0) - (b1 - b0)) / h
        return [h / 2 * push, -h / 2 * push], [h / 2 * push, -h / 2 * push]

    return sg.DiscreteSystem(G, L, parameters=[h, m, k, c], forces=forces, inputs=[u],
                             name="internal", time_step=h)


def test_internal_forces_leave_the_momentum_conserved():
    system = _internal_pair()
    sim = system.euler_lagrange().compile()
    nq = system.noether([1, 1])
    steps = 300
    U = np.cos(0.1 * np.arange(steps))
    traj = sim.simulate({"a": (0.0, 0.01), "b": (1.0, 1.0), "u": 0.5}, steps, PLANE_PARAMS,
                        inputs=U)
    assert np.abs(nq.impulse(traj)).max() < 1e-16
    J = nq.along(traj)
    # J = m·(Δa + Δb)/h reads coordinates rounded to ε·|q|: rounding is ε·m·|q|/h per state,
    # a random walk over the steps (the conserved drift would be 1e-2 without conservation)
    rounding = np.finfo(float).eps * 1.3 * np.abs(traj.states[:, :4]).max() / 0.01
    assert np.ptp(J) < 4 * np.sqrt(steps) * rounding
    gap = traj["a"] - traj["b"]
    assert np.ptp(gap) > 1e-2  # the internal force does move the particles apart


def test_forced_noether_balance_on_a_lie_group():
    """An axisymmetric rigid body (I1 = I2) on SO(3) with body torques as inputs: the third
    body momentum changes by the torque's impulse (h/2)(τ3_k + τ3_{k+1}) to rounding."""
    I12, I3 = sp.symbols("I I3", positive=True)
    tau = sp.symbols("tau1:4", real=True)
    Jd = systems.discrete_inertia(I12, I12, I3)

    def L(g):
        return -(Jd * g.matrix).trace() / h

    def forces(g):
        half = [h / 2 * t for t in tau]
        return half, half

    system = sg.DiscreteSystem(sg.SO3("W"), L, parameters=[h, I12, I3], forces=forces,
                               inputs=list(tau), name="spun", time_step=h)
    nq = system.noether(2)
    assert nq.is_symmetry
    sim = system.euler_lagrange().compile()
    W0 = sp.matrix2numpy(sp.rot_axis1(0.02) * sp.rot_axis3(0.05), dtype=float).T
    steps = 200
    rng = np.random.default_rng(5)
    U = rng.normal(size=(steps, 3))
    traj = sim.simulate({"W": W0, "tau1": 0.0, "tau2": 0.0, "tau3": 0.1}, steps,
                        {"h": 0.05, "I": 1.0, "I3": 2.0}, inputs=U)
    J = nq.along(traj)
    impulse = nq.impulse(traj)
    np.testing.assert_allclose(impulse[1:], 0.05 / 2 * (U[:-1, 2] + U[1:, 2]), rtol=1e-14)
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-12)


# --- inputs at run time ------------------------------------------------------------------------

def test_inputs_through_simulate_step_and_numpy_agree_bitwise(plane):
    steps = 40
    U = np.linspace(-1, 1, steps)[:, None]
    options = sg.NewtonOptions(extrapolate=False)
    start = {"x": (1.0, 1.0), "y": (0.0, 0.012), "u": [0.3]}
    traj = plane.simulate(start, steps, PLANE_PARAMS, inputs=U, options=options)
    state = plane.state(start, PLANE_PARAMS)
    n = plane.layout.n_known - 1  # the last entry: the slot of the input to come
    for j in range(steps):
        state = plane.step(state, PLANE_PARAMS, inputs=U[j], options=options)
        assert np.array_equal(state[:n], traj.states[j + 1, :n])
    twin = plane.equations.compile(backend="numpy")
    other = twin.simulate(start, steps, PLANE_PARAMS, inputs=U, options=options)
    assert np.array_equal(other.states, traj.states)
    assert np.array_equal(traj["u"], np.r_[0.3, U[:, 0]])
    held = plane.simulate(start, steps, PLANE_PARAMS, inputs=[0.2])
    assert np.array_equal(held["u"][1:], np.full(steps, 0.2))


def test_a_run_keeps_every_kth_state_with_inputs(plane):
    U = np.sin(np.arange(30))[:, None]
    whole = plane.simulate({"x": (1.0, 1.0), "y": (0.0, 0.012), "u": 0.0}, 30, PLANE_PARAMS,
                           inputs=U)
    sampled = plane.simulate({"x": (1.0, 1.0), "y": (0.0, 0.012), "u": 0.0}, 30,
                             PLANE_PARAMS, inputs=U, every=7)
    assert np.array_equal(sampled.states, whole.states[[0, 7, 14, 21, 28, 30]])


@pytest.mark.parametrize("bad, error", [
    (None, ShapeError), (np.zeros((5, 2)), ShapeError), (np.zeros(3), ShapeError),
    (np.r_[0.0, np.nan, 0, 0, 0, 0, 0, 0, 0, 0], DomainError),
    ([["a"]] * 10, sg.SymgroupoidError),
])
def test_bad_input_sequences_are_refused_before_any_step(plane, bad, error):
    with pytest.raises(error):
        plane.simulate({"x": (1.0, 1.0), "y": (0.0, 0.0), "u": 0.0}, 10, PLANE_PARAMS,
                       inputs=bad)


def test_entry_points_without_inputs_refuse_a_system_with_inputs(plane):
    start = {"x": (1.0, 1.0), "y": (0.0, 0.0), "u": 0.0}
    with pytest.raises(ShapeError, match="inputs"):
        plane.simulate_batch([start, start], 5, PLANE_PARAMS)
    with pytest.raises(ShapeError, match="inputs"):
        plane.stream(start, 5, PLANE_PARAMS)
    with pytest.raises(ShapeError, match="inputs"):
        sg.sweep(plane, start, PLANE_PARAMS, 5)
    with pytest.raises(ShapeError, match="inputs"):
        plane.step(plane.state(start, PLANE_PARAMS), PLANE_PARAMS)


def test_a_system_without_inputs_takes_none():
    sim = _plane_system().euler_lagrange().compile()
    with pytest.raises(ShapeError, match="no inputs"):
        sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.0)}, 3, PLANE_PARAMS, inputs=[1.0])


# --- hostile declarations ----------------------------------------------------------------------

@pytest.mark.parametrize("forces, inputs, error", [
    (lambda g: ([1], [1]), [], ShapeError),  # one component, rank 2
    (lambda g: [[1, 1]], [], ShapeError),  # not a pair
    (lambda g: ([c * w, 0], [0, 0]), [], UndeclaredSymbolError),  # w not declared
    (lambda g: ([h, 0], [0, 0]), [h], InputNameError),  # an input that is a parameter
    (lambda g: ([0, 0], [0, 0]), [sp.Symbol("x")], InputNameError),  # a coordinate's name
    (None, [u], UnsupportedFeatureError),  # inputs without forces
    ("not callable", [], CallableError),
    (lambda g: ([0, 0], [0, 0]), ["u"], InputTypeError),  # an input that is no symbol
    (lambda g: ([0, 0], [0, 0]), [u, u], InputNameError),  # declared twice
    (lambda g: 1 / 0, [], CallableError),
])
def test_bad_forces_are_refused_at_construction(forces, inputs, error):
    with pytest.raises(error):
        _plane_system(forces, inputs)


@pytest.mark.parametrize("name", ["u_k", "u_{k+1}", "w_{k-1}"])
def test_an_input_named_as_a_value_at_a_step_is_refused_as_an_input(name):
    """An input u_k would print as the value of an input u at step k; the refusal named it
    a "parameter" (the two were checked together)."""
    with pytest.raises(InputNameError, match=rf"input '{re.escape(name)}' cannot be used: it is "
                                             rf"written .*, as a value at a step is"):
        _plane_system(lambda g: ([0, 0], [0, 0]), [sp.Symbol(name, real=True)])


def test_an_integer_input_in_a_power_of_minus_one_steps():
    """SymPy writes cos(nπ) for an integer n as (−1)ⁿ; the program read it as exp(n·log(−1)),
    NaN at every n, so every step failed.  With n = 2 the force is h/2 (cos 2π = 1), with
    n = 3 it is −h/2: the steps of the literal forces, in C and NumPy."""
    n = sp.Symbol("n", integer=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        return (g.target[0] - g.source[0]) ** 2 / (2 * h) - h * g.target[0] ** 2 / 2

    powered = sg.DiscreteSystem(G, L, parameters=[h], time_step=h, inputs=[n], name="power",
                                forces=lambda g: ([h / 2 * sp.cos(n * sp.pi)], [0]))
    residual = powered.euler_lagrange().residuals[0]
    assert any(power.base == -1 for power in residual.atoms(sp.Pow)), residual
    for value in (2.0, 3.0):
        literal = sg.DiscreteSystem(G, L, parameters=[h], time_step=h, name="literal",
                                    forces=lambda g, v=value: ([h / 2 * (-1) ** int(v)], [0]))
        want = literal.euler_lagrange().compile(backend="numpy").simulate(
            {"q": (0.0, 0.1)}, 4, {"h": 0.1})["q"]
        for backend in ("c", "numpy"):
            sim = powered.euler_lagrange().compile(backend=backend)
            got = sim.simulate({"q": (0.0, 0.1), "n": value}, 4, {"h": 0.1},
                               inputs=[value])["q"]
            assert np.allclose(got, want, rtol=0, atol=1e-15), (backend, value)


def test_forces_on_a_second_order_system_take_the_pair():
    """A second-order system's forces are f(g1, g2) -> (f0, f1, f2), the covectors at the
    pair's three base points (docs/conventions.md §20; tests/test_forces_kinds.py)."""
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    with pytest.raises(CallableError):  # a function of one arrow
        sg.SecondOrderSystem(G, lambda g1, g2: g1.target[0] ** 2, parameters=[],
                             forces=lambda g: ([0], [0]))
    with pytest.raises(ShapeError, match="3 covectors"):  # two covectors of first order
        sg.SecondOrderSystem(G, lambda g1, g2: g1.target[0] ** 2, parameters=[],
                             forces=lambda g1, g2: ([0], [0]))


# --- the continuous limit ----------------------------------------------------------------------

def _double_pendulum():
    """The damped, driven double pendulum: midpoint L_d and the midpoint discrete forces
    f± = (h/2)·F(q̄, Δq/h, u) of F = −c·θ̇ + u (torques at the joints)."""
    g0 = sp.Rational(981, 100)
    u1, u2 = sp.symbols("u1 u2", real=True)
    G = sg.PairGroupoid(sg.EuclideanSpace(["a", "b"]))

    def lagrangian(q, v):
        a, b = q
        va, vb = v
        T = va ** 2 + vb ** 2 / 2 + va * vb * sp.cos(a - b)
        V = -2 * g0 * sp.cos(a) - g0 * sp.cos(b)
        return T - V

    def force(q, v, inputs):
        return [-c * v[0] + inputs[0], -c * v[1] + inputs[1]]

    def midpoint(g):
        q0, q1 = g.source, g.target
        return [(x + y) / 2 for x, y in zip(q0, q1)], [(y - x) / h for x, y in zip(q0, q1)]

    def L(g):
        q, v = midpoint(g)
        return h * lagrangian(q, v)

    def forces(g):
        q, v = midpoint(g)
        half = [h / 2 * f for f in force(q, v, (u1, u2))]
        return half, half

    system = sg.DiscreteSystem(G, L, parameters=[h, c], forces=forces, inputs=[u1, u2],
                               name="driven", time_step=h)
    return system, lagrangian, force


def _ode(lagrangian, force, c_value, drive):
    """q̈ from the continuous forced Euler–Lagrange equations, for scipy."""
    q = sp.symbols("qa qb")
    v = sp.symbols("va vb")
    Lc = lagrangian(q, v)
    M = sp.Matrix(2, 2, lambda i, j: sp.diff(Lc, v[i], v[j]))
    rest = sp.Matrix([sp.diff(Lc, q[i]) - sum(sp.diff(Lc, v[i], q[j]) * v[j] for j in range(2))
                      for i in range(2)])
    uu = sp.symbols("ua ub")
    F = sp.Matrix(force(q, v, uu)).subs(c, c_value)
    acc = sp.lambdify([q, v, uu], M.LUsolve(rest + F), "numpy")

    def rhs(t, y):
        return np.r_[y[2:], np.asarray(acc(y[:2], y[2:], drive(t)), float).ravel()]

    return rhs


@pytest.mark.slow
def test_the_driven_damped_double_pendulum_converges_at_order_two():
    from scipy.integrate import solve_ivp

    system, lagrangian, force = _double_pendulum()
    sim = system.euler_lagrange().compile()
    c_value, T = 0.3, 1.0

    def drive(t):
        return (0.5 * np.sin(3 * t), 0.2 * np.cos(2 * t))

    rhs = _ode(lagrangian, force, c_value, drive)
    exact = solve_ivp(rhs, (0, T + 0.1), [0.4, -0.3, 0.0, 0.5], rtol=1e-12, atol=1e-12,
                      dense_output=True, method="DOP853").sol
    errors = []
    for n in (50, 100, 200):
        hh = T / n
        # u of the arrow (q_{j-1}, q_j) at its midpoint time (j - 1/2) h
        U = np.array([drive((j + 0.5) * hh) for j in range(1, n)])
        u0 = drive(0.5 * hh)
        q0, q1 = exact(0.0)[:2], exact(hh)[:2]
        traj = sim.simulate({"a": (q0[0], q1[0]), "b": (q0[1], q1[1]), "u1": u0[0],
                             "u2": u0[1]}, n - 1, {"h": hh, "c": c_value}, inputs=U)
        errors.append(np.abs(np.c_[traj["a"][-1], traj["b"][-1]] - exact(T)[:2]).max())
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert (rates > 1.9).all() and (rates < 2.2).all(), (errors, rates)


# --- ∂F/∂u and the helpers ------------------------------------------------------------------

def test_the_input_jacobian_agrees_with_finite_differences():
    step = _plane_system(_torque_and_damping, [u]).euler_lagrange()
    rng = np.random.default_rng(11)
    x, known = rng.normal(size=len(step.unknowns)), rng.normal(size=len(step.knowns))
    p = rng.uniform(0.5, 2, size=len(step.parameters))
    J = step.input_jacobian(x, known, p)
    assert J.shape == (2, 2)
    eps = 1e-6
    for j, i in enumerate(range(len(known) - 2, len(known))):
        d = np.zeros_like(known)
        d[i] = eps
        fd = (step.evaluate(x, known + d, p)[0] - step.evaluate(x, known - d, p)[0]) / (2 * eps)
        np.testing.assert_allclose(J[:, j], fd, rtol=1e-7, atol=1e-9)
    assert np.abs(J).max() > 1e-3  # the inputs do enter
    with pytest.raises(UnsupportedFeatureError):
        _plane_system().euler_lagrange().input_jacobian(x, known[:-2], p)


def _residuals(forces, inputs=(u,)):
    return _plane_system(forces, list(inputs)).euler_lagrange().residuals


def test_the_midpoint_helper_and_rayleigh_damping_are_the_hand_written_forces():
    def F(q, v):
        r2 = q[0] ** 2 + q[1] ** 2 + 1
        return [-c * v[0] - u * q[1] / r2, -c * v[1] + u * q[0] / r2]

    by_hand = _residuals(_torque_and_damping)
    assert [sp.simplify(a - b) for a, b in zip(_residuals(sg.midpoint_forces(F, h)),
                                               by_hand)] == [0, 0]
    damped = _residuals(sg.rayleigh_damping(lambda q, v: c * (v[0] ** 2 + v[1] ** 2) / 2, h),
                        ())
    plain = _residuals(sg.midpoint_forces(lambda q, v: [-c * v[0], -c * v[1]], h), ())
    assert [sp.simplify(a - b) for a, b in zip(damped, plain)] == [0, 0]


def test_the_trapezoid_helper_evaluates_the_force_at_the_ends():
    f = sg.trapezoid_forces(lambda q, v: [q[0] * v[1], u * q[1]], h)
    G = sg.PairGroupoid(sg.EuclideanSpace(["x", "y"]))
    x0, y0, x1, y1 = sp.symbols("x0 y0 x1 y1")
    minus, plus = f(G.view((x0, y0, x1, y1)))
    assert sp.simplify(minus[0] - h / 2 * x0 * (y1 - y0) / h) == 0
    assert sp.simplify(plus[1] - h / 2 * u * y1) == 0


def test_joint_torques_are_internal():
    f = sg.joint_torque(6, [2], [5], [u], h)
    minus, plus = f(None)
    assert sum(minus) == 0 and minus[2] == h * u / 2 and plus[5] == -h * u / 2
    with pytest.raises(ShapeError):
        sg.joint_torque(6, [2], [6], [u], h)


def test_the_helpers_refuse_what_they_cannot_discretise():
    """By the helpers' own named errors, not wrapped in a CallableError (which would hide
    them from ``except sg.ShapeError``)."""
    with pytest.raises(sg.InputTypeError, match="no consecutive configurations"):
        sg.DiscreteSystem(sg.SO3("W"), lambda g: g.matrix[0, 0], parameters=[h],
                          forces=sg.midpoint_forces(lambda q, v: [0, 0, 0], h))
    with pytest.raises(ShapeError):
        _plane_system(sg.midpoint_forces(lambda q, v: [0], h))


def test_a_continuous_force_of_the_wrong_length_is_a_shape_error():
    """As a DiscreteSystem's forces of the wrong length; it was a CallableError wrapping the
    ShapeError, and a user function that raised was wrapped twice."""
    c = sp.Symbol("c", positive=True)
    system = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * xi)[0, 0] / 2,
                                 parameters=[h, c], forces=lambda R, xi: [-c * xi[0], -c * xi[1]],
                                 name="short_torque")
    with pytest.raises(ShapeError, match=r"returned 2 components; one generalised force per "
                                         r"coordinate \(3\)"):
        system.discretize(h, sg.GaussLegendre(2)).euler_lagrange()

    def fails(R, xi):
        raise IndexError("no such component")

    system = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * xi)[0, 0] / 2,
                                 parameters=[h, c], forces=fails, name="failing_torque")
    with pytest.raises(CallableError) as info:
        system.discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    assert str(info.value).count("raised") == 1, str(info.value)


def test_a_failing_step_keeps_the_run_up_to_it(plane):
    """An input that overflows the residual at step 5: the error names the step and carries
    the states before it, bitwise those of the run without that input."""
    U = np.zeros((10, 1))
    U[5] = 1e308
    start = {"x": (1.0, 1.0), "y": (0.0, 0.012), "u": 0.0}
    with pytest.raises(sg.SymgroupoidError) as info:
        plane.simulate(start, 10, PLANE_PARAMS, inputs=U)
    err = info.value
    assert err.step == 5
    kept = err.trajectory.states
    good = plane.simulate(start, 5, PLANE_PARAMS, inputs=U[:5])
    assert len(kept) == 6 and np.array_equal(kept[:5], good.states[:5])
    assert np.isfinite(kept).all()


@pytest.mark.slow
def test_the_latex_names_the_forces():
    """The printed equations read X⃖[L](g_k) − X⃗[L](g_{k+1}) + f⁺(g_k) + f⁻(g_{k+1}), the
    forces defined in the "where" list (each printed form is verified to be the residual).
    Slow (the longest test of this file); the fast tests print the named forces of a first-
    and a second-order system (tests/test_forces_kinds.py,
    test_the_latex_names_the_forces_of_every_kind) and a forced step's inputs
    (tests/test_forced_latex_matrix.py)."""
    tex = _plane_system(_torque_and_damping, [u]).euler_lagrange().latex()
    for b in (1, 2):
        assert f"f^{{+}}_{{{b}}}(g_{{k}})" in tex and f"f^{{-}}_{{{b}}}(g_{{k+1}})" in tex
    # L in its pieces (the midpoints and difference quotients it is written in), the forces
    # after them in the "where" list (a forced step printed L expanded, 6× longer)
    assert r"\Delta x_{k+1/2}" in tex
    assert "u_{k+1}" in tex.split(r"\intertext{and the discrete forces}")[1]


@pytest.mark.slow
def test_a_forced_chain_prints_l_in_its_pieces():
    """The forced planar chain printed L expanded (12,313 characters, longer than SymPy's
    own printing of the residuals); now through the partial derivatives of L at the
    midpoints, as the unforced chain, and its forces named (each form verified)."""
    from symgroupoid import systems

    forced = systems.planar_chain(2, forced=True).euler_lagrange().latex()
    unforced = systems.planar_chain(2).euler_lagrange().latex()
    assert r"(\partial_{\Delta \theta_{1}} L)_{k+1/2}" in forced
    assert r"f^{-}_{2}(g_{k+1})" in forced and len(forced) < 2 * len(unforced)


EMBED_MAIN = r"""
#include <stdio.h>
#include "plane.h"
/* reads p (4 numbers), the state (6) and n rows of inputs; prints the n + 1 states */
int main(int argc, char **argv)
{
    enum { N = 60 };
    double p[4], known[PLANE_N_KNOWNS], u[N * PLANE_N_INPUTS], states[(N + 1) * PLANE_N_KNOWNS];
    int iterations[N], i;
    double norms[N];
    long failed = -1;
    (void)argc;
    (void)argv;
    for (i = 0; i < 4; ++i) if (scanf("%lf", &p[i]) != 1) return 2;
    for (i = 0; i < PLANE_N_KNOWNS; ++i) if (scanf("%lf", &known[i]) != 1) return 2;
    for (i = 0; i < N * PLANE_N_INPUTS; ++i) if (scanf("%lf", &u[i]) != 1) return 2;
    if (plane_simulate(known, p, u, N, NULL, NULL, states, N + 1, iterations, norms, &failed,
                       NULL) != PLANE_OK) return 1;
    for (i = 0; i < (N + 1) * PLANE_N_KNOWNS; ++i) printf("%.17g\n", states[i]);
    /* a kernel with inputs refuses to run without them */
    return plane_simulate(known, p, NULL, N, NULL, NULL, states, N + 1, iterations, norms,
                          &failed, NULL) == PLANE_INVALID_ARGUMENT ? 0 : 3;
}
"""


def test_the_emitted_c_reads_the_inputs_and_agrees_bitwise(plane, tmp_path):
    import shutil
    import subprocess

    if shutil.which("cc") is None:
        pytest.skip("no C compiler (cc) on PATH")
    sg.emit_c(plane.equations, tmp_path / "plane", prefix="plane")
    (tmp_path / "main.c").write_text(EMBED_MAIN)
    exe = tmp_path / "plane_demo"
    build = subprocess.run(["cc", "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror",
                            "-ffp-contract=off", f"-I{tmp_path}", str(tmp_path / "main.c"),
                            str(tmp_path / "plane.c"), "-lm", "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    U = np.cos(0.3 * np.arange(60))[:, None]
    start = plane.state({"x": (1.0, 1.0), "y": (0.0, 0.012), "u": 0.2}, PLANE_PARAMS)
    data = [*plane.parameters(PLANE_PARAMS), *start, *U[:, 0]]
    run = subprocess.run([str(exe)], input=" ".join(repr(float(v)) for v in data),
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, (run.returncode, run.stderr)
    states = np.array([float(v) for v in run.stdout.split()]).reshape(61, -1)
    traj = plane.simulate(start, 60, PLANE_PARAMS, inputs=U)
    assert np.array_equal(states, traj.states)  # without contraction: the same bits (§17)
    assert np.array_equal(states[:, 4], np.r_[0.2, U[:, 0]])


@pytest.mark.parametrize("bad, error", [
    ([np.nan], DomainError), ([0.0, 1.0], ShapeError), (np.array([np.inf]), DomainError),
    ("u", sg.SymgroupoidError), (np.zeros((1, 1)), ShapeError),
])
def test_a_step_refuses_bad_inputs(plane, bad, error):
    state = plane.state({"x": (1.0, 1.0), "y": (0.0, 0.0), "u": 0.0}, PLANE_PARAMS)
    with pytest.raises(error):
        plane.step(state, PLANE_PARAMS, inputs=bad)


def test_the_helpers_refuse_a_bad_rule_or_force():
    """At once, before any derivation: a rule that is none of the two, a force that is not
    a function; a function that fails on the arrow is a CallableError at derivation."""
    with pytest.raises(sg.DomainError, match="rule must be one of 'midpoint', 'trapezoid'"):
        sg.rayleigh_damping(lambda q, v: 0, h, rule="euler")
    with pytest.raises(InputTypeError, match="midpoint_forces: F must be a function"):
        sg.midpoint_forces("not a function", h)
    with pytest.raises(CallableError):
        _plane_system(sg.midpoint_forces(lambda q, v: 1 / 0, h))
