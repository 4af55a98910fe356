"""Layer 3: step equations (residuals, unknowns, knowns, Jacobian, LaTeX) and systems."""

from ._latex import GroupoidLatexPrinter, latex
from ._momenta import LegendreTransforms, LiePoissonEquations, NoetherQuantity
from ._programs import (
    StatePrograms,
    WindowPrograms,
    action_program,
    cost_program,
    state_programs,
    step_program,
    structure_program,
    window_programs,
)
from ._step import StepEquations
from ._system import DiscreteSystem, NonholonomicSystem, SecondOrderSystem

__all__ = [
    "DiscreteSystem", "GroupoidLatexPrinter", "LegendreTransforms", "LiePoissonEquations",
    "NoetherQuantity", "NonholonomicSystem", "SecondOrderSystem", "StatePrograms",
    "StepEquations", "WindowPrograms", "action_program", "cost_program", "latex",
    "state_programs", "step_program", "structure_program", "window_programs",
]
