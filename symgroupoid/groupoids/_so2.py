"""SO(2), the rotations of the plane (a matrix Lie group; see ``_matrix_groups``)."""

from __future__ import annotations

import sympy as sp

from ._matrix_groups import MatrixLieGroup


class SO2(MatrixLieGroup):
    """Rotations of the plane; so(2) basis E = [[0, −1], [1, 0]]."""

    n = 2
    group_name = "SO2"
    rotation_block = 2

    @classmethod
    def _basis(cls):
        return [sp.Matrix([[0, -1], [1, 0]])]

    def _inverse_matrix(self, M):
        return M.T

    @staticmethod
    def _inverse_closed_form(M):
        return M.T

    @classmethod
    def _exp_closed_form(cls, x):
        th = x[0]
        return sp.Matrix([[sp.cos(th), -sp.sin(th)], [sp.sin(th), sp.cos(th)]])

    def cayley_inverse(self, M):
        # on SO(2): cay⁻¹(R) = 2(R − Rᵀ)/(2 + tr R)
        return self.vee(2 * (M - M.T) / (2 + M.trace())).applyfunc(sp.cancel)

    def log(self, M):
        return sp.Matrix([sp.atan2(M[1, 0], M[0, 0])])
