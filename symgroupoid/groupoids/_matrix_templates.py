"""Symbolic templates of the matrix Lie groups, derived once per group class and
retraction on placeholders (or read from the stored closed forms) and substituted: the
Cayley map, τ, dτ, dτ⁻¹, the translated retraction and increment coordinates, the
renormalisation, the numeric retraction and logarithm."""

from __future__ import annotations

import functools
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from .._lambdify import NUMPY_MODULES

if TYPE_CHECKING:
    from ._matrix_groups import MatrixLieGroup



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
    """True for the library's groups SO2, SO3, SE2, SE3, each defined in the module of its
    name (their templates may be stored; a subclass derives its own)."""
    return (cls.__module__ == f"{__package__}._{cls.__name__.lower()}"
            and "." not in cls.__qualname__)


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
