"""Continuous forces with the Galerkin schemes (docs/conventions.md §22, "Forces"): the
forced Galerkin step is the discrete Lagrange–d'Alembert principle with the quadrature of the
virtual work h Σ_i b_i F(q_i, v_i)·δq_i, written here by hand in Marsden–West's control-point
form and compared symbolically; the observed orders against DOP853 solutions of the forced
equations on R (a damped, driven Duffing oscillator) and on SO(3) (a rigid body with a
body-frame damping torque and an input torque); the inputs held per arrow; the forced Noether
balance of a translation with internal forces; the C and NumPy evaluators give the same
bits."""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import symgroupoid as sg
from symgroupoid import UnsupportedFeatureError

h = sp.Symbol("h", positive=True)
c = sp.Symbol("c", real=True)
u = sp.Symbol("u", real=True)
C, U = 0.4, 0.7  # damping and a constant drive


def _duffing(inputs: bool = True) -> sg.ContinuousSystem:
    """q̈ = −q − q³ − c q̇ + u."""
    return sg.ContinuousSystem(
        sg.EuclideanSpace("q"), lambda q, v: v[0] ** 2 / 2 - q[0] ** 2 / 2 - q[0] ** 4 / 4,
        parameters=[h, c], forces=lambda q, v: [-c * v[0] + (u if inputs else 0)],
        inputs=[u] if inputs else [], name="duffing")


def _duffing_solution(drive, T: float):
    def rhs(t, y):
        return [y[1], -y[0] - y[0] ** 3 - C * y[1] + drive(t)]

    return solve_ivp(rhs, (0, T), [0.5, 0.3], method="DOP853", rtol=1e-13, atol=1e-13,
                     dense_output=True).sol


def _duffing_errors(sim, steps, T: float = 2.0) -> np.ndarray:
    """Final-time errors from the exact first arrow (q(0), q(h)), the drive held at U."""
    exact = _duffing_solution(lambda t: U, T)
    errors = []
    for n in steps:
        dt = T / n
        traj = sim.simulate({"q": (exact(0)[0], exact(dt)[0]), "u": [U]}, n - 1,
                            {"h": dt, "c": C}, inputs=np.full((n - 1, 1), U))
        errors.append(abs(traj.states[-1][1] - exact(T)[0]))
    return np.array(errors)


def _order(steps, errors) -> float:
    return float(-np.polyfit(np.log(steps), np.log(errors), 1)[0])


# --- the step is the forced Galerkin principle -------------------------------------------------

def test_the_forced_gauss_step_is_marsden_west_forced_galerkin():
    """GaussLegendre(2) on R, written by hand: control points P₀ = q₀, P₁ = q₀ + Δ/2 + ζ,
    P₂ = q₁, the curve q(τh) = Σ_j ℓ_j(τ) P_j, the action h Σ_i b_i L, and the forces of
    the control points f_j = h Σ_i b_i ℓ_j(c_i) F(q(c_i h), q̇(c_i h)) carried to the
    arrow's ends and the stage by the chain rule (∂P₁/∂q₀ = ∂P₁/∂q₁ = 1/2): f⁻ = f₀ + f₁/2,
    f⁺ = f₂ + f₁/2, f_ζ = f₁.  The discretised system's step equals this one."""
    tau = sp.Symbol("tau")
    nodes = [sp.Rational(1, 2) - sp.sqrt(3) / 6, sp.Rational(1, 2) + sp.sqrt(3) / 6]
    times = [0, sp.Rational(1, 2), 1]
    ell = [sp.prod([(tau - times[i]) / (times[j] - times[i]) for i in range(3) if i != j])
           for j in range(3)]

    def lagrangian(q, v):
        return v ** 2 / 2 - q ** 2 / 2 - q ** 4 / 4

    def force(q, v):
        return -c * v + u

    def curve(g, z):
        q0, q1 = g.source[0], g.target[0]
        P = [q0, q0 + (q1 - q0) / 2 + z[0], q1]
        at = [(sum(e.subs(tau, ci) * p for e, p in zip(ell, P)),
               sum(sp.diff(e, tau).subs(tau, ci) * p for e, p in zip(ell, P)) / h)
              for ci in nodes]
        return at

    def L(g, z):
        return h * sum(lagrangian(q, v) for q, v in curve(g, z)) / 2

    def forces(g, z):
        f = [h * sum(e.subs(tau, ci) * force(q, v) for ci, (q, v) in zip(nodes, curve(g, z)))
             / 2 for e in ell]
        return [f[0] + f[1] / 2], [f[2] + f[1] / 2], [f[1]]

    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    by_hand = sg.DiscreteSystem(G, L, parameters=[h, c], forces=forces, inputs=[u],
                                stages=1, time_step=h, name="by_hand").euler_lagrange()
    derived = _duffing().discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    assert len(derived) == len(by_hand) == 3
    for a, b in zip(derived.residuals, by_hand.residuals):
        assert sp.simplify(a - b) == 0
    # the stage rows carry the forces: ∂L/∂ζ + f_ζ
    assert derived.residuals[1].has(c)
    assert "u_{k+1}" in {str(s) for s in derived.residuals[2].free_symbols}


