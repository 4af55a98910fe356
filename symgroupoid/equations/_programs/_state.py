"""Programs of the structure-preservation diagnostics of a step's known state.

Every quantity is a small :class:`~symgroupoid.ir.Program` over the flat known state of the
step (inputs ``known`` and ``p``), built from the system's own Lagrangian L and constraints
φ by the window action of :class:`~symgroupoid.derivation.WindowAction`: its term
T = L + λ·φ is captured once on generic slot arrows, differentiated by reverse mode, and
instantiated at the arrows the state holds; the invariant vector fields X⃖_b, X⃗_b come from
the structure maps (seed 000 eqs. (1)–(2)).  A whole trajectory is one vectorised evaluation
(the states are the batch axis); the SymPy residuals of the step are never needed.

Quantities (docs/conventions.md §3, §7):

- discrete momenta (seed 000 §3.3), per state (g_k, λ_k) of a first-order step:
  ⟨F⁻L(g_k, λ_k), X_b⟩ = X⃗_b[L + λ_k·φ](g_k),  ⟨F⁺L(g_k, λ_k), X_b⟩ = X⃖_b[L + λ_k·φ](g_k);
  along a solution F⁺L(g_k, λ_k) = F⁻L(g_{k+1}, λ_{k+1}) (the DEL).  Second order (seed 001
  §4): the momenta of the window (g_{k-1}, g_k, g_{k+1}) of
  :func:`~symgroupoid.derivation.second_order_legendre_forms`, with
  F⁺L(state k) = F⁻L(state k+2);
- the discrete energy: E_d = −∂L_d/∂h(g_k) for a declared step parameter h (the energy a
  fixed-step variational integrator keeps to O(h²) without drift), or, on a
  :class:`~symgroupoid.groupoids.TimeGroupoid`, the energy conjugate to time
  E(g_k) = −X⃖_t[L](g_k) = −∂L/∂t₁(g_k) (seed 000 §6.3), which the adaptive
  (unconstrained-time) step conserves exactly when L does not depend on the time
  explicitly (the time section a symmetry; otherwise E changes along the motion);
- constraint residuals: φ on the newest known arrows of each state (first order φ(g_k),
  second order Φ(g_k, g_{k+1}), nonholonomic ψ(g_k)).

A discrete Lagrangian with internal stages ζ (docs/conventions.md §22) is L_d(g) =
L(g, ζ*(g)) with ∂L/∂ζ(g, ζ*) = 0; by the envelope theorem its momenta and its energy are
those of L(g, ζ) at ζ = ζ*.  The programs of such a system take the stages as a further input
``zeta``, and :meth:`StatePrograms.quantity` ``"stages"`` gives the rows ∂L/∂ζ and their
Jacobian for the evaluator to solve ζ* at every state.

Of a forced first-order system (docs/conventions.md §20, §22) the momenta are the forced
discrete Legendre transforms F⁻L − f⁻ and F⁺L + f⁺ of the state's arrow with its inputs u_k
(Marsden–West eq. (3.2.4)), and the stage rows are the forced ones, ∂L/∂ζ + f_ζ: the
evaluator solves the stages the step solved, and the momenta and the energy are taken there.
"""

from __future__ import annotations

import functools
import weakref
from collections.abc import Sequence

import sympy as sp

