"""Two-point boundary-value problems (seed 000 §6.1–§6.2, seed 001 §3.3), and the solver's
parts one by one: the window kernel and its evaluator, the assembly (by the layout's fixed
pattern, against the block scatter), the layout, the banded LU solve, the line search at the
rounding floor, the globalised iteration and its restart from the fast path's best iterate
(the initial path as fallback), and the second-order condition — computed on request, its
banded inertia against dense linear algebra."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
import sympy as sp
from conftest import load_example
from kernel_support import benchmark_module
from test_program_evaluator import VALUES, _program

import symgroupoid as sg
from symgroupoid import BoundaryValueDivergenceError
from symgroupoid.derivation import WindowAction

# white-box: the solver's parts (runtime/_bvp: window kernels, assembly, layout, linear solves,
# solver state, fast and globalised paths), the banded LAPACK and LDLᵀ beside it
# (runtime/_lapack.py, _banded.py), the window programs' evaluator (runtime/_programs.py) and
# a sweep's solution data are checked one by one; none of them has a public constructor
from symgroupoid.runtime import ProgramEvaluator, _lapack, _programs, interpolate_arrows
from symgroupoid.runtime._banded import banded_inertia
from symgroupoid.runtime._bvp import (
    WindowKernel,
    _fast,
    _globalised,
    _kernels,
    _solve,
    _state,
    window_kernel,
)
from symgroupoid.runtime._bvp._assembly import _add, _assemble, _excess, _rounding_floor
from symgroupoid.runtime._bvp._kernels import _maps
from symgroupoid.runtime._bvp._layout import _layout, _multiplier_rows, _variation_rows
from symgroupoid.runtime._bvp._linear import _block_tridiagonal, _solve_banded
from symgroupoid.runtime._bvp._state import _Problem
from symgroupoid.runtime._sweep_boundary import _solution_data
from symgroupoid.verification import action

h = sp.Symbol("h", positive=True)


def _cay(x):
    return np.array(sg.SO3("t").cayley([sp.Float(v) for v in x]).tolist(), float)


@pytest.fixture(scope="module")
def so3_control():
    """Seed 000 §6.1: L(g) = h·l(cay⁻¹(g)/h), l(ξ) = ½ξᵀIξ."""
    inertia = sp.diag(1, 2, 3)

    def L(g):
        xi = g.coordinates / h
        return h * (xi.T * inertia * xi)[0, 0] / 2

    return sg.DiscreteSystem(sg.SO3("g"), L, parameters=[h], name="so3_control")


def _cayley(x) -> np.ndarray:
    """cay(x̂) = I + 4/(4 + |x|²)(x̂ + x̂²/2) in floating point (seed 001 eq. (63))."""
    X = np.array([[0.0, -x[2], x[1]], [x[2], 0.0, -x[0]], [-x[1], x[0], 0.0]])
    return np.eye(3) + 4.0 / (4.0 + float(np.dot(x, x))) * (X + X @ X / 2)


@pytest.fixture
def numpy_windows(monkeypatch):
    """Window programs evaluated with NumPy: small problems need no C build."""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


@pytest.fixture(scope="module")
def problems():
    """``benchmarks/_bvp_problems.py`` (the problem families shared with the benchmark)."""
    return benchmark_module("_bvp_problems")


def test_the_guess_splits_a_half_turn_into_equal_turns(so3_control):
    """The geodesic guess splits a half-turn about a generic axis into N turns by π/N (the
    Cayley-chart guess was singular there: |F| = 6e17 after 1 iteration)."""
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    end = 2 * np.outer(axis, axis) - np.eye(3)  # the rotation by π about the axis
    guess = interpolate_arrows(so3_control.groupoid, end.ravel(), 20)
    angles = [np.arccos((np.trace(a.reshape(3, 3)) - 1) / 2) for a in guess]
    assert np.allclose(angles, np.pi / 20, atol=1e-12)


def test_so3_attitude_problem_converges_and_is_stationary(so3_control):
    R0, RN = np.eye(3), _cay([0.5, -0.3, 0.8])
    sol = sg.solve_boundary_value(so3_control.euler_lagrange(), R0, RN, 40, params={h: 0.025})
    assert sol.residual_norm < 1e-10 and sol.iterations <= 6
    assert np.allclose(sol.configurations[-1], RN, atol=1e-12)
    # quadratic convergence: each residual about the square of the previous (relative)
    hist = sol.history
    assert hist[-2] < 1e-5 and hist[-1] < 1e-10
    assert sg.verify_stationary(sol, so3_control).stationary
    assert sol.controls.shape == (40, 3) and sol["g"].shape == (40, 3, 3)
    # the DEL hold along the solution when stepped with the step equations
    step = so3_control.euler_lagrange()
    for k in (3, 17, 30):
        F, _ = step.evaluate(sol.controls[k + 1], sol.arrows[k], [0.025])
        assert np.max(np.abs(F)) < 1e-10


def test_pair_groupoid_free_particle_is_a_straight_line():
    """L = ½|Δq|²/h: the discrete geodesic between two points is uniformly spaced."""
    Q = sg.EuclideanSpace("x y")
    system = sg.DiscreteSystem(
        sg.PairGroupoid(Q),
        lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h),
        parameters=[h], name="free")
    rng = np.random.default_rng(0)
    pts = np.column_stack([np.linspace(0, 2, 9), np.linspace(1, -1, 9)])
    pts[1:-1] += rng.normal(scale=0.3, size=(7, 2))  # a bent guess with the right ends
    guess = np.hstack([pts[:-1], pts[1:]])
    sol = sg.solve_boundary_value(system.euler_lagrange(), (0.0, 1.0), (2.0, -1.0), 8,
                                  params=[0.1], guess=guess)
    assert np.allclose(sol["x"], np.linspace(0, 2, 9)[1:], atol=1e-12)
    assert np.allclose(sol["y"], np.linspace(1, -1, 9)[1:], atol=1e-12)
    assert sol.iterations == 1  # a linear problem: one Newton step


def test_banded_fallback_matches_lapack(so3_control):
    """The NumPy block-tridiagonal elimination (used without SciPy) gives the same step."""
    with pytest.raises(BoundaryValueDivergenceError) as stopped:  # the initial path
        sg.solve_boundary_value(so3_control, np.eye(3), _cay([0.2, 0.1, -0.4]), 12,
                                params=[1 / 12], max_iterations=0)
    arrows = np.asarray(stopped.value.iterate, float)
    problem = _Problem.of(so3_control, 12, np.array([1 / 12]))
    lay = problem.lay
    assert lay is _layout(12, 1, 3, 0)
    F, rows, cols, vals, *_ = _assemble(problem, arrows, np.zeros((len(arrows), 0)))
    A = np.zeros((lay.size, lay.size))
    np.add.at(A, (rows, cols), vals)
    F = F + 0.01 * np.arange(lay.size)  # a generic right-hand side
    x1 = _solve_banded(rows, cols, vals, lay.size, F)
    x2 = _block_tridiagonal(rows, cols, vals, lay.size, F,
                            int(max(np.max(rows - cols), np.max(cols - rows))))
    assert np.allclose(A @ x1, F) and np.allclose(x1, x2, atol=1e-10)


def test_second_order_rigid_body_attitude_bvp():
    """Seed 001 §3.3.4 shape: a second-order cost on SO(3) (Cayley), g₀, g₁, g_{N−1}, g_N
    fixed; the solution is a critical point of the action."""
    W = sg.SO3("W")

    def L(a, b):
        xa, xb = a.coordinates / h, b.coordinates / h
        acc = (xb - xa) / h
        return h * (acc.T * acc)[0, 0] / 2

    system = sg.SecondOrderSystem(W, L, parameters=[h], name="attitude2")
    N, dt = 20, 0.05
    R1 = _cay([0.0, 0.0, 0.05])
    RN1 = _cay([0.4, -0.2, 0.6])
    RN = RN1 @ _cay([0.0, 0.05, 0.0])
    sol = sg.solve_boundary_value(system.euler_lagrange(), (np.eye(3), R1), (RN1, RN), N,
                                  params=[dt])
    assert sol.residual_norm < 1e-10
    assert np.allclose(sol.arrows[0], _cay([0.0, 0.0, 0.05]).ravel())
    assert np.allclose(sol.configurations[-1], RN, atol=1e-10)
    assert sg.verify_stationary(sol, system).stationary


def test_boundary_data_errors(so3_control):
    step = so3_control.euler_lagrange()
    with pytest.raises(sg.ShapeError, match="at least 2 steps"):
        sg.solve_boundary_value(step, np.eye(3), np.eye(3), 1, params=[0.1])
    with pytest.raises(sg.ShapeError, match=r"3×3 matrix"):
        sg.solve_boundary_value(step, np.eye(2), np.eye(3), 5, params=[0.1])
    with pytest.raises(sg.ShapeError, match=r"guess must have shape \(5, 9\)"):
        sg.solve_boundary_value(step, np.eye(3), np.eye(3), 5, params=[0.1],
                                guess=np.zeros((4, 9)))
    with pytest.raises(KeyError, match="missing parameter h"):
        sg.solve_boundary_value(step, np.eye(3), np.eye(3), 5, params={})
    G = sg.ActionGroupoid(sg.EuclideanSpace.vector("p", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))
    with pytest.raises(sg.NotComposableError, match="not connected"):
        G.arrow_between(((0, 0, 1), np.eye(3)), ((1, 0, 0), np.eye(3)))


def test_second_order_needs_enough_steps_and_both_end_pairs():
    W = sg.SO3("W")
    system = sg.SecondOrderSystem(
        W, lambda a, b: ((b.coordinates - a.coordinates).T * (b.coordinates - a.coordinates))[
            0, 0], name="so2")
    with pytest.raises(sg.ShapeError, match="order 2 needs at least 4"):
        sg.solve_boundary_value(system, (np.eye(3), np.eye(3)), (np.eye(3), np.eye(3)), 3)
    with pytest.raises(sg.ShapeError, match="two configurations at each end"):
        sg.solve_boundary_value(system, np.eye(3), np.eye(3), 6)


def test_unsatisfiable_constraints_report_the_worst_step():
    """A fixed time step with end times that do not fit N steps cannot be solved: the
    error names the step and residual instead of returning garbage."""
    GR = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    system = sg.DiscreteSystem(
        GR, lambda g: (g.target[0] - g.source[0]) ** 2 / (2 * (g.t1 - g.t0)),
        constraints=lambda g: [g.t1 - g.t0 - h], parameters=[h], name="timed")
    with pytest.raises(sg.SymgroupoidError, match="worst at configuration") as info:
        sg.solve_boundary_value(system, (0.0, (0.0,)), (1.0, (1.0,)), 5, params=[0.1],
                                max_iterations=8)
    assert 1 <= info.value.step <= 5 and info.value.residual_norm > 0.01


def test_window_kernels_compiled_and_numpy_agree(so3_control, monkeypatch, tmp_path):
    """The window programs run compiled through the kernel cache once built (in the
    background); forcing the NumPy backend gives the same residual and blocks, bit for bit."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    compiled = WindowKernel(so3_control)
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    plain = WindowKernel(so3_control)
    assert compiled._junction.wait(120) and compiled._junction.backend == "c"
    assert plain._junction.backend == "numpy" and not plain._junction.wait(0)
    arrows = interpolate_arrows(so3_control.groupoid,
                                np.array(sg.SO3("g").numeric_fibre_chart([0.4, -0.2, 0.7])), 12)
    windows = np.stack([arrows[:-1], arrows[1:]], axis=1)
    lams = np.zeros((11, 2, 0))
    (r1, left1, right1, _), (r2, left2, right2, _) = (
        k.junction(windows, lams, np.array([0.1])) for k in (compiled, plain))
    assert np.array_equal(r1, r2) and np.abs(r1).max() > 1e-3
    for o in compiled.offsets:
        assert np.array_equal(left1[o], left2[o]) and np.array_equal(right1[o], right2[o])


