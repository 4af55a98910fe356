"""Layer 3: step equations (residuals, unknowns, knowns, Jacobian, LaTeX) and systems."""

from ._latex import GroupoidLatexPrinter, latex
from ._step import StepEquations
from ._system import DiscreteSystem

__all__ = ["DiscreteSystem", "GroupoidLatexPrinter", "StepEquations", "latex"]