def test_forces_on_a_discrete_system_with_stages_are_checked():
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g, z):
        return (g.target[0] - g.source[0]) ** 2 / (2 * h) + z[0] ** 2

    with pytest.raises(sg.ShapeError, match="f_minus, f_plus, f_stages"):
        sg.DiscreteSystem(G, L, parameters=[h], stages=1, forces=lambda g, z: ([0], [0]))
    with pytest.raises(sg.ShapeError, match="one per internal stage"):
        sg.DiscreteSystem(G, L, parameters=[h], stages=1,
                          forces=lambda g, z: ([0], [0], [z[0], 1]))


# --- orders --------------------------------------------------------------------------------------

@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2), sg.LobattoIIIAB(3)])
def test_the_damped_driven_oscillator_converges_at_order_four(scheme):
    steps = [10, 20, 40]
    sim = _duffing().discretize(h, scheme).euler_lagrange().compile(backend="numpy")
    errors = _duffing_errors(sim, steps)
    assert abs(_order(steps, errors) - 4) < 0.1, errors
    assert errors[-1] < 5e-8  # measured: 1.6e-8 (Gauss), 4.2e-9 (Lobatto)


@pytest.mark.slow
def test_gauss_three_with_forces_converges_at_order_six():
    steps = [10, 20, 40]
    sim = _duffing().discretize(h, sg.GaussLegendre(3)).euler_lagrange().compile()
    errors = _duffing_errors(sim, steps)
    assert abs(_order(steps, errors) - 6) < 0.1, errors


def test_the_inputs_are_held_over_each_arrow():
    """u_k belongs to the arrow (q_k, q_{k+1}) (docs/conventions.md §20): with the drive
    sampled at each arrow's midpoint time and held over it, the run converges at order 4 to
    the solution of the equations driven by that piecewise-constant input (the reference
    integrates each arrow's interval with its own u_k)."""
    sim = _duffing().discretize(h, sg.GaussLegendre(2)).euler_lagrange().compile(
        backend="numpy")
    T, steps, errors = 2.0, [10, 20, 40], []
    for n in steps:
        dt = T / n
        held = np.sin(3 * (np.arange(n) + 0.5) * dt)  # u_k of the arrow k
        y, states = np.array([0.5, 0.3]), [0.5]
        for k in range(n):
            def rhs(t, y, drive=held[k]):
                return [y[1], -y[0] - y[0] ** 3 - C * y[1] + drive]
            y = solve_ivp(rhs, (0, dt), y, method="DOP853", rtol=1e-13, atol=1e-13).y[:, -1]
            states.append(y[0])
        traj = sim.simulate({"q": (states[0], states[1]), "u": [held[0]]}, n - 1,
                            {"h": dt, "c": C}, inputs=held[1:, None])
        errors.append(abs(traj.states[-1][1] - states[-1]))
    assert abs(_order(steps, errors) - 4) < 0.1, errors


# --- from a velocity: the forced discrete Legendre transform ---------------------------------

@pytest.mark.parametrize("scheme, order", [("midpoint", 2), (sg.GaussLegendre(2), 4),
                                           (sg.LobattoIIIAB(3), 4)])
