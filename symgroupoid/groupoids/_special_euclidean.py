"""SE(n) = SO(n) ⋉ ℝⁿ as (n + 1)×(n + 1) matrices [[R, u], [0, 1]]: what SE(2) and
SE(3) share."""

from __future__ import annotations

import sympy as sp

from ._matrix_groups import MatrixLieGroup
from ._matrix_templates import _basis_of


class _SpecialEuclidean(MatrixLieGroup):
    affine = True
    rot: type[MatrixLieGroup]

    @classmethod
    def _split(cls, x):
        r = len(_basis_of(cls.rot))
        return x[:r], x[r:]

    @classmethod
    def hat(cls, x):
        m = cls.n - 1
        w, v = cls._split(cls._hat_coordinates(x, len(_basis_of(cls.rot)) + m))
        out = sp.zeros(cls.n, cls.n)
        out[:m, :m] = cls.rot.hat(w)
        out[:m, m] = sp.Matrix(v)
        return out

    def _inverse_matrix(self, M):
        return self._inverse_closed_form(M)

    @classmethod
    def _inverse_closed_form(cls, M):
        m = cls.n - 1
        R, p = M[:m, :m], M[:m, m]
        out = sp.eye(cls.n)
        out[:m, :m] = R.T
        out[:m, m] = -R.T * p
        return out

    def cayley_inverse(self, M):
        # ω = cay⁻¹(R), v = (I − ω̂/2) p   (block form of 2(g − I)(g + I)⁻¹)
        m = self.n - 1
        R, p = M[:m, :m], M[:m, m]
        w = self.rot("tmp").cayley_inverse(R)
        v = (sp.eye(m) - self.rot.hat(list(w)) / 2) * p
        return sp.Matrix(list(w) + list(v))

    def log(self, M):
        m = self.n - 1
        R, p = M[:m, :m], M[:m, m]
        w = list(self.rot("tmp", retraction="exp").log(R))
        return sp.Matrix(w + list(self._V_inverse(w) * p))

    @classmethod
    def _exp_closed_form(cls, x):
        w, v = cls._split(list(x))
        m = cls.n - 1
        out = sp.eye(cls.n)
        out[:m, :m] = cls.rot._exp_closed_form(w)
        out[:m, m] = cls._V(w) * sp.Matrix(v)
        return out


