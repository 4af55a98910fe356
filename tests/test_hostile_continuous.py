"""Hostile input at the continuous entry points: ``ContinuousSystem`` (Q, L, parameters,
name, holonomic constraints, forces, inputs), ``discretize`` (the step symbol and the
scheme: ``GaussLegendre(s)``, ``LobattoIIIAB(s)`` with s of every kind and size, and their
tables), ``DiscreteSystem(..., stages=...)``, ``Simulator.from_velocity`` and
``convergence_order`` (steps, T, params, initial data, reference).

The invariant (tests/_hostile.py): a valid call, or a named SymgroupoidError subclass whose
message names the argument — never a raw TypeError / KeyError, a hang or a result computed
from a non-finite value.  Each defect this suite found has its own regression test below
(see the comments): they failed before the fixes.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from _hostile import (
    PROFILES,
    judge,
    junk,
    near,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid import (
    CallableError,
    InputTypeError,
    ShapeError,
    SymgroupoidError,
    UnsupportedFeatureError,
)
from symgroupoid.equations import MAX_NODES, gauss_legendre_tableau, lobatto_tableau

h, grav = sp.symbols("h g", positive=True)
u_torque = sp.Symbol("u", real=True)
THETA = sg.EuclideanSpace("theta")
PARAMS = {"g": 9.81}


def lagrangian(q, v):
    return v[0] ** 2 / 2 + grav * sp.cos(q[0])


def pendulum(**kwargs) -> sg.ContinuousSystem:
    return sg.ContinuousSystem(THETA, lagrangian, **{"parameters": [h, grav],
                                                     "name": "pendulum", **kwargs})


@functools.cache
def simulator(scheme_label: str = "gauss2"):
    """The NumPy simulator of the pendulum, GaussLegendre(2) (stages) or midpoint."""
    scheme = sg.GaussLegendre(2) if scheme_label == "gauss2" else "midpoint"
    return pendulum().discretize(h, scheme).euler_lagrange().compile(backend="numpy")


def refused(call, error=SymgroupoidError, match: str | None = None) -> SymgroupoidError:
    """``call`` raises a named SymgroupoidError subclass (not the base class itself)."""
    with pytest.raises(error, match=match) as info:
        call()
    assert type(info.value) is not SymgroupoidError
    return info.value


# --- ContinuousSystem -------------------------------------------------------------------------

@pytest.mark.parametrize("Q", [None, "theta", 3, [], [None], [THETA, "x"], {"a": THETA},
                               sg.PairGroupoid(THETA), [THETA, THETA]])
def test_a_bad_configuration_space_is_refused(Q):
    refused(lambda: sg.ContinuousSystem(Q, lagrangian, [h, grav]).discretize(h, "midpoint")
            .euler_lagrange())


BAD_LAGRANGIANS = {
    "not callable": None, "a string": lambda q, v: "abc", "None": lambda q, v: None,
    "raises": lambda q, v: 1 / 0, "a column": lambda q, v: sp.Matrix([1, 2]),
    "complex": lambda q, v: v[0] ** 2 + sp.I, "nan": lambda q, v: v[0] ** 2 * sp.nan,
    "infinite": lambda q, v: v[0] ** 2 + sp.oo, "undeclared": lambda q, v: sp.Symbol("k"),
    "one argument": lambda q: q[0], "a list": lambda q, v: [v[0] ** 2],
    "out of range": lambda q, v: v[5], "an array": lambda q, v: np.array([1.0]),
    "constant": lambda q, v: 1.5, "degenerate": lambda q, v: q[0],
}


@pytest.mark.parametrize("scheme", ["midpoint", sg.GaussLegendre(2)], ids=["midpoint", "gauss2"])
@pytest.mark.parametrize("kind", list(BAD_LAGRANGIANS))
def test_a_bad_lagrangian_is_refused(kind, scheme):
    L = BAD_LAGRANGIANS[kind]
    refused(lambda: sg.ContinuousSystem(THETA, L, [h, grav], name="bad")
            .discretize(h, scheme).euler_lagrange())


@pytest.mark.parametrize("L, shown", [(lambda q, v: [v[0] ** 2], "returned a list"),
                                      (lambda q, v: sp.Matrix([1, 2]), "returned a 2×1 matrix"),
                                      (lambda q, v: "abc", "returned the string")])
def test_a_lagrangian_that_is_no_scalar_says_what_it_returned(L, shown):
    """(A list was a CallableError quoting SymPy: 'list' object has no attribute
    'xreplace'.)"""
    refused(lambda: sg.ContinuousSystem(THETA, L, [h, grav], name="bad")
            .discretize(h, "midpoint").euler_lagrange(), ShapeError,
            f"the Lagrangian L\\(q, v\\) {shown}")


def test_a_lagrangian_of_the_wrong_arity_is_refused_where_it_is_given():
    """(L(q) was reported twice wrapped, from the derivation, as "raised TypeError: <lambda>()
    takes 1 positional argument", without saying L takes (q, v).)"""
    error = refused(lambda: sg.ContinuousSystem(THETA, lambda q: q[0], [h, grav]),
                    CallableError)
    assert "L(q, v)" in str(error) and "raised" not in str(error)


@pytest.mark.parametrize("parameters", [h, "h", None, {h: 1.0}, [h, "g"], [h, h, grav],
                                        [1, 2], [h, grav, 2 * sp.Symbol("x")], 3.0])
def test_bad_parameters_are_refused(parameters):
    """(``parameters=h``, ``"h"`` and ``None`` raised TypeError / AttributeError; a dict was
    read as the list of its keys.)  A single symbol is read as a list of it, as
    DiscreteSystem reads it: here g is then undeclared."""
    refused(lambda: sg.ContinuousSystem(THETA, lagrangian, parameters)
            .discretize(h, "midpoint").euler_lagrange())


@pytest.mark.parametrize("parameters", [["h", grav], [h, "g"], [h, h], [grav, 1.0]])
def test_parameters_that_are_not_distinct_symbols_are_refused_at_construction(parameters):
    """(A string among the parameters reached ``discretize("h", ...)``, which looked the
    step up by name and raised AttributeError: 'str' object has no attribute
    'is_integer'.)  Refused where they are given, with what to pass instead."""
    error = refused(lambda: sg.ContinuousSystem(THETA, lagrangian, parameters),
                    sg.ParameterDeclarationError, match="parameter")
    if any(isinstance(p, str) for p in parameters):
        assert "not strings" in str(error)


def test_a_single_parameter_symbol_is_a_list_of_it():
    system = sg.ContinuousSystem(THETA, lambda q, v: v[0] ** 2 / 2, h, name="free")
    assert system.parameters == [h]
    assert system.discretize(h, "midpoint").parameters == [h]


@pytest.mark.parametrize("name", [None, 3, "", b"p", ["p"]])
def test_a_bad_name_is_refused(name):
    """(Any object was taken as the name: None became the system ``None_midpoint``.)"""
    refused(lambda: pendulum(name=name), match="name")


@pytest.mark.parametrize("what, value", [("holonomic", "x"), ("holonomic", 3),
                                         ("forces", "f"), ("forces", [1.0])])
def test_constraints_and_forces_must_be_functions(what, value):
    """(A string as ``holonomic`` was reported as 'a function of the arrow' only when a
    Galerkin scheme evaluated it, and as forces inside a nested CallableError.)"""
    error = refused(lambda: pendulum(**{what: value}), CallableError, match=what)
    assert "function of the configuration" in str(error)


@pytest.mark.parametrize("inputs", [3, "u", None, {sp.Symbol("u"): 1}])
def test_bad_inputs_are_refused(inputs):
    """(``inputs=3`` raised TypeError.)"""
    refused(lambda: pendulum(inputs=inputs, forces=lambda q, v: [0]), match="inputs")


@pytest.mark.parametrize("step", [None, 0.1, 1, "x", 2 * grav, [h], sp.Symbol("k")])
def test_a_bad_step_symbol_is_refused(step):
    """A step that is not one of the parameters (by symbol or name) is refused, naming
    the parameters."""
    error = refused(lambda: pendulum().discretize(step, "midpoint"), InputTypeError)
    assert "step" in str(error) and "h, g" in str(error)


def test_the_step_by_name_or_symbol():
    assert pendulum().discretize("h", "midpoint").time_step == h
    assert pendulum().discretize(sp.Symbol("h", positive=True), "midpoint").time_step == h


# --- schemes --------------------------------------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda: sg.GaussLegendre("2"), lambda: sg.GaussLegendre(True), lambda: sg.GaussLegendre(2.5),
    lambda: sg.GaussLegendre(0), lambda: sg.GaussLegendre(-1), lambda: sg.GaussLegendre(None),
    lambda: sg.GaussLegendre(float("nan")), lambda: sg.GaussLegendre([2]),
    lambda: sg.GaussLegendre(1j), lambda: sg.LobattoIIIAB(1), lambda: sg.LobattoIIIAB(True),
    lambda: sg.LobattoIIIAB("3"), lambda: sg.LobattoIIIAB(np.inf),
], ids=["str", "bool", "fraction", "zero", "negative", "None", "nan", "list", "complex",
        "lobatto1", "lobatto-bool", "lobatto-str", "lobatto-inf"])