@pytest.mark.parametrize("which", ["so3", "second_order"])
def test_junction_blocks_are_the_derivatives_along_the_fields(so3_control, which):
    """Each block (reverse mode: the residual's gradient contracted with the field) is the
    derivative of the junction residual along X⃖_c or X⃗_c on its slot: central differences
    of the residual with the slot's arrow moved by the section flow."""
    W = sg.SO3("W")
    system = so3_control if which == "so3" else sg.SecondOrderSystem(
        W, lambda a, b: sp.Rational(1, 2) * sum(
            (i + 1) * (b.coordinates[i] - a.coordinates[i]) ** 2 for i in range(3)),
        name="so2_blocks")
    kernel, G = window_kernel(system), system.groupoid
    maps = _maps(G)
    rng = np.random.default_rng(11)
    arrows = np.array([np.array(W.cayley(list(rng.uniform(-0.4, 0.4, 3))).tolist(),
                                float).ravel() for _ in range(len(kernel.offsets))])
    windows, lams = arrows[None], np.zeros((1, len(kernel.starts), kernel.m))
    params = np.array([0.1]) if which == "so3" else np.zeros(0)
    _, left, right, _ = kernel.junction(windows, lams, params)
    t = 1e-6
    for k, o in enumerate(kernel.offsets):
        for side, blocks in (("left", left[o][0]), ("right", right[o][0])):
            for c in range(3):
                moved = []
                for s in (t, -t):
                    h = maps.flow_at_target(arrows[k][None], (np.eye(3)[c] * s)[None])
                    a = (maps.multiply(arrows[k][None], h) if side == "left" else
                         maps.multiply(maps.inverse(h), arrows[k][None]))
                    w = windows.copy()
                    w[0, k] = a[0]
                    moved.append(kernel.junction(w, lams, params)[0][0])
                fd = (moved[0] - moved[1]) / (2 * t) * (1 if side == "left" else -1)
                assert np.allclose(blocks[:, c], fd, rtol=1e-6, atol=1e-7), (o, side, c)


