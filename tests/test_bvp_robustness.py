"""The boundary-value solver never returns a non-solution: inputs checked before solving,
half-turns between the ends, the residual criterion at the rounding floor, failed Newton
iterations reported; and verify_stationary on every kind of trajectory."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SEED_DATA,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
    seed_system,
)

import symgroupoid as sg
from symgroupoid import (
    BoundaryValueDivergenceError,
    CutLocusError,
    DomainError,
    ParameterError,
)

h = sp.Symbol("h", positive=True)


def rotation(axis, angle: float) -> np.ndarray:
    """Rodrigues: the rotation by ``angle`` about ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@pytest.fixture(scope="module")
def so3_control():
    """Seed 000 §6.1: L(g) = h·l(cay⁻¹(g)/h), l(ξ) = ½ξᵀIξ (Cayley coordinates)."""
    inertia = sp.diag(1, 2, 3)

    def L(g):
        xi = g.coordinates / h
        return h * (xi.T * inertia * xi)[0, 0] / 2

    return sg.DiscreteSystem(sg.SO3("g"), L, parameters=[h], name="so3_control")


@pytest.fixture(scope="module")
def free():
    """L = ½|Δq|²/h on the pair groupoid of R²: the solution is a uniform straight line."""
    return sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("x y")),
        lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h),
        parameters=[h], name="free")


@pytest.fixture
def no_solve(monkeypatch):
    """Fail the test if the solver assembles the equations (inputs must be rejected first)."""
    def refuse(*args, **kwargs):
        raise AssertionError("the equations were assembled before the input was rejected")

    monkeypatch.setattr("symgroupoid.runtime._bvp._state._assemble", refuse)
    monkeypatch.setattr("symgroupoid.runtime._bvp._state.window_kernel", refuse)


# --- half-turns and the cut locus of the Cayley chart ---------------------------------------------

def test_half_turn_about_a_generic_axis_is_solved_and_stationary(so3_control):
    """Formerly |F| = 6e17 returned after 1 iteration: the Cayley-chart guess was singular.
    The geodesic guess splits the half-turn into N turns by π/N (tests/test_bvp.py)."""
    end = rotation([1, 2, 3], np.pi)
    sol = sg.solve_boundary_value(so3_control, np.eye(3), end, 20, params=[0.05])
    assert sol.residual_norm < 1e-12
    assert np.allclose(sol.configurations[-1], end, atol=1e-12)
    assert sg.verify_stationary(sol, so3_control).stationary


def test_half_turn_about_a_principal_axis_is_the_uniform_rotation(so3_control):
    """Formerly a raw LinAlgError.  A uniform rotation about a principal axis of inertia is
    a solution: every arrow is the turn by π/N about z."""
    sol = sg.solve_boundary_value(so3_control, np.eye(3), rotation([0, 0, 1], np.pi), 12,
                                  params=[0.05])
    assert np.allclose(sol.arrows, rotation([0, 0, 1], np.pi / 12).ravel(), atol=1e-13)
    assert sg.verify_stationary(sol, so3_control).stationary


@pytest.mark.parametrize("n", [1, 2])
def test_half_turn_on_the_pair_groupoid_of_attitudes_is_solved(n):
    """Formerly a raw LinAlgError: the pair groupoid's guess interpolated q₀⁻¹q₁ in the
    Cayley chart, singular at the exact half-turn diag(1, −1, −1).  Each attitude now moves
    along its group's geodesic q₀·exp(s log(q₀⁻¹q₁)), as on the group itself."""
    from symgroupoid import systems

    half = np.diag([1.0, -1.0, -1.0])
    start, end = (np.eye(3), half) if n == 1 else ((np.eye(3),) * 2, (half, np.eye(3)))
    step = systems.spherical_chain(n).euler_lagrange()
    sol = sg.solve_boundary_value(step, start, end, 8, params={"h": 0.02, "g": 9.81})
    assert sol.residual_norm < 1e-12
    target = sol.arrows[-1][9 * n:9 * n + 9]  # the last arrow's target, first body
    assert np.allclose(target, half.ravel(), atol=1e-12)


