"""Matrix Lie groups as groupoids over a point: SO(2), SO(3), SE(2), SE(3).

A Lie group G ⇉ {e} has α = β = const, m = matrix product, ε = I, i = matrix inverse
(seed 001 §2.1.1).  The basis sections are the Lie algebra basis E_a, as curves τ(t E_a).
Arrows are stored as the free entries of the matrix (row-major; SE(n)'s last row is fixed).

Retractions τ: g → G (seed 000 §6.1, seed 001 App. D):

- Cayley ``cay(ξ) = (I − ξ/2)⁻¹(I + ξ/2)`` (default), derived symbolically;
- exponential, in closed form (Rodrigues and its SE(n) analogues).

Their left- and right-trivialised tangents dτ_x, dτ⁻¹_x (docs/conventions.md §5) are derived
symbolically from τ, never typed in: ``T_xτ(y) = τ(x)·dτ_x(y)`` (left) and
``T_xτ(y) = dτ_x(y)·τ(x)`` (right).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import sympy as sp

from .._arguments import choice_argument, name_argument
from .._lambdify import NUMPY_MODULES
from .._symbols import StepSymbol, indexed_symbol, latex_name, subscripted
from ..ir import (
    HalfThetaCotHalfTheta,
    OneMinusCosOverTheta2,
    SE3LogCoefficient,
    SinOverTheta,
    ThetaMinusSinOverTheta3,
    ThetaOverTwoSin,
)
from ._base import Arrow, Groupoid
from ._matrix_form import StructuredMatrix, block_of, named_basis

_named_basis = functools.cache(named_basis)

RETRACTIONS = ("cayley", "exp")


def hat3(w: Sequence) -> sp.Matrix:
    """ω ↦ ω̂ with ω̂ v = ω × v (the so(3) hat map, E₁, E₂, E₃ basis)."""
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


class MatrixArrow(Arrow):
    """An element of a matrix Lie group: ``.matrix`` (SymPy Matrix) and ``.coordinates``.

    ``.coordinates`` are the retraction coordinates τ⁻¹(g) (Cayley by default); for SE(n)
    also ``.rotation`` and ``.translation``.
    """

    @property
    def matrix(self) -> sp.Matrix:
        return self.groupoid.matrix(self.coords)

    @property
    def coordinates(self) -> sp.Matrix:
        """τ⁻¹(g) as a column of Lie-algebra coordinates (symbolic, valid on the group)."""
        return self.groupoid.retraction_inverse(self.matrix)

    @property
    def rotation(self) -> sp.Matrix:
        n = self.groupoid.n - (1 if self.groupoid.affine else 0)
        return self.matrix[:n, :n]

    @property
    def translation(self) -> sp.Matrix:
        if not self.groupoid.affine:
            raise AttributeError(f"{self.groupoid.name} has no translation part")
        n = self.groupoid.n - 1
        return self.matrix[:n, n]


class MatrixLieGroup(Groupoid):
    """A matrix Lie group given by its Lie algebra basis and inversion.

    Subclasses set ``n`` (matrix size), ``basis`` (list of n×n matrices), ``affine``
    (SE(n): last row fixed to (0, …, 0, 1)) and the closed-form exponential and logarithm.
    """

    n: int = 0
    affine: bool = False
    group_name: str = "G"

    def __init__(self, name: str = "g", retraction: str = "cayley"):
        name = name_argument(name, "the group's name", owner=self.group_name)
        choice_argument(retraction, RETRACTIONS, "retraction", owner=self.group_name)
        self.symbol_name = name
        self.latex = latex_name(name)
        self.retraction = retraction
        self.name = f"{self.group_name}({name})"

    # --- algebra ------------------------------------------------------------------------
    @classmethod
    def basis_matrices(cls) -> list[sp.ImmutableMatrix]:
        """The Lie algebra basis E_1, …, E_r used for sections and coordinates."""
        return list(_basis_of(cls))

    @classmethod
    def _basis(cls) -> list[sp.Matrix]:
        raise NotImplementedError

    @classmethod
    def named_basis(cls) -> dict:
        """Basis values → MatrixSymbols E_a (for the matrix form)."""
        return _named_basis(cls)

    def matrix_parts(self):
        return [(0, self)]

    @classmethod
    def hat(cls, x: Sequence) -> sp.Matrix:
        """Σ x_a E_a."""
        out = sp.zeros(cls.n, cls.n)
        for xa, E in zip(x, _basis_of(cls)):
            out += xa * E
        return sp.Matrix(out)

    @classmethod
    @functools.cache
    def _gram_inverse(cls) -> sp.Matrix:
        B = _basis_of(cls)
        gram = sp.Matrix(len(B), len(B), lambda i, j: (B[i].T * B[j]).trace())
        return gram.inv()

    @classmethod
    def vee(cls, M: sp.Matrix) -> sp.Matrix:
        """Coordinates of a Lie-algebra matrix in the basis (Frobenius projection)."""
        B = _basis_of(cls)
        rhs = sp.Matrix([(E.T * M).trace() for E in B])
        return cls._gram_inverse() * rhs

    @property
    def rank(self) -> int:
        return len(_basis_of(type(self)))

    @property
    def _free(self) -> list[tuple[int, int]]:
        rows = self.n - 1 if self.affine else self.n
        return [(i, j) for i in range(rows) for j in range(self.n)]

    @property
    def free_entries(self) -> list[tuple[int, int]]:
        """The matrix positions (i, j) the arrow coordinates hold, in order (row-major; SE(n)
        without its fixed last row (0, …, 0, 1))."""
        return self._free

    @property
    def arrow_dim(self) -> int:
        return len(self._free)

    @property
    def base_dim(self) -> int:
        return 0

    def matrix(self, coords: Sequence) -> sp.Matrix:
        """The full n×n matrix of an arrow's coordinates.

        In matrix form (coordinates = the entries of one MatrixSymbol) this is a
        :class:`StructuredMatrix` on that symbol.
        """
        M = block_of(tuple(coords), self._free)
        if M is not None and not self.affine:
            return StructuredMatrix(M, self.named_basis())
        M = sp.eye(self.n)
        for (i, j), c in zip(self._free, coords):
            M[i, j] = c
        return M

    def entries(self, M: sp.Matrix) -> tuple:
        """Free entries of a matrix (the arrow coordinates)."""
        return tuple(M[i, j] for i, j in self._free)

    # --- structure maps -------------------------------------------------------------------
    def source(self, a):
        return ()

    def target(self, a):
        return ()

    def multiply(self, a, b):
        return self.entries(self.matrix(a) * self.matrix(b))

    def identity(self, q):
        return self.entries(sp.eye(self.n))

    def inverse(self, a):
        return self.entries(self._inverse_matrix(self.matrix(a)))

    def _inverse_matrix(self, M: sp.Matrix) -> sp.Matrix:
        return M.inv()

    #: size of the rotation block (the leading block whose columns are orthonormal on the
    #: group: SO(n), and the linear part of SE(n)); 0 when the group has none
    rotation_block: int = 0

    def renormalised_matrix(self, M: sp.Matrix) -> sp.Matrix:
        """M with its rotation block Q replaced by Q(3I − QᵀQ)/2 (one Newton–Schulz step
        toward the nearest orthogonal matrix; docs/conventions.md §16).

        The identity on the group (QᵀQ = I), so no equation changes; off the group it takes
        the orthogonality defect δ = QᵀQ − I to O(δ²).  Applied to the configuration a step
        stores (q_{k+1} = q_k τ(x), rounded), it keeps q_k on the group to rounding over any
        number of steps instead of letting the defect random-walk — which would otherwise
        break the discrete Noether identity by O(δ·|∂L|) per step.  Groups without a
        rotation block: M itself."""
        m = self.rotation_block
        if not m:
            return M
        entries, template = _renormalised_template(m)
        out = sp.Matrix(M)
        out[:m, :m] = template.xreplace({d: M[i, j] for (i, j), d in entries.items()})
        return out

    def section_curves(self, q, t):
        return [self.entries(self.cayley([t if b == a else 0 for b in range(self.rank)]))
                for a in range(self.rank)]

    # --- retractions ----------------------------------------------------------------------
    @classmethod
    def _cayley_closed_form(cls, x: Sequence) -> sp.Matrix | None:
        """cay(ξ) in closed form where one is known (None: solved symbolically)."""
        return None

    def cayley(self, x: Sequence) -> sp.Matrix:
        """cay(ξ) = (I − ξ/2)⁻¹(I + ξ/2), ξ = Σ x_a E_a (seed 000 §6.1)."""
        return _cayley_template(type(self)).xreplace(dict(zip(_dtau_dummies(type(self)), x)))

    def exp(self, x: Sequence) -> sp.Matrix:
        """exp(ξ), ξ = Σ x_a E_a, in closed form."""
        raise NotImplementedError

    def tau(self, x: Sequence) -> sp.Matrix:
        """The retraction in use (``self.retraction``)."""
        return self.cayley(x) if self.retraction == "cayley" else self.exp(x)

    def translated_retraction(self, q: Sequence, x: Sequence) -> tuple:
        """The entries of q·τ(x): the chart of the group around q (the point reached from q
        by the retraction coordinates x of the increment; seed 000 §6.1)."""
        q, x = self._checked(q, "q", self.arrow_dim), self._checked(x, "x", self.rank)
        if block_of(q, self._free) is not None:  # matrix form: a structured product
            return self.entries(self.matrix(q) * self.tau(list(x)))
        return _instantiated(self, "translated_retraction", (*q, *x))

    def increment_coordinates(self, q: Sequence, p: Sequence) -> tuple:
        """τ⁻¹(q⁻¹p): the retraction coordinates of the increment from q to p (symbolic;
        valid for q, p in the group)."""
        q, p = self._checked(q, "q", self.arrow_dim), self._checked(p, "p", self.arrow_dim)
        if block_of(q, self._free) is not None or block_of(p, self._free) is not None:
            return tuple(self.retraction_inverse(self._inverse_matrix(self.matrix(q))
                                                 * self.matrix(p)))
        return _instantiated(self, "increment_coordinates", (*q, *p))

    def _checked(self, values: Sequence, what: str, size: int) -> tuple:
        """``values`` as a tuple of ``size`` SymPy expressions; :class:`ShapeError` for
        another length, :class:`InputTypeError` for entries that are not expressions."""
        from .._errors import InputTypeError, ShapeError

        if isinstance(values, (str, bytes, dict)) or not hasattr(values, "__len__"):
            raise InputTypeError(f"{self.name}: {what} must be a sequence of {size} "
                                 f"coordinates, got {type(values).__name__}")
        values = tuple(values)
        if len(values) != size:
            raise ShapeError(f"{self.name}: {what} has {len(values)} coordinates, expected "
                             f"{size}")
        out = []
        for i, v in enumerate(values):
            try:
                e = sp.sympify(v, strict=True)
            except (sp.SympifyError, TypeError, ValueError) as exc:
                raise InputTypeError(f"{self.name}: {what}[{i}] is {v!r}, not a number or "
                                     f"expression") from exc
            if not isinstance(e, sp.Expr):
                raise InputTypeError(f"{self.name}: {what}[{i}] is {v!r}, not a number or "
                                     f"expression")
            out.append(e)
        return tuple(out)

    def retraction_inverse(self, M: sp.Matrix) -> sp.Matrix:
        """τ⁻¹(M) symbolically, valid for M in the group."""
        if self.retraction == "cayley":
            return self.cayley_inverse(M)
        return self.log(M)

    def cayley_inverse(self, M: sp.Matrix) -> sp.Matrix:
        """cay⁻¹(g) = 2(g − I)(g + I)⁻¹, as Lie-algebra coordinates."""
        eye = sp.eye(self.n)
        return self.vee(2 * (M - eye) * (M + eye).inv())

    def log(self, M: sp.Matrix) -> sp.Matrix:
        raise NotImplementedError

    def dtau(self, x: Sequence, side: str = "left") -> sp.Matrix:
        """Trivialised tangent of τ at x as a matrix in the basis.

        ``side="left"``:  T_xτ(y) = τ(x)·dτ_x(y);  ``side="right"``:  T_xτ(y) = dτ_x(y)·τ(x).
        """
        return _dtau_template(type(self), self.retraction, side).xreplace(
            dict(zip(_dtau_dummies(type(self)), x)))

    def dtau_inverse(self, x: Sequence, side: str = "left") -> sp.Matrix:
        """(dτ_x)⁻¹, simplified."""
        return _dtau_inverse_template(type(self), self.retraction, side).xreplace(
            dict(zip(_dtau_dummies(type(self)), x)))

    def Ad(self, M: sp.Matrix) -> sp.Matrix:
        """Ad_g as a matrix on Lie-algebra coordinates: columns vee(g E_a g⁻¹)."""
        Minv = self._inverse_matrix(M)
        cols = [self.vee(M * E * Minv) for E in _basis_of(type(self))]
        return sp.Matrix.hstack(*cols)

    def Ad_star(self, M: sp.Matrix) -> sp.Matrix:
        """Ad*_g on g* in the dual basis: ⟨Ad*_g μ, ξ⟩ = ⟨μ, Ad_g ξ⟩, i.e. (Ad_g)ᵀ."""
        return self.Ad(M).T

    # --- fibre chart ----------------------------------------------------------------------
    def arrow_from(self, q, f):
        return tuple(f)

    def fibre_of(self, a):
        return tuple(a)

    def fibre_chart(self, x, source=None):
        return self.entries(self.tau(x))

    def chart_of_fibre(self, f, source=None):
        return tuple(self.retraction_inverse(self.matrix(f)))

    def fibre_chart_inverse(self, f, source=None):
        return tuple(self.numeric_retraction_inverse(self.numeric_matrix([float(v) for v in f])))

    def named_groups(self):
        return {self.symbol_name: self}

    def numeric_retraction_inverse(self, M: np.ndarray) -> np.ndarray:
        """τ⁻¹ of a numeric group element."""
        eye = np.eye(self.n)
        if self.retraction == "cayley":
            xi = 2.0 * (M - eye) @ np.linalg.inv(M + eye)
            return self._numeric_vee(xi)
        return self._numeric_log(M)

    def numeric_tau(self, x: Sequence) -> np.ndarray:
        """τ(x) of numeric coordinates x (NumPy; the symbolic retraction, lambdified once
        per group class and retraction)."""
        from .._errors import DomainError

        x = self._checked(x, "x", self.rank)
        if not all(v.is_number and v.is_finite and v.is_extended_real for v in x):
            raise DomainError(f"{self.name}: τ(x) needs finite real numbers x, got "
                              f"{', '.join(map(str, x))}")
        values = [float(v) for v in x]
        if self.retraction == "cayley":  # (I − ξ/2)⁻¹(I + ξ/2), ξ = Σ x_a E_a: no lambdify
            xi = np.tensordot(values, _numeric_basis(type(self)), axes=1)
            eye = np.eye(self.n)
            try:
                M = np.linalg.solve(eye - xi / 2, eye + xi / 2)
            except np.linalg.LinAlgError:
                M = None
            if M is None or not np.isfinite(M).all():
                raise DomainError(f"{self.name}: cay(x) is undefined at x = "
                                  f"{', '.join(map(str, values))} (I − ξ/2 is singular)")
            return M
        return np.asarray(_numeric_tau(type(self), self.retraction)(*values),
                          float).reshape(self.n, self.n)

    def _numeric_vee(self, xi: np.ndarray) -> np.ndarray:
        B = [np.array(E.tolist(), dtype=float) for E in _basis_of(type(self))]
        rhs = np.array([np.trace(E.T @ xi) for E in B])
        gram_inv = np.array(self._gram_inverse().tolist(), dtype=float)
        return gram_inv @ rhs

    def _numeric_log(self, M: np.ndarray) -> np.ndarray:
        """log of a numeric group element (the symbolic closed form, lambdified once)."""
        return np.asarray(_numeric_log(type(self))(M), float).ravel()

    def random_base_point(self, rng):
        return ()

    def _numeric_matrix(self, c) -> np.ndarray:
        from .._errors import ShapeError

        M = np.asarray(c, dtype=float)
        if M.shape != (self.n, self.n):
            raise ShapeError(f"{self.name}: a configuration is a {self.n}×{self.n} matrix, "
                             f"got shape {M.shape}")
        return M

    def arrow_between(self, c0, c1):
        """R₀⁻¹R₁ for group elements R₀, R₁ (matrices)."""
        M0, M1 = self._numeric_matrix(c0), self._numeric_matrix(c1)
        M = np.linalg.solve(M0, M1)
        return tuple(float(M[i, j]) for i, j in self._free)

    def numeric_matrix(self, coords: Sequence) -> np.ndarray:
        """The full matrix of numeric arrow coordinates (NumPy)."""
        M = np.eye(self.n)
        for (i, j), c in zip(self._free, coords):
            M[i, j] = c
        return M

    def configuration_after(self, c0, a):
        return self._numeric_matrix(c0) @ self.numeric_matrix(a)

    def nearest_element(self, M) -> np.ndarray:
        """The element of the group nearest to the numeric n×n matrix ``M`` (a rotation, or
        a rigid motion, typed or stored to a few digits): its rotation block replaced by the
        orthogonal factor of its polar decomposition, U Vᵀ from the SVD U Σ Vᵀ (the nearest
        rotation in the Frobenius norm, det +1), and for SE(n) the last row set to
        (0, …, 0, 1); the translation is kept."""
        from .._arguments import real_array
        from .._errors import DomainError, ShapeError

        M = real_array(M, "M", owner=self.name)
        if M.shape != (self.n, self.n) or not np.isfinite(M).all():
            raise ShapeError(f"{self.name}: nearest_element needs a finite {self.n}×{self.n} "
                             f"matrix, got shape {M.shape}")
        n = self.n - 1 if self.affine else self.n
        U, _, Vt = np.linalg.svd(M[:n, :n])
        if np.linalg.det(U @ Vt) < 0:
            raise DomainError(f"{self.name}: the rotation block has det < 0 (a reflection); "
                              f"no nearby element of {self.name}")
        out = M.copy()
        out[:n, :n] = U @ Vt
        if self.affine:
            out[-1] = np.eye(self.n)[-1]
        return out

    def increments(self, a):
        return [(self.symbol_name, self, self.numeric_matrix([float(v) for v in a]))]

    def numeric_matrices(self, arrows: np.ndarray) -> np.ndarray:
        """:meth:`numeric_matrix` of every row of ``arrows``: (N, n, n)."""
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        M = np.broadcast_to(np.eye(self.n), (len(arrows), self.n, self.n)).copy()
        for c, (i, j) in enumerate(self._free):
            M[:, i, j] = arrows[:, c]
        return M

    def products(self, start, increments: np.ndarray) -> np.ndarray:
        """R_0 = ``start`` (None: the identity), R_{k+1} = R_k W_k for the matrices W_k of
        ``increments`` (N, n, n): the (N + 1, n, n) partial products."""
        out = np.empty((len(increments) + 1, self.n, self.n))
        out[0] = np.eye(self.n) if start is None else self._numeric_matrix(start)
        for k, W in enumerate(increments):
            np.matmul(out[k], W, out=out[k + 1])
        return out

    def configurations_along(self, arrows, start=None):
        """R_0 = ``start`` (default the identity), R_{k+1} = R_k W_k: the configurations
        whose increments W_k = R_k⁻¹R_{k+1} are the arrows (a Lie group's state)."""
        return self.products(start, self.numeric_matrices(arrows))

    # --- geodesics and configurations (numeric) ----------------------------------------------
    is_lie_group = True

    def configuration(self, value, name, check):
        """A group element (its matrix)."""
        return check.group_element(self, value, name)

    def log_coordinates(self, M: np.ndarray) -> np.ndarray | None:
        """Lie-algebra coordinates x with exp(Σ x_a E_a) = M for a numeric element M, or None
        where they are not available (the closed-form logarithm, lambdified once; SO(3) and
        SE(3) override it with forms accurate up to and including half-turns)."""
        try:
            with np.errstate(all="ignore"):
                x = np.asarray(self._numeric_log(M), float)
        except NotImplementedError:
            return None
        return x if np.isfinite(x).all() else None

    @functools.cached_property
    def exponential_group(self) -> MatrixLieGroup:
        """The same group with the exponential retraction (its fibre chart is exp)."""
        return type(self)(self.symbol_name, retraction="exp")

    def fibre_charts(self, X: np.ndarray) -> np.ndarray:
        """``numeric_fibre_chart(x)`` for every row x of X, in one vectorised call of the
        lambdified chart when it broadcasts (checked on the first and last rows against the
        single-row form), else row by row."""
        q = np.zeros(self.base_dim)
        single = [self.numeric_fibre_chart(x) for x in X[[0, -1]]]
        try:
            with np.errstate(all="ignore"):
                values = self._numeric_fibre_chart(X.T, q)
            rows = np.array([np.broadcast_to(np.asarray(v, float), (len(X),))
                             for v in values]).T
            if rows.shape == (len(X), len(single[0])) and np.isfinite(rows).all() and \
                    np.allclose(rows[[0, -1]], single, rtol=1e-14, atol=1e-15):
                return rows
        except (TypeError, ValueError, AttributeError):
            pass
        return np.array([self.numeric_fibre_chart(x) for x in X])

    def exp_rows(self, X: np.ndarray) -> np.ndarray:
        """exp(Σ x_a E_a) for every row x of X, as arrows (one per row)."""
        return self.exponential_group.fibre_charts(X)

    def geodesic(self, total, s):
        """exp(s·log g), g = ``total`` (defined up to and including half-turns, where the
        Cayley chart is not); the chart path where the logarithm is not available."""
        x = self.log_coordinates(self.numeric_matrix(total))
        if x is None:
            return self.chart_path(total, s)
        return self.exp_rows(np.outer(s, x))

    def configurations_from(self, start, arrows):
        """[R₀, …, R_N]: R₀ = ``start``, R_{k+1} = R_k g_k (matrix products)."""
        out = [start]
        for M in self.numeric_matrices(arrows):
            out.append(out[-1] @ M)
        return out

    def numeric_Ad(self, M: np.ndarray) -> np.ndarray:
        """Ad_g on Lie-algebra coordinates (columns vee(g E_a g⁻¹)) for each matrix of the
        stack ``M`` (N, n, n): (N, rank, rank)."""
        M = np.asarray(M, float)
        E = _numeric_basis(type(self))
        moved = np.einsum("kij,ajl,klm->akim", M, E, np.linalg.inv(M))
        gram = np.array(self._gram_inverse().tolist(), dtype=float)
        traces = np.einsum("bji,akji->kba", E, moved)  # tr(E_bᵀ g E_a g⁻¹)
        return np.einsum("cb,kba->kca", gram, traces)

    def body_to_spatial(self, momenta: np.ndarray, configurations: np.ndarray) -> np.ndarray:
        """Ad*_{c⁻¹} μ = (Ad_{c⁻¹})ᵀ μ for each row μ of ``momenta`` (N, rank) at the
        configuration c of the same row of ``configurations`` (N, n, n); SO(3): c μ."""
        Ad_inverse = self.numeric_Ad(np.linalg.inv(configurations))
        return np.einsum("kab,ka->kb", Ad_inverse, np.asarray(momenta, float))

    def spatial_momenta(self, momenta, arrows, start=None):
        sources = self.configurations_along(arrows, start)[:-1]
        return self.body_to_spatial(momenta, sources)

    # --- naming -----------------------------------------------------------------------------
    def named_matrix(self, offset: int) -> sp.Matrix:
        """g_{k+offset} as a matrix of named entries (g_{k})_{ij}."""
        M = sp.eye(self.n)
        for i, j in self._free:
            M[i, j] = indexed_symbol(self.latex, offset, f"{i + 1}{j + 1}")
        return M

    def named_fibre(self, offset):
        return self.entries(self.named_matrix(offset))

    def named_source(self, offset):
        return ()

    def named_chart(self, offset):
        name = subscripted(self.latex, offset)
        return tuple(StepSymbol(f"(\\tau^{{-1}} {name})_{{{a + 1}}}") for a in range(self.rank))

    def symbols_by_name(self, offset):
        return {self.symbol_name: self.named_matrix(offset)}

    def view(self, coords):
        return MatrixArrow(self, coords)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.symbol_name!r}, retraction={self.retraction!r})"