def test_a_bad_number_of_stages_is_refused(make):
    refused(make, ShapeError, match="stages")


@pytest.mark.parametrize("make", [lambda s: sg.GaussLegendre(s), lambda s: sg.LobattoIIIAB(s),
                                  gauss_legendre_tableau, lobatto_tableau],
                         ids=["GaussLegendre", "LobattoIIIAB", "gauss table", "lobatto table"])
@pytest.mark.parametrize("s", [MAX_NODES + 1, 60, 10**6, 10**9])
def test_a_huge_number_of_stages_is_refused_at_once(make, s):
    """(GaussLegendre(60), GaussLegendre(10**6) and LobattoIIIAB(10**9) were accepted and
    building their tables did not end; s = 12 took a minute.)  At most MAX_NODES = 10
    nodes: order 20, below double precision's rounding at any step Newton converges at."""
    refused(lambda: make(s), ShapeError, match=f"at most {MAX_NODES}")


def test_integral_spellings_of_the_stages_are_accepted():
    assert sg.GaussLegendre(np.int64(2)) == sg.GaussLegendre(2.0) == sg.GaussLegendre(2)
    assert sg.LobattoIIIAB(MAX_NODES).order == 2 * MAX_NODES - 2


@pytest.mark.parametrize("scheme", [None, "Midpoint", "gauss2", 2, sg.GaussLegendre, object(),
                                    ("midpoint",)])
