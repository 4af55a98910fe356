"""The window action of a step and its junction variation, assembled once.

For L: Gᵃ → R (a = the order) and constraints φ, the window of a step holds the arrows
g_{k+o}, o ∈ ``offsets`` = 1 − a, …, a, and the terms T_s = [L + λ_{k+s}·φ](g_{k+s}, …,
g_{k+s+a−1}) for s ∈ ``starts`` = 1 − a, …, 1 (seed 001 eq. (12); first order: T₀ = [L +
λ_k·φ](g_k), T₁ = [L + λ_{k+1}·φ](g_{k+1})).  The action of the window is

    S = Σ_s T_s,

and its junction variation between g_k and g_{k+1} for the basis section X_b is

    d/dt S = X⃖_b[S](g_k) − X⃗_b[S](g_{k+1})

(seed 000 §5.1, seed 001 eq. (11); docs/conventions.md §2, §4, §8).  A step adds its rows
on the newest term: φ, then ψ at the target of its last arrow (docs/conventions.md §15).

:class:`WindowAction` is that definition, and every user takes its pieces from it:

- in SymPy (printing and checking): :meth:`WindowAction.action`, :meth:`~WindowAction.halves`
  on independent slot arrows, :meth:`~WindowAction.residuals` at the named arrows — the
  step's residuals, its forms in named pieces (:mod:`._pieces`, for LaTeX) and the
  energy–momentum halves;
- on the expression graph (every evaluator): :meth:`~WindowAction.term_nodes` — one term on
  generic slots and its gradient by reverse mode, taken once —, :meth:`~WindowAction.instantiate`
  at the arrows of a term, :meth:`~WindowAction.junction_nodes` (the step kernel and the
  boundary-value window), :meth:`~WindowAction.derivation_nodes` (the discrete momenta of a
  state, its halves), and :func:`field_derivatives`/:func:`slot_derivatives` (the
  derivatives of window residuals along the section fields: the boundary-value Jacobian).

Nothing is expanded on the graph; shared subexpressions stay shared.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import sympy as sp

from .._errors import UnsupportedFeatureError
from .._symbols import multiplier_symbols, stage_symbols
from ..groupoids import Groupoid
from ..ir import Context, Graph, domain_nodes, forward, from_sympy, gradient
from ._junction import junction_halves, slot, slot_substitution
from ._step import SystemFunctions, named, next_arrow, shifted, tidy, window


@dataclass
class TermNodes:
    """One term T = L + λ·φ of the action on generic slot arrows (graph nodes)."""

    slots: list  # per slot: the nodes of its coordinates
    multipliers: list  # the generic λ nodes
    lagrangian: int  # L
    gradient: list  # ∂T/∂(slot coordinates), slot by slot
    constraints: list  # φ (as in the action: the user's φ, then ψ at the source node)
    rows: list  # a step's rows on the term: φ, then ψ at the target of its last arrow
    stages: list  # the generic internal stage nodes ζ (docs/conventions.md §22)
    stage_gradient: list  # ∂T/∂ζ: the term's stage rows
    #: nodes of L, φ and the rows defined on part of the real line only (log, √, acos, …;
    #: :func:`symgroupoid.ir.domain_nodes`): finite exactly where the term is defined
    domain: list = field(default_factory=list)

    @property
    def flat_slots(self) -> list:
        return [n for s in self.slots for n in s]


@dataclass
class JunctionNodes:
    """The junction variation of a window's action at given arrows (graph nodes)."""

    left: list  # X⃖_b[S](g_0), one per basis section
    right: list  # X⃗_b[S](g_1)
    residuals: list  # left − right: the junction residuals (docs/conventions.md §2)
    constraints: dict  # start offset s -> φ on the term starting at s (as in the action)
    rows: dict  # start offset s -> a step's rows on that term: φ, then ψ(β(its last arrow))
    stage_rows: dict  # start offset s -> ∂T_s/∂ζ_s (empty without internal stages)
    #: start offset s -> the term's domain nodes (:attr:`TermNodes.domain`) at its arrows
    domain: dict = field(default_factory=dict)


