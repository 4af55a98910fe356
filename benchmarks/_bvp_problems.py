"""Two-point optimal control problems for the boundary-value benchmark and its slow tests.

Three families, each one system with symbolic parameters (so one window kernel per family):

- ``so3``: attitude steering on SO(3), first order with the Cayley chart (seed 000 §6.1),
  L(g) = h·l(ξ), ξ = cay⁻¹(g)/h, l(ξ) = ½(I₁ξ₁² + I₂ξ₂² + I₃ξ₃²), and a control constraint
  ψ(ξ) = ξ₃ − u·ξ₁ (the spin about the third body axis slaved to the first: the problem
  is underactuated, non-convex and has several local minima for large turns);
- ``so3_free``: the same cost without constraint (the discrete free rigid body, a geodesic
  problem of a left-invariant metric);
- ``se2``: the unicycle on SE(2), ξ = (ω, v₁, v₂), l = ½(Aω² + Mv₁²), ψ = v₂ (no sideways
  velocity): reaching a pose to the side of the start needs a manoeuvre.

Time T = 1, h = T/N.  ``random_problems`` draws end rotations up to 150° from the start (a
uniformly random axis), random inertias, and N in [100, 2000]; the solver starts from its
default (geodesic) guess.  The CasADi transcriptions live in ``_bvp_casadi.py``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
I1, I2, I3, u = sp.symbols("I_1 I_2 I_3 u", real=True)
A, M = sp.symbols("A M", positive=True)


@functools.cache
def so3_system(constrained: bool = True) -> sg.DiscreteSystem:
    """L = h·½Σ Iᵢξᵢ², optionally ψ = ξ₃ − u·ξ₁, on SO(3) with the Cayley chart."""

    def L(g):
        xi = g.coordinates / h
        return h * (I1 * xi[0] ** 2 + I2 * xi[1] ** 2 + I3 * xi[2] ** 2) / 2

    def phi(g):
        xi = g.coordinates / h
        return [h * (xi[2] - u * xi[0])]

    if constrained:
        return sg.DiscreteSystem(sg.SO3("g"), L, constraints=phi, parameters=[h, I1, I2, I3, u],
                                 name="so3_steering")
    return sg.DiscreteSystem(sg.SO3("g"), L, parameters=[h, I1, I2, I3], name="so3_free")


@functools.cache
def se2_system() -> sg.DiscreteSystem:
    """The unicycle: L = h·½(Aω² + Mv₁²), ψ = v₂, on SE(2) with the Cayley chart."""

    def L(g):
        w, v1, _ = (c / h for c in g.coordinates)
        return h * (A * w ** 2 + M * v1 ** 2) / 2

    def phi(g):
        return [g.coordinates[2]]

    return sg.DiscreteSystem(sg.SE2("s"), L, constraints=phi, parameters=[h, A, M],
                             name="se2_unicycle")


def rotation(axis_angle) -> np.ndarray:
    """exp(ω̂) (Rodrigues)."""
    w = np.asarray(axis_angle, float)
    th = float(np.linalg.norm(w))
    if th == 0.0:
        return np.eye(3)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / th
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def pose(x: float, y: float, theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class Problem:
    """One two-point problem: ``kind`` ∈ {so3, so3_free, se2}, the end configuration (the
    start is the identity), N, and the parameter values (h first)."""

    kind: str
    end: np.ndarray
    steps: int
    params: tuple
    label: str = ""

    @property
    def system(self) -> sg.DiscreteSystem:
        if self.kind == "se2":
            return se2_system()
        return so3_system(self.kind == "so3")

    @property
    def start(self) -> np.ndarray:
        return np.eye(3)

    def solve(self, **options) -> sg.BoundaryValueSolution:
        return sg.solve_boundary_value(self.system, self.start, self.end, self.steps,
                                       params=list(self.params), **options)

    def cost(self, arrows: np.ndarray) -> float:
        """Σ h·l(ξ_k) from the Cayley coordinates of the arrows."""
        G = self.system.groupoid
        x = np.array([G.fibre_chart_inverse(a) for a in arrows]) / self.params[0]
        if self.kind == "se2":
            a, m = self.params[1:3]
            weights = np.array([a, m, 0.0])
        else:
            weights = np.array(self.params[1:4])
        return float(self.params[0] * np.sum(weights * x ** 2) / 2)


def random_problems(count: int = 20, seed: int = 20240609, steps: tuple = (100, 2000)
                    ) -> list[Problem]:
    """``count`` problems alternating SE(2) and SO(3) (every fourth SO(3) one unconstrained):
    an end rotation by an angle in [0°, 150°] about a uniform random axis (SE(2): about the
    normal, with a translation in [−1.5, 1.5]²), inertias in [0.5, 3], u in [−0.5, 0.5],
    N in ``steps``."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(count):
        n = int(rng.integers(steps[0], steps[1] + 1))
        dt = 1.0 / n
        angle = np.deg2rad(rng.uniform(0.0, 150.0))
        if i % 2 == 0:
            x, y = rng.uniform(-1.5, 1.5, size=2)
            theta = angle * rng.choice([-1.0, 1.0])
            a, m = rng.uniform(0.5, 3.0, size=2)
            out.append(Problem("se2", pose(x, y, theta), n, (dt, a, m),
                               f"se2 #{i}: ({x:+.2f}, {y:+.2f}, {np.rad2deg(theta):+.0f}°)"))
            continue
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        inertia = rng.uniform(0.5, 3.0, size=3)
        kind = "so3_free" if i % 4 == 1 else "so3"
        params = (dt, *inertia) if kind == "so3_free" else (dt, *inertia, rng.uniform(-0.5, 0.5))
        out.append(Problem(kind, rotation(angle * axis), n, params,
                           f"{kind} #{i}: {np.rad2deg(angle):.0f}° about "
                           f"({axis[0]:+.2f}, {axis[1]:+.2f}, {axis[2]:+.2f})"))
    return out