def test_a_bad_scheme_object_is_refused(scheme):
    refused(lambda: pendulum().discretize(h, scheme), InputTypeError, match="scheme")


@pytest.mark.parametrize("run", PROFILES)
def test_schemes_of_any_value(run):
    @profile(run, 40)
    @given(value=st.one_of(scalars, junk(max_leaves=2), st.integers(-5, 12)))
    def prop(value):
        for cls in (sg.GaussLegendre, sg.LobattoIIIAB):
            judge(cls.__name__, lambda cls=cls: cls(value), ["stages"],
                  verify=lambda scheme: _check_scheme(scheme, value))

    prop()


def _check_scheme(scheme, value) -> None:
    lowest = 1 if isinstance(scheme, sg.GaussLegendre) else 2
    assert isinstance(scheme.stages, int) and lowest <= scheme.stages <= MAX_NODES
    assert scheme.stages == value and not isinstance(value, bool)


# --- stages of a DiscreteSystem -------------------------------------------------------------

LINE = sg.PairGroupoid(sg.EuclideanSpace("q"))


def _staged(g, z):
    return (g.target[0] - g.source[0]) ** 2 / (2 * h) + sum(
        (zi - (g.target[0] - g.source[0])) ** 2 for zi in z)


@pytest.mark.parametrize("stages", ["2", True, 2.5, -1, None, float("nan"), [1], 1j,
                                    10**6, 10**9])
def test_bad_stages_are_refused(stages):
    """(stages=10**6 and 10**9 were accepted and the derivation made a symbol per stage
    without end; at most MAX_DIMENSION = 100 000 now, as for a dimension.)"""
    refused(lambda: sg.DiscreteSystem(LINE, _staged, parameters=[h], stages=stages),
            ShapeError, match="stages")


@pytest.mark.parametrize("L", [lambda g: (g.target[0] - g.source[0]) ** 2 / h,
                               lambda g, z: (g.target[0] - g.source[0]) ** 2 / h + z[3] ** 2,
                               lambda g, z: "z"],
                         ids=["no stage argument", "stage out of range", "a string"])
def test_a_lagrangian_that_does_not_fit_its_stages_is_refused(L):
    refused(lambda: sg.DiscreteSystem(LINE, L, parameters=[h], stages=1).euler_lagrange())


