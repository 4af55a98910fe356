"""Hostile input at the symbolic entry points: groupoid constructors (EuclideanSpace,
PairGroupoid, the matrix groups, ActionGroupoid, ProductGroupoid, TimeGroupoid,
DefinedGroupoid), ``check_axioms``, and DiscreteSystem / SecondOrderSystem /
NonholonomicSystem construction with ``euler_lagrange``.

Malformed input: objects of the wrong kind, names that are not strings, structure maps that
raise, return the wrong number of coordinates, strings, NaN, infinities or complex values,
or violate an axiom (a left action given as a right one); Lagrangians and constraints that
return the wrong type or shape, non-finite, complex or out-of-range constants, undefined
functions, unevaluated derivatives and integrals, undeclared or mis-declared symbols, have
the wrong arity, raise, or are degenerate.  The invariant (tests/_hostile.py): a groupoid
that passes ``check_axioms``, a system whose simulated steps are stationary points of its
own action (``verify_stationary``, independent of the derived equations) — or a
SymgroupoidError naming the argument, the map or the function.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from _hostile import (
    PROFILES,
    H,
    judge,
    junk,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
    verify_trajectory,
)
from _hostile_cases import runnable
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg

# --- groupoid constructors ----------------------------------------------------------------------

names = st.one_of(st.text(max_size=6), st.lists(st.text(max_size=4), max_size=3), junk(),
                  st.sampled_from(["x y", "x, y", "x x", "lambda", "λ", "", " ", "a\0b",
                                   ["q"], ["q", "q"], ("a", "b"), [1, 2], ["x", None]]))


def verify_groupoid(G) -> None:
    """A constructed groupoid satisfies the axioms (another seed than its own check)."""
    assert isinstance(G, sg.Groupoid), G
    sg.check_axioms(G, samples=1, seed=7)


def verify_space(space) -> None:
    assert isinstance(space, sg.EuclideanSpace)
    assert all(isinstance(n, str) and n for n in space.names)
    assert len(set(space.names)) == len(space.names) >= 1
    if len(space.names) <= 20:  # an accepted dimension of 10⁵ is valid, but not checked here
        verify_groupoid(sg.PairGroupoid(space))


@pytest.mark.parametrize("run", PROFILES)
def test_spaces_and_built_in_groupoids(run):
    @profile(run, 20)
    @given(data=st.data())
    def prop(data):
        kind = data.draw(st.sampled_from(["space", "vector", "pair", "group", "group maps",
                                          "time", "product", "multiply"]))
        if kind == "space":
            value = data.draw(names)
            judge("EuclideanSpace", lambda: sg.EuclideanSpace(value),
                  ["EuclideanSpace", "coordinate", "names"], verify=verify_space)
        elif kind == "vector":
            name, dim = data.draw(st.one_of(names, st.just("G"))), data.draw(
                st.one_of(scalars, st.integers(-3, 4)))
            judge("EuclideanSpace", lambda: sg.EuclideanSpace.vector(name, dim),
                  ["dim", "name", "EuclideanSpace"], verify=verify_space)
        elif kind == "pair":
            space = data.draw(st.one_of(junk(), st.sampled_from(
                [sg.SO2("R"), sg.PairGroupoid(sg.EuclideanSpace("x")), sg.SO2("g") * sg.SO2("h"),
                 sg.EuclideanSpace("x y")])))
            judge("PairGroupoid", lambda: sg.PairGroupoid(space),
                  ["PairGroupoid", "manifold"], verify=verify_groupoid)
        elif kind == "group":
            cls = data.draw(st.sampled_from([sg.SO2, sg.SO3, sg.SE2, sg.SE3]))
            name = data.draw(st.one_of(names, st.just("W")))
            retraction = data.draw(st.one_of(st.sampled_from(["cayley", "exp", "Cayley"]),
                                             scalars))
            judge("matrix Lie group", lambda: cls(name, retraction=retraction),
                  ["name", "retraction"], verify=lambda G: isinstance(G, sg.MatrixLieGroup))
        elif kind == "group maps":
            G = data.draw(st.sampled_from([sg.SO2("R"), sg.SO3("R"), sg.SE2("g", "exp"),
                                           sg.SE3("g")]))
            coords = st.one_of(junk(), st.lists(st.floats(-2, 2), min_size=1, max_size=13),
                               *[st.lists(st.floats(-2, 2), min_size=k, max_size=k)
                                 for k in (G.rank, G.arrow_dim)])
            q, x = data.draw(coords), data.draw(coords)
            method = data.draw(st.sampled_from(["translated_retraction",
                                                "increment_coordinates", "numeric_tau"]))
            args = (x,) if method == "numeric_tau" else (q, x)

            def check(result):
                assert len(np.ravel(np.asarray(result, dtype=object))) in (
                    G.n * G.n, G.arrow_dim, G.rank)

            judge(f"MatrixLieGroup.{method}", lambda: getattr(G, method)(*args),
                  ["coordinates", "expression", "finite real", "sequence"], verify=check)
            # a refused call leaves the maps of the class intact
            rng = np.random.default_rng(0)
            y = rng.uniform(-0.5, 0.5, G.rank)
            M = G.numeric_tau(y)
            assert np.allclose(G.increment_coordinates(G.entries(sp.eye(G.n)),
                                                       [M[i, j] for i, j in G._free]),
                               y, atol=1e-12)
        elif kind == "time":
            inner = data.draw(st.one_of(junk(), st.just(sg.SO2("s"))))
            time_name = data.draw(st.one_of(st.just("t"), names))
            judge("TimeGroupoid", lambda: sg.TimeGroupoid(inner, time_name),
                  ["inner groupoid", "time_name"], verify=verify_groupoid)
        elif kind == "product":
            factors = data.draw(st.lists(st.one_of(junk(max_leaves=2), st.sampled_from(
                [sg.SO2("s"), sg.PairGroupoid(sg.EuclideanSpace("x"))])), max_size=3))
            judge("ProductGroupoid", lambda: sg.ProductGroupoid(*factors),
                  ["factor", "ProductGroupoid"], verify=verify_groupoid)
        else:
            other = data.draw(junk())
            judge("ProductGroupoid", lambda: sg.SO2("s") * other, ["groupoid", "SO2(s)"],
                  verify=verify_groupoid)

    prop()


# --- action groupoids -----------------------------------------------------------------------

ACTIONS = {
    "right": lambda p, W: tuple(W.T * sp.Matrix(p)),
    "left (not a right action)": lambda p, W: tuple(W * sp.Matrix(p)),
    "matrix result": lambda p, W: W.T * sp.Matrix(p),
    "scaled": lambda p, W: tuple(2 * W.T * sp.Matrix(p)),
    "too short": lambda p, W: tuple(W.T * sp.Matrix(p))[:2],
    "raises": lambda p, W: p[7],
    "scalar": lambda p, W: 3,
    "None": lambda p, W: None,
    "string": lambda p, W: "abc",
    "nan": lambda p, W: (sp.nan, p[1], p[2]),
    "complex": lambda p, W: tuple(W.T * sp.Matrix(p) + sp.Matrix([sp.I, 0, 0])),
    "numpy nan": lambda p, W: (np.nan, 0.0, 0.0),
    "free symbol": lambda p, W: tuple(W.T * sp.Matrix(p) * sp.Symbol("s", positive=True)),
    "trivial": lambda p, W: tuple(p),
}


@pytest.mark.parametrize("run", PROFILES)
def test_action_groupoids(run):
    @profile(run, 10, 80)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["space", "group", "action"]))
        space, group = sg.EuclideanSpace.vector("Gamma", 3), sg.SO3("W")
        action = ACTIONS["right"]
        label = "action"
        if which == "space":
            space = data.draw(st.one_of(junk(), st.just(sg.SO3("R"))))
        elif which == "group":
            group = data.draw(st.one_of(junk(), st.just(sg.EuclideanSpace("x"))))
        else:
            label = data.draw(st.sampled_from(sorted(ACTIONS) + ["junk"]))
            action = ACTIONS[label] if label != "junk" else data.draw(junk())
        judge("ActionGroupoid", lambda: sg.ActionGroupoid(space, group, action),
              [which, "action", "Gamma_1, Gamma_2, Gamma_3"], verify=verify_groupoid)

    prop()


# --- DefinedGroupoid --------------------------------------------------------------------------

LINE_MAPS = dict(source=lambda a: (a[0],), target=lambda a: (a[1],),
                 multiply=lambda a, b: (a[0], b[1]), identity=lambda q: (q[0], q[0]),
                 inverse=lambda a: (a[1], a[0]), sections=lambda q, t: [(q[0], q[0] + t)])

#: malformed versions of one structure map (the map's own arity is kept)
MAP_FAULTS = {
    "raises": lambda *args: args[0][5],
    "None": lambda *args: None,
    "scalar": lambda *args: 1,
    "string": lambda *args: "ab",
    "nan": lambda *args: tuple(sp.nan for _ in args[0]) * 2,
    "too long": lambda *args: (*args[0], *args[0], 0),
    "complex": lambda *args: tuple(sp.sympify(c) + sp.I for c in args[0]),
    "numpy complex": lambda *args: tuple(complex(1, 1) for _ in range(2)),
    "infinite": lambda *args: tuple(sp.oo for _ in args[0]),
    "undeclared symbol": lambda *args: tuple(sp.sympify(c) + sp.Symbol("zz")
                                             for c in args[0]),
    "doubled": lambda *args: tuple(2 * sp.sympify(c) for c in args[0]),
}


@pytest.mark.parametrize("run", PROFILES)
def test_defined_groupoids(run):
    @profile(run, 12, 120)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["map", "name", "base_names", "fibre_names",
                                           "source_offset", "map not callable"]))
        kwargs = dict(LINE_MAPS, base_names=["q"], fibre_names=["q"])
        name = "line"
        expected = [which]
        if which == "map":
            key = data.draw(st.sampled_from(sorted(LINE_MAPS)))
            fault = data.draw(st.sampled_from(sorted(MAP_FAULTS)))
            kwargs[key] = MAP_FAULTS[fault]
            expected = [key, "section", "line"]
        elif which == "map not callable":
            key = data.draw(st.sampled_from(sorted(LINE_MAPS)))
            kwargs[key] = data.draw(junk())
            expected = [key, "section"]
        elif which == "name":
            name = data.draw(names)
            expected = ["name", "DefinedGroupoid"]
        elif which in ("base_names", "fibre_names"):
            kwargs[which] = data.draw(names)
            expected = [which, "coordinate", "line", "fibre"]
        else:
            kwargs["source_offset"] = data.draw(st.one_of(scalars, st.integers(-3, 3)))
        judge("DefinedGroupoid", lambda: sg.DefinedGroupoid(name, **kwargs), expected,
              verify=verify_groupoid)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_check_axioms_arguments(run):
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    @profile(run, 12)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["G", "samples", "seed", "tol", "parameters"]))
        kwargs = {"samples": 1}
        target = G
        if which == "G":
            target = data.draw(junk())
        else:
            kwargs[which] = data.draw(st.one_of(scalars, junk()))
        if which == "samples":  # an accepted count runs that many samples: keep it short
            kwargs["samples"] = runnable(kwargs["samples"], memory_checked=False)
        judge("check_axioms", lambda: sg.check_axioms(target, **kwargs),
              [which, "parameter"], verify=lambda result: None)

    prop()


# --- systems ---------------------------------------------------------------------------------

q_undeclared, zeta = sp.Symbol("q"), sp.Symbol("zeta")
f_undefined = sp.Function("f")


def kinetic(g):
    (q0,), (q1,) = g.source, g.target
    return H / 2 * ((q1 - q0) / H) ** 2


def _n(g):
    return g.target[0]


#: extra terms added to a valid Lagrangian (or returned instead of it), with the names a
#: clear error about them must mention
TERMS = {
    "nan": (lambda g: sp.nan, ["nan", "Lagrangian"]),
    "numpy nan": (lambda g: np.nan * _n(g), ["nan", "Lagrangian"]),
    "oo": (lambda g: sp.oo * _n(g), ["oo", "Lagrangian"]),
    "zoo": (lambda g: _n(g) / 0, ["zoo", "Lagrangian"]),
    "I": (lambda g: sp.I * _n(g), ["I", "Lagrangian"]),
    "python complex": (lambda g: 1j * _n(g), ["I", "Lagrangian"]),
    "numpy complex": (lambda g: np.complex128(1 + 1j) * _n(g), ["I", "Lagrangian"]),
    "beyond double": (lambda g: sp.Float("1e400") * _n(g) ** 2, ["Lagrangian", "double"]),
    "huge rational": (lambda g: sp.Rational(10**400, 3) * _n(g) ** 2,
                      ["Lagrangian", "double"]),
    "numpy float": (lambda g: np.float64(0.5) * _n(g) ** 2, ["Lagrangian"]),
    "undefined function": (lambda g: f_undefined(_n(g)), ["f", "Lagrangian"]),
    "derivative": (lambda g: sp.Derivative(f_undefined(_n(g)), _n(g)),
                   ["Derivative", "Lagrangian"]),
    "integral": (lambda g: sp.Integral(_n(g) * zeta, (zeta, 0, 1)),
                 ["Integral", "Lagrangian"]),
    "undeclared symbol": (lambda g: zeta * _n(g), ["zeta", "Lagrangian"]),
    "coordinate look-alike": (lambda g: q_undeclared ** 2, ["q", "Lagrangian"]),
    "mis-declared h": (lambda g: sp.Symbol("h") * _n(g) ** 2, ["h", "Lagrangian"]),
    "matrix symbol": (lambda g: sp.MatrixSymbol("A", 1, 1)[0, 0] * _n(g),
                      ["A", "Lagrangian"]),
    "floor": (lambda g: sp.floor(_n(g)), ["floor", "Lagrangian"]),
    "besselj": (lambda g: sp.besselj(0, _n(g)), ["besselj", "Lagrangian"]),
    "log of a negative": (lambda g: sp.log(-1 - _n(g) ** 2), ["Lagrangian"]),
    "sqrt of a negative": (lambda g: sp.sqrt(-1 - _n(g) ** 2), ["Lagrangian"]),
    "abs": (lambda g: sp.Abs(_n(g)) ** 3, ["Lagrangian"]),
    "piecewise": (lambda g: sp.Piecewise((_n(g) ** 2, _n(g) > 0), (0, True)),
                  ["Lagrangian"]),
    "exp": (lambda g: sp.exp(_n(g)) / 100, ["Lagrangian"]),
}

#: Lagrangians that are wrong as a whole (returned instead of a valid one)
WHOLE = {
    "zero": (lambda g: 0, ["Lagrangian"]),
    "constant": (lambda g: sp.Integer(3), ["Lagrangian"]),
    "null (a difference)": (lambda g: (g.target[0] ** 2 - g.source[0] ** 2) / H,
                            ["Lagrangian"]),
    "source only": (lambda g: g.source[0] ** 2 / H, ["Lagrangian"]),
    "not regular": (lambda g: (g.target[0] - g.source[0]) / H, ["Lagrangian"]),
    "list": (lambda g: [kinetic(g)], ["Lagrangian"]),
    "matrix": (lambda g: sp.Matrix([kinetic(g), 1]), ["Lagrangian"]),
    "numpy array": (lambda g: np.array([kinetic(g)]), ["Lagrangian"]),
    "string": (lambda g: "q**2", ["Lagrangian", "q"]),
    "garbage string": (lambda g: "(((", ["Lagrangian"]),
    "None": (lambda g: None, ["Lagrangian"]),
    "bool": (lambda g: True, ["Lagrangian"]),
    "equation": (lambda g: sp.Eq(g.target[0], 1), ["Lagrangian"]),
    "raises": (lambda g: g.matrix, ["Lagrangian"]),
    "two arguments": (lambda a, b: kinetic(a), ["Lagrangian"]),
    "no argument": (lambda: 1, ["Lagrangian"]),
}

#: constraints (a first-order system on the pair groupoid of R²)
CONSTRAINTS = {
    "valid": (lambda g: [(g.target[0] - g.source[0]) - (g.target[1] - g.source[1])], []),
    "scalar": (lambda g: g.target[0], ["constraints"]),
    "nested": (lambda g: [[g.target[0]]], ["constraints"]),
    "matrix": (lambda g: sp.eye(2), ["constraints"]),
    "nan": (lambda g: [g.target[0] + sp.nan], ["constraints", "nan"]),
    "complex": (lambda g: [g.target[0] + 1j], ["constraints", "I"]),
    "zero": (lambda g: [0 * g.target[0]], ["constraint", "φ_1"]),
    "duplicate": (lambda g: [g.target[0] - g.target[1]] * 2, ["constraint", "φ_1", "φ_2"]),
    "source only": (lambda g: [g.source[0] - 1], ["constraint", "φ_1"]),
    "target only": (lambda g: [g.target[0] - 1], ["constraint", "φ_1", "multiplier"]),
    "too many": (lambda g: [g.target[0], g.target[1], g.source[0]], ["constraints"]),
    "undeclared": (lambda g: [g.target[0] - zeta], ["constraints", "zeta"]),
    "raises": (lambda g: 1 / 0, ["constraints"]),
    "list not function": ([sp.Symbol("x")], ["constraints"]),
    "generator": (lambda g: (c for c in [g.target[0]]), ["constraints"]),
    "numpy": (lambda g: np.array([g.target[0] - g.target[1]]), ["constraints"]),
    "beyond double": (lambda g: [sp.Float("1e400") * (g.target[0] - g.source[0])
                                 - (g.target[1] - g.source[1])], ["constraints", "double"]),
}


def free_plane(g):
    return sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * H)


def plane_declaration(**changes) -> dict:
    """The keyword arguments of a free particle on the plane's pair groupoid, with
    ``changes``: what a property then makes hostile."""
    return dict(groupoid=sg.PairGroupoid(sg.EuclideanSpace("x y")), lagrangian=free_plane,
                parameters=[H], name="hostile", **changes)


def derived(kind, kwargs: dict):
    """What ``judge`` builds: the ``kind`` system of ``kwargs``, its equations derived."""
    def build():
        system = kind(**kwargs)
        system.euler_lagrange()
        return system
    return build


def verify_system(system) -> None:
    """A derived system: its simulated steps solve the derived equations and are stationary
    points of the system's own action (``verify_stationary``)."""
    step = system.euler_lagrange()
    sim = step.compile(backend="numpy")
    n = system.groupoid.base_dim
    state = {name: (0.1 * (i + 1), 0.1 * (i + 1) + 0.05)
             for i, name in enumerate(system.groupoid.space.names)}
    if step.n_constraints:
        state = {name: (0.0, 0.05) for name in system.groupoid.space.names}
        state["lambda"] = [0.0] * step.n_constraints
    params = {str(s): 0.1 for s in system.parameters}
    try:
        traj = sim.simulate(state, 3, params)
    except (sg.NewtonDivergenceError, sg.SingularJacobianError, sg.ShapeError):
        return  # a clear error for this state; the derivation itself was checked
    verify_trajectory(step, traj, sim.parameters(params))
    assert sg.verify_stationary(traj, system), f"{system.name}: not stationary ({n})"


