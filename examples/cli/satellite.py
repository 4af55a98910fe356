"""A satellite with a reaction wheel on its third body axis: SO(3) × (R × R) ⇉ R.

The body's increment W_k = R_kᵀR_{k+1} and the wheel's angle θ; with the body's angular
velocity Ω = vee(W − Wᵀ)/(2h) and I = diag(I1, I2, I3),

    L_d = h (ΩᵀIΩ/2 + J_w (Ω₃ + (θ₁ − θ₀)/h)²/2).

``symgroupoid derive examples/cli/satellite.py`` prints the equations with Ω named
(ABBREVIATIONS, docs/cli.md); ``--pdf`` typesets them.
"""

import sympy as sp

import symgroupoid as sg

h, I1, I2, I3, Jw = sp.symbols("h I1 I2 I3 J_w", positive=True)


def omega(g) -> sp.Matrix:
    """Ω = vee(W − Wᵀ)/(2h) of the arrow's rotation part."""
    W = g[0].matrix
    return sg.SO3.vee(W - W.T) / (2 * h)


def satellite() -> sg.DiscreteSystem:
    G = sg.SO3("W") * sg.PairGroupoid(sg.EuclideanSpace("theta"))
    inertia = sp.diag(I1, I2, I3)

    def L(g):
        (theta0,), (theta1,) = g[1].source, g[1].target
        w = omega(g)
        return h * ((w.T * inertia * w)[0, 0] / 2
                    + Jw * (w[2] + (theta1 - theta0) / h) ** 2 / 2)

    return sg.DiscreteSystem(G, L, parameters=[h, I1, I2, I3, Jw], name="satellite")


PARAMS = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0, "J_w": 0.1}
ABBREVIATIONS = {rf"\Omega_{{{a + 1}}}": (lambda g, a=a: omega(g)[a]) for a in range(3)}
