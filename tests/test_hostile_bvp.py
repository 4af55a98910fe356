"""Hostile input at ``solve_boundary_value`` and ``sweep_boundary_value``.

Systems: the oscillator (pair groupoid of R), the diagonal particle (one constraint), a
second-order discrete spline, and the free rigid body on SO(3) (group elements as
boundary data, the Cayley chart's cut locus).  Each example makes one argument malformed:
the system (not a system), the boundary configurations (wrong shape, NaN, strings, complex,
matrices off the group, reflections, half-turns), the number of steps, the guess (arrows of
the wrong shape or dtype, not composable, with NaN; a tuple of arrows; multipliers of the
wrong shape), the parameters, the tolerances and iteration cap, ``progress``; and for the
sweep the tables of ends, ``combine``, ``continuation``, ``reduce`` and unknown options.

The invariant (tests/_hostile.py): a clear SymgroupoidError, or a solution that is one: its
configurations start and end at the boundary data and it is a critical point of the
discrete action (``verify_stationary``, independent of the solver's equations).  The window
kernels are evaluated with NumPy here (``SYMGROUPOID_BACKEND=numpy``): the inputs reach them
only after the checks this suite exercises.

The defects this suite found in runtime/_bvp.py are fixed; the tests at the end of this file
reproduce each of them.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from _hostile import (
    PROFILES,
    H,
    K,
    diagonal,
    judge,
    junk,
    near,
    oscillator,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from _hostile_cases import counts, runnable
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg


@pytest.fixture(autouse=True)
def numpy_windows(monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")


def rigid_body() -> sg.DiscreteSystem:
    """L = −tr(J_d W)/h on SO(3), J_d = diag(1, 2, 3)/2·… (a free rigid body)."""
    inertia = sp.diag(1, 2, 3)
    Jd = inertia.trace() / 2 * sp.eye(3) - inertia
    return sg.DiscreteSystem(sg.SO3("W"), lambda a: -(Jd * a.matrix).trace() / H,
                             parameters=[H], name="free_body")


def spline() -> sg.SecondOrderSystem:
    """L = (q₂ − 2q₁ + q₀)²/(2h³) on the pair groupoid of R: a discrete cubic spline, a
    second-order problem fixing two configurations at each end."""
    return sg.SecondOrderSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a, b: (b.target[0] - 2 * a.target[0] + a.source[0]) ** 2 / (2 * H ** 3),
        parameters=[H], name="spline")


def rotation(axis, angle: float) -> np.ndarray:
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@functools.cache
def problem(name: str) -> dict:
    """A valid problem: system, start, end, steps, params."""
    if name == "oscillator":
        return dict(system=oscillator(), start=0.0, end=1.0, params={"h": 0.1, "k": 1.0})
    if name == "diagonal":
        return dict(system=diagonal(), start=(0.0, 0.0), end=(1.0, 1.0),
                    params={"h": 0.1, "k": 1.0})
    if name == "spline":
        return dict(system=spline(), start=(0.0, 0.01), end=(0.5, 0.52), params={"h": 0.1})
    return dict(system=rigid_body(), start=np.eye(3), end=rotation((1, 2, 3), 0.8),
                params={"h": 0.1})


PROBLEMS = ["oscillator", "diagonal", "spline", "free_body"]

#: boundary data a hostile user gives an SO(3) problem
ODD_ROTATIONS = [np.diag([1.0, 1.0, -1.0]), 2 * np.eye(3), np.zeros((3, 3)),
                 rotation((0, 0, 1), np.pi), rotation((1, 2, 3), np.pi), np.eye(3)[:2],
                 np.eye(4), rotation((1, 0, 0), 1.0) + 1e-6, np.eye(3).tolist(), [[1, 0, 0]],
                 np.eye(3, dtype=complex), np.full((3, 3), np.nan)]


@functools.cache
def valid_solution(name: str):
    p = problem(name)
    steps = 6
    return sg.solve_boundary_value(p["system"].euler_lagrange(), p["start"], p["end"], steps,
                                   params=p["params"])


class AsGiven:
    """The parts of a configuration as given (``Groupoid.configuration`` says what the parts
    are; the solve has checked them already)."""

    def point(self, value, dim: int, name: str) -> tuple:
        return tuple(float(v) for v in np.asarray(value, float).reshape(dim))

    def group_element(self, group, value, name: str) -> np.ndarray:
        return np.asarray(value, float)

    def time(self, value, name: str) -> float:
        return float(value)

    def pieces(self, value, count: int, name: str, what: str) -> tuple:
        assert len(value) == count, (name, what)
        return tuple(value)

    def no_configuration_space(self, groupoid, name: str):
        raise AssertionError(f"{groupoid.name} has no configuration space")


def end_points_ok(name: str, solution, start, end) -> None:
    """The solution's configurations run from ``start`` to ``end`` (read as given)."""
    system = problem(name)["system"]
    G = system.groupoid
    configs = solution.configurations
    slots = system.functions.slots
    if slots and len(slots) == 2:
        given = [G.configuration(c, "c", AsGiven()) for c in (*start, *end)]
        got = [configs[0], configs[1], configs[-2], configs[-1]]
    else:
        given = [G.configuration(start, "start", AsGiven()), G.configuration(end, "end", AsGiven())]
        got = [configs[0], configs[-1]]
    for want, have in zip(given, got):
        assert np.allclose(np.asarray(have, float), np.asarray(want, float), atol=1e-8), \
            (have, want)


