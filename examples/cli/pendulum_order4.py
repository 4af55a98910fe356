"""A pendulum from its continuous Lagrangian, discretised with the two-stage Gauss–Legendre
Galerkin scheme (order 4; docs/conventions.md §22).  ``symgroupoid verify`` measures the
observed order from INITIAL (a configuration and a velocity) over HORIZON:

    symgroupoid verify examples/cli/pendulum_order4.py
"""

import sympy as sp

import symgroupoid as sg

h, g = sp.symbols("h g", positive=True)


def pendulum() -> sg.DiscreteSystem:
    continuous = sg.ContinuousSystem(sg.EuclideanSpace("theta"),
                                     lambda q, v: v[0] ** 2 / 2 + g * sp.cos(q[0]),
                                     parameters=[h, g], name="pendulum")
    return continuous.discretize(h, sg.GaussLegendre(2))


PARAMS = {"h": 0.05, "g": 9.81}
INITIAL = {"configuration": {"theta": 0.3}, "velocity": [0.5]}
HORIZON = 1.0