def test_stages_spelled_as_integral_numbers_are_accepted():
    for stages in (np.int64(1), 1.0):
        step = sg.DiscreteSystem(LINE, _staged, parameters=[h], stages=stages).euler_lagrange()
        assert len(step.unknowns) == 3  # x, ζ_k, ζ_{k+1}


# --- from_velocity --------------------------------------------------------------------------

@pytest.mark.parametrize("configuration, velocity", [
    ({"theta": 0.3}, [0.5, 0.1]), ({"theta": 0.3}, []), ({"theta": 0.3}, [np.nan]),
    ({"theta": 0.3}, [np.inf]), ({"theta": 0.3}, ["0.5"]), ({"theta": 0.3}, [1j]),
    ({"theta": 0.3}, None), ({"theta": 0.3}, [[0.5]]), ({"theta": np.nan}, [0.5]),
    ({"theta": [0.3, 0.4]}, [0.5]), ({"phi": 0.3}, [0.5]), ({}, [0.5]), (None, [0.5]),
    ("theta", [0.5]), ({"theta": "0.3"}, [0.5]),
])
@pytest.mark.parametrize("label", ["gauss2", "midpoint"])
def test_from_velocity_refuses_bad_data(label, configuration, velocity):
    sim = simulator(label)
    refused(lambda: sim.from_velocity(configuration, velocity, {"h": 0.1, **PARAMS}))


@pytest.mark.parametrize("params", [None, {"h": 0.1}, {"h": np.nan, "g": 9.81},
                                    {"h": -0.1, "g": 9.81}, {"h": 0.1, "g": 9.81, "x": 1.0}])
def test_from_velocity_refuses_bad_parameters(params):
    refused(lambda: simulator().from_velocity({"theta": 0.3}, [0.5], params))


def test_from_velocity_needs_a_continuous_origin():
    system = sg.DiscreteSystem(LINE, lambda g: (g.target[0] - g.source[0]) ** 2 / (2 * h),
                               parameters=[h], name="line")
    sim = system.euler_lagrange().compile(backend="numpy")
    refused(lambda: sim.from_velocity({"q": 0.0}, [1.0], {"h": 0.1}), UnsupportedFeatureError)


@functools.cache
def _free_body(label: str):
    scheme = sg.GaussLegendre(2) if label == "gauss2" else "midpoint"
    system = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * xi)[0, 0] / 2,
                                 parameters=[h], name="free_body")
    return system.discretize(h, scheme).euler_lagrange().compile(backend="numpy")


@pytest.mark.parametrize("label", ["gauss2", "midpoint"])
def test_from_velocity_names_a_configuration_outside_the_group(label):
    """(A matrix of ones as R₀ was reported as "non-finite values solving for the initial
    state" by GaussLegendre(2) and as a singular Jacobian by the midpoint rule: named now,
    before any solve, as a state's group part is; one given to a few digits is rounded to
    the group with a warning.)"""
    sim = _free_body(label)
    for bad in (np.ones((3, 3)), np.diag([1.0, 1.0, -1.0]), np.full((3, 3), np.nan)):
        error = refused(functools.partial(sim.from_velocity, {"R": bad}, [0.1, 0.2, 0.3],
                                          {"h": 0.01}))
        assert "configuration part 'R'" in str(error)
    close = np.round(np.array([[0.6, -0.8, 0.0], [0.8, 0.6, 0.0], [0.0, 0.0, 1.0]]) * (1 + 1e-8),
                     12)
    with pytest.warns(sg.GroupRoundingWarning):
        state = sim.from_velocity({"R": close}, [0.1, 0.2, 0.3], {"h": 0.01})
    assert np.all(np.isfinite(state))


@pytest.mark.parametrize("psi", [lambda q: "x", lambda q: [q[0] - sp.Symbol("ell")],
                                 lambda q: [1.0]], ids=["string", "undeclared", "constant"])
def test_a_bad_holonomic_constraint_is_named_as_such(psi):
    """(A constraint function returning the string "x" was reported as "the Lagrangian uses
    symbol(s) x" by the Lobatto scheme, whose discrete Lagrangian holds the constraints at
    its interior nodes.)"""
    system = sg.ContinuousSystem(sg.EuclideanSpace("a b"),
                                 lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2, parameters=[h],
                                 holonomic=psi)
    error = refused(lambda: system.discretize(h, sg.LobattoIIIAB(3)))
    assert "holonomic" in str(error) and "Lagrangian" not in str(error), error


