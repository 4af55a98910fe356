"""Configuration manifolds Q of pair groupoids Q × Q ⇉ Q.

A manifold here is what the pair groupoid needs of Q: flat coordinates of a point, named
points at a step, curves through a point along a basis of TQ (the sections of the pair
groupoid's algebroid), and a chart around each point in which a step solves for the next
configuration.

- :class:`~symgroupoid.groupoids.EuclideanSpace` Rⁿ: coordinates are the point; the chart is
  the point itself (a step solves for q_{k+1}).
- :class:`GroupManifold`: a matrix Lie group G as a manifold; coordinates are the free matrix
  entries, curves q·τ(tE_a), and the chart around q is q·τ(x) — a step solves for the
  retraction coordinates of the increment q_k⁻¹q_{k+1} (Lie group variational integrators).
- :class:`ProductManifold`: products, e.g. ``SE2("g") * EuclideanSpace("psi")``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from itertools import accumulate

import numpy as np
import sympy as sp

from .._errors import CoordinateNameError, InputTypeError
from .._symbols import alias_words, aliased_names


class Manifold(ABC):
    """The configuration manifold of a pair groupoid (see the module docstring)."""

    def configuration(self, value, name: str, check):
        """``value`` as a point of this manifold, checked by ``check``
        (:class:`~symgroupoid.groupoids._numerics.ConfigurationChecks`): by default a
        point of ℝⁿ, n = ``coords_dim``."""
        return check.point(value, self.coords_dim, name)

    @property
    @abstractmethod
    def dim(self) -> int:
        """Dimension (the number of chart coordinates)."""

    @property
    @abstractmethod
    def coords_dim(self) -> int:
        """Length of a point's coordinate tuple (≥ dim)."""

    @abstractmethod
    def point(self, offset: int) -> tuple:
        """The named point q_{k+offset} (coordinates as StepSymbols)."""

    @abstractmethod
    def named_chart(self, offset: int) -> tuple:
        """Chart coordinates of q_{k+offset} around q_{k+offset−1} (a step's unknowns)."""

    @abstractmethod
    def symbols_by_name(self, offset: int) -> dict:
        """Named parts of q_{k+offset}: ``{"x": x_{k+offset}}``, ``{"R": Matrix}``, …"""

    @abstractmethod
    def curves(self, q: Sequence, t: sp.Symbol) -> list[tuple]:
        """A basis of T_qQ as curves through q (coordinate tuples in t)."""

    def tangent_nodes(self, g, q: Sequence[int]) -> list[list[int]]:
        """The velocities ċ_b(0) of :meth:`curves` at a point given by nodes of the
        expression graph ``g``: one list of coordinate nodes per basis vector of T_qQ.
        Default: the curves at placeholder coordinates, differentiated in t on the graph."""
        from ..ir import forward, from_sympy

        t = sp.Dummy("t", real=True)
        placeholders = tuple(sp.Dummy(f"q{i}", real=True) for i in range(self.coords_dim))
        symbols = {**dict(zip(placeholders, q)), t: g.input(t)}
        memo: dict = {}
        out = []
        for curve in self.curves(placeholders, t):
            nodes = [from_sympy(g, sp.sympify(c), symbols, "the tangent basis", memo)
                     for c in curve]
            velocity = forward(g, nodes, {symbols[t]: g.one})
            out.append(g.substitute(velocity, {symbols[t]: g.zero}))
        return out

    @abstractmethod
    def chart(self, q: Sequence, x: Sequence) -> tuple:
        """The point with chart coordinates x in the chart around q."""

    def numeric_chart(self, q: Sequence, x: Sequence) -> np.ndarray:
        """:meth:`chart` at numeric q and x (default: SymPy's arithmetic on Floats)."""
        return np.array([float(sp.N(v)) for v in self.chart(tuple(sp.Float(c) for c in q),
                                                             tuple(sp.Float(c) for c in x))])

    @abstractmethod
    def chart_inverse(self, q: Sequence, p: Sequence) -> tuple:
        """Chart coordinates of the point p in the chart around q (symbolic)."""

    @abstractmethod
    def numeric_chart_inverse(self, q: Sequence, p: Sequence) -> np.ndarray:
        """Chart coordinates of p around q, numerically."""

    def point_geodesic(self, q0: Sequence, q1: Sequence, s: np.ndarray) -> np.ndarray | None:
        """Points from q₀ to q₁ along the manifold's geodesic (coordinates, one row per
        entry of ``s`` ∈ [0, 1]), or None where it has none (the caller's chart path)."""
        return None

    @abstractmethod
    def predict(self, q0: Sequence, q1: Sequence) -> tuple:
        """Chart coordinates (around q1) of the configuration after q0, q1 at constant
        velocity: the first Newton guess of a step."""

    def stacked_points(self, coords: np.ndarray):
        """The points with the coordinates of the rows of ``coords`` (N, coords_dim), as
        arrays: Rⁿ (N, n); a matrix group (N, n, n); a product a tuple per factor."""
        return np.asarray(coords, float)

    def body_to_spatial(self, momenta: np.ndarray, coords: np.ndarray) -> np.ndarray:
        """Momenta (N, dim) in the dual of the basis of :meth:`curves` at the points
        ``coords`` (N, coords_dim), in the spatial frame (Rⁿ: as they are)."""
        return np.asarray(momenta, float)

    def increments(self, q0: Sequence, q1: Sequence) -> list:
        """(part name, group, numeric matrix) of each group increment q0⁻¹q1 whose
        retraction coordinates the chart takes (none on Rⁿ); see
        :meth:`~symgroupoid.groupoids.Groupoid.increments`."""
        return []

    @abstractmethod
    def view_point(self, coords: Sequence):
        """The user-facing value of a point (a tuple, a Matrix, or a tuple of parts)."""

    @abstractmethod
    def random_point(self, rng: np.random.Generator) -> tuple:
        """A random point (numeric coordinates)."""

    @abstractmethod
    def numeric_point(self, c) -> tuple:
        """Numeric coordinates of a configuration given as the user writes it (checked)."""

    def groups(self) -> dict:
        """Named matrix-group parts of a point: name → (offset in the coordinates, group)."""
        return {}

    def renormalised(self, p: Sequence) -> tuple:
        """The coordinates p of a computed point pulled back onto Q where they
        over-parametrise it (a matrix group's rotation block: see
        :meth:`MatrixLieGroup.renormalised_matrix`); the identity on Q.  Default: p."""
        return tuple(p)

    def __mul__(self, other):
        return ProductManifold(self, as_manifold(other))

    def __rmul__(self, other):
        return ProductManifold(as_manifold(other), self)


