"""Every program the evaluators run, built in one place from the derivation.

A :class:`~symgroupoid.ir.Program` (named input arrays, named output arrays over one
expression graph) is the only thing that passes from the symbolic side to an evaluator:
the C kernels (:mod:`symgroupoid.codegen`) and the NumPy forms
(:meth:`~symgroupoid.ir.Program.numpy_function`) run programs and derive nothing.

- :func:`step_program` — a step's residual, exact Jacobian, chart, prediction, update;
- :func:`window_programs`, :func:`cost_program`, :func:`action_program`,
  :func:`structure_program` — a boundary-value solve's window residuals and blocks, its
  cost, the action's terms and the structure maps it applies to rows of arrows;
- :func:`state_programs` — the diagnostics of a step's known state (energy, momenta,
  constraint residuals) and the projection of an initial state onto the constraints;
- :func:`momentum_program`, :func:`second_order_momentum_program`,
  :func:`source_projection_program`, :func:`holonomic_projection_program` — the
  initial-state solves; :func:`gauss_newton` and :class:`RestrictedArrows` — points of a
  holonomic constraint set (initial states, the Noether check of docs/conventions.md §22);
- :func:`constraint_program`, :func:`holonomic_program` — the constraint checks of initial
  states and boundary data (values and the size of their terms, :func:`magnitude`).
"""

from ._checks import constraint_program, holonomic_program, magnitude
from ._initial import (
    MomentumProgram,
    holonomic_projection_program,
    momentum_program,
    second_order_momentum_program,
    source_projection_program,
)
from ._noether import noether_nodes
from ._projections import PROJECTED, RestrictedArrows, gauss_newton
from ._stages import ROUNDING_UPDATE, solve_stages
from ._state import StatePrograms, state_programs
from ._step import input_jacobian_program, step_program
from ._window import (
    WindowPrograms,
    action_program,
    cost_program,
    structure_program,
    window_programs,
)

__all__ = ["MomentumProgram", "StatePrograms", "WindowPrograms", "action_program",
           "constraint_program", "cost_program", "holonomic_program", "magnitude",
           "momentum_program", "noether_nodes", "second_order_momentum_program",
           "source_projection_program", "state_programs", "solve_stages", "input_jacobian_program",
           "PROJECTED", "ROUNDING_UPDATE", "RestrictedArrows", "gauss_newton",
           "holonomic_projection_program",
           "step_program", "structure_program", "window_programs"]
