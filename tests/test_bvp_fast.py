"""The boundary-value solver's per-solve work: the assembly by the layout's fixed pattern, the
second-order condition and the configurations computed on request, and the globalised
iteration's restart from the fast path's best iterate (with the initial path as fallback)."""

from __future__ import annotations

import pathlib
import pickle
import sys

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import BoundaryValueDivergenceError

# the solver's fast path and its fixed-pattern assembly are checked against the general one
from symgroupoid.runtime._bvp import _fast, _globalised, _solve, interpolate_arrows
from symgroupoid.runtime._bvp._assembly import _add, _assemble
from symgroupoid.runtime._bvp._linear import _solve_banded
from symgroupoid.runtime._bvp._state import _Problem
from symgroupoid.runtime._sweep_boundary import _solution_data

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent / "benchmarks"
h = sp.Symbol("h", positive=True)


@pytest.fixture(autouse=True)
def numpy_windows(monkeypatch):
    """Window programs evaluated with NumPy: small problems need no C build."""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


@pytest.fixture(scope="module")
def problems():
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    import _bvp_problems

    return _bvp_problems


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
