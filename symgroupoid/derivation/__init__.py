"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._first_order import DerivedStep, first_order_step
from ._junction import junction_variation

__all__ = ["DerivedStep", "first_order_step", "junction_variation"]
