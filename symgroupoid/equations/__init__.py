"""Layer 3: step equations (residuals, unknowns, knowns, Jacobian, LaTeX) and systems."""

from ._latex import GroupoidLatexPrinter, latex
from ._momenta import LegendreTransforms, LiePoissonEquations, NoetherQuantity
from ._step import StepEquations
from ._system import DiscreteSystem, NonholonomicSystem, SecondOrderSystem

__all__ = [
    "DiscreteSystem", "GroupoidLatexPrinter", "LegendreTransforms", "LiePoissonEquations",
    "NoetherQuantity", "NonholonomicSystem", "SecondOrderSystem", "StepEquations", "latex",
]
