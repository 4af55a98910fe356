"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._junction import junction_variation
from ._step import DerivedStep, junction_step, window

__all__ = ["DerivedStep", "junction_step", "junction_variation", "window"]
