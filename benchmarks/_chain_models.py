"""The 3D chain of n rigid bodies (``symgroupoid.systems.spherical_chain``'s physics) as a
continuous system, three times over, for ``benchmarks/work_precision.py``:

- :func:`continuous_chain`: a :class:`symgroupoid.ContinuousSystem` on SO(3)ⁿ with the
  Lagrangian in the body velocities ξᵢ = RᵢᵀṘᵢ,

      L(R, ξ) = Σᵢ ½ ξᵢᵀJᵢξᵢ + ½|ċᵢ|² − g e₃·cᵢ,
      cᵢ = Σ_{j<i} R_j ℓ + Rᵢ ρ,   ċᵢ = Σ_{j<i} R_j ξ̂_j ℓ + Rᵢ ξ̂ᵢ ρ,

  unit masses, Jᵢ = ``systems.chain_inertia(i)`` (about the centre of mass, in the body
  frame), ℓ = (0, 0, −1), ρ = (0, 0, −½), body 1 pinned at the origin;
- :class:`ChainODE`: the same continuous equations as an ODE for scipy, derived here
  symbolically and independently of the library: Ṙᵢ = Rᵢξ̂ᵢ and the Euler–Poincaré
  equations of the left-trivialised Lagrangian (Holm–Schmah–Stoica, Geometric Mechanics and
  Symmetry, §7; for SO(3) with the hat map ξ ↦ ξ̂),

      d/dt ∂L/∂ξᵢ + ξᵢ × ∂L/∂ξᵢ = Tᵢ,   Tᵢ·η = d/dε|₀ L(…, Rᵢ exp(εη̂), …; ξ),

  written M(R) ξ̇ = T − ξ × Π − (∂Π/∂R)·Ṙ with Π = ∂L/∂ξ = M(R)ξ (L is quadratic in ξ);
  for one body with ρ = 0 they are Euler's equations J ξ̇ = Jξ × ξ (:func:`euler_poincare`
  returns the symbolic right-hand side so that this can be checked);
- :func:`mjcf_chain`: the same chain as a MuJoCo model (ball joints, no contact, the same
  masses, inertias and geometry), with the conversions between (Rᵢ, ξᵢ) and MuJoCo's
  (qpos, qvel) (a ball joint holds the rotation Qᵢ = R_{i−1}ᵀRᵢ relative to its parent as a
  quaternion and its angular velocity relative to the parent in its own frame,
  ωᵢ = ξᵢ − Qᵢᵀξ_{i−1}).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

import symgroupoid as sg
from symgroupoid.systems import chain_inertia

LINK = (0, 0, -1)
CENTRE = (0, 0, sp.Rational(-1, 2))
GRAVITY = 9.81


def hat(w) -> sp.Matrix:
    """ŵ, the skew matrix with ŵv = w × v."""
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def hat_numeric(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def chain_lagrangian(R: Sequence[sp.Matrix], xi: Sequence[sp.Matrix], inertias, grav,
                     link=LINK, centre=CENTRE) -> sp.Expr:
    """L(R, ξ) of the module docstring (unit masses)."""
    ell, rho, up = sp.Matrix(link), sp.Matrix(centre), sp.Matrix([0, 0, 1])
    joint, joint_rate = sp.zeros(3, 1), sp.zeros(3, 1)
    L = sp.S.Zero
    for Ri, wi, J in zip(R, xi, inertias):
        c = joint + Ri * rho
        c_dot = joint_rate + Ri * (hat(wi) * rho)
        L += (wi.T * J * wi)[0, 0] / 2 + (c_dot.T * c_dot)[0, 0] / 2 - grav * (up.T * c)[0, 0]
        joint, joint_rate = joint + Ri * ell, joint_rate + Ri * (hat(wi) * ell)
    return L


def chain_energy(R, xi, inertias, grav, link=LINK, centre=CENTRE) -> sp.Expr:
    """E = Σᵢ ½ξᵢᵀJᵢξᵢ + ½|ċᵢ|² + g e₃·cᵢ."""
    kinetic = chain_lagrangian(R, xi, inertias, 0, link, centre)
    potential = kinetic - chain_lagrangian(R, xi, inertias, grav, link, centre)
    return kinetic + potential


def chain_vertical_momentum(R, xi, inertias, link=LINK, centre=CENTRE) -> sp.Expr:
    """e₃·Σᵢ (RᵢJᵢξᵢ + cᵢ × ċᵢ): the angular momentum about the vertical through the pin,
    conserved (gravity is vertical)."""
    ell, rho = sp.Matrix(link), sp.Matrix(centre)
    joint, joint_rate = sp.zeros(3, 1), sp.zeros(3, 1)
    total = sp.zeros(3, 1)
    for Ri, wi, J in zip(R, xi, inertias):
        c, c_dot = joint + Ri * rho, joint_rate + Ri * (hat(wi) * rho)
        total += Ri * (J * wi) + c.cross(c_dot)
        joint, joint_rate = joint + Ri * ell, joint_rate + Ri * (hat(wi) * ell)
    return total[2]


def continuous_chain(n: int = 3) -> sg.ContinuousSystem:
    """The chain as a :class:`symgroupoid.ContinuousSystem` on SO(3)ⁿ; parameters h, g."""
    h, grav = sp.symbols("h g", positive=True)
    inertias = [chain_inertia(i) for i in range(1, n + 1)]
    factors = [sg.SO3(f"R{i}") for i in range(1, n + 1)]

    def L(q, v):
        R = list(q) if n > 1 else [q]
        xi = list(v) if n > 1 else [v]
        return chain_lagrangian(R, xi, inertias, grav)

    return sg.ContinuousSystem(factors if n > 1 else factors[0], L, parameters=[h, grav],
                               name=f"chain_{n}")


# --- the independent ODE ---------------------------------------------------------------------

def _symbols(n: int):
    R = [sp.Matrix(3, 3, sp.symbols(f"r{i}_0:9")) for i in range(1, n + 1)]
    xi = [sp.Matrix(sp.symbols(f"w{i}_0:3")) for i in range(1, n + 1)]
    return R, xi


def euler_poincare(R, xi, L: sp.Expr):
    """The symbolic (M, rhs) with M(R) ξ̇ = rhs(R, ξ) (module docstring): Π = ∂L/∂ξ,
    M = ∂Π/∂ξ, rhs = T − ξ × Π − Σ_j ∂Π/∂R_j : R_j ξ̂_j, Tᵢ,ₖ = ∂L/∂Rᵢ : Rᵢ êₖ."""
    w = sp.Matrix.vstack(*xi)
    Pi = sp.Matrix([sp.diff(L, s) for s in w])
    M = Pi.jacobian(w)
    basis = [hat(sp.eye(3)[:, k]) for k in range(3)]
    rhs = []
    for i, (Ri, wi) in enumerate(zip(R, xi)):
        dL = Ri.applyfunc(lambda r: sp.diff(L, r))
        Pi_i = Pi[3 * i:3 * i + 3, 0]
        torque = sp.Matrix([sum(dL.multiply_elementwise(Ri * E)) for E in basis])
        rhs.append(torque - wi.cross(Pi_i))
    rhs = sp.Matrix.vstack(*rhs)
    for Rj, wj in zip(R, xi):
        rate = Rj * hat(wj)
        for a in range(3):
            for b in range(3):
                if rate[a, b] != 0:
                    rhs -= Pi.diff(Rj[a, b]) * rate[a, b]
    return M, rhs


@dataclass
class ChainODE:
    """y = (R₁ row by row, …, Rₙ, ξ₁, …, ξₙ); ``rhs(t, y)`` for scipy, ``energy(y)`` and
    ``vertical_momentum(y)`` (lambdified once from the symbolic forms)."""

    n: int
    _M: object
    _rhs: object
    _energy: object
    _momentum: object

    @classmethod
    def build(cls, n: int = 3, grav: float = GRAVITY) -> ChainODE:
        R, xi = _symbols(n)
        inertias = [chain_inertia(i) for i in range(1, n + 1)]
        L = chain_lagrangian(R, xi, inertias, sp.Float(grav))
        M, rhs = euler_poincare(R, xi, L)
        args = [*(s for Ri in R for s in Ri), *(s for wi in xi for s in wi)]
        E = chain_energy(R, xi, inertias, sp.Float(grav))
        J = chain_vertical_momentum(R, xi, inertias)
        return cls(n, sp.lambdify([args], M, "numpy", cse=True),
                   sp.lambdify([args], rhs, "numpy", cse=True),
                   sp.lambdify([args], E, "numpy", cse=True),
                   sp.lambdify([args], J, "numpy", cse=True))

    def state(self, attitudes: Sequence[np.ndarray], xi: np.ndarray) -> np.ndarray:
        return np.concatenate([*(np.asarray(R, float).ravel() for R in attitudes),
                               np.asarray(xi, float).ravel()])

    def attitudes(self, y: np.ndarray) -> np.ndarray:
        return y[:9 * self.n].reshape(self.n, 3, 3)

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        n = self.n
        w = y[9 * n:]
        dR = [(y[9 * i:9 * i + 9].reshape(3, 3) @ hat_numeric(w[3 * i:3 * i + 3])).ravel()
              for i in range(n)]
        dw = np.linalg.solve(np.asarray(self._M(y), float),
                             np.asarray(self._rhs(y), float).ravel())
        return np.concatenate([*dR, dw])

    def energy(self, y: np.ndarray) -> float:
        return float(self._energy(y))

    def vertical_momentum(self, y: np.ndarray) -> float:
        return float(self._momentum(y))


# --- MuJoCo ------------------------------------------------------------------------------------

def mjcf_chain(n: int = 3, timestep: float = 0.01, grav: float = GRAVITY,
               integrator: str = "RK4") -> str:
    """The chain as an MJCF model: body i's frame at its joint with the body-frame axes of Rᵢ
    (nested bodies at ℓ from their parent), a ball joint at its origin, the centre of mass at
    ρ, unit mass, the principal inertia Jᵢ; no geometry (so no contact); ``integrator``:
    MuJoCo's integrator ("RK4", "Euler", "implicit" or "implicitfast")."""
    def inertial(i: int) -> str:
        J = [float(chain_inertia(i)[k, k]) for k in range(3)]
        return (f'<inertial pos="{float(CENTRE[0])} {float(CENTRE[1])} {float(CENTRE[2])}" '
                f'mass="1" diaginertia="{J[0]!r} {J[1]!r} {J[2]!r}"/>')

    body = ""
    for i in range(n, 0, -1):
        pos = "0 0 0" if i == 1 else f"{LINK[0]} {LINK[1]} {LINK[2]}"
        body = (f'<body name="b{i}" pos="{pos}"><joint name="j{i}" type="ball" '
                f'damping="0" armature="0"/>{inertial(i)}{body}</body>')
    return (f'<mujoco model="chain_{n}"><option timestep="{timestep!r}" '
            f'integrator="{integrator}" gravity="0 0 {-grav!r}">'
            f'<flag contact="disable" energy="enable"/></option>'
            f'<worldbody>{body}</worldbody></mujoco>')


