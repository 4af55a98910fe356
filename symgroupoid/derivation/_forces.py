"""Discrete forces and control inputs: the Lagrange–d'Alembert terms of a junction.

Discrete forces are two maps f⁻, f⁺: G → A*G, a covector on the algebroid at the source and
at the target of an arrow (on Q × Q the f_d^± of Marsden–West §3.2).  The discrete
Lagrange–d'Alembert principle

    δ Σ_k L(g_k) + Σ_k [f⁻(g_k)·δ⁻g_k + f⁺(g_k)·δ⁺g_k] = 0,

varied at the junction between g_k and g_{k+1} along the section X (g_k ↦ g_k·h_X(t),
g_{k+1} ↦ h_X(t)⁻¹·g_{k+1}; seed 000 §5), moves the target of g_k and the source of g_{k+1}
by X, so the junction residual of every basis section X_b gains

    f⁺_b(g_k) + f⁻_b(g_{k+1})

(docs/conventions.md §20; on Q × Q: D₂L(q_{k−1}, q_k) + f⁺(q_{k−1}, q_k) + D₁L(q_k, q_{k+1})
+ f⁻(q_k, q_{k+1}) = 0, Marsden–West eq. (3.2.3)).  The forces are not the variation of a
function, so they are added after the junction variation, never differentiated as an action.

Inputs are symbols like parameters whose values change from arrow to arrow: the value u_k
belongs to the arrow g_k, so a step g_k → g_{k+1} reads u_k (in f⁺(g_k)) and u_{k+1} (in
f⁻(g_{k+1})).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import sympy as sp

from .._errors import (
    InputNameError,
    InputTypeError,
    ParameterDeclarationError,
    ShapeError,
    UnsupportedFeatureError,
)
from .._symbols import (
    MULTIPLIER_NAMES,
    alias_words,
    latex_name,
    scalar_symbol,
    unprintable_name,
)
from ..groupoids import Groupoid
from ._callables import as_scalar_list, call_user, check_symbols, check_values, step_subscript
from ._junction import slot, slot_substitution


@dataclass
class ForceFunctions:
    """The discrete forces of one term of the action, in the basis sections' order.

    First order (one arrow A): f⁻ and f⁺, covectors at α(A) and β(A).  Second order (a
    composable pair (A₁, A₂), docs/conventions.md §20): f⁰, f¹, f², covectors at the pair's
    three base points α(A₁), β(A₁) = α(A₂), β(A₂).  ``slots`` hold the term's arrows
    (coordinates); ``inputs`` the user's input symbols; ``nodes[i]`` the rank(AG)
    expressions of the covector at the term's base point i, in the slot coordinates, the
    parameters and the inputs (of that term).  With internal stages ζ (first order,
    docs/conventions.md §22) the covectors may depend on the generic ``stages`` too, and
    ``stage_forces`` holds f_ζ, the virtual work's coefficients of the stages' variations,
    which the stage rows ∂L/∂ζ gain."""

    slots: tuple
    inputs: list
    nodes: list
    stages: tuple = ()  # the generic internal stages ζ the forces are written in
    stage_forces: list = field(default_factory=list)  # f_ζ, one per stage

    def _stage_substitution(self, stages: Sequence | None) -> dict:
        if not self.stages or stages is None:
            return {}
        return dict(zip(self.stages, stages))

    @property
    def slot(self) -> tuple:
        """The arrow of a first-order term."""
        return self.slots[0]

    @property
    def minus(self) -> list:
        """f⁻: the covector at the source of the term (f⁰ of a pair)."""
        return self.nodes[0]

    @property
    def plus(self) -> list:
        """f⁺: the covector at the target of the term (f² of a pair)."""
        return self.nodes[-1]

    def on(self, arrows: Sequence[Sequence], offset: int,
           stages: Sequence | None = None) -> list[list]:
        """The covectors at every base point of the term with arrows ``arrows`` (coordinate
        tuples) whose inputs are u_{k+offset} and internal stages ``stages`` (None: the
        generic ζ stay)."""
        sub = self._substitution(arrows, offset, stages)
        return [[f.xreplace(sub) for f in node] for node in self.nodes]

    def _substitution(self, arrows: Sequence[Sequence], offset: int,
                      stages: Sequence | None) -> dict:
        sub: dict = {}
        for s, a in zip(self.slots, arrows):
            sub.update(slot_substitution(s, tuple(a)))
        sub.update(zip(self.inputs, input_symbols(self.inputs, offset)))
        sub.update(self._stage_substitution(stages))
        return sub

    def stage_terms(self, arrow: Sequence, offset: int, stages: Sequence) -> list:
        """f_ζ on the arrow ``arrow`` with inputs u_{k+offset} and stages ``stages``: what
        the term's stage rows ∂L/∂ζ gain (docs/conventions.md §22)."""
        sub = self._substitution([arrow], offset, stages)
        return [f.xreplace(sub) for f in self.stage_forces]

    def at(self, arrow: Sequence, offset: int) -> tuple[list, list]:
        """(f⁻, f⁺) on the arrow with coordinates ``arrow`` whose inputs are u_{k+offset}
        (first order)."""
        nodes = self.on([arrow], offset)
        return nodes[0], nodes[-1]

    def window_terms(self, arrows: dict, starts: Sequence[int],
                     stages: dict | None = None) -> list:
        """Σ_s f^{(1−s)}_b(term s) for every basis section b: the forces of every term of the
        window at the junction node β(g_k), which is base point 1 − s of the term starting at
        offset s (whose arrows are ``arrows[s]``, …, and whose inputs are u_{k+s}).  First
        order: f⁺_b(g_k) + f⁻_b(g_{k+1}); second order: f²_b(g_{k−1}, g_k) + f¹_b(g_k,
        g_{k+1}) + f⁰_b(g_{k+1}, g_{k+2}).  ``stages[s]``: the internal stages of term s."""
        arity = len(self.slots)
        parts = [self.on([arrows[s + i] for i in range(arity)], s,
                         None if stages is None else stages[s])[1 - s] for s in starts]
        return [sum(column[1:], column[0]) for column in zip(*parts)]

    def junction_terms(self, left: Sequence, right: Sequence) -> list:
        """f⁺_b(g_k) + f⁻_b(g_{k+1}) for every basis section b, at the named arrows ``left``
        (g_k, inputs u_k) and ``right`` (g_{k+1}, inputs u_{k+1})."""
        return self.window_terms({0: left, 1: right}, [0, 1])


