"""Projecting an initial state onto the constraints (:meth:`Simulator.project_initial`).

The known arrow g_k of a first-order state is moved within its α-fibre — its source α(g_k)
fixed — to the nearest zero of the constraints in the fibre chart: with g(x) =
arrow_from(α(g_k), τ(x)) and x₀ = τ⁻¹(g_k), Gauss–Newton with minimum-norm steps

    x ← x − J⁺ φ(g(x)),   J = ∂φ(g(x))/∂x  (m × rank, forward mode on the graph),

(:func:`~symgroupoid.equations.gauss_newton`) converges to a point of N = {φ = 0} near x₀ (to
first order the orthogonal projection of x₀ in the chart).  On a pair groupoid (q₀, q₁) this
keeps q₀ and corrects q₁; on a Lie group it corrects the element; on a time groupoid with
φ = t₁ − t₀ − h it sets t₁.  Holonomic constraints are projected at the target,
ψ(β(g_k)) = 0, and first at the source: a configuration typed to a few digits is off
M = {ψ = 0}, so the source is moved onto M first (:class:`SourceProjection`), keeping the
target.  The multipliers λ_k are not changed (they enter the run only through
F⁺L(g_k, λ_k)).
"""

from __future__ import annotations

import weakref

import numpy as np

from .._errors import DomainError
from ..equations import PROJECTED, gauss_newton, source_projection_program, state_programs

_EPS = float(np.finfo(float).eps)


def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows), or None."""
    return getattr(system, "_fs", None)


class ProjectionError(DomainError):
    """An initial state cannot be projected onto the constraints (no nearby zero of φ in the
    fibre of its source, or a step kind the projection does not handle)."""


class ConstraintProjection:
    """The Gauss–Newton projection of one step's known arrow (see the module docstring)."""

    def __init__(self, step, layout):
        # no reference to the step or its layout: cached per step in a weak mapping
        self.name, self.index = step.name, layout.arrow_index[0]
        if step.order != 1:
            raise ProjectionError(
                f"{step.name}: project_initial handles first-order steps; for a second-order "
                f"step give consistent arrows, or start from a momentum "
                f"(Simulator.from_momentum)")
        programs = state_programs(step)
        self.has_constraints = programs.has_constraints
        if not self.has_constraints:
            return
        fs = _functions(getattr(step, "system", None))
        self.source = SourceProjection(step) if fs is not None and fs.n_holonomic else None
        self.groupoid = step.groupoid
        self.program = programs.projection
        self.m = len(self.program.outputs["phi"])

    def __call__(self, state: np.ndarray, p: np.ndarray, max_iterations: int = 50
                 ) -> np.ndarray:
        if not self.has_constraints:
            return state.copy()
        G = self.groupoid
        index = self.index
        if self.source is not None:  # α(g_k) onto M first: a typed configuration is off it
            state = state.copy()
            state[index] = self.source(state[index], p, max_iterations)
        a0 = state[index]
        source = tuple(float(v) for v in G.source(tuple(a0)))
        x = np.array(G.fibre_chart_inverse(tuple(G.fibre_of(tuple(a0))), source), float)
        f = self.program.numpy_function(["phi", "J", "arrow"], ["x", "known", "p"])
        best, history, _ = gauss_newton(lambda x: f(x, state, p), x, max_iterations)
        if best is None or not best[0] < PROJECTED:
            shown = ", ".join(f"{v:.1e}" for v in history[-4:]) or "non-finite"
            raise ProjectionError(
                f"{self.name}: could not project the initial state onto the constraints: "
                f"Gauss–Newton in the fibre of α(g_k) reached |φ|∞ = {shown}; no zero of the "
                f"constraints near the given arrow (check the parameters, or start closer)")
        out = state.copy()
        out[index] = best[2]
        return out


class SourceProjection:
    """The source q = α(g) of the known arrow moved onto M = {ψ = 0}, its target kept.

    With e(x) = arrow_from(q, τ_q(x)) the arrow from q with fibre chart coordinates x (so
    that e(x₀) = ε(q)), the new source is q′ = β(e(x)) and the new arrow e(x)⁻¹·g, the
    groupoid's own multiplication: on a pair groupoid (q, q₁) ↦ (q′, q₁).  x solves ψ(β(e(x)))
    = 0 by Gauss–Newton with minimum-norm steps from x₀ (to first order the orthogonal
    projection of q onto M in the chart), the Jacobian exact (forward mode on the graph of
    :func:`~symgroupoid.equations.source_projection_program`).
    """

    def __init__(self, step):
        self.name, self.groupoid = step.name, step.groupoid
        program = source_projection_program(step)
        self.residual = program.numpy_function(["psi", "J"], ["x", "q", "p"])
        self.moved = program.numpy_function(["moved"], ["x", "a"])

    def __call__(self, arrow: np.ndarray, p: np.ndarray, max_iterations: int) -> np.ndarray:
        G = self.groupoid
        q = tuple(float(v) for v in G.source(tuple(arrow)))
        x = np.array(G.fibre_chart_inverse(tuple(G.fibre_of(G.identity(q))), q), float)
        _, history, x = gauss_newton(lambda x: self.residual(x, q, p), x, max_iterations)
        if not history or not min(history) < PROJECTED:
            shown = ", ".join(f"{v:.1e}" for v in history[-4:]) or "non-finite"
            raise ProjectionError(
                f"{self.name}: could not move the configuration α(g_k) onto the holonomic "
                f"constraint set M = {{ψ = 0}}: Gauss–Newton reached |ψ|∞ = {shown}; no point "
                f"of M near the given configuration (check the parameters, e.g. the lengths)")
        return np.array([float(v) for v in self.moved(x, list(arrow))[0]])


_PROJECTIONS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def projection(step, layout) -> ConstraintProjection:
    """The (cached) :class:`ConstraintProjection` of a step."""
    hit = _PROJECTIONS.get(step)
    if hit is None:
        hit = _PROJECTIONS[step] = ConstraintProjection(step, layout)
    return hit
