"""Euclidean spaces and the pair groupoid Q × Q ⇉ Q (seed 000 §1.1, seed 001 §2.1.1).

Q is any configuration manifold the library has (:mod:`symgroupoid.groupoids._manifold`):
Rⁿ, a matrix Lie group, or a product of these.  On a Lie group the arrows carry consecutive
attitudes (R_k, R_{k+1}) and a step solves in retraction coordinates of the increment
R_k⁻¹R_{k+1} — the setting of Lie group variational integrators with attitude-dependent
potentials.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import sympy as sp

from .._arguments import MAX_DIMENSION, integer_argument, name_argument, names_argument
from .._errors import CoordinateNameError, InputTypeError, ShapeError
from .._symbols import (
    alias_words,
    aliased_names,
    latex_name,
    printable_name,
    scalar_symbol,
)
from ._base import Arrow, Groupoid
from ._manifold import Manifold, as_manifold
from ._numerics import PairCoordinate


class EuclideanSpace(Manifold):
    """The manifold Rⁿ with named coordinates, e.g. ``EuclideanSpace("x y")``.

    ``EuclideanSpace.vector("Gamma", 3)`` names the coordinates Γ₁, Γ₂, Γ₃ of one
    vector quantity.  Its chart is the point itself: a step solves for q_{k+1}.
    """

    def __init__(self, names: str | Sequence[str]):
        if isinstance(names, str):
            names = names.replace(",", " ").split()
        self.names: tuple[str, ...] = names_argument(names, "the coordinate names",
                                                     owner="EuclideanSpace")
        if not self.names:
            raise ShapeError("EuclideanSpace needs at least one coordinate name")
        for n in self.names:
            printable_name(n, "the coordinate name", "EuclideanSpace")
        aliased = aliased_names(self.names)
        if aliased is not None:
            raise CoordinateNameError(f"EuclideanSpace: coordinate names {self.names}: "
                                      f"{alias_words(aliased)}; each coordinate needs its "
                                      f"own name")
        self.latex = tuple(latex_name(n) for n in self.names)
        self.vector_name: str | None = None

    @classmethod
    def vector(cls, name: str, dim: int) -> EuclideanSpace:
        """Rⁿ whose coordinates are the components ``name_1 … name_n`` of one vector."""
        name = name_argument(name, "the vector's name", owner="EuclideanSpace.vector")
        dim = integer_argument(dim, "dim", minimum=1, maximum=MAX_DIMENSION,
                               owner="EuclideanSpace.vector")
        space = cls([f"{name}_{i + 1}" for i in range(dim)])
        space.vector_name = name
        return space

    @property
    def dim(self) -> int:
        return len(self.names)

    @property
    def coords_dim(self) -> int:
        return len(self.names)

    def point(self, offset: int) -> tuple:
        """The named point q_{k+offset}."""
        return tuple(scalar_symbol(s, offset) for s in self.latex)

    def named_chart(self, offset: int) -> tuple:
        return self.point(offset)

    def symbols_by_name(self, offset: int) -> dict:
        pts = self.point(offset)
        out = dict(zip(self.names, pts))
        if self.vector_name is not None:
            out[self.vector_name] = sp.Matrix(pts)
        return out

    def curves(self, q, t):
        n = self.dim
        return [tuple(q[i] + (t if i == j else 0) for i in range(n)) for j in range(n)]

    def tangent_nodes(self, g, q):
        n = self.dim
        return [[g.one if i == j else g.zero for i in range(n)] for j in range(n)]

    def chart(self, q, x):
        return tuple(x)

    def chart_inverse(self, q, p):
        return tuple(p)

    def numeric_chart(self, q, x):
        return np.asarray(x, float)

    def numeric_chart_inverse(self, q, p):
        return np.asarray(p, float)

    def point_geodesic(self, q0, q1, s):
        """The segment q₀ + s(q₁ − q₀), one row per entry of ``s``."""
        a, b = np.asarray(q0, float), np.asarray(q1, float)
        with np.errstate(over="ignore", invalid="ignore"):  # ends near ±1e308: the caller
            # refuses the non-finite path by name
            return a + np.outer(s, b - a)

    def predict(self, q0, q1):
        """Linear extrapolation q_{k+1} ≈ 2 q_k − q_{k−1}."""
        return tuple(2 * b - a for a, b in zip(q0, q1))

    def view_point(self, coords):
        return tuple(coords)

    def random_point(self, rng):
        return tuple(float(v) for v in rng.uniform(-1.0, 1.0, self.dim))

    def numeric_point(self, c):
        return _point(c, self.dim)

    def __repr__(self) -> str:
        return f"EuclideanSpace({' '.join(self.names)!r})"


def _point(c, dim: int) -> tuple:
    from .._errors import ShapeError

    values = tuple(float(v) for v in (c if hasattr(c, "__len__") else [c]))
    if len(values) != dim:
        raise ShapeError(f"a configuration of this space has {dim} coordinates, got {len(values)}")
    return values


class PairArrow(Arrow):
    """An arrow (q₀, q₁) of a pair groupoid: ``.source`` = q₀, ``.target`` = q₁ (a tuple of
    coordinates on Rⁿ, a matrix on a Lie group, a tuple of parts on a product)."""

    @property
    def source(self):
        G = self.groupoid
        return G.space.view_point(self.coords[: G.base_dim])

    @property
    def target(self):
        G = self.groupoid
        return G.space.view_point(self.coords[G.base_dim:])


class PairGroupoid(Groupoid):
    """The pair groupoid Q × Q ⇉ Q: α(q₀, q₁) = q₀, β = q₁, (q₀, q₁)(q₁, q₂) = (q₀, q₂).

    Q: an :class:`EuclideanSpace`, a matrix Lie group (``SO3("R")``), or a product of these
    (``SE2("g") * EuclideanSpace("psi")``).  Sections: a basis of TQ as curves
    (q, c_j(t)) — the coordinate fields ∂/∂qʲ on Rⁿ, q·τ(tE_a) on a group.  The α-fibre of q
    is charted by Q's chart around q: on Rⁿ the target point itself (a step solves for
    q_{k+1}); on a group q·τ(x) (a step solves for τ⁻¹(q_k⁻¹q_{k+1})).  The arrow g_k is
    (q_{k-1}, q_k).
    """

    def __init__(self, space):
        try:
            self.space = as_manifold(space)
        except InputTypeError as exc:
            raise InputTypeError(f"PairGroupoid needs a configuration manifold: {exc}") \
                from None
        names = ", ".join(getattr(self.space, "names", ()))
        if isinstance(self.space, EuclideanSpace):
            self.name = f"pair groupoid of R^{self.space.dim} ({names})"
        else:
            self.name = f"pair groupoid of {self.space!r}"

    @property
    def arrow_dim(self) -> int:
        return 2 * self.space.coords_dim

    @property
    def base_dim(self) -> int:
        return self.space.coords_dim

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
        return [tuple(q) + tuple(c) for c in self.space.curves(tuple(q), t)]

    def arrow_from(self, q, f):
        return tuple(q) + tuple(f)

    def field_nodes(self, g, side, coords, parameters=None):
        """Closed form of the fields of (q₀, q₁): m(a, h_b(t)) = (q₀, c_b(t)) with c_b the
        space's curves at q₁, so X⃖_b = (0, ċ_b(0)); m(h_b(t)⁻¹, a) = (c_b(t), q₁) with c_b
        at q₀, so X⃗_b = (−ċ_b(0), 0) — the tangent basis of the space
        (:meth:`Manifold.tangent_nodes`) padded with zeros."""
        n = self.base_dim
        coords = list(coords)
        if side == "left":
            return [[g.zero] * n + v for v in self.space.tangent_nodes(g, coords[n:])]
        return [[g.neg(c) for c in v] + [g.zero] * n
                for v in self.space.tangent_nodes(g, coords[:n])]

    def fibre_of(self, a):
        return tuple(a[self.base_dim:])

    def _source_or_fail(self, source):
        if source is None:
            if isinstance(self.space, EuclideanSpace):
                return (0,) * self.base_dim
            raise ValueError(f"{self.name}: the fibre chart needs the source point")
        return tuple(source)

    def fibre_chart(self, x, source=None):
        return tuple(self.space.chart(self._source_or_fail(source), tuple(x)))

    def chart_of_fibre(self, f, source=None):
        return tuple(self.space.chart_inverse(self._source_or_fail(source), tuple(f)))

    def renormalised_fibre(self, f):
        return self.space.renormalised(tuple(f))

    def numeric_fibre_arrow(self, q, x):
        """(q, q·τ(x)) on a group, (q, x) on Rⁿ: the space's chart, numerically."""
        q = tuple(float(v) for v in q)
        return q + tuple(float(v) for v in self.space.numeric_chart(q, x))

    def fibre_chart_inverse(self, f, source=None):
        q = self._source_or_fail(source)
        return tuple(float(v) for v in self.space.numeric_chart_inverse(q, tuple(f)))

    def predict_chart(self, a):
        """Constant velocity: q_{k+1} ≈ 2 q_k − q_{k−1} on Rⁿ, q_k q_{k−1}⁻¹ q_k on a group."""
        return tuple(self.space.predict(self.source(a), self.target(a)))

    def arrow_between(self, c0, c1):
        """(q₀, q₁) for configurations q₀, q₁ (points; matrices on a group)."""
        return tuple(self.space.numeric_point(c0)) + tuple(self.space.numeric_point(c1))

    def increments(self, a):
        return self.space.increments(self.source(a), self.target(a))

    def configurations_along(self, arrows, start=None):
        """The points q_0, q_1, …, q_N the arrows (q_k, q_{k+1}) hold (``start``, if given,
        must be q_0), stacked by :meth:`Manifold.stacked_points`."""
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        d = self.base_dim
        coords = np.vstack([arrows[:1, :d], arrows[:, d:]])
        _check_start(self, start, coords[0])
        return self.space.stacked_points(coords)

    def spatial_momenta(self, momenta, arrows, start=None):
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        _check_start(self, start, arrows[0, :self.base_dim])
        return self.space.body_to_spatial(momenta, arrows[:, :self.base_dim])

    def configuration_after(self, c0, a):
        target = tuple(float(v) for v in self.target(a))
        if isinstance(self.space, EuclideanSpace):
            return target
        return _numeric_view(self.space, target)

    def named_fibre(self, offset):
        return self.space.point(offset)

    def named_source(self, offset):
        return self.space.point(offset - 1)

    def named_chart(self, offset):
        return self.space.named_chart(offset)

    def symbols_by_name(self, offset):
        return self.space.symbols_by_name(offset)

    def configuration(self, value, name, check):
        """A point of the manifold (ℝⁿ: n numbers; a Lie group: a group element; a product:
        one point per factor)."""
        return self.space.configuration(value, name, check)

    def geodesic(self, total, s):
        """ℝⁿ: the straight segment (q₀, q₀ + s(q₁ − q₀)); a matrix Lie group, or a product
        of them and of ℝⁿ: (q₀, q₀·exp(s log(q₀⁻¹q₁))) on each group factor (through
        half-turns, where the Cayley chart of q₀⁻¹q₁ is singular), the segment on the others;
        other manifolds: the chart path."""
        q0, q1 = total[:self.base_dim], total[self.base_dim:]
        points = self.space.point_geodesic(q0, q1, np.asarray(s, float))
        if points is None:
            return self.chart_path(total, s)
        return np.hstack([np.tile(np.asarray(q0, float), (len(s), 1)), points])

    def pair_coordinates(self):
        """ℝⁿ: coordinate i at positions i (source) and n + i (target)."""
        if not isinstance(self.space, EuclideanSpace):
            return []
        n = self.base_dim
        return [PairCoordinate(i, n + i, self.space.names[i]) for i in range(n)]

    def named_groups(self):
        return {name: group for name, (_, group) in self.space.groups().items()}

    def base_groups(self):
        return self.named_groups()

    def random_base_point(self, rng):
        return self.space.random_point(rng)

    def view(self, coords):
        return PairArrow(self, coords)

    def base_view(self, coords):
        return self.space.view_point(tuple(coords))

    def __repr__(self) -> str:
        return f"PairGroupoid({self.space!r})"


def _check_start(groupoid, start, first: np.ndarray) -> None:
    """A given first configuration must be the one the arrows hold (to rounding)."""
    from .._errors import DomainError

    if start is None:
        return
    given = np.asarray(groupoid.space.numeric_point(start) if hasattr(groupoid, "space")
                       else start, float).ravel()
    if given.shape != first.shape or not np.allclose(given, first, rtol=1e-12, atol=1e-12):
        raise DomainError(f"{groupoid.name}: start {np.round(given, 12).tolist()} is not the "
                          f"first configuration the arrows hold, {first.tolist()} (leave "
                          f"start out: the arrows of a pair groupoid hold their "
                          f"configurations)")


def _numeric_view(space, coords):
    """A point with numeric values, as the user writes it (matrices as arrays)."""
    from ._manifold import GroupManifold, ProductManifold

    if isinstance(space, GroupManifold):
        return space.group.numeric_matrix(coords)
    if isinstance(space, ProductManifold):
        parts = space._split(coords, space._coords)
        return tuple(_numeric_view(f, p) for f, p in zip(space.factors, parts))
    return tuple(coords)
