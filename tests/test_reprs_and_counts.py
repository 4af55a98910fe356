"""Short reprs of the result objects, and one rule for counts at every entry point
(``steps=1e7`` accepted, ``steps=-5`` or ``2.5`` refused with the argument's name)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import ShapeError
from symgroupoid.derivation import ConservedQuantities

h = sp.Symbol("h", positive=True)


def rotor() -> sg.DiscreteSystem:
    """A free rotor on SO(2): L = (1 − R₁₁)/h."""
    return sg.DiscreteSystem(sg.SO2("R"), lambda g: (1 - g.matrix[0, 0]) / h, parameters=[h],
                             name="rotor")


def pendulum(order: int = 1):
    space = sg.PairGroupoid(sg.EuclideanSpace("q"))
    if order == 2:
        return sg.SecondOrderSystem(
            space, lambda a, b: (b.target[0] - 2 * a.target[0] + a.source[0]) ** 2 / h,
            parameters=[h], name="spline")
    return sg.DiscreteSystem(space, lambda g: (g.target[0] - g.source[0]) ** 2 / h,
                             parameters=[h], name="free")


def test_reprs_are_short_and_informative():
    system = rotor()
    assert repr(system) == "DiscreteSystem('rotor' on SO2(R), 0 constraints)"
    assert repr(pendulum(2)).startswith("SecondOrderSystem('spline' on pair groupoid")
    assert repr(system.legendre()) == ("<LegendreTransforms F⁻L, F⁺L: 1 components each "
                                       "(section basis), on arrows of 4 coordinates, "
                                       "0 multipliers>")
    quantity = pendulum().noether(0)
    assert repr(quantity) == ("<NoetherQuantity F_X = -2*q_{k-1}/h + 2*q_{k}/h "
                              "(symmetry verified)>")
    long = pendulum().noether(lambda q: [q[0]])
    assert len(repr(long)) < 120 and "NOT verified to be a symmetry" in repr(long)
    lie_poisson = repr(system.lie_poisson())
    assert lie_poisson.startswith("<LiePoissonEquations 'rotor")
    assert "1 momenta" in lie_poisson and "reconstruction 1 equations in 1 unknowns" in lie_poisson
    conserved = ConservedQuantities(sp.Symbol("E"), [sp.Symbol("J")], "symbolic", ["fails"],
                                    (), [])
    assert repr(conserved) == "<ConservedQuantities: energy (symbolic), 1 momenta (fails)>"


def test_one_rule_for_counts():
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    sg.check_axioms(G, samples=2.0, seed=np.int64(3))  # integral values are counts
    for samples, message in ((-5, "samples must be at least 1, got -5"),
                             (0, "samples must be at least 1, got 0"),
                             (2.5, "samples must be an integer, got 2.5"),
                             (True, "samples must be an integer, got the boolean True")):
        with pytest.raises(ShapeError, match=message):
            sg.check_axioms(G, samples=samples)
    with pytest.raises(ShapeError, match="seed must be at least 0, got -1"):
        sg.check_axioms(G, seed=-1)
    identity = sg.GroupoidMorphism(G, G, lambda g: g.coords, name="id")
    sg.check_morphism(identity, samples=1e0)
    with pytest.raises(ShapeError, match="id: samples must be at least 1, got -5"):
        sg.check_morphism(identity, samples=-5)
    with pytest.raises(ShapeError, match="id: seed must be an integer, got 0.5"):
        sg.check_morphism(identity, seed=0.5)
    system = pendulum()
    arrows = np.array([[0.0, 0.1], [0.1, 0.2], [0.2, 0.3]])
    assert sg.verify_stationary(arrows, system, {"h": 0.1}, seed=2.0)
    with pytest.raises(ShapeError, match="free: seed must be at least 0, got -1"):
        sg.verify_stationary(arrows, system, {"h": 0.1}, seed=-1)
