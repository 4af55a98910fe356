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
from .._symbols import multiplier_symbols
from ..groupoids import Groupoid
from ._callables import as_scalar, as_scalar_list, call_user, check_symbols
from ._junction import junction_variation, slot


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


def evaluate_system(name: str, groupoid: Groupoid, lagrangian: Callable,
                    constraints: Callable | None, parameters: Sequence,
                    arity: int = 1) -> SystemFunctions:
    """Evaluate L and φ on ``arity`` independent symbolic arrows, with all input checks."""
    slots = tuple(slot(groupoid, f"s{i}_") for i in range(arity))
    views = [groupoid.view(s) for s in slots]
    L = as_scalar(name, "Lagrangian", call_user(name, "Lagrangian", lagrangian, *views))
    coords = [c for s in slots for c in s]
    check_symbols(name, "Lagrangian", [L], coords, parameters)
    phis: list = []
    if constraints is not None:
        raw = call_user(name, "constraints", constraints, *views)
        phis = as_scalar_list(name, "constraints", raw)
        check_symbols(name, "constraints", phis, coords, parameters)
    if len(phis) > groupoid.rank:
        raise ShapeError(
            f"{name}: {len(phis)} constraints but only {groupoid.rank} unknown fibre "
            f"coordinates per step on {groupoid.name}; more constraints than unknowns")
    return SystemFunctions(slots, L, phis)


def shifted(fs: SystemFunctions, slots: Sequence[tuple], multipliers: Sequence) -> sp.Expr:
    """L + λ·φ with the slot arrows replaced by ``slots`` (independent copies)."""
    sub = {a: b for s_old, s_new in zip(fs.slots, slots) for a, b in zip(s_old, s_new)}
    total = fs.lagrangian.xreplace(sub)
    for lam, phi in zip(multipliers, fs.constraints):
        total += lam * phi.xreplace(sub)
    return total


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
    A0, A1 = slot(G, "a"), slot(G, "b")
    S = shifted(fs, [A0], lam0) + shifted(fs, [A1], lam1)
    dels = junction_variation(G, S, A0, A1)

    g0 = tuple(G.named_arrow(0))
    fibre1, chart1, cmap = chart_of(G, 1)
    g1 = tuple(G.arrow_from(G.target(g0), fibre1))
    sub = dict(zip(A0, g0)) | dict(zip(A1, g1))
    phis1 = [shifted(SystemFunctions(fs.slots, sp.S.Zero, [p]), [A1], [1]) for p in
             fs.constraints]
    residuals = [sp.expand(d.xreplace(sub)) for d in dels]
    residuals += [sp.expand(p.xreplace(sub)) for p in phis1]
    knowns = list(g0) + lam0
    next_knowns = [sp.sympify(c).xreplace(cmap) for c in g1] + lam1
    return DerivedStep(
        name=name, groupoid=G, order=1, residuals=residuals, knowns=knowns,
        fibre_unknowns=fibre1, chart_unknowns=chart1, chart_map=cmap,
        multipliers_next=lam1, next_knowns=next_knowns, parameters=list(parameters),
        n_constraints=m, offsets=(0, 1), arrows={0: g0, 1: g1},
        prediction=list(G.predict_chart(g0)) + lam0)