def test_pair_groupoid_of_attitudes_takes_matrices_at_the_ends() -> None:
    """On the pair groupoid of SO(3)² the end configurations are tuples of rotation
    matrices, checked as group elements (a point of R⁹ is refused, as the arrows need the
    matrices), and the solution reaches them."""
    from symgroupoid import systems

    step = systems.spherical_chain(2).euler_lagrange()
    start = (_cay([0.1, 0.2, 0.3]), _cay([0.2, -0.1, 0.1]))
    end = (_cay([0.15, 0.25, 0.32]), _cay([0.22, -0.05, 0.12]))
    sol = sg.solve_boundary_value(step, start, end, 6, params={"h": 0.01, "g": 9.81})
    last = sol.arrows[-1]
    np.testing.assert_allclose(last[18:27].reshape(3, 3), end[0], atol=1e-12)
    np.testing.assert_allclose(last[27:].reshape(3, 3), end[1], atol=1e-12)
    with pytest.raises(sg.ShapeError, match="one per factor"):
        sg.solve_boundary_value(step, start[0], end, 6, params={"h": 0.01, "g": 9.81})
    off = (end[0] + 1e-3, end[1])
    with pytest.raises(sg.DomainError, match=r"end\[0\]"):
        sg.solve_boundary_value(step, start, off, 6, params={"h": 0.01, "g": 9.81})


# --- the boundary-value Jacobian at rest ---------------------------------------------------------

@pytest.fixture(scope="module")
def heavy_top_rotors():
    """The underactuated heavy top with two rotors (seed 001 §3.3.5; examples/)."""
    return load_example("heavy_top_rotors")


@pytest.mark.usefixtures("numpy_windows")
def test_heavy_top_at_rest_the_linearised_problem_is_singular(heavy_top_rotors):
    """Why a rest-to-rest maneuver is ill-posed for Newton: at rest the boundary-value Jacobian
    has exactly the null vectors λ₃,k = a + bk (multipliers of Φ³ only).  The windows through
    NumPy (the C windows compute the same bits: test_window_kernels_compiled_and_numpy_agree);
    their C build was two thirds of this test's CPU time."""
    ht = heavy_top_rotors
    system = ht.heavy_top_system()
    n = 12
    arrows = np.array([ht.arrow(ht.E3, np.eye(3), (0.3, 0.1), (0.3, 0.1))] * n)
    problem = _Problem.of(system, n, np.array(ht.parameter_values(0.1)))
    lay = problem.lay
    assert lay is _layout(n, 2, 5, 3)
    F, rows, cols, vals, *_ = _assemble(problem, arrows, np.zeros((n - 1, 3)))
    A = np.zeros((lay.size, lay.size))
    np.add.at(A, (rows, cols), vals)
    s = np.linalg.svd(A, compute_uv=False)
    assert np.abs(F).max() < 1e-12
    assert s[-2] < 1e-14 * s[0] and s[-3] > 1e-10 * s[0]
    null = np.zeros((2, lay.size))
    for t, k in lay.lam_index.items():
        null[0, k + 2], null[1, k + 2] = 1.0, t
    assert np.abs(A @ null.T).max() < 1e-12 * s[0]


# --- the forward-mode window kernel -----------------------------------------------------------

@pytest.mark.slow
def test_window_kernel_matches_symbolic_derivatives():
    """The kernel's residual and blocks equal the X⃖/X⃗ derivatives of the window residual
    differentiated as expression trees, on a constrained second-order system on a product
    groupoid with functions and an opaque one (erf)."""
    h = sp.Symbol("h", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("q")) * sg.SO3("W")

    def L(a, b):
        xa, xb = a[1].coordinates, b[1].coordinates
        q0, q1, q2 = a[0].source[0], a[0].target[0], b[0].target[0]
        return ((xb - xa).dot(xb - xa) / h ** 3 + sp.sin(q1) * xa[0]
                + (q2 - 2 * q1 + q0) ** 2 / h + xb[2] * sp.erf(xb[2]))

    def phi(a, b):
        return [b[1].coordinates[2] - a[1].coordinates[1] * a[0].target[0] - h,
                sp.exp(b[0].target[0]) - a[1].coordinates[0]]

    system = sg.SecondOrderSystem(G, L, constraints=phi, parameters=[h], name="kernel_check")
    kernel = WindowKernel(system)
    action = WindowAction(G, system.functions)
    slots = action.slots("v")
    multipliers = {s: action.multipliers(s) for s in action.starts}
    rng = np.random.default_rng(3)
    windows = np.array([[np.concatenate([rng.normal(size=2), G.factors[1].numeric_fibre_chart(
        rng.normal(scale=0.5, size=3))]) for _ in range(4)] for _ in range(3)])
    lams = rng.normal(size=(3, 3, 2))
    res, left, right, dlam = kernel.junction(windows, lams, np.array([0.2]))
    r = action.variation(slots)
    blocks = {o: ([G.apply_left(e, slots[o]) for e in r],
                  [G.apply_right(e, slots[o]) for e in r]) for o in kernel.offsets}
    dl = {s: [[sp.diff(e, x) for x in multipliers[s]] for e in r] for s in kernel.starts}
    for w in range(3):
        sub = {h: 0.2}
        for o in kernel.offsets:
            sub.update(zip(slots[o], windows[w, o - kernel.offsets[0]]))
        for s in kernel.starts:
            sub.update(zip(multipliers[s], lams[w, s - kernel.starts[0]]))
        value = np.vectorize(lambda e, sub=sub: float(sp.sympify(e).xreplace(sub)))
        assert np.allclose(res[w], value(r), rtol=1e-10, atol=1e-10)
        for o in kernel.offsets:
            assert np.allclose(left[o][w], value(blocks[o][0]), rtol=1e-9, atol=1e-9)
            assert np.allclose(right[o][w], value(blocks[o][1]), rtol=1e-9, atol=1e-9)
        for s in kernel.starts:
            assert np.allclose(dlam[s][w], value(dl[s]), atol=1e-10)
    c = action.constraints_on(slots, 0)
    cblocks = [([G.apply_left(e, slots[o]) for e in c], [G.apply_right(e, slots[o])
                                                             for e in c]) for o in range(2)]
    cres, cleft, cright = kernel.term(windows[:, :2], np.array([0.2]))
    for w in range(3):
        sub = {h: 0.2}
        for o in range(2):
            sub.update(zip(slots[o], windows[w, o]))
        value = np.vectorize(lambda e, sub=sub: float(sp.sympify(e).xreplace(sub)))
        assert np.allclose(cres[w], value(c))
        for o in range(2):
            assert np.allclose(cleft[o][w], value(cblocks[o][0]))
            assert np.allclose(cright[o][w], value(cblocks[o][1]))