def _check_state(state) -> None:
    sim = simulator()
    state = np.asarray(state, float)
    assert state.shape == (len(sim.equations.knowns),) and np.all(np.isfinite(state))


@pytest.mark.parametrize("run", PROFILES)
def test_from_velocity_with_values_near_valid_ones(run):
    @profile(run, 30)
    @given(data=st.data())
    def prop(data):
        configuration = data.draw(st.one_of(
            st.builds(lambda v: {"theta": v}, st.one_of(near(0.3), scalars)), junk(3)))
        velocity = data.draw(st.one_of(near([0.5]), junk(3)))
        judge("Simulator.from_velocity",
              lambda: simulator().from_velocity(configuration, velocity,
                                                {"h": 0.1, **PARAMS}),
              ["configuration", "velocity", "theta", "momentum"], owner="pendulum_gauss2",
              verify=_check_state)

    prop()


# --- convergence_order ----------------------------------------------------------------------

INITIAL = ({"theta": 0.3}, [0.5])


def order(**kwargs):
    arguments = dict(system=pendulum(), scheme="midpoint", initial=INITIAL, params=PARAMS,
                     T=1.0, steps=[10, 20], backend="numpy")
    arguments.update(kwargs)
    return sg.convergence_order(**arguments)


@pytest.mark.parametrize("steps", [10, None, "10 20", [10], [10, 10], [], [10, 0], [10, -20],
                                   [10, 2.5], [10, "20"], [10, None], [10, True],
                                   [10, float("nan")], {10: 1, 20: 2}, [10, 10**12]])
def test_bad_step_counts_are_refused_before_any_derivation(steps, monkeypatch):
    """(``steps=10`` and ``None`` raised TypeError; ``[10, 10**12]`` was accepted, and its
    reference run of 8·10¹² steps would have allocated a trajectory of that length.)"""
    monkeypatch.setattr(sg.ContinuousSystem, "discretize", _no_derivation)
    refused(lambda: order(steps=steps), match="step")


@pytest.mark.parametrize("forced, inputs, error, match", [
    (True, None, ShapeError, "pass inputs="),  # (a forced system could not be measured)
    (True, [0.1, 0.2], ShapeError, "held over every arrow"),
    (True, np.zeros((20, 1)), ShapeError, "held over every arrow"),
    (True, [float("nan")], sg.DomainError, "finite"),
    (True, ["a"], ShapeError, "inputs"),
    (False, [0.1], ShapeError, "has no inputs"),
])
def test_bad_held_inputs_are_refused(forced, inputs, error, match):
    """``inputs=``: the m values a system's inputs hold over every arrow of every run."""
    system = pendulum(forces=lambda q, v: [u_torque], inputs=[u_torque]) if forced else None
    refused(lambda: order(**({"system": system} if forced else {}), inputs=inputs), error,
            match=match)


@pytest.mark.parametrize("T", [None, "1.0", "abc", 0.0, -1.0, float("nan"), float("inf"),
                               True, [1.0], 1j, np.array([1.0, 2.0])])
def test_a_bad_final_time_is_refused_before_any_derivation(T, monkeypatch):
    """(``T="abc"`` raised ValueError, ``T=None`` and ``T=[1.0]`` TypeError, ``T=True``
    was read as 1.)"""
    monkeypatch.setattr(sg.ContinuousSystem, "discretize", _no_derivation)
    refused(lambda: order(T=T), ShapeError, match="T")


@pytest.mark.parametrize("kwargs, match", [
    (dict(params=None), "params"), (dict(params=[9.81]), "params"),
    (dict(initial=None), "initial"), (dict(initial=({"theta": 0.3},)), "initial"),
    (dict(initial="theta"), "initial"), (dict(initial={"theta": 0.3}), "initial"),
    (dict(reference=[0.1, 0.2]), "reference"), (dict(reference=[]), "reference"),
    (dict(reference=[np.nan]), "reference"), (dict(reference=["0.1"]), "reference"),
    (dict(reference=[1j]), "reference"), (dict(reference="0.1"), "reference"),
    (dict(reference={"theta": 0.1}), "reference"), (dict(system=None), "system"),
    (dict(system=simulator), "system"),
])
def test_bad_data_is_refused_before_any_derivation(kwargs, match, monkeypatch):
    """(``params=None`` and ``initial=None`` raised TypeError after the derivation; a
    reference with NaN gave NaN errors and an order of NaN; a reference of the wrong size
    was noticed only after every run.)"""
    monkeypatch.setattr(sg.ContinuousSystem, "discretize", _no_derivation)
    refused(lambda: order(**kwargs), match=match)


