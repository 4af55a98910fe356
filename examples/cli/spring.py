"""A discrete harmonic oscillator on R: a system file for the ``symgroupoid`` command line.

L = (q₁ − q₀)²/(2h) − h k (q₀² + q₁²)/4 on the pair groupoid of R, defined as a top-level
system object (docs/cli.md).  ``spring_bvp.json`` holds a two-point problem for it:

    symgroupoid bvp examples/cli/spring.py examples/cli/spring_bvp.json --check
"""

import sympy as sp

import symgroupoid as sg

h, k = sp.symbols("h k", positive=True)


def L(g):
    (q0,), (q1,) = g.source, g.target
    return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4


spring = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                           name="spring")
PARAMS = {"h": 0.05, "k": 1.0}
INITIAL = {"q": [1.0, 0.999]}