from ..._errors import DiagnosticsError, TimeStepError
from ..._symbols import multiplier_symbols
from ...derivation import (
    WindowAction,
    declared_step_behaves,
    identified_time_steps,
    input_symbols,
    step_jacobian,
)
from ...ir import Graph, Program, from_sympy, gradient, term_magnitude


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows), or None."""
    return getattr(system, "_fs", None)


class StatePrograms:
    """The graph of the diagnostics of one step's known state (see the module docstring)."""

    def __init__(self, step):
        system = getattr(step, "system", None)
        fs = _functions(system)
        if fs is None:
            raise DiagnosticsError(
                f"{step.name}: diagnostics need the system's Lagrangian and constraints, and "
                f"these equations have no system attached (equations from "
                f"DiscreteSystem.euler_lagrange() carry one)")
        # no reference to the step itself: programs are cached per step in a weak mapping
        self.name, self.system, self.fs = step.name, system, fs
        self.knowns, self.parameters = list(step.knowns), list(step.parameters)
        self.groupoid = step.groupoid
        self.action = WindowAction(step.groupoid, fs)
        self.arity = self.action.arity
        self.m = step.n_constraints  # multipliers in the action (0 for nonholonomic steps)
        g = self.graph = Graph()
        self.symbols = {s: g.input(s) for s in (*step.knowns, *step.parameters)}
        self.pnodes = {p: self.symbols[p] for p in step.parameters}
        self.memo: dict = {}
        available = set(step.knowns) | set(step.parameters)
        self.offsets = [o for o in sorted(step.arrows)
                        if all(sp.sympify(c).free_symbols <= available
                               for c in step.arrows[o])]
        self.arrows = {o: [from_sympy(g, c, self.symbols, f"{self.name}: the arrows of the "
                                      f"state", self.memo) for c in step.arrows[o]]
                       for o in self.offsets}
        self.starts = [s for s in self.offsets
                       if all(s + i in self.arrows for i in range(self.arity))]
        if not self.starts:
            raise DiagnosticsError(f"{self.name}: the state holds no complete term of the "
                                   f"action")
        self.lam = {s: [self.symbols[x] for x in multiplier_symbols(self.m, s)]
                    for s in self.starts}
        self.term = self.action.term_nodes(g, list(self.parameters), self.m > 0, self.name)
        self.stage_symbols = [sp.Dummy(f"zeta{a}", real=True) for a in range(len(fs.stages))]
        if self.stage_symbols and self.arity != 1:
            raise DiagnosticsError(f"{self.name}: internal stages are first order only")
        self.zeta = ({0: [g.input(z) for z in self.stage_symbols]} if self.stage_symbols
                     else None)
        self._arrow_expressions = dict(step.arrows)
        self._fields: dict = {}
        self._programs: dict = {}

    @property
    def has_constraints(self) -> bool:
        """Whether the system has constraints (φ, ψ, or nonholonomic ψ)."""
        return bool(self.term.constraints)

    def instantiate(self, nodes: Sequence[int], s: int) -> list[int]:
        """Generic-slot nodes at the term starting at offset s (its arrows and λ_{k+s})."""
        arrows = [self.arrows[s + i] for i in range(self.arity)]
        return self.action.instantiate(self.graph, self.term, nodes, arrows, self.lam[s],
                                       stages=None if self.zeta is None else self.zeta[s])

    def fields(self, side: str, o: int) -> list[list[int]]:
        """X⃖_b (side "left") or X⃗_b ("right") at the state's arrow g_{k+o}."""
        key = (side, o)
        if key not in self._fields:
            self._fields[key] = self.action.fields(self.graph, side, self.arrows[o],
                                                   self.pnodes)
        return self._fields[key]

    def derivation(self, side: str, o: int, terms: Sequence[int], grad=None) -> list[int]:
        """Σ over the terms T_s of X_b[T_s] at the arrow g_{k+o} (one node per section b)."""
        return self.action.derivation_nodes(self.graph, self.term, self.fields(side, o), o,
                                            terms, self.arrows, self.lam, grad, self.zeta)

    # --- the quantities ------------------------------------------------------------------------
    @functools.cached_property
    def forces(self) -> tuple[list[int], list[int], list[int]] | None:
        """(f⁻, f⁺, f_ζ) of the state's arrow g_k with its inputs u_k (and the stages ζ of
        a system with internal stages) for a forced first-order system, else None
        (docs/conventions.md §20, §22)."""
        forces = self.fs.forces
        if forces is None or self.arity != 1:
            return None
        mapping = dict(self.pnodes)
        mapping.update(zip(forces.slot, self.arrows[0]))
        mapping.update(zip(forces.inputs, [self.symbols[s]
                                           for s in input_symbols(forces.inputs, 0)]))
        if forces.stages:
            mapping.update(zip(forces.stages, self.zeta[0]))
        memo: dict = {}

        def nodes(exprs, what: str) -> list[int]:
            return [from_sympy(self.graph, e, mapping, f"{self.name}: {what}", memo)
                    for e in exprs]

        return (nodes(forces.minus, "the forces (f⁻)"), nodes(forces.plus, "the forces (f⁺)"),
                nodes(forces.stage_forces, "the stage forces"))

    @functools.cached_property
    def momenta(self) -> tuple[list[int], list[int]]:
        """(F⁻L, F⁺L) nodes of the state (see the module docstring); of a forced first-order
        system the forced discrete Legendre transforms F⁻L − f⁻ and F⁺L + f⁺ (Marsden–West
        eq. (3.2.4)), whose matching F⁺L(g_k) + f⁺(g_k) = F⁻L(g_{k+1}) − f⁻(g_{k+1}) is the
        forced DEL (docs/conventions.md §20)."""
        d = self.derivation
        if self.arity == 1:
            minus, plus = d("right", 0, [0]), d("left", 0, [0])
            if self.forces is not None:
                f_minus, f_plus, _ = self.forces
                g = self.graph
                minus = [g.sub(a, b) for a, b in zip(minus, f_minus)]
                plus = [g.add(a, b) for a, b in zip(plus, f_plus)]
            return minus, plus
        a0, a1, a2 = self.offsets[:3]
        t0, t1 = self.starts[:2]
        g = self.graph
        plus = ([g.sub(x, y) for x, y in zip(d("left", a1, [t0, t1]), d("right", a2, [t1]))]
                + d("left", a2, [t1]))
        minus = (d("right", a0, [t0])
                 + [g.sub(y, x) for x, y in zip(d("left", a0, [t0]),
                                                d("right", a1, [t0, t1]))])
        return minus, plus

    @functools.cached_property
    def constraints(self) -> list[int]:
        """φ on the newest term of the state (holonomic constraints: ψ at the target of its
        last arrow, the newest node)."""
        return self.instantiate(self.term.rows, self.starts[-1])

    def energy(self, step_parameter: str | None) -> tuple[list[int], str]:
        """The energy node and its description (see the module docstring)."""
        if self.arity != 1:
            raise DiagnosticsError(f"{self.name}: the discrete energy is defined here for "
                                   f"first-order systems (L: G → R) only")
        g, slots = self.graph, self.term.flat_slots
        if step_parameter is None and self.groupoid.timed:
            grad_L = gradient(g, self.term.lagrangian, slots)
            # the time section ∂/∂t is the first basis section of R×R×G
            return [g.neg(self.derivation("left", 0, [0], grad_L)[0])], "E = −∂L/∂t₁"
        h = self._step_symbol(step_parameter)
        (dL,) = gradient(g, self.term.lagrangian, [self.pnodes[h]])
        return [g.neg(self.instantiate([dL], 0)[0])], f"E_d = −∂L_d/∂{h}"

    def _step_symbol(self, name: str | None) -> sp.Symbol:
        """The parameter to differentiate by: ``name`` when given, else the system's time
        step (declared, or identified by the continuous limit), else a :class:`TimeStepError`."""
        by_name = {str(p): p for p in self.parameters}
        if name is not None and not isinstance(name, (str, sp.Symbol)):
            raise DiagnosticsError(f"{self.name}: step_parameter must be the name of a "
                                   f"parameter (a string), got {type(name).__name__} "
                                   f"{name!r}")
        if name is None:
            return self._checked_step(self._time_step(by_name))
        if str(name) not in by_name:
            raise DiagnosticsError(f"{self.name}: step_parameter={name!r} is not a parameter "
                                   f"of the system (parameters: {', '.join(by_name) or 'none'})")
        return by_name[str(name)]

    def time_step(self) -> sp.Symbol | None:
        """The system's time step h — declared (``time_step=``), else the one parameter that
        behaves as the step in the continuous limit (docs/conventions.md §19) — or None
        when it cannot be told (a time groupoid's step is each arrow's t₁ − t₀)."""
        try:
            return self._time_step({str(p): p for p in self.parameters})
        except TimeStepError:
            return None

    def _checked_step(self, h: sp.Symbol) -> sp.Symbol:
        """The declared step ``h`` once the continuous limit has not refuted it (§19: an
        energy −∂L_d/∂h of a step that is not one is no energy), else a
        :class:`TimeStepError`; an identified step has passed the limit already."""
        if declared_step_behaves(self.system) is False:
            raise TimeStepError(
                f"{self.name}: the declared time step {h} does not behave as the step in the "
                f"continuous limit (L_d(g_h(q, v))/h tends to no Lagrangian with a kinetic "
                f"term as {h} → 0; docs/conventions.md §19), so E_d = −∂L_d/∂{h} would not "
                f"be the energy.  A discrete Lagrangian approximates the action over a step, "
                f"h·L: e.g. the midpoint rule h·L((q₀ + q₁)/2, (q₁ − q₀)/h), not "
                f"L((q₀ + q₁)/2, (q₁ − q₀)/h); step_parameter=... differentiates by a "
                f"parameter unchecked")
        return h

    def _time_step(self, by_name: dict) -> sp.Symbol:
        declared = getattr(self.system, "time_step", None)
        if declared is not None:
            return by_name.get(str(declared), declared)
        found = identified_time_steps(self.system)
        if len(found) == 1:
            return by_name.get(str(found[0]), found[0])
        listed = ", ".join(by_name) or "none"
        if found:
            why = (f"several parameters behave as the step in the continuous limit "
                   f"({', '.join(map(str, found))}: L_d(g_h(q, v))/h has a limit with each "
                   f"of them as h)")
        else:
            why = (f"no parameter behaves as the step in the continuous limit (for none of "
                   f"{listed} as h does L_d(g_h(q, v))/h tend to a Lagrangian with a kinetic "
                   f"term)")
        raise TimeStepError(
            f"{self.name}: the discrete energy E_d = −∂L_d/∂h needs the time step h, and {why} "
            f"(docs/conventions.md §19); declare it: {type(self.system).__name__}(..., "
            f"time_step=<the step parameter>), or pass step_parameter=... here")

    @property
    def n_stages(self) -> int:
        """The number of internal stages ζ of the state's arrow (an input ``zeta`` of every
        quantity's program when positive)."""
        return len(self.stage_symbols)

    def program(self, outputs: dict) -> Program:
        """The program of ``outputs`` (name → nodes of this graph) over the known state (and
        the stages ``zeta`` of a system with internal stages)."""
        inputs = {"known": self.knowns, "p": self.parameters}
        if self.stage_symbols:
            inputs["zeta"] = list(self.stage_symbols)
        return Program(self.graph, inputs, outputs)

    def stages(self) -> tuple[list[int], list[int]]:
        """The stage rows ∂L/∂ζ(g_k, ζ) of the state's arrow and their Jacobian ∂/∂ζ
        (row-major), whose root ζ* the evaluator solves; of a forced system the forced
        stage rows ∂L/∂ζ + f_ζ(g_k, ζ; u_k), whose root is the stages the step solved for
        the state's arrow with its inputs (docs/conventions.md §22)."""
        rows = self.instantiate(self.term.stage_gradient, 0)
        if self.forces is not None:  # the forced stage rows ∂L/∂ζ + f_ζ (§22)
            rows = [self.graph.add(r, f) for r, f in zip(rows, self.forces[2])]
        J = step_jacobian(self.graph, rows, self.zeta[0])
        return rows, [c for row in J for c in row]

    # --- the programs an evaluator runs ------------------------------------------------------
    def quantity(self, key: str, step_parameter: str | None = None) -> Program:
        """The (cached) program of one quantity, its output ``out``: ``"minus"`` (F⁻L),
        ``"plus"`` (F⁺L), ``"constraints"`` (φ on the newest term), ``"energy"`` (by
        ``step_parameter``, see :meth:`energy`; a further output ``scale``, the size of the
        terms it is computed from, the state's entries varying:
        :func:`~symgroupoid.ir.term_magnitude`) or ``"stages"`` (outputs ``out``, the stage
        rows, and ``J``, their Jacobian, see :meth:`stages`)."""
        cache_key = f"energy:{step_parameter}" if key == "energy" else key
        hit = self._programs.get(cache_key)
        if hit is None:
            if key == "energy":
                nodes = self.energy(step_parameter)[0]
                varying = [self.symbols[s] for s in self.knowns]
                varying += self.zeta[0] if self.zeta is not None else []
                scale = term_magnitude(self.graph, nodes, varying)
                hit = self._programs[cache_key] = self.program({"out": nodes, "scale": scale})
                return hit
            elif key in ("minus", "plus"):
                nodes = self.momenta[key == "plus"]
            elif key == "constraints":
                nodes = self.constraints
            elif key == "stages" and self.zeta is not None:
                nodes, J = self.stages()
                hit = self._programs[cache_key] = self.program({"out": nodes, "J": J})
                return hit
            else:
                raise ValueError(f"unknown quantity {key!r}")
            hit = self._programs[cache_key] = self.program({"out": nodes})
        return hit

    def energy_label(self, step_parameter: str | None) -> str:
        """What the energy program computes, e.g. ``"E_d = −∂L_d/∂h"``."""
        return self.energy(step_parameter)[1]

    @functools.cached_property
    def projection(self) -> Program:
        """The constraints φ on the known arrow moved within its α-fibre (first-order
        steps): inputs ``x`` (fibre chart coordinates, rank), ``known``, ``p``; outputs
        ``phi`` = φ(g(x)) with g(x) = arrow_from(α(g_k), τ(x)), ``J`` = ∂φ/∂x (m × rank,
        row-major, forward mode through the chart) and ``arrow`` = g(x)."""
        G, g = self.groupoid, self.graph
        chart = [sp.Dummy(f"x{i}", real=True) for i in range(G.rank)]
        symbols = dict(self.symbols)
        symbols.update({x: g.input(x) for x in chart})
        source = tuple(G.source(self._arrow_expressions[0]))
        moved = tuple(G.arrow_from(source, G.fibre_chart(tuple(chart), source)))
        arrow = [from_sympy(g, c, symbols, f"{self.name}: the fibre chart of the known arrow")
                 for c in moved]
        phi = g.substitute(self.term.rows, dict(zip(self.term.flat_slots, arrow)))
        J = step_jacobian(g, phi, [symbols[x] for x in chart])
        return Program(g, {"x": chart, "known": self.knowns, "p": self.parameters},
                       {"phi": phi, "J": [c for row in J for c in row], "arrow": arrow})


_PROGRAMS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def state_programs(step) -> StatePrograms:
    """The (cached) :class:`StatePrograms` of a step."""
    hit = _PROGRAMS.get(step)
    if hit is None:
        hit = _PROGRAMS[step] = StatePrograms(step)
    return hit