def check_solution(name: str, start, end, tol=1e-10):
    """A solution's end points, and (unless the caller loosened ``tol``, the absolute
    residual it accepts) that it is a critical point of the discrete action."""
    def verify(solution):
        assert isinstance(solution, sg.BoundaryValueSolution)
        assert np.isfinite(solution.arrows).all() and np.isfinite(solution.multipliers).all()
        assert np.isfinite(solution.residual_norm)
        end_points_ok(name, solution, start, end)
        if float(tol) > 1e-8:
            return
        try:
            report = sg.verify_stationary(solution, problem(name)["system"])
        except sg.ShapeError as err:  # the action overflows: it cannot be evaluated there
            assert "not finite" in str(err), err
            return
        assert report, f"{name}: the solution is not a critical point of the action: {report}"
    return verify


@st.composite
def bvp_calls(draw, name: str):
    """(args, kwargs, names): a solve_boundary_value call with one argument malformed."""
    p = problem(name)
    system = p["system"]
    step = system.euler_lagrange()
    args = {"step": step, "start": p["start"], "end": p["end"], "steps": 6}
    kwargs = {"guess": None, "params": p["params"], "tol": 1e-10, "tol_step": 1e-9,
              "max_iterations": 30}
    which = draw(st.sampled_from(["step", "start", "end", "steps", "guess", "params", "tol",
                                  "tol_step", "max_iterations", "progress", "none"]))
    names = [which]
    if which == "step":
        args["step"] = draw(st.one_of(junk(), st.sampled_from([system, sg.SO3("R")])))
        names = ["step", "step_equations", "system"]
    elif which in ("start", "end"):
        valid = p[which]
        if name == "free_body":
            value = draw(st.one_of(st.sampled_from(ODD_ROTATIONS), near(valid), junk()))
        elif name == "spline":
            value = draw(st.one_of(near(valid), st.tuples(near(valid[0]), st.just(valid[1])),
                                   junk()))
        else:
            value = draw(st.one_of(near(valid), junk()))
        args[which] = value
        names = [which, f"{which}[0]", f"{which}[1]"]
    elif which == "steps":
        args["steps"] = runnable(draw(counts), memory_checked=False)
    elif which == "guess":
        arrows = valid_solution(name).arrows
        lam = valid_solution(name).multipliers
        kind = draw(st.sampled_from(["arrows", "pair", "multipliers", "junk"]))
        if kind == "arrows":
            kwargs["guess"] = draw(near(arrows))
        elif kind == "pair":
            kwargs["guess"] = (draw(near(arrows)), lam)
        elif kind == "multipliers":
            kwargs["guess"] = (arrows, draw(st.one_of(near(lam), junk())))
        else:
            kwargs["guess"] = draw(junk())
        names = ["guess", "multiplier", "multipliers", "composable", "guess[0]"]
    elif which == "params":
        kwargs["params"] = draw(st.one_of(junk(), st.fixed_dictionaries(
            {k: st.one_of(scalars, st.floats(-1, 1)) for k in p["params"]})))
        names = ["params", "parameter", "parameters", *p["params"]]
    elif which in ("tol", "tol_step"):
        kwargs[which] = draw(st.one_of(scalars, st.floats(0, 1e-3)))
    elif which == "max_iterations":
        kwargs["max_iterations"] = draw(st.one_of(counts, st.integers(0, 40)))
        if isinstance(kwargs["max_iterations"], int) and kwargs["max_iterations"] > 100:
            kwargs["max_iterations"] = 40
    elif which == "progress":
        kwargs["progress"] = draw(scalars)
    return args, kwargs, names


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", PROBLEMS)
def test_solve_boundary_value(name, run):
    system = problem(name)["system"]

    @profile(run, 3 if name == "free_body" else 5, 120)
    @given(call=bvp_calls(name))
    def prop(call):
        args, kwargs, names = call
        judge("solve_boundary_value",
              lambda: sg.solve_boundary_value(args["step"], args["start"], args["end"],
                                              args["steps"], **kwargs),
              names, owner=system.name, verify=check_solution(name, args["start"],
                                                              args["end"], kwargs["tol"]))

    prop()


