"""A step's solution is accepted only where the discrete Lagrangian is defined
(docs/conventions.md §11, "Staying in the domain of L").

L = v²/2 − log x pulls x towards 0; its step equations hold 1/x, never log x, so Newton
solves them on both sides of x = 0.  Without the domain check a run by the midpoint rule
from (1, 0.95) at h = 0.01 crossed to x < 0 at step 18 and went on to x = −6.0 with every
residual at rounding.  The check evaluates the window's logarithms (square roots, acos, …)
at every solution: the same run now stops there with a LagrangianDomainError, in C and in
NumPy alike, with the trajectory up to the step before.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
PARAMS = {"h": 0.01}
START = {"x": (1.0, 0.95)}
CROSSING = 18  # the step whose solution lies at x < 0 (the midpoint rule, from START)


def _system(potential=lambda x: sp.log(x), name="logpot") -> sg.ContinuousSystem:
    return sg.ContinuousSystem(sg.EuclideanSpace("x"),
                               lambda q, v: v[0] ** 2 / 2 - potential(q[0]),
                               parameters=[h], name=name)


@pytest.fixture(scope="module")
def log_step():
    return _system().discretize(h, "midpoint").euler_lagrange()


@pytest.fixture(scope="module")
def domain_cache(tmp_path_factory):
    """One kernel cache for the module's runs (none of its tests is about the cache): the
    logarithm's step is compiled once."""
    return tmp_path_factory.mktemp("domain_cache")


@pytest.fixture(scope="module", params=["c", "numpy"])
def log_sim(request, log_step, domain_cache):
    return log_step.compile(backend=request.param, cache_dir=domain_cache)


def test_kinds_name_the_logarithm_of_every_term(log_step):
    kinds = log_step.domain_kinds
    assert len(kinds) == 2 == len(log_step.program.outputs["domain"])
    assert kinds[0] == "log(x_{k+1}/2 + x_{k}/2): log needs an argument > 0 (the new arrow's term)"
    assert kinds[1] == "log(x_{k-1}/2 + x_{k}/2): log needs an argument > 0 (a known arrow's term)"


def test_a_run_stops_where_the_solution_leaves_the_domain(log_sim):
    with pytest.raises(sg.LagrangianDomainError) as info:
        log_sim.simulate(START, 400, PARAMS)
    err = info.value
    assert isinstance(err, sg.NewtonDivergenceError)
    assert err.step == CROSSING
    assert err.residual_norm < 1e-12  # Newton did solve the step equations there
    assert "log" in str(err) and "not defined" in str(err)
    assert any("new arrow" in k for k in err.kinds)
    kept = err.trajectory.states
    assert len(kept) == CROSSING + 1
    assert (kept[:, :2].sum(axis=1) > 0).all()  # every kept arrow's midpoint inside
    # the solution refused: its midpoint is at x < 0, where log is not defined
    assert err.iterate[0] + kept[-1][1] < 0


def test_c_and_numpy_stop_at_the_same_step_with_the_same_states(log_step, domain_cache):
    runs = []
    for backend in ("c", "numpy"):
        sim = log_step.compile(backend=backend, cache_dir=domain_cache)
        with pytest.raises(sg.LagrangianDomainError) as info:
            sim.simulate(START, 400, PARAMS)
        runs.append(info.value)
    assert runs[0].step == runs[1].step
    np.testing.assert_array_equal(runs[0].trajectory.states, runs[1].trajectory.states)


def test_a_step_from_python_is_refused_too(log_sim):
    traj = log_sim.simulate(START, CROSSING, PARAMS)
    state = traj.states[-1]
    with pytest.raises(sg.LagrangianDomainError):
        log_sim.step(state, PARAMS)


def test_a_batch_stops_the_run_that_leaves_and_finishes_the_others(log_sim):
    starts = np.array([[1.0, 0.95], [1.0, 1.0]])  # the second starts at rest: it also falls
    batch = log_sim.simulate_batch(starts, 10, PARAMS)
    assert batch.ok.all()
    batch = log_sim.simulate_batch(np.array([[1.0, 0.95], [3.0, 3.0]]), 40, PARAMS)
    assert int(batch.status[0]) == int(sg.Status.OUTSIDE_DOMAIN)
    assert int(batch.failed_step[0]) == CROSSING
    assert int(batch.status[1]) == int(sg.Status.OK)


def test_an_initial_state_outside_the_domain_is_refused_at_its_first_step(log_sim):
    with pytest.raises(sg.LagrangianDomainError) as info:
        log_sim.simulate({"x": (-1.0, -1.01)}, 5, PARAMS)
    assert info.value.step == 0
    assert "initial state" in str(info.value)
    assert any("known arrow" in k for k in info.value.kinds)


