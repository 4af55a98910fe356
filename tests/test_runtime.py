"""Layer 5: Simulator, Trajectory, initial data, input checks and failures."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SEED_DATA,
    SESSION_CACHE,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
    seed_step,
    seed_system,
)

import symgroupoid as sg

SEEDS = ("plate_ball", "heavy_top", "rigid_body")


def free_fall(name="ball", mass=None):
    """A particle on R with L = h[m/2 ((q₁−q₀)/h)² − a·√q₀] (the force blows up at q = 0)."""
    h, a = sp.symbols("h a", positive=True)
    m = sp.Symbol("m", nonnegative=True) if mass is None else mass

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h * (m / 2 * ((q1 - q0) / h) ** 2 - a * sp.sqrt(q0))

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L,
                             parameters=[h, a, m], name=name)


@pytest.fixture(scope="module")
def fall_step():
    return free_fall().euler_lagrange()


# --- backends agree -------------------------------------------------------------------------

@needs_cc
@pytest.mark.parametrize("name", SEEDS)
def test_numpy_backend_matches_c_to_1e_12(name):
    c_sim, np_sim = compiled(name), compiled(name, backend="numpy")
    assert (c_sim.backend, np_sim.backend) == ("c", "numpy")
    params = SEED_DATA[name][0]
    state = initial_state(c_sim, name)
    a = c_sim.simulate(state, 100, params)
    b = np_sim.simulate(state, 100, params)
    assert np.abs(a.states - b.states).max() <= 1e-12 * max(1.0, np.abs(a.states).max())
    assert np.array_equal(a.newton_iterations, b.newton_iterations)


@needs_cc
@pytest.mark.parametrize("name", SEEDS)
def test_prediction_and_extrapolation_reach_the_same_solutions(name):
    """The Newton guess changes the iteration count, not the solution of each step."""
    sim, params = compiled(name), SEED_DATA[name][0]
    state = initial_state(sim, name)
    a = sim.simulate(state, 200, params)
    b = sim.simulate(state, 200, params, options=sg.NewtonOptions(extrapolate=False))
    c = compiled(name, backend="numpy").simulate(state, 200, params,
                                                 options=sg.NewtonOptions(extrapolate=False))
    scale = max(1.0, np.abs(a.states).max())
    assert np.abs(a.states - b.states).max() <= 1e-12 * scale
    assert np.abs(b.states - c.states).max() <= 1e-12 * scale
    assert np.array_equal(b.newton_iterations, c.newton_iterations)
    assert a.newton_iterations[2:].sum() <= b.newton_iterations[2:].sum()


# --- trajectories ---------------------------------------------------------------------------

@needs_cc
def test_trajectory_named_arrays():
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    flat = initial_state(sim, "plate_ball")  # consistent: on the constraints
    named = {part: sim.layout.view(flat[None], part) for part in ("x", "y", "g", "lambda")}
    W1 = named["g"][0]
    initial = {"x": tuple(named["x"]), "y": tuple(named["y"]), "g": W1,
               "lambda": named["lambda"][0]}
    assert np.array_equal(sim.state(initial), flat)
    traj = sim.simulate(initial, 50, params)
    assert traj.steps == 50 and len(traj) == 51
    assert traj["x"].shape == (52,) and traj["y"].shape == (52,)
    assert traj["x"][:2].tolist() == named["x"].tolist()
    assert np.array_equal(traj["x"][1:], traj.states[:, 2])
    assert traj["g"].shape == (51, 3, 3) and np.array_equal(traj["g"][0], W1)
    assert traj.multipliers.shape == (51, 3)
    assert traj.multipliers[0].tolist() == named["lambda"][0].tolist()
    assert traj.newton_iterations.shape == (50,) and traj.residual_norms.shape == (50,)
    assert (traj.residual_norms <= 1e-10).all() and np.isfinite(traj.states).all()
    assert traj.parameters == params
    assert sorted(traj.keys()) == ["g", "lambda", "x", "y"]
    with pytest.raises(KeyError, match="available"):
        traj["z"]
    # continuing from the last state reproduces the longer run (to rounding: the Newton
    # guesses of a fresh run start from the prediction instead of the extrapolation)
    more = sim.simulate(traj.final_state(), 10, params)
    longer = sim.simulate(initial, 60, params).states[50:]
    assert np.abs(more.states - longer).max() <= 1e-12


@needs_cc
def test_heavy_top_vector_parts_and_step():
    sim = compiled("heavy_top")
    params = SEED_DATA["heavy_top"][0]
    gamma = (0.0, 0.6, 0.8)
    W = np.asarray(sp.N(sg.SO3("W").cayley([0.02, 0.0, 0.03])), dtype=float)
    s = sim.state({"Gamma": gamma, "W": W})
    assert np.array_equal(s, sim.state({"Gamma_1": 0.0, "Gamma_2": 0.6, "Gamma_3": 0.8,
                                        "W": W}))
    traj = sim.simulate(s, 3, params)
    assert traj["Gamma"].shape == (4, 3) and traj["Gamma_2"].shape == (4,)
    assert np.array_equal(sim.step(s, params), traj.states[1])
    # Γ_{k+1} = W_kᵀ Γ_k (the target of the action groupoid arrow)
    assert np.allclose(traj["Gamma"][1], W.T @ np.array(gamma), atol=1e-15)


# --- initial data from a momentum -----------------------------------------------------------

@needs_cc
@pytest.mark.parametrize("name", SEEDS)
def test_from_momentum_solves_the_legendre_transform(name):
    """F⁻L(g₁, λ₁) = p₀, φ(g₁) = 0, and the DEL F⁺L(g₁, λ₁) = F⁻L(g₂, λ₂) along the run."""
    sim, system, step = compiled(name), seed_system(name), seed_step(name)
    params, config, momentum = SEED_DATA[name]
    p = sim.parameters(params)
    legendre = system.legendre()
    n = len(legendre.arrow)
    assert tuple(legendre.arrow) == tuple(step.knowns[:n])
    state = sim.from_momentum(config, momentum, params)
    minus, plus = legendre.evaluate(state[:n], state[n:], p)
    assert np.abs(minus - momentum).max() < 1e-13
    if step.n_constraints:
        phi = sp.lambdify([step.knowns, step.parameters],
                          system.constraints(step.groupoid.view(step.arrows[0])))
        assert np.abs(phi(state, p)).max() < 1e-13
    nxt = sim.step(state, params)
    minus_next, _ = legendre.evaluate(nxt[:n], nxt[n:], p)
    assert np.abs(plus - minus_next).max() < 1e-12


@needs_cc
def test_from_momentum_input_errors():
    sim = compiled("plate_ball")
    params, config, momentum = SEED_DATA["plate_ball"]
    with pytest.raises(sg.ShapeError, match="5 components"):
        sim.from_momentum(config, momentum[:3], params)
    with pytest.raises(KeyError, match="'g' is not a coordinate of the configuration"):
        sim.from_momentum({"g": np.eye(3)}, momentum, params)
    with pytest.raises(KeyError, match="configuration needs x, y"):
        sim.from_momentum({"x": 0.0}, momentum, params)
    with pytest.raises(ValueError, match="non-finite momentum"):
        sim.from_momentum(config, (np.nan, 0, 0, 0, 0), params)


# --- input checks ---------------------------------------------------------------------------

@needs_cc
def test_state_and_parameter_checks_name_the_problem():
    sim = compiled("plate_ball")
    params = dict(SEED_DATA["plate_ball"][0])
    good = {"x": (0.0, 0.001), "y": (0.0, 0.0), "g": np.eye(3), "lambda": [0, 0, 0]}
    with pytest.raises(sg.ShapeError, match=r"shape \(16,\)"):
        sim.simulate(np.zeros(15), 1, params)
    with pytest.raises(KeyError, match="missing parameter.*Omega"):
        sim.simulate(good, 1, {k: v for k, v in params.items() if k != "Omega"})
    with pytest.raises(KeyError, match="unknown parameter.*omega"):
        sim.simulate(good, 1, {**params, "omega": 1.0})
    with pytest.raises(sg.ShapeError, match="3 parameter values given, expected 4"):
        sim.simulate(good, 1, [0.01, 1.0, 0.1])
    with pytest.raises(ValueError, match="non-finite parameter.*h"):
        sim.simulate(good, 1, {**params, "h": np.inf})
    with pytest.raises(ValueError, match=r"non-finite initial data in x \(step k-1\)"):
        sim.simulate({**good, "x": (np.nan, 0.0)}, 1, params)
    with pytest.raises(ValueError, match=r"non-finite initial data in g\[1, 2\]"):
        bad = np.eye(3)
        bad[1, 2] = np.nan
        sim.simulate({**good, "g": bad}, 1, params)
    with pytest.raises(ValueError, match="non-finite initial data in lambda"):
        state = sim.state(good)
        state[-1] = np.inf
        sim.simulate(state, 1, params)
    with pytest.raises(KeyError, match="misses lambda"):
        sim.simulate({k: v for k, v in good.items() if k != "lambda"}, 1, params)
    with pytest.raises(KeyError, match="misses y"):
        sim.simulate({k: v for k, v in good.items() if k != "y"}, 1, params)
    with pytest.raises(KeyError, match="unknown state part 'z'"):
        sim.simulate({**good, "z": 1.0}, 1, params)
    with pytest.raises(sg.ShapeError, match=r"'x' needs 2 consecutive values, oldest first "
                       r"\(x_\{k-1\}, x_k\), each a number; got a single value"):
        sim.simulate({**good, "x": 0.5}, 1, params)
    with pytest.raises(ValueError, match="'g' is not in SO3"):
        sim.simulate({**good, "g": 1.01 * np.eye(3)}, 1, params)
    with pytest.raises(sg.ShapeError, match="'g' needs shape"):
        sim.simulate({**good, "g": np.eye(2)}, 1, params)
    with pytest.raises(sg.ShapeError, match="plate_ball: steps must be at least 0, got -1"):
        sim.simulate(good, -1, params)


# --- failures -------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_singular_jacobian_is_reported_with_step_and_iterate(backend):
    """With m = 0 the DEL do not involve q_{k+1}: F⁻L is not invertible."""
    sim = free_fall(name="massless").euler_lagrange().compile(backend=backend,
                                                              cache_dir=SESSION_CACHE)
    with pytest.raises(sg.SingularJacobianError) as info:
        sim.simulate({"q": (1.0, 0.99)}, 10, {"h": 0.01, "a": 1.0, "m": 0.0})
    err = info.value
    assert err.step == 0 and np.isfinite(err.residual_norm) and err.residual_norm > 0
    assert err.iterate.shape == (1,) and np.isfinite(err.iterate).all()
    assert "massless: step 0 failed: singular Jacobian" in str(err)


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_non_finite_values_stop_at_the_failing_step(backend, fall_step):
    """The force ∝ 1/√q is NaN once q < 0: the error names the first step whose known
    position is negative, and nothing non-finite is returned."""
    sim = fall_step.compile(backend=backend, cache_dir=SESSION_CACHE)
    params = {"h": 0.01, "a": 0.1, "m": 1.0}
    with pytest.raises(sg.NewtonDivergenceError) as info:
        sim.simulate({"q": (1.0, 0.99)}, 1000, params)
    err = info.value
    assert 0 < err.step < 1000 and "non-finite" in str(err)
    before = sim.simulate({"q": (1.0, 0.99)}, err.step, params)
    assert np.isfinite(before.states).all()
    q = before["q"]
    assert q[-1] < 0 and (q[:-1] >= 0).all()


def on_the_line(L, name):
    """A first-order system on the pair groupoid of R with Lagrangian L(q₀, q₁; h)."""
    h = sp.Symbol("h", positive=True)

    def lagrangian(g):
        (q0,), (q1,) = g.source, g.target
        return L(q0, q1, h)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), lagrangian,
                             parameters=[h], name=name)


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_a_guess_that_solves_a_singular_step_is_not_accepted(backend):
    """L = (q₁ − q₀)⁴/(4h) at rest: the prediction q₂ = 2q₁ − q₀ = q₁ makes F exactly 0,
    and ∂F/∂q₂ = −3(q₂ − q₁)²/h = 0 there.  The stepper used to accept the guess before
    looking at the Jacobian (0 iterations, "converged"); it must report the singular step."""
    step = on_the_line(lambda q0, q1, h: (q1 - q0) ** 4 / (4 * h), "quartic").euler_lagrange()
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    params = {"h": 0.1}
    known, p = sim.state({"q": (1.0, 1.0)}), sim.parameters(params)
    guess = sim.kernel.predict(known, p)
    assert sim.kernel.residual(guess, known, p).tolist() == [0.0]
    with pytest.raises(sg.SingularJacobianError, match="quartic: step 0 failed: singular") as info:
        sim.simulate({"q": (1.0, 1.0)}, 10, params)
    assert info.value.step == 0 and len(info.value.trajectory) == 1
    with pytest.raises(sg.SingularJacobianError):
        sim.solve({"q": (1.0, 1.0)}, params)
    with pytest.raises(sg.SingularJacobianError):
        sim.solve({"q": (1.0, 1.0)}, params, guess=[1.0])
    moving = sim.simulate({"q": (1.0, 1.1)}, 3, params)  # regular away from rest
    assert np.allclose(moving["q"], [1.0, 1.1, 1.2, 1.3, 1.4], atol=1e-12)


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_an_identically_degenerate_step_is_reported(backend):
    """L = (q₁² − q₀²)/(2h): the DEL are 0 = 0 for every q₂ (F ≡ 0, J ≡ 0)."""
    system = on_the_line(lambda q0, q1, h: (q1 ** 2 - q0 ** 2) / (2 * h), "degenerate")
    try:
        step = system.euler_lagrange()
    except sg.SymgroupoidError as exc:  # rejected before any kernel exists
        pytest.skip(f"the derivation rejects the degenerate system: {exc}")
    sim = step.compile(backend=backend, cache_dir=SESSION_CACHE)
    with pytest.raises(sg.SingularJacobianError, match="degenerate: step 0 failed") as info:
        sim.simulate({"q": (0.5, 0.7)}, 4, {"h": 0.1})
    assert info.value.iterate.shape == (1,)


def two_masses():
    """Two free particles, L = (h/2)(m₁((x₁−x₀)/h)² + m₂((y₁−y₀)/h)²): J = diag(−m₁/h, −m₂/h)."""
    h, m1, m2 = sp.symbols("h m1 m2", positive=True)

    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return h / 2 * (m1 * ((x1 - x0) / h) ** 2 + m2 * ((y1 - y0) / h) ** 2)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L,
                             parameters=[h, m1, m2], name="two masses").euler_lagrange()


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_equations_of_very_different_sizes_are_not_called_singular(backend):
    """m₁ = 10³⁰⁰, m₂ = 1: a regular Jacobian whose rows differ by 300 orders of magnitude.
    Judged against its largest entry it looked singular ("not regular"); the pivots are
    now judged per equation."""
    sim = two_masses().compile(backend=backend, cache_dir=SESSION_CACHE)
    traj = sim.simulate({"x": (0.0, 0.1), "y": (1.0, 0.5)}, 5,
                        {"h": 0.01, "m1": 1e300, "m2": 1.0})
    assert np.allclose(traj["x"], 0.1 * np.arange(7), atol=1e-12)
    assert np.allclose(traj["y"], 1.0 - 0.5 * np.arange(7), atol=1e-12)


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_overflow_is_reported_as_overflow_not_as_a_singular_jacobian(backend):
    """m₁ = 10³⁰⁸ with h = 0.01: ∂F/∂x = −m₁/h overflows to infinity."""
    sim = two_masses().compile(backend=backend, cache_dir=SESSION_CACHE)
    params = {"h": 0.01, "m1": 1e308, "m2": 1.0}
    with pytest.raises(sg.NewtonDivergenceError, match="overflow") as info:
        sim.simulate({"x": (0.0, 0.1), "y": (1.0, 0.5)}, 5, params)
    assert "not regular" not in str(info.value) and info.value.step == 0
    with pytest.raises(sg.NewtonDivergenceError, match="overflow"):
        sim.solve({"x": (0.0, 0.1), "y": (1.0, 0.5)}, params, guess=[0.2, 0.0])


@needs_cc
def test_iteration_cap_raises_divergence():
    sim = compiled("rigid_body")
    params, _, momentum = SEED_DATA["rigid_body"]
    state = sim.from_momentum(None, momentum, params)
    with pytest.raises(sg.NewtonDivergenceError, match="iteration cap") as info:
        sim.simulate(state, 5, params, options=sg.NewtonOptions(max_iterations=0))
    assert info.value.step == 0


def test_newton_options_are_checked():
    with pytest.raises(ValueError, match="tol_step"):
        sg.NewtonOptions(tol_step=-1.0)
    with pytest.raises(ValueError, match="tol_residual"):
        sg.NewtonOptions(tol_residual=float("nan"))
    with pytest.raises(sg.ShapeError, match="max_iterations must be an integer"):
        sg.NewtonOptions(max_iterations=2.5)


@needs_cc
def test_second_order_state_is_a_window_of_configurations():
    """L(g_k, g_{k+1}) on the pair groupoid: the state holds q_{k-2} … q_{k+1}, given as
    four consecutive configurations; trajectories list every position."""
    h = sp.Symbol("h", positive=True)

    def L(g1, g2):
        (q0,), (q1,) = g1.source, g1.target
        (q2,) = g2.target
        return h * (((q2 - 2 * q1 + q0) / h ** 2) ** 2 / 2 + q1 ** 2 / 2)

    step = sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h],
                                name="spline").euler_lagrange()
    sim = step.compile(backend="c")
    initial = {"q": (0.0, 0.01, 0.02, 0.03)}
    traj = sim.simulate(initial, 20, {"h": 0.1})
    assert traj["q"].shape == (24,) and traj["q"][:4].tolist() == [0.0, 0.01, 0.02, 0.03]
    other = step.compile(backend="numpy").simulate(initial, 20, {"h": 0.1})
    assert np.abs(traj.states - other.states).max() <= 1e-12
    with pytest.raises(sg.ShapeError, match="'q' needs 4 consecutive values"):
        sim.simulate({"q": (0.0, 0.01)}, 1, {"h": 0.1})
    with pytest.raises(TypeError, match="first arrow"):
        sim.from_momentum({"q": 0.0}, (0.1, 0.2), {"h": 0.1})
    # (first arrow, momentum) initial data give back the state of a computed trajectory
    leg = step.system.legendre()
    s3 = traj.states[3]  # (q_{k-2}, q_{k-1}, q_k, q_{k+1})
    momentum = leg.evaluate(s3, [], [0.1])[0]
    assert np.allclose(sim.from_momentum(s3[:2], momentum, {"h": 0.1}), s3, atol=1e-12)


def test_lu_solve_judges_pivots_per_equation_and_reports_overflow():
    """The NumPy twin of the kernel's LU: exact power-of-two row scaling (also for
    subnormal rows), singular only for a zero row or a pivot below n·ε of its equation,
    non-finite values reported as such."""
    from symgroupoid.stepper import Status, lu_solve

    NON_FINITE, OK, SINGULAR_JACOBIAN = Status.NON_FINITE, Status.OK, Status.SINGULAR_JACOBIAN

    A = np.array([[1e-310, 0.0, 2e-310], [0.0, 1e300, 0.0], [1.0, 0.0, -3.0]])
    x = np.array([1.0, -2.0, 0.5])
    status, solution = lu_solve(A, A @ x)
    assert status == OK and np.allclose(solution, x, rtol=1e-14, atol=0)
    assert lu_solve(np.array([[1.0, 2.0], [2.0, 4.0]]), [1.0, 1.0])[0] == SINGULAR_JACOBIAN
    assert lu_solve(np.array([[1.0, 0.0], [0.0, 0.0]]), [1.0, 1.0])[0] == SINGULAR_JACOBIAN
    assert lu_solve(np.array([[1.0, 2.0], [2.0, 4.0 + 1e-9]]), [1.0, 1.0])[0] == OK
    assert lu_solve(np.array([[np.inf, 0.0], [0.0, 1.0]]), [1.0, 1.0])[0] == NON_FINITE
    assert lu_solve(np.eye(2), [np.nan, 1.0])[0] == NON_FINITE
    # the step overflows: |b_i| / (largest |A_ij| of its row) beyond the double range
    assert lu_solve(np.diag([1e-10, 1.0]), [1e300, 1.0])[0] == NON_FINITE


@pytest.mark.parametrize("backend", [pytest.param("c", marks=needs_cc), "numpy"])
def test_non_finite_input_is_never_converged(backend, fall_step):
    """A NaN state or guess handed to the kernel directly is an invalid argument (in C the
    same check would vanish under -ffast-math, which the source therefore refuses)."""
    sim = fall_step.compile(backend=backend, cache_dir=SESSION_CACHE)
    p = sim.parameters({"h": 0.01, "a": 0.1, "m": 1.0})
    from symgroupoid.stepper import Status

    INVALID_ARGUMENT = Status.INVALID_ARGUMENT

    for known, guess in [([np.nan, 1.0], [1.0]), ([1.0, 0.99], [np.nan])]:
        status, *_ = sim.kernel.solve_step(np.array(known), p, np.array(guess), sim.options)
        assert status == INVALID_ARGUMENT
    run = sim.kernel.simulate(np.array([1.0, np.nan]), p, 3, sim.options)
    assert run.status == INVALID_ARGUMENT