class GroupManifold(Manifold):
    """A matrix Lie group as a manifold; points are group elements (free matrix entries)."""

    def __init__(self, group):
        self.group = group
        self.names = (group.symbol_name,)
        self.latex = (group.latex,)

    def configuration(self, value, name, check):
        """A group element (its matrix)."""
        return check.group_element(self.group, value, name)

    @property
    def dim(self) -> int:
        return self.group.rank

    @property
    def coords_dim(self) -> int:
        return self.group.arrow_dim

    def point(self, offset):
        return self.group.named_fibre(offset)

    def named_chart(self, offset):
        """Retraction coordinates of the increment, (τ⁻¹(R_{k+o−1}⁻¹R_{k+o}))_a."""
        from .._symbols import StepSymbol, subscripted

        G = self.group
        before, now = subscripted(G.latex, offset - 1), subscripted(G.latex, offset)
        return tuple(StepSymbol(f"(\\tau^{{-1}}({before}^{{-1}} {now}))_{{{a + 1}}}")
                     for a in range(self.dim))

    def symbols_by_name(self, offset):
        return self.group.symbols_by_name(offset)

    def curves(self, q, t):
        return [self.group.translated_retraction(q, [t if b == a else 0
                                                     for b in range(self.dim)])
                for a in range(self.dim)]

    def tangent_nodes(self, g, q):
        """ċ_b(0) = q·E_b (τ(tE_b) = I + tE_b + O(t²) for the Cayley map and exp), the free
        entries of the product, on the graph."""
        G = self.group
        M = [[None] * G.n for _ in range(G.n)]
        identity = sp.eye(G.n)
        for i in range(G.n):
            for j in range(G.n):
                M[i][j] = g.const(identity[i, j])
        for (i, j), c in zip(G._free, q):
            M[i][j] = c
        out = []
        for E in G.basis_matrices():
            entries = []
            for i, j in G._free:
                terms = [g.mul(g.const(E[k, j]), M[i][k]) for k in range(G.n) if E[k, j] != 0]
                entries.append(g.add(*terms) if terms else g.zero)
            out.append(entries)
        return out

    def chart(self, q, x):
        return self.group.translated_retraction(q, x)

    def chart_inverse(self, q, p):
        return self.group.increment_coordinates(q, p)

    def numeric_chart(self, q, x):
        G = self.group
        M = G.numeric_matrix([float(v) for v in q]) @ G.numeric_tau(x)
        return G.numeric_coordinates(M)

    def numeric_chart_inverse(self, q, p):
        G = self.group
        M0, M1 = G.numeric_matrix(q), G.numeric_matrix(p)
        return G.numeric_retraction_inverse(np.linalg.solve(M0, M1))

    def point_geodesic(self, q0, q1, s):
        """q₀·exp(s log(q₀⁻¹q₁)): the group's geodesic (through half-turns)."""
        return self.group.point_geodesic(q0, q1, s)

    def predict(self, q0, q1):
        """The increment repeats: q_{k+1} = q_k q_{k−1}⁻¹ q_k, i.e. x = τ⁻¹(q_{k−1}⁻¹q_k)."""
        return self.chart_inverse(q0, q1)

    def stacked_points(self, coords):
        return self.group.numeric_matrices(coords)

    def body_to_spatial(self, momenta, coords):
        """The basis curves q·τ(tE_a) move q on the right: body momenta, Ad*_{q⁻¹}μ."""
        return self.group.body_to_spatial(momenta, self.group.numeric_matrices(coords))

    def increments(self, q0, q1):
        G = self.group
        M0, M1 = G.numeric_matrix([float(v) for v in q0]), G.numeric_matrix(
            [float(v) for v in q1])
        return [(G.symbol_name, G, np.linalg.solve(M0, M1))]

    def view_point(self, coords):
        return self.group.matrix(coords)

    def random_point(self, rng):
        G = self.group
        M = G.numeric_tau(G.random_chart(rng, scale=1.0))
        return tuple(float(M[i, j]) for i, j in G._free)

    def numeric_point(self, c):
        M = self.group._numeric_matrix(c)
        return tuple(float(M[i, j]) for i, j in self.group._free)

    def groups(self):
        return {self.group.symbol_name: (0, self.group)}

    def renormalised(self, p):
        G = self.group
        return G.entries(G.renormalised_matrix(G.matrix(tuple(p))))

    def __repr__(self) -> str:
        return repr(self.group)


