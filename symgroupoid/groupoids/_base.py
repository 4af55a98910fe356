"""Lie groupoids given by their structure maps, and the invariant derivations they induce.

A groupoid ``G ⇉ Q`` is described by its source α, target β, multiplication m on composable
pairs, identity ε and inversion i, all acting on *flat coordinate tuples* of SymPy expressions,
plus a basis of sections of its Lie algebroid, each section given as a curve
``h_X(t)`` in the α-fibre through the identity (docs/conventions.md §1):

    X⃖[f](g) =  d/dt f(g · h_X(t))|_{t=0},       h_X(t) ∈ α⁻¹(β(g)),
    X⃗[f](g) = -d/dt f(h_X(t)⁻¹ · g)|_{t=0},     h_X(t) ∈ α⁻¹(α(g))

(seed 000, eqs. (1)–(2)).  The tangent vectors ``d/dt m(g, h_X(t))`` are derived here once,
generically, from the structure maps; no groupoid hand-codes its derivations.

Besides the structure maps a groupoid knows how to *name* its arrows at a step in the papers'
notation and the *chart* of an α-fibre a step is solved in:

- ``arrow_from(q, f)`` builds the arrow with source ``q`` and fibre variables ``f``
  (pair groupoid: the target point; a Lie group: its matrix entries),
- ``fibre_chart(x, q)`` maps chart coordinates to fibre variables of the α-fibre of q (pair
  groupoid of Rⁿ: identity; Lie groups: a retraction τ, Cayley by default; pair groupoid of
  a Lie group: q·τ(x)).
"""

from __future__ import annotations

import functools
from abc import ABC, abstractmethod
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import sympy as sp

from .._arguments import real_argument, real_array
from .._errors import CallableError, InputTypeError, ShapeError, SymgroupoidError
from .._lambdify import NUMPY_MODULES
from .._symbols import scalar_expressions
from ._numerics import GroupoidNumerics

#: the largest |offset| of a named arrow g_{k+offset} (a window spans a few arrows)
MAX_OFFSET = 64

Coords = tuple  # flat tuple of SymPy expressions (or numbers)


class Arrow:
    """User-facing view of a (symbolic) arrow.

    Subclasses add the attributes that the papers use: ``.source``/``.target`` for pair
    groupoids, ``.matrix`` for matrix Lie groups, indexing ``g[i]`` for products.
    """

    def __init__(self, groupoid: Groupoid, coords: Sequence):
        if not isinstance(groupoid, Groupoid):
            raise InputTypeError(f"Arrow: groupoid must be a Groupoid, got "
                                 f"{type(groupoid).__name__}")
        if isinstance(coords, (str, bytes, dict, set)) or not hasattr(coords, "__iter__"):
            raise InputTypeError(f"Arrow: coords must be the arrow's coordinates (a list or "
                                 f"tuple), got {type(coords).__name__}")
        self.groupoid = groupoid
        self.coords = tuple(coords)

    @property
    def alpha(self) -> tuple:
        """Source α(g) as a coordinate tuple of the base."""
        return self.groupoid.source(self.coords)

    @property
    def beta(self) -> tuple:
        """Target β(g) as a coordinate tuple of the base."""
        return self.groupoid.target(self.coords)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} of {self.groupoid.name}: {self.coords}>"


def coordinate_values(name: str, what: str, values: Sequence, sympified: bool = True
                      ) -> tuple:
    """The coordinates a user's map returned, as SymPy expressions (``sympified``, else as
    returned: floats stay floats for the numerics); a string, a truth value (``True``,
    ``q > 0``) or anything else that is not a number or an expression is a
    :class:`ShapeError` naming the map and the entry (not a symbol made of the string's
    text, not a raw error later)."""
    out, bad = scalar_expressions(values)
    if bad is not None:
        value = values[bad]
        kind = "the string" if isinstance(value, (str, bytes)) else type(value).__name__
        raise ShapeError(f"{name}: the {what} returned {kind} {value!r} as coordinate {bad}; "
                         f"a coordinate is a number or a SymPy expression")
    return out if sympified else tuple(values)


