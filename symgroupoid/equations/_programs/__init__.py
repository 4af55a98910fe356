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
  constraint residuals) and the projection of an initial state onto the constraints.
"""

from ._state import StatePrograms, state_programs
from ._step import step_program
from ._window import (
    WindowPrograms,
    action_program,
    cost_program,
    structure_program,
    window_programs,
)

__all__ = ["StatePrograms", "WindowPrograms", "action_program", "cost_program",
           "state_programs", "step_program", "structure_program", "window_programs"]
