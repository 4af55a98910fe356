"""The pair groupoid of a matrix Lie group K, presented as the action groupoid K × K ⇉ K of
right multiplication: an arrow is (q₀, F) with α = q₀, β = q₀·F, (q₀, F)(q₀F, F′) = (q₀, FF′).
Arrows are determined by their source and target, so this is the pair groupoid of K in a
different chart of its α-fibres; the reductions tested with it use only α and β."""

from __future__ import annotations

import sympy as sp

import symgroupoid as sg


class LieGroupPair(sg.ActionGroupoid):
    """K × K ⇉ K; base points are the free matrix entries of q (named ``<point>_ij``)."""

    def __init__(self, group_cls: type, point: str = "R", increment: str = "F"):
        K = group_cls(increment)
        names = [f"{point}_{i + 1}{j + 1}" for i, j in K._free]
        super().__init__(sg.EuclideanSpace(names), K,
                         lambda p, F: tuple(K.entries(K.matrix(p) * F)))
        self.name = f"pair groupoid of {K.group_name}"

    def random_base_point(self, rng):
        x = [sp.Float(v) for v in rng.uniform(-1.0, 1.0, self.group.rank)]
        return tuple(float(v) for v in self.group.fibre_chart(x))


def point_matrix(G: LieGroupPair, q) -> sp.Matrix:
    """The matrix of a base point (flat entries)."""
    return G.group.matrix(tuple(q))
