"""The seeds' example systems, built once for several test modules.

- plate-ball: seed 000 §6.2, eq. (8);
- heavy top: seed 002 "Example: The heavy top" (docs/conventions.md §9);
- optimal control with the Cayley retraction on SO(3) and SE(2): seed 000 §6.1
  (docs/conventions.md §5).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import sympy as sp

import symgroupoid as sg
import symgroupoid.systems as sg_systems

# --- plate-ball (seed 000 §6.2) --------------------------------------------------------------

PB_H, PB_R, PB_OMEGA, PB_C = sp.symbols("h r Omega c", positive=True)
PB_PARAMETERS = (PB_H, PB_R, PB_OMEGA, PB_C)
E1, E2, E3 = (sp.Matrix(E) for E in sg.SO3.basis_matrices())


def plate_ball_system() -> sg.DiscreteSystem:
    """L and φ¹, φ², φ³ exactly as in seed 000 eq. (8) and the line after it (the library's
    ``symgroupoid.systems.plate_ball``)."""
    return sg_systems.plate_ball()


# --- heavy top (seed 002) --------------------------------------------------------------------

HT_H, HT_M, HT_G, HT_L = sp.symbols("h m g l", positive=True)
HT_INERTIA_SYMBOLS = sp.symbols("I11 I12 I13 I22 I23 I33", real=True)
HT_E = sp.Matrix(sp.symbols("e1:4", real=True))
_i = HT_INERTIA_SYMBOLS
HT_INERTIA = sp.Matrix([[_i[0], _i[1], _i[2]], [_i[1], _i[3], _i[4]], [_i[2], _i[4], _i[5]]])
HT_J = HT_INERTIA.trace() / 2 * sp.eye(3) - HT_INERTIA  # J_d = ½ tr(I) I₃ − I
HT_PARAMETERS = [HT_H, HT_M, HT_G, HT_L, *HT_INERTIA_SYMBOLS, *HT_E]


def heavy_top_groupoid() -> sg.ActionGroupoid:
    """S² × SO(3) ⇉ S² with Γ·W = WᵀΓ (seed 002)."""
    return sg.ActionGroupoid(sg.EuclideanSpace.vector("Gamma", 3), sg.SO3("W"),
                             lambda p, W: tuple(W.T * sp.Matrix(p)))


def heavy_top_system() -> sg.DiscreteSystem:
    """L_d(Γ, W) = −(1/h) tr(J_d W) − h m g l Γ·e (seed 002), general symmetric inertia."""
    def L(g):
        Gamma = sp.Matrix(g.point)
        return -(HT_J * g.matrix).trace() / HT_H - HT_H * HT_M * HT_G * HT_L * Gamma.dot(HT_E)

    return sg.DiscreteSystem(heavy_top_groupoid(), L, parameters=HT_PARAMETERS,
                             name="heavy_top")


# --- optimal control with the Cayley retraction (seed 000 §6.1) -----------------------------

def control_system(G: sg.MatrixLieGroup, cost: Callable, psi: Callable,
                   parameters: Sequence, name: str) -> sg.DiscreteSystem:
    """L(g) = h·l(τ⁻¹(g)/h), φᵃ(g) = h·ψᵃ(τ⁻¹(g)/h) with h = ``parameters[0]``."""
    h = parameters[0]

    def L(g):
        return h * cost(list(g.coordinates / h))

    def phi(g):
        return [h * p for p in psi(list(g.coordinates / h))]

    return sg.DiscreteSystem(G, L, constraints=phi, parameters=parameters, name=name)


SO3_H, SO3_U, SO3_RHO = sp.symbols("h u rho", positive=True)
SO3_I = sp.symbols("I1:4", positive=True)
SO3_PARAMETERS = [SO3_H, SO3_U, SO3_RHO, *SO3_I]


def so3_cost(xi: Sequence) -> sp.Expr:
    """l(ξ) = ½ ξᵀ diag(I₁, I₂, I₃) ξ."""
    return sum(i * v**2 for i, v in zip(SO3_I, xi)) / 2


def so3_psi(xi: Sequence) -> list:
    """One linear and one nonlinear control constraint."""
    return [xi[2] - SO3_U, xi[0] ** 2 + xi[1] * xi[2] - SO3_RHO]


SE2_H, SE2_KAPPA, SE2_C = sp.symbols("h kappa c", positive=True)
SE2_A, SE2_M = sp.symbols("A M", positive=True)
SE2_B = sp.Symbol("B", real=True)
SE2_INERTIA = sp.Matrix([[SE2_A, SE2_B, 0], [SE2_B, SE2_M, 0], [0, 0, SE2_M]])
SE2_PARAMETERS = [SE2_H, SE2_KAPPA, SE2_C, SE2_A, SE2_B, SE2_M]


def se2_cost(xi: Sequence) -> sp.Expr:
    """l(ξ) = ½ ξᵀ I ξ with a non-diagonal I coupling rotation and forward velocity."""
    v = sp.Matrix(xi)
    return (v.T * SE2_INERTIA * v)[0, 0] / 2


def se2_psi(xi: Sequence) -> list:
    """Lateral velocity tied to the turning rate (linear) and a nonlinear constraint."""
    return [xi[2] - SE2_KAPPA * xi[0], xi[1] ** 2 + xi[0] * xi[2] - SE2_C]


def so3_control_system() -> sg.DiscreteSystem:
    return control_system(sg.SO3("g"), so3_cost, so3_psi, SO3_PARAMETERS, "oc_so3")


def se2_control_system() -> sg.DiscreteSystem:
    return control_system(sg.SE2("s"), se2_cost, se2_psi, SE2_PARAMETERS, "oc_se2")


# --- a run that fails at a fixed step (long-run tests) -----------------------------------------

def falling(name: str = "fall"):
    """A particle on R under a force ∝ 1/√q: NaN once q < 0, so the run fails at a fixed
    step (L = h[((q₁−q₀)/h)²/2 − a·√q₀])."""
    h, a = sp.symbols("h a", positive=True)

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h * (((q1 - q0) / h) ** 2 / 2 - a * sp.sqrt(q0))

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, a],
                             name=name).euler_lagrange()


FALL_PARAMS = {"h": 0.01, "a": 0.1}
FALL_START = {"q": (1.0, 0.99)}


# --- a driven, damped oscillator (docs/conventions.md §20) ------------------------------------

DRIVEN_H, DRIVEN_K, DRIVEN_C = sp.symbols("h k c", positive=True)
DRIVEN_U = sp.Symbol("u", real=True)


def driven_oscillator(name: str = "driven_oscillator") -> sg.DiscreteSystem:
    """A damped oscillator on R driven by an input u: the midpoint rule's L_d and discrete
    forces f⁻ = f⁺ = (h/2)·(u − c·v); parameters h, k, c."""
    h, k, c, u = DRIVEN_H, DRIVEN_K, DRIVEN_C, DRIVEN_U
    G = sg.PairGroupoid(sg.EuclideanSpace(["x"]))

    def L(g):
        (x0,), (x1,) = g.source, g.target
        return h * (((x1 - x0) / h) ** 2 / 2 - k / 2 * ((x0 + x1) / 2) ** 2)

    def forces(g):
        (x0,), (x1,) = g.source, g.target
        half = h / 2 * (u - c * (x1 - x0) / h)
        return [half], [half]

    return sg.DiscreteSystem(G, L, parameters=[h, k, c], forces=forces, inputs=[u],
                             time_step=h, name=name)

