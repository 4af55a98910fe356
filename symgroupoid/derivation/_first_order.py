"""First-order discrete (constrained) Euler–Lagrange equations on a Lie groupoid.

For L: G → R and constraints φᵃ: G → R (seed 000 §3.3, Thm 2.13; EQUATIONS.md §2, §4):

    X⃖[L + λ_k·φ](g_k) = X⃗[L + λ_{k+1}·φ](g_{k+1})   for every basis section X,
    φ(g_{k+1}) = 0,

with g_{k+1} in the α-fibre of β(g_k).  Obtained by :func:`junction_variation` of
S = L(g_k) + λ_k·φ(g_k) + L(g_{k+1}) + λ_{k+1}·φ(g_{k+1}).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import sympy as sp

from .._errors import ShapeError
from .._symbols import multiplier_symbols, subscripted
from ..groupoids import Groupoid
from ._callables import as_scalar, as_scalar_list, call_user, check_symbols
from ._junction import junction_variation, slot, slot_substitution


@dataclass
class DerivedStep:
    """Plain result of a derivation: what a :class:`StepEquations` is built from."""

    name: str
    groupoid: Groupoid
    order: int
    residuals: list
    knowns: list
    fibre_unknowns: tuple
    chart_unknowns: tuple
    chart_map: dict
    multipliers_next: list
    next_knowns: list
    parameters: list
    n_constraints: int
    offsets: tuple  # (first known arrow offset, unknown arrow offset)
    arrows: dict = field(default_factory=dict)  # offset -> named arrow coordinates
    prediction: list = field(default_factory=list)  # guess for the unknowns from the knowns


@dataclass
class SystemFunctions:
    """A Lagrangian and constraints evaluated on independent slot arrows."""

    slots: tuple  # tuple of slot coordinate tuples
    lagrangian: sp.Expr
    constraints: list
    matrix_form: bool = False


def evaluate_system(name: str, groupoid: Groupoid, lagrangian: Callable,
                    constraints: Callable | None, parameters: Sequence,
                    arity: int = 1, matrix_form: bool = False) -> SystemFunctions:
    """Evaluate L and φ on ``arity`` independent symbolic arrows, with all input checks.

    With ``matrix_form`` the matrix parts of the arrows are MatrixSymbols (for printing).
    """
    slots = tuple(slot(groupoid, f"s{i}_", matrix_form) for i in range(arity))
    views = [groupoid.view(s) for s in slots]
    L = as_scalar(name, "Lagrangian", call_user(name, "Lagrangian", lagrangian, *views))
    coords = [c for s in slots for c in s]
    if not matrix_form:
        check_symbols(name, "Lagrangian", [L], coords, parameters)
    phis: list = []
    if constraints is not None:
        raw = call_user(name, "constraints", constraints, *views)
        phis = as_scalar_list(name, "constraints", raw)
        if not matrix_form:
            check_symbols(name, "constraints", phis, coords, parameters)
    if len(phis) > groupoid.rank:
        raise ShapeError(
            f"{name}: {len(phis)} constraints but only {groupoid.rank} unknown fibre "
            f"coordinates per step on {groupoid.name}; more constraints than unknowns")
    return SystemFunctions(slots, L, phis, matrix_form)


def shifted(fs: SystemFunctions, slots: Sequence[tuple], multipliers: Sequence,
            lagrangian: bool = True) -> sp.Expr:
    """L + λ·φ with the slot arrows replaced by ``slots`` (independent copies)."""
    sub: dict = {}
    for s_old, s_new in zip(fs.slots, slots):
        sub.update(slot_substitution(s_old, s_new))
    total = fs.lagrangian.xreplace(sub) if lagrangian else sp.S.Zero
    for lam, phi in zip(multipliers, fs.constraints):
        total += lam * phi.xreplace(sub)
    return total


def named(groupoid: Groupoid, offset: int, matrix_form: bool) -> tuple:
    """The named arrow g_{k+offset}, with matrix parts as MatrixSymbols in matrix form."""
    a = tuple(groupoid.named_arrow(offset))
    if matrix_form:
        a = groupoid.in_matrix_form(a, lambda g: subscripted(g.latex, offset))
    return a


def next_arrow(groupoid: Groupoid, previous: tuple, offset: int, matrix_form: bool) -> tuple:
    """g_{k+offset} composable after ``previous``: source β(previous), named fibre variables."""
    fibre = groupoid.fibre_of(named(groupoid, offset, matrix_form))
    return tuple(groupoid.arrow_from(groupoid.target(previous), fibre))


def first_order_residuals(G: Groupoid, fs: SystemFunctions) -> tuple[list, tuple, tuple]:
    """DEL residuals and constraints at k+1, with g_k and g_{k+1} = (β(g_k), fibre_{k+1})."""
    m, mf = len(fs.constraints), fs.matrix_form
    lam0, lam1 = multiplier_symbols(m, 0), multiplier_symbols(m, 1)
    A0, A1 = slot(G, "a", mf), slot(G, "b", mf)
    S = shifted(fs, [A0], lam0) + shifted(fs, [A1], lam1)
    dels = junction_variation(G, S, A0, A1)
    g0 = named(G, 0, mf)
    g1 = next_arrow(G, g0, 1, mf)
    sub = slot_substitution(A0, g0) | slot_substitution(A1, g1)
    residuals = [sp.expand(d.xreplace(sub)) for d in dels]
    residuals += [sp.expand(phi.xreplace(slot_substitution(fs.slots[0], g1)))
                  for phi in fs.constraints]
    return residuals, g0, g1


def chart_of(groupoid: Groupoid, offset: int) -> tuple[tuple, tuple, dict]:
    """Named fibre variables, chart coordinates and the map fibre ← chart of g_{k+offset}."""
    fibre = tuple(groupoid.named_fibre(offset))
    chart = tuple(groupoid.named_chart(offset))
    values = tuple(groupoid.fibre_chart(chart))
    cmap = {f: v for f, v in zip(fibre, values) if f != v}
    return fibre, chart, cmap


def first_order_step(name: str, groupoid: Groupoid, fs: SystemFunctions,
                     parameters: Sequence) -> DerivedStep:
    """Derive the step (g_k, λ_k) → (g_{k+1}, λ_{k+1})."""
    G, m = groupoid, len(fs.constraints)
    lam0, lam1 = multiplier_symbols(m, 0), multiplier_symbols(m, 1)
    residuals, g0, g1 = first_order_residuals(G, fs)
    fibre1, chart1, cmap = chart_of(G, 1)
    knowns = list(g0) + lam0
    next_knowns = [sp.sympify(c).xreplace(cmap) for c in g1] + lam1
    return DerivedStep(
        name=name, groupoid=G, order=1, residuals=residuals, knowns=knowns,
        fibre_unknowns=fibre1, chart_unknowns=chart1, chart_map=cmap,
        multipliers_next=lam1, next_knowns=next_knowns, parameters=list(parameters),
        n_constraints=m, offsets=(0, 1), arrows={0: g0, 1: g1},
        prediction=list(G.predict_chart(g0)) + lam0)


def matrix_form_values(groupoid: Groupoid, offsets: Sequence[int]) -> dict:
    """MatrixSymbol g_{k+o} → explicit named matrix, and E_a → its value (for checking)."""
    values: dict = {}
    for _, group in groupoid.matrix_parts():
        for o in offsets:
            M = sp.MatrixSymbol(subscripted(group.latex, o), group.n, group.n)
            values[M] = sp.ImmutableMatrix(group.named_matrix(o))
        values.update({E: value for value, E in group.named_basis().items()})
    return values


def verified_matrix_form(explicit: Sequence[sp.Expr], structured: Sequence[sp.Expr],
                         groupoid: Groupoid, offsets: Sequence[int]) -> list | None:
    """``structured`` if, with the matrices written out, it equals ``explicit`` exactly."""
    from ..groupoids._matrix_form import to_explicit

    values = matrix_form_values(groupoid, offsets)
    for e, s in zip(explicit, structured):
        if sp.expand(to_explicit(s, values) - e) != 0:
            return None
    return list(structured)


def first_order_matrix_form(name: str, groupoid: Groupoid, lagrangian: Callable,
                            constraints: Callable | None, parameters: Sequence,
                            explicit: Sequence[sp.Expr]) -> list | None:
    """The residuals with matrix parts kept as matrices (for LaTeX), verified against the
    explicit residuals; None when the groupoid has no matrix part or the form is unavailable."""
    if not any(not g.affine for _, g in groupoid.matrix_parts()):
        return None
    try:
        fs = evaluate_system(name, groupoid, lagrangian, constraints, parameters,
                             matrix_form=True)
        structured, _, _ = first_order_residuals(groupoid, fs)
    except (NotImplementedError, TypeError, AttributeError, ValueError):
        return None
    return verified_matrix_form(explicit, structured, groupoid, (0, 1))
