"""Layer 3: step equations (residuals, unknowns, knowns, Jacobian, LaTeX) and systems."""

from ._abbreviations import LatexOptionError, UnusedAbbreviationWarning
from ._forcing import (
    body_torque,
    joint_torque,
    midpoint_forces,
    rayleigh_damping,
    trapezoid_forces,
)
from ._latex import GroupoidLatexPrinter, LatexVerificationError, equation_lines, latex
from ._momenta import LegendreTransforms, LiePoissonEquations, NoetherQuantity
from ._programs import (
    MomentumProgram,
    StatePrograms,
    WindowPrograms,
    action_program,
    constraint_program,
    cost_program,
    holonomic_program,
    magnitude,
    momentum_program,
    second_order_momentum_program,
    source_projection_program,
    state_programs,
    step_program,
    structure_program,
    window_programs,
)
from ._reduced import ReducedSystem, check_system_morphism
from ._step import StepEquations
from ._system import DiscreteSystem, NonholonomicSystem, SecondOrderSystem

__all__ = [
    "DiscreteSystem", "GroupoidLatexPrinter", "LegendreTransforms", "LiePoissonEquations",
    "MomentumProgram", "NoetherQuantity", "NonholonomicSystem", "ReducedSystem",
    "SecondOrderSystem", "StatePrograms", "StepEquations", "WindowPrograms", "action_program",
    "check_system_morphism", "constraint_program",
    "cost_program", "holonomic_program", "latex", "magnitude", "momentum_program",
    "second_order_momentum_program", "source_projection_program", "state_programs",
    "step_program", "structure_program", "window_programs",
    "LatexOptionError", "LatexVerificationError", "UnusedAbbreviationWarning",
    "equation_lines", "body_torque", "joint_torque", "midpoint_forces", "rayleigh_damping",
    "trapezoid_forces",
]