# --- the banded LU solve through NumPy's own LAPACK (runtime/_lapack.py) -------------------------

needs_lapack = pytest.mark.skipif(not _lapack.available(),
                                  reason="this NumPy has no LAPACK of its own")


def _banded(n: int, kl: int, ku: int, rng) -> tuple[np.ndarray, np.ndarray]:
    A = np.zeros((n, n))
    ab = np.zeros((2 * kl + ku + 1, n))
    for i in range(n):
        for j in range(max(0, i - kl), min(n, i + ku + 1)):
            A[i, j] = ab[kl + ku + i - j, j] = rng.normal()
    return A, ab


@needs_lapack
@pytest.mark.parametrize("n,kl,ku", [(1, 0, 0), (7, 2, 1), (200, 5, 9), (64, 0, 3)])
def test_solves_banded_systems(n, kl, ku):
    rng = np.random.default_rng(n + kl + ku)
    A, ab = _banded(n, kl, ku, rng)
    A += np.eye(n) * 4
    ab[kl + ku] += 4
    b = rng.normal(size=n)
    before = ab.copy()
    x, info = _lapack.dgbsv(kl, ku, ab, b)
    assert info == 0
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-12 * np.abs(b).max())
    assert np.array_equal(ab, before), "the caller's storage is not modified"
    scipy_lapack = pytest.importorskip("scipy.linalg.lapack")
    _, _, y, _ = scipy_lapack.dgbsv(kl, ku, ab.copy(), b.copy())
    np.testing.assert_allclose(x, y, rtol=1e-13, atol=1e-15)


@needs_lapack
def test_singular_matrix_reports_its_zero_pivot():
    A, ab = _banded(5, 1, 1, np.random.default_rng(0))
    ab[:, 2] = 0.0  # column 2 is zero
    _, info = _lapack.dgbsv(1, 1, ab, np.ones(5))
    assert info == 3
    rows, cols = np.nonzero(A)
    keep = cols != 2
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        _solve_banded(rows[keep], cols[keep], A[rows[keep], cols[keep]], 5, np.ones(5))


@needs_lapack
def test_storage_that_does_not_fit_the_bandwidths_is_refused():
    with pytest.raises(ValueError, match="do not fit"):
        _lapack.dgbsv(1, 1, np.zeros((3, 4)), np.zeros(4))


@needs_lapack
def test_solver_falls_back_when_numpy_has_no_lapack(monkeypatch):
    rng = np.random.default_rng(3)
    A, _ = _banded(30, 2, 2, rng)
    A += np.eye(30) * 4
    rows, cols = np.nonzero(A)
    b = rng.normal(size=30)
    calls = []
    monkeypatch.setattr(_lapack, "dgbsv", lambda *args: calls.append(args))  # returns None
    pytest.importorskip("scipy.linalg")
    x = _solve_banded(rows, cols, A[rows, cols], 30, b)
    assert calls, "NumPy's LAPACK was asked first"
    # SciPy's gbsv (another LAPACK build: equal to rounding, not necessarily bit for bit)
    np.testing.assert_allclose(A @ x, b, rtol=0, atol=1e-13 * np.abs(b).max())


# --- the window programs' evaluator (runtime/_programs.py) -------------------------------------

def test_unknown_backend_in_the_environment_is_refused(monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "fortran")
    with pytest.raises(sg.DomainError, match="SYMGROUPOID_BACKEND"):
        _kernels._vectorised("bad backend", _program(), "a", "out")


def test_numpy_form_is_evaluated_in_bounded_chunks(monkeypatch):
    """Rows are evaluated a bounded number at a time (memory), with the same bits."""
    program = _program(5)
    whole = program.numpy_function(["out"], ["a"])(VALUES.T)[0].T
    seen = []
    monkeypatch.setattr(_programs, "NUMPY_ROWS", 10)
    evaluator = ProgramEvaluator("evaluator chunks", program, "a", "out", backend="numpy")
    raw = program.numpy_function(["out"], ["a"])

    def spy(values):
        seen.append(values.shape[1])
        return raw(values)

    evaluator._numpy = spy
    assert np.array_equal(evaluator(VALUES), whole)
    assert max(seen) == 10 and sum(seen) == len(VALUES)


# --- the assembly by the layout's fixed pattern; the second-order condition on request ------

def _scattered(kernel, lay, arrows, lam, p):
    """F, the cancelling magnitudes and the dense Jacobian scattered block by block from the
    window programs' split outputs (the assembly before the pattern)."""
    r, m, a = kernel.rank, kernel.m, kernel.arity
    F, cancel = np.zeros(lay.size), np.zeros(lay.size)
    rows, cols, vals = [], [], []
    J, T = lay.junctions, lay.terms
    windows = np.stack([arrows[J + o] for o in kernel.offsets], axis=1)
    lams = (np.stack([lam[J + s] for s in kernel.starts], axis=1) if m
            else np.zeros((len(J), len(kernel.starts), 0)))
    res, left, right, dlam, sizes = kernel.junction_terms(windows, lams, p)
    eq = lay.delta_at[J]
    F[eq[:, None] + np.arange(r)], cancel[eq[:, None] + np.arange(r)] = res, sizes
    for o in kernel.offsets:
        _add(rows, cols, vals, lay.delta_at, eq, J + o, left[o], r)
        _add(rows, cols, vals, lay.delta_at, eq, J + o - 1, -right[o], r)
    for s in kernel.starts:
        _add(rows, cols, vals, lay.lam_at, eq, J + s, dlam[s], m)
    if m:
        res, left, right, sizes = kernel.term_terms(
            np.stack([arrows[T + o] for o in range(a)], axis=1), p)
        eq = lay.lam_at[T]
        F[eq[:, None] + np.arange(m)], cancel[eq[:, None] + np.arange(m)] = res, sizes
        for o in range(a):
            _add(rows, cols, vals, lay.delta_at, eq, T + o, left[o], r, m)
            _add(rows, cols, vals, lay.delta_at, eq, T + o - 1, -right[o], r, m)
    A = np.zeros((lay.size, lay.size))
    np.add.at(A, (np.concatenate(rows), np.concatenate(cols)), np.concatenate(vals))
    return F, cancel, A