# --- sweeps of boundary values ------------------------------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", ["oscillator", "free_body"])
def test_sweep_boundary_value(name, run):
    p = problem(name)
    system = p["system"]
    step = system.euler_lagrange()

    @profile(run, 4)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["step", "starts", "ends", "combine", "continuation",
                                           "reduce", "options", "guess", "workers", "none"]))
        args = {"step": step, "starts": [p["start"]], "ends": [p["end"], p["end"]],
                "steps": 6}
        kwargs = {"params": p["params"], "combine": "zip", "continuation": False,
                  "reduce": None, "workers": 1}
        names = [which]
        if which == "step":
            args["step"] = data.draw(junk())
        elif which in ("starts", "ends"):
            odd = ODD_ROTATIONS if name == "free_body" else [np.nan, "a", [1.0, 2.0], 1j]
            args[which] = data.draw(st.one_of(junk(), st.lists(st.sampled_from(
                [p["start"], *odd]), max_size=3)))
            names = [which, "start", "end", "boundary-value run"]
        elif which == "combine":
            kwargs["combine"] = data.draw(st.one_of(scalars, st.sampled_from(["product"])))
            names = ["combine", "zip"]
        elif which == "continuation":
            kwargs["continuation"] = data.draw(st.one_of(scalars, st.booleans()))
        elif which == "reduce":
            kwargs["reduce"] = data.draw(st.one_of(junk(), st.just(lambda s: s.residual_norm)))
        elif which == "options":
            key = data.draw(st.sampled_from(["tol", "max_iterations", "foo", "guesses"]))
            kwargs[key] = data.draw(st.one_of(scalars, st.integers(0, 30)))
            names = [key, "option", "options"]
        elif which == "guess":
            kwargs["guess"] = data.draw(junk())
            names = ["guess", "boundary-value run"]
        elif which == "workers":
            value = data.draw(st.one_of(scalars, st.integers(-2, 1)))
            kwargs["workers"] = 1 if isinstance(value, int) and value > 1 else value

        def verify(result):
            assert isinstance(result, sg.SweepResult)
            starts, ends = result.initial
            for r in range(min(len(result), 2)):
                if result.status.reshape(-1)[r] != 0:
                    continue
                i = r if len(starts) > 1 else 0
                j = r if len(ends) > 1 else 0
                if kwargs["reduce"] is None:
                    solution = result.solutions.reshape(-1)[r]
                    check_solution(name, starts[i], ends[j],
                                   kwargs.get("tol", 1e-10))(solution)

        judge("sweep_boundary_value",
              lambda: sg.sweep_boundary_value(args["step"], args["starts"], args["ends"],
                                              args["steps"], **kwargs),
              names, owner=system.name, verify=verify)

    prop()


# --- forced systems: inputs (docs/conventions.md §20) -------------------------------------------

C_DAMP, U_IN = sp.Symbol("c", positive=True), sp.Symbol("u", real=True)
FORCED_PARAMS = {"h": 0.1, "k": 1.0, "c": 0.5}
FORCED_STEPS = 6


@functools.cache
def driven_oscillator() -> sg.DiscreteSystem:
    """The oscillator with the midpoint forces (h/2)·(−c·v + u): damping and a drive u."""
    def L(g):
        (q0,), (q1,) = g.source, g.target
        return H * (((q1 - q0) / H) ** 2 / 2 - K * ((q0 + q1) / 2) ** 2 / 2)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L,
                             parameters=[H, K, C_DAMP],
                             forces=sg.midpoint_forces(lambda q, v: [-C_DAMP * v[0] + U_IN], H),
                             inputs=[U_IN], name="driven_oscillator")