# --- cached symbolic templates (per group class) --------------------------------------------

def _simplify_matrix(M: sp.Matrix) -> sp.Matrix:
    return M.applyfunc(lambda e: sp.factor(sp.cancel(e)))


@functools.cache
def _renormalised_template(m: int) -> tuple[dict, sp.Matrix]:
    """Q(3I − QᵀQ)/2 on an m×m matrix of placeholders (substituted, not multiplied out
    again, for each matrix: SymPy's matrix product of large entries is slow)."""
    entries = {(i, j): sp.Dummy(f"q{i}{j}") for i in range(m) for j in range(m)}
    stored = _stored_form(f"renormalised.{m}", list(entries.values()))
    return entries, stored if stored is not None else _direct_renormalised(entries, m)


def _direct_renormalised(entries: dict, m: int) -> sp.Matrix:
    Q = sp.Matrix(m, m, lambda i, j: entries[(i, j)])
    return Q * (3 * sp.eye(m) - Q.T * Q) / 2


def _builtin(cls) -> bool:
    """True for the groups defined here (whose templates may be stored)."""
    return cls.__module__ == __name__ and "." not in cls.__qualname__


def _stored_form(key: str, placeholders: Sequence[sp.Symbol]):
    """The template ``key`` as stored in ``groupoids/_closed_forms.py`` (a matrix or a tuple
    of expressions), built on ``placeholders``; None when it is not stored.

    The stored text is the exact tree of the derivation (SymPy's ``srepr`` with the
    placeholders as ``P[i]``, evaluated without SymPy's automatic simplification, so that
    every node is rebuilt as written), written by ``groupoids/_closed_forms_build.py`` and checked
    against the derivation by the tests: evaluating it gives the same expressions as the
    derivation (about 5 ms instead of 20–50 ms per template in every new process: the
    Cayley map's ``factor``, the products of symbolic matrices)."""
    from ._closed_forms import FORMS

    text = FORMS.get(key)
    if text is None:
        return None
    with sp.evaluate(False):  # the tree as written, node for node (factor's forms included)
        return eval(text, {**_stored_namespace(), "P": tuple(placeholders)})  # noqa: S307