def _second_order_so3():
    W = sg.SO3("W")

    def L(a, b):
        xa, xb = a.coordinates / h, b.coordinates / h
        return h * sum((xb[i] - xa[i]) ** 2 for i in range(3)) / (2 * h ** 2)

    return sg.SecondOrderSystem(W, L, parameters=[h], name="so3_jerk")


@pytest.mark.usefixtures("numpy_windows")
def test_gathered_assembly_matches_the_block_scatter(problems):
    """The pattern's gather gives F, the cancelling magnitudes and the Jacobian of the
    block-by-block scatter, for a constrained first-order and a second-order system, at an
    iterate with non-zero multipliers; the banded solve through the pattern's storage
    solves the dense system."""
    rng = np.random.default_rng(7)
    se2 = problems.se2_system()
    cases = [(se2, problems.pose(0.8, 0.6, 1.0), 9, [1 / 9, 1.0, 2.0])]
    W = _second_order_so3()
    cases.append((W, problems.rotation((0.3, -0.2, 0.5)), 10, [0.1]))
    for system, end, n, params in cases:
        p = np.array(params, float)
        problem, G = _Problem.of(system, n, p), system.groupoid
        kernel, lay = problem.kernel, problem.lay
        a, m = kernel.arity, kernel.m
        arrows = interpolate_arrows(G, G.arrow_between(np.eye(3), end), n)
        lam = rng.normal(size=(n - a + 1, m))
        state = _assemble(problem, arrows, lam)
        F, cancel, A = _scattered(kernel, lay, arrows, lam, p)
        dense = np.zeros_like(A)
        np.add.at(dense, (state.rows, state.cols), state.vals)
        assert np.array_equal(state.F, F) and np.array_equal(state.cancel, cancel)
        assert np.array_equal(dense, A), system.name
        x = _solve_banded(state.rows, state.cols, state.vals, lay.size, F, state.band)
        assert np.allclose(A @ x, F, rtol=1e-9, atol=1e-9 * np.abs(F).max())


@pytest.mark.usefixtures("numpy_windows")
def test_inertia_and_configurations_are_computed_on_request(problems):
    """A solve leaves the second-order condition to the solution, which computes it at the
    solution's KKT matrix when asked — the same inertia as computed in the solve (minimum
    =True), and also after the solution was pickled (as sweeps send it between processes);
    the configurations are the products of the arrows from the first."""
    system = problems.se2_system()
    end = problems.pose(0.5, 0.4, 0.7)
    sol = sg.solve_boundary_value(system, np.eye(3), end, 40, params=[1 / 40, 1.0, 1.0])
    assert sol.second_order == ()
    data = pickle.loads(pickle.dumps(_solution_data(sol)))  # as a sweep's worker sends it
    copy = sg.BoundaryValueSolution(system=system, **data)
    eager = sg.solve_boundary_value(system, np.eye(3), end, 40, params=[1 / 40, 1.0, 1.0],
                                    minimum=True)
    assert len(eager.second_order) == 1 and eager.inertia is not None
    assert sol.inertia == eager.inertia == copy.inertia and sol.is_local_minimum
    assert sol.second_order == (sol.inertia,)
    expected = [np.eye(3)]
    for g in sol.arrows:
        expected.append(expected[-1] @ system.groupoid.numeric_matrix(g))
    assert np.allclose(np.array(sol.configurations), np.array(expected), atol=1e-13)
    assert np.allclose(sol.configurations[-1], end, atol=1e-12)


def _handing_over(problems):
    """SE(2), N = 151 (``random_problems(20, seed=1, steps=(60, 200))[10]``): the fast path
    hands over to the globalised iteration."""
    p = problems.random_problems(20, seed=1, steps=(60, 200))[10]
    assert p.kind == "se2" and p.steps == 151
    return p


@pytest.mark.usefixtures("numpy_windows")
def test_the_globalised_iteration_restarts_from_the_best_fast_path_iterate(problems,
                                                                            monkeypatch):
    """After the handover the globalised iteration starts at the fast path's iterate of least
    merit (not the initial path) and reaches the same local minimum as from the initial
    path, in fewer iterations."""
    p = _handing_over(problems)
    chosen = []
    restart = _fast._restart_points

    def spy(state, initial, iterates):
        starts = restart(state, initial, iterates)
        chosen.append((starts, initial))
        return starts

    monkeypatch.setattr(_solve, "_restart_points", spy)
    sol = p.solve()
    (starts, initial), = chosen
    assert len(starts) == 2 and starts[1][0] is initial[0]
    assert not np.array_equal(starts[0][0], initial[0])
    monkeypatch.setattr(_solve, "_restart_points", lambda state, initial, iterates: [initial[:2]])
    from_initial = p.solve()
    assert "inertia-corrected" in sol.method and sol.is_local_minimum
    assert sol.iterations < from_initial.iterations
    assert np.abs(sol.controls - from_initial.controls).max() / p.params[0] < 1e-8
    assert sol.cost == pytest.approx(from_initial.cost, rel=1e-12)


@pytest.mark.usefixtures("numpy_windows")
def test_the_initial_path_is_the_fallback_of_the_restart(problems, monkeypatch):
    """When the globalised iteration from the best iterate finds no decrease, it starts again
    from the initial path and converges there; when that fails too, the error names both."""
    p = _handing_over(problems)
    globalised, calls = _globalised._globalised, []

    def first_fails(state, arrows, lam):
        calls.append(arrows)
        if len(calls) == 1:
            raise BoundaryValueDivergenceError("x: boundary-value iteration found no decrease "
                                               "(line search); after 0 iterations", iterations=0)
        return globalised(state, arrows, lam)

    monkeypatch.setattr(_globalised, "_globalised", first_fails)
    sol = p.solve()
    assert len(calls) == 2 and sol.is_local_minimum
    G = p.system.groupoid
    initial = interpolate_arrows(G, G.arrow_between(p.start, p.end), p.steps)
    assert np.array_equal(calls[1], initial)

    def always_fails(state, arrows, lam):
        raise BoundaryValueDivergenceError("x: boundary-value iteration found no decrease "
                                           "(line search); after 0 iterations", iterations=0)

    monkeypatch.setattr(_globalised, "_globalised", always_fails)
    with pytest.raises(BoundaryValueDivergenceError,
                       match="from its best iterate, the globalised iteration"):
        p.solve()