class WindowAction:
    """The action of a step's window and its junction variation (see the module docstring)."""

    def __init__(self, groupoid: Groupoid, functions: SystemFunctions):
        self.groupoid, self.functions = groupoid, functions
        self.arity, self.m = len(functions.slots), len(functions.constraints)
        self.offsets, self.starts = window(self.arity)

    def multipliers(self, s: int) -> list:
        """λ_{k+s}, the multipliers of the term starting at offset s."""
        return multiplier_symbols(self.m, s)

    def stages(self, s: int) -> list:
        """ζ_{k+s}, the internal stages of the term starting at offset s."""
        return stage_symbols(len(self.functions.stages), s)

    def newest(self, arrows: dict) -> list:
        """The arrows of the newest term (the one a step solves for)."""
        return [arrows[self.starts[-1] + i] for i in range(self.arity)]

    # --- SymPy -----------------------------------------------------------------------------
    def slots(self, prefix: str, matrix_form: bool = False) -> dict:
        """Independent slot arrows A_o for every offset o (fresh Dummy coordinates)."""
        return {o: slot(self.groupoid, f"{prefix}{o + 2}_", matrix_form) for o in self.offsets}

    def action(self, slots: dict, multipliers: bool = True, lagrangian: bool = True
               ) -> sp.Expr:
        """S = Σ_s [L + λ_s·φ](A_s, …) (``multipliers=False``: Σ_s L; ``lagrangian=False``:
        Σ_s λ_s·φ)."""
        fs, arity = self.functions, self.arity
        return sum((shifted(fs, [slots[s + i] for i in range(arity)],
                            self.multipliers(s) if multipliers else [], lagrangian=lagrangian,
                            stages=self.stages(s))
                    for s in self.starts), sp.S.Zero)

    def halves(self, slots: dict, multipliers: bool = True, lagrangian: bool = True
               ) -> tuple[list, list]:
        """(X⃖_b[S](A_0), X⃗_b[S](A_1)) in the slot coordinates."""
        return junction_halves(self.groupoid, self.action(slots, multipliers, lagrangian),
                               slots[0], slots[1])

    def variation(self, slots: dict, multipliers: bool = True, lagrangian: bool = True
                  ) -> list:
        """X⃖_b[S](A_0) − X⃗_b[S](A_1), one per basis section."""
        left, right = self.halves(slots, multipliers, lagrangian)
        return [a - b for a, b in zip(left, right)]

    def named_arrows(self, matrix_form: bool = False) -> dict:
        """The named arrows g_{k+o} of the window, each composable after the one before."""
        G, offsets = self.groupoid, self.offsets
        arrows = {offsets[0]: named(G, offsets[0], matrix_form)}
        for o in offsets[1:]:
            arrows[o] = next_arrow(G, arrows[o - 1], o, matrix_form)
        return arrows

    @staticmethod
    def naming(slots: dict, arrows: dict) -> dict:
        """The substitution taking every slot to its named arrow."""
        sub: dict = {}
        for o in slots:
            sub.update(slot_substitution(slots[o], arrows[o]))
        return sub

    def residuals(self, multipliers: bool = True) -> tuple[list, dict]:
        """The step's residuals in SymPy — the junction variation at the named arrows, then
        the stage rows ∂S/∂ζ_{k+s} of every term (docs/conventions.md §22), the rows on the
        newest term — and the named arrows by offset.  With ``multipliers=False`` the
        constraints are not in the action (nonholonomic)."""
        fs, mf = self.functions, self.functions.matrix_form
        slots = self.slots("w", mf)
        variation = self.variation(slots, multipliers)
        arrows = self.named_arrows(mf)
        sub = self.naming(slots, arrows)
        residuals = [d.xreplace(sub) for d in variation]
        stages = {s: self.stages(s) for s in self.starts}
        if fs.forces is not None:
            residuals = [r + f for r, f in zip(residuals, fs.forces.window_terms(
                arrows, self.starts, stages if fs.stages else None))]
        if fs.stages:
            action = self.action(slots, multipliers)
            residuals += [sp.diff(action, z).xreplace(sub) + f for s in self.starts
                          for z, f in zip(stages[s], self._stage_forces(arrows, s, stages))]
        residuals = [tidy(r) for r in residuals]
        residuals += [tidy(c) for c in fs.rows_on(self.groupoid, self.newest(arrows))]
        return residuals, arrows

    def _stage_forces(self, arrows: dict, s: int, stages: dict) -> list:
        """f_ζ of the term starting at s (zeros without forces; docs/conventions.md §22)."""
        forces = self.functions.forces
        if forces is None or not forces.stages:
            return [sp.S.Zero] * len(stages[s])
        return forces.stage_terms(arrows[s], s, stages[s])

    def constraints_on(self, slots: dict, s: int | None = None) -> list:
        """φ on the term starting at offset s (default: the newest), in the slot
        coordinates (as in the action)."""
        s = self.starts[-1] if s is None else s
        return shifted(self.functions, [slots[s + i] for i in range(self.arity)],
                       [1] * self.m, lagrangian=False, separate=True)

    # --- the expression graph ------------------------------------------------------------------
    def term_nodes(self, g: Graph, parameters: Sequence, with_multipliers: bool = True,
                   name: str = "") -> TermNodes:
        """T = L + λ·φ on generic slots (``with_multipliers=False``: T = L), its gradient in
        the slot coordinates (reverse mode, once), φ, and a step's rows on the term; the
        ``parameters`` (symbols) are the graph's input nodes of theirs."""
        fs, m = self.functions, self.m
        where = f"{name}: " if name else ""
        smap = {c: g.input(c) for s in fs.slots for c in s}
        smap.update({z: g.input(z) for z in fs.stages})
        smap.update({p: g.input(p) for p in parameters})
        memo: dict = {}
        # (messages show the term's slot coordinates as the arrows g_k, g_{k+1}, …)
        shown = {c: n for i, s in enumerate(fs.slots)
                 for c, n in zip(s, self.groupoid.named_arrow(i))}

        def node(expr, what: str) -> int:
            return from_sympy(g, expr, smap, Context(f"{where}{what}", shown), memo)

        L = node(fs.lagrangian, "the Lagrangian")
        phis = [node(phi, f"constraint {a + 1}") for a, phi in enumerate(fs.constraints)]
        held = m - fs.n_holonomic
        rows = phis[:held] + [node(psi, f"holonomic constraint {a + 1}")
                              for a, psi in enumerate(fs.rows[held:])]
        lam = [g.input(sp.Dummy(f"lam{a}", real=True)) for a in range(m)]
        T = L
        if with_multipliers and m:
            T = g.add(L, *[g.mul(x, phi) for x, phi in zip(lam, phis)])
        slot_nodes = [[smap[c] for c in s] for s in fs.slots]
        zeta = [smap[z] for z in fs.stages]
        flat = [n for s in slot_nodes for n in s]
        grad = gradient(g, T, flat + zeta)
        return TermNodes(slot_nodes, lam, L, grad[:len(flat)], phis, rows, zeta,
                         grad[len(flat):], domain_nodes(g, [L, *phis, *rows], flat + zeta))

    def instantiate(self, g: Graph, term: TermNodes, nodes: Sequence[int], arrows: Sequence,
                    multipliers: Sequence | None = None, extra: dict | None = None,
                    stages: Sequence | None = None) -> list[int]:
        """Generic-slot ``nodes`` of ``term`` at a term's arrows (one node list per slot),
        multipliers (None: the generic λ stay) and internal stages.  Nodes that depend on the
        internal stages need ``stages`` (an :class:`UnsupportedFeatureError` otherwise: the
        evaluation has no values for them)."""
        mapping = dict(zip(term.flat_slots, [c for a in arrows for c in a]))
        mapping.update(extra or {})
        if multipliers is not None:
            mapping.update(dict(zip(term.multipliers, multipliers)))
        if stages is not None:
            mapping.update(dict(zip(term.stages, stages)))
        elif term.stages and set(term.stages) & set(g.reachable(list(nodes))):
            raise UnsupportedFeatureError(
                "this evaluation needs the internal stages of a discrete Lagrangian with "
                "internal stages (a Galerkin discretisation), which it does not solve for; "
                "see docs/conventions.md §22 for what such systems support")
        return g.substitute(list(nodes), mapping)

    def fields(self, g: Graph, side: str, coords: Sequence[int], parameters: dict
               ) -> list[list[int]]:
        """X⃖_b(a) (``side="left"``) or X⃗_b(a) at an arrow given by nodes: the groupoid's
        :meth:`~symgroupoid.groupoids.Groupoid.field_nodes` (seed 000 eqs. (1)–(2))."""
        return self.groupoid.field_nodes(g, side, coords, parameters)

    def junction_nodes(self, g: Graph, parameters: dict, arrows: dict,
                       multipliers: dict | None, inputs: dict | None = None,
                       stages: dict | None = None, name: str = "") -> JunctionNodes:
        """The junction variation between the window's arrows at offsets 0 and 1, at arrows
        given as graph nodes (``arrows[o]``: the coordinate nodes of the arrow at offset o;
        any nodes — named knowns and a chart of the unknown for a step, independent inputs
        for a boundary-value window).  ``parameters``: symbol → node; ``multipliers[s]``:
        the nodes of λ_s of the term starting at s (None: the constraints are not in the
        action, as for nonholonomic steps).  Also φ on every term of the window, and the
        rows a step imposes on each term: φ, then the holonomic constraints at the target
        of the term's last arrow (their action terms, ψ at each term's source node, are
        among the φ: the junction residual gets λ·dψ(β(g_0))(ρ(X)) from X⃗[ψ∘α](g_1),
        docs/conventions.md §15).  A forced system's residuals add f⁺(g_0) + f⁻(g_1)
        (:meth:`force_nodes`), with ``inputs[o]`` the nodes of the inputs of the arrow at
        offset o.  With internal stages, ``stages[s]`` are the nodes of ζ_s of the term
        starting at s, and ``stage_rows[s]`` its rows ∂T_s/∂ζ_s (docs/conventions.md §22).
        ``name`` (the step's) prefixes the messages of expressions code cannot evaluate."""
        G, arity, dim = self.groupoid, self.arity, self.groupoid.arrow_dim
        term = self.term_nodes(g, list(parameters), multipliers is not None, name)
        pmap = {g.inputs[p]: n for p, n in parameters.items() if p in g.inputs and
                g.inputs[p] != n}

        def instantiate(nodes: Sequence[int], s: int) -> list[int]:
            return self.instantiate(g, term, nodes, [arrows[s + i] for i in range(arity)],
                                    None if multipliers is None else multipliers[s], pmap,
                                    None if stages is None else stages[s])

        left = self.fields(g, "left", arrows[0], parameters)
        right = self.fields(g, "right", arrows[1], parameters)
        halves: dict = {0: [[] for _ in range(G.rank)], 1: [[] for _ in range(G.rank)]}
        for s in self.starts:
            grads = instantiate(term.gradient, s)
            for i in range(arity):
                o = s + i
                if o not in (0, 1):
                    continue
                part = grads[i * dim:(i + 1) * dim]
                fields = left if o == 0 else right
                for b in range(G.rank):
                    halves[o][b].extend(g.mul(d, v) for d, v in zip(part, fields[b])
                                        if d != g.zero and v != g.zero)
        lefts = [g.add(*t) for t in halves[0]]
        rights = [g.add(*t) for t in halves[1]]
        constraints = {s: instantiate(term.constraints, s) if self.m else []
                       for s in self.starts}
        rows = {s: instantiate(term.rows, s) if self.functions.n_holonomic else constraints[s]
                for s in self.starts}
        residuals = [g.sub(a, b) for a, b in zip(lefts, rights)]
        stage_rows = {s: instantiate(term.stage_gradient, s) if term.stages else []
                      for s in self.starts}
        if self.functions.forces is not None:
            forced, staged = self.force_nodes(g, parameters, arrows, inputs, stages)
            residuals = [g.add(r, f) for r, f in zip(residuals, forced)]
            stage_rows = {s: [g.add(r, f) for r, f in zip(stage_rows[s], staged[s])]
                          if staged[s] else stage_rows[s] for s in self.starts}
        domain = {s: instantiate(term.domain, s) for s in self.starts} if term.domain else {}
        return JunctionNodes(lefts, rights, residuals, constraints, rows, stage_rows, domain)

    def force_nodes(self, g: Graph, parameters: dict, arrows: dict, inputs: dict | None,
                    stages: dict | None = None) -> tuple[list[int], dict]:
        """Σ_s f^{(1−s)}_b(term s) for every basis section b (docs/conventions.md §20): the
        forces of each term of the window at the junction node β(g_0), base point 1 − s of
        the term starting at offset s, whose inputs are ``inputs[s]`` (nodes).  First order:
        f⁺_b(g_0) + f⁻_b(g_1); second order: f²_b(g_{−1}, g_0) + f¹_b(g_0, g_1) +
        f⁰_b(g_1, g_2); and by start offset s, f_ζ of term s, the stage forces (empty
        without internal stages), with ``stages[s]`` the nodes of ζ_s (docs/conventions.md
        §22)."""
        forces = self.functions.forces
        if inputs is None:
            raise UnsupportedFeatureError(
                "this evaluation of the junction has no inputs for the forces of a forced "
                "system: it needs the inputs of every term of the window (an empty list for "
                "forces without inputs)")
        if forces.stages and stages is None:
            raise UnsupportedFeatureError(
                "this evaluation needs the internal stages of a forced discrete Lagrangian "
                "with internal stages, which it does not solve for (docs/conventions.md §22)")

        def term(s: int) -> tuple[list[int], list[int]]:
            symbols = dict(parameters)
            for i, slot_arrow in enumerate(forces.slots):
                symbols.update(zip(slot_arrow, arrows[s + i]))
            symbols.update(zip(forces.inputs, inputs[s]))
            if forces.stages:
                symbols.update(zip(forces.stages, stages[s]))
            memo: dict = {}
            node = [from_sympy(g, e, symbols, f"the forces (component {b + 1})", memo)
                    for b, e in enumerate(forces.nodes[1 - s])]
            staged = [from_sympy(g, e, symbols, f"the stage forces (component {a + 1})",
                                 memo) for a, e in enumerate(forces.stage_forces)]
            return node, staged

        parts = {s: term(s) for s in self.starts}
        total = [g.add(*column) for column in zip(*(parts[s][0] for s in self.starts))]
        return total, {s: parts[s][1] for s in self.starts}

    def derivation_nodes(self, g: Graph, term: TermNodes, fields: Sequence, o: int,
                         terms: Sequence[int], arrows: dict, multipliers: dict,
                         gradient_nodes: Sequence[int] | None = None,
                         stages: dict | None = None) -> list[int]:
        """Σ over the terms T_s (s in ``terms``, each containing the arrow at offset o) of
        X_b[T_s] at that arrow, one node per section b; ``fields``: X_b at the arrow
        (:meth:`fields`), ``gradient_nodes``: the generic gradient to use (default T's),
        ``stages[s]``: the internal stages of term s (docs/conventions.md §22)."""
        G, dim = self.groupoid, self.groupoid.arrow_dim
        grad = term.gradient if gradient_nodes is None else gradient_nodes
        rows = [[] for _ in range(G.rank)]
        for s in terms:
            i = o - s
            at = [arrows[s + j] for j in range(self.arity)]
            inst = self.instantiate(g, term, grad[i * dim:(i + 1) * dim], at, multipliers[s],
                                    stages=None if stages is None else stages[s])
            for b in range(G.rank):
                rows[b].extend(g.mul(d, v) for d, v in zip(inst, fields[b])
                               if d != g.zero and v != g.zero)
        return [g.add(*r) for r in rows]