@functools.cache
def _stored_namespace() -> dict:
    """The SymPy names a stored template's text refers to."""
    return {name: getattr(sp, name) for name in dir(sp) if not name.startswith("_")}


@functools.cache
def _basis_of(cls) -> tuple[sp.ImmutableMatrix, ...]:
    """The Lie-algebra basis of a group class (``_basis``), made once and immutable."""
    return tuple(sp.ImmutableMatrix(E) for E in cls._basis())


#: (group class, retraction, map) → (placeholders, entries): the maps of
#: :func:`_instantiated`, derived once per kind of group
_MAP_TEMPLATES: dict[tuple, tuple[tuple, tuple]] = {}


def _instantiated(group: MatrixLieGroup, name: str, values: Sequence) -> tuple:
    """``group.<name>(…)`` at ``values``: the map derived once on placeholders for every
    group of the same class and retraction (the class fixes the basis, the free entries and
    the structure maps), then substituted.  SymPy's products of symbolic matrices cost
    about 10–20 ms per group element (3D chain of 8 bodies: 0.3 s of its derivation);
    a substitution about 0.5 ms."""
    key = (type(group), group.retraction, name)
    template = _MAP_TEMPLATES.get(key)
    if template is None:
        placeholders = tuple(sp.Dummy(f"a{i}") for i in range(len(values)))
        stored = (_stored_form(f"{type(group).__name__}.{group.retraction}.{name}",
                               placeholders) if _builtin(type(group)) else None)
        entries = stored if stored is not None else _direct_map(group, name, placeholders)
        template = (placeholders, entries)
        _MAP_TEMPLATES[key] = template
    placeholders, entries = template
    sub = dict(zip(placeholders, (sp.sympify(v) for v in values)))
    return tuple(e.xreplace(sub) for e in entries)