@pytest.mark.usefixtures("numpy_windows")
def test_a_stall_is_not_retried_from_the_initial_path(problems, monkeypatch):
    """A stall (an update below tol_step, or one that changes nothing) is the caller's
    criterion or the rounding floor: the solve stops there instead of starting over from
    the initial path."""
    p = _handing_over(problems)
    calls = []

    def stalls(state, arrows, lam):
        calls.append(arrows)
        state.stalled = f"the update fell below tol_step = {state.problem.tol_step:g}"
        raise BoundaryValueDivergenceError("x: boundary-value iteration stalled: "
                                           f"{state.stalled}", iterations=state.iterations)

    monkeypatch.setattr(_globalised, "_globalised", stalls)
    with pytest.raises(BoundaryValueDivergenceError, match="stalled"):
        p.solve()
    assert len(calls) == 1


# --- the line search at the rounding floor ---------------------------------------------------

def test_line_search_at_the_rounding_floor_takes_the_step_at_once(so3_control, monkeypatch):
    """At a solution (|F| at its floor) a step that cannot decrease |F| — here dz = 0, where
    the Armijo test always fails — is taken with one evaluation, not halved 30 times."""
    end = _cayley(np.array([0.4, 0.2, -0.5]))
    sol = sg.solve_boundary_value(so3_control, np.eye(3), end, 40, params=[1 / 40])
    problem = _state._Problem.of(so3_control, 40, np.array([1 / 40]))
    assert problem.lay is _layout(40, 1, 3, 0)
    state = _state._SolverState.at(problem, sol.arrows, sol.multipliers)
    calls = []
    assemble = _state._assemble
    monkeypatch.setattr(_state, "_assemble", lambda *a: calls.append(1) or assemble(*a))
    step = _fast._line_search(state, np.zeros(problem.lay.size))
    assert step is not None and step.length == 1.0 and step.at_floor and len(calls) == 1


def test_rigid_body_line_search_never_backtracks(monkeypatch):
    """The N = 1000 attitude maneuver (seed 001 §3.3.4): every update is a full Newton step,
    with one assembly per iteration, up to the floor."""
    rb = load_example("rigid_body_attitude")
    calls = []
    assemble = _state._assemble
    monkeypatch.setattr(_state, "_assemble", lambda *a: calls.append(1) or assemble(*a))
    sol = rb.solve(1000)
    assert sol.iterations <= 5 and len(calls) == sol.iterations + 1
    assert sol.method == "Newton" and sol.is_local_minimum
    assert sol.cost == pytest.approx(rb.cost(sol), rel=1e-12)


@pytest.mark.usefixtures("numpy_windows")
def test_a_constraint_of_small_chart_coordinates_converges_to_its_floor(problems, monkeypatch):
    """SE(2) unicycle, N = 151, the globalised iteration restarted from the initial path:
    the last update needed is ~1e-22 (the constraint v₂ = x₃ of arrows near the identity, a
    difference of products of matrix entries); the former absolute criterion tol_step = 1e-9
    called that a stall, the floor-relative one does not."""
    monkeypatch.setattr(_solve, "_restart_points", lambda state, initial, iterates: [initial[:2]])
    p = problems.random_problems(20, seed=1, steps=(60, 200))[10]
    assert p.kind == "se2" and p.steps == 151
    sol = p.solve()
    problem = _state._Problem.of(p.system, p.steps, np.array(p.params))
    assert problem.lay is _layout(p.steps, 1, 3, 1)
    state = _assemble(problem, sol.arrows, sol.multipliers)
    assert _excess(state.F, _rounding_floor(state), 0.0) <= 1.0
    with pytest.raises(BoundaryValueDivergenceError, match="tol_step"):
        p.solve(tol_step=1e-9)


# --- globalisation -------------------------------------------------------------------------------

def _dense(state, n: int) -> np.ndarray:
    A = np.zeros((n, n))
    np.add.at(A, (state.rows, state.cols), state.vals)
    return A


def _reduced_hessian_eigenvalues(system, sol, params) -> np.ndarray:
    """Eigenvalues of ZᵀHZ from dense linear algebra: H the δ-block of the symmetrised
    Jacobian at the solution, Z an orthonormal basis of the null space of the constraint
    gradients (independent of the banded LDLᵀ)."""
    from scipy.linalg import null_space

    G = system.groupoid
    a, m = len(system._fs.slots), len(system._fs.constraints)
    problem = _state._Problem.of(system, sol.steps, np.asarray(params, float))
    lay = problem.lay
    assert lay is _layout(sol.steps, a, G.rank, m)
    state = _assemble(problem, sol.arrows, sol.multipliers)
    K = _dense(state, lay.size)
    K = (K + K.T) / 2
    d, c = _variation_rows(lay, G.rank), _multiplier_rows(lay, m)
    H = K[np.ix_(d, d)]
    Z = null_space(K[np.ix_(c, d)]) if len(c) else np.eye(len(d))
    return np.linalg.eigvalsh(Z.T @ H @ Z)


@pytest.mark.usefixtures("numpy_windows")
def test_globalised_iteration_converges_where_newton_crawls(problems, monkeypatch):
    """SO(3) steering with ψ = ξ₃ − uξ₁ (13° turn, N = 150): Newton alone from the geodesic
    guess crawls with damped steps (it fails the former cap of 30 iterations); the solver
    hands over to the inertia-corrected iteration and converges in half of that, to a
    stationary point (checked on the action) that is a strict local minimum (checked by dense
    linear algebra)."""
    base = problems.random_problems()[11]
    p = dataclasses.replace(base, steps=150, params=(1 / 150,) + base.params[1:])
    sol = p.solve()
    assert "inertia-corrected" in sol.method and sol.iterations <= 15
    assert sg.verify_stationary(sol, p.system).stationary
    eigenvalues = _reduced_hessian_eigenvalues(p.system, sol, p.params)
    assert eigenvalues.min() > 0 and sol.is_local_minimum
    assert sol.inertia.positive == len(eigenvalues)
    assert sol.cost == pytest.approx(p.cost(sol.arrows), rel=1e-12)

    def refuse(state, starts, why):
        raise BoundaryValueDivergenceError(why, iterations=state.iterations)

    monkeypatch.setattr(_fast, "MAX_DAMPED", 10**9)
    monkeypatch.setattr(_solve, "_globalised_after", refuse)
    with pytest.raises(BoundaryValueDivergenceError, match="30 iterations"):
        p.solve(max_iterations=30)


# --- the second-order condition: banded inertia (runtime/_banded.py), dense checks --------------

