"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._assembly import (
    JunctionNodes,
    TermNodes,
    WindowAction,
    field_derivatives,
    slot_derivatives,
)
from ._junction import junction_variation
from ._limit import identified_time_steps
from ._momenta import second_order_legendre_forms
from ._step import (
    DerivedStep,
    SystemFunctions,
    chart_of,
    junction_step,
    named,
    next_arrow,
    window,
)
from ._window import step_jacobian

__all__ = ["DerivedStep", "JunctionNodes", "SystemFunctions", "TermNodes", "WindowAction",
           "chart_of", "field_derivatives", "identified_time_steps", "junction_step",
           "junction_variation", "named", "next_arrow", "second_order_legendre_forms",
           "slot_derivatives", "step_jacobian", "window"]
