"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._assembly import (
    JunctionNodes,
    TermNodes,
    WindowAction,
    field_derivatives,
    slot_derivatives,
)
from ._callables import as_scalar, call_user
from ._junction import junction_variation
from ._limit import SCALES, extrapolate, identified_time_steps, limit_points, parameter_value
from ._momenta import momentum_symbols, second_order_legendre_forms
from ._pieces import (
    Partial,
    PieceRule,
    WindowPieces,
    partial_residuals,
    piece_residuals,
    window_in_pieces,
)
from ._step import (
    DerivedStep,
    SystemFunctions,
    chart_of,
    evaluate_system,
    junction_step,
    matrix_form_values,
    named,
    next_arrow,
    window,
)
from ._window import step_jacobian

__all__ = ["SCALES", "DerivedStep", "JunctionNodes", "Partial", "PieceRule", "SystemFunctions",
           "TermNodes", "WindowAction", "WindowPieces", "as_scalar", "call_user", "chart_of",
           "evaluate_system", "extrapolate", "field_derivatives", "identified_time_steps",
           "junction_step", "junction_variation", "limit_points", "matrix_form_values",
           "momentum_symbols", "named", "next_arrow", "parameter_value", "partial_residuals",
           "piece_residuals", "second_order_legendre_forms", "slot_derivatives",
           "step_jacobian", "window", "window_in_pieces"]
