"""A particle on a circle: a system file for the ``symgroupoid`` command line (docs/cli.md).

The pair groupoid of R² with L = |q₁ − q₀|²/(2h) and the constraint φ = ψ(q₁) − ψ(q₀),
ψ(q) = |q|²/2, which keeps |q| at its initial value with a multiplier the equations
determine.  Rotations are a symmetry, so the angular momentum is conserved (seed 000
Thm 4.9).

    symgroupoid derive examples/cli/ring.py
    symgroupoid verify examples/cli/ring.py
    symgroupoid simulate examples/cli/ring.py --steps 1e5 --every 100 -o ring.npz
"""

import math

import sympy as sp

import symgroupoid as sg

h, r = sp.symbols("h r", positive=True)


def ring() -> sg.DiscreteSystem:
    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h)

    def phi(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return [(x1 ** 2 + y1 ** 2 - x0 ** 2 - y0 ** 2) / 2]

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L, constraints=phi,
                             parameters=[h, r], name="ring")


def helper(x):
    """Not a system: a function with an argument is never taken for one."""
    return x


#: defaults of the commands (--params and --initial override them)
PARAMS = {"h": 0.01, "r": 1.0}
INITIAL = {"x": [1.0, math.cos(0.01)], "y": [0.0, math.sin(0.01)], "lambda": [0.0]}
#: what `symgroupoid verify` checks: the rotation q ↦ (−y, x) is a symmetry
NOETHER = [{"name": "angular momentum", "section": lambda q: [-q[1], q[0]]}]
