"""Newton's rounding floors at large coordinates, its distinct failures, and branch jumps.

A residual written in increments of positions far from the origin, (x_{k+1} − x_k)/h at
|x| ~ 10³, cannot go below ε·|x|/h whatever the (small) unknowns: the floor must count the
size of the terms the residual is computed from (the program's ``F_scale``), not only the
unknowns.  Free and falling bodies on the pair groupoids of SE(2) and SE(3) (and their
increment coordinates) run 10⁵ steps, their increments constant to rounding.  The iteration
cap and a stalled update are different failures with their own messages, and a step whose
solution jumps far outside the trust region of its guess (q̈ = q³ past the fold of its
midpoint step) stops with :class:`~symgroupoid.BranchJumpError`, in C and NumPy alike.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from kernel_support import BACKENDS, SESSION_CACHE, isolated_cache, needs_cc  # noqa: F401

import symgroupoid as sg
from symgroupoid.stepper import STATUS_MESSAGES, Status

BRANCH_JUMP, NOT_CONVERGED, STALLED = Status.BRANCH_JUMP, Status.NOT_CONVERGED, Status.STALLED

h, m, J, grav = sp.symbols("h m J g", positive=True)
PARAMS = {"h": 0.01, "m": 1.0, "J": 0.1, "g": 9.81}
EPS = np.finfo(float).eps
#: the Cayley coordinates of the first increment: 2 rad/s and 1 m/s at h = 0.01
INCREMENT = [0.02, 0.01, 0.0]


def body_se2(groupoid_kind: str, falling: bool) -> sg.DiscreteSystem:
    """L = h(m|Δp/h|²/2 + J(ΔR₁₀/h)²/2) (− h m g (y₀ + y₁)/2 when falling) on the pair
    groupoid of SE(2), or in its increment coordinates (Δp = R₀ F_p, ΔR = F_R)."""
    S = sg.SE2("q")

    def lagrangian(q0, F):
        dp = q0[:2, :2] * F[:2, 2]
        L = h * (m * (dp.T * dp)[0, 0] / h**2 / 2 + J * (F[1, 0] / h) ** 2 / 2)
        if falling:
            L -= h * m * grav * (2 * q0[1, 2] + dp[1]) / 2
        return L

    if groupoid_kind == "pair":
        G = sg.PairGroupoid(S)
        def L(a):
            return lagrangian(a.source, S._inverse_matrix(a.source) * a.target)
    else:
        G = sg.TrivialisedPairGroupoid(S)
        def L(a):
            return lagrangian(a.source, a.increment)
    return sg.DiscreteSystem(G, L, parameters=[h, m, J, grav],
                             name=f"{'falling' if falling else 'free'}_se2_{groupoid_kind}")


def body_se3(groupoid_kind: str) -> sg.DiscreteSystem:
    """A free rigid body on SE(3): L = (tr((I − F_R) J_d) + |R₀ F_p|²/2)/h."""
    S = sg.SE3("g")
    Jd = sp.diag(1, 2, 3)

    def lagrangian(q0, F):
        move = q0[:3, :3] * F[:3, 3]
        return (((sp.eye(3) - F[:3, :3]) * Jd).trace() + (move.T * move)[0, 0] / 2) / h

    if groupoid_kind == "pair":
        G = sg.PairGroupoid(S)
        def L(a):
            return lagrangian(a.source, S._inverse_matrix(a.source) * a.target)
    else:
        G = sg.TrivialisedPairGroupoid(S)
        def L(a):
            return lagrangian(a.source, a.increment)
    return sg.DiscreteSystem(G, L, parameters=[h], name=f"free_se3_{groupoid_kind}")


def se2_state(groupoid_kind: str, start=(0.0, 0.0)) -> dict:
    """Moving at 1 m/s along x and spinning at 2 rad/s (h = 0.01)."""
    S = sg.SE2("q")
    q0 = S.numeric_tau([0.0, 0.0, 0.0])
    q0[:2, 2] = start
    F = S.numeric_tau(INCREMENT)
    return {"q": (q0, q0 @ F)} if groupoid_kind == "pair" else {"q": q0, "Fq": F}


def positions(sim, traj, name="q", rows=slice(0, 2)) -> tuple[np.ndarray, np.ndarray]:
    """(j, p_j): the translation of a configuration q_j of every kept state: its target
    q_{k+1} on the pair groupoid (whose view lists q_0, then the targets of the kept arrows),
    its q_k in increment coordinates (whose view lists the q_k)."""
    q = np.asarray(sim.layout.view(traj.states, name))
    k = traj.step_indices
    if len(q) == len(k) + 1:
        return k + 1, q[1:, rows, -1]
    return k, q[:, rows, -1]


@needs_cc
@pytest.mark.parametrize("kind", ["pair", "increments"])
def test_free_planar_body_runs_far_with_constant_increments(kind):
    """10⁵ steps to x ≈ 10³ m (the pair groupoid failed at x ≈ 128 m with a false 'iteration
    cap'): the spatial increment q_{k+1} − q_k of the free body stays 0.01 m to the
    rounding of |q_k|."""
    system = body_se2(kind, falling=False)
    sim = system.euler_lagrange().compile(cache_dir=SESSION_CACHE)
    traj = sim.simulate(se2_state(kind), 10**5, PARAMS, every=100)
    _, p = positions(sim, traj)
    assert p[-1, 0] > 998.0
    assert traj.newton_iterations.max() <= 100 * 6  # a handful of updates per step
    step = np.diff(p, axis=0) / 100  # mean increment over each kept interval
    assert np.abs(step - step[0]).max() <= 100 * EPS * np.abs(p).max()


@needs_cc
@pytest.mark.parametrize("kind", ["pair", "increments"])
def test_falling_planar_body_follows_its_discrete_parabola(kind):
    """Under gravity the discrete trajectory is exactly y_k = y_0 + k·v_0·h − g h² k(k−1)/2
    (the DEL m(y_{k+1} − 2y_k + y_{k−1})/h² = −m g); 10⁵ steps to |y| ≈ 5·10⁶ m (it
    stopped at step 780 with 'iteration cap after 4 iterations')."""
    sim = body_se2(kind, falling=True).euler_lagrange().compile(cache_dir=SESSION_CACHE)
    traj = sim.simulate(se2_state(kind), 10**5, PARAMS, every=1000)
    j, p = positions(sim, traj)
    y, k = p[:, 1], j.astype(float)
    hh, y1 = PARAMS["h"], sg.SE2("q").numeric_tau(INCREMENT)[1, 2]  # y_1
    expected = k * y1 - PARAMS["g"] * hh**2 * k * (k - 1) / 2  # (y_0 = 0)
    assert abs(y[-1]) > 4e6
    np.testing.assert_allclose(y, expected, rtol=1e-9, atol=1e-12)


@needs_cc
@pytest.mark.parametrize("kind", ["pair", "increments"])
def test_free_se3_body_drifts_far(kind):
    """A free SE(3) body drifting at 1 m/s (it stopped at step 7 899 on the pair
    groupoid): 10⁵ steps, the spatial increment constant to the rounding of |p|."""
    S = sg.SE3("g")
    sim = body_se3(kind).euler_lagrange().compile(cache_dir=SESSION_CACHE)
    M0 = S.numeric_tau([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    F = S.numeric_tau([0.01, -0.02, 0.015, 0.01, 0.0, 0.0])
    state = {"g": (M0, M0 @ F)} if kind == "pair" else {"g": M0, "Fg": F}
    traj = sim.simulate(state, 10**5, {"h": 0.01}, every=100)
    _, p = positions(sim, traj, "g", slice(0, 3))
    assert np.linalg.norm(p[-1]) > 900.0
    step = np.diff(p, axis=0) / 100
    assert np.abs(step - step[0]).max() <= 100 * EPS * np.abs(p).max()


@needs_cc
@pytest.mark.parametrize("kind", ["pair", "increments"])
def test_c_and_numpy_accept_at_the_same_floor(kind):
    """Far from the origin (x = 10⁴ m) from the first step on, the NumPy twin stops where C
    stops, bit for bit."""
    step = body_se2(kind, falling=True).euler_lagrange()
    state = se2_state(kind, start=(1e4, -3e4))
    c = step.compile(cache_dir=SESSION_CACHE).simulate(state, 200, PARAMS)
    numpy = step.compile(backend="numpy").simulate(state, 200, PARAMS)
    np.testing.assert_array_equal(c.states, numpy.states)
    np.testing.assert_array_equal(c.newton_iterations, numpy.newton_iterations)


@pytest.mark.parametrize("backend", BACKENDS)
def test_iteration_cap_and_stall_are_told_apart(backend):
    """Without the floors (floor_factor = 0) the falling body cannot be accepted once its
    residual is at the rounding of its terms: its update reaches the rounding noise of the
    solve (STALLED, after a few iterations, once the body has fallen far enough for the
    rounding of its terms to outgrow the tolerance: step 360 on one machine, 420 on another,
    where the processor's rounding differs); a cap of 2 updates is reached at once
    (NOT_CONVERGED).  Two statuses, two messages, each with the true iteration count (two
    tries of a step past the second: from the extrapolated guess and the prediction)."""
    sim = body_se2("pair", falling=True).euler_lagrange().compile(backend=backend,
                                                                 cache_dir=SESSION_CACHE)
    with pytest.raises(sg.NewtonDivergenceError) as stalled:
        sim.simulate(se2_state("pair"), 1000, PARAMS,
                     options=sg.NewtonOptions(floor_factor=0.0))
    text = str(stalled.value)
    k = stalled.value.step
    assert 200 <= k <= 600 and STATUS_MESSAGES[STALLED] in text
    run = stalled.value.trajectory
    assert len(run) == k + 1
    assert "two tries of at most 50 each" in text
    with pytest.raises(sg.NewtonDivergenceError) as capped:
        sim.simulate(se2_state("pair"), 1000, PARAMS, options=sg.NewtonOptions(max_iterations=2))
    text = str(capped.value)
    assert STATUS_MESSAGES[NOT_CONVERGED] in text and "max_iterations=2)" in text
    k = capped.value.step
    assert f"after {2 if k < 2 else 4} Newton iterations" in text
    assert STATUS_MESSAGES[STALLED] != STATUS_MESSAGES[NOT_CONVERGED]


def oscillator() -> sg.DiscreteSystem:
    """q̈ = −q by the midpoint rule: a linear step, solved exactly by one Newton update."""
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h * (((q1 - q0) / h) ** 2 / 2 - ((q0 + q1) / 2) ** 2 / 2)

    return sg.DiscreteSystem(G, L, parameters=[h], name="oscillator")


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_cap_accepts_an_iterate_at_the_rounding_floor(backend):
    """A linear step is solved by its one update, its residual then at rounding (4e-15):
    with max_iterations=1 every step was NOT_CONVERGED ("after 1 Newton iteration, |F| =
    4.2e-15").  At the cap an iterate at the rounding floor is accepted, as after a final
    update, with the same bits as the uncapped run where both stop there; and max_iterations=0
    accepts a guess only where it already solves the step."""
    sim = oscillator().euler_lagrange().compile(backend=backend, cache_dir=SESSION_CACHE)
    capped = sim.simulate({"q": (1.0, 0.999)}, 200, {"h": 0.01},
                          options=sg.NewtonOptions(max_iterations=1))
    assert np.all(capped.newton_iterations == 1) and capped.residual_norms.max() < 1e-13
    free = sim.simulate({"q": (1.0, 0.999)}, 200, {"h": 0.01})
    assert np.max(np.abs(capped["q"] - free["q"])) < 1e-13
    with pytest.raises(sg.NewtonDivergenceError, match="max_iterations=0"):
        sim.simulate({"q": (1.0, 0.999)}, 5, {"h": 0.01},
                     options=sg.NewtonOptions(max_iterations=0))
    rest = sim.simulate({"q": (0.0, 0.0)}, 5, {"h": 0.01},
                        options=sg.NewtonOptions(max_iterations=0))
    assert np.all(rest["q"] == 0.0) and np.all(rest.newton_iterations == 0)


def cubic_system() -> sg.DiscreteSystem:
    """q̈ = q³ by the midpoint rule: L_d = h(((q₁ − q₀)/h)²/2 + ((q₀ + q₁)/2)⁴/4)."""
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h * (((q1 - q0) / h) ** 2 / 2 + ((q0 + q1) / 2) ** 4 / 4)

    return sg.DiscreteSystem(G, L, parameters=[h], name="cubic_blowup")


@pytest.mark.parametrize("backend", BACKENDS)
def test_no_silent_branch_jump(backend):
    """h = 0.05, q₀ = 1, q₁ = 1.025: the root near the motion disappears at step 27 (the
    last step moved 4.2); the only real root lies ~118 away.  The run stops there with
    BranchJumpError and the trajectory so far; with the check off it goes on along the
    spurious branch, solved to rounding at every step, to |q| ~ 4·10⁵ (it stopped after 99
    more steps, when the iteration cap was reached at an iterate at the rounding floor)."""
    sim = cubic_system().euler_lagrange().compile(backend=backend, cache_dir=SESSION_CACHE)
    state, params = {"q": (1.0, 1.025)}, {"h": 0.05}
    with pytest.raises(sg.BranchJumpError) as info:
        sim.simulate(state, 200, params)
    err = info.value
    assert err.step == 27 and "branch jump" in str(err) and "trust_factor" in str(err)
    q = err.trajectory.states
    assert len(q) == 28 and np.isfinite(q).all()
    assert abs(err.iterate[0] - q[-1, 1]) > 100  # the far root, reported
    off = sim.simulate(state, 200, params, options=sg.NewtonOptions(trust_factor=0))
    assert np.abs(off["q"][100:]).min() > 1e4 and np.isfinite(off["q"]).all()
    assert off.residual_norms.max() < 1e-3  # |F| of terms ~|q|³ ~ 10¹⁵: at rounding


@pytest.mark.parametrize("backend", BACKENDS)
def test_no_silent_branch_jump_without_extrapolation(backend):
    """With ``extrapolate=False`` (each step a function of its state) the same equations went on
    along the far root (q = −120.6, 285.7, −516.1 after 20.7, from q₁ = 1.005) solved
    to rounding: the trust region was checked only for extrapolated guesses.  The solution
    from the prediction is now checked against the extrapolation of the run's last
    solutions too: the run stops at step 33 as with extrapolation, and the steps before are
    bitwise those of a run without the check and of a loop of step calls."""
    sim = cubic_system().euler_lagrange().compile(backend=backend, cache_dir=SESSION_CACHE)
    state, params = {"q": (1.0, 1.005)}, {"h": 0.05}
    exact = sg.NewtonOptions(extrapolate=False)
    with pytest.raises(sg.BranchJumpError) as info:
        sim.simulate(state, 200, params, options=exact)
    assert info.value.step == 33 and len(info.value.trajectory.states) == 34
    unchecked = sim.simulate(state, 33, params,
                             options=sg.NewtonOptions(extrapolate=False, trust_factor=0))
    assert np.array_equal(info.value.trajectory.states, unchecked.states)
    s = sim.state(state, params)
    for _ in range(33):  # a loop of step calls: the same states
        s = sim.step(s, params, options=exact)
    assert np.array_equal(s, unchecked.states[-1])


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_trust_region_passes_fast_oscillations(backend):
    """Fast oscillations pass the trust region, with and without extrapolation
    (:func:`_fast_oscillations`)."""
    _fast_oscillations(backend, sg.NewtonOptions())
    _fast_oscillations(backend, sg.NewtonOptions(extrapolate=False))


def _fast_oscillations(backend, options):
    """A harmonic oscillator at hω = 0.3, 1, 1.9, 4 and 20 (the last one two steps a period
    and a bit, where the
    guess misses by up to twice a step's motion) and one starting at rest run 2·10³ steps
    without a branch jump (the NumPy twin, bitwise the same stepper, 300 steps: the misses
    come at every step from the start)."""
    from _hostile import oscillator

    sim = oscillator().euler_lagrange().compile(backend=backend, cache_dir=SESSION_CACHE)
    steps = 2000 if backend == "c" else 300
    for hw in (0.3, 1.0, 1.9, 4.0, 20.0):
        sim.simulate({"q": (1.0, np.cos(hw))}, steps, {"h": 0.1, "k": (hw / 0.1) ** 2},
                     options=options)
    sim.simulate({"q": (1.0, 1.0)}, steps, {"h": 0.1, "k": 1e-6}, options=options)


@pytest.mark.parametrize("backend", BACKENDS)
def test_batches_report_the_new_statuses(backend):
    """simulate_batch records BRANCH_JUMP per run, and its error is the BranchJumpError."""
    sim = cubic_system().euler_lagrange().compile(backend=backend, cache_dir=SESSION_CACHE)
    states = np.array([sim.state({"q": (1.0, 1.025)}), sim.state({"q": (0.1, 0.1001)})])
    batch = sim.simulate_batch(states, 100, {"h": 0.05})
    assert list(batch.status) == [BRANCH_JUMP, 0]
    assert isinstance(batch.error(0), sg.BranchJumpError)
    assert batch.failed_step[0] == 27


@pytest.mark.parametrize("value", [-1.0, float("nan"), float("inf"), "10", None])
def test_trust_factor_is_checked(value):
    with pytest.raises(sg.SymgroupoidError, match="trust_factor"):
        sg.NewtonOptions(trust_factor=value)


def driven_adaptive_oscillator() -> sg.DiscreteSystem:
    """A damped, driven oscillator on the time groupoid (the step's duration an unknown, fixed
    by the discrete energy balance): L_d = Δt(((q₁ − q₀)/Δt)²/2 − κ q̄²/2), f± = (Δt/2)(u −
    c v) in the q direction and −(Δt/2)(u − c v) v in the time direction (docs/conventions.md
    §20)."""
    kappa, c = sp.symbols("kappa c", positive=True)
    u = sp.Symbol("u", real=True)

    def L(a):
        dt, q0, q1 = a.step, a.source[0], a.target[0]
        return dt * (((q1 - q0) / dt) ** 2 / 2 - kappa * ((q0 + q1) / 2) ** 2 / 2)

    def forces(a):
        dt, q0, q1 = a.step, a.source[0], a.target[0]
        v = (q1 - q0) / dt
        half = dt / 2 * (u - c * v)
        return [-half * v, half], [-half * v, half]

    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    return sg.DiscreteSystem(G, L, parameters=[kappa, c], forces=forces, inputs=[u],
                             name="driven_adaptive_oscillator")


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_slow_chord_update_is_not_taken_for_a_stall(backend):
    """With the time t_{k+1} ~ 10 among the unknowns, F moves by ~10⁻¹³ under a few ulps of
    t, so a residual of that size passes the floor of the unknowns' rounding; a chord update
    that brought it there (contracting fivefold: slow, but no stall) was accepted with
    |F| = 5.7·10⁻¹³, where one more Newton update gives 5·10⁻¹⁵.  Only a Newton update or
    rounding noise counts as a stall now: every step ends at the floor of F's evaluation."""
    sim = driven_adaptive_oscillator().euler_lagrange().compile(backend=backend,
                                                                cache_dir=SESSION_CACHE)
    params = {"kappa": 1.0, "c": 0.1}
    inputs = 0.05 * np.sin(0.3 * np.arange(300))[:, None]
    state = sim.state({"t": (0.0, 0.05), "q": (1.0, 1.02), "u": [0.0]}, params)
    run = sim.simulate(state, 300, params, inputs=inputs)
    assert run.states[-1, 1] > 14.0  # (the time reached: t ~ 15, ulp(t) ~ 1.8e-15)
    assert run.residual_norms.max() < 3e-14


def _top(scheme="midpoint", name="top_midpoint"):
    """An asymmetric heavy top on SO(3) (parameters h, m, g, J1..3, χ1..3) discretized by
    ``scheme`` (the midpoint rule: a large step h = 1 turns it by up to 124° per step)."""
    h, m, grav = sp.symbols("h m g", positive=True)
    J = sp.diag(*sp.symbols("J1:4", positive=True))
    chi = sp.Matrix(sp.symbols("chi1:4", real=True))

    def L(R, xi):
        return (xi.T * J * xi)[0, 0] / 2 - m * grav * (R * chi)[2, 0]

    return sg.ContinuousSystem(sg.SO3("R"), L, parameters=[h, m, grav, *J.diagonal(), *chi],
                               name=name).discretize(h, scheme).euler_lagrange()


@needs_cc
def test_a_large_midpoint_step_on_a_group_is_not_accepted_on_its_terms_size():
    """Its residual's terms reach 1e15 at some Newton iterates, whose |F| ~ 5 passed the
    test "within the rounding of F's own terms" after one update: 28 of 200 steps were
    returned as solved with |F| up to 5.3.  An iterate at a floor must also be one from which
    the last factorisation moves the unknowns by at most 1e-4 (relative): every step now
    solves its equations, in C and NumPy alike."""
    P = {"m": 1.0, "g": 9.81, "J1": 0.8, "J2": 1.1, "J3": 0.45, "chi1": 0.05,
         "chi2": -0.03, "chi3": 0.3, "h": 1.0}
    a, b = 0.5, 0.3
    R0 = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]) @ \
        np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    step = _top()
    runs = []
    for sim in (step.compile(cache_dir=SESSION_CACHE), step.compile(backend="numpy")):
        traj = sim.simulate(sim.from_velocity({"R": R0}, 3 * np.array([0.7, -0.4, 2.5]), P),
                            60, P)
        assert traj.residual_norms.max() <= 1e-12
        runs.append(traj.states)
    np.testing.assert_array_equal(runs[0], runs[1])


def _driven_pendulum_adaptive():
    """A pendulum driven by A q cos(Ω t), the midpoint rule on the time groupoid with the
    time step an unknown (energy balance): its Jacobian is nearly singular at t ≈ 7."""
    kappa, A, Omega = sp.symbols("kappa A Omega", positive=True)

    def L(a):
        dt, q0, q1 = a.t1 - a.t0, a.source[0], a.target[0]
        v, qm, tm = (q1 - q0) / dt, (q0 + q1) / 2, (a.t0 + a.t1) / 2
        return dt * (v ** 2 / 2 + kappa * sp.cos(qm) + A * qm * sp.cos(Omega * tm))

    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    return sg.DiscreteSystem(G, L, parameters=[kappa, A, Omega],
                             name="driven_adaptive").euler_lagrange()


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_slow_newton_stretch_is_not_taken_for_the_floor_of_the_terms(backend):
    """(22 of 480 steps were accepted after one slow Newton update with |F| up to 9.7e-8,
    within ε times the size of their terms, which counts t_{k+1} − t_k at |t| ≈ 7; the same
    steps solved afresh reach 7e-15.)  An iterate accepted on that size must resist a trial
    chord update; every step of the run now solves its equations to 1e-12."""
    step = _driven_pendulum_adaptive()
    p = [1.0, 0.4, 1.3]
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    states = sim.simulate([0.0, 0.025, 1.0, 1.0075695898590376], 480, p).states
    residuals = [np.abs(step.evaluate(states[k + 1][[1, 3]], states[k], p)[0]).max()
                 for k in range(480)]
    assert max(residuals) <= 1e-12, max(residuals)


def _driven_pendulum_fixed_step():
    """The driven pendulum above with the time step fixed by a constraint t₁ − t₀ = h."""
    h, kappa, A, Omega = sp.symbols("h kappa A Omega", positive=True)

    def L(a):
        dt, q0, q1 = a.t1 - a.t0, a.source[0], a.target[0]
        v, qm, tm = (q1 - q0) / dt, (q0 + q1) / 2, (a.t0 + a.t1) / 2
        return dt * (v ** 2 / 2 + kappa * sp.cos(qm) + A * qm * sp.cos(Omega * tm))

    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    return sg.DiscreteSystem(G, L, constraints=lambda a: [a.t1 - a.t0 - h],
                             parameters=[h, kappa, A, Omega],
                             name="driven_fixed").euler_lagrange()


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_runaway_with_a_singular_jacobian_is_not_explained_by_rounding(backend):
    """At h = 2 from q = 0.3 → 40.3, Newton runs away to q ≈ 1.9e7 with a pivot ratio of
    1.2e14, where "a rounding-level update of that solve explains F" held at |F| = 4.8e13:
    the step was returned as solved.  That residual still calls for an update of 1.6
    relative to the unknowns; an iterate at a floor must call for at most 1e-4.  The step now
    fails (Newton goes on from the runaway until its Jacobian is singular to rounding), and
    every step a run returns solves its equations."""
    step = _driven_pendulum_fixed_step()
    params = {"h": 2.0, "kappa": 1.0, "A": 0.5, "Omega": 1.3}
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    p = sim.parameters(params)
    known = np.array([0.0, 2.0, 0.3, 40.3, 0.0])
    failures = (sg.NewtonDivergenceError, sg.SingularJacobianError)
    with pytest.raises(failures, match="step 0 failed"):
        sim.simulate(known, 5, params)
    with pytest.raises(failures):
        sim.solve(known, p)
    # from a gentle start the same step size runs, and every step solves its equations
    states = sim.simulate(np.array([0.0, 2.0, 0.3, 1.3, 0.0]), 40, params).states
    residuals = [np.abs(step.evaluate(states[k + 1][[1, 3, 4]], states[k], p)[0]).max()
                 for k in range(40)]
    assert max(residuals) <= 1e-12, max(residuals)


def _mathieu_fixed_step():
    """A Mathieu oscillator q̈ = −k₀(1 + e cos ωt) q by the midpoint rule on the time
    groupoid with t₁ − t₀ = h (a multiplier λ for the constraint)."""
    h, k0, e, w = sp.symbols("h k0 e omega", positive=True)

    def L(a):
        dt, q0, q1 = a.t1 - a.t0, a.source[0], a.target[0]
        tm, qm = (a.t0 + a.t1) / 2, (q0 + q1) / 2
        return dt * (((q1 - q0) / dt) ** 2 / 2 - k0 * (1 + e * sp.cos(w * tm)) * qm ** 2 / 2)

    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    return sg.DiscreteSystem(G, L, constraints=lambda a: [a.t1 - a.t0 - h],
                             parameters=[h, k0, e, w], name="mathieu").euler_lagrange()


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_large_multiplier_does_not_make_every_update_noise(backend):
    """In parametric resonance (h = 1, e = 0.9, ω = 2) the amplitude grows to 10⁷ and the
    multiplier λ to 10¹³, beside times of 100: its column's pivot is 10⁻¹⁴ of its row, and the
    unweighted pivot ratio (1.7·10¹⁴) made any update "rounding noise of the solve" that
    explained any residual: steps 98–110 were returned with λ off by up to 98 %.  The ratio is
    now also taken with each column weighted by 1 + |u_j|, the scale of the updates: every
    returned step is a fixed point of Newton to 1e-12 relative."""
    step = _mathieu_fixed_step()
    params = {"h": 1.0, "k0": 1.0, "e": 0.9, "omega": 2.0}
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    p = sim.parameters(params)
    S = sim.simulate({"t": (0.0, 1.0), "q": (1.0, 0.0), "lambda": [0.0]}, 110, params).states
    assert np.abs(S[-1, 3]) > 1e6  # (the resonance has grown)
    for k in range(110):
        u = S[k + 1][[1, 3, 4]]
        F, J = step.evaluate(u, S[k], p)
        left = np.linalg.solve(J, F) / (1.0 + np.abs(u))
        assert np.abs(left).max() <= 1e-12, (k, left)


#: an arrow (R_{k-1}, R_k) of an asymmetric heavy top and its parameters (h, m, g, J1..3,
#: χ1..3), from which a Lobatto IIIA–IIIB step at h = 0.3 runs away
_RUNAWAY_TOP_ARROW = [
    0.7354617368487767, 0.6611547941749505, 0.1482240593522506, -0.486789484607971,
    0.6677528193346478, -0.5631537711369207, -0.4713088491705695, 0.3420241371747148,
    0.8129498497960408, -0.13760042430535985, 0.5899451244334069, 0.7956323732655911,
    -0.2159726973930541, 0.7660748392376786, -0.6053801571473361, -0.966655014579531,
    -0.255135436276926, 0.021999816908999048]
_RUNAWAY_TOP_PARAMETERS = [0.3, 1.0, 9.81, 1.2089035430696038, 0.270400273382784,
                           0.61360333962012, -0.005270774792846853, -0.04355406739609834,
                           0.812705740035221]


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_runaway_to_the_cut_locus_is_not_a_floor(backend):
    """Newton ran away to Cayley coordinates of 4e4 (a rotation per step within 1e-4 of a
    half-turn, where the chart is singular and F is the noise of its own evaluation:
    |F| = 9e4, moved by as much under 4 ulps of the unknowns), and that passed the floor of
    the unknowns' rounding: solve() and simulate() returned it as solved (a run's residual
    norms reached 4.8e5).  An iterate whose residual exceeds its guess's a thousandfold is
    never a floor: the step now fails, and what is returned solves its equations."""
    step = _top(sg.LobattoIIIAB(3), "top_lobatto")
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    known, p = np.array(_RUNAWAY_TOP_ARROW), np.array(_RUNAWAY_TOP_PARAMETERS)
    with pytest.raises(sg.NewtonDivergenceError, match="step 0 failed"):
        sim.solve(known, p)
    with pytest.raises(sg.NewtonDivergenceError, match="step 0 failed"):
        sim.simulate(known, 20, p)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_size_of_a_product_of_differences_is_not_the_product_of_their_sizes(backend):
    """The driven pendulum with an adaptive step at t ≈ 95 (Δt ≈ 0.004, a nearly singular
    Jacobian near a turning point): its residual's terms were sized Π S(a_k) for a product,
    so v² = ((q₁ − q₀)/(t₁ − t₀))² counted (|t₁| + |t₀|)²/Δt⁴ and "within ε times the size
    of its terms" held at |F| = 2·10⁻³: steps were returned with q off by 5·10⁻³ (a root
    4.6·10⁻¹¹ from zero lies there).  A product is now sized by the first-order propagation
    of its factors' rounding: every returned step is a fixed point of Newton."""
    step = _driven_pendulum_adaptive()
    p = [12.35464509798145, 0.9699889676778422, 0.5700725448307911]
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    start = [94.42599084206836, 94.42599084206836 + 0.003076508169774939,
             -1.853548989032439, -1.8796569561146568]
    try:
        states = sim.simulate(start, 200, p).states
    except sg.BranchJumpError as err:  # (the energy balance loses its root at step 163)
        states = err.trajectory.states
    assert len(states) > 150
    for k in range(len(states) - 1):
        u = states[k + 1][[1, 3]]
        F, J = step.evaluate(u, states[k], p)
        assert np.max(np.abs(np.linalg.solve(J, F)) / (1 + np.abs(u))) <= 1e-8, k


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_creep_to_the_cut_locus_from_a_guess_is_not_a_floor(backend):
    """From the run's own quadratic extrapolation (|F| = 29), Newton crept toward the Cayley
    chart's cut locus (coordinates of 1.3e3, κ ~ 1e8), where a move of 4 ulps of the
    unknowns moves F as much as F: solve(guess=…) returned |F| = 0.25 as solved, its update
    3.4e-7 relative to those coordinates (4e-4 absolute).  The update an iterate at a floor
    calls for is now measured against the smaller of the iterate and the guess: the solve
    fails, and the step's root (from the prediction) is found as before."""
    step = _top(sg.LobattoIIIAB(3), "top_lobatto")
    known = np.array([
        -0.6114015322401963, -0.7912749906717953, -0.008488551801707194, 0.1480744381032513,
        -0.1249384296895363, 0.9810526742061914, -0.7773429919634873, 0.5985601706796594,
        0.19355514697674808, -0.8402027151153941, -0.21287371076024977, 0.49874259972442875,
        0.4397074809508634, 0.2708148657588233, 0.8563390915285118, -0.3173589902753132,
        0.9387992819294184, -0.1339372223851222])
    p = np.array([0.08829430222478998, 1.0, 9.81, 3.774482419228239, 0.40400771503000027,
                  0.807227184526906, 0.011916632244497696, -0.08773702528952658,
                  -0.2345725387070526])
    guess = np.array([0.588532496681659, -1.308592107322521, 1.5151908511044179,
                      -0.06976622151251054, -0.22802500203122675, -0.6454390185976736,
                      -0.04515458769565926, 0.6770893566513012, 0.39114035311225825])
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    with pytest.raises(sg.NewtonDivergenceError):
        sim.solve(known, p, guess=guess)
    u, _, norm = sim.solve(known, p)
    assert norm <= 1e-12 and np.abs(step.evaluate(u, known, p)[0]).max() <= 1e-12


@pytest.mark.parametrize("backend", BACKENDS)
def test_a_slow_chord_update_of_a_tiny_mass_is_not_rounding_noise(backend):
    """A planar pendulum (x² + y² = 1) of mass 1e-12 at h = 0.2: its motion is the unit
    mass's, but the pivot ratio was 1.8e10, so 64εκ ≈ 0.25 and a chord update contracting
    9.9-fold counted as "rounding noise" that explained its residual: steps were returned
    with the constraint violated by 7e-5.  Only a Newton update is now taken for noise:
    the positions equal the unit mass's to rounding and the constraint holds."""
    h, grav, m = sp.symbols("h g m", positive=True)

    def L(a):
        q0, q1 = sp.Matrix(a.source), sp.Matrix(a.target)
        v, mid = (q1 - q0) / h, (q0 + q1) / 2
        return h * m * (v.dot(v) / 2 - grav * mid[1])

    step = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L,
                             holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1],
                             parameters=[h, grav, m], name="light_pendulum",
                             time_step=h).euler_lagrange()
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    runs = []
    for mass in (1.0, 1e-12):
        P = {"h": 0.2, "g": 9.81, "m": mass}
        start = sim.project_initial({"x": (np.sin(1.0), np.sin(1.06)),
                                     "y": (-np.cos(1.0), -np.cos(1.06))}, P)
        S = sim.simulate(start, 200, P).states
        assert np.abs(S[:, 2] ** 2 + S[:, 3] ** 2 - 1).max() <= 1e-14
        runs.append(S[:, :4])
    np.testing.assert_allclose(runs[1], runs[0], rtol=0, atol=1e-12)