def _direct_map(group: MatrixLieGroup, name: str, placeholders: Sequence) -> tuple:
    """The map ``name`` of :func:`_instantiated` derived on ``placeholders``."""
    direct = {"translated_retraction": _direct_translated_retraction,
              "increment_coordinates": _direct_increment_coordinates}[name]
    return tuple(sp.sympify(e) for e in direct(group, placeholders))


def _direct_translated_retraction(group: MatrixLieGroup, values: Sequence) -> tuple:
    q, x = values[:group.arrow_dim], values[group.arrow_dim:]
    return group.entries(group.matrix(q) * group.tau(list(x)))


def _direct_increment_coordinates(group: MatrixLieGroup, values: Sequence) -> tuple:
    q, p = values[:group.arrow_dim], values[group.arrow_dim:]
    return tuple(group.retraction_inverse(group._inverse_matrix(group.matrix(q))
                                          * group.matrix(p)))


@functools.cache
def _dtau_dummies(cls) -> tuple:
    return tuple(sp.Dummy(f"y{a}", real=True) for a in range(len(_basis_of(cls))))


@functools.cache
def _cayley_template(cls) -> sp.Matrix:
    x = _dtau_dummies(cls)
    stored = _stored_form(f"{cls.__name__}.cayley", x) if _builtin(cls) else None
    return stored if stored is not None else _direct_cayley(cls, x)


