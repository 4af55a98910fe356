"""The seed example systems, ready-made (their kernels are shipped in ``generated/``).

- ``plate_ball``: a ball rolling on a rotating plate, R²×R²×SO(3) ⇉ R² with three
  constraints (seed 000 §6.2, docs/conventions.md §6);
- ``heavy_top``: the heavy top on the action groupoid S²×SO(3) ⇉ S², Γ·W = WᵀΓ,
  L(Γ, W) = −(1/h) tr(J_d W) − h m g l Γ·e, J_d = ½ tr(I) I₃ − I (docs/conventions.md §9);
- ``rigid_body``: the Moser–Veselov rigid body on SO(3), L(W) = −(1/h) tr(J_d W).

The sign of the rigid-body Lagrangian is the one that makes its kinetic part positive:
with W = cay(ξ), tr(J_d W) = tr J_d − ½ ξᵀ I ξ + O(|ξ|³), so −tr(J_d W)/h = ξᵀIξ/(2h) + const.
The discrete Euler–Lagrange equations are linear in L, so the opposite sign gives the same
equations (and the same regularity near the identity); only the sign of the momenta changes.
"""

from __future__ import annotations

from collections.abc import Callable

import sympy as sp

from .equations import DiscreteSystem
from .groupoids import SO3, ActionGroupoid, EuclideanSpace, NamedMatrix, PairGroupoid


def plate_ball() -> DiscreteSystem:
    """Ball of radius r rolling without slipping on a plate rotating at rate Ω.

    Parameters ``h, r, Omega, c``; c fixes the rotation about the vertical axis per step.
    This is the optimal-control model of seed 000 §6.2 (cost ½|v|², no rotational inertia):
    its flow is constrained variational dynamics, not nonholonomic rolling, and its solutions
    can escape to infinity.  The steps approximate that flow while the rotation per step is
    small, hΩ|q|/r ≪ 1; at hΩ|q|/r ≈ 1 it reaches π/2 and the discrete solution leaves the
    continuous one (docs/conventions.md §12).
    """
    h, r, omega, c = sp.symbols("h r Omega c", positive=True)
    G = PairGroupoid(EuclideanSpace("x y")) * SO3("g")
    E1, E2, E3 = SO3.basis_matrices()

    def L(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        return h / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)

    def phi(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return [h * ((y1 - y0) / h - r / (2 * h) * (W * E1).trace() - omega * (x1 + x0) / 2),
                h * ((x1 - x0) / h + r / (2 * h) * (W * E2).trace() + omega * (y1 + y0) / 2),
                h * (c + (W * E3).trace() / (2 * h))]

    return DiscreteSystem(G, L, constraints=phi, parameters=[h, r, omega, c],
                          name="plate_ball")


def inertia_symbols() -> tuple:
    """Principal moments of inertia I1, I2, I3 (positive symbols)."""
    return sp.symbols("I1 I2 I3", positive=True)


def discrete_inertia(I1, I2, I3) -> sp.Matrix:
    """J_d = ½ tr(I) I₃ − I for I = diag(I1, I2, I3), printed as J_d."""
    inertia = sp.diag(I1, I2, I3)
    return NamedMatrix(inertia.trace() / 2 * sp.eye(3) - inertia, name="J_d")


def heavy_top() -> DiscreteSystem:
    """The heavy top; parameters ``h, mgl, I1, I2, I3`` (mgl = m g l)."""
    h, mgl = sp.symbols("h mgl", positive=True)
    I1, I2, I3 = inertia_symbols()
    Jd = discrete_inertia(I1, I2, I3)
    G = ActionGroupoid(EuclideanSpace.vector("Gamma", 3), SO3("W"),
                       lambda p, W: tuple(W.T * sp.Matrix(p)))

    def L(g):
        gamma = g.point
        return -(Jd * g.matrix).trace() / h - h * mgl * gamma[2]

    return DiscreteSystem(G, L, parameters=[h, mgl, I1, I2, I3], name="heavy_top")


def rigid_body() -> DiscreteSystem:
    """The Moser–Veselov free rigid body; parameters ``h, I1, I2, I3``."""
    h = sp.Symbol("h", positive=True)
    I1, I2, I3 = inertia_symbols()
    Jd = discrete_inertia(I1, I2, I3)

    def L(g):
        return -(Jd * g.matrix).trace() / h

    return DiscreteSystem(SO3("W"), L, parameters=[h, I1, I2, I3], name="rigid_body")


SEED_SYSTEMS: dict[str, Callable[[], DiscreteSystem]] = {
    "plate_ball": plate_ball, "heavy_top": heavy_top, "rigid_body": rigid_body}