def test_banded_inertia_matches_dense_eigenvalues():
    """Random symmetric banded matrices: definite, indefinite, saddle-point (zero blocks, as
    KKT matrices have) and singular ones."""
    rng = np.random.default_rng(7)
    for trial in range(120):
        n, w = int(rng.integers(1, 50)), int(rng.integers(0, 6))
        A = rng.normal(size=(n, n)) * (np.abs(np.subtract.outer(range(n), range(n))) <= w)
        if trial % 3 == 0:
            idx = rng.choice(n, size=n // 3, replace=False)
            A[np.ix_(idx, idx)] = 0.0
        if trial % 5 == 0:
            A = A @ A.T * (np.abs(np.subtract.outer(range(n), range(n))) <= w)
        if trial % 7 == 0 and n > 2:
            A[:, 1] = A[1, :] = 0.0
        ev = np.linalg.eigvalsh((A + A.T) / 2)
        tiny = 1e-9 * max(np.abs(ev).max(), 1e-300)
        expected = ((ev > tiny).sum(), (ev < -tiny).sum(), (np.abs(ev) <= tiny).sum())
        r, c = np.nonzero(A)
        assert tuple(banded_inertia(r, c, A[r, c], n)) == expected, (n, w, trial)


@pytest.fixture(scope="module")
def spring():
    """L = (q₁ − q₀)²/(2h) − h k (q₀² + q₁²)/4 on the pair groupoid of R (a harmonic
    oscillator, ω = √k): the action is minimal only up to the first conjugate point, ωT = π."""
    k = sp.Symbol("k", positive=True)

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                             name="spring")


@pytest.mark.usefixtures("numpy_windows")
@pytest.mark.parametrize("k, descent", [(4.0, 0), (16.0, 1), (60.0, 2)])
def test_a_stationary_point_past_conjugate_points_is_flagged(spring, k, descent):
    """T = 1, ω = √k: ωT = 2, 4, 7.7 passes 0, 1, 2 conjugate points (multiples of π), so
    the Hessian of the action has that many negative eigenvalues (dense check), the flag
    and the repr say so, and ``minimum=True`` refuses the saddle."""
    sol = sg.solve_boundary_value(spring, 0.0, 1.0, 40, params=[1 / 40, k])
    eigenvalues = _reduced_hessian_eigenvalues(spring, sol, [1 / 40, k])
    assert (eigenvalues < 0).sum() == descent
    assert sol.inertia.negative == descent and sol.is_local_minimum == (descent == 0)
    assert repr(sol).endswith(", local minimum>") == (descent == 0)
    assert ("NOT a local minimum" in repr(sol)) == (descent > 0)
    assert sol.cost == pytest.approx(action(spring, sol.arrows, None, [1 / 40, k]), rel=1e-12)
    if descent:
        with pytest.raises(BoundaryValueDivergenceError):
            sg.solve_boundary_value(spring, 0.0, 1.0, 40, params=[1 / 40, k], minimum=True,
                                    max_iterations=20)


@pytest.mark.usefixtures("numpy_windows")
def test_a_turn_past_two_pi_is_a_saddle():
    """Isotropic inertia (a bi-invariant metric): the uniform rotation by 2.5π about an axis is
    a discrete geodesic past its conjugate point at 2π, of multiplicity two (the directions
    normal to the axis), so the reduced Hessian has two negative eigenvalues."""

    def L(g):
        xi = g.coordinates / h
        return h * (xi.T * xi)[0, 0] / 2

    system = sg.DiscreteSystem(sg.SO3("g"), L, parameters=[h], name="so3_isotropic")
    n, axis = 60, np.array([1.0, 2.0, 2.0]) / 3
    arrow = sg.SO3("g").numeric_fibre_chart(2 * np.tan(2.5 * np.pi / (2 * n)) * axis)
    guess = np.tile(arrow, (n, 1))
    end = np.linalg.matrix_power(arrow.reshape(3, 3), n)
    sol = sg.solve_boundary_value(system, np.eye(3), end, n, params=[1 / n], guess=guess)
    assert np.abs(sol.arrows - guess).max() < 1e-12
    assert sol.inertia.negative == 2 and sol.is_local_minimum is False
    assert (_reduced_hessian_eigenvalues(system, sol, [1 / n]) < 0).sum() == 2
    default = sg.solve_boundary_value(system, np.eye(3), end, n, params=[1 / n])
    assert default.is_local_minimum and default.cost < sol.cost


# --- forced systems (docs/conventions.md §20) --------------------------------------------------

def test_a_forced_solve_has_no_globalised_iteration(numpy_windows, monkeypatch):
    """A forced system's solutions are not critical points of the action: when the fast path
    gives up, the solve raises instead of descending the action (a singular Jacobian that
    ended it is raised as it is)."""
    from test_forced_bvp import PENDULUM, driven_double_pendulum

    called = []

    def gives_up(why):
        def fast(state):
            state.record()
            if why == "singular":
                raise _fast._Handover("a singular Jacobian", []) from state.singular()
            raise _fast._Handover("found no decrease (test)", [])
        return fast

    monkeypatch.setattr(_solve, "_globalised_after", lambda *a: called.append(a))
    for why, error, match in (("decrease", BoundaryValueDivergenceError, "no action to descend"),
                              ("singular", sg.SingularJacobianError, "singular")):
        monkeypatch.setattr(_solve, "_fast_newton", gives_up(why))
        with pytest.raises(error, match=match):
            sg.solve_boundary_value(driven_double_pendulum(), (0.3, -0.2), (0.5, 0.1), 8,
                                    params=PENDULUM, inputs=[0.0, 0.0])
    assert not called


def test_a_forced_window_kernel_takes_the_inputs_of_its_terms(numpy_windows):
    """The kernel places the inputs of each term of each window after the multipliers; a
    forced system's kernel without them is refused."""
    from test_forced_bvp import (
        PENDULUM,
        driven_double_pendulum,
        forced_step_residuals,
        pendulum_run,
    )

    system = driven_double_pendulum()
    kernel = window_kernel(system)
    assert kernel.forced and kernel.n_inputs == 2
    U = np.random.default_rng(6).normal(size=(6, 2))
    arrows = pendulum_run(system, 6, U)
    windows = np.stack([arrows[:-1], arrows[1:]], axis=1)
    inputs = np.stack([U[:-1], U[1:]], axis=1)
    res = kernel.junction(windows, np.zeros((5, 2, 0)), np.array([0.05, 0.3]), inputs)[0]
    np.testing.assert_allclose(res, forced_step_residuals(system, arrows, U, PENDULUM),
                               rtol=1e-12, atol=1e-12)
    with pytest.raises(sg.ShapeError, match="inputs"):
        kernel.junction(windows, np.zeros((5, 2, 0)), np.array([0.05, 0.3]))
    with pytest.raises(sg.ShapeError, match="needs them"):
        _Problem.of(system, 6, np.array([0.05, 0.3]))