def _slices(sizes):
    ends = list(accumulate(sizes))
    return [(e - s, e) for s, e in zip(sizes, ends)]


class ProductManifold(Manifold):
    """Q₁ × ⋯ × Q_n, coordinates concatenated; points are tuples of the factors' points."""

    def __init__(self, *factors):
        flat: list = []
        for f in factors:
            f = as_manifold(f)
            flat.extend(f.factors if isinstance(f, ProductManifold) else [f])
        self.factors = tuple(flat)
        self._coords = _slices([f.coords_dim for f in self.factors])
        self._charts = _slices([f.dim for f in self.factors])
        self.names = tuple(n for f in self.factors for n in f.names)
        aliased = aliased_names(self.names)
        if aliased is not None:
            raise CoordinateNameError(
                f"{' × '.join(map(repr, self.factors))}: two factors name a coordinate alike "
                f"({alias_words(aliased)}); the factors of a product need distinct names "
                f"(e.g. SO3(\"R1\") * SO3(\"R2\"))")

    def point_geodesic(self, q0, q1, s):
        """Each factor along its own geodesic; None when a factor has none."""
        parts = [f.point_geodesic(q0[lo:hi], q1[lo:hi], s)
                 for f, (lo, hi) in zip(self.factors, self._coords)]
        return None if any(p is None for p in parts) else np.hstack(parts)

    def configuration(self, value, name, check):
        """One point per factor, named ``name[i]``."""
        parts = check.pieces(value, len(self.factors), name,
                             f"a configuration of {self!r}, one per factor")
        return tuple(f.configuration(c, f"{name}[{i}]", check)
                     for i, (f, c) in enumerate(zip(self.factors, parts)))

    @property
    def dim(self):
        return sum(f.dim for f in self.factors)

    @property
    def coords_dim(self):
        return sum(f.coords_dim for f in self.factors)

    def _split(self, v, slices):
        return [tuple(v[lo:hi]) for lo, hi in slices]

    def point(self, offset):
        return sum((tuple(f.point(offset)) for f in self.factors), ())

    def named_chart(self, offset):
        return sum((tuple(f.named_chart(offset)) for f in self.factors), ())

    def symbols_by_name(self, offset):
        out: dict = {}
        for f in self.factors:
            out.update(f.symbols_by_name(offset))
        return out

    def curves(self, q, t):
        parts = self._split(q, self._coords)
        out = []
        for i, f in enumerate(self.factors):
            for c in f.curves(parts[i], t):
                out.append(sum((tuple(c) if j == i else parts[j]
                                for j in range(len(parts))), ()))
        return out

    def _pointwise(self, name, q, v, slices_v):
        qs, vs = self._split(q, self._coords), self._split(v, slices_v)
        return sum((tuple(getattr(f, name)(a, b)) for f, a, b in zip(self.factors, qs, vs)),
                   ())

    def tangent_nodes(self, g, q):
        """Each factor's tangent basis, the other factors' coordinates zero."""
        parts = self._split(list(q), self._coords)
        out = []
        for i, f in enumerate(self.factors):
            for v in f.tangent_nodes(g, parts[i]):
                out.append([c for j, part in enumerate(parts)
                            for c in (v if j == i else [g.zero] * len(part))])
        return out

    def chart(self, q, x):
        return self._pointwise("chart", q, x, self._charts)

    def chart_inverse(self, q, p):
        return self._pointwise("chart_inverse", q, p, self._coords)

    def numeric_chart(self, q, x):
        qs, xs = self._split(q, self._coords), self._split(x, self._charts)
        return np.concatenate([np.asarray(f.numeric_chart(a, b), float)
                               for f, a, b in zip(self.factors, qs, xs)])

    def numeric_chart_inverse(self, q, p):
        return np.array(self._pointwise("numeric_chart_inverse", q, p, self._coords), float)

    def renormalised(self, p):
        return sum((f.renormalised(part) for f, part in zip(self.factors,
                                                             self._split(p, self._coords))),
                   ())

    def predict(self, q0, q1):
        return self._pointwise("predict", q0, q1, self._coords)

    def stacked_points(self, coords):
        coords = np.asarray(coords, float)
        return tuple(f.stacked_points(coords[:, lo:hi])
                     for f, (lo, hi) in zip(self.factors, self._coords))

    def body_to_spatial(self, momenta, coords):
        momenta, coords = np.asarray(momenta, float), np.asarray(coords, float)
        return np.hstack([f.body_to_spatial(momenta[:, a:b], coords[:, lo:hi])
                          for f, (lo, hi), (a, b) in zip(self.factors, self._coords,
                                                         self._charts)])

    def increments(self, q0, q1):
        parts = zip(self.factors, self._split(q0, self._coords), self._split(q1, self._coords))
        return [i for f, a, b in parts for i in f.increments(a, b)]

    def view_point(self, coords):
        return tuple(f.view_point(c) for f, c in zip(self.factors,
                                                      self._split(coords, self._coords)))

    def random_point(self, rng):
        return sum((tuple(f.random_point(rng)) for f in self.factors), ())

    def numeric_point(self, c):
        from .._errors import ShapeError

        try:
            parts = list(c)
        except TypeError:
            parts = None
        if parts is None or len(parts) != len(self.factors):
            raise ShapeError(f"a configuration of {self!r} is a tuple of {len(self.factors)} "
                             f"parts, one per factor")
        return sum((tuple(f.numeric_point(p)) for f, p in zip(self.factors, parts)), ())

    def groups(self):
        out = {}
        for f, (lo, _) in zip(self.factors, self._coords):
            out.update({k: (lo + o, g) for k, (o, g) in f.groups().items()})
        return out

    def __repr__(self) -> str:
        return " * ".join(repr(f) for f in self.factors)


def as_manifold(space) -> Manifold:
    """``space`` as a :class:`Manifold`: a manifold, a matrix Lie group, or a product of
    Lie groups (a Lie group itself)."""
    from ._matrix_groups import MatrixLieGroup
    from ._product import ProductGroupoid

    if isinstance(space, Manifold):
        return space
    if isinstance(space, MatrixLieGroup):
        return GroupManifold(space)
    if isinstance(space, ProductGroupoid) and all(isinstance(f, MatrixLieGroup)
                                                  for f in space.factors):
        return ProductManifold(*space.factors)
    raise InputTypeError(f"not a configuration manifold: {space!r} (use EuclideanSpace, a "
                         f"matrix Lie group such as SO3('R'), or a product of these)")