def test_a_guess_through_a_half_turn_is_a_cut_locus_error(so3_control):
    half = np.diag([-1.0, -1.0, 1.0]).ravel()  # the turn by π about z
    guess = np.array([half, half, np.eye(3).ravel(), np.eye(3).ravel()])
    with pytest.raises(CutLocusError, match=r"guess has arrows\[0\].*arrows\[1\].*half-turns")\
            as info:
        sg.solve_boundary_value(so3_control, np.eye(3), np.eye(3), 4, params=[0.1],
                                guess=guess)
    assert info.value.arrows == (0, 1)


def test_second_order_boundary_arrow_on_the_cut_locus():
    """The fixed first arrow c₀⁻¹c₁ of a second-order problem is a half-turn."""
    W = sg.SO3("W")

    def L(a, b):
        d = b.coordinates - a.coordinates
        return (d.T * d)[0, 0] / h

    system = sg.SecondOrderSystem(W, L, parameters=[h], name="so2nd")
    half = rotation([0, 1, 0], np.pi)
    with pytest.raises(CutLocusError, match=r"initial path has arrows\[0\]"):
        sg.solve_boundary_value(system, (np.eye(3), half), (half, half), 6, params=[0.1])


# --- boundary data checked as states are, before any solve -------------------------------------

@pytest.mark.parametrize("end, message", [
    (2 * np.eye(3), r"end is not in SO3\(g\): its rotation block is off orthonormal"),
    (np.zeros((3, 3)), r"end is not in SO3\(g\)"),
    (np.diag([1.0, 1.0, -1.0]), r"end is not in SO3\(g\): det = -1 \(a reflection"),
    (np.full((3, 3), np.nan), "end has non-finite entries"),
    (np.eye(2), r"end: a configuration of SO3\(g\) is a 3×3 matrix"),
])
def test_end_outside_the_group_is_rejected_before_solving(so3_control, no_solve, end, message):
    with pytest.raises(sg.ShapeError, match=message):
        sg.solve_boundary_value(so3_control, np.eye(3), end, 10, params=[0.1])


def test_counts_points_and_parameters_are_checked_before_solving(so3_control, free, no_solve):
    R = rotation([0, 0, 1], 0.5)
    with pytest.raises(sg.ShapeError, match="steps must be an integer, got 2.5"):
        sg.solve_boundary_value(so3_control, np.eye(3), R, 2.5, params=[0.1])
    with pytest.raises(sg.ShapeError, match="steps must be an integer, got the boolean"):
        sg.solve_boundary_value(so3_control, np.eye(3), R, True, params=[0.1])
    with pytest.raises(sg.ShapeError, match="max_iterations must be at least 0"):
        sg.solve_boundary_value(so3_control, np.eye(3), R, 10, params=[0.1], max_iterations=-1)
    with pytest.raises(sg.ShapeError, match="tol must be at least 0"):
        sg.solve_boundary_value(so3_control, np.eye(3), R, 10, params=[0.1], tol=-1.0)
    with pytest.raises(sg.ShapeError, match=r"start: a point here has 2 coordinates \(shape "
                                            r"\(2,\)\), got an array of shape \(2, 2\)"):
        sg.solve_boundary_value(free, np.eye(2), (1.0, 1.0), 8, params=[0.1])
    with pytest.raises(ParameterError, match="unknown parameter zz; the parameters are h"):
        sg.solve_boundary_value(so3_control, np.eye(3), R, 10, params={"h": 0.1, "zz": 1})
    with pytest.raises(ParameterError, match="parameter h is declared positive, got h = -0.1"):
        sg.solve_boundary_value(so3_control, np.eye(3), R, 10, params={h: -0.1})
    with pytest.raises(sg.ShapeError, match=r"guess\[3\] \(its 'g' part\) is not in SO3"):
        guess = np.tile(rotation([0, 0, 1], 0.05).ravel(), (10, 1))  # ten turns make R
        guess[3] *= 1.5
        sg.solve_boundary_value(so3_control, np.eye(3), R, 10, params=[0.1], guess=guess)