def impulse_section(groupoid: Groupoid, section, parameters: Sequence
                    ) -> tuple[list, tuple, tuple]:
    """The section X at the junction node β(a) of two consecutive slot arrows a = g_k and
    b = g_{k+1}: (X(β(a)) in a's coordinates, a, b)."""
    from ._momenta import section_coefficients

    a, b = slot(groupoid, "a_"), slot(groupoid, "b_")
    return section_coefficients(groupoid, section, groupoid.target(a), parameters), a, b


def impulse_form(groupoid: Groupoid, forces: ForceFunctions, section, parameters: Sequence
                 ) -> tuple[sp.Expr, tuple, tuple]:
    """The impulse of the forces along a section X over one junction (docs/conventions.md
    §20): I = Σ_b X^b(β(a))·(f⁺_b(a) + f⁻_b(b)) for consecutive arrows a = g_k (inputs
    u_k) and b = g_{k+1} (inputs u_{k+1}), so that a Noether quantity of a symmetry X of L
    changes by it, J(g_{k+1}) − J(g_k) = I.  Returns (I, a, b): the expression and the two
    independent arrows (slot coordinates) it is written in.  (With internal stages the
    forces are large and read both arrows' stages: :class:`~symgroupoid.NoetherQuantity`
    builds the impulse on its expression graph from :func:`impulse_section` and the
    forces in their slot coordinates, docs/conventions.md §22.)"""
    X, a, b = impulse_section(groupoid, section, parameters)
    _, plus = forces.at(a, 0)
    minus, _ = forces.at(b, 1)
    return sum((x * (fp + fm) for x, fp, fm in zip(X, plus, minus)), sp.S.Zero), a, b