def _direct_cayley(cls, x: Sequence) -> sp.Matrix:
    closed = cls._cayley_closed_form(x)
    if closed is not None:  # the same canonical form as below, without the symbolic solve
        return closed.applyfunc(lambda e: sp.factor(sp.together(e)))
    X = cls.hat(x)
    eye = sp.eye(cls.n)
    M = (eye - X / 2).LUsolve(eye + X / 2)
    return _simplify_matrix(M)


def _tau_template(cls, retraction: str) -> sp.Matrix:
    x = _dtau_dummies(cls)
    if retraction == "cayley":
        return _cayley_template(cls)
    return cls._exp_closed_form(x)


@functools.cache
def _dtau_template(cls, retraction: str, side: str) -> sp.Matrix:
    x = _dtau_dummies(cls)
    T = _tau_template(cls, retraction)
    Tinv = cls._inverse_closed_form(T)
    cols = []
    for xa in x:
        dT = T.diff(xa)
        prod = Tinv * dT if side == "left" else dT * Tinv
        cols.append(cls.vee(prod))
    D = sp.Matrix.hstack(*cols)
    return D.applyfunc(_tidy(retraction))


@functools.cache
def _dtau_inverse_template(cls, retraction: str, side: str) -> sp.Matrix:
    D = _dtau_template(cls, retraction, side)
    if retraction == "cayley":
        return D.inv().applyfunc(_tidy(retraction))
    # exp: the entries hold the smooth special functions; an LU inverse without zero-testing
    # simplification stays fast (the result is exact, not simplified)
    return D.inv(method="LU", iszerofunc=lambda e: e.is_zero is True)