def test_composite_configurations_are_checked_per_factor(no_solve):
    """Products, action and time groupoids: each piece is checked and named."""
    pair = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    product = sg.DiscreteSystem(pair * sg.SO3("g"), lambda g: g[0].target[0] ** 2,
                                name="product")
    with pytest.raises(DomainError, match=r"end\[1\] is not in SO3\(g\): det = -1"):
        sg.solve_boundary_value(product, ((0, 0), np.eye(3)),
                                ((1, 2), np.diag([-1.0, 1.0, 1.0])), 4)
    with pytest.raises(sg.ShapeError, match=r"start must be a configuration of .* one per "
                                            r"factor: 2 parts, got 3"):
        sg.solve_boundary_value(product, ((0, 0), np.eye(3), 1), ((1, 2), np.eye(3)), 4)
    action = sg.DiscreteSystem(
        sg.ActionGroupoid(sg.EuclideanSpace.vector("p", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p))),
        lambda g: g.point[0], name="action")
    with pytest.raises(DomainError, match=r"start\[1\] is not in SO3\(W\)"):
        sg.solve_boundary_value(action, ((0, 0, 1), 2 * np.eye(3)), ((0, 0, 1), np.eye(3)), 4)
    with pytest.raises(sg.ShapeError, match=r"end\[0\]: a point here has 3 coordinates"):
        sg.solve_boundary_value(action, ((0, 0, 1), np.eye(3)), ((0, 1), np.eye(3)), 4)
    timed = sg.DiscreteSystem(sg.TimeGroupoid(pair), lambda g: g.t1 - g.t0, name="timed")
    with pytest.raises(sg.ShapeError, match=r"end\[0\] \(the time\) must be finite"):
        sg.solve_boundary_value(timed, (0.0, (0, 0)), (np.nan, (1, 1)), 4)


def test_second_order_boundary_pairs_are_checked_per_configuration(no_solve):
    system = sg.SecondOrderSystem(
        sg.SO3("W"), lambda a, b: ((b.coordinates - a.coordinates).T
                                   * (b.coordinates - a.coordinates))[0, 0], name="so2")
    with pytest.raises(DomainError, match=r"start\[1\] is not in SO3\(W\): det = -1"):
        sg.solve_boundary_value(system, (np.eye(3), -np.eye(3)), (np.eye(3), np.eye(3)), 6)


# --- the residual criterion and failed iterations --------------------------------------------

def test_a_stalled_newton_iteration_raises_instead_of_returning(so3_control):
    """The old step criterion accepted any iterate after a small update; a huge tol_step
    makes every update 'small': the solver must still refuse a non-solution."""
    end = rotation([0.3, -0.5, 0.8], 2.0)
    with pytest.raises(BoundaryValueDivergenceError, match="stalled") as info:
        sg.solve_boundary_value(so3_control, np.eye(3), end, 10, params=[0.1], tol_step=1e3)
    err = info.value
    assert isinstance(err, sg.NewtonDivergenceError)
    assert err.iterations == 1 and err.residual_norm > 1e-6
    assert len(err.history) == 2 and err.history[-1] == err.residual_norm
    assert err.iterate.shape == (10, 9)