class Groupoid(GroupoidNumerics, ABC):
    """Abstract Lie groupoid ``G ⇉ Q`` given by structure maps on flat coordinates.

    A user-defined groupoid subclasses this and implements the structure maps, the section
    curves, ``arrow_from``/``fibre_of`` and the naming hooks.  Everything else (invariant
    derivations, charts, axiom checks) is derived.
    """

    #: human-readable name used in messages and generated code
    name: str = "G"

    # --- dimensions -----------------------------------------------------------------------
    @property
    @abstractmethod
    def arrow_dim(self) -> int:
        """Length of the flat coordinate tuple of an arrow."""

    @property
    @abstractmethod
    def base_dim(self) -> int:
        """Length of the coordinate tuple of a base point."""

    @property
    @abstractmethod
    def rank(self) -> int:
        """Dimension of the α-fibres = rank of AG = number of basis sections."""

    @property
    def fibre_dim(self) -> int:
        """Number of fibre variables (``arrow_from`` takes this many); ≥ rank."""
        return self.arrow_dim - self.base_dim

    # --- structure maps -------------------------------------------------------------------
    @abstractmethod
    def source(self, a: Sequence) -> tuple:
        """α(a)."""

    @abstractmethod
    def target(self, a: Sequence) -> tuple:
        """β(a)."""

    @abstractmethod
    def multiply(self, a: Sequence, b: Sequence) -> tuple:
        """m(a, b) = a·b for β(a) = α(b)."""

    @abstractmethod
    def identity(self, q: Sequence) -> tuple:
        """ε(q)."""

    @abstractmethod
    def inverse(self, a: Sequence) -> tuple:
        """i(a) = a⁻¹."""

    @abstractmethod
    def section_curves(self, q: Sequence, t: sp.Symbol) -> list[tuple]:
        """Basis of sections of AG at q: curves h_X(t) ⊂ α⁻¹(q) with h_X(0) = ε(q)."""

    def map_expressions(self, a: Sequence) -> tuple[list, list]:
        """What the maps a user wrote give at the arrow ``a`` (symbolic coordinates), to
        be checked for symbols that are neither coordinates nor declared parameters, and
        the placeholder symbols those expressions may also hold (a curve parameter, a second
        arrow's fibre).  A groupoid whose maps are the library's own: none."""
        return [], []

    # --- fibres and charts ----------------------------------------------------------------
    @abstractmethod
    def arrow_from(self, q: Sequence, f: Sequence) -> tuple:
        """The arrow with source ``q`` and fibre variables ``f``."""

    @abstractmethod
    def fibre_of(self, a: Sequence) -> tuple:
        """Fibre variables of ``a`` (inverse of :meth:`arrow_from` at fixed source)."""

    def fibre_chart(self, x: Sequence, source: Sequence | None = None) -> tuple:
        """Fibre variables from chart coordinates (``rank`` of them) in the α-fibre of
        ``source`` (a chart may depend on the fibre's base point, e.g. q·τ(x) on the pair
        groupoid of a Lie group).  Default: identity."""
        return tuple(x)

    def renormalised_fibre(self, f: Sequence) -> tuple:
        """Fibre variables f computed by a step (``fibre_chart`` of the solved chart
        coordinates, rounded) pulled back onto the fibre where they over-parametrise it —
        the identity on the fibre.  The pair groupoid of a matrix Lie group renormalises the
        rotation block of q_{k+1} (docs/conventions.md §16), so that q_k stays on the group
        over any number of steps.  Default: f (the arrow of a Lie group groupoid is the
        retraction of the step's own unknowns, never a product of stored values)."""
        return tuple(f)

    def renormalised_arrow(self, a: Sequence) -> tuple:
        """A known arrow a step stores (its source computed as the target of the arrow
        before) pulled back onto the groupoid where its coordinates over-parametrise it —
        the identity on the groupoid.  :class:`TrivialisedPairGroupoid` renormalises the
        configuration q_{k+1} = q_k(I + D_k).  Default: a."""
        return tuple(a)

    @functools.cached_property
    def _numeric_fibre_chart(self):
        x = tuple(sp.Dummy(f"x{i}", real=True) for i in range(self.rank))
        q = tuple(sp.Dummy(f"q{i}", real=True) for i in range(self.base_dim))
        return sp.lambdify([x, q], list(self.fibre_chart(x, q)), NUMPY_MODULES)

    def numeric_fibre_chart(self, x: Sequence, source: Sequence | None = None) -> np.ndarray:
        """:meth:`fibre_chart` evaluated numerically (lambdified once)."""
        q = np.zeros(self.base_dim) if source is None else np.asarray(source, float)
        values = self._numeric_fibre_chart(np.asarray(x, float), q)
        return np.array([float(v) for v in values])

    def fibre_chart_inverse(self, f: Sequence, source: Sequence | None = None) -> tuple:
        """Chart coordinates of fibre variables (numeric).  Default: identity."""
        return tuple(f)

    def predict_chart(self, a: Sequence) -> tuple:
        """Chart coordinates of a first guess for the arrow after ``a`` (symbolic or numeric).

        Default: the next arrow repeats ``a``'s chart coordinates (``chart_of_fibre``).
        """
        return tuple(self.chart_of_fibre(self.fibre_of(a), self.source(a)))

    def chart_of_fibre(self, f: Sequence, source: Sequence | None = None) -> tuple:
        """Chart coordinates of fibre variables, symbolically.  Default: identity."""
        return tuple(f)

    def named_groups(self) -> dict:
        """Matrix-group parts of an arrow's named coordinates: name → MatrixLieGroup (their
        values are checked to lie in the group)."""
        return {}

    def off_group_rows(self, arrows: np.ndarray, tolerance: float) -> np.ndarray:
        """The rows of ``arrows`` (N, arrow_dim) whose named group parts
        (:meth:`named_groups`, at the arrow's base points) are farther than ``tolerance``
        from their groups (:meth:`MatrixLieGroup.deviations`), computed for all rows at
        once; a part whose entries are not among the arrow's coordinates is not checked.
        Rows of another width, and a tolerance that is not a non-negative number, are a
        :class:`ShapeError`."""
        arrows = np.atleast_2d(real_array(arrows, "arrows", owner=self.name))
        if arrows.ndim != 2 or arrows.shape[1] != self.arrow_dim:
            raise ShapeError(f"{self.name}: arrows are rows of {self.arrow_dim} coordinates, "
                             f"got shape {arrows.shape}")
        tolerance = real_argument(tolerance, "tolerance", minimum=0.0, owner=self.name)
        position = {c: i for i, c in enumerate(self.named_arrow(0))}
        bad = np.zeros(len(arrows), dtype=bool)
        for name, group in dict(self.named_groups()).items():
            for offset in (-1, 0, 1):
                value = self.symbols_by_name(offset).get(name)
                if value is None or not hasattr(value, "shape") or value.shape != (
                        group.n, group.n):
                    continue
                M = _matrices(arrows, value, position)
                if M is not None:
                    bad |= ~(group.deviations(M) <= tolerance)
        return np.flatnonzero(bad)

    def base_groups(self) -> dict:
        """Matrix-group parts of a base point's named coordinates: name → MatrixLieGroup
        (the base of a pair groupoid of a group; a Lie group's base is a point, an action
        groupoid's the manifold acted on).  Where there are any, a symbolic check on the
        base treats its points as arbitrary arrays."""
        return {}

    # --- naming in the papers' notation ---------------------------------------------------
    @abstractmethod
    def named_fibre(self, offset: int) -> tuple:
        """Fibre variables of the arrow g_{k+offset}, as named StepSymbols."""

    @abstractmethod
    def named_source(self, offset: int) -> tuple:
        """Source point of the arrow g_{k+offset}, as named StepSymbols."""

    def named_chart(self, offset: int) -> tuple:
        """Chart coordinates (the unknowns) of g_{k+offset}.  Default: the fibre variables."""
        return self.named_fibre(offset)

    def named_arrow(self, offset: int) -> tuple:
        """The arrow g_{k+offset} with every coordinate a named StepSymbol."""
        from .._arguments import integer_argument

        offset = integer_argument(offset, "offset", minimum=-MAX_OFFSET, maximum=MAX_OFFSET,
                                  owner=f"{self.name}.named_arrow")
        return self.arrow_from(self.named_source(offset), self.named_fibre(offset))

    def symbols_by_name(self, offset: int) -> dict[str, Any]:
        """Named coordinates of g_{k+offset}: ``{"x": x_{k+offset}, "g": Matrix, ...}``."""
        return {}

    def view(self, coords: Sequence) -> Arrow:
        """The user-facing :class:`Arrow` for these coordinates."""
        return Arrow(self, coords)

    def base_view(self, coords: Sequence):
        """The user-facing value of a base point q ∈ Q (what a holonomic constraint ψ(q)
        receives): the coordinate tuple by default; a pair groupoid gives its points as
        ``.source``/``.target`` do (a matrix on a Lie group), a product a tuple of its
        factors' base points."""
        return tuple(coords)

    # --- numerics -------------------------------------------------------------------------
    def random_base_point(self, rng: np.random.Generator) -> tuple:
        """A random base point (used by :func:`check_axioms` and property tests)."""
        return tuple(rng.uniform(-1.0, 1.0, self.base_dim))

    def random_chart(self, rng: np.random.Generator, scale: float = 0.5) -> tuple:
        """Random chart coordinates near the identity."""
        return tuple(rng.uniform(-scale, scale, self.rank))

    def random_arrow(self, rng: np.random.Generator, source: Sequence | None = None) -> tuple:
        """A random arrow (optionally with prescribed source), as numeric coordinates: the
        arrow of random chart coordinates in the α-fibre of a random base point."""
        q = self.random_base_point(rng) if source is None else tuple(source)
        return self.numeric_fibre_arrow(q, self.random_chart(rng))

    def numeric_fibre_arrow(self, q: Sequence, x: Sequence) -> tuple:
        """The arrow with source q and fibre chart coordinates x, numerically (the
        symbolic maps compiled once; SymPy's own arithmetic where NumPy cannot evaluate
        them)."""
        try:
            values = self._numeric_fibre_arrow()(*q, *x)
        except (TypeError, ValueError, NameError, ZeroDivisionError, AttributeError):
            values = None  # a structure map NumPy cannot evaluate: SymPy's own arithmetic
        if values is None or not np.all(np.isfinite(np.asarray(values, dtype=float))):
            f = self.fibre_chart([sp.Float(v) for v in x], q)
            values = self.arrow_from(q, [sp.N(v) for v in f])
        return tuple(float(v) for v in values)

    def _numeric_fibre_arrow(self) -> Callable:
        """(q, x) ↦ the arrow with source q and fibre chart coordinates x, compiled once."""
        cached = self.__dict__.get("_fibre_arrow_function")
        if cached is None:
            q = [sp.Dummy(f"q{i}", real=True) for i in range(self.base_dim)]
            x = [sp.Dummy(f"x{i}", real=True) for i in range(self.rank)]
            arrow = [sp.sympify(c) for c in self.arrow_from(q, self.fibre_chart(x, q))]
            cached = _graph_function([*q, *x], arrow)
            self.__dict__["_fibre_arrow_function"] = cached
        return cached

    def section_flow(self, q: Sequence, delta: Sequence) -> tuple:
        """h(δ) ⊂ α⁻¹(q): the section curves h_a(δ_a) composed one after another, so that
        h(0) = ε(q) and dh/dδ_a(0) = X_a(q) exactly (used for Newton updates on arrows)."""
        h = None
        point = tuple(q)
        t = sp.Dummy("t", real=True)
        for a, d in enumerate(delta):
            piece = tuple(c.subs(t, d) for c in self._curves(point, t)[a])
            h = piece if h is None else tuple(self.multiply(h, piece))
            point = tuple(self.target(h))
        return h

    def field_nodes(self, g, side: str, coords: Sequence[int],
                    parameters: dict | None = None) -> list[list[int]]:
        """The left fields X⃖_b(a) = d/dt m(a, h_b(t)) (``side="left"``) or the right fields
        X⃗_b(a) = −d/dt m(h_b(t)⁻¹, a) at t = 0 (seed 000 eqs. (1)–(2)), one per basis
        section, at an arrow given by nodes of the expression graph ``g`` (symgroupoid.ir).

        The structure maps are evaluated on the section curves and differentiated in t on
        the graph (forward mode), then t = 0.  They may use the step's parameters (symbol →
        node in ``parameters``).  Groupoids whose fields have a closed form override this.
        """
        from ..ir import forward, from_sympy

        generic = self._generic_arrow
        t = sp.Dummy("t", real=True)
        symbols = {**(parameters or {}), **{a: c for a, c in zip(generic, coords)}}
        symbols[t] = g.input(t)
        memo: dict = {}
        q = self.target(generic) if side == "left" else self.source(generic)
        out = []
        for h in self._curves(q, t):
            moved = (self.multiply(generic, h) if side == "left"
                     else self.multiply(self.inverse(h), generic))
            nodes = [from_sympy(g, sp.sympify(c), symbols, f"the {side} fields of {self.name}",
                                memo) for c in moved]
            velocity = forward(g, nodes, {symbols[t]: g.one})
            at_zero = g.substitute(velocity, {symbols[t]: g.zero})
            out.append(at_zero if side == "left" else [g.neg(v) for v in at_zero])
        return out

    def section_flow_nodes(self, g, arrow: Sequence[int], delta: Sequence[int]) -> list[int]:
        """:meth:`section_flow` at the target of an arrow given by graph nodes, built on the
        expression graph ``g`` (symgroupoid.ir): the section curves h_c(δ_c) composed one
        after another, each at the target of the product so far.  The structure maps are
        expanded once, at generic arguments, and applied to nodes — composing them in SymPy
        expands the products of curves (on a rotation group, of Cayley matrices).  Other
        symbols of the maps (a system's parameters) are the graph's inputs of those symbols."""
        from ..ir import from_sympy

        a, t = self._generic_arrow, sp.Dummy("t", real=True)
        b = tuple(sp.Dummy(f"b{i}", real=True) for i in range(self.arrow_dim))
        q = tuple(sp.Dummy(f"q{i}", real=True) for i in range(self.base_dim))
        curves = self._curves(q, t)
        product, target = list(self.multiply(a, b)), list(self.target(a))

        def apply(exprs: list, values: dict) -> list[int]:
            known = {**g.inputs, **values}
            return [from_sympy(g, sp.sympify(e), known, f"{self.name}: the section flow")
                    for e in exprs]

        point = apply(target, dict(zip(a, arrow)))
        h: list[int] = []
        for c, d in enumerate(delta):
            piece = apply(list(curves[c]), {**dict(zip(q, point)), t: d})
            h = piece if c == 0 else apply(product, {**dict(zip(a, h)), **dict(zip(b, piece))})
            point = apply(target, dict(zip(a, h)))
        return h

    # --- configurations (boundary data of boundary-value problems) ----------------------
    def arrow_between(self, c0, c1) -> tuple:
        """The arrow from configuration ``c0`` to ``c1`` (numeric).  Pair groupoids: points;
        Lie groups: matrices (R₀⁻¹R₁); products: tuples; see each groupoid."""
        raise NotImplementedError(f"{self.name}: no configuration space; give boundary arrows")

    def configuration_after(self, c0, a: Sequence):
        """The configuration reached from ``c0`` along the arrow ``a`` (numeric)."""
        raise NotImplementedError(f"{self.name}: no configuration space")

    def increments(self, a: Sequence) -> list[tuple[str, Any, np.ndarray]]:
        """(part name, MatrixLieGroup, numeric matrix) of each group element at the numeric
        arrow ``a`` whose retraction coordinates τ⁻¹ the α-fibre chart of a step takes: a
        Lie group's element itself, the increment R₀⁻¹R₁ of a pair groupoid of a group, the
        increment F of :class:`TrivialisedPairGroupoid`.  Where one is a half-turn (the cut
        locus of the Cayley map and of the logarithm) the step's prediction and unknowns are
        not defined.  None for groupoids without group parts (the default)."""
        return []

    def configurations_along(self, arrows: np.ndarray, start=None):
        """The configurations c_0, …, c_N that the composable numeric arrows g_0, …, g_{N−1}
        (the rows of ``arrows``) pass through: c_{k+1} = c_k·g_k (:meth:`configuration_after`,
        the groupoid's multiplication), c_0 = ``start``.  The library's groupoids stack them
        (a Lie group: an (N + 1, n, n) array of R_k, from R_0 = ``start`` or the identity; a
        pair groupoid: its points, which the arrows hold, ``start`` only checked; products
        and action and time groupoids: a tuple with one entry per part, ``start`` with None
        for a part the arrows determine); this default, for a groupoid that defines
        :meth:`configuration_after`, returns the list."""
        if start is None:
            raise ShapeError(f"{self.name}: give the first configuration (start=...): the "
                             f"arrows do not determine it")
        out = [start]
        for a in np.asarray(arrows, float):
            out.append(self.configuration_after(out[-1], tuple(a)))
        return out

    def spatial_momenta(self, momenta: np.ndarray, arrows: np.ndarray, start=None):
        """The momenta F⁻L(g_k) (rows of ``momenta``, in the dual of the section basis, at
        the sources α(g_k) of the rows of ``arrows``) in the spatial frame: a Lie group's
        components μ ↦ Ad*_{c⁻¹} μ = (Ad_{c⁻¹})ᵀ μ, c the configuration α(g_k)
        (reconstructed from ``start`` as in :meth:`configurations_along`; for a left-invariant
        Lagrangian the Noether quantity of left translations, seed 000 Thm 4.9), other
        components as they are (a pair groupoid of Rⁿ: already spatial).  Not defined for
        groupoids the library does not know."""
        from .._errors import UnsupportedFeatureError

        raise UnsupportedFeatureError(f"{self.name}: spatial momenta are defined for the "
                                      f"library's groupoids of Lie groups, pair, action, "
                                      f"time and product groupoids")

    # --- products -------------------------------------------------------------------------
    def __mul__(self, other: Groupoid) -> Groupoid:
        from ._manifold import Manifold
        from ._product import ProductGroupoid

        if isinstance(other, Manifold):  # SE2("g") * EuclideanSpace("psi"): a manifold
            return NotImplemented          # (Manifold.__rmul__), as the other order gives
        if not isinstance(other, Groupoid):
            raise InputTypeError(f"{self.name}: a groupoid can only be multiplied by a "
                                 f"groupoid (the product G₁ × G₂), got "
                                 f"{type(other).__name__} {other!r}")
        return ProductGroupoid(self, other)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name})"

    # --- derived: invariant vector fields -------------------------------------------------
    @functools.cached_property
    def _generic_arrow(self) -> tuple:
        return tuple(sp.Dummy(f"a{i}", real=True) for i in range(self.arrow_dim))

    @functools.cached_property
    def _left_fields(self) -> list[tuple]:
        """Components of X⃖_i at the generic arrow: d/dt m(a, h_i(t))|_0 with h_i ⊂ α⁻¹(β(a))."""
        a, t = self._generic_arrow, sp.Dummy("t", real=True)
        curves = self._curves(self.target(a), t)
        return [_tangent(self.multiply(a, h), t) for h in curves]

    @functools.cached_property
    def _right_fields(self) -> list[tuple]:
        """Components of X⃗_i at the generic arrow: -d/dt m(h_i(t)⁻¹, a)|_0, h_i ⊂ α⁻¹(α(a))."""
        a, t = self._generic_arrow, sp.Dummy("t", real=True)
        curves = self._curves(self.source(a), t)
        fields = []
        for h in curves:
            v = _tangent(self.multiply(self.inverse(h), a), t)
            fields.append(tuple(-c for c in v))
        return fields

    def _curves(self, q: Sequence, t: sp.Symbol) -> list[tuple]:
        try:
            curves = self.section_curves(q, t)
        except Exception as exc:  # noqa: BLE001 - re-raised with context
            raise CallableError(f"{self.name}: section_curves raised {exc!r}") from exc
        if len(curves) != self.rank:
            raise ShapeError(
                f"{self.name}: {len(curves)} section curves given but the α-fibres have "
                f"dimension {self.rank}; a basis of sections needs exactly {self.rank}")
        for i, h in enumerate(curves):
            if len(h) != self.arrow_dim:
                raise ShapeError(f"{self.name}: section curve {i} has {len(h)} coordinates, "
                                 f"arrows have {self.arrow_dim}")
        return [coordinate_values(self.name, f"section curve {i}", h)
                for i, h in enumerate(curves)]

    # --- matrix form (matrix-valued parts kept as matrices) ---------------------------------
    def matrix_parts(self) -> list[tuple[int, Any]]:
        """(offset in the arrow coordinates, MatrixLieGroup) of each matrix-valued part."""
        return []

    def offset_parts(self) -> list[tuple[int, Any]]:
        """(offset in the arrow coordinates, MatrixLieGroup) of each part stored as the
        offset M − I of a group element M (:class:`TrivialisedPairGroupoid`), on the group's
        free entries (``_free``, as its own coordinates)."""
        return []

    def in_matrix_form(self, coords: Sequence, name_of: Callable[[Any], str]) -> tuple:
        """``coords`` with each matrix part replaced by the entries of a MatrixSymbol.

        ``name_of(group)`` gives the symbol's name (its LaTeX).  Affine groups (SE(n)) keep
        explicit entries.
        """
        from ._matrix_form import matrix_entries

        out = list(coords)
        for start, group in self.matrix_parts():
            if group.affine:
                continue
            M = sp.MatrixSymbol(name_of(group), group.n, group.n)
            out[start:start + group.arrow_dim] = matrix_entries(M, group._free)
        return tuple(out)

    def apply_left(self, f: sp.Expr, a: Sequence) -> list[sp.Expr]:
        """X⃖_i[f](a) for every basis section; ``a`` explicit or in matrix form."""
        return self._apply(f, tuple(a), "left")

    def apply_right(self, f: sp.Expr, a: Sequence) -> list[sp.Expr]:
        """X⃗_i[f](a) for every basis section; ``a`` explicit or in matrix form."""
        return self._apply(f, tuple(a), "right")

    def _apply(self, f, a, side):
        from ._matrix_form import block_of, directional_derivative

        fields = self.left_field(a) if side == "left" else self.right_field(a)
        blocks = []
        for start, group in self.matrix_parts():
            M = block_of(a[start:start + group.arrow_dim], group._free)
            if M is not None:
                blocks.append((start, group, M))
        if not blocks:
            return derivation(fields, a, f)
        skip = {i for start, g, _ in blocks for i in range(start, start + g.arrow_dim)}
        scalar = [i for i in range(len(a)) if i not in skip]
        directions = self._matrix_directions(side)
        out = []
        for s, v in enumerate(fields):
            total = derivation([tuple(v[i] for i in scalar)], [a[i] for i in scalar], f)[0]
            for start, group, M in blocks:
                C = directions[s][start]
                if C is None:
                    continue
                C = group.named_basis().get(C, C)
                V = sp.MatMul(M, C) if side == "left" else sp.MatMul(C, M)
                total += directional_derivative(f, M, V)
            out.append(total)
        return out

    def _matrix_directions(self, side: str) -> list[dict]:
        """For each section, the Lie-algebra element C with X(g) = g·C (left) or C·g (right)
        on each matrix part — read off at the identity and verified at a generic arrow."""
        cache = self.__dict__.setdefault("_matrix_direction_cache", {})
        if side not in cache:
            cache[side] = self._read_matrix_directions(side)
        return cache[side]

    def _read_matrix_directions(self, side: str) -> list[dict]:
        a = self._generic_arrow
        fields = self._left_fields if side == "left" else self._right_fields
        q = tuple(sp.Dummy(f"q{i}") for i in range(self.base_dim))
        unit = self.identity(q)
        out = []
        for v in fields:
            at_unit = [sp.sympify(c).xreplace(dict(zip(a, unit))) for c in v]
            per_part = {}
            for start, group in self.matrix_parts():
                sl = slice(start, start + group.arrow_dim)
                C = sp.Matrix(group.matrix(at_unit[sl]))
                for i in range(group.n):  # the fixed row of SE(n) carries no velocity
                    if group.affine and i == group.n - 1:
                        C[i, :] = sp.zeros(1, group.n)
                C = sp.ImmutableMatrix(C) if any(c != 0 for c in C) else None
                if C is not None:
                    if any(e.free_symbols for e in C):
                        raise NotImplementedError("section not constant on a matrix part")
                    Mg = group.matrix(a[sl])
                    expect = Mg * C if side == "left" else C * Mg
                    got = group.matrix(v[sl])
                    if any(sp.expand(got[i, j] - expect[i, j]) != 0 for i, j in group._free):
                        raise NotImplementedError("section is not g·C / C·g on a matrix part")
                per_part[start] = C
            out.append(per_part)
        return out

    def left_field(self, a: Sequence) -> list[tuple]:
        """Tangent vectors X⃖_i(a) ∈ T_aG, one per basis section (arrow coordinates)."""
        return self._instantiate(self._left_fields, a)

    def right_field(self, a: Sequence) -> list[tuple]:
        """Tangent vectors X⃗_i(a) ∈ T_aG, one per basis section (arrow coordinates)."""
        return self._instantiate(self._right_fields, a)

    def _instantiate(self, fields: list[tuple], a: Sequence) -> list[tuple]:
        sub = dict(zip(self._generic_arrow, a))
        return [tuple(c.xreplace(sub) for c in v) for v in fields]