def _tidy(retraction: str):
    """Cayley: rational entries, put in lowest terms.  exp: left as derived (simplifying
    expressions in the smooth special functions gains little and costs much)."""
    if retraction == "cayley":
        return lambda e: sp.factor(sp.cancel(e))
    return lambda e: e


@functools.cache
def _numeric_basis(cls) -> np.ndarray:
    """The Lie algebra basis E_a as a (rank, n, n) array."""
    return np.array([np.array(E.tolist(), dtype=float) for E in _basis_of(cls)])


@functools.cache
def _numeric_tau(cls, retraction: str):
    return sp.lambdify(list(_dtau_dummies(cls)), list(_tau_template(cls, retraction)),
                       NUMPY_MODULES)


@functools.cache
def _numeric_log(cls):
    M = sp.MatrixSymbol("M", cls.n, cls.n)
    return sp.lambdify([M], list(cls("log", retraction="exp").log(sp.Matrix(M))), NUMPY_MODULES)


# --- the built-in groups --------------------------------------------------------------------

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

    def exp(self, x):
        return self._exp_closed_form(x)

    def cayley_inverse(self, M):
        # on SO(2): cay⁻¹(R) = 2(R − Rᵀ)/(2 + tr R)
        return self.vee(2 * (M - M.T) / (2 + M.trace())).applyfunc(sp.cancel)

    def log(self, M):
        return sp.Matrix([sp.atan2(M[1, 0], M[0, 0])])