def test_the_order_from_a_velocity_is_the_schemes(scheme, order):
    """convergence_order starts from (q₀, v₀) through from_velocity: with the forced
    discrete Legendre transform F⁻L − f⁻ = p₀ the observed order is the scheme's (without
    f⁻ it was 1.0 for every scheme: the start O(h) away)."""
    exact = _duffing_solution(lambda t: 0.0, 1.0)
    report = sg.convergence_order(_duffing(inputs=False), scheme, ({"q": 0.5}, [0.3]),
                                  {"c": C}, 1.0, [10, 20, 40], reference=[exact(1.0)[0]],
                                  backend="numpy")
    assert abs(report.order - order) < 0.1, report


def test_from_velocity_reads_the_inputs_of_the_first_arrow():
    """The inputs u₁ of g₁ enter f⁻(g₁) and the forced stage rows of the start."""
    sim = _duffing().discretize(h, sg.GaussLegendre(2)).euler_lagrange().compile(
        backend="numpy")
    exact = _duffing_solution(lambda t: U, 2.0)
    errors, steps = [], [10, 20, 40]
    for n in steps:
        params = {"h": 2.0 / n, "c": C}
        start = sim.from_velocity({"q": 0.5}, [0.3], params, inputs=[U])
        traj = sim.simulate(start, n - 1, params, inputs=np.full((n - 1, 1), U))
        errors.append(abs(traj.states[-1][1] - exact(2.0)[0]))
    assert abs(_order(steps, errors) - 4) < 0.1, errors
    # from_momentum keeps its meaning, F⁻L(g₁) = p₀: another first arrow
    params = {"h": 0.1, "c": C}
    forced = sim.from_velocity({"q": 0.5}, [0.3], params, inputs=[U])
    plain = sim.from_momentum({"q": 0.5}, [0.3], params, inputs=[U])
    assert abs(forced[1] - plain[1]) > 1e-4


# --- the forced Noether balance ----------------------------------------------------------------

@pytest.mark.parametrize("scheme", [sg.GaussLegendre(2), sg.LobattoIIIAB(3)])
def test_internal_forces_keep_the_momentum_and_inputs_change_it_by_their_impulse(scheme):
    """Two particles on a line with an internal spring and damper, and a drive u on the
    first: L is invariant under translations, whose Noether quantity is J = Σ_p Δq_p/h (the
    stage terms integrate ℓ_j′ exactly).  The forced balance (docs/conventions.md §20) is
    J_{k+1} − J_k = f⁺(g_k)·X + f⁻(g_{k+1})·X = h (u_k + u_{k+1})/2, to rounding, for
    inputs changing at every step; the damper, internal, does not enter it."""
    pair = sg.ContinuousSystem(
        sg.EuclideanSpace("x y"),
        lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - (q[0] - q[1]) ** 2 / 2
        - (q[0] - q[1]) ** 4 / 4,
        parameters=[h, c], forces=lambda q, v: [-c * (v[0] - v[1]) + u, c * (v[0] - v[1])],
        inputs=[u], name="pair")
    sim = pair.discretize(h, scheme).euler_lagrange().compile(backend="numpy")
    dt, n = 0.05, 400
    U_ = np.random.default_rng(3).uniform(-1, 1, n + 1)
    traj = sim.simulate({"x": (0.0, 0.02), "y": (1.0, 0.99), "u": [U_[0]]}, n,
                        {"h": dt, "c": C}, inputs=U_[1:, None])
    x = traj.states[:, :4]  # (x_k, y_k, x_{k+1}, y_{k+1})
    J = (x[:, 2] - x[:, 0] + x[:, 3] - x[:, 1]) / dt
    impulse = dt * (U_[:-1] + U_[1:]) / 2
    assert np.abs(np.diff(J) - impulse).max() < 1e-12
    assert np.abs(impulse).max() > 1e-3  # a real change
    # and without the drive the momentum is kept while the damper acts
    quiet = sim.simulate({"x": (0.0, 0.02), "y": (1.0, 0.99), "u": [0.0]}, n,
                         {"h": dt, "c": C}, inputs=np.zeros((n, 1)))
    x = quiet.states[:, :4]
    J = (x[:, 2] - x[:, 0] + x[:, 3] - x[:, 1]) / dt
    assert np.abs(J - J[0]).max() < 1e-12
    gap = x[:, 2] - x[:, 3]
    assert abs(gap[-1]) < 0.1 * abs(gap[0])  # damped towards the spring's rest


