"""Errors that say what to do, and Lie-group states a user can read (regression tests).

Each test reproduces what a new user met: a product of two groups with one name, numeric
functions and non-smooth functions in a Lagrangian, a half-turn increment in a Cayley chart,
a holonomic system started from typed numbers, the increments W_k = R_kᵀR_{k+1} of a
Lie-group state without the attitudes R_k, unreadable plot legends, trajectories that could
be saved only from the command line.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid._errors import CoordinateNameError, UnsupportedExpressionError

H = sp.Symbol("h", positive=True)


# --- products with duplicate part names ---------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda: sg.SO3("R") * sg.SO3("R"),
    lambda: (sg.SO3("R") * sg.PairGroupoid(sg.EuclideanSpace("x"))) * sg.SO3("R"),
    lambda: sg.PairGroupoid(sg.EuclideanSpace("x")) * sg.PairGroupoid(sg.EuclideanSpace("y x")),
    lambda: sg.EuclideanSpace("x") * sg.EuclideanSpace("x"),
    lambda: sg.PairGroupoid(sg.SO3("R") * sg.SO3("R")),
], ids=["SO3*SO3", "nested", "pair coordinates", "manifolds", "pair of a product"])
def test_products_refuse_duplicate_part_names(make):
    with pytest.raises(CoordinateNameError, match=r"'(R|x)'.*distinct names"):
        make()


def test_products_with_distinct_names_are_accepted():
    G = sg.SO3("R1") * sg.SO3("R2") * sg.PairGroupoid(sg.EuclideanSpace("x"))
    assert len(G.factors) == 3


# --- numeric and non-smooth functions in a Lagrangian -------------------------------------------

def _oscillator(potential):
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return H * (((q1 - q0) / H) ** 2 / 2 - potential(q0))

    return sg.DiscreteSystem(G, L, parameters=[H], name="pendulum")


def test_math_cos_in_the_lagrangian_says_use_sympy():
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return H * (((q1 - q0) / H) ** 2 / 2 - math.cos(q0))

    with pytest.raises(sg.CallableError, match=r"calls math\.cos.*SymPy's functions.*sp\.cos"):
        sg.DiscreteSystem(G, L, parameters=[H], name="pendulum")


def test_numpy_cos_in_the_lagrangian_says_use_sympy():
    with pytest.raises(sg.CallableError, match=r"np\.cos.*SymPy's functions.*sp\.cos") as info:
        _oscillator(np.cos)
    assert "Dummy" not in str(info.value)


@pytest.mark.parametrize("function, name", [
    (lambda q: sp.Max(q, 0), "Max"), (lambda q: sp.Min(q, 1), "Min"), (sp.Abs, "Abs"),
    (abs, "Abs"), (lambda q: q * sp.sign(q), "sign"),
    (lambda q: sp.Piecewise((q, q > 0), (0, True)), "Piecewise"), (sp.floor, "floor"),
    (sp.Heaviside, "Heaviside")])
def test_non_smooth_functions_are_refused_by_name(function, name):
    with pytest.raises(UnsupportedExpressionError, match=rf"{name} in the Lagrangian.*"
                                                         r"non-smooth functions.*not supported"
                       ) as info:
        _oscillator(function)
    assert "_x" not in str(info.value) and "Dummy" not in str(info.value)
    assert "q_{k" in str(info.value)  # the coordinate by its name


def test_non_smooth_holonomic_constraint_is_refused_with_coordinate_names():
    ell = sp.Symbol("ell", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y z"))
    with pytest.raises(UnsupportedExpressionError, match=r"Max in the holonomic constraints "
                                                         r"\(Max\(x_\{k\}, y_\{k\}\)\)"):
        sg.DiscreteSystem(G, lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target)),
                          holonomic=lambda q: [sp.Max(q[0], q[1]) + q[2] ** 2 - ell ** 2],
                          parameters=[ell], name="bowl")


# --- the cut locus, h = 0 -----------------------------------------------------------------------

HALF_TURN = np.diag([1.0, -1.0, -1.0])  # a rotation by π about e₁
RIGID = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}


def _rigid_body(retraction: str = "cayley") -> sg.DiscreteSystem:
    I1, I2, I3 = sp.symbols("I1 I2 I3", positive=True)
    J = sp.diag((I2 + I3 - I1) / 2, (I1 + I3 - I2) / 2, (I1 + I2 - I3) / 2)
    return sg.DiscreteSystem(sg.SO3("W", retraction=retraction),
                             lambda g: -(J * g.matrix).trace() / H, parameters=[H, I1, I2, I3],
                             name=f"rigid_{retraction}")


@pytest.mark.parametrize("backend", [pytest.param("c", marks=pytest.mark.skipif(
    __import__("shutil").which("cc") is None, reason="no C compiler")), "numpy"])
@pytest.mark.parametrize("retraction", ["cayley", "exp"])
def test_a_half_turn_increment_names_the_cut_locus_and_the_remedy(backend, retraction):
    sim = _rigid_body(retraction).euler_lagrange().compile(backend=backend)
    chart = "Cayley map" if retraction == "cayley" else "logarithm"
    for run in (lambda: sim.simulate({"W": HALF_TURN}, 5, RIGID),
                lambda: sim.simulate({"W": HALF_TURN}, 5, RIGID, every=2),
                lambda: sim.step({"W": HALF_TURN}, RIGID),
                lambda: sim.solve({"W": HALF_TURN}, RIGID)):
        with pytest.raises(sg.CutLocusStepError,
                           match=rf"step 0 failed: the increment 'W' .*initial state is a "
                                 rf"half-turn.*cut locus of the {chart}.*smaller time step"
                           ) as info:
            run()
        assert isinstance(info.value, sg.CutLocusError)
        assert isinstance(info.value, sg.NewtonDivergenceError)
        assert info.value.parts == ("W",)
        if retraction == "cayley":
            assert 'retraction="exp"' in str(info.value)
    batch = sim.simulate_batch(np.array([sim.state({"W": np.eye(3)}),
                                         sim.state({"W": HALF_TURN})]), 3, RIGID)
    assert batch.error(0) is None and isinstance(batch.error(1), sg.CutLocusStepError)
    near = np.array(sg.SO3("W").numeric_tau([0.0, 0.0, 50.0]))  # 2·atan(25): 176° per step
    assert len(sim.simulate({"W": near}, 3, RIGID)) == 4


def test_increments_of_every_groupoid_with_group_parts():
    R = np.array(sg.SO3("R").numeric_tau([0.3, -0.2, 0.1]))
    pair = sg.PairGroupoid(sg.SO3("R") * sg.SO3("S"))
    free = [R[i, j] for i in range(3) for j in range(3)]
    turned = R @ HALF_TURN
    a = free + [1, 0, 0, 0, 1, 0, 0, 0, 1] + [turned[i, j] for i in range(3)
                                             for j in range(3)] + [1, 0, 0, 0, 1, 0, 0, 0, 1]
    names = [(n, round(abs(np.linalg.det(np.eye(3) + M)), 12))
             for n, _, M in pair.increments(a)]
    assert names == [("R", 0.0), ("S", 8.0)]
    chain = sg.TrivialisedPairGroupoid(sg.SO3("R"), increment="F")
    F = chain.increments(free + list((HALF_TURN - np.eye(3)).ravel()))
    assert F[0][0] == "F" and np.allclose(F[0][2], HALF_TURN)
    product = sg.PairGroupoid(sg.EuclideanSpace("x")) * sg.SO3("W")
    assert [n for n, _, _ in product.increments([0.0, 1.0] + list(HALF_TURN.ravel()))] == ["W"]
    assert sg.PairGroupoid(sg.EuclideanSpace("x")).increments([0.0, 1.0]) == []


@pytest.mark.parametrize("backend", ["numpy", pytest.param("c", marks=pytest.mark.skipif(
    __import__("shutil").which("cc") is None, reason="no C compiler"))])
def test_a_zero_time_step_not_declared_positive_is_refused_with_the_remedy(backend):
    h = sp.Symbol("h")  # not declared positive: 0 passes the assumption checks
    system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")),
                               lambda g: h * ((g.target[0] - g.source[0]) / h) ** 2 / 2,
                               parameters=[h], name="free")
    sim = system.euler_lagrange().compile(backend=backend)
    pattern = (r"free: the parameter h = 0 makes the Lagrangian non-finite \(it divides by "
               r"h\).*nonzero value.*positive=True")
    for run in (lambda: sim.simulate({"q": (0.0, 0.1)}, 3, {"h": 0}),
                lambda: sim.step(np.array([0.0, 0.1]), np.zeros(1)),
                lambda: sim.step(np.array([0.0, 0.1]), {"h": 0.0}),
                lambda: sim.simulate_batch(np.array([[0.0, 0.1]]), 3, {"h": [0.0]})):
        with pytest.raises(sg.ParameterError, match=pattern):
            run()
    p = np.array([0.1])
    state = sim.step(np.array([0.0, 0.1]), p)
    p[0] = 0.0  # the same vector, changed in place inside a loop
    with pytest.raises(sg.ParameterError, match=pattern):
        sim.step(state, p)
    assert np.allclose(sim.step(np.array([0.0, 0.1]), {"h": 0.1}), [0.1, 0.2])


# --- starting a holonomic system, and rotations, from typed numbers ----------------------------

def test_project_initial_moves_typed_configurations_onto_the_holonomic_constraints():
    from symgroupoid import systems

    sim = systems.spherical_pendulum().euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "ell": 1.0, "g": 9.81}
    typed = {"x": (0.707, 0.71), "y": (0.0, 0.01), "z": (-0.707, -0.70)}
    with pytest.raises(sg.DomainError, match=r"ψ_1\(α\(g_k\)\).*project_initial"):
        sim.state(typed, params)
    state = sim.project_initial(typed, params)
    x, y = state[:3], state[3:6]
    assert abs(x @ x - 1.0) < 1e-14 and abs(y @ y - 1.0) < 1e-14
    assert np.abs(state[:3] - [0.707, 0.0, -0.707]).max() < 2e-3  # the nearest point of M
    assert len(sim.simulate(state, 3, params)) == 4

    chain = systems.link_chain(2).euler_lagrange().compile(backend="numpy")
    lengths = {"h": 0.01, "g": 9.81, "l1": 1.0, "l2": 1.0}
    state = chain.project_initial({"x1": (0.5, 0.51), "y1": (-0.866, -0.86),
                                   "x2": (1.5, 1.51), "y2": (-0.866, -0.86)}, lengths)
    p1, p2 = state[0:2], state[2:4]
    assert abs(p1 @ p1 - 1) < 1e-14 and abs((p2 - p1) @ (p2 - p1) - 1) < 1e-14
    with pytest.raises(sg.DomainError, match=r"onto the holonomic constraint set M"):
        chain.project_initial({"x1": (0.0, 0.0), "y1": (0.0, 0.0), "x2": (0.0, 0.0),
                               "y2": (0.0, 0.0)}, {**lengths, "l2": 5.0})


def test_project_initial_moves_the_base_point_of_an_action_groupoid_along_its_orbit():
    from symgroupoid import systems

    sim = systems.tilted_top().euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "mgl": 1.0, "I1": 1.0, "I2": 1.0, "I3": 0.5, "c": 0.8}
    state = sim.project_initial({"Gamma": (0.0, 0.6, 0.8001), "W": np.eye(3)}, params)
    gamma = state[:3]
    assert abs(gamma[2] - 0.8) < 1e-14
    assert abs(gamma @ gamma - (0.36 + 0.8001 ** 2)) < 1e-14  # moved by a rotation


def test_a_rotation_given_to_eight_digits_is_orthonormalised_with_a_warning():
    from symgroupoid import systems

    R = np.array(sg.SO3("W").numeric_tau([0.3, -0.2, 0.5]))
    rounded = np.round(R, 8)
    sim = systems.rigid_body().euler_lagrange().compile(backend="numpy")
    with pytest.warns(sg.GroupRoundingWarning, match=r"'W' is off SO3\(W\) by .*nearest "
                                                     r"element"):
        state = sim.state({"W": rounded})
    W = sim.layout.view(state[None], "W")[0]
    assert np.abs(W.T @ W - np.eye(3)).max() < 1e-15 and np.abs(W - R).max() < 1e-8
    flat = sim.state({"W": R})
    flat[:9] = np.round(flat[:9], 8)
    with pytest.warns(sg.GroupRoundingWarning):
        assert np.abs(sim.state(flat)[:9] - state[:9]).max() < 1e-15
    with pytest.raises(sg.DomainError, match=r"off orthonormal by 1\.\d+e-04.*nearest_element"):
        sim.state({"W": np.round(R, 4)})
    with pytest.raises(sg.DomainError, match="reflection"):
        sim.state({"W": -R})
    assert np.allclose(sg.SO3("W").nearest_element(rounded), W, atol=1e-15)


def test_configurations_of_a_pair_groupoid_of_rotations_are_checked_for_the_group():
    from symgroupoid import systems

    sim = systems.spherical_chain(1).euler_lagrange().compile(backend="numpy")
    R = np.array(sg.SO3("R").numeric_tau([0.1, 0.2, 0.3]))
    with pytest.raises(sg.DomainError, match=r"'R1' is not in SO3\(R1\)"):
        sim.state({"R1": (R, 1.01 * R)})
    with pytest.warns(sg.GroupRoundingWarning, match="'R1'"):
        state = sim.state({"R1": (np.round(R, 8), R)})
    R0 = state[:9].reshape(3, 3)
    assert np.abs(R0.T @ R0 - np.eye(3)).max() < 1e-15
