"""Write a consistent plate-ball initial condition for the embedding example.

The state (g_1, λ_1) is solved from the position (x_0, y_0) = (0, 0) and the discrete
momentum p_0 = (0.1, 0.05, 0.01, 0.02, 0.01) with ``Simulator.from_momentum``, so it
satisfies the rolling constraints.  Usage: ``python make_input.py > initial.txt``.
"""

from __future__ import annotations

import sys

from symgroupoid.systems import plate_ball

PARAMS = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02}
MOMENTUM = (0.1, 0.05, 0.01, 0.02, 0.01)


def main() -> None:
    sim = plate_ball().euler_lagrange().compile(backend="numpy")
    state = sim.from_momentum({"x": 0.0, "y": 0.0}, MOMENTUM, PARAMS)
    params = sim.parameters(PARAMS)
    sys.stdout.write(" ".join(repr(float(v)) for v in params) + "\n")
    sys.stdout.write(" ".join(repr(float(v)) for v in state) + "\n")


if __name__ == "__main__":
    main()