def _tangent(curve: Sequence, t: sp.Symbol) -> tuple:
    """d/dt curve(t) at t = 0, componentwise."""
    return tuple(sp.sympify(c).diff(t).subs(t, 0) for c in curve)


def derivation(fields: list[tuple], a: Sequence, f: sp.Expr) -> list[sp.Expr]:
    """Apply tangent vectors (in coordinates of ``a``) to a function f of ``a``'s coordinates.

    ``X[f](a) = Σ_j ∂f/∂a_j · X_j(a)``: the derivative of f along any curve with velocity X.
    """
    grads = {}
    out = []
    for v in fields:
        total = sp.S.Zero
        for aj, vj in zip(a, v):
            if vj == 0:
                continue
            if aj not in grads:
                grads[aj] = sp.diff(f, aj)
            total += grads[aj] * vj
        out.append(total)
    return out


def _call_on(owner: str, f: Callable, arrow):
    """f(arrow), an exception raised by the user's function wrapped in a
    :class:`~symgroupoid.CallableError` naming ``owner``."""
    try:
        return f(arrow)
    except SymgroupoidError:
        raise
    except Exception as exc:  # noqa: BLE001 - re-raised with context
        raise CallableError(f"{owner}: evaluating f on the arrow raised "
                            f"{type(exc).__name__}: {exc}") from exc


