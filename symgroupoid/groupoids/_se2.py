"""SE(2), the rigid motions of the plane (see ``_special_euclidean``)."""

from __future__ import annotations

import sympy as sp

from ..ir import (
    HalfThetaCotHalfTheta,
    OneMinusCosOverTheta2,
    SinOverTheta,
)
from ._so2 import SO2
from ._special_euclidean import _SpecialEuclidean


class SE2(_SpecialEuclidean):
    """Rigid motions of the plane; se(2) coordinates (ω, v₁, v₂)."""

    n = 3
    group_name = "SE2"
    rotation_block = 2
    rot = SO2

    @classmethod
    def _basis(cls):
        return [cls.hat([1, 0, 0]), cls.hat([0, 1, 0]), cls.hat([0, 0, 1])]

    @classmethod
    def hat(cls, x):
        x = cls._hat_coordinates(x, 3)
        out = sp.zeros(3, 3)
        out[:2, :2] = SO2.hat([x[0]])
        out[0, 2], out[1, 2] = x[1], x[2]
        return out

    @staticmethod
    def _V(w):
        """[[sin θ/θ, −(1 − cos θ)/θ], [(1 − cos θ)/θ, sin θ/θ]] with smooth coefficients."""
        th = w[0]
        A, B = SinOverTheta(th ** 2), th * OneMinusCosOverTheta2(th ** 2)
        return sp.Matrix([[A, -B], [B, A]])

    @staticmethod
    def _V_inverse(w):
        """V⁻¹ = [[a, θ/2], [−θ/2, a]], a = (θ/2) cot(θ/2)."""
        th = w[0]
        a = HalfThetaCotHalfTheta(th ** 2)
        return sp.Matrix([[a, th / 2], [-th / 2, a]])