def test_inside_the_domain_nothing_changes(log_sim):
    # pushed away from 0 (the same L, started moving outward): no step is refused
    traj = log_sim.simulate({"x": (1.0, 1.05)}, 200, PARAMS)
    assert np.isfinite(traj.states).all() and len(traj.states) == 201


@pytest.mark.parametrize("potential, word", [
    (lambda x: sp.sqrt(x), "power 1/2 needs a base >= 0"),
    (lambda x: sp.acos(x / 4), "acos needs an argument in [-1, 1]"),
    (lambda x: x ** sp.Rational(3, 2), "power 3/2"),
    (lambda x: x ** -0.5, "needs a base > 0"),
    (lambda x: sp.atanh(x / 4), "atanh needs a finite value"),  # an opaque SymPy function
])
def test_kinds_of_other_partial_functions(potential, word):
    step = _system(potential, "partial").discretize(h, "midpoint").euler_lagrange()
    assert step.domain_kinds and all(word in k for k in step.domain_kinds)


@pytest.mark.parametrize("potential", [
    lambda x: -x ** 2 / 2,
    lambda x: -x ** 2.0 / 2,  # a Float exponent that is an integer: pow(x, 2.0) is total
    lambda x: sp.asinh(x),  # an opaque function SymPy knows to be real everywhere
    lambda x: -sp.sqrt(h) * x ** 2,  # a square root of a parameter alone: not per step
])
@pytest.mark.parametrize("backend", ["c", "numpy"])
def test_a_lagrangian_defined_everywhere_has_no_domain_values(potential, backend, tmp_path):
    step = _system(potential, "everywhere").discretize(h, "midpoint").euler_lagrange()
    assert step.domain_kinds == [] and step.program.outputs["domain"] == []
    sim = step.compile(backend=backend, cache_dir=tmp_path)
    assert sim.kernel.domain([0.5], [1.0, 0.99], [0.01]).shape == (0,)


def test_an_overflowing_jacobian_is_not_blamed_on_the_domain(log_sim):
    # a guess outside the domain where the Jacobian overflows at a finite residual: Newton
    # solved nothing, so this is the non-finite failure, not a solution outside the domain
    state = np.array([3e-160, 1e-160])
    with pytest.raises(sg.NewtonDivergenceError) as info:
        log_sim.solve(state, PARAMS, guess=[-3e-160])
    assert not isinstance(info.value, sg.LagrangianDomainError)
    assert "non-finite" in str(info.value)


def test_an_unpickled_simulator_reports_the_domain(log_step, tmp_path):
    import pickle

    sim = pickle.loads(pickle.dumps(log_step.compile(cache_dir=tmp_path)))
    with pytest.raises(sg.LagrangianDomainError) as info:
        sim.simulate(START, 400, PARAMS)
    assert info.value.step == CROSSING and len(info.value.trajectory.states) == CROSSING + 1
    assert "log(x_{k+1}/2 + x_{k}/2)" in str(info.value)


def test_an_initial_state_outside_is_named_as_such_by_the_trapezoid_rule(tmp_path):
    # log(x_k) belongs to both terms of the trapezoid rule's window: the known arrow's too
    step = _system().discretize(h, "trapezoid").euler_lagrange()
    sim = step.compile(cache_dir=tmp_path)
    with pytest.raises(sg.LagrangianDomainError) as info:
        sim.simulate({"x": (1.0, -0.5)}, 5, PARAMS)
    assert info.value.step == 0 and "initial state" in str(info.value)


def test_the_galerkin_stages_are_checked_too(tmp_path):
    step = _system().discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    assert len(step.domain_kinds) == 4  # two nodes on each of the two terms
    sim = step.compile(cache_dir=tmp_path)
    with pytest.raises(sg.LagrangianDomainError):
        sim.simulate(START, 400, PARAMS)


def test_a_boundary_value_solution_outside_the_domain_is_refused(log_step):
    # the path from x = 1 to x = −1 solves the equations (which hold 1/x) through x = 0,
    # where L is not defined: it was returned with cost nan
    with pytest.raises(sg.LagrangianDomainError) as info:
        sg.solve_boundary_value(log_step, [1.0], [-1.0], 50, params=PARAMS)
    assert "not defined" in str(info.value)
    sol = sg.solve_boundary_value(log_step, [1.0], [0.5], 50, params=PARAMS)
    assert np.isfinite(sol.cost) and sol.arrows.min() > 0
