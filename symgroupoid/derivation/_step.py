"""Discrete (constrained) Euler–Lagrange steps on a Lie groupoid, first and second order.

For L: G → R and constraints φᵃ: G → R (seed 000 §3.3, Thm 2.13; docs/conventions.md §2, §4):

    X⃖[L + λ_k·φ](g_k) = X⃗[L + λ_{k+1}·φ](g_{k+1})   for every basis section X,
    φ(g_{k+1}) = 0,

with g_{k+1} in the α-fibre of β(g_k).  Obtained by :func:`junction_variation` of
S = L(g_k) + λ_k·φ(g_k) + L(g_{k+1}) + λ_{k+1}·φ(g_{k+1}).

Second order (seed 001 eqs. (13)/(15), constrained eq. (18); docs/conventions.md §8): L, Φ on G₂,
S = Σ_{s=-1}^{1} [L + λ_{k+s}·Φ](g_{k+s}, g_{k+s+1}) varied at the same junction, with
unknown g_{k+2} and the constraints Φ(g_{k+1}, g_{k+2}) = 0.

Holonomic constraints ψ: Q → Rʰ (seed 000 §3.3 with N the restriction of G to M = {ψ = 0};
docs/conventions.md §15) add λ·ψ(α(A₀)) to every term — the multiplier of a term sits at its
source node — so the junction variation gives X⃖[L](g_k) − X⃗[L](g_{k+1}) +
λ_{k+1}·dψ(β(g_k))(ρ(X)) = 0 through X⃗[ψ∘α] = −dψ∘ρ, and the step's row for ψ is
ψ(β(newest arrow)) = 0 (ψ(α(·)) of the newest term holds by the step before).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from .._errors import CallableError, ShapeError, UnsupportedFeatureError
from .._symbols import multiplier_symbols, stage_symbols, subscripted
from ..groupoids import Groupoid
from ._callables import (
    as_scalar,
    as_scalar_list,
    call_user,
    check_parameters_unlike_coordinates,
    check_symbols,
)
from ._forces import check_force_letter, force_functions, input_symbols
from ._junction import slot, slot_substitution


@dataclass
class DerivedStep:
    """Plain result of a derivation: what a :class:`StepEquations` is built from.

    The residuals exist in two exact forms: ``window`` — graph nodes (the fast route, what
    code generation and numerics use) — and SymPy expressions, given directly
    (``residuals``) or computed on first request by ``symbolic()`` (printing, checking).
    """

    name: str
    groupoid: Groupoid
    order: int
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
    residuals: list | None = None  # SymPy residuals, when derived symbolically
    symbolic: Callable[[], list] | None = None  # SymPy residuals on demand
    graph: Callable[[], Any] | None = None  # the residuals as graph nodes, on demand
    n_equations: int = 0
    n_holonomic: int = 0  # the last n_holonomic multipliers belong to holonomic constraints
    inputs: list = field(default_factory=list)  # input symbols: knowns end with u_k, u_{k+1}
    stage_unknowns: list = field(default_factory=list)  # ζ_k, ζ_{k+1} (after the chart)
    _window: Any = None

    @property
    def window(self):
        """The :class:`~symgroupoid.derivation._window.WindowGraph` of the residuals (built
        on first request; None for steps known only symbolically)."""
        if self._window is None and self.graph is not None:
            self._window = self.graph()
        return self._window

    def build_graph(self) -> None:
        """Build the graph now, so that errors in the user's maps surface at derivation; an
        expression compiled code cannot evaluate (e.g. an undefined function, fine for
        symbolic work) is reported when a program is asked for instead."""
        from .._errors import UnsupportedExpressionError

        try:
            self.window  # noqa: B018 - builds and caches
        except UnsupportedExpressionError:
            pass

    def sympy_residuals(self) -> list:
        """The residuals as SymPy expressions (computed once, on first request)."""
        if self.residuals is None:
            if self.symbolic is None:
                raise ValueError(f"{self.name}: no symbolic form of the residuals")
            self.residuals = list(self.symbolic())
        return self.residuals


@dataclass
class SystemFunctions:
    """A system's Lagrangian and constraints evaluated on independent slot arrows.

    This is what a system is to everything built from it (``system.functions``): the
    derivation, the printers, the programs the evaluators run.

    ``slots`` are symbolic arrows s₀, …, s_{r−1} (r = 1 for L_d: G → ℝ, r = 2 for a
    second-order L_d: G₂ → ℝ), each a tuple of the groupoid's arrow coordinates.
    ``lagrangian`` is L_d(s₀, …, s_{r−1}).  ``constraints`` are the functions the
    multipliers of a term multiply in the augmented action L_d + λ·Φ (seed 000 §3.3,
    docs/conventions.md §15): the user's constraints φ on the term's arrows, then the
    holonomic constraints at the term's source node, ψ(α(s₀)).  ``holonomic`` holds ψ on the
    generic base point ``base`` (``at_base`` evaluates it at a base point); ``rows`` are
    the conditions a step imposes on its newest term: φ, then ψ at the target β(s_{r−1})
    of the term's last arrow (``rows_on`` gives them on other arrows).  With
    ``matrix_form`` the matrix parts of the slots are matrix symbols (for printing).
    ``forces`` holds the discrete forces f⁻, f⁺ of a forced system on an arrow of their own
    (:class:`~symgroupoid.derivation.ForceFunctions`), with the inputs they read.
    ``stages`` are the internal variables ζ of a term (first order only): L_d(s₀, ζ), whose
    discrete Lagrangian is the stationary value over ζ (docs/conventions.md §22).
    """

    slots: tuple  # tuple of slot coordinate tuples
    lagrangian: sp.Expr
    constraints: list
    matrix_form: bool = False
    base: tuple = ()  # generic base-point coordinates ψ is written in
    holonomic: list = field(default_factory=list)  # ψ_a on ``base``
    rows: list = field(default_factory=list)  # rows_on(the slots), set by evaluate_system
    forces: Any = None  # ForceFunctions: f⁻, f⁺ on one arrow (docs/conventions.md §20)
    stages: list = field(default_factory=list)  # internal variables ζ of the slot term

    @property
    def inputs(self) -> list:
        """The input symbols the forces read (empty without forces)."""
        return [] if self.forces is None else list(self.forces.inputs)

    @property
    def n_holonomic(self) -> int:
        """How many of the constraints (the last ones) are holonomic."""
        return len(self.holonomic)

    def at_base(self, q: Sequence) -> list:
        """ψ at the base point with coordinates ``q`` (expressions or numbers)."""
        sub = dict(zip(self.base, q))
        return [psi.xreplace(sub) for psi in self.holonomic]

    def rows_on(self, groupoid: Groupoid, arrows: Sequence[Sequence]) -> list:
        """The step's conditions on the term with these arrows: the user's constraints φ,
        then ψ(β(last arrow)) (a term's own ψ(α(A₀)) is already zero by the step before)."""
        sub: dict = {}
        for s_old, s_new in zip(self.slots, arrows):
            sub.update(slot_substitution(s_old, s_new))
        m = len(self.constraints) - self.n_holonomic
        return ([phi.xreplace(sub) for phi in self.constraints[:m]]
                + self.at_base(groupoid.target(tuple(arrows[-1]))))


def evaluate_system(name: str, groupoid: Groupoid, lagrangian: Callable,
                    constraints: Callable | None, parameters: Sequence,
                    arity: int = 1, matrix_form: bool = False,
                    holonomic: Callable | None = None, forces: Callable | None = None,
                    inputs: Sequence = (), stages: int = 0) -> SystemFunctions:
    """Evaluate L and φ on ``arity`` independent symbolic arrows, with all input checks.

    ``holonomic``: ψ(q) on a base point (``groupoid.base_view``); its components are added
    to the constraints of every term at the term's source node, ψ(α(A₀))
    (docs/conventions.md §15).  With ``matrix_form`` the matrix parts of the arrows are
    MatrixSymbols (for printing).  ``forces(g) -> (f_minus, f_plus)`` with ``inputs``: the
    discrete forces (:func:`~symgroupoid.derivation.force_functions`, docs/conventions.md
    §20).  ``stages``: the number of internal variables ζ of each arrow; L is then called
    ``L(g, zeta)`` with ζ a list of symbols, and the forces ``forces(g, zeta) -> (f_minus,
    f_plus, f_stages)`` (docs/conventions.md §22).
    """
    slots = tuple(slot(groupoid, f"s{i}_", matrix_form) for i in range(arity))
    views = [groupoid.view(s) for s in slots]
    zeta = internal_stages(name, stages, arity)
    L = as_scalar(name, "Lagrangian", call_user(name, "Lagrangian", lagrangian, *views,
                                                *([list(zeta)] if zeta else []), smooth=True))
    coords = [c for s in slots for c in s] + list(zeta)
    if not matrix_form:
        check_symbols(name, "Lagrangian", [L], coords, parameters, inputs)
        maps, placeholders = groupoid.map_expressions(slots[0])
        check_symbols(name, f"groupoid {groupoid.name} (its structure maps)",
                      [sp.sympify(e) for e in maps], [*coords, *placeholders], parameters)
    phis: list = []
    if constraints is not None:
        raw = call_user(name, "constraints", constraints, *views, smooth=True)
        phis = as_scalar_list(name, "constraints", raw)
        if not matrix_form:
            check_symbols(name, "constraints", phis, coords, parameters, inputs)
    base = tuple(sp.Dummy(f"q{i}", real=True) for i in range(groupoid.base_dim))
    psis = [] if holonomic is None else holonomic_functions(name, groupoid, holonomic, base,
                                                           parameters)
    if not matrix_form:
        check_parameters_unlike_coordinates(name, groupoid, parameters,
                                            constrained=bool(phis or psis))
    if len(phis) + len(psis) > groupoid.rank:
        held = f" and {len(psis)} holonomic" if psis else ""
        raise ShapeError(
            f"{name}: {len(phis)} constraints{held} but only {groupoid.rank} unknown fibre "
            f"coordinates per step on {groupoid.name}; more constraints than unknowns")
    fs = SystemFunctions(slots, L, phis, matrix_form, base, psis, stages=list(zeta))
    if forces is not None and not matrix_form:
        check_force_letter(name, parameters)
        fs.forces = force_functions(name, groupoid, forces, inputs, parameters, arity,
                                    stages=zeta)
    fs.constraints = phis + fs.at_base(groupoid.source(slots[0]))
    fs.rows = fs.rows_on(groupoid, slots)
    return fs


def internal_stages(name: str, stages: int, arity: int) -> tuple:
    """The generic internal variables ζ of a term: ``stages`` real symbols (first order)."""
    if not stages:
        return ()
    if arity != 1:
        raise UnsupportedFeatureError(f"{name}: internal stages are supported on first-order "
                                      f"systems only")
    return tuple(sp.Dummy(f"zeta{i}", real=True) for i in range(stages))


def holonomic_functions(name: str, groupoid: Groupoid, holonomic: Callable, base: tuple,
                        parameters: Sequence) -> list:
    """ψ(q) from the user's callable on a symbolic base point, checked: a list of scalars in
    the base point's coordinates and the parameters, each depending on the point (a
    constant constrains no configuration)."""
    what = "holonomic constraints"
    if groupoid.base_dim == 0:
        raise ShapeError(f"{name}: {groupoid.name} has a single base point, so there is no "
                         f"configuration for holonomic constraints to restrict; write "
                         f"constraints on the arrows (constraints=) instead")
    if not callable(holonomic):
        raise CallableError(f"{name}: the holonomic constraints must be a function of the base "
                            f"point (e.g. lambda q: [...]), got a {type(holonomic).__name__}")
    display = dict(zip(base, groupoid.named_source(1)))  # q_k, by the coordinates' names
    raw = call_user(name, what, holonomic, groupoid.base_view(base), smooth=True,
                    display=display)
    psis = as_scalar_list(name, what, raw)
    check_symbols(name, what, psis, base, parameters)
    for a, psi in enumerate(psis):
        if not psi.free_symbols & set(base):
            raise ShapeError(f"{name}: holonomic constraint {a + 1} ({psi}) does not depend "
                             f"on the configuration; ψ(q) must vary with the base point q")
    return psis


def shifted(fs: SystemFunctions, slots: Sequence[tuple], multipliers: Sequence,
            lagrangian: bool = True, separate: bool = False, stages: Sequence = ()):
    """L + λ·φ with the slot arrows replaced by ``slots`` (independent copies) and the
    internal stages by ``stages``; ``separate=True`` returns the list of λ_a·φᵃ terms
    instead."""
    sub: dict = dict(zip(fs.stages, stages))
    for s_old, s_new in zip(fs.slots, slots):
        sub.update(slot_substitution(s_old, s_new))
    terms = [lam * phi.xreplace(sub) for lam, phi in zip(multipliers, fs.constraints)]
    if separate:
        return terms
    total = fs.lagrangian.xreplace(sub) if lagrangian else sp.S.Zero
    return total + sum(terms, sp.S.Zero)


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


def chart_of(groupoid: Groupoid, offset: int, source: Sequence | None = None
             ) -> tuple[tuple, tuple, dict]:
    """Named fibre variables, chart coordinates and the map fibre ← chart of g_{k+offset},
    whose source is ``source`` (default: its named source)."""
    fibre = tuple(groupoid.named_fibre(offset))
    chart = tuple(groupoid.named_chart(offset))
    if source is None:
        source = groupoid.named_source(offset)
    values = tuple(groupoid.fibre_chart(chart, tuple(source)))
    cmap = {f: v for f, v in zip(fibre, values) if f != v}
    return fibre, chart, cmap


def next_map(groupoid: Groupoid, fibre: Sequence, cmap: dict) -> dict:
    """The substitution that gives a step's next known state: ``cmap`` (fibre ← chart of the
    newest arrow) with the newest fibre renormalised (:meth:`Groupoid.renormalised_fibre`,
    the identity on the fibre: docs/conventions.md §16).  Only the stored state uses it; the
    residuals use ``cmap`` itself."""
    values = [cmap.get(f, f) for f in fibre]
    renormalised = groupoid.renormalised_fibre(values)
    out = dict(cmap)
    out.update({f: v for f, v in zip(fibre, renormalised) if f != v})
    return out


def tidy(expr: sp.Expr) -> sp.Expr:
    """Expand polynomial-like residuals; keep rational ones (sum denominators) unexpanded."""
    expr = sp.sympify(expr)
    if any(p.exp.is_negative and isinstance(p.base, sp.Add) for p in expr.atoms(sp.Pow)):
        return expr
    return sp.expand(expr)


def window(arity: int) -> tuple[list[int], list[int]]:
    """Arrow offsets of the varied window and start offsets of its action terms.

    First order (arity 1): arrows g_k, g_{k+1}; terms L(g_k), L(g_{k+1}).
    Second order (arity 2): arrows g_{k-1} … g_{k+2}; terms L(g_{k-1}, g_k), L(g_k, g_{k+1}),
    L(g_{k+1}, g_{k+2}) (seed 001 eq. (12)).  The junction is always between g_k and g_{k+1};
    the term starting at offset s carries the multipliers λ_{k+s}.
    """
    return list(range(1 - arity, arity + 1)), list(range(1 - arity, 2))


def with_inputs(fs: SystemFunctions, knowns: list, next_knowns: list) -> tuple[list, list]:
    """The knowns and next knowns of a forced step (docs/conventions.md §20).  The input u_j
    belongs to the term of the action starting at g_j (first order: the arrow g_j; second
    order: the pair (g_j, g_{j+1})).  The state gains the inputs of its known terms (first
    order u_k; second order u_{k−1}, u_k), and the step reads the new term's inputs after
    them (u_{k+1}); the next state carries the inputs of its known terms, and its slot for
    the inputs to come holds u_{k+1} until the caller writes the next ones."""
    if not fs.inputs:
        return knowns, next_knowns
    _, starts = window(len(fs.slots))
    own = [u for s in starts[:-1] for u in input_symbols(fs.inputs, s)]
    new = input_symbols(fs.inputs, starts[-1])
    shifted_own = [u for s in starts[1:] for u in input_symbols(fs.inputs, s)]
    return knowns + own + new, next_knowns + shifted_own + new


def window_arrows(G: Groupoid, offsets: Sequence[int]) -> dict:
    """The named arrows g_{k+o} of a window, each composable after the previous one."""
    arrows = {offsets[0]: named(G, offsets[0], False)}
    for o in offsets[1:]:
        arrows[o] = next_arrow(G, arrows[o - 1], o, False)
    return arrows


def window_residuals(G: Groupoid, fs: SystemFunctions,
                     multipliers: bool = True) -> tuple[list, dict]:
    """Residuals of the junction variation between g_k and g_{k+1}, then the constraints on
    the newest term; returns them with the named arrows by offset.  With
    ``multipliers=False`` the constraints are not added to the action (nonholonomic).  The
    SymPy form of :class:`~symgroupoid.derivation.WindowAction`."""
    from ._assembly import WindowAction

    return WindowAction(G, fs).residuals(multipliers)


def junction_step(name: str, G: Groupoid, fs: SystemFunctions,
                  parameters: Sequence) -> DerivedStep:
    """The step of order ``len(fs.slots)``: known arrows and multipliers → the newest arrow
    (through its fibre chart) and multipliers.  One mechanism for every order: the residuals
    are the junction variation of the window action, as graph nodes (``_window``), and the
    same derivation in SymPy on request."""
    from ._window import window_graph

    arity, m = len(fs.slots), len(fs.constraints)
    offsets, starts = window(arity)
    arrows = window_arrows(G, offsets)
    newest, first = offsets[-1], offsets[0]
    fibre, chart, cmap = chart_of(G, newest, G.target(arrows[newest - 1]))
    lam = {s: multiplier_symbols(m, s) for s in starts}
    known_fibres = [f for o in offsets[1:-1] for f in G.named_fibre(o)]
    knowns = list(arrows[first]) + known_fibres + [x for s in starts[:-1] for x in lam[s]]
    shifted_fibres = [f for o in offsets[2:] for f in G.named_fibre(o)]
    next_knowns = (list(G.renormalised_arrow(arrows[first + 1])) + shifted_fibres
                   + [x for s in starts[1:] for x in lam[s]])
    successor = next_map(G, fibre, cmap)
    next_knowns = [sp.sympify(e).xreplace(successor) for e in next_knowns]
    stages = [z for s in starts for z in stage_symbols(len(fs.stages), s)]
    prediction = (list(G.predict_chart(arrows[newest - 1])) + [sp.S.Zero] * len(stages)
                  + lam[starts[-2]])
    knowns, next_knowns = with_inputs(fs, knowns, next_knowns)
    return DerivedStep(
        name=name, groupoid=G, order=arity, knowns=knowns, inputs=fs.inputs,
        stage_unknowns=stages,
        fibre_unknowns=fibre, chart_unknowns=chart, chart_map=cmap,
        multipliers_next=lam[starts[-1]], next_knowns=next_knowns,
        parameters=list(parameters), n_constraints=m, offsets=(first, newest),
        arrows=arrows, prediction=prediction,
        symbolic=lambda: window_residuals(G, fs)[0],
        graph=lambda: window_graph(name, G, fs, parameters),
        n_equations=G.rank + len(stages) + m,
        n_holonomic=fs.n_holonomic)


def check_nonholonomic_dimensions(name: str, G: Groupoid, r: int, m: int) -> None:
    """dim D_c + #constraints must equal the rank (seed 002: dim M_c = dim D_c)."""
    if r + m != G.rank:
        raise ShapeError(f"{name}: dim D_c ({r}) + number of discrete constraints ({m}) must "
                         f"equal the fibre dimension {G.rank}")


def _distribution_coefficients(name: str, G: Groupoid, distribution: Sequence,
                               q: Sequence) -> list[list]:
    """c_a^b(q) for each element X_a = Σ_b c_a^b E_b of D_c, at the base point q."""
    rows = []
    for a, basis in enumerate(distribution):
        coeffs = basis(tuple(q)) if callable(basis) else basis
        coeffs = [sp.sympify(c) for c in coeffs]
        if len(coeffs) != G.rank:
            raise ShapeError(f"{name}: distribution element {a} has {len(coeffs)} "
                             f"coefficients; the algebroid has rank {G.rank}")
        rows.append(coeffs)
    return rows


def distribution_coefficients(name: str, G: Groupoid, distribution: Sequence,
                              q: Sequence) -> list[list]:
    """c_a^b(q) for each element X_a = Σ_b c_a^b E_b of D_c at the base point q: the rows of
    the Hölder step are Σ_b c_a^b(β(g_k))·(the junction residual of E_b) (seed 002,
    docs/conventions.md §10)."""
    return _distribution_coefficients(name, G, distribution, q)


def nonholonomic_step(name: str, G: Groupoid, fs: SystemFunctions, distribution: Sequence,
                      parameters: Sequence) -> DerivedStep:
    """Discrete nonholonomic step (seed 002, discrete Hölder principle;
    docs/conventions.md §10):

        X⃖_a[L](g_k) = X⃗_a[L](g_{k+1})  for a basis X_a = Σ_b c_a^b E_b of D_c,
        g_{k+1} ∈ M_c = {ψ = 0},

    with the coefficients c_a^b evaluated at β(g_k) = α(g_{k+1}).  ``fs.constraints`` are
    the functions ψ defining M_c; ``distribution`` is a list of callables (or coefficient
    lists) giving c_a(q).  No multipliers: dim D_c + #ψ = rank.
    """
    from ._window import window_graph

    check_nonholonomic_dimensions(name, G, len(distribution), len(fs.constraints))
    arrows = window_arrows(G, window(1)[0])
    q = G.target(arrows[0])
    coefficients = _distribution_coefficients(name, G, distribution, q)

    def graph():
        wg = window_graph(name, G, fs, parameters, multipliers=False)
        g = wg.graph
        rows = [g.add(*[g.mul(_node(wg, c, name), d) for c, d in zip(coeffs, wg.del_rows)])
                for coeffs in coefficients]
        wg.residuals = rows + list(wg.constraint_rows)
        return wg

    def symbolic() -> list:
        residuals, _ = window_residuals(G, fs, multipliers=False)
        dels, psis = residuals[:G.rank], residuals[G.rank:]
        return [tidy(sum((c * d for c, d in zip(coeffs, dels)), sp.S.Zero))
                for coeffs in coefficients] + psis

    fibre, chart, cmap = chart_of(G, 1, G.target(arrows[0]))
    g0, g1 = arrows[0], arrows[1]
    knowns, next_knowns = with_inputs(
        fs, list(g0), [sp.sympify(c).xreplace(next_map(G, fibre, cmap))
                       for c in G.renormalised_arrow(g1)])
    return DerivedStep(
        name=name, groupoid=G, order=1, knowns=knowns, inputs=fs.inputs,
        fibre_unknowns=fibre, chart_unknowns=chart, chart_map=cmap, multipliers_next=[],
        next_knowns=next_knowns,
        parameters=list(parameters), n_constraints=0, offsets=(0, 1), arrows=arrows,
        prediction=list(G.predict_chart(g0)), symbolic=symbolic, graph=graph,
        n_equations=len(distribution) + len(fs.constraints))


def _node(wg, expr, name: str) -> int:
    """The graph node of a SymPy expression in the step's named symbols."""
    from ..ir import from_sympy

    for s in sorted(sp.sympify(expr).free_symbols, key=str):
        if s not in wg.symbols:
            wg.symbols[s] = wg.graph.input(s)
    return from_sympy(wg.graph, expr, wg.symbols, f"{name}: the distribution D_c", wg.memo)


def matrix_form_values(groupoid: Groupoid, offsets: Sequence[int]) -> dict:
    """MatrixSymbol g_{k+o} → explicit named matrix, and E_a → its value (for checking;
    named constants such as J_d carry their own values)."""
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
    from ..groupoids import to_explicit

    values = matrix_form_values(groupoid, offsets)
    for e, s in zip(explicit, structured):
        if sp.expand(to_explicit(s, values) - e) != 0:
            return None
    return list(structured)


def matrix_form_residuals(name: str, groupoid: Groupoid, lagrangian: Callable,
                          constraints: Callable | None, parameters: Sequence,
                          explicit: Sequence[sp.Expr], arity: int = 1,
                          holonomic: Callable | None = None) -> list | None:
    """The residuals with matrix parts kept as matrices (for LaTeX), verified against the
    explicit residuals; None when the groupoid has no matrix part or the form is unavailable."""
    if not any(not g.affine for _, g in groupoid.matrix_parts()):
        return None
    try:
        fs = evaluate_system(name, groupoid, lagrangian, constraints, parameters,
                             arity=arity, matrix_form=True, holonomic=holonomic)
        structured, _ = window_residuals(groupoid, fs)
    except (NotImplementedError, TypeError, AttributeError, ValueError):
        return None
    return verified_matrix_form(explicit, structured, groupoid, window(arity)[0])
