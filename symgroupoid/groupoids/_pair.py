"""Euclidean spaces and the pair groupoid Q × Q ⇉ Q (seed 000 §1.1, seed 001 §2.1.1)."""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from .._symbols import latex_name, scalar_symbol
from ._base import Arrow, Groupoid


class EuclideanSpace:
    """The manifold Rⁿ with named coordinates, e.g. ``EuclideanSpace("x y")``.

    ``EuclideanSpace.vector("Gamma", 3)`` names the coordinates Γ₁, Γ₂, Γ₃ of one
    vector quantity.
    """

    def __init__(self, names: str | Sequence[str]):
        if isinstance(names, str):
            names = names.replace(",", " ").split()
        self.names: tuple[str, ...] = tuple(names)
        if not self.names:
            raise ValueError("EuclideanSpace needs at least one coordinate name")
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"repeated coordinate names in {self.names}")
        self.latex = tuple(latex_name(n) for n in self.names)
        self.vector_name: str | None = None

    @classmethod
    def vector(cls, name: str, dim: int) -> EuclideanSpace:
        """Rⁿ whose coordinates are the components ``name_1 … name_n`` of one vector."""
        space = cls([f"{name}_{i + 1}" for i in range(dim)])
        space.vector_name = name
        return space

    @property
    def dim(self) -> int:
        return len(self.names)

    def point(self, offset: int) -> tuple:
        """The named point q_{k+offset}."""
        return tuple(scalar_symbol(s, offset) for s in self.latex)

    def symbols_by_name(self, offset: int) -> dict:
        pts = self.point(offset)
        out = dict(zip(self.names, pts))
        if self.vector_name is not None:
            out[self.vector_name] = sp.Matrix(pts)
        return out

    def __repr__(self) -> str:
        return f"EuclideanSpace({' '.join(self.names)!r})"


def _point(c, dim: int) -> tuple:
    from .._errors import ShapeError

    values = tuple(float(v) for v in (c if hasattr(c, "__len__") else [c]))
    if len(values) != dim:
        raise ShapeError(f"a configuration of this space has {dim} coordinates, got {len(values)}")
    return values


class PairArrow(Arrow):
    """An arrow (q₀, q₁) of a pair groupoid: ``.source`` = q₀, ``.target`` = q₁."""

    @property
    def source(self) -> tuple:
        return self.coords[: len(self.coords) // 2]

    @property
    def target(self) -> tuple:
        return self.coords[len(self.coords) // 2:]


class PairGroupoid(Groupoid):
    """The pair groupoid Q × Q ⇉ Q: α(q₀, q₁) = q₀, β = q₁, (q₀, q₁)(q₁, q₂) = (q₀, q₂).

    Sections: the coordinate fields ∂/∂qʲ, as curves (q, q + t eⱼ).  The α-fibre chart is the
    target point, so a step solves for q_{k+1}; the arrow g_k is (q_{k-1}, q_k).
    """

    def __init__(self, space: EuclideanSpace):
        if not isinstance(space, EuclideanSpace):
            raise TypeError(f"PairGroupoid needs an EuclideanSpace, got {space!r}")
        self.space = space
        self.name = f"pair groupoid of R^{space.dim} ({', '.join(space.names)})"

    @property
    def arrow_dim(self) -> int:
        return 2 * self.space.dim

    @property
    def base_dim(self) -> int:
        return self.space.dim

    @property
    def rank(self) -> int:
        return self.space.dim

    def source(self, a):
        return tuple(a[: self.base_dim])

    def target(self, a):
        return tuple(a[self.base_dim:])

    def multiply(self, a, b):
        return tuple(a[: self.base_dim]) + tuple(b[self.base_dim:])

    def identity(self, q):
        return tuple(q) + tuple(q)

    def inverse(self, a):
        return tuple(a[self.base_dim:]) + tuple(a[: self.base_dim])

    def section_curves(self, q, t):
        n = self.base_dim
        return [tuple(q) + tuple(q[i] + (t if i == j else 0) for i in range(n))
                for j in range(n)]

    def arrow_from(self, q, f):
        return tuple(q) + tuple(f)

    def fibre_of(self, a):
        return tuple(a[self.base_dim:])

    def predict_chart(self, a):
        """Linear extrapolation q_{k+1} ≈ 2 q_k − q_{k−1}."""
        return tuple(2 * b - a0 for a0, b in zip(self.source(a), self.target(a)))

    def arrow_between(self, c0, c1):
        """(q₀, q₁) for points q₀, q₁."""
        c0, c1 = _point(c0, self.base_dim), _point(c1, self.base_dim)
        return tuple(c0) + tuple(c1)

    def configuration_after(self, c0, a):
        return tuple(float(v) for v in self.target(a))

    def named_fibre(self, offset):
        return self.space.point(offset)

    def named_source(self, offset):
        return self.space.point(offset - 1)

    def symbols_by_name(self, offset):
        return self.space.symbols_by_name(offset)

    def view(self, coords):
        return PairArrow(self, coords)

    def __repr__(self) -> str:
        return f"PairGroupoid({self.space!r})"
