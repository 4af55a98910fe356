"""Atiyah (gauge) groupoids (Q × Q)/H ⇉ Q/H of a trivial principal bundle Q = H × S → S.

For a free action of a matrix Lie group H on Q = H × S (S a shape space, Rᵈ here) the
quotient of the pair groupoid by the diagonal action is a Lie groupoid over S (seed 002,
"Atiyah or gauge groupoids"): α[(q₀, q₁)] = s₀, β[(q₀, q₁)] = s₁,
[(q₀, q₁)][(q₁, q₂)] = [(q₀, q₂)].  Trivialising by the H factor, an orbit [(q₀, q₁)] is
(s₀, s₁, W) with the invariant

    left action  h·(h′, s) = (hh′, s):   W = h₀⁻¹h₁ (body increment),   product W W′;
    right action (h′, s)·h = (h′h, s):   W = h₁h₀⁻¹ (spatial increment), product W′ W.

Both are written with one product W ⋆ W′ (H for the left action, the opposite group for the
right one), so all the structure maps below are derived, never typed: ε(s) = (s, s, I),
(s₀, s₁, W)⁻¹ = (s₁, s₀, W⁻¹).

Connection-adapted (locked-frame) chart.  Given a discrete connection 𝒜: S × S → H with
𝒜(s, s) = I, the arrow is written (s₀, s₁, W̃) with W̃ = W ⋆ 𝒜(s₀, s₁).  Then

    (s₀, s₁, W̃)(s₁, s₂, W̃′) = (s₀, s₂, W̃ ⋆ 𝒜₀₁⁻¹ ⋆ W̃′ ⋆ 𝒜₁₂⁻¹ ⋆ 𝒜₀₂),
    (s₀, s₁, W̃)⁻¹ = (s₁, s₀, 𝒜₀₁ ⋆ W̃⁻¹ ⋆ 𝒜₁₀),

the sections of the algebroid TS ⊕ 𝔥 are the curves (s, s + t e_j, I) — horizontal for the
connection — and (s, s, τ(tE_a)).  For Elroy's beanie (H = SE(2), S = S¹,
𝒜(ψ₀, ψ₁) = exp(c(ψ₁ − ψ₀)E_θ), c = I₂/(I₁ + I₂)) this is the twisted product
(ψ₀, ψ₁, u, Ω₃)(ψ₁, ψ₂, u′, Ω₃′) = (ψ₀, ψ₂, u + R(Ω₃ − cΔψ)u′, Ω₃ + Ω₃′) of seed 002,
derived here from 𝒜.  Conventions: docs/conventions.md §13.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .._arguments import callable_argument, choice_argument, name_argument, shown_value
from .._errors import CallableError, DomainError, InputTypeError, ShapeError, SymgroupoidError
from ._base import Arrow, Groupoid
from ._manifold import GroupManifold, ProductManifold
from ._matrix_groups import MatrixLieGroup
from ._pair import EuclideanSpace

ACTIONS = ("left", "right")


def manifold_factors(Q) -> list:
    """The factors of a configuration manifold Q given as a factor, a sequence of factors, or
    an object with ``.factors`` (a product)."""
    if isinstance(Q, (list, tuple)):
        out: list = []
        for f in Q:
            out.extend(manifold_factors(f))
        return out
    factors = getattr(Q, "factors", None)  # a product's tuple (not, e.g., Rational.factors)
    if isinstance(factors, (list, tuple)) and not isinstance(Q, (MatrixLieGroup, EuclideanSpace)):
        return manifold_factors(tuple(factors))
    if isinstance(Q, GroupManifold):  # a group as a factor of a product manifold
        return [Q.group]
    return [Q]


def _factor_dim(f) -> int:
    if isinstance(f, MatrixLieGroup):
        return f.arrow_dim
    if isinstance(f, EuclideanSpace):
        return f.dim
    raise InputTypeError(f"AtiyahGroupoid: a factor of Q must be a matrix Lie group or an "
                         f"EuclideanSpace, got {type(f).__name__} {shown_value(f)}")


class AtiyahArrow(Arrow):
    """An arrow (s₀, s₁, W̃): ``.source`` = s₀, ``.target`` = s₁, ``.matrix`` = W̃ (in the
    groupoid's chart), ``.group`` its group view (``.rotation``, ``.translation``,
    ``.coordinates``), ``.increment`` = W = W̃ ⋆ 𝒜(s₀, s₁)⁻¹ (the orbit's invariant)."""

    @property
    def source(self) -> tuple:
        return self.coords[: self.groupoid.base_dim]

    @property
    def target(self) -> tuple:
        d = self.groupoid.base_dim
        return self.coords[d: 2 * d]

    @property
    def group(self):
        return self.groupoid.group.view(self.coords[2 * self.groupoid.base_dim:])

    @property
    def matrix(self) -> sp.Matrix:
        return self.group.matrix

    @property
    def coordinates(self) -> sp.Matrix:
        return self.group.coordinates

    @property
    def increment(self) -> sp.Matrix:
        G = self.groupoid
        return G.untwist(self.source, self.target, self.matrix)


class AtiyahGroupoid(Groupoid):
    """The Atiyah groupoid (Q × Q)/H ⇉ S of Q = H × S (see the module docstring).

    Parameters
    ----------
    Q : the configuration manifold: a sequence of factors (one matrix Lie group of the kind
        H, the others EuclideanSpaces forming the shape space S), or a product of them.
    H : the acting group: a MatrixLieGroup class (``sg.SE2``) or the factor itself.
    action : ``"left"`` (h·(h′, s) = (hh′, s)) or ``"right"`` ((h′, s)·h = (h′h, s)).
    connection : optional discrete connection ``𝒜(s0, s1)`` (tuples of S coordinates) for
        the connection-adapted chart: an element of H (a matrix) or Lie-algebra coordinates
        (mapped by the exponential); 𝒜(s, s) must be the identity.  Its free symbols (e.g.
        c = I₂/(I₁+I₂)) are parameters of the structure maps.
    """

    def __init__(self, Q, H, action: str = "left", connection: Callable | None = None,
                 name: str | None = None):
        choice_argument(action, ACTIONS, "action", owner="AtiyahGroupoid")
        callable_argument(connection, "connection", owner="AtiyahGroupoid", none=True)
        if name is not None:
            name_argument(name, "name", owner="AtiyahGroupoid")
        self.configuration_space = Q
        self.action = action
        factors = manifold_factors(Q)
        self.group, self._h_slice, s_factors, self._s_index = self._split_factors(factors, H)
        names = [n for f in s_factors for n in f.names]
        self.shape_space = EuclideanSpace(names) if names else None
        self.configuration_dim = sum(_factor_dim(f) for f in factors)
        self.name = name or (f"({' × '.join(_label(f) for f in factors)})² / "
                             f"{self.group.group_name} ({action})")
        self._connection = connection
        self._A = None if connection is None else self._connection_template(connection)

    # --- construction -------------------------------------------------------------------------
    @staticmethod
    def _split_factors(factors: list, H):
        def is_h(f) -> bool:
            if isinstance(H, type):
                return isinstance(f, H)
            return f is H or (isinstance(H, MatrixLieGroup) and type(f) is type(H)
                              and isinstance(f, MatrixLieGroup))

        hits = [i for i, f in enumerate(factors) if is_h(f)]
        shown = getattr(H, "__name__", repr(H))
        if len(hits) != 1:
            raise ShapeError(f"AtiyahGroupoid: Q must have exactly one factor of the acting "
                             f"group {shown}; found {len(hits)} among "
                             f"{[_label(f) for f in factors]}")
        offsets, pos = [], 0
        for f in factors:
            offsets.append(pos)
            pos += _factor_dim(f)
        i = hits[0]
        group = factors[i]
        s_factors = [f for j, f in enumerate(factors) if j != i]
        for f in s_factors:
            if not isinstance(f, EuclideanSpace):
                raise InputTypeError(f"AtiyahGroupoid: the shape space must be a product of "
                                     f"EuclideanSpaces; {_label(f)} is not one")
        s_index = [offsets[j] + k for j, f in enumerate(factors) if j != i
                   for k in range(f.dim)]
        return group, slice(offsets[i], offsets[i] + group.arrow_dim), s_factors, s_index

    def _connection_template(self, connection: Callable) -> tuple:
        d = self.base_dim
        s0 = tuple(sp.Dummy(f"s0_{i}", real=True) for i in range(d))
        s1 = tuple(sp.Dummy(f"s1_{i}", real=True) for i in range(d))
        A = self._connection_value(connection, s0, s1)
        self._check_in_group(A, set(s0) | set(s1))
        at_diagonal = A.xreplace(dict(zip(s1, s0)))
        if any(sp.simplify(e) != 0 for e in at_diagonal - sp.eye(self.group.n)):
            raise DomainError(f"{self.name}: the connection must satisfy 𝒜(s, s) = I; got "
                              f"{at_diagonal.tolist()}")
        return s0, s1, A

    def _check_in_group(self, A: sp.Matrix, shape: set) -> None:
        """A :class:`DomainError` unless the connection's values lie in H at three random
        points (its free symbols drawn in (−1, 1), parameters in (1/2, 3/2)): the entries H
        fixes as the identity's, and a rotation block Q with QᵀQ = I and det Q > 0."""
        G, rng = self.group, np.random.default_rng(0)
        free = sorted(A.free_symbols, key=str)
        fixed = [(i, j) for i in range(G.n) for j in range(G.n) if (i, j) not in G._free]
        m = G.rotation_block
        for _ in range(3):
            sub = {x: rng.uniform(-1.0, 1.0) if x in shape else rng.uniform(0.5, 1.5)
                   for x in free}
            try:
                M = np.array(A.xreplace(sub).evalf().tolist(), dtype=float)
            except (TypeError, ValueError):
                return  # not numeric at these values: left to the axioms' check
            if not np.all(np.isfinite(M)):
                continue
            Q = M[:m, :m]
            scale = 1.0 + float(np.abs(M).max())
            bad = [f"entry ({i + 1}, {j + 1}) is {M[i, j]:.6g}, not {int(i == j)}"
                   for i, j in fixed if abs(M[i, j] - (i == j)) > 1e-9 * scale]
            if m and (np.abs(Q.T @ Q - np.eye(m)).max() > 1e-9 * scale ** 2
                      or np.linalg.det(Q) <= 0):
                bad.append("its rotation block is not a rotation (QᵀQ ≠ I or det Q ≤ 0)")
            if bad:
                shown = np.round(M, 4).tolist()
                raise DomainError(f"{self.name}: the connection must take values in "
                                  f"{G.group_name}; at a random point it is {shown}: "
                                  f"{'; '.join(bad)}")

    def _connection_value(self, connection: Callable, s0, s1) -> sp.Matrix:
        G = self.group
        try:
            value = connection(tuple(s0), tuple(s1))
        except SymgroupoidError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise CallableError(f"{self.name}: the connection raised {type(exc).__name__}: "
                                f"{exc}") from exc
        if isinstance(value, sp.MatrixBase) and value.shape == (G.n, G.n):
            return sp.Matrix(value)
        coords = list(value)
        if len(coords) != G.rank:
            raise ShapeError(f"{self.name}: the connection must return a {G.n}×{G.n} element "
                             f"of {G.group_name} or {G.rank} Lie-algebra coordinates; got "
                             f"{value!r}")
        return sp.Matrix(G.exp([sp.sympify(c) for c in coords]))

    # --- sizes --------------------------------------------------------------------------------
    @property
    def base_dim(self) -> int:
        return 0 if self.shape_space is None else self.shape_space.dim

    @property
    def arrow_dim(self) -> int:
        return 2 * self.base_dim + self.group.arrow_dim

    @property
    def rank(self) -> int:
        return self.base_dim + self.group.rank

    # --- the group product of the quotient (H, or its opposite for the right action) ----------
    def star(self, A: sp.Matrix, B: sp.Matrix) -> sp.Matrix:
        """A ⋆ B: A·B for the left action, B·A for the right one."""
        return A * B if self.action == "left" else B * A

    def _inv(self, A: sp.Matrix) -> sp.Matrix:
        return self.group._inverse_matrix(A)

    def connection(self, s0: Sequence, s1: Sequence) -> sp.Matrix:
        """𝒜(s₀, s₁) (the identity without a connection)."""
        if self._A is None:
            return sp.eye(self.group.n)
        t0, t1, A = self._A
        return A.xreplace(dict(zip(t0 + t1, tuple(s0) + tuple(s1))))

    @functools.cached_property
    def _transport_template(self) -> tuple:
        """K(s₀, s₁, s₂) = 𝒜₁₂⁻¹ ⋆ 𝒜₀₂, simplified once (trigonometric identities)."""
        d = self.base_dim
        s = [tuple(sp.Dummy(f"s{i}_{j}", real=True) for j in range(d)) for i in range(3)]
        K = self.star(self._inv(self.connection(s[1], s[2])), self.connection(s[0], s[2]))
        return s, K.applyfunc(lambda e: sp.trigsimp(sp.expand_trig(e)))

    def twist(self, s0: Sequence, s1: Sequence, W: sp.Matrix) -> sp.Matrix:
        """W̃ = W ⋆ 𝒜(s₀, s₁) (the chart of the connection)."""
        return W if self._A is None else self.star(W, self.connection(s0, s1))

    def untwist(self, s0: Sequence, s1: Sequence, Wt: sp.Matrix) -> sp.Matrix:
        """W = W̃ ⋆ 𝒜(s₀, s₁)⁻¹."""
        return Wt if self._A is None else self.star(Wt, self._inv(self.connection(s0, s1)))

    # --- structure maps -------------------------------------------------------------------------
    def _split(self, a: Sequence) -> tuple:
        d = self.base_dim
        return tuple(a[:d]), tuple(a[d:2 * d]), self.group.matrix(tuple(a[2 * d:]))

    def _join(self, s0: Sequence, s1: Sequence, W: sp.Matrix) -> tuple:
        return tuple(s0) + tuple(s1) + tuple(self.group.entries(W))

    def source(self, a):
        return tuple(a[: self.base_dim])

    def target(self, a):
        d = self.base_dim
        return tuple(a[d: 2 * d])

    def multiply(self, a, b):
        s0, s1, W = self._split(a)
        _, s2, W2 = self._split(b)
        if self._A is None:
            return self._join(s0, s2, self.star(W, W2))
        s, K = self._transport_template
        K = K.xreplace(dict(zip(s[0] + s[1] + s[2], tuple(s0) + tuple(s1) + tuple(s2))))
        inner = self.star(self.star(W, self._inv(self.connection(s0, s1))), W2)
        return self._join(s0, s2, self.star(inner, K))

    def identity(self, q):
        return tuple(q) + tuple(q) + tuple(self.group.identity(()))

    def inverse(self, a):
        s0, s1, W = self._split(a)
        if self._A is None:
            return self._join(s1, s0, self._inv(W))
        Wi = self.star(self.star(self.connection(s0, s1), self._inv(W)),
                       self.connection(s1, s0))
        return self._join(s1, s0, Wi)

    def section_curves(self, q, t):
        d = self.base_dim
        unit = tuple(self.group.identity(()))
        shape = [tuple(q) + tuple(q[i] + (t if i == j else 0) for i in range(d)) + unit
                 for j in range(d)]
        vertical = [tuple(q) + tuple(q) + tuple(h) for h in self.group.section_curves((), t)]
        return shape + vertical

    # --- fibres and charts --------------------------------------------------------------------
    def arrow_from(self, q, f):
        return tuple(q) + tuple(f)

    def fibre_of(self, a):
        return tuple(a[self.base_dim:])

    def _fibre_parts(self, f):
        d = self.base_dim
        return tuple(f[:d]), tuple(f[d:])

    def fibre_chart(self, x, source=None):
        s1, xi = self._fibre_parts(x)
        return s1 + tuple(self.group.fibre_chart(xi))

    def chart_of_fibre(self, f, source=None):
        s1, w = self._fibre_parts(f)
        return s1 + tuple(self.group.chart_of_fibre(w))

    def fibre_chart_inverse(self, f, source=None):
        s1, w = self._fibre_parts(f)
        return tuple(float(v) for v in s1) + tuple(self.group.fibre_chart_inverse(w))

    def predict_chart(self, a):
        """s_{k+1} ≈ 2s_k − s_{k−1}; the group part repeats W̃_k."""
        s0, s1 = self.source(a), self.target(a)
        w = tuple(a[2 * self.base_dim:])
        return (tuple(2 * b - c for b, c in zip(s1, s0))
                + tuple(self.group.chart_of_fibre(w)))

    def matrix_parts(self):
        return [(2 * self.base_dim, self.group)]

    def named_groups(self) -> dict:
        return {self.group.symbol_name: self.group}

    # --- naming -------------------------------------------------------------------------------
    def _point(self, offset: int) -> tuple:
        return () if self.shape_space is None else self.shape_space.point(offset)

    def named_fibre(self, offset):
        return self._point(offset) + tuple(self.group.named_fibre(offset))

    def named_source(self, offset):
        return self._point(offset - 1)

    def named_chart(self, offset):
        return self._point(offset) + tuple(self.group.named_chart(offset))

    def symbols_by_name(self, offset):
        out = {} if self.shape_space is None else self.shape_space.symbols_by_name(offset)
        out.update(self.group.symbols_by_name(offset))
        return out

    def view(self, coords):
        return AtiyahArrow(self, coords)

    # --- the quotient map of the pair groupoid ------------------------------------------------
    def split_configuration(self, q: Sequence) -> tuple[sp.Matrix, tuple]:
        """(h, s) of a point q of Q in flat coordinates (Q's factors concatenated)."""
        q = tuple(q)
        if len(q) != self.configuration_dim:
            raise ShapeError(f"{self.name}: a point of Q has {self.configuration_dim} "
                             f"coordinates, got {len(q)}")
        return self.group.matrix(q[self._h_slice]), tuple(q[i] for i in self._s_index)

    def join_configuration(self, h: sp.Matrix, s: Sequence) -> tuple:
        """The flat coordinates of (h, s) ∈ Q."""
        out: list = [None] * self.configuration_dim
        out[self._h_slice] = list(self.group.entries(h))
        for i, v in zip(self._s_index, s):
            out[i] = v
        return tuple(out)

    def orbit(self, q0: Sequence, q1: Sequence) -> tuple:
        """[(q₀, q₁)] = (s₀, s₁, W ⋆ 𝒜(s₀, s₁)) with W = h₀⁻¹ ⋆ h₁."""
        h0, s0 = self.split_configuration(q0)
        h1, s1 = self.split_configuration(q1)
        return self._join(s0, s1, self.twist(s0, s1, self.star(self._inv(h0), h1)))

    def configuration_after(self, q0: Sequence, a: Sequence) -> tuple:
        """q₁ with [(q₀, q₁)] = a: h₁ = h₀ ⋆ W, s₁ = β(a)."""
        h0, _ = self.split_configuration(q0)
        s0, s1, Wt = self._split(a)
        return self.join_configuration(self.star(h0, self.untwist(s0, s1, Wt)), s1)

    @functools.cached_property
    def quotient_map(self):
        """π: Q × Q → (Q × Q)/H on the pair groupoid of Q (``PairGroupoid(Q)``)."""
        from ._pair import PairGroupoid

        space = self.configuration_space
        if isinstance(space, (list, tuple)):  # Q given as its factors: their product
            factors = manifold_factors(space)
            space = factors[0] if len(factors) == 1 else ProductManifold(*factors)
        try:
            pair = PairGroupoid(space)
        except (TypeError, ValueError) as exc:
            raise InputTypeError(f"{self.name}: cannot build the pair groupoid of Q ({exc}); "
                                 f"build it and use quotient_map_from(pair_groupoid)") from exc
        return self.quotient_map_from(pair)

    def quotient_map_from(self, pair: Groupoid, name: str | None = None):
        """π: P → (Q × Q)/H, g ↦ [(α(g), β(g))], for any presentation P of the pair groupoid
        of Q (an arrow determined by its source and target, points of Q in flat coordinates).

        The section σ(s₀, s₁, W̃) = ((e, s₀), (W, s₁)) is used to pull Lagrangians back; the
        reconstruction lifts each reduced arrow to q₁ = (h₀ ⋆ W, s₁).
        """
        from ._morphism import GroupoidMorphism

        if pair.base_dim != self.configuration_dim:
            raise ShapeError(f"{self.name}: the pair groupoid's base has {pair.base_dim} "
                             f"coordinates, Q has {self.configuration_dim}")

        def pi(g):
            return self.orbit(pair.source(g.coords), pair.target(g.coords))

        def section(a):
            s0, s1, Wt = self._split(a.coords)
            q0 = self.join_configuration(sp.eye(self.group.n), s0)
            q1 = self.join_configuration(self.untwist(s0, s1, Wt), s1)
            return pair.arrow_from(q0, q1)

        exact = self._pair_arrow_is_target(pair)
        valid = exact or self._section_is_valid(pair, section)
        return GroupoidMorphism(pair, self, pi, section=section if valid else None,
                                lift=self._lift(pair) if exact else None,
                                name=name or f"π: pair groupoid of Q → {self.name}")

    def _pair_arrow_is_target(self, pair: Groupoid) -> bool:
        """Whether ``pair.arrow_from(q₀, q₁)`` is the arrow from q₀ to q₁ (at random points)."""
        rng = np.random.default_rng(0)
        try:
            q0, q1 = pair.random_base_point(rng), pair.random_base_point(rng)
            a = pair.arrow_from(q0, q1)
            return bool(np.allclose([float(v) for v in pair.source(a)], q0)
                        and np.allclose([float(v) for v in pair.target(a)], q1))
        except (TypeError, ValueError):
            return False

    def _section_is_valid(self, pair: Groupoid, section: Callable) -> bool:
        """Whether the section's arrow has source (e, s₀) and target (W, s₁) (at a random
        arrow and random parameter values)."""
        from ._morphism import ParameterValues

        rng = np.random.default_rng(1)
        values = ParameterValues(rng=rng)
        a = self.random_arrow(rng)
        s0, s1, Wt = self._split(a)
        try:
            g = section(self.view(a))
            expected = (self.join_configuration(sp.eye(self.group.n), s0),
                        self.join_configuration(self.untwist(s0, s1, Wt), s1))
            got = (pair.source(g), pair.target(g))
            return all(np.allclose(values.numbers(x), values.numbers(y), atol=1e-9)
                       for x, y in zip(got, expected))
        except (TypeError, ValueError):
            return False

    def _lift(self, pair: Groupoid) -> Callable:
        def lift(q0, reduced, params):
            from ._morphism import ParameterValues

            values = ParameterValues(params, strict=True)
            q1 = self.configuration_after(tuple(q0), tuple(reduced))
            return values.numbers(pair.arrow_from(tuple(q0), q1))

        return lift

    def __repr__(self) -> str:
        return f"AtiyahGroupoid({self.name})"


def _label(f) -> str:
    if isinstance(f, EuclideanSpace):
        return f"R^{f.dim} ({', '.join(f.names)})"
    return getattr(f, "name", repr(f))