def _derivative_arguments(groupoid, f, a, owner: str) -> tuple[tuple, sp.Expr]:
    """(arrow coordinates, scalar expression) of a left or right derivative's arguments: a
    :class:`Groupoid`, an arrow (None: the named arrow g_k; else as many coordinates as
    the groupoid's arrows have) and a function on arrows or an expression giving a scalar;
    anything else is a named :class:`~symgroupoid.SymgroupoidError`."""
    from .._arguments import instance_argument, sequence_argument, shown_value

    instance_argument(groupoid, Groupoid, "groupoid", "a Groupoid", owner=owner)
    named = groupoid.named_arrow(0)
    if a is None:
        a = named
    else:
        a = tuple(sequence_argument(list(a) if isinstance(a, sp.MatrixBase) else a, "a",
                                    owner=owner))
        if len(a) != len(named):
            raise ShapeError(f"{owner}: a must be an arrow of {groupoid.name} "
                             f"({len(named)} coordinates), got {len(a)}")
    expr = f
    try:
        a = tuple(sp.sympify(c, strict=True) for c in a)
        if callable(f):
            expr = _call_on(owner, f, groupoid.view(a))
        expr = sp.sympify(expr, strict=True)
    except (sp.SympifyError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, SymgroupoidError):
            raise
        raise InputTypeError(f"{owner}: f must be a scalar expression or a function giving "
                             f"one, and a an arrow of scalars; got f = {shown_value(f)}, "
                             f"a = {shown_value(a)}") from exc
    if not isinstance(expr, sp.Expr) or isinstance(expr, sp.MatrixBase):
        raise InputTypeError(f"{owner}: f must be a scalar expression or a function giving "
                             f"one, got {type(expr).__name__} {shown_value(expr)}")
    return a, expr