@pytest.mark.parametrize("run", PROFILES)
def test_systems_with_malformed_lagrangians(run):
    line = sg.PairGroupoid(sg.EuclideanSpace("q"))

    @profile(run, 14, 120)
    @given(data=st.data())
    def prop(data):
        if data.draw(st.booleans()):
            key = data.draw(st.sampled_from(sorted(TERMS)))
            term, expected = TERMS[key]

            def lagrangian(g):
                return kinetic(g) + term(g)
        else:
            key = data.draw(st.sampled_from(sorted(WHOLE)))
            lagrangian, expected = WHOLE[key]

        def build():
            system = sg.DiscreteSystem(line, lagrangian, parameters=[H], name="hostile")
            system.euler_lagrange().compile(backend="numpy")
            return system

        judge("DiscreteSystem (Lagrangian)", build, expected + ["hostile"],
              owner="hostile", verify=verify_system)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_systems_with_malformed_constraints_and_declarations(run):
    @profile(run, 14, 120)
    @given(data=st.data())
    def prop(data):
        constraints, expected = CONSTRAINTS[data.draw(st.sampled_from(sorted(CONSTRAINTS)))]
        which = data.draw(st.sampled_from(["constraints", "parameters", "name", "groupoid",
                                           "lagrangian"]))
        kwargs = plane_declaration(constraints=constraints)
        if which == "parameters":
            kwargs["constraints"] = CONSTRAINTS["valid"][0]
            kwargs["parameters"] = data.draw(st.one_of(junk(), st.sampled_from(
                [["h"], [sp.Symbol("h")], [H, H], [H, sp.Symbol("h", real=True)], H, None,
                 {H}, (H,), [H, 2 * H], [H, "zeta"]])))
            expected = ["parameters", "parameter", "h", "H", "zeta"]
        elif which == "name":
            kwargs["constraints"] = CONSTRAINTS["valid"][0]
            kwargs["name"] = data.draw(names)
            expected = ["name"]
        elif which == "groupoid":
            kwargs["groupoid"] = data.draw(st.one_of(junk(), st.just(sg.EuclideanSpace("x"))))
            expected = ["groupoid"]
        elif which == "lagrangian":
            kwargs["lagrangian"] = data.draw(junk())
            expected = ["Lagrangian"]

        judge("DiscreteSystem (constraints)", derived(sg.DiscreteSystem, kwargs),
              expected + ["hostile"], owner="hostile", verify=verify_system)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_second_order_systems(run):
    line = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def accel(a, b):
        return (b.target[0] - 2 * a.target[0] + a.source[0]) ** 2 / H ** 3

    variants = {
        "valid": (accel, None, []),
        "first-order Lagrangian": (kinetic, None, ["Lagrangian"]),
        "three arguments": (lambda a, b, c: accel(a, b), None, ["Lagrangian"]),
        "nan": (lambda a, b: accel(a, b) + sp.nan, None, ["Lagrangian", "nan"]),
        "null": (lambda a, b: (b.target[0] - a.source[0]) / H, None, ["Lagrangian"]),
        "constraint of one arrow": (accel, lambda a: [a.target[0]], ["constraints"]),
        "dependent constraints": (accel, lambda a, b: [b.target[0] - a.target[0]] * 2,
                                  ["constraint", "φ_1", "φ_2"]),
        "constraint not a list": (accel, lambda a, b: b.target[0], ["constraints"]),
    }

    @profile(run, 6, 40)
    @given(key=st.sampled_from(sorted(variants)))
    def prop(key):
        lagrangian, constraints, expected = variants[key]

        def build():
            system = sg.SecondOrderSystem(line, lagrangian, constraints=constraints,
                                          parameters=[H], name="hostile2")
            system.euler_lagrange()
            return system

        def verify(system):
            step = system.euler_lagrange()
            sim = step.compile(backend="numpy")
            traj = sim.simulate({"q": [0.0, 0.1, 0.21, 0.33]}, 3, {"h": 0.1})
            verify_trajectory(step, traj, sim.parameters({"h": 0.1}))
            assert sg.verify_stationary(traj, system)

        judge("SecondOrderSystem", build, expected + ["hostile2"], owner="hostile2",
              verify=verify)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_nonholonomic_systems(run):
    @profile(run, 10, 80)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["distribution", "method", "metric", "groupoid",
                                           "constraints"]))
        kwargs = plane_declaration(constraints=lambda g: [
            g.target[0] - g.source[0] - (g.target[1] - g.source[1])], distribution=[[1, 1]])
        kwargs["name"] = "hostile_nh"
        expected = [which]
        if which == "distribution":
            kwargs["distribution"] = data.draw(st.one_of(junk(), st.sampled_from(
                [[[np.nan, 1]], [[1]], [[0, 0]], [lambda q: 1 / 0], [lambda q: [1, sp.I]],
                 "ab", [[1, 1], [1, 1]], [lambda q: [1, 1]], [[sp.oo, 1]]])))
            expected = ["distribution", "D_c", "D"]
        elif which == "method":
            kwargs["method"] = data.draw(st.one_of(scalars, st.sampled_from(
                ["holder", "energy_momentum", "Holder"])))
            expected = ["method", "metric"]
        elif which == "metric":
            kwargs.update(method="energy_momentum", constraints=None,
                          distribution=[[1, 1]])
            kwargs["metric"] = data.draw(st.one_of(junk(), st.sampled_from(
                [[[1, 0], [0, 1]], [[np.nan, 0], [0, 1]], [[1, 2], [3, 4]], [[0, 0], [0, 0]],
                 lambda q: 1 / 0, [[1, 0], [0, -1]], [[sp.I, 0], [0, 1]]])))
            expected = ["metric", "G_c"]
        elif which == "groupoid":
            kwargs["groupoid"] = data.draw(junk())
        else:
            kwargs["constraints"] = CONSTRAINTS[data.draw(st.sampled_from(
                sorted(CONSTRAINTS)))][0]
            expected = ["constraints", "constraint", "φ_1", "D_c"]


        def verify(system):
            step = system.euler_lagrange()
            assert isinstance(step, sg.StepEquations)
            sim = step.compile(backend="numpy")
            try:
                traj = sim.simulate({"x": (0.0, 0.05), "y": (0.0, 0.05)}, 3, {"h": 0.1})
            except (sg.ShapeError, sg.NewtonDivergenceError, sg.SingularJacobianError):
                return  # this state is off the system's constraints, or cannot be stepped
            verify_trajectory(step, traj, sim.parameters({"h": 0.1}))

        judge("NonholonomicSystem", derived(sg.NonholonomicSystem, kwargs),
              expected + ["hostile_nh"], owner="hostile_nh", verify=verify)

    prop()
