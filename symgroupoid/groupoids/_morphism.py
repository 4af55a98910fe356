"""Morphisms of Lie groupoids and the algebroid maps they induce (seed 000 §4.1).

A morphism Φ: G → G′ maps composable pairs to composable pairs and products to products
(seed 000 Def. 4.1).  It then covers a base map Φ₀: Q → Q′ with

    α′∘Φ = Φ₀∘α,   β′∘Φ = Φ₀∘β,   Φ∘ε = ε′∘Φ₀,   Φ∘i = i′∘Φ,

and induces AΦ: AG → AG′, AΦ(v) = TΦ(v) for v ∈ A_qG = T_{ε(q)}α⁻¹(q).  In the section bases,
AΦ(X_a(q)) = Σ_b M_ab(q) X′_b(Φ₀(q)); two sections X = Σ c_a X_a and X′ = Σ c′_b X′_b are
AΦ-related (AΦ∘X = X′∘Φ₀) iff c′(Φ₀(q)) = M(q)ᵀ c(q) — equivalently their left-invariant
(and right-invariant) vector fields are Φ-related.  Dually, p′ ∈ A*_{Φ₀(q)}G′ and
p ∈ A*_qG are A*Φ-related iff p = M(q) p′ (seed 000 Def. 4.4); Theorem 4.5 says the discrete
Legendre transforms of related systems are so related.

Nothing here depends on the kind of groupoid: Φ is given on flat coordinates (through the
source groupoid's arrow views), Φ₀ is derived as α′∘Φ∘ε, and M from the section curves.
Conventions: docs/conventions.md §13.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Mapping, Sequence

import numpy as np
import sympy as sp

from .._arguments import instance_argument, integer_argument, real_argument, shown_value
from .._errors import (
    CallableError,
    DomainError,
    InputTypeError,
    MorphismError,
    ReconstructionError,
    ShapeError,
    SymgroupoidError,
)
from .._lambdify import NUMPY_MODULES
from .._symbols import scalar_expressions
from ._base import Groupoid

#: relative tolerance of the numeric identities (morphism axioms, lifts, AΦ)
TOLERANCE = 1e-9


# --- coordinates ------------------------------------------------------------------------------

def flatten_arrow(groupoid: Groupoid, value, what: str) -> tuple:
    """Flat arrow coordinates of ``groupoid`` from a user value.

    Accepted: a flat sequence of scalars, or a sequence of parts — scalars, sequences, column
    vectors, and n×n matrices for the matrix parts of the groupoid (stored as their free
    entries, e.g. SE(n) without its fixed last row).
    """
    parts = list(value) if isinstance(value, (list, tuple)) else [value]
    starts = dict(groupoid.matrix_parts())
    flat: list = []
    for item in parts:
        if isinstance(item, (sp.MatrixBase, np.ndarray)):
            M = sp.Matrix(item)
            group = starts.get(len(flat))
            if group is not None and M.shape == (group.n, group.n):
                flat.extend(group.entries(M))
            elif 1 in M.shape:
                flat.extend(M)
            else:
                raise ShapeError(f"{what}: a {M.shape[0]}×{M.shape[1]} matrix at coordinate "
                                 f"{len(flat)} of {groupoid.name}, where no matrix part of "
                                 f"that size starts")
        elif isinstance(item, (list, tuple)):
            flat.extend(flatten_arrow(groupoid, item, what) if _nested(item) else item)
        else:
            flat.append(item)
    if len(flat) != groupoid.arrow_dim:
        raise ShapeError(f"{what}: {len(flat)} coordinates, but an arrow of {groupoid.name} "
                         f"has {groupoid.arrow_dim}")
    return _scalars(flat, what)


def _scalars(values: Sequence, what: str) -> tuple:
    """``values`` as SymPy scalar expressions; a :class:`ShapeError` naming the first that is
    none (a string is not read as a symbol: "a" would become a free parameter)."""
    out, bad = scalar_expressions(values)
    if bad is not None:
        c = values[bad]
        raise ShapeError(f"{what}: coordinates must be numbers or SymPy expressions, got "
                         f"{type(c).__name__} {c!r} at coordinate {bad}")
    return out


def _nested(item) -> bool:
    return any(isinstance(c, (list, tuple, sp.MatrixBase, np.ndarray)) for c in item)


def chart_to_fibre(G: Groupoid, x: Sequence, q: Sequence) -> tuple:
    """``G.fibre_chart(x)`` in the α-fibre of q (charts may depend on the fibre's source)."""
    if len(inspect.signature(G.fibre_chart).parameters) >= 2:
        return tuple(G.fibre_chart(x, q))
    return tuple(G.fibre_chart(x))


def fibre_to_chart(G: Groupoid, f: Sequence, q: Sequence) -> tuple:
    """``G.fibre_chart_inverse(f)`` (numeric) in the α-fibre of q."""
    if len(inspect.signature(G.fibre_chart_inverse).parameters) >= 2:
        return tuple(G.fibre_chart_inverse(f, q))
    return tuple(G.fibre_chart_inverse(f))


def _dummies(prefix: str, n: int) -> tuple:
    return tuple(sp.Dummy(f"{prefix}{i}", real=True) for i in range(n))


def _tangent(curve: Sequence, t: sp.Symbol) -> list:
    return [sp.sympify(c).diff(t).subs(t, 0) for c in curve]


class ParameterValues:
    """Numeric values of the free symbols of structure maps, maps and systems.

    Given values (by symbol or by name) first; any other free symbol gets a random value in
    [0.5, 1.5] on first use (recorded in ``.values``, so failures can be reproduced).
    """

    def __init__(self, given: Mapping | None = None, rng: np.random.Generator | None = None,
                 strict: bool = False):
        if isinstance(given, ParameterValues):
            self.by_name, self.values = given.by_name, given.values
            self.rng, self.strict = given.rng, given.strict
            return
        self.by_name = {str(k): float(v) for k, v in (given or {}).items()}
        self.rng = rng or np.random.default_rng(0)
        self.values: dict = {}
        self.strict = strict

    def value(self, s: sp.Symbol) -> float:
        if s not in self.values:
            if s.name in self.by_name:
                self.values[s] = self.by_name[s.name]
            elif self.strict:
                raise KeyError(f"give the value of parameter {s.name} in params=")
            else:
                self.values[s] = float(self.rng.uniform(0.5, 1.5))
        return self.values[s]

    def vector(self, symbols: Sequence) -> np.ndarray:
        return np.array([self.value(s) for s in symbols], dtype=float)

    def number(self, e) -> float:
        e = sp.sympify(e)
        if e.free_symbols:
            e = e.xreplace({s: sp.Float(self.value(s)) for s in e.free_symbols})
        v = complex(sp.N(e))
        if abs(v.imag) > 1e-12 * max(1.0, abs(v.real)) or not np.isfinite(v.real):
            raise DomainError(f"not a finite real number: {e}")
        return v.real

    def numbers(self, v: Sequence) -> np.ndarray:
        return np.array([self.number(c) for c in v], dtype=float)

    def describe(self) -> str:
        if not self.values:
            return ""
        shown = ", ".join(f"{s}={v:.6g}" for s, v in sorted(self.values.items(),
                                                             key=lambda kv: kv[0].name))
        return f" (parameters {shown})"


def _lambdify(args: Sequence, exprs: Sequence) -> Callable:
    return sp.lambdify(list(args), list(exprs), NUMPY_MODULES)


def arrows_of(G: Groupoid, value) -> np.ndarray:
    """Arrows of G as an (N, dim) array: rows of an array, or the arrows g_k of a first-order
    trajectory (an object with ``.states`` whose rows start with g_k)."""
    states = getattr(value, "states", None)
    if states is not None:
        return np.asarray(states, float)[:, :G.arrow_dim]
    return np.atleast_2d(np.asarray(value, float))


def _rows(f: Callable, X: np.ndarray, *extra) -> np.ndarray:
    """Evaluate a lambdified vector function on each row of X (vectorised), shape (N, m)."""
    X = np.atleast_2d(np.asarray(X, float))
    out = f(list(X.T), *extra)
    n = X.shape[0]
    return np.stack([np.broadcast_to(np.asarray(v, float), (n,)) for v in out], axis=1)


# --- the morphism ---------------------------------------------------------------------------

class GroupoidMorphism:
    """A morphism of Lie groupoids Φ: G → G′ (seed 000 Def. 4.1).

    Parameters
    ----------
    source, target : the groupoids G and G′.
    map : ``map(g) -> arrow of G′`` on a symbolic arrow view of G (as a Lagrangian is
        written); returns flat coordinates of G′ or parts (see :func:`flatten_arrow`).
    base_map : optional ``Φ₀(q) -> point of Q′`` on coordinate tuples; derived as α′∘Φ∘ε
        when omitted (a morphism determines it).
    section : optional ``σ(g′) -> arrow of G`` with Φ∘σ = id (a reduction then finds the
        reduced Lagrangian by substitution, L′ = L∘σ).
    lift : optional ``lift(q, g′, params) -> arrow of G`` (numeric) with source q and
        Φ(arrow) = g′; by default such an arrow is found by Gauss–Newton in G's α-fibre chart.
    name : used in messages.

    Free symbols of the map (parameters such as a coupling constant) are allowed; numeric
    methods take their values as ``params`` (a mapping from symbol or name to value).
    """

    def __init__(self, source: Groupoid, target: Groupoid, map: Callable,
                 base_map: Callable | None = None, *, section: Callable | None = None,
                 lift: Callable | None = None, name: str | None = None):
        for what, G in (("source", source), ("target", target)):
            if not isinstance(G, Groupoid):
                raise InputTypeError(f"GroupoidMorphism: the {what} must be a Groupoid, got "
                                     f"{type(G).__name__}")
        if not callable(map):
            raise CallableError(f"GroupoidMorphism: map must be a function of an arrow of "
                                f"{source.name}, got {type(map).__name__}")
        self.source, self.target = source, target
        self.name = name or f"Φ: {source.name} → {target.name}"
        self._map, self._base_map, self._section, self._lift = map, base_map, section, lift
        self._generic = _dummies("a", source.arrow_dim)
        self.image = self._call_map(self._generic)
        self._generic_base = _dummies("q", source.base_dim)
        self.base_image = self._compute_base(self._generic_base)
        found = set().union(*(sp.sympify(e).free_symbols for e in self.image + self.base_image))
        inner = set(self._generic) | set(self._generic_base)
        #: free symbols of Φ and Φ₀ besides the arrow's coordinates (sorted by name)
        self.parameters: list = sorted(found - inner, key=lambda s: s.name)

    # --- symbolic application -------------------------------------------------------------
    def _call_map(self, coords: Sequence) -> tuple:
        try:
            out = self._map(self.source.view(tuple(coords)))
        except SymgroupoidError:
            raise
        except Exception as exc:  # noqa: BLE001 - re-raised with context
            raise CallableError(f"{self.name}: the map raised {type(exc).__name__}: "
                                f"{exc}") from exc
        return flatten_arrow(self.target, out, f"{self.name}: the map")

    def _compute_base(self, q: Sequence) -> tuple:
        if self._base_map is None:
            return tuple(self.target.source(self(self.source.identity(tuple(q)))))
        try:
            out = self._base_map(tuple(q))
        except SymgroupoidError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise CallableError(f"{self.name}: the base map raised {type(exc).__name__}: "
                                f"{exc}") from exc
        out = _scalars(out if isinstance(out, (list, tuple, sp.MatrixBase)) else [out],
                       f"{self.name}: the base map")
        if len(out) != self.target.base_dim:
            raise ShapeError(f"{self.name}: the base map returned {len(out)} coordinates; a "
                             f"point of the base of {self.target.name} has "
                             f"{self.target.base_dim}")
        return out

    def __call__(self, coords: Sequence) -> tuple:
        """Φ(g) for an arrow given by coordinates (symbolic or numeric)."""
        coords = tuple(coords)
        if len(coords) != self.source.arrow_dim:
            raise ShapeError(f"{self.name}: an arrow of {self.source.name} has "
                             f"{self.source.arrow_dim} coordinates, got {len(coords)}")
        sub = dict(zip(self._generic, (sp.sympify(c) for c in coords)))
        return tuple(e.xreplace(sub) for e in self.image)

    def base(self, q: Sequence) -> tuple:
        """Φ₀(q)."""
        sub = dict(zip(self._generic_base, (sp.sympify(c) for c in q)))
        return tuple(e.xreplace(sub) for e in self.base_image)

    def section(self, coords: Sequence) -> tuple | None:
        """σ(g′) (symbolic), or None when no section was given."""
        if self._section is None:
            return None
        try:
            out = self._section(self.target.view(tuple(coords)))
        except SymgroupoidError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise CallableError(f"{self.name}: the section raised {type(exc).__name__}: "
                                f"{exc}") from exc
        return flatten_arrow(self.source, out, f"{self.name}: the section")

    @property
    def has_section(self) -> bool:
        return self._section is not None

    # --- numerics ---------------------------------------------------------------------------
    def _params(self, params, symbols: Sequence) -> np.ndarray:
        """Values of ``symbols``: from a :class:`ParameterValues` (random where it draws
        them) or from a mapping, where every one must be given."""
        values = params if isinstance(params, ParameterValues) else ParameterValues(params)
        missing = [s for s in symbols if s not in values.values and s.name not in values.by_name]
        if missing and (values.strict or not isinstance(params, ParameterValues)):
            raise KeyError(f"{self.name}: give the value of parameter(s) "
                           f"{', '.join(s.name for s in missing)} in params=")
        return values.vector(symbols)

    @functools.cached_property
    def _numeric_map(self) -> Callable:
        return _lambdify([self._generic, self.parameters], self.image)

    def project(self, arrows: np.ndarray, params: Mapping | None = None) -> np.ndarray:
        """Φ applied to each arrow (rows of an N × dim G array, or the arrows of a trajectory),
        numerically."""
        arrows = arrows_of(self.source, arrows)
        if arrows.shape[1] != self.source.arrow_dim:
            raise ShapeError(f"{self.name}: arrows of {self.source.name} have "
                             f"{self.source.arrow_dim} coordinates, got shape {arrows.shape}")
        return _rows(self._numeric_map, arrows, self._params(params, self.parameters))

    @functools.cached_property
    def _numeric_source_structure(self) -> tuple[Callable, Callable, list]:
        a = self._generic
        alpha, beta = self.source.source(a), self.source.target(a)
        free = set().union(*(sp.sympify(e).free_symbols for e in alpha + beta)) - set(a)
        syms = sorted(free, key=lambda s: s.name)
        return _lambdify([a, syms], alpha), _lambdify([a, syms], beta), syms

    @functools.cached_property
    def _gauss_newton(self):
        """r(x; q) = Φ(arrow_from(q, chart(x))) and the arrow itself, lambdified."""
        G = self.source
        x, q = _dummies("x", G.rank), _dummies("p", G.base_dim)
        arrow = tuple(G.arrow_from(q, chart_to_fibre(G, x, q)))
        r = self(arrow)
        free = set().union(*(sp.sympify(e).free_symbols for e in r + arrow))
        syms = sorted(free - set(x) - set(q), key=lambda s: s.name)
        return _lambdify([x, q, syms], r), _lambdify([x, q, syms], arrow), syms

    def lift(self, q: Sequence, reduced: Sequence, params: Mapping | None = None,
             guess: Sequence | None = None) -> np.ndarray:
        """The arrow of G with source q that Φ maps to ``reduced`` (numeric).

        Uses the given ``lift`` if any, else Gauss–Newton in G's α-fibre chart from ``guess``
        (chart coordinates; default zero).  The result is checked: α = q and Φ = ``reduced``
        to rounding, or a :class:`ReconstructionError`.
        """
        q = np.asarray(q, float)
        target = np.asarray(reduced, float)
        if self._lift is not None:
            arrow = np.asarray(self._lift(q, target, params), float)
        else:
            arrow = self._solve_lift(q, target, params, guess)
        self._check_lift(arrow, q, target, params)
        return arrow

    def _solve_lift(self, q, target, params, guess) -> np.ndarray:
        """Gauss–Newton on Φ(arrow(x)) = target in the α-fibre chart of q; the Jacobian by
        central differences (the iteration converges to the same root at a linear rate of
        the differences' error, ~1e-9, so a few iterations reach rounding level)."""
        G = self.source
        x = np.zeros(G.rank) if guess is None else np.asarray(guess, float).copy()
        fr, farrow, syms = self._gauss_newton
        p = self._params(params, syms)

        def residual(z):
            return np.asarray(fr(z, q, p), float) - target

        for _ in range(60):
            r = residual(x)
            J = np.empty((len(r), G.rank))
            for j in range(G.rank):
                d = 1e-6 * (1.0 + abs(x[j]))
                e = np.zeros(G.rank)
                e[j] = d
                J[:, j] = (residual(x + e) - residual(x - e)) / (2 * d)
            dx = np.linalg.lstsq(J, -r, rcond=None)[0]
            x = x + dx
            if not np.isfinite(x).all() or np.linalg.norm(dx) <= 1e-15 * (1.0 + np.linalg.norm(x)):
                break
        return np.array([float(v) for v in farrow(x, q, p)], dtype=float)

    def _check_lift(self, arrow, q, target, params) -> None:
        fa, _, syms = self._numeric_source_structure
        p = self._params(params, syms) if syms else np.zeros(0)
        got_q = np.asarray(fa(arrow, p), float).ravel()
        got = self.project(arrow[None], params)[0]
        scale = 1.0 + np.abs(target).max(initial=0.0)
        bad_q = got_q.size and not np.allclose(got_q, q, rtol=TOLERANCE, atol=TOLERANCE)
        if not np.isfinite(arrow).all() or bad_q or np.abs(got - target).max(
                initial=0.0) > TOLERANCE * scale:
            raise ReconstructionError(
                f"{self.name}: no arrow with source {np.round(q, 9).tolist()} maps to "
                f"{np.round(target, 9).tolist()} (closest found maps to "
                f"{np.round(got, 9).tolist()}); is the reduced arrow in the image of Φ?")

    def reconstruct(self, arrows: np.ndarray, initial: Sequence,
                    params: Mapping | None = None) -> np.ndarray:
        """A composable sequence g_0, g_1, … of G with g_0 = ``initial`` and
        Φ(g_k) = ``arrows[k]`` (the reconstruction of Corollary 4.6 / Remark 4.7).

        ``arrows``: rows of an array, or the arrows of a trajectory of the reduced system.
        ``initial`` must project onto ``arrows[0]``; each g_{k+1} is the lift of
        ``arrows[k+1]`` to the α-fibre of β(g_k).
        """
        arrows = arrows_of(self.target, arrows)
        if arrows.shape[1] != self.target.arrow_dim:
            raise ShapeError(f"{self.name}: arrows of {self.target.name} have "
                             f"{self.target.arrow_dim} coordinates, got shape {arrows.shape}")
        g0 = np.asarray(initial, float)
        if g0.shape != (self.source.arrow_dim,):
            raise ShapeError(f"{self.name}: the initial arrow has {self.source.arrow_dim} "
                             f"coordinates, got shape {g0.shape}")
        first = self.project(g0[None], params)[0]
        if not np.allclose(first, arrows[0], rtol=TOLERANCE, atol=TOLERANCE):
            raise ReconstructionError(
                f"{self.name}: the initial arrow projects to {np.round(first, 9).tolist()}, "
                f"not to the first reduced arrow {np.round(arrows[0], 9).tolist()}")
        _, fb, syms = self._numeric_source_structure
        p = self._params(params, syms) if syms else np.zeros(0)
        out = np.empty((len(arrows), self.source.arrow_dim))
        out[0] = g0
        guess = None
        for k in range(1, len(arrows)):
            q = np.asarray(fb(out[k - 1], p), float).ravel()
            out[k] = self.lift(q, arrows[k], params, guess)
            if self._lift is None:
                guess = self._chart_of(out[k], q)
        return out

    def _chart_of(self, arrow: np.ndarray, q: np.ndarray) -> np.ndarray | None:
        G = self.source
        try:
            return np.asarray(fibre_to_chart(G, G.fibre_of(tuple(arrow)), q), float)
        except (TypeError, ValueError, np.linalg.LinAlgError):
            return None

    # --- the induced algebroid map ------------------------------------------------------------
    @functools.cached_property
    def _algebroid_templates(self):
        q = self._generic_base
        t = sp.Dummy("t", real=True)
        V = [_tangent(self(h), t) for h in self.source._curves(q, t)]
        B = [_tangent(h, t) for h in self.target._curves(self.base(q), t)]
        free = set().union(*(sp.sympify(e).free_symbols for v in V + B for e in v)) - set(q)
        syms = sorted(free, key=lambda s: s.name)
        return q, V, B, syms

    def algebroid_matrix(self, q: Sequence, params: Mapping | None = None) -> np.ndarray:
        """M(q) with AΦ(X_a(q)) = Σ_b M[a, b] X′_b(Φ₀(q)) (numeric, at a base point q).

        Raises :class:`MorphismError` when TΦ does not map A_qG into A_{Φ₀(q)}G′.
        """
        qs, V, B, syms = self._algebroid_templates
        key = "_algebroid_numeric"
        if key not in self.__dict__:
            self.__dict__[key] = (sp.lambdify([qs, syms], sp.Matrix(V), NUMPY_MODULES),
                                  sp.lambdify([qs, syms], sp.Matrix(B), NUMPY_MODULES))
        fV, fB = self.__dict__[key]
        p = self._params(params, syms)
        qv = np.asarray(q, float)
        Vn = np.asarray(fV(qv, p), float).reshape(len(V), -1)
        Bn = np.asarray(fB(qv, p), float).reshape(len(B), -1)
        M, *_ = np.linalg.lstsq(Bn.T, Vn.T, rcond=None)
        M = M.T
        defect = np.abs(M @ Bn - Vn).max(initial=0.0)
        if defect > TOLERANCE * (1.0 + np.abs(Vn).max(initial=0.0)):
            raise MorphismError(f"{self.name}: TΦ maps the sections at q = "
                                f"{np.round(qv, 9).tolist()} out of the algebroid of "
                                f"{self.target.name} (defect {defect:.2e}): Φ is not a "
                                f"groupoid morphism")
        return M

    def pull_back_momentum(self, q: Sequence, momentum: Sequence,
                           params: Mapping | None = None) -> np.ndarray:
        """A*Φ(p′) ∈ A*_qG for p′ ∈ A*_{Φ₀(q)}G′: ⟨A*Φ(p′), v⟩ = ⟨p′, AΦ(v)⟩, i.e. M(q) p′
        (the A*Φ-relation of seed 000 Def. 4.4)."""
        return self.algebroid_matrix(q, params) @ np.asarray(momentum, float)

    def related(self, section: Sequence | Callable, target_section: Sequence | Callable,
                samples: int = 5, seed: int = 0, params: Mapping | None = None) -> bool:
        """Whether X = Σ c_a X_a and X′ = Σ c′_b X′_b are AΦ-related, AΦ∘X = X′∘Φ₀,
        checked at random base points (coefficients: lists, or callables of the point)."""
        rng = np.random.default_rng(seed)
        values = ParameterValues(params, rng)
        for _ in range(samples):
            q = self.source.random_base_point(rng)
            qp = values.numbers(self.base(q))
            c = values.numbers(section(tuple(q)) if callable(section) else section)
            cp = values.numbers(target_section(tuple(qp)) if callable(target_section)
                                else target_section)
            M = self.algebroid_matrix(q, values)
            if not np.allclose(M.T @ c, cp, rtol=TOLERANCE, atol=TOLERANCE):
                return False
        return True

    def __repr__(self) -> str:
        return f"GroupoidMorphism({self.name})"


# --- verification -----------------------------------------------------------------------------

def _fail(phi: GroupoidMorphism, axiom: str, values: ParameterValues,
          **arrows) -> MorphismError:
    shown = ", ".join(f"{k}=({', '.join(f'{c:.6g}' for c in v)})" for k, v in arrows.items())
    err = MorphismError(f"{phi.name}: {axiom} fails for {shown}{values.describe()}")
    err.axiom = axiom
    err.arrows = {k: tuple(float(c) for c in v) for k, v in arrows.items()}
    err.parameters = {s.name: v for s, v in values.values.items()}
    return err


def check_morphism(phi: GroupoidMorphism, samples: int = 5, seed: int = 0,
                   tol: float = TOLERANCE, params: Mapping | None = None) -> None:
    """Check seed 000 Def. 4.1 and its consequences on random composable pairs (a, b):

    (Φa, Φb) composable, Φ(ab) = Φ(a)Φ(b), α′∘Φ = Φ₀∘α, β′∘Φ = Φ₀∘β, Φ∘ε = ε′∘Φ₀,
    Φ∘i = i′∘Φ, and TΦ(A_qG) ⊂ A_{Φ₀(q)}G′.  Free parameters get the values in ``params``
    or random ones.  Raises :class:`MorphismError` naming the identity, the arrows and the
    parameter values.  ``samples`` (at least 1) and ``seed`` are counts
    (:func:`~symgroupoid._arguments.integer_argument`).
    """
    instance_argument(phi, GroupoidMorphism, "phi", "a GroupoidMorphism",
                      owner="check_morphism")
    samples = integer_argument(samples, "samples", minimum=1, owner=phi.name)
    tol = real_argument(tol, "tol", minimum=0.0, owner=phi.name)
    if params is not None and not isinstance(params, Mapping):
        raise InputTypeError(f"{phi.name}: params must be a mapping from symbol or name to "
                             f"value, got {type(params).__name__} {shown_value(params)}")
    seed = integer_argument(seed, "seed", owner=phi.name)
    rng = np.random.default_rng(seed)
    values = ParameterValues(params, rng)

    def close(x, y) -> bool:
        x, y = values.numbers(x), values.numbers(y)
        return x.shape == y.shape and bool(np.allclose(x, y, rtol=tol, atol=tol))

    try:
        _check_samples(phi, samples, rng, values, close)
    except DomainError as err:  # (ParameterValues.number: a value that is not finite)
        raise DomainError(f"{phi.name}: the map's value at a random arrow is {err}"
                          f"{values.describe()}; Φ must map arrows to arrows") from None


def _check_samples(phi: GroupoidMorphism, samples: int, rng, values, close) -> None:
    """The identities of :func:`check_morphism` at ``samples`` random arrows."""
    G, H = phi.source, phi.target
    for _ in range(samples):
        a = G.random_arrow(rng)
        b = G.random_arrow(rng, G.target(a))
        fa, fb = values.numbers(phi(a)), values.numbers(phi(b))
        if not close(H.target(fa), H.source(fb)):
            raise _fail(phi, "(Φa, Φb) composable: β′(Φa) = α′(Φb)", values, a=a, b=b)
        if not close(phi(G.multiply(a, b)), H.multiply(fa, fb)):
            raise _fail(phi, "Φ(ab) = Φ(a)Φ(b)", values, a=a, b=b)
        if not close(H.source(fa), phi.base(G.source(a))):
            raise _fail(phi, "α′∘Φ = Φ₀∘α", values, a=a)
        if not close(H.target(fa), phi.base(G.target(a))):
            raise _fail(phi, "β′∘Φ = Φ₀∘β", values, a=a)
        if not close(phi(G.inverse(a)), H.inverse(fa)):
            raise _fail(phi, "Φ∘i = i′∘Φ", values, a=a)
        q = G.random_base_point(rng)
        if not close(phi(G.identity(q)), H.identity(values.numbers(phi.base(q)))):
            raise _fail(phi, "Φ∘ε = ε′∘Φ₀", values, q=q)
        try:
            phi.algebroid_matrix(q, values)
        except MorphismError:
            raise _fail(phi, "TΦ maps A_qG into A_{Φ₀(q)}G′", values, q=q) from None