def left_derivative(groupoid: Groupoid, f: Callable[[Arrow], sp.Expr] | sp.Expr,
                    a: Sequence | None = None) -> list[sp.Expr]:
    """X⃖_i[f](a) for every basis section (docs/conventions.md §1, seed 000 eq. (1)).

    ``f`` is a callable on arrows or an expression in the coordinates of ``a``.
    With ``a=None`` a named arrow g_k is used.
    """
    a, expr = _derivative_arguments(groupoid, f, a, "left_derivative")
    return groupoid.apply_left(expr, a)


def right_derivative(groupoid: Groupoid, f: Callable[[Arrow], sp.Expr] | sp.Expr,
                     a: Sequence | None = None) -> list[sp.Expr]:
    """X⃗_i[f](a) for every basis section (docs/conventions.md §1, seed 000 eq. (2))."""
    a, expr = _derivative_arguments(groupoid, f, a, "right_derivative")
    return groupoid.apply_right(expr, a)


def _graph_function(symbols: list, exprs: list) -> Callable:
    """f(*values) -> list of floats: ``exprs`` evaluated in NumPy through the expression graph
    (linear in the size of the expressions' DAG; :func:`sympy.lambdify` prints the expanded
    trees, 10× slower for a product groupoid of many rotations); lambdify for expressions
    the graph refuses."""
    from ..ir import Graph, Program, from_sympy

    try:
        g = Graph()
        nodes = {s: g.input(s) for s in symbols}
        memo: dict = {}
        outs = [from_sympy(g, e, nodes, memo=memo) for e in exprs]
    except SymgroupoidError:
        return sp.lambdify(symbols, exprs, NUMPY_MODULES)
    evaluate = Program(g, {"z": list(symbols)}, {"out": outs}).numpy_function(["out"], ["z"])

    def f(*values):
        return list(evaluate(np.array(values, dtype=float))[0])

    return f


def _matrices(arrows: np.ndarray, value, position: dict) -> np.ndarray | None:
    """The matrices (N, n, n) whose entries are the arrow coordinates or numbers of the
    symbolic matrix ``value``, at every row of ``arrows``; None when an entry is neither."""
    n, m = value.shape
    out = np.empty((len(arrows), n, m))
    for i in range(n):
        for j in range(m):
            entry = value[i, j]
            if entry in position:
                out[:, i, j] = arrows[:, position[entry]]
            elif getattr(entry, "is_number", False):
                out[:, i, j] = float(entry)
            else:
                return None
    return out
