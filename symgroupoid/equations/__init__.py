"""Layer 3: step equations (residuals, unknowns, knowns, Jacobian, LaTeX) and systems."""

from ._abbreviations import LatexOptionError, UnusedAbbreviationWarning
from ._continuous import ContinuousSystem, GaussLegendre, LobattoIIIAB
from ._findings import (
    DEPENDENT_CONSTRAINTS,
    IDENTICALLY_ZERO,
    NO_UNKNOWN,
    NOT_REGULAR,
    UNDETERMINED_MULTIPLIER,
    UNUSED_UNKNOWN,
)
from ._forcing import (
    body_torque,
    joint_torque,
    midpoint_forces,
    rayleigh_damping,
    trapezoid_forces,
)
from ._galerkin import MAX_NODES, GalerkinTableau, gauss_legendre_tableau, lobatto_tableau
from ._kinetic import DEGENERATE_KINETIC
from ._latex import (
    EXPANSION_LIMIT,
    PRINT_LIMIT,
    GroupoidLatexPrinter,
    LatexVerificationError,
    equation_lines,
    latex,
)
from ._layout import PAGE_WIDTH, WideLinesWarning
from ._momenta import LegendreTransforms, LiePoissonEquations, NoetherQuantity
from ._programs import (
    PROJECTED,
    ROUNDING_UPDATE,
    MomentumProgram,
    RestrictedArrows,
    StatePrograms,
    WindowPrograms,
    action_program,
    constraint_program,
    cost_program,
    gauss_newton,
    holonomic_program,
    holonomic_projection_program,
    input_jacobian_program,
    magnitude,
    momentum_program,
    second_order_momentum_program,
    solve_stages,
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
    "cost_program", "holonomic_program", "input_jacobian_program", "latex", "magnitude",
    "momentum_program",
    "second_order_momentum_program", "source_projection_program", "state_programs",
    "solve_stages",
    "step_program", "structure_program", "window_programs", "PROJECTED", "ROUNDING_UPDATE",
    "RestrictedArrows", "gauss_newton", "holonomic_projection_program",
    "LatexOptionError", "LatexVerificationError", "UnusedAbbreviationWarning",
    "WideLinesWarning",
    "equation_lines", "body_torque", "joint_torque", "midpoint_forces", "rayleigh_damping",
    "trapezoid_forces", "ContinuousSystem", "GaussLegendre", "LobattoIIIAB",
    "GalerkinTableau", "MAX_NODES", "gauss_legendre_tableau", "lobatto_tableau",
    # pt: the text width of a LaTeX document, and the default width of the printed lines
    "PAGE_WIDTH",
    # operations of the written-out residuals above which a step is not printed
    "EXPANSION_LIMIT",
    "PRINT_LIMIT",
    # the causes a DegenerateSystemError names (its ``causes``, each finding's ``cause``)
    "DEGENERATE_KINETIC", "DEPENDENT_CONSTRAINTS", "IDENTICALLY_ZERO", "NOT_REGULAR",
    "NO_UNKNOWN", "UNDETERMINED_MULTIPLIER", "UNUSED_UNKNOWN",
]