def forced_residuals(q: np.ndarray, u: np.ndarray, p: dict) -> tuple[np.ndarray, float]:
    """The forced DEL of the driven oscillator written by hand (Marsden–West (3.2.3)),
    D₂L(q_{j−1}, q_j) + D₁L(q_j, q_{j+1}) + f⁺(q_{j−1}, q_j) + f⁻(q_j, q_{j+1}), at every
    interior node, and the size of its terms, both divided by s = max(1, |q|, |u|): the DEL
    is linear in (q, u), so it is evaluated at (q/s, u/s), which does not overflow where the
    solution lies near the largest doubles (a start of 1e308: q₀ + 2q₁ + q₂ overflowed here
    while the solver's midpoint terms do not)."""
    h, k, c = p["h"], p["k"], p["c"]
    s = max(1.0, float(np.abs(q).max()), float(np.abs(u).max(initial=0.0)))
    q, u = q / s, u / s
    d = np.diff(q) / h
    force = h / 2 * (-c * d + u)
    r = d[:-1] - d[1:] - h * k * (q[:-2] + 2 * q[1:-1] + q[2:]) / 4 + force[:-1] + force[1:]
    size = max(1.0, float(np.abs(d).max()) * max(1.0, h * c),
               h * k * float(np.abs(q).max()), h * float(np.abs(u).max(initial=0.0)))
    return r, size


def check_forced_solution(start, end, inputs, params):
    def verify(solution):
        assert isinstance(solution, sg.BoundaryValueSolution) and solution.forced
        q = np.array(solution.configurations, float).ravel()
        assert np.isfinite(q).all()
        assert q[0] == pytest.approx(float(np.ravel(start)[0]), abs=1e-8)
        assert q[-1] == pytest.approx(float(np.ravel(end)[0]), abs=1e-8)
        u = np.broadcast_to(np.asarray(inputs, float).reshape(-1), (FORCED_STEPS,))
        r, size = forced_residuals(q, u, params)
        assert np.abs(r).max() <= 1e-10 * float(size), (r, size)  # (size may be float16)
    return verify


@pytest.mark.parametrize("run", PROFILES)
def test_solve_boundary_value_of_a_forced_system(run):
    """Hostile inputs (and the other arguments) of a forced system's solve: a clear error, or
    a solution of the forced DEL written by hand."""
    system = driven_oscillator()
    valid = np.linspace(-1.0, 1.0, FORCED_STEPS)[:, None]

    @profile(run, 12, 200)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["inputs", "inputs", "inputs", "start", "end",
                                           "steps", "params", "minimum", "none"]))
        args = {"start": 0.0, "end": 1.0, "steps": FORCED_STEPS}
        kwargs = {"params": dict(FORCED_PARAMS), "inputs": valid, "max_iterations": 30}
        names = [which]
        if which == "inputs":
            kwargs["inputs"] = data.draw(st.one_of(near(valid), near(valid[:, 0]), near([0.3]),
                                                   junk(), st.none()))
            names = ["inputs", "input", "u"]
        elif which in ("start", "end"):
            args[which] = data.draw(st.one_of(near(args[which]), junk()))
            names = [which]
        elif which == "steps":
            args["steps"] = runnable(data.draw(counts), memory_checked=False)
            names = ["steps", "inputs"]
        elif which == "params":
            kwargs["params"] = data.draw(st.fixed_dictionaries(
                {k: st.one_of(scalars, st.floats(-1, 1)) for k in FORCED_PARAMS}))
            names = ["params", "parameter", "parameters", *FORCED_PARAMS]
        elif which == "minimum":
            kwargs["minimum"] = data.draw(st.one_of(st.just(True), scalars))
            names = ["minimum"]
        judge("solve_boundary_value (forced)",
              lambda: sg.solve_boundary_value(system, args["start"], args["end"],
                                              args["steps"], **kwargs),
              names, owner=system.name,
              verify=check_forced_solution(args["start"], args["end"], kwargs["inputs"],
                                           kwargs["params"]))

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_sweep_boundary_value_of_a_forced_system(run):
    """Hostile inputs of a forced system's sweep (one table for all runs or one per run)."""
    system = driven_oscillator()
    valid = np.linspace(-1.0, 1.0, FORCED_STEPS)[:, None]

    @profile(run, 6, 100)
    @given(inputs=st.one_of(near(valid), near(np.stack([valid, valid])), junk(), st.none()))
    def prop(inputs):
        def verify(result):
            assert isinstance(result, sg.SweepResult)
            arr = np.asarray(inputs, float)
            for r in range(2):
                if result.status[r] == 0:
                    table = arr[r] if arr.ndim == 3 else arr
                    check_forced_solution(0.0, [1.0, 0.5][r], table,
                                          FORCED_PARAMS)(result.solutions[r])

        judge("sweep_boundary_value (forced)",
              lambda: sg.sweep_boundary_value(system, [0.0], [1.0, 0.5], FORCED_STEPS,
                                              FORCED_PARAMS, inputs=inputs, workers=1),
              ["inputs", "input", "u"], owner=system.name, verify=verify)

    prop()


