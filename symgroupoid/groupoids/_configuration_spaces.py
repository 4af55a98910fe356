"""The configuration spaces of continuous systems: a Euclidean space, a matrix Lie group, or a
product of them, and what a variational discretisation needs of each factor
(docs/conventions.md §21): the velocity of an arrow (q₀, q₁) a step h apart — (q₁ − q₀)/h,
or the body velocity τ⁻¹(g₀⁻¹g₁)/h through the group's retraction τ — and the midpoint of
the curve it moves along; and the pair groupoid Q × Q ⇉ Q the discrete system lives on."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from .._errors import InputTypeError
from ._manifold import GroupManifold, ProductManifold
from ._matrix_groups import MatrixLieGroup
from ._pair import EuclideanSpace, PairGroupoid
from ._product import ProductGroupoid


@dataclass(frozen=True)
class ConfigurationFactor:
    """One factor of Q: a Euclidean space or a matrix Lie group."""

    space: object

    @property
    def is_group(self) -> bool:
        return isinstance(self.space, MatrixLieGroup)

    @property
    def dim(self) -> int:
        return self.space.rank if self.is_group else self.space.dim

    def velocity(self, a, b, h):
        """v = (b − a)/h, or ξ = τ⁻¹(a⁻¹b)/h on a group."""
        if not self.is_group:
            return (sp.Matrix(list(b)) - sp.Matrix(list(a))) / h
        G = self.space
        inverse = G.matrix(G.inverse(G.entries(a)))
        return sp.Matrix(G.retraction_inverse(inverse * b)) / h

    def point(self, a):
        return a if self.is_group else sp.Matrix(list(a))

    def increment(self, a, b) -> sp.Matrix:
        """The chart value of b seen from a: b − a, or τ⁻¹(a⁻¹b) on a group (the
        coordinates the Galerkin curve of docs/conventions.md §22 is a polynomial in)."""
        if not self.is_group:
            return sp.Matrix(list(b)) - sp.Matrix(list(a))
        G = self.space
        return sp.Matrix(G.retraction_inverse(G.matrix(G.inverse(G.entries(a))) * b))

    def along(self, a, x: sp.Matrix):
        """The configuration at chart value x from a: a + x, or a·τ(x) on a group."""
        if not self.is_group:
            return sp.Matrix(list(a)) + x
        return a * self.space.tau(list(x))

    def chart_velocity(self, x: sp.Matrix, xdot: sp.Matrix) -> sp.Matrix:
        """The velocity of a curve in the chart at x with chart velocity ẋ: ẋ, or the body
        velocity dτ_x(ẋ) on a group (the left-trivialised tangent of the retraction)."""
        if not self.is_group:
            return xdot
        return self.space.dtau(list(x), "left") * xdot

    def midpoint(self, a, b, v, h):
        """(a + b)/2, or a·τ(hξ/2) on a group."""
        if not self.is_group:
            return (sp.Matrix(list(a)) + sp.Matrix(list(b))) / 2
        return a * self.space.tau(list(h * v / 2))


def configuration_factors(Q) -> tuple[list[ConfigurationFactor], bool]:
    """The factors of Q and whether Q is a product (its configurations are tuples)."""
    if isinstance(Q, (EuclideanSpace, MatrixLieGroup)):
        return [ConfigurationFactor(Q)], False
    items = Q.factors if isinstance(Q, ProductGroupoid) else Q
    if isinstance(Q, ProductManifold):  # Q1 * Q2 of spaces and groups: its groups unwrapped
        items = [f.group if isinstance(f, GroupManifold) else f for f in Q.factors]
    if isinstance(items, (str, bytes)) or not isinstance(items, Sequence) or not items:
        raise InputTypeError(f"ContinuousSystem: Q must be a EuclideanSpace, a matrix Lie "
                             f"group (SO2, SO3, SE2, SE3) or a product of them (a "
                             f"product Q1 * Q2, or a list of factors); got "
                             f"{type(Q).__name__} {Q!r}")
    factors = []
    for i, item in enumerate(items):
        if not isinstance(item, (EuclideanSpace, MatrixLieGroup)):
            raise InputTypeError(f"ContinuousSystem: factor {i} of Q must be a EuclideanSpace "
                                 f"or a matrix Lie group; got {type(item).__name__} {item!r}")
        factors.append(ConfigurationFactor(item))
    return factors, True


def pair_groupoid_of(Q, factors: list[ConfigurationFactor], product: bool):
    """Q × Q ⇉ Q as the library writes it, and a reader arrow → [(a_i, b_i)] per factor."""
    if not product:
        return PairGroupoid(factors[0].space), lambda g: [(g.source, g.target)]
    if all(f.is_group for f in factors):
        space = Q if isinstance(Q, ProductGroupoid) else ProductGroupoid(
            *[f.space for f in factors])
        return PairGroupoid(space), lambda g: list(zip(g.source, g.target))
    G = ProductGroupoid(*[PairGroupoid(f.space) for f in factors])
    return G, lambda g: [(g[i].source, g[i].target) for i in range(len(factors))]


__all__ = ["ConfigurationFactor", "configuration_factors", "pair_groupoid_of"]