class SO3(MatrixLieGroup):
    """Rotations of space; so(3) basis E₁, E₂, E₃ of seed 000 §6.2 (ω̂ = Σ ω_a E_a)."""

    n = 3
    group_name = "SO3"
    rotation_block = 3

    @classmethod
    def _basis(cls):
        return [hat3((1, 0, 0)), hat3((0, 1, 0)), hat3((0, 0, 1))]

    @classmethod
    def _cayley_closed_form(cls, x):
        """cay(ξ) = I + 4/(4 + |x|²)(ξ + ξ²/2) (seed 000 §6.1), ξ = x̂."""
        X = cls.hat(x)
        return sp.eye(3) + 4 / (4 + sum(v**2 for v in x)) * (X + X * X / 2)

    def _inverse_matrix(self, M):
        return M.T

    @staticmethod
    def _inverse_closed_form(M):
        return M.T

    @classmethod
    def _exp_closed_form(cls, x):
        """Rodrigues: I + A(θ²) x̂ + B(θ²) x̂², A = sin θ/θ, B = (1 − cos θ)/θ² (smooth at 0)."""
        th2 = x[0] ** 2 + x[1] ** 2 + x[2] ** 2
        W = hat3(x)
        return sp.eye(3) + SinOverTheta(th2) * W + OneMinusCosOverTheta2(th2) * W * W

    def exp(self, x):
        return self._exp_closed_form(x)

    def log_coordinates(self, M):
        """ω with exp(ω̂) = R, θ = |ω| ∈ [0, π] (:func:`so3_log`)."""
        return so3_log(M)

    def exp_rows(self, X):
        """Rodrigues' formula for every row (:func:`so3_exp_rows`)."""
        return so3_exp_rows(X)

    def cayley_inverse(self, M):
        # on SO(3): cay⁻¹(R) = 2(R − Rᵀ)/(1 + tr R)   (from seed 001 eq. (63))
        return self.vee(2 * (M - M.T) / (1 + M.trace()))

    def log(self, M):
        """θ/(2 sin θ)·vee(R − Rᵀ), the coefficient a smooth function of cos θ = (tr R − 1)/2."""
        return self.vee(ThetaOverTwoSin((M.trace() - 1) / 2) * (M - M.T))


class _SpecialEuclidean(MatrixLieGroup):
    affine = True
    rot: type[MatrixLieGroup]

    @classmethod
    def _split(cls, x):
        r = len(_basis_of(cls.rot))
        return x[:r], x[r:]

    @classmethod
    def hat(cls, x):
        w, v = cls._split(list(x))
        m = cls.n - 1
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

    def exp(self, x):
        return self._exp_closed_form(x)


