"""Reduction of discrete constrained Lagrangian systems by groupoid morphisms (seed 000 §4.1).

A morphism Φ: G → G′ is a morphism of the systems (G, N, L) and (G′, N′, L′) when
L = L′∘Φ and N = Φ⁻¹(N′) (Def. 4.2); N = Φ⁻¹(N′) is checked in the form of Example 4.3,
φᵃ = φ′ᵃ∘Φ for each constraint.  Then (Thm 4.5, Cor. 4.6) Φ maps solutions of (G, N, L) to
solutions of (G′, N′, L′) with the same multipliers, and the discrete Legendre transforms
are A*Φ-related; when Φ is a submersion the converse holds (Remark 4.7), so a reduced
solution and one initial arrow determine the unreduced solution.

The reduced Lagrangian is given, or found by substitution, L′ = L∘σ, when Φ has a section σ
(Φ∘σ = id).  Every identity is checked symbolically when SymPy proves it (expansion, then
cancellation of small rational differences) and otherwise numerically on random arrows with random
parameter values — e.g. identities that hold only because the arrows' matrices are rotations.
A forced system reduces when its forces are A*Φ-related to the reduced ones,
f±(g) = M·f′±(Φ(g)) (:func:`check_forces`, numeric: M is).
Conventions: docs/conventions.md §13.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._errors import DomainError, MorphismError, ShapeError
from .._lambdify import NUMPY_MODULES
from .._rational import vanishes
from .._sizes import ops_at_most
from ..groupoids import GroupoidMorphism, ParameterValues
from ._callables import as_scalar, as_scalar_list, call_user
from ._forces import ForceFunctions
from ._junction import slot

#: differences with more operations than this are not put over a common denominator
SIMPLIFY_LIMIT = 400
#: random arrows of the numeric check, and its relative tolerance
SAMPLES, TOLERANCE = 8, 1e-9


@dataclass
class IdentityCheck:
    """How an identity f = f′∘Φ was verified: ``"symbolic"`` or ``"numeric"`` (then on
    ``samples`` random arrows, largest relative defect ``defect``)."""

    what: str
    method: str
    samples: int = 0
    defect: float = 0.0

    def __str__(self) -> str:
        if self.method == "symbolic":
            return f"{self.what}: verified symbolically"
        return (f"{self.what}: verified numerically on {self.samples} random arrows "
                f"(largest relative defect {self.defect:.1e})")


def pulled_back(name: str, phi: GroupoidMorphism, func: Callable, what: str) -> Callable:
    """f′ = f∘σ as a callable on arrows of G′ (σ the section of Φ)."""
    if not phi.has_section:
        raise DomainError(f"{name}: {phi.name} has no section, so the reduced {what} cannot "
                          f"be found by substitution; give it explicitly")

    def reduced(g):
        return call_user(name, what, func, phi.source.view(phi.section(g.coords)))

    return reduced


def check_identity(name: str, what: str, phi: GroupoidMorphism, f: sp.Expr,
                   source_slot: tuple, f_reduced: sp.Expr, target_slot: tuple,
                   samples: int = SAMPLES, seed: int = 0) -> IdentityCheck:
    """Verify f = f′∘Φ (f in the source slot's coordinates, f′ in the target slot's);
    raise :class:`MorphismError` with the arrow when it fails."""
    composed = sp.sympify(f_reduced).xreplace(dict(zip(target_slot, phi(source_slot))))
    difference = sp.sympify(f) - composed
    if _is_zero(difference):
        return IdentityCheck(what, "symbolic")
    G = phi.source
    free = (difference.free_symbols | sp.sympify(f).free_symbols) - set(source_slot)
    symbols = sorted(free, key=lambda s: s.name)
    lhs = sp.lambdify([source_slot, symbols], f, NUMPY_MODULES)
    rhs = sp.lambdify([source_slot, symbols], composed, NUMPY_MODULES)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(samples):
        values = ParameterValues(rng=rng)
        p = values.vector(symbols)
        a = np.asarray(G.random_arrow(rng), float)
        x, y = float(lhs(a, p)), float(rhs(a, p))
        defect = abs(x - y) / (1.0 + abs(x))
        worst = max(worst, defect)
        if not (np.isfinite(x) and np.isfinite(y)) or defect > TOLERANCE:
            shown = ", ".join(f"{v:.6g}" for v in a)
            err = MorphismError(
                f"{name}: {what} fails at the arrow ({shown}){values.describe()}: "
                f"{x:.12g} ≠ {y:.12g}")
            err.axiom, err.arrows = what, {"g": tuple(float(v) for v in a)}
            err.parameters = {s.name: v for s, v in values.values.items()}
            raise err
    return IdentityCheck(what, "numeric", samples, worst)


def _is_zero(e: sp.Expr) -> bool:
    """A cheap proof that e ≡ 0: expansion, then (for small rational expressions) cancelling
    over a common denominator.  Identities that need the manifold's equations (RᵀR = I) or
    trigonometric identities are left to the numeric check."""
    expanded = sp.expand(e)
    if e == 0 or expanded == 0:
        return True
    zero = vanishes(expanded)
    if zero is not None:
        return zero
    if not ops_at_most(e, SIMPLIFY_LIMIT) or e.has(sp.Function):
        return False
    return sp.cancel(sp.together(e)) == 0


def check_forces(name: str, morphism: GroupoidMorphism, forces: ForceFunctions,
                 reduced: ForceFunctions, samples: int = SAMPLES, seed: int = 0
                 ) -> IdentityCheck:
    """Verify that the forces f± of G and f′± of G′ are A*Φ-related (seed 000 Def. 4.4):
    f⁻(g) = M(α(g))·f′⁻(Φ(g)) and f⁺(g) = M(β(g))·f′⁺(Φ(g)), M the algebroid matrix of Φ
    (AΦ(X_a) = Σ_b M_ab X′_b, docs/conventions.md §13), i.e. f±(g)(X) = f′±(Φ(g))(AΦ(X))
    for every basis section X.  M is numeric, so the check is numeric: on ``samples`` random
    arrows with random parameter and input values, relative tolerance TOLERANCE; a
    :class:`MorphismError` with the arrow, the side and the values when it fails."""
    G = morphism.source
    a, b = forces.slot, reduced.slot
    inputs = list(forces.inputs)
    symbols = sorted({s for side in (*forces.nodes, *reduced.nodes) for e in side
                      for s in sp.sympify(e).free_symbols} - set(a) - set(b) - set(inputs)
                     | set(morphism.parameters), key=lambda s: s.name)
    full = sp.lambdify([a, inputs, symbols], [list(forces.minus), list(forces.plus)],
                       NUMPY_MODULES)
    image = sp.lambdify([b, inputs, symbols], [list(reduced.minus), list(reduced.plus)],
                        NUMPY_MODULES)
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(samples):
        values = ParameterValues(rng=rng)
        p = values.vector(symbols)
        u = rng.normal(size=len(inputs))
        g = np.asarray(G.random_arrow(rng), float)
        gr = morphism.project(g[None], values)[0]
        minus, plus = (np.asarray(v, float).ravel() for v in full(g, u, p))
        rminus, rplus = (np.asarray(v, float).ravel() for v in image(gr, u, p))
        ends = (np.asarray(G.source(tuple(g)), float), np.asarray(G.target(tuple(g)), float))
        for side, f, fr, q in (("f⁻", minus, rminus, ends[0]), ("f⁺", plus, rplus, ends[1])):
            pulled = morphism.algebroid_matrix(q, values) @ fr
            defect = float(np.abs(f - pulled).max(initial=0.0)) / (
                1.0 + float(np.abs(f).max(initial=0.0)))
            worst = max(worst, defect)
            if not (np.isfinite(f).all() and np.isfinite(pulled).all()) or defect > TOLERANCE:
                shown = ", ".join(f"{v:.6g}" for v in g)
                inputs_shown = ", ".join(f"{s}={v:.6g}" for s, v in zip(inputs, u))
                err = MorphismError(
                    f"{name}: the forces are not A*Φ-related to the reduced forces: {side}(g) "
                    f"= {np.round(f, 12).tolist()} but A*Φ {side}′(Φ(g)) = "
                    f"{np.round(pulled, 12).tolist()} at the arrow ({shown})"
                    f"{values.describe()}{f' with inputs {inputs_shown}' if inputs else ''}; "
                    f"give reduced forces f′ with f±(g) = M·f′±(Φ(g)), M the algebroid matrix "
                    f"of the morphism (docs/conventions.md §13)")
                err.axiom = f"{side} = A*Φ {side}′∘Φ"
                err.arrows = {"g": tuple(float(v) for v in g)}
                err.parameters = {s.name: v for s, v in values.values.items()}
                raise err
    return IdentityCheck("f± = A*Φ f′±∘Φ (the forces are A*Φ-related)", "numeric", samples,
                         worst)


@dataclass
class Reduction:
    """The reduced Lagrangian and constraints (callables on arrows of G′), the parameters of
    the reduced system, and how Def. 4.2 was verified."""

    lagrangian: Callable
    constraints: Callable | None
    parameters: list
    checks: list


def reduce_functions(name: str, phi: GroupoidMorphism, lagrangian: Callable,
                     constraints: Callable | None, parameters: Sequence,
                     reduced_lagrangian: Callable | None = None,
                     reduced_constraints: Callable | None = None) -> Reduction:
    """L′ and φ′ (given, or L∘σ and φ∘σ) with L = L′∘Φ and φ = φ′∘Φ verified."""
    G, H = phi.source, phi.target
    Lr = reduced_lagrangian or pulled_back(name, phi, lagrangian, "Lagrangian")
    if constraints is None and reduced_constraints is not None:
        raise ShapeError(f"{name}: the system has no constraints; reduced constraints were "
                         f"given")
    Cr = None
    if constraints is not None:
        Cr = reduced_constraints or pulled_back(name, phi, constraints, "constraints")
    a, b = slot(G, "u"), slot(H, "v")
    va, vb = G.view(a), H.view(b)
    checks = [check_identity(
        name, "L = L′∘Φ", phi,
        as_scalar(name, "Lagrangian", call_user(name, "Lagrangian", lagrangian, va)), a,
        as_scalar(name, "reduced Lagrangian", call_user(name, "reduced Lagrangian", Lr, vb)),
        b)]
    if constraints is not None:
        phis = as_scalar_list(name, "constraints", call_user(name, "constraints", constraints,
                                                             va))
        reduced = as_scalar_list(name, "reduced constraints",
                                 call_user(name, "reduced constraints", Cr, vb))
        if len(phis) != len(reduced):
            raise ShapeError(f"{name}: {len(phis)} constraints but {len(reduced)} reduced "
                             f"constraints; N = Φ⁻¹(N′) is checked as φᵃ = φ′ᵃ∘Φ")
        checks += [check_identity(name, f"φ{i + 1} = φ′{i + 1}∘Φ (N = Φ⁻¹(N′))", phi, f, a,
                                  fr, b) for i, (f, fr) in enumerate(zip(phis, reduced))]
    return Reduction(Lr, Cr, reduced_parameters(phi, parameters), checks)


def reduced_parameters(phi: GroupoidMorphism, parameters: Sequence) -> list:
    """The system's parameters, then any other free symbol of Φ or of G′'s structure maps
    (sorted by name): the reduced equations may use them."""
    H = phi.target
    generic = set(H._generic_arrow)
    fields = [e for v in H._left_fields + H._right_fields for e in v]
    free = set(phi.parameters)
    for e in fields:
        free |= sp.sympify(e).free_symbols - generic
    extra = sorted(free - set(parameters), key=lambda s: s.name)
    return list(parameters) + extra