# --- known defects in runtime/_bvp.py (fixes described in tests/_hostile.py KNOWN) ------------

def test_known_bvp_system_that_is_not_a_system():
    with pytest.raises(sg.SymgroupoidError, match="step"):
        sg.solve_boundary_value("not a system", 0.0, 1.0, 6, params={"h": 0.1})


def test_known_bvp_guess_given_as_a_tuple_of_arrows():
    p = problem("oscillator")
    arrows = valid_solution("oscillator").arrows
    solution = sg.solve_boundary_value(p["system"].euler_lagrange(), p["start"], p["end"], 6,
                                       guess=tuple(map(tuple, arrows)), params=p["params"])
    assert np.allclose(solution.arrows, arrows)


def test_known_bvp_guess_converted_without_the_one_validation():
    import warnings

    p = problem("oscillator")
    arrows = valid_solution("oscillator").arrows
    step = p["system"].euler_lagrange()
    for bad in (arrows.astype(str), arrows.astype(complex) + 1e-3j, arrows > 0.5,
                [[10**400, 0.0]] * len(arrows)):
        with warnings.catch_warnings():
            warnings.simplefilter("error", np.exceptions.ComplexWarning)
            try:
                sg.solve_boundary_value(step, p["start"], p["end"], 6, guess=bad,
                                        params=p["params"])
            except sg.ShapeError as err:
                assert "guess" in str(err)
                continue
        raise AssertionError(f"a guess of dtype {np.asarray(bad).dtype} was accepted")


def test_known_bvp_second_order_end_given_as_a_scalar_array():
    p = problem("spline")
    with pytest.raises(sg.ShapeError, match="start is not a pair"):
        sg.solve_boundary_value(p["system"].euler_lagrange(), np.zeros(()), p["end"], 6,
                                params=p["params"])


def test_known_bvp_absolute_tolerance_accepts_small_equations():
    """Equations whose terms are all below 1e-10 (h ≈ 10³ in L = (Δ²q)²/2h³) are solved, not
    accepted at the initial path: the default criterion is the rounding floor alone."""
    p = problem("spline")
    solution = sg.solve_boundary_value(p["system"].euler_lagrange(), p["start"], p["end"], 6,
                                       params={"h": 1041.0})
    assert sg.verify_stationary(solution, p["system"]), solution



@pytest.mark.parametrize("tol", [0.011, 1.0, 1e6])
def test_known_bvp_a_relative_tolerance_of_the_terms_themselves_is_refused(tol):
    """(``tol=1`` or more returned the initial path as the solution, which no
    verification passes: the tolerance is relative to each equation's terms.)"""
    p = problem("spline")
    with pytest.raises(sg.ShapeError, match="at most 0.01"):
        sg.solve_boundary_value(p["system"].euler_lagrange(), p["start"], p["end"], 6,
                                params={"h": 1.0}, tol=tol)


def test_a_problem_larger_than_the_memory_is_refused_up_front(monkeypatch):
    """steps=10**9 ended in a raw MemoryError under ``ulimit -v`` (and without one, in the
    kernel's out-of-memory killer); simulate refuses such runs by name, and so does this."""
    p = problem("oscillator")
    monkeypatch.setattr("symgroupoid.runtime._bvp._solve.available_memory", lambda: 10_000)
    with pytest.raises(sg.TrajectoryTooLargeError, match="1000 steps needs at least"):
        sg.solve_boundary_value(p["system"].euler_lagrange(), p["start"], p["end"], 1000,
                                params=p["params"])
    monkeypatch.setattr("symgroupoid.runtime._bvp._solve.available_memory", lambda: None)
    assert sg.solve_boundary_value(p["system"].euler_lagrange(), p["start"], p["end"], 6,
                                   params=p["params"]).iterations >= 1