class SE2(_SpecialEuclidean):
    """Rigid motions of the plane; se(2) coordinates (ω, v₁, v₂)."""

    n = 3
    group_name = "SE2"
    rotation_block = 2
    rot = SO2

    @classmethod
    def _basis(cls):
        return [cls.hat([1, 0, 0]), cls.hat([0, 1, 0]), cls.hat([0, 0, 1])]

    @classmethod
    def hat(cls, x):
        out = sp.zeros(3, 3)
        out[:2, :2] = SO2.hat([x[0]])
        out[0, 2], out[1, 2] = x[1], x[2]
        return out

    @staticmethod
    def _V(w):
        """[[sin θ/θ, −(1 − cos θ)/θ], [(1 − cos θ)/θ, sin θ/θ]] with smooth coefficients."""
        th = w[0]
        A, B = SinOverTheta(th ** 2), th * OneMinusCosOverTheta2(th ** 2)
        return sp.Matrix([[A, -B], [B, A]])

    @staticmethod
    def _V_inverse(w):
        """V⁻¹ = [[a, θ/2], [−θ/2, a]], a = (θ/2) cot(θ/2)."""
        th = w[0]
        a = HalfThetaCotHalfTheta(th ** 2)
        return sp.Matrix([[a, th / 2], [-th / 2, a]])


class SE3(_SpecialEuclidean):
    """Rigid motions of space; se(3) coordinates (ω₁, ω₂, ω₃, v₁, v₂, v₃)."""

    n = 4
    group_name = "SE3"
    rotation_block = 3
    rot = SO3

    @classmethod
    def _basis(cls):
        return [cls.hat([1 if i == a else 0 for i in range(6)]) for a in range(6)]

    @classmethod
    def hat(cls, x):
        out = sp.zeros(4, 4)
        out[:3, :3] = hat3(x[:3])
        out[0, 3], out[1, 3], out[2, 3] = x[3], x[4], x[5]
        return out

    def log_coordinates(self, M):
        """(ω, V(ω)⁻¹u) for M = [[R, u], [0, 1]], ω = log R (:func:`so3_log`)."""
        w = so3_log(M[:3, :3])
        return np.concatenate([w, np.asarray(_se3_v_inverse()(w), float) @ M[:3, 3]])

    @staticmethod
    def _V(w):
        """I + B(θ²) ω̂ + C(θ²) ω̂², C = (θ − sin θ)/θ³."""
        th2 = w[0] ** 2 + w[1] ** 2 + w[2] ** 2
        W = hat3(w)
        return (sp.eye(3) + OneMinusCosOverTheta2(th2) * W
                + ThetaMinusSinOverTheta3(th2) * W * W)

    @staticmethod
    def _V_inverse(w):
        """I − ω̂/2 + D(θ²) ω̂², D = (1 − (θ/2) cot(θ/2))/θ²."""
        th2 = w[0] ** 2 + w[1] ** 2 + w[2] ** 2
        W = hat3(w)
        return sp.eye(3) - W / 2 + SE3LogCoefficient(th2) * W * W


def so3_log(R: np.ndarray) -> np.ndarray:
    """ω with exp(ω̂) = R for a rotation R, θ = |ω| ∈ [0, π]; accurate at and near a
    half-turn, where θ/(2 sin θ)·vee(R − Rᵀ) is 0·∞ (there the axis is read off the
    symmetric part: (R + Rᵀ)/2 − cos θ·I = (1 − cos θ)·a aᵀ)."""
    c = float(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))
    s_axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    s = float(np.linalg.norm(s_axis))  # sin θ
    theta = float(np.arctan2(s, c))
    if c > -0.5:
        return s_axis * (theta / s if s > 1e-12 else 1.0 + s * s / 6.0)
    B = (R + R.T) / 2.0 - c * np.eye(3)
    i = int(np.argmax(np.diag(B)))
    axis = B[:, i] / np.sqrt(max(B[i, i], 1e-300) * (1.0 - c))
    if axis @ s_axis < 0:
        axis = -axis
    return theta * axis / np.linalg.norm(axis)


def so3_exp_rows(W: np.ndarray) -> np.ndarray:
    """exp(ω̂) for every row ω of W (Rodrigues, sin θ/θ and (1 − cos θ)/θ² by their series
    near θ = 0), as arrows of SO(3) (the nine entries, row-major)."""
    theta = np.linalg.norm(W, axis=1)
    small = theta < 1e-4
    t = np.where(small, 1.0, theta)
    a = np.where(small, 1 - theta ** 2 / 6, np.sin(t) / t)
    b = np.where(small, 0.5 - theta ** 2 / 24, (1 - np.cos(t)) / t ** 2)
    K = np.zeros((len(W), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -W[:, 2], W[:, 1], -W[:, 0]
    K -= np.swapaxes(K, 1, 2)
    R = np.eye(3) + a[:, None, None] * K + b[:, None, None] * (K @ K)
    return R.reshape(len(W), 9)


@functools.cache
def _se3_v_inverse():
    w = sp.symbols("w1:4", real=True)
    return sp.lambdify([w], SE3._V_inverse(w), NUMPY_MODULES)