def pair_impulse_form(groupoid: Groupoid, forces: ForceFunctions, section,
                      parameters: Sequence) -> tuple[sp.Expr, tuple, tuple]:
    """The impulse of the forces of a second-order system along a section X over one step
    (docs/conventions.md §20): at the node β(g_k) of the junction between g_k and g_{k+1},

        I_k = Σ_b X^b(β(g_k))·(f²_b(g_{k−1}, g_k) + f¹_b(g_k, g_{k+1}) + f⁰_b(g_{k+1}, g_{k+2})),

    the pair starting at g_j with the inputs u_j, so that the Noether quantity of a
    symmetry X of L on the window (g_{k−1}, g_k, g_{k+1}) changes by it from that window to
    the next, J_{k+1} − J_k = I_k.  Returns (I, window, new): the expression, the window's
    coordinates (the first arrow's, then the fibre variables of the two after it, as the
    second-order Noether quantity is written) and the fibre variables of g_{k+2}."""
    from ._momenta import section_coefficients
    from ._step import named, next_arrow

    arrows = [named(groupoid, 0, False)]
    for o in (1, 2, 3):
        arrows.append(next_arrow(groupoid, arrows[-1], o, False))
    fibres = [tuple(groupoid.fibre_of(named(groupoid, o, False))) for o in (1, 2, 3)]
    X = section_coefficients(groupoid, section, groupoid.target(arrows[1]), parameters)
    # the window's pairs start at g_{k−1}, g_k, g_{k+1}: offsets −1, 0, 1 of arrows[1] = g_k
    work = forces.window_terms({s - 1: a for s, a in enumerate(arrows)}, [-1, 0, 1])
    expr = sum((x * w for x, w in zip(X, work)), sp.S.Zero)
    return expr, tuple(arrows[0]) + fibres[0] + fibres[1], fibres[2]


def input_symbols(inputs: Sequence[sp.Symbol], offset: int) -> list:
    """The inputs of the arrow g_{k+offset}: u ↦ u_{k+offset} (named in LaTeX)."""
    return [scalar_symbol(latex_name(u.name), offset) for u in inputs]


def input_arguments(name: str, inputs, parameters: Sequence, forces) -> list:
    """The declared inputs: distinct SymPy symbols, none a parameter, and only with forces."""
    if isinstance(inputs, sp.Symbol):
        inputs = [inputs]
    if isinstance(inputs, (str, bytes)) or not isinstance(inputs, Sequence):
        raise InputTypeError(f"{name}: inputs must be a list of SymPy symbols, got "
                             f"{type(inputs).__name__} {inputs!r}")
    inputs = list(inputs)
    if inputs and forces is None:
        raise UnsupportedFeatureError(
            f"{name}: inputs {', '.join(map(str, inputs))} are declared but the system has "
            f"no forces to use them; pass forces=f with f(g) -> (f_minus, f_plus) in the inputs")
    seen: dict = {}
    names = {latex_name(str(p)): p for p in parameters}
    for u in inputs:
        if not isinstance(u, sp.Symbol):
            raise InputTypeError(f"{name}: each input must be a SymPy symbol, got "
                                 f"{type(u).__name__} {u!r}")
        why = unprintable_name(str(u))
        if why is not None:
            raise InputNameError(f"{name}: input {str(u)!r} cannot be used: {why}; name the "
                                 f"input otherwise")
        key = latex_name(str(u))
        if step_subscript(key):
            raise InputNameError(f"{name}: input {str(u)!r} is written {key}, as a value at a "
                                 f"step is; an input's values at the arrows are written with the "
                                 f"step as a subscript (u_k, u_{{k+1}} for an input u): name "
                                 f"it otherwise")
        if key in names:
            raise InputNameError(f"{name}: {u} is declared both as an input and as a "
                                 f"parameter{_alias(u, names[key])}; a parameter is fixed for a "
                                 f"run, an input changes from step to step: declare it once")
        if key in seen:
            raise InputNameError(f"{name}: input {u} is declared twice"
                                 f"{_alias(u, seen[key])}")
        seen[key] = u
    return inputs


def _alias(u: sp.Symbol, other) -> str:
    """Words naming the other spelling of ``u``'s name (θ, theta, \\theta), or ""."""
    return "" if str(other) == str(u) else f" ({alias_words((str(other), str(u)))})"


#: how the printed equations write the discrete forces: f^{+}(g_k), f^{-}(g_{k+1})
FORCE_LETTER = "f"


def _misread_input(key: str, taken: dict) -> str | None:
    """Why an input printed ``key`` would be misread in the printed equations, where its
    values are (key)_{k}, (key)_{k+1}: written f, as the forces f⁺, f⁻ are (f_{k} reads as
    the force on g_k), or a coordinate's name with a subscript ((g_{1})_{k} beside the
    arrows' (g_{k})_{12}, (x_{1})_{k} beside x_{k}); None if it reads as itself."""
    if key == FORCE_LETTER:
        return (f"is written {key}, as the discrete forces f^{{+}}, f^{{-}} are ({key}_{{k}} "
                f"would read as the force on g_k)")
    base = key.split("_", 1)[0]
    if "_" in key and base in taken:
        return (f"is written {key}, the name of the coordinate {taken[base]!r} with a "
                f"subscript: its values ({key})_{{k}} would read as that coordinate's at a "
                f"step")
    return None


