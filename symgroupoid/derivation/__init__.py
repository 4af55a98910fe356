"""Layer 2: derivation by varying a composable sequence at a junction."""

from ._assembly import (
    JunctionNodes,
    TermNodes,
    WindowAction,
    field_derivatives,
    slot_derivatives,
)
from ._callables import call_user, check_values
from ._energy_momentum import (
    NONHOLONOMIC_METHODS,
    conserved_quantities,
    energy_momentum_step,
)
from ._junction import junction_variation
from ._limit import identified_time_steps, may_be_step, time_step_candidates
from ._momenta import (
    LegendreForms,
    LiePoissonForms,
    NoetherForms,
    legendre_forms,
    lie_poisson_forms,
    noether_forms,
    second_order_legendre_forms,
    vanishes_on_restriction,
    vanishing_check,
)
from ._reduction import reduce_functions
from ._step import (
    DerivedStep,
    SystemFunctions,
    chart_of,
    check_nonholonomic_dimensions,
    evaluate_system,
    junction_step,
    matrix_form_residuals,
    named,
    next_arrow,
    nonholonomic_step,
    window,
)
from ._window import step_jacobian

__all__ = ["DerivedStep", "JunctionNodes", "LegendreForms", "LiePoissonForms",
           "NONHOLONOMIC_METHODS", "NoetherForms", "SystemFunctions", "TermNodes",
           "WindowAction", "call_user", "chart_of", "check_nonholonomic_dimensions",
           "check_values", "conserved_quantities", "energy_momentum_step", "evaluate_system",
           "field_derivatives", "identified_time_steps", "junction_step", "junction_variation",
           "legendre_forms", "lie_poisson_forms", "matrix_form_residuals", "may_be_step", "named",
           "next_arrow", "noether_forms", "nonholonomic_step", "reduce_functions",
           "second_order_legendre_forms", "slot_derivatives", "step_jacobian",
           "time_step_candidates", "vanishes_on_restriction", "vanishing_check", "window"]
