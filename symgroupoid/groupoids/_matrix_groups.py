"""Matrix Lie groups as groupoids over a point: the shared base of SO(2), SO(3), SE(2), SE(3)
(one module each: ``_so2``, ``_so3``, ``_se2``, ``_se3`` over ``_special_euclidean``; their
symbolic templates in ``_matrix_templates``).

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

from .._arguments import choice_argument, name_argument, sequence_argument, shown_value
from .._errors import InputTypeError, ShapeError
from .._symbols import (
    StepSymbol,
    indexed_symbol,
    latex_name,
    printable_name,
    scalar_expression,
    scalar_expressions,
    subscripted,
)
from ._base import Arrow, Groupoid
from ._matrix_form import StructuredMatrix, block_of, named_basis
from ._matrix_templates import (
    _basis_of,
    _cayley_template,
    _dtau_dummies,
    _dtau_inverse_template,
    _dtau_template,
    _instantiated,
    _numeric_basis,
    _numeric_log,
    _numeric_tau,
    _renormalised_template,
)

_named_basis = functools.cache(named_basis)

RETRACTIONS = ("cayley", "exp")


def _finite_expression(value, what: str, owner: str) -> sp.Expr:
    """``value`` as a SymPy expression: an :class:`InputTypeError` for what is not a number
    or expression, a :class:`DomainError` for a number that is not finite (NaN, ±∞)."""
    from .._errors import DomainError

    e = scalar_expression(value)
    if e is None:
        raise InputTypeError(f"{owner}: {what} is {shown_value(value)}, not a number or "
                             f"expression")
    if e.has(sp.nan, sp.oo, -sp.oo, sp.zoo):
        raise DomainError(f"{owner}: {what} is {e}, not a finite number")
    return e


def hat3(w: Sequence) -> sp.Matrix:
    """ω ↦ ω̂ with ω̂ v = ω × v (the so(3) hat map, E₁, E₂, E₃ basis).  ``w``: three
    numbers or SymPy scalars (a list, tuple, array or 3-vector); anything else is an
    :class:`~symgroupoid.InputTypeError` or :class:`~symgroupoid.ShapeError` naming ``w``."""
    w = sequence_argument(list(w) if isinstance(w, sp.MatrixBase) else w, "w", owner="hat3")
    if len(w) != 3:
        raise ShapeError(f"hat3: w must have 3 components, got {len(w)}")
    try:
        x = [sp.sympify(w[i], strict=True) for i in range(3)]
    except (sp.SympifyError, TypeError, ValueError, AttributeError) as exc:
        raise InputTypeError(f"hat3: w must be three scalars, got {shown_value(w)}") from exc
    if not all(isinstance(v, sp.Expr) and not isinstance(v, sp.MatrixBase) for v in x):
        raise InputTypeError(f"hat3: w must be three scalars, got {shown_value(w)}")
    return sp.Matrix([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])


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


#: tolerance of the group-membership check of matrices (|RᵀR − I|, |det R − 1|, the fixed
#: last row of SE(n); :meth:`MatrixLieGroup.deviations`): far above the rounding of a
#: product of many rotations, far below any matrix that is not a rotation
GROUP_TOLERANCE = 1e-9


class MatrixLieGroup(Groupoid):
    """A matrix Lie group given by its Lie algebra basis and inversion.

    Subclasses set ``n`` (matrix size), ``basis`` (list of n×n matrices), ``affine``
    (SE(n): last row fixed to (0, …, 0, 1)) and the closed-form exponential and logarithm.
    """

    n: int = 0
    affine: bool = False
    group_name: str = "G"

    def __init__(self, name: str = "g", retraction: str = "cayley"):
        name = printable_name(name_argument(name, "the group's name", owner=self.group_name),
                              "the group's name", self.group_name, words=False)
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
        x = cls._hat_coordinates(x, len(_basis_of(cls)))
        out = sp.zeros(cls.n, cls.n)
        for xa, E in zip(x, _basis_of(cls)):
            out += xa * E
        return sp.Matrix(out)

    @classmethod
    def _hat_coordinates(cls, x: Sequence, size: int) -> list:
        """``x`` as a list of ``size`` coordinates (one per basis element E_a); an
        :class:`InputTypeError` for what is not a sequence, a :class:`ShapeError` for
        another length."""
        owner = f"{cls.__name__}.hat"
        x = sequence_argument(x, "x", owner=owner)
        if len(x) != size:
            raise ShapeError(f"{owner}: x has {len(x)} coordinates, expected {size} (one per "
                             f"basis element E_a)")
        return [_finite_expression(v, f"x[{i}]", owner) for i, v in enumerate(x)]

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
        x = self.algebra_coordinates(x)
        return _cayley_template(type(self)).xreplace(dict(zip(_dtau_dummies(type(self)), x)))

    def exp(self, x: Sequence) -> sp.Matrix:
        """exp(ξ), ξ = Σ x_a E_a, in closed form."""
        return self._exp_closed_form(self.algebra_coordinates(x))

    @classmethod
    def _exp_closed_form(cls, x: Sequence) -> sp.Matrix:
        raise NotImplementedError

    def algebra_coordinates(self, x: Sequence, what: str = "x") -> tuple:
        """``x`` as the rank coordinates of ξ = Σ x_a E_a: a :class:`ShapeError` for another
        length, :class:`InputTypeError` for entries that are not numbers or expressions,
        :class:`DomainError` for a number that is not finite (NaN, ±∞)."""
        values = self._checked(x, what, self.rank)
        return tuple(_finite_expression(v, f"{what}[{i}]", self.name)
                     for i, v in enumerate(values))

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
        try:
            values = tuple(values)
        except TypeError as exc:  # e.g. a 0-d array: sized by its class, not iterable
            raise InputTypeError(f"{self.name}: {what} must be a sequence of {size} "
                                 f"coordinates, got {shown_value(values)}") from exc
        if len(values) != size:
            raise ShapeError(f"{self.name}: {what} has {len(values)} coordinates, expected "
                             f"{size}")
        out, bad = scalar_expressions(values)
        if bad is not None:
            raise InputTypeError(f"{self.name}: {what}[{bad}] is {values[bad]!r}, not a number "
                                 f"or expression")
        return out

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
        if M.shape != (self.n, self.n):
            raise ShapeError(f"{self.name}: nearest_element needs a {self.n}×{self.n} "
                             f"matrix, got shape {M.shape}")
        if not np.isfinite(M).all():
            raise DomainError(f"{self.name}: nearest_element needs a finite matrix, got "
                              f"non-finite entries at {np.argwhere(~np.isfinite(M)).tolist()}")
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

    def numeric_coordinates(self, M: np.ndarray) -> np.ndarray:
        """The arrow coordinates (free entries) of a numeric matrix: the inverse of
        :meth:`numeric_matrix` on the group."""
        return np.array([M[i, j] for i, j in self._free], float)

    def point_geodesic(self, q0: Sequence, q1: Sequence, s: np.ndarray) -> np.ndarray:
        """Points q(sᵢ) = q₀·exp(sᵢ log(q₀⁻¹q₁)) from q₀ to q₁ (coordinates, one row per
        entry of ``s``): the group's geodesic, defined through half-turns, where the Cayley
        chart of q₀⁻¹q₁ is not."""
        Q0 = self.numeric_matrix([float(v) for v in q0])
        relative = np.linalg.solve(Q0, self.numeric_matrix([float(v) for v in q1]))
        path = self.numeric_matrices(self.geodesic(self.numeric_coordinates(relative), s))
        return np.array([self.numeric_coordinates(Q0 @ M) for M in path])

    def deviations(self, M: np.ndarray) -> np.ndarray:
        """How far each matrix of ``M`` (..., n, n) is from the group: the largest of
        |RᵀR − I|, |det R − 1| for its rotation block R and, for an affine group, the
        distance of its last row from (0, …, 0, 1); shape (...)."""
        M = np.asarray(M, float)
        n = self.n - 1 if self.affine else self.n
        R = M[..., :n, :n]
        off = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(n)).max(axis=(-1, -2))
        worst = np.maximum(off, np.abs(np.linalg.det(R) - 1.0))
        if self.affine:
            worst = np.maximum(worst, np.abs(M[..., -1, :] - np.eye(self.n)[-1]).max(-1))
        return worst

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