def _stage_systems(which: str):
    """Discretised systems with internal stages (docs/conventions.md §22), their parameters,
    inputs and two end configurations (tests/test_stage_bvp.py)."""
    from test_stage_bvp import BODY, PEND, double_pendulum, rigid_body

    if which == "forced_gauss2":
        return (double_pendulum(sg.GaussLegendre(2), forced=True), PEND, np.zeros((7, 1)),
                ([0.4, -0.2], [0.5, 0.3]))
    if which == "lobatto3_constrained":
        continuous = sg.ContinuousSystem(
            sg.EuclideanSpace("x y"), lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - 9 * q[1],
            parameters=[h], holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1], name="cartesian")
        return (continuous.discretize(h, sg.LobattoIIIAB(3)), {"h": 0.05}, None,
                ([np.sin(0.3), -np.cos(0.3)], [np.sin(0.8), -np.cos(0.8)]))
    return (rigid_body(forced=True), BODY, np.zeros((7, 3)),
            (np.eye(3), _cayley(np.array([0.4, 0.2, -0.3]))))


@pytest.mark.parametrize("which", ["forced_gauss2", "lobatto3_constrained",
                                   pytest.param("forced_body", marks=pytest.mark.slow)])
def test_the_jacobian_with_internal_stages_is_the_derivative_of_the_residual(numpy_windows,
                                                                             which):
    """With internal stages the unknowns gain ζ_t of every term (after its multipliers) and
    the equations their stage rows (§22): at a random iterate (random stages, multipliers and
    inputs, arrows off the solution) every column of the assembled Jacobian is the central
    difference of F along that unknown (the junction variations through the groupoid's
    flow, the stages and multipliers as coordinates); the pattern's band widths are those of
    the matrix, and the banded solve is the dense one."""
    system, params, U, (start, end) = _stage_systems(which)
    n, rng = 7, np.random.default_rng(11)
    p = np.array([params[str(s)] for s in system.parameters], float)
    if U is not None:
        U = rng.normal(size=U.shape)
    problem = _Problem.of(system, n, p, inputs=U)
    kernel, lay = problem.kernel, problem.lay
    assert kernel.n_stages == system.stages and len(lay.staged) == n
    G = system.groupoid
    arrows = interpolate_arrows(G, G.arrow_between(start, end), n)
    start_state = _state._SolverState.at(problem, arrows,
                                         np.zeros((n, kernel.m + kernel.n_stages)))
    arrows = start_state.update(0.02 * rng.normal(size=lay.size))[0]  # off the straight path
    lam = np.hstack([rng.normal(size=(n, kernel.m)),
                     0.01 * rng.normal(size=(n, kernel.n_stages))])
    state = _state._SolverState.at(problem, arrows, lam)
    A = np.zeros((lay.size, lay.size))
    np.add.at(A, (state.assembled.rows, state.assembled.cols), state.assembled.vals)
    eps = 1e-6
    for k in range(lay.size):
        dz = np.zeros(lay.size)
        dz[k] = eps
        plus = _assemble(problem, *state.update(dz)).F
        minus = _assemble(problem, *state.update(-dz)).F
        column = (plus - minus) / (2 * eps)
        assert np.abs(column - A[:, k]).max() <= 1e-6 * max(1.0, np.abs(A[:, k]).max()), k
    rows, cols = np.nonzero(A)
    band, widths = state.assembled.band, (int((rows - cols).max()), int((cols - rows).max()))
    assert band.kl >= widths[0] and band.ku >= widths[1] and max(band.kl, band.ku) < 12
    if not kernel.m:  # every entry of the pattern is generically non-zero
        assert (band.kl, band.ku) == widths
    F = state.assembled.F
    x = _solve_banded(state.assembled.rows, state.assembled.cols, state.assembled.vals,
                      lay.size, F, band)
    np.testing.assert_allclose(x, np.linalg.solve(A, F), rtol=1e-9,
                               atol=1e-9 * np.abs(x).max())


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("scale", [1e40, 1e60])
def test_a_guess_whose_residual_squares_overflow_is_refused_by_name(scale):
    """A quartic potential at a guess of size 1e40 or 1e60: |F|₂² and the rounding floor's
    square overflow (|F| beyond 1e154).  The line search halves such trials instead of
    taking an overflowed square for a decrease, and the floor test compares scaled squares:
    a BoundaryValueDivergenceError, no RuntimeWarning, no step accepted on noise."""
    h, k = sp.symbols("h k", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x"))

    def L(g):
        a, b = g.source[0], g.target[0]
        return (b - a) ** 2 / (2 * h) - h * k * (a ** 4 + b ** 4) / 4

    step = sg.DiscreteSystem(G, L, parameters=[h, k], name="quartic").euler_lagrange()
    q = np.linspace(0.1, 0.2, 11) * scale
    q[0], q[-1] = 0.1, 0.2
    guess = np.stack([q[:-1], q[1:]], axis=1)
    with pytest.raises(BoundaryValueDivergenceError, match="quartic"):
        sg.solve_boundary_value(step, [0.1], [0.2], 10, guess=guess,
                                params={"h": 0.1, "k": 1.0})
    q = np.linspace(0.1, 0.2, 11)
    solved = sg.solve_boundary_value(step, [0.1], [0.2], 10,
                                     guess=np.stack([q[:-1], q[1:]], axis=1),
                                     params={"h": 0.1, "k": 1.0})
    assert solved.arrows[0][0] == 0.1 and solved.arrows[-1][1] == 0.2


def test_a_singular_initial_path_is_named_once(monkeypatch):
    """A pendulum in (x, y) on x² + y² = 1 from the bottom to the top: both ends on the
    circle, but the default path runs straight through the centre, where the constraint's
    gradient vanishes.  The error blamed the boundary data, and said it twice (the fast
    path's message inside the globalised one's); it names the initial path, once.  (The
    globalised iteration is made to fail at once here, as it does at an exactly singular
    path: its inertia computation is LAPACK's, which is not what is tested.)"""
    # white-box: the globalised iteration replaced by its failure at the first iterate
    from symgroupoid.runtime._bvp import _globalised

    monkeypatch.setattr(_globalised, "_globalised",
                        lambda state, *start: (_ for _ in ()).throw(state.singular()))
    h, g = sp.symbols("h g", positive=True)

    def L(a):
        (x0, y0), (x1, y1) = a.source, a.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h) - h * g * (y0 + y1) / 2

    pendulum = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L,
                                 holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1],
                                 parameters=[h, g], name="planar").euler_lagrange()
    with pytest.raises(sg.SingularJacobianError, match="at the initial path") as info:
        sg.solve_boundary_value(pendulum, (0.0, -1.0), (0.0, 1.0), 30,
                                params={"h": 0.05, "g": 9.81})
    assert str(info.value).count("singular boundary-value Jacobian") == 1
    assert "the Newton fast path ended the same way" in str(info.value)