def _quaternion(Q: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation matrix (Shepperd's method)."""
    t = np.trace(Q)
    if t > 0:
        s = 2.0 * np.sqrt(1.0 + t)
        q = [s / 4, (Q[2, 1] - Q[1, 2]) / s, (Q[0, 2] - Q[2, 0]) / s, (Q[1, 0] - Q[0, 1]) / s]
    else:
        k = int(np.argmax(np.diag(Q)))
        i, j = (k + 1) % 3, (k + 2) % 3
        s = 2.0 * np.sqrt(1.0 + Q[k, k] - Q[i, i] - Q[j, j])
        q = [0.0] * 4
        q[0] = (Q[j, i] - Q[i, j]) / s
        q[1 + k] = s / 4
        q[1 + i] = (Q[i, k] + Q[k, i]) / s
        q[1 + j] = (Q[j, k] + Q[k, j]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def mujoco_state(attitudes: Sequence[np.ndarray], xi: np.ndarray):
    """(qpos, qvel) of the chain at attitudes Rᵢ and body velocities ξᵢ."""
    qpos, qvel = [], []
    parent, parent_xi = np.eye(3), np.zeros(3)
    for i, R in enumerate(attitudes):
        Q = parent.T @ R
        w = np.asarray(xi[3 * i:3 * i + 3], float)
        qpos.append(_quaternion(Q))
        qvel.append(w - Q.T @ parent_xi)
        parent, parent_xi = R, w
    return np.concatenate(qpos), np.concatenate(qvel)


def mujoco_attitudes_velocities(xmat: np.ndarray, qpos: np.ndarray, qvel: np.ndarray,
                                n: int) -> tuple[np.ndarray, np.ndarray]:
    """(Rᵢ from the bodies' world frames ``xmat`` (body 0 is the world), ξ) from MuJoCo."""
    R = np.asarray(xmat, float).reshape(-1, 3, 3)[1:n + 1]
    xi, parent_xi = [], np.zeros(3)
    for i in range(n):
        Q = R[i] if i == 0 else R[i - 1].T @ R[i]
        w = Q.T @ parent_xi + qvel[3 * i:3 * i + 3]
        xi.append(w)
        parent_xi = w
    return R, np.concatenate(xi)
