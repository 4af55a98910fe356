"""Matrix-valued arrow parts kept as matrices: the form the papers print.

In *matrix form* the group part of an arrow is a SymPy ``MatrixSymbol`` g_k rather than its
entries, and user code sees it through :class:`StructuredMatrix`, which supports what a
Lagrangian needs (products with constant matrices, transpose, trace, entries, inverse).
Lie-algebra basis matrices appear by name (E_1, E_2, …), so a constraint
``tr(g E_1)`` varied along the left-invariant section E_2 prints as ``tr(g_k E_2 E_1)``
(seed 000 §6.2), not as a nine-term sum.

:func:`directional_derivative` differentiates a scalar expression in trace and entry atoms
along a matrix direction V: d/dt f(M + tV)|_{t=0}, by the product rule on matrix words.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import sympy as sp
from sympy.core.symbol import Str
from sympy.matrices.expressions.matexpr import MatrixElement

from .._arguments import name_argument
from .._errors import DomainError, InputTypeError


class NamedMatrix(sp.ImmutableDenseMatrix):
    """A constant matrix with a LaTeX name, e.g. ``NamedMatrix(J, name="J_d")``.

    It behaves as the SymPy matrix it holds; in printed (matrix-form) equations it appears
    by name: ``tr(W_k E_1 J_d)`` rather than with its entries.
    """

    latex_name: str | None = None

    def __new__(cls, *args, name: str | None = None):
        if name is not None:
            name = name_argument(name, "name", owner="NamedMatrix")
        label = f"NamedMatrix{'' if name is None else f' {name}'}"
        if any(isinstance(a, (str, bytes)) for a in args):
            raise InputTypeError(f"{label}: the matrix must be what sympy.Matrix takes (rows "
                                 f"of scalars, or rows, columns and entries); got {args!r}")
        try:
            obj = super().__new__(cls, *args)
        except (TypeError, ValueError, IndexError, AttributeError, NotImplementedError,
                sp.SympifyError) as exc:
            raise InputTypeError(f"{label}: the matrix must be what sympy.Matrix takes (rows "
                                 f"of scalars, or rows, columns and entries); {exc}") from exc
        if any(e.has(sp.nan, sp.zoo, sp.oo, -sp.oo) or e.is_extended_real is False
               for e in obj if isinstance(e, sp.Basic)):
            raise DomainError(f"{label}: the entries must be real and finite (a constant of "
                              f"the equations), got {obj.tolist()}")
        if name is not None:
            obj.latex_name = name
        return obj


#: digest of a constant's value → the value (content-addressed: a digest names one value)
_VALUES: dict = {}


class ConstantMatrix(sp.MatrixSymbol):
    """A :class:`NamedMatrix` in a matrix-form expression: a MatrixSymbol that prints as its
    name (``J_d``) and holds, as a hidden argument, the digest of its value, so that two
    constants of one name but different values (two systems' ``J_d``) are different symbols,
    and writing an expression out needs nothing but the expression (:func:`to_explicit`)."""

    def __new__(cls, name, *shape_and_value):
        last = shape_and_value[-1]
        if isinstance(last, Str):  # rebuilt from its arguments
            digest = last
            n, m = shape_and_value[:2]
        else:
            value = sp.ImmutableMatrix(last)
            digest = Str(hashlib.sha256(sp.srepr(value).encode()).hexdigest()[:20])
            _VALUES.setdefault(digest.name, value)
            n, m = value.shape
        name = Str(name) if isinstance(name, str) else name
        return sp.Basic.__new__(cls, name, sp.Integer(n), sp.Integer(m), digest)

    @property
    def value(self) -> sp.ImmutableMatrix:
        """The matrix the name stands for."""
        return _VALUES[self.args[3].name]


def named_constants(expr) -> dict:
    """ConstantMatrix → value for the named constant matrices in ``expr``."""
    return {c: c.value for c in sp.sympify(expr).atoms(ConstantMatrix)}


def is_constant_matrix(symbol) -> bool:
    """Whether a MatrixSymbol of a matrix form stands for a named constant matrix (J_d)."""
    return isinstance(symbol, ConstantMatrix)


class StructuredMatrix:
    """A matrix expression (SymPy ``MatrixExpr``) with the ``Matrix`` methods user code uses."""

    _op_priority = 20.0  # ahead of SymPy's Matrix, so Matrix * StructuredMatrix comes here

    def __init__(self, expr: sp.MatrixExpr, names: dict | None = None):
        self.expr = expr
        self.names = names or {}  # ImmutableMatrix value -> named MatrixSymbol

    # --- conversion -------------------------------------------------------------------------
    def _wrap(self, expr) -> StructuredMatrix:
        return StructuredMatrix(expr, self.names)

    def _operand(self, other):
        if isinstance(other, StructuredMatrix):
            return other.expr
        if isinstance(other, sp.MatrixBase):
            name = getattr(other, "latex_name", None)
            value = sp.ImmutableMatrix(other)
            if name is not None:
                return ConstantMatrix(name, value)
            return self.names.get(value, value)
        if isinstance(other, sp.MatrixExpr):
            return other
        return None

    # --- arithmetic -------------------------------------------------------------------------
    def __mul__(self, other):
        op = self._operand(other)
        if op is None:
            return self._wrap(sp.MatMul(sp.sympify(other), self.expr))
        return self._wrap(sp.MatMul(self.expr, op))

    __matmul__ = __mul__

    def __rmul__(self, other):
        op = self._operand(other)
        if op is None:
            return self._wrap(sp.MatMul(sp.sympify(other), self.expr))
        return self._wrap(sp.MatMul(op, self.expr))

    __rmatmul__ = __rmul__

    def __truediv__(self, other):
        return self * (1 / sp.sympify(other))

    def __add__(self, other):
        op = self._operand(other)
        if op is None:
            return NotImplemented
        return self._wrap(sp.MatAdd(self.expr, op))

    __radd__ = __add__

    def __neg__(self):
        return self._wrap(sp.MatMul(-1, self.expr))

    def __sub__(self, other):
        op = self._operand(other)
        if op is None:
            return NotImplemented
        return self._wrap(sp.MatAdd(self.expr, sp.MatMul(-1, op)))

    def __rsub__(self, other):
        op = self._operand(other)
        if op is None:
            return NotImplemented
        return self._wrap(sp.MatAdd(op, sp.MatMul(-1, self.expr)))

    # --- Matrix API ----------------------------------------------------------------------------
    @property
    def T(self) -> StructuredMatrix:
        return self._wrap(sp.Transpose(self.expr))

    def transpose(self) -> StructuredMatrix:
        return self.T

    def inv(self) -> StructuredMatrix:
        return self._wrap(sp.Inverse(self.expr))

    def trace(self) -> sp.Expr:
        return sp.Trace(self.expr)

    @property
    def shape(self) -> tuple:
        return self.expr.shape

    def __getitem__(self, key):
        if isinstance(key, tuple):
            return self.expr[key]
        rows, cols = self.shape
        return self.expr[key // cols, key % cols]

    def __len__(self) -> int:
        rows, cols = self.shape
        return rows * cols

    def __iter__(self):
        rows, cols = self.shape
        return (self.expr[i, j] for i in range(rows) for j in range(cols))

    def __repr__(self) -> str:
        return f"StructuredMatrix({self.expr})"


def named_basis(group_cls) -> dict:
    """ImmutableMatrix value of each basis element → a :class:`ConstantMatrix` named E_a
    (a document defines it in its "where" list: its signs decide the equations')."""
    basis = group_cls.basis_matrices()
    if len(basis) == 1:
        return {basis[0]: ConstantMatrix("E", basis[0])}
    return {E: ConstantMatrix(f"E_{{{a + 1}}}", E) for a, E in enumerate(basis)}


def block_of(coords: Sequence, free: Sequence[tuple[int, int]]):
    """The MatrixSymbol M if ``coords`` are exactly its entries at ``free``; else None."""
    if not coords or not all(isinstance(c, MatrixElement) for c in coords):
        return None
    M = coords[0].parent
    if not isinstance(M, sp.MatrixSymbol):
        return None
    for c, (i, j) in zip(coords, free):
        if c.parent != M or (c.i, c.j) != (i, j):
            return None
    return M


def matrix_entries(M: sp.MatrixSymbol, free: Sequence[tuple[int, int]]) -> tuple:
    """The entries M[i, j] at ``free``."""
    return tuple(M[i, j] for i, j in free)


# --- differentiation along a matrix direction -----------------------------------------------

def _dmat(X, M, V):
    """Derivative of the matrix expression X(M) along V (None where it vanishes)."""
    if X == M:
        return V
    if not X.has(M):
        return None
    if isinstance(X, sp.Transpose):
        d = _dmat(X.arg, M, V)
        return None if d is None else sp.Transpose(d)
    if isinstance(X, sp.Inverse):
        d = _dmat(X.arg, M, V)
        return None if d is None else sp.MatMul(-1, X, d, X)
    if isinstance(X, sp.MatAdd):
        terms = [d for d in (_dmat(a, M, V) for a in X.args) if d is not None]
        return sp.MatAdd(*terms) if terms else None
    if isinstance(X, sp.MatMul):
        terms = []
        for i, a in enumerate(X.args):
            if not a.has(M):
                continue
            if not isinstance(a, sp.MatrixExpr):
                raise NotImplementedError(f"scalar factor {a} depends on {M}")
            d = _dmat(a, M, V)
            if d is not None:
                terms.append(sp.MatMul(*X.args[:i], d, *X.args[i + 1:]))
        return sp.MatAdd(*terms) if terms else None
    raise NotImplementedError(f"cannot differentiate {type(X).__name__} along a matrix")


def _datom(atom, M, V):
    if isinstance(atom, sp.Trace):
        d = _dmat(atom.arg, M, V)
        return sp.S.Zero if d is None else sp.Trace(d)
    d = _dmat(atom.parent, M, V)
    return sp.S.Zero if d is None else d[atom.i, atom.j]


def directional_derivative(f: sp.Expr, M: sp.MatrixSymbol, V: sp.MatrixExpr) -> sp.Expr:
    """d/dt f(M + tV) at t = 0, f a scalar expression in trace/entry atoms of M."""
    atoms = [a for a in f.atoms(sp.Trace, MatrixElement) if a.has(M)]
    if not atoms:
        return sp.S.Zero
    stand_in = {a: sp.Dummy("m") for a in atoms}
    g = f.xreplace(stand_in)
    back = {d: a for a, d in stand_in.items()}
    total = sp.S.Zero
    for a, d in stand_in.items():
        coeff = sp.diff(g, d)
        if coeff != 0:
            total += coeff.xreplace(back) * _datom(a, M, V)
    return total


def to_explicit(expr, values: dict):
    """Replace MatrixSymbols by explicit matrices (``values``; named constants by their
    own values) and evaluate traces/products/entries."""
    return sp.expand(expr.xreplace({**named_constants(expr), **values}).doit())
