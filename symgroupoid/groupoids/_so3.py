"""SO(3), the rotations of space (a matrix Lie group; see ``_matrix_groups``), with its
numeric logarithm and exponential accurate up to and including half-turns."""

from __future__ import annotations

import numpy as np
import sympy as sp

from ..ir import (
    OneMinusCosOverTheta2,
    SinOverTheta,
    ThetaOverTwoSin,
)
from ._matrix_groups import MatrixLieGroup, hat3


class SO3(MatrixLieGroup):
    """Rotations of space; so(3) basis E₁, E₂, E₃ of seed 000 §6.2 (ω̂ = Σ ω_a E_a)."""

    n = 3
    group_name = "SO3"
    rotation_block = 3

    @classmethod
    def _basis(cls):
        return [hat3((1, 0, 0)), hat3((0, 1, 0)), hat3((0, 0, 1))]

    @classmethod
    def _cayley_closed_form(cls, x):
        """cay(ξ) = I + 4/(4 + |x|²)(ξ + ξ²/2) (seed 000 §6.1), ξ = x̂."""
        X = cls.hat(x)
        return sp.eye(3) + 4 / (4 + sum(v**2 for v in x)) * (X + X * X / 2)

    def _inverse_matrix(self, M):
        return M.T

    @staticmethod
    def _inverse_closed_form(M):
        return M.T

    @classmethod
    def _exp_closed_form(cls, x):
        """Rodrigues: I + A(θ²) x̂ + B(θ²) x̂², A = sin θ/θ, B = (1 − cos θ)/θ² (smooth at 0)."""
        th2 = x[0] ** 2 + x[1] ** 2 + x[2] ** 2
        W = hat3(x)
        return sp.eye(3) + SinOverTheta(th2) * W + OneMinusCosOverTheta2(th2) * W * W

    def log_coordinates(self, M):
        """ω with exp(ω̂) = R, θ = |ω| ∈ [0, π] (:func:`so3_log`)."""
        return so3_log(M)

    def exp_rows(self, X):
        """Rodrigues' formula for every row (:func:`so3_exp_rows`)."""
        return so3_exp_rows(X)

    def cayley_inverse(self, M):
        # on SO(3): cay⁻¹(R) = 2(R − Rᵀ)/(1 + tr R)   (from seed 001 eq. (63))
        return self.vee(2 * (M - M.T) / (1 + M.trace()))

    def log(self, M):
        """θ/(2 sin θ)·vee(R − Rᵀ), the coefficient a smooth function of cos θ = (tr R − 1)/2."""
        return self.vee(ThetaOverTwoSin((M.trace() - 1) / 2) * (M - M.T))


def so3_log(R: np.ndarray) -> np.ndarray:
    """ω with exp(ω̂) = R for a rotation R, θ = |ω| ∈ [0, π]; accurate at and near a
    half-turn, where θ/(2 sin θ)·vee(R − Rᵀ) is 0·∞ (there the axis is read off the
    symmetric part: (R + Rᵀ)/2 − cos θ·I = (1 − cos θ)·a aᵀ)."""
    c = float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
    s_axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    s = float(np.linalg.norm(s_axis))  # sin θ
    theta = float(np.arctan2(s, c))
    if c > -0.5:
        return s_axis * (theta / s if s > 1e-12 else 1.0 + s * s / 6.0)
    B = (R + R.T) / 2.0 - c * np.eye(3)
    i = int(np.argmax(np.diag(B)))
    axis = B[:, i] / np.sqrt(max(B[i, i], 1e-300) * (1.0 - c))
    if axis @ s_axis < 0:
        axis = -axis
    return theta * axis / np.linalg.norm(axis)


def so3_exp_rows(W: np.ndarray) -> np.ndarray:
    """exp(ω̂) for every row ω of W (Rodrigues, sin θ/θ and (1 − cos θ)/θ² by their series
    near θ = 0), as arrows of SO(3) (the nine entries, row-major)."""
    theta = np.linalg.norm(W, axis=1)
    small = theta < 1e-4
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1 - theta ** 2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta ** 2 / 24, (1 - np.cos(t)) / t ** 2)
    K = np.zeros((len(W), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -W[:, 2], W[:, 1], -W[:, 0]
    K -= np.swapaxes(K, 1, 2)
    R = np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)
    return R.reshape(len(W), 9)