# --- evaluators ----------------------------------------------------------------------------------

def test_c_and_numpy_give_the_same_bits():
    step = _duffing().discretize(h, sg.LobattoIIIAB(3)).euler_lagrange()
    start = {"q": (0.5, 0.52), "u": [U]}
    drive = np.sin(np.arange(50) * 0.1)[:, None]
    runs = [step.compile(backend=b).simulate(start, 50, {"h": 0.05, "c": C}, inputs=drive)
            for b in ("numpy", "c")]
    assert np.array_equal(runs[0].states, runs[1].states)


# --- on SO(3) ------------------------------------------------------------------------------------

J_BODY = sp.diag(*sp.symbols("J1:4", positive=True))
D_BODY = sp.Symbol("d", real=True)
TORQUE = sp.symbols("tau1:4", real=True)
INERTIA, DAMPING, INPUT = np.diag([1.0, 2.0, 3.0]), 0.3, np.array([0.1, -0.2, 0.05])


def _damped_body() -> sg.ContinuousSystem:
    """A rigid body with the body-frame torque −d ξ + τ (τ an input)."""
    return sg.ContinuousSystem(
        sg.SO3("R"), lambda R, xi: (xi.T * J_BODY * xi)[0, 0] / 2,
        parameters=[h, *J_BODY.diagonal(), D_BODY],
        forces=lambda R, xi: [-D_BODY * xi[a] + TORQUE[a] for a in range(3)],
        inputs=list(TORQUE), name="damped_body")


def _body_solution(T: float):
    def rhs(t, y):
        R, w = y[:9].reshape(3, 3), y[9:]
        hat = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.r_[(R @ hat).ravel(),
                     np.linalg.solve(INERTIA, np.cross(INERTIA @ w, w) - DAMPING * w + INPUT)]

    return solve_ivp(rhs, (0, T), np.r_[np.eye(3).ravel(), 0.3, 1.0, 0.4], method="DOP853",
                     rtol=1e-13, atol=1e-13, dense_output=True).sol


def _body_errors(sim, steps, T: float = 2.0) -> np.ndarray:
    exact = _body_solution(T)
    params = {"J1": 1.0, "J2": 2.0, "J3": 3.0, "d": DAMPING}
    errors = []
    for n in steps:
        dt = T / n
        start = {"R": (exact(0)[:9].reshape(3, 3), exact(dt)[:9].reshape(3, 3)),
                 **{f"tau{a + 1}": INPUT[a] for a in range(3)}}
        traj = sim.simulate(start, n - 1, {**params, "h": dt},
                            inputs=np.tile(INPUT, (n - 1, 1)))
        final = np.asarray(traj.configurations())[-1]
        errors.append(np.abs(final.ravel() - exact(T)[:9]).max())
    return np.array(errors)


def test_the_damped_rigid_body_converges_at_order_four():
    """GaussLegendre(2) on SO(3) through the Cayley retraction: the torque pairs with the
    body variation of every node, Ad_{τ(x_i)⁻¹}η₀ + dτ_{x_i}(δx_i)."""
    steps = [20, 40, 80]
    step = _damped_body().discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    errors = _body_errors(step.compile(backend="numpy"), steps)
    assert abs(_order(steps, errors) - 4) < 0.1, errors


@pytest.mark.slow
def test_the_damped_rigid_body_with_lobatto_converges_at_order_four_in_c():
    steps = [20, 40, 80]
    step = _damped_body().discretize(h, sg.LobattoIIIAB(3)).euler_lagrange()
    errors = _body_errors(step.compile(), steps)
    assert abs(_order(steps, errors) - 4) < 0.1, errors


# --- what stays refused ------------------------------------------------------------------------

def test_the_rules_without_stages_refuse_forces_on_a_group():
    with pytest.raises(UnsupportedFeatureError, match="Galerkin"):
        _damped_body().discretize(h, "midpoint")