# --- derivatives of window residuals along the section fields ----------------------------------

def field_derivatives(g: Graph, values: list, arrows: dict, fields: dict) -> dict:
    """d[o][side][c][i] = the derivative of values[i] along field c of ``side`` (0: left,
    1: right) on the arrow at offset o.

    Reverse mode: one backward sweep per value gives its gradient with respect to every
    arrow coordinate of the window, then each field derivative is the gradient contracted
    with the field, Σ_j ∂v/∂a_{o,j}·X_c(a_o)_j.  Forward mode would sweep the values once per
    field (slots × 2 sides × rank sweeps); the residuals are few (the rank), so reverse
    costs a third as many operations for a second-order window."""
    coords = [c for o in arrows for c in arrows[o]]
    grads = [dict(zip(coords, gradient(g, v, coords))) for v in values]
    out: dict = {}
    for o, a in arrows.items():
        out[o] = [[[_contract(g, grad, a, field) for grad in grads] for field in fields[o][side]]
                  for side in (0, 1)]
    return out


def _contract(g: Graph, grad: dict, coords: list, field: list) -> int:
    terms = [g.mul(grad[c], v) for c, v in zip(coords, field)
             if v != g.zero and grad[c] != g.zero]
    return g.add(*terms) if terms else g.zero


def slot_derivatives(g: Graph, values: list, coords: list, fields: list, order) -> list:
    """d/dt values along each field (a tangent vector on ``coords``), forward mode."""
    return [forward(g, values, {c: v for c, v in zip(coords, field) if v != g.zero}, order)
            for field in fields]
