"""SE(3), the rigid motions of space (see ``_special_euclidean``)."""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

from .._lambdify import NUMPY_MODULES
from ..ir import (
    OneMinusCosOverTheta2,
    SE3LogCoefficient,
    ThetaMinusSinOverTheta3,
)
from ._matrix_groups import hat3
from ._so3 import SO3, so3_log
from ._special_euclidean import _SpecialEuclidean


class SE3(_SpecialEuclidean):
    """Rigid motions of space; se(3) coordinates (ω₁, ω₂, ω₃, v₁, v₂, v₃)."""

    n = 4
    group_name = "SE3"
    rotation_block = 3
    rot = SO3

    @classmethod
    def _basis(cls):
        return [cls.hat([1 if i == a else 0 for i in range(6)]) for a in range(6)]

    @classmethod
    def hat(cls, x):
        x = cls._hat_coordinates(x, 6)
        out = sp.zeros(4, 4)
        out[:3, :3] = hat3(x[:3])
        out[0, 3], out[1, 3], out[2, 3] = x[3], x[4], x[5]
        return out

    def log_coordinates(self, M):
        """(ω, V(ω)⁻¹u) for M = [[R, u], [0, 1]], ω = log R (:func:`so3_log`)."""
        w = so3_log(M[:3, :3])
        return np.concatenate([w, np.asarray(_se3_v_inverse()(w), float) @ M[:3, 3]])

    @staticmethod
    def _V(w):
        """I + B(θ²) ω̂ + C(θ²) ω̂², C = (θ − sin θ)/θ³."""
        th2 = w[0] ** 2 + w[1] ** 2 + w[2] ** 2
        W = hat3(w)
        return (sp.eye(3) + OneMinusCosOverTheta2(th2) * W
                + ThetaMinusSinOverTheta3(th2) * W * W)

    @staticmethod
    def _V_inverse(w):
        """I − ω̂/2 + D(θ²) ω̂², D = (1 − (θ/2) cot(θ/2))/θ²."""
        th2 = w[0] ** 2 + w[1] ** 2 + w[2] ** 2
        W = hat3(w)
        return sp.eye(3) - W / 2 + SE3LogCoefficient(th2) * W * W


@functools.cache
def _se3_v_inverse():
    w = sp.symbols("w1:4", real=True)
    return sp.lambdify([w], SE3._V_inverse(w), NUMPY_MODULES)