def _no_derivation(*args, **kwargs):
    raise AssertionError("derived before checking the arguments")


def test_a_group_reference_is_its_matrix_entries():
    """The reference size on SO(3) is the 9 entries of R(T); 3 (the dimension) is refused
    before the derivation."""
    body = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * xi)[0, 0] / 2,
                               parameters=[h], name="sphere")
    with pytest.raises(ShapeError, match="the reference has 3 entries, the configuration 9"):
        sg.convergence_order(body, "midpoint", ({"R": np.eye(3)}, [0.1, 0.2, 0.3]), {}, 1.0,
                             [10, 20], reference=[0.0, 0.0, 0.0])


def test_measure_order_needs_a_discretised_continuous_system():
    system = sg.DiscreteSystem(LINE, lambda g: (g.target[0] - g.source[0]) ** 2 / (2 * h),
                               parameters=[h], name="line")
    sim = system.euler_lagrange().compile(backend="numpy")
    refused(lambda: sg.convergence.measure_order(sim, ({"q": 0.0}, [1.0]), {}, 1.0, [10, 20]),
            UnsupportedFeatureError)


def test_long_runs_are_simulated_in_chunks(monkeypatch):
    """Runs longer than a chunk continue from the last state: the final configuration of
    a run in chunks of 7 steps is the one-run configuration (to rounding, Newton restarts
    from the chunk's prediction), and no trajectory longer than a chunk is kept; how far
    the run goes from its first configuration is measured over every chunk."""
    from symgroupoid import convergence

    sim = simulator()
    params = {"h": 0.01, **PARAMS}
    whole, motion = convergence._run(sim, INITIAL, params, 50)
    lengths = []
    original = type(sim).simulate

    def spy(self, state, n, *args, **kwargs):
        lengths.append(n)
        return original(self, state, n, *args, **kwargs)

    monkeypatch.setattr(convergence, "CHUNK", 7)
    monkeypatch.setattr(type(sim), "simulate", spy)
    chunked, chunked_motion = convergence._run(sim, INITIAL, params, 50)
    assert lengths == [7] * 7 + [1]
    assert np.abs(chunked - whole).max() < 1e-13
    assert motion > 0.1 and abs(chunked_motion - motion) < 1e-13


@pytest.mark.parametrize("run", PROFILES)
def test_convergence_order_arguments_of_any_value(run, monkeypatch):
    """Any steps, T, params, initial data or reference: a valid measurement or a named
    error; the arguments are checked before the derivation (which is stubbed here, so a
    call that passes the checks ends at it)."""
    monkeypatch.setattr(sg.ContinuousSystem, "discretize", _Derived.stub)

    @profile(run, 40)
    @given(data=st.data())
    def prop(data):
        kind = data.draw(st.sampled_from(["steps", "T", "params", "initial", "reference"]))
        value = data.draw(st.one_of(junk(3), near([10.0, 20.0]) if kind == "steps"
                                    else near([0.1])))
        judge("convergence_order", lambda: _ordered(**{kind: value}),
              ["steps", "T", "params", "initial", "reference"],
              verify=lambda result: None)

    prop()


class _Derived(Exception):
    """The stub derivation's signal: the arguments passed every check."""

    @staticmethod
    def stub(*args, **kwargs):
        raise _Derived


def _ordered(**kwargs):
    try:
        return order(**kwargs)
    except _Derived:
        return "derived"


def test_a_force_that_is_not_real_is_refused_at_once_on_a_group():
    """A body torque i·ξ₁ on SO(3) with GaussLegendre(2) sat in ``sympy.expand`` of the
    force at the Galerkin nodes (rational functions of the stages) for minutes; F is now
    checked once on generic symbols, named by them."""
    body = sg.ContinuousSystem(sg.SO3("R"), lambda R, w: (w.T * sp.diag(1, 2, 3) * w)[0, 0] / 2,
                               parameters=[h], forces=lambda R, w: [sp.I * w[0], 0, 0],
                               name="complex_torque")
    with pytest.raises(sg.InvalidExpressionError,
                       match=r"F\(q, v\) \(entry 0\) contains I .* in the term I\*v0_0"):
        body.discretize(h, sg.GaussLegendre(2))
