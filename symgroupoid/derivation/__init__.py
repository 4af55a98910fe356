"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._junction import junction_variation
from ._step import DerivedStep, SystemFunctions, junction_step, window

__all__ = ["DerivedStep", "SystemFunctions", "junction_step", "junction_variation", "window"]