@pytest.mark.parametrize("steps, tol", [(20, 1e-2), (1000, 1e-6)])
def test_a_loose_tol_does_not_accept_a_smooth_path_that_is_no_solution(steps, tol):
    """The straight path between the ends of a spring (L = Δq²/(2h) − hk(q₀² + q₁²)/4) has
    a DEL residual hk·q_j, O(h²) of the terms' sensitivity to the coordinates: tol accepted
    it after 0 iterations, 43 % of the way from the solution (verify_stationary False).
    The Newton update from it must be below tol too."""
    k = sp.Symbol("k", positive=True)

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4

    spring = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                               name="spring")
    params = {"h": 1.0 / steps, "k": 4.0}
    exact = sg.solve_boundary_value(spring, 0.0, 1.0, steps, params=params)
    loose = sg.solve_boundary_value(spring, 0.0, 1.0, steps, params=params, tol=tol)
    assert loose.iterations >= 1 and sg.verify_stationary(loose, spring)
    assert np.abs(loose.arrows - exact.arrows).max() <= 10 * tol


def test_the_iteration_cap_reports_iterations_and_residual(so3_control):
    end = rotation([0.3, -0.5, 0.8], 2.0)
    with pytest.raises(BoundaryValueDivergenceError, match="did not converge in 1 iteration")\
            as info:
        sg.solve_boundary_value(so3_control, np.eye(3), end, 10, params=[0.1],
                                max_iterations=1)
    assert info.value.iterations == 1 and len(info.value.history) == 2


def test_a_failed_line_search_raises_instead_of_taking_a_worse_step(so3_control, monkeypatch):
    """Along an ascent direction no step length decreases |F|: the solver reports it (the
    old line search returned its last halved step even though the residual had grown)."""
    def ascent(rows, cols, vals, n, rhs, band=None):
        """The Newton step reversed: J dz = rhs solved (densely), negated."""
        J = np.zeros((n, n))
        np.add.at(J, (rows, cols), vals)
        return -np.linalg.solve(J, rhs)

    monkeypatch.setattr("symgroupoid.runtime._bvp._state._solve_banded", ascent)
    with pytest.raises(BoundaryValueDivergenceError, match="line search") as info:
        sg.solve_boundary_value(so3_control, np.eye(3), rotation([1, 2, 0.5], 1.0), 10,
                                params=[0.1])
    assert info.value.iterations == 0


def test_the_residual_criterion_follows_the_rounding_floor(free):
    """Coordinates near 10⁸ hold the residual (q_{k+1} − 2q_k + q_{k−1})/h to ~ε·10⁸/h: a
    fixed tol = 1e-10 is out of reach, the per-equation floor is not; the straight line is
    found to the precision of the coordinates."""
    q0, q1 = np.array([1e8, -3e8]), np.array([1e8 + 2.0, -3e8 + 1.0])
    sol = sg.solve_boundary_value(free, q0, q1, 10, params=[0.01])
    line = q0 + np.outer(np.arange(1, 11) / 10, q1 - q0)
    assert np.abs(np.column_stack([sol["x"], sol["y"]]) - line).max() < 1e-6
    assert sol.residual_norm > 1e-10  # accepted at the rounding floor, not at tol
    assert sol.residual_norm < 8.0 * 1e2 * np.finfo(float).eps * 3e8 / 0.01  # 8 floors accepted


# --- verify_stationary ----------------------------------------------------------------------------

@needs_cc
def test_verify_stationary_accepts_a_simulated_trajectory():
    """A Trajectory from Simulator.simulate (plate-ball, constrained): its arrows g_0 … g_N
    and multipliers λ_0 … λ_N are a critical point of Σ [L + λ·φ]."""
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    traj = sim.simulate(initial_state(sim, "plate_ball"), 12, params)
    report = sg.verify_stationary(traj, seed_system("plate_ball"))
    assert report.stationary, report
    with pytest.raises(ParameterError, match="unknown parameter hh"):
        sg.verify_stationary(traj, seed_system("plate_ball"), {**params, "hh": 1.0})