def check_force_letter(name: str, parameters: Sequence) -> None:
    """In a system with forces, a parameter written f would read as the discrete forces
    f⁺, f⁻ of the printed equations: a :class:`ParameterDeclarationError`."""
    for p in parameters:
        if isinstance(p, sp.Symbol) and latex_name(p.name.strip()) == FORCE_LETTER:
            raise ParameterDeclarationError(
                f"{name}: parameter {p.name!r} is written {FORCE_LETTER}, as the discrete "
                f"forces f^{{+}}, f^{{-}} of the printed equations are; name it otherwise")


def force_functions(name: str, groupoid: Groupoid, forces: Callable, inputs: Sequence,
                    parameters: Sequence, arity: int = 1,
                    stages: Sequence = ()) -> ForceFunctions:
    """The forces from the user's callable on symbolic arrows, checked: first order
    ``forces(g) -> (f_minus, f_plus)``; second order ``forces(g1, g2) -> (f0, f1, f2)``, the
    covectors at the pair's three base points (docs/conventions.md §20).  Each is a list of
    rank(AG) scalars in the arrows' coordinates, the parameters and the inputs; an input
    must not be a coordinate of the arrow.  With internal stages ζ (first order,
    docs/conventions.md §22): ``forces(g, zeta) -> (f_minus, f_plus, f_stages)``, the
    covectors in the arrow's coordinates and ζ, and f_ζ, one scalar per stage."""
    what = "forces"
    arrows = tuple(slot(groupoid, f"f{i}_") for i in range(arity))
    taken = {latex_name(n): n for n in (*groupoid.symbols_by_name(0),
                                         *groupoid.symbols_by_name(1), *MULTIPLIER_NAMES)}
    for u in inputs:
        key = latex_name(str(u))
        if key in taken:
            raise InputNameError(f"{name}: input {u} has the name of a coordinate (or the "
                                 f"multipliers) of {groupoid.name}{_alias(u, taken[key])}, "
                                 f"which names a part of the state; give the input another "
                                 f"name")
        why = _misread_input(key, taken)
        if why is not None:
            raise InputNameError(f"{name}: input {u} {why}; give the input another name")
    stages = tuple(stages)
    value = call_user(name, what, forces, *[groupoid.view(a) for a in arrows],
                      *([list(stages)] if stages else []), smooth=True)
    sides = ("f_minus", "f_plus") if arity == 1 else tuple(f"f{i}" for i in range(arity + 1))
    shape = ("a pair (f_minus, f_plus)" if arity == 1 else
             f"{arity + 1} covectors ({', '.join(sides)}) at the pair's base points")
    if stages:
        sides, shape = (*sides, "f_stages"), ("a triple (f_minus, f_plus, f_stages) (with "
                                              "internal stages)")
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) \
            or len(value) != len(sides):
        raise ShapeError(f"{name}: the forces must return {shape}, each a list of "
                         f"{groupoid.rank} components in the basis sections' order; got "
                         f"{type(value).__name__}")
    parts = []
    for side, part in zip(sides, value):
        components = as_scalar_list(name, f"forces ({side})", part)
        if not getattr(forces, "symgroupoid_checked", False):  # (as call_user's values)
            check_values(name, f"forces ({side})", components, arrows)
        if side == "f_stages":
            if len(components) != len(stages):
                raise ShapeError(f"{name}: the forces' f_stages has {len(components)} "
                                 f"components; one per internal stage ({len(stages)})")
        elif len(components) != groupoid.rank:
            raise ShapeError(f"{name}: the forces' {side} has {len(components)} components; "
                             f"the algebroid of {groupoid.name} has rank {groupoid.rank} (one "
                             f"per basis section, in the order of the step's residuals)")
        parts.append(components)
    check_symbols(name, what, [f for part in parts for f in part],
                  [c for a in arrows for c in a] + list(stages), [*parameters, *inputs],
                  forces=True)
    if stages:
        return ForceFunctions(arrows, list(inputs), parts[:-1], stages, parts[-1])
    return ForceFunctions(arrows, list(inputs), parts)


__all__ = ["FORCE_LETTER", "ForceFunctions", "check_force_letter", "force_functions",
           "impulse_form", "impulse_section",
           "input_arguments", "input_symbols", "pair_impulse_form"]
