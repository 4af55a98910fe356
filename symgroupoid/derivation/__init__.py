"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._assembly import (
    JunctionNodes,
    TermNodes,
    WindowAction,
    field_derivatives,
    slot_derivatives,
)
from ._callables import (
    as_scalar,
    as_scalar_list,
    call_user,
    check_parameters,
    check_symbols,
    check_values,
    checked_callable,
)
from ._energy_momentum import (
    NONHOLONOMIC_METHODS,
    ConservedQuantities,
    check_metric,
    conserved_quantities,
    energy_momentum_step,
)
from ._forces import (
    ForceFunctions,
    force_functions,
    impulse_form,
    impulse_section,
    input_arguments,
    input_symbols,
    pair_impulse_form,
)
from ._junction import junction_variation
from ._limit import (
    SCALES,
    declared_step_behaves,
    extrapolate,
    identified_time_steps,
    limit_points,
    may_be_step,
    parameter_value,
    scaled_norm,
    time_step_candidates,
)
from ._momenta import (
    LegendreForms,
    LiePoissonForms,
    NoetherForms,
    legendre_forms,
    lie_poisson_forms,
    momentum_symbols,
    noether_ends,
    noether_forms,
    second_order_legendre_forms,
    vanishes_on_restriction,
    vanishing_check,
)
from ._pieces import (
    Partial,
    PieceRule,
    WindowPieces,
    partial_residuals,
    piece_residuals,
    window_in_pieces,
)
from ._reduction import check_forces, reduce_functions
from ._step import (
    DerivedStep,
    SystemFunctions,
    chart_of,
    check_nonholonomic_dimensions,
    distribution_coefficients,
    evaluate_system,
    holonomic_functions,
    junction_step,
    matrix_form_residuals,
    matrix_form_values,
    named,
    next_arrow,
    nonholonomic_step,
    window,
)
from ._window import step_jacobian

__all__ = ["NONHOLONOMIC_METHODS", "SCALES", "ConservedQuantities", "DerivedStep", "check_metric",
           "ForceFunctions", "JunctionNodes", "LegendreForms", "LiePoissonForms", "NoetherForms",
           "Partial", "PieceRule", "SystemFunctions", "TermNodes", "WindowAction", "WindowPieces",
           "as_scalar", "as_scalar_list", "call_user", "check_parameters", "checked_callable",
           "chart_of",
           "holonomic_functions",
           "check_nonholonomic_dimensions", "check_symbols", "check_values",
           "conserved_quantities", "distribution_coefficients", "energy_momentum_step",
           "evaluate_system", "extrapolate",
           "declared_step_behaves", "field_derivatives", "force_functions",
           "identified_time_steps", "impulse_form",
           "impulse_section",
           "input_arguments", "input_symbols", "junction_step", "junction_variation",
           "legendre_forms", "lie_poisson_forms", "limit_points", "matrix_form_residuals",
           "matrix_form_values", "may_be_step", "momentum_symbols", "named", "next_arrow",
           "noether_ends", "noether_forms", "nonholonomic_step",
           "parameter_value",
           "pair_impulse_form", "partial_residuals",
           "piece_residuals", "check_forces", "reduce_functions", "scaled_norm",
           "second_order_legendre_forms",
           "slot_derivatives", "step_jacobian", "time_step_candidates", "vanishes_on_restriction",
           "vanishing_check", "window", "window_in_pieces"]