def test_verify_stationary_accepts_a_second_order_trajectory():
    """Second order: the states (g_{k-1}, g_k, g_{k+1}) overlap; the trajectory's arrows are
    g_{-1}, g_0, …, g_{N+1}."""
    system = sg.SecondOrderSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a, b: ((b.target[0] - 2 * a.target[0] + a.source[0]) / h ** 2) ** 2 * h / 2
        + sp.cos(a.target[0]) * h, parameters=[h], name="spline")
    sim = system.euler_lagrange().compile(backend="numpy")
    traj = sim.simulate({"q": (0.0, 0.1, 0.25, 0.45)}, 8, {"h": 0.1})
    arrows = sim.layout.arrows(traj.states)
    assert arrows.shape == (11, 2) and np.allclose(arrows[1:, 0], arrows[:-1, 1])
    assert sg.verify_stationary(traj, system).stationary


def test_the_trivial_solution_is_stationary_and_a_nearby_path_is_not(so3_control):
    """start = end: every arrow is the identity and the derivative along any variation is
    O(ε²) with no first-order part; a bump of 10⁻⁶ rad is detected."""
    sol = sg.solve_boundary_value(so3_control, np.eye(3), np.eye(3), 10, params=[0.1])
    assert sol.iterations == 0 and sol.residual_norm == 0.0
    report = sg.verify_stationary(sol, so3_control)
    assert report.stationary, report
    bump = rotation([1, 0, 0], 1e-6)
    arrows = sol.arrows.copy()
    arrows[3] = (arrows[3].reshape(3, 3) @ bump).ravel()
    arrows[4] = (bump.T @ arrows[4].reshape(3, 3)).ravel()
    assert not sg.verify_stationary(arrows, so3_control, [0.1]).stationary


def test_verify_stationary_input_errors(so3_control):
    arrows = np.tile(rotation([0, 0, 1], 1.0 / 6).ravel(), (6, 1))
    with pytest.raises(ParameterError, match="missing parameter h"):
        sg.verify_stationary(arrows, so3_control)
    with pytest.raises(sg.ShapeError, match=r"arrows must have shape \(N, 9\)"):
        sg.verify_stationary(arrows[:, :4], so3_control, [0.1])
    with pytest.raises(sg.ShapeError, match=r"multipliers must have shape \(6, 0\)"):
        sg.verify_stationary(arrows, so3_control, [0.1], multipliers=np.zeros((5, 1)))


def test_ends_near_the_largest_double_are_refused_without_warnings():
    """Ends ±1e308: the straight initial path overflowed with NumPy RuntimeWarnings printed
    before the named refusal (on the command line, above its one error line)."""
    import warnings

    h = sp.Symbol("h", positive=True)

    def L(a):
        (q0,), (q1,) = a.source, a.target
        return (q1 - q0) ** 2 / (2 * h) + h * (sp.cos(q0) + sp.cos(q1)) / 2

    pendulum = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("theta")), L,
                                 parameters=[h], time_step=h, name="pendulum")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(sg.SymgroupoidError, match="non-finite"):
            sg.solve_boundary_value(pendulum, 1e308, -1e308, 5, params=[0.05])


@pytest.mark.parametrize("steps", [-1, 0, 1])
def test_too_few_steps_have_one_message_in_the_solve_and_the_sweep(steps):
    """(steps = −1 said "at least 0" where 0 said "at least 2"; a sweep checked only the
    sign, and each of its runs failed on its own.)  Every count below 2·order is refused
    before anything is solved, with the same message by both."""
    from symgroupoid import systems

    step = systems.planar_chain(1).euler_lagrange()
    message = f"a problem of order 1 needs at least 2 steps, got {steps}"
    params = {"h": 0.1, "g": 9.81}
    with pytest.raises(sg.ShapeError, match=message):
        sg.solve_boundary_value(step, [0.0], [1.0], steps, params=params)
    with pytest.raises(sg.ShapeError, match=f"^planar_chain_1: {message}$"):
        sg.sweep_boundary_value(step, [[0.0]], [[1.0]], steps, params)


