"""The matrix parts of a step's printed forms: which are kept by name, which are evaluated.

Matrix parts (tr(g_k E_i E_j), W_kᵀΓ_k) and Ad*_{g_k} keep their names; what would print
with the numbers of a constant matrix (an entry (E_a)_{ij}, an entry of a product with one, a
trace with an explicit matrix) is evaluated, and a matrix form with no matrix left to name is
not offered (the explicit residuals print alike).  The matrix form itself, and the values of
its matrix symbols, are the derivation's (:func:`~symgroupoid.derivation.matrix_form_values`,
:attr:`StepEquations.structured`).
"""

from __future__ import annotations

import weakref
from collections.abc import Mapping, Sequence

import sympy as sp
from sympy.matrices.expressions.matexpr import MatrixElement

from .._errors import SymgroupoidError
from ..derivation import evaluate_system, matrix_form_values, window

#: what building a form in named pieces may raise for a system it does not fit (a Lagrangian
#: that does not take pieces, a groupoid without pair coordinates): that form is not offered
NOT_IN_PIECES = (SymgroupoidError, AttributeError, TypeError, ValueError, NotImplementedError)

# --- the step's system ---------------------------------------------------------------------------


def junction_system(step):
    """The system whose step is the junction variation of L (+ λ·φ), if that is what
    ``step`` is; None otherwise (nonholonomic, reconstruction, …)."""
    from ._system import DiscreteSystem

    system = step.system
    if not isinstance(system, DiscreteSystem) or step.order != system._arity:
        return None
    return system


def matrix_values(step) -> dict:
    """MatrixSymbols of the step's matrix form → explicit matrices, its named constants (J_d)
    included (empty without one)."""
    from ..groupoids import named_constants

    if step.structured is None:
        return {}
    values = matrix_form_values(step.groupoid, window(step.order)[0])
    for e in step.structured:
        values.update(named_constants(e))
    return values


# --- constant matrix parts evaluated ------------------------------------------------------------


def constant_matrices(G) -> set:
    """The MatrixSymbols of G's matrix form that stand for constant matrices: the Lie-algebra
    basis E_a of each matrix part (the named constants, J_d, are known by their type,
    :func:`is_constant`)."""
    out: set = set()
    for _, group in G.matrix_parts():
        out.update(group.named_basis().values())
    return out


def is_constant(symbol, constants: set) -> bool:
    """Whether a MatrixSymbol stands for a constant matrix: one of ``constants``
    (:func:`constant_matrices`) or a named constant (J_d)."""
    from ..groupoids import is_constant_matrix

    return symbol in constants or is_constant_matrix(symbol)


def kept_by_name(atom, constants: set) -> bool:
    """Whether a matrix atom of the matrix form prints as the papers write it: an entry of a
    group matrix ((g_{k})_{12}), or the trace of a product of named matrices at least one of
    which is a group matrix (tr(g_k E_1 E_2), tr(J_d W_k E_1)).  Entries of constant matrices
    and of products ((E_1)_{23}, (W_k E_1)_{21}) and traces with an explicit matrix or of
    constants only are not: they are numbers, or sums of entries, when written out."""
    if isinstance(atom, MatrixElement):
        return isinstance(atom.parent, sp.MatrixSymbol) and not is_constant(atom.parent,
                                                                             constants)
    symbols = atom.arg.atoms(sp.MatrixSymbol)
    explicit = any(isinstance(a, sp.MatrixBase) for a in sp.preorder_traversal(atom.arg))
    return not explicit and any(not is_constant(s, constants) for s in symbols)


def evaluated_constants(expr: sp.Expr, values: Mapping, constants: set) -> sp.Expr:
    """``expr`` (in the matrix form) with every matrix atom that is not
    :func:`kept_by_name` written out through ``values`` and expanded, and the entries of
    group matrices as the step's symbols (they print alike): (E_1)_{11} (W_{k+1})_{12} is
    0, (W_k E_1)_{21} is −(W_k)_{31}, tr(E_1ᵀ W_k) is (W_k)_{32} − (W_k)_{23}."""
    from ..groupoids import to_explicit

    sub: dict = {}
    for atom in expr.atoms(MatrixElement, sp.Trace):
        if isinstance(atom, MatrixElement) and atom.parent in values and kept_by_name(
                atom, constants):
            sub[atom] = values[atom.parent][atom.i, atom.j]
        elif not kept_by_name(atom, constants):
            sub[atom] = to_explicit(atom, values)
    return sp.expand(expr.xreplace(sub)) if sub else expr


def keeps_matrices(equations: Sequence[sp.Expr]) -> bool:
    """Whether any of ``equations`` has a matrix by name (a trace, an operator)."""
    return any(sp.sympify(e).atoms(sp.MatrixSymbol) for e in equations)


def _matrix_form_keeps(step) -> bool:
    """Whether L or the constraints, evaluated in matrix form, keep a matrix by name (a
    trace :func:`kept_by_name`); if not, no derivative of them does (an entry varied along
    g E_a is an entry of a product), and the matrix form is not built for printing."""
    system = junction_system(step)
    if system is None:
        return True
    try:
        fs = system_functions(system, True)
    except NOT_IN_PIECES:
        return False
    constants = constant_matrices(step.groupoid)
    return any(kept_by_name(t, constants)
               for e in [fs.lagrangian, *fs.constraints] for t in sp.sympify(e).atoms(sp.Trace))


#: each step's :func:`kept_matrix_form` (None too), built once
_KEPT: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def kept_matrix_form(step) -> list | None:
    """The step's matrix form (:attr:`StepEquations.structured`) with its constant parts
    evaluated (:func:`evaluated_constants`), if it still keeps a matrix by name; else None
    (the explicit residuals are as short, and print alike)."""
    if step not in _KEPT:
        _KEPT[step] = _kept_matrix_form(step)
    return _KEPT[step]


def _kept_matrix_form(step) -> list | None:
    if not step.groupoid.matrix_parts() or not _matrix_form_keeps(step):
        return None
    structured = step.structured
    if structured is None:
        return None
    values, constants = matrix_values(step), constant_matrices(step.groupoid)
    equations = [evaluated_constants(e, values, constants) for e in structured]
    return equations if keeps_matrices(equations) else None


def system_functions(system, matrix_form: bool):
    """The system's L and constraints on slot arrows (``matrix_form``: with the matrix parts
    as matrix symbols, as the derivation gives them for printing)."""
    if not matrix_form:
        return system.functions
    return evaluate_system(system.name, system.groupoid, system.lagrangian, system.constraints,
                           system.parameters, arity=system._arity, matrix_form=True)

