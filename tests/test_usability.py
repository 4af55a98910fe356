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
