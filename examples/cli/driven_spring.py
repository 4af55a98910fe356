"""A damped harmonic oscillator on R driven by an input u: a forced system file for the
``symgroupoid`` command line (docs/conventions.md §20, docs/how-to/forces.md).

L = (q₁ − q₀)²/(2h) − h k (q₀² + q₁²)/4 on the pair groupoid of R, with the midpoint rule's
discrete forces f⁻ = f⁺ = (h/2)·(u − c·(q₁ − q₀)/h).  The input sequence is a file, one row
per step:

    symgroupoid simulate examples/cli/driven_spring.py --steps 100 --inputs U.csv
"""

import sympy as sp

import symgroupoid as sg

h, k, c = sp.symbols("h k c", positive=True)
u = sp.Symbol("u", real=True)


def L(g):
    (q0,), (q1,) = g.source, g.target
    return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4


def forces(g):
    (q0,), (q1,) = g.source, g.target
    half = h / 2 * (u - c * (q1 - q0) / h)
    return [half], [half]


driven_spring = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L,
                                  parameters=[h, k, c], forces=forces, inputs=[u],
                                  time_step=h, name="driven_spring")
PARAMS = {"h": 0.05, "k": 1.0, "c": 0.2}
#: the state holds the input of its arrow (u₀)
INITIAL = {"q": [1.0, 0.999], "u": [0.0]}
