"""Where a step on a time groupoid R × R × G keeps its times (seed 000 §6.3).

The stepper treats the time of such a step apart (docs/conventions.md §7): it solves the
guess onto the fixed-step equations before Newton (``<prefix>_hold_time``) and accepts a
solved step only when its time step h_{k+1} = t_{k+1} − t_k keeps the sign of the last step
h_k = t_k − t_{k−1} and changes by at most the factor :data:`STEP_RATIO`
(``<prefix>_time_step_kept``).  ``symgroupoid.codegen.time_layout`` finds the indices
the kernel needs.
"""

from __future__ import annotations

from dataclasses import dataclass

#: the most a time step may grow or shrink in one step (``SG_STEP_RATIO``): a solution with
#: h_{k+1}/h_k outside [1/STEP_RATIO, STEP_RATIO] is on another branch of the step equations
STEP_RATIO = 2.0

#: the updates of the fixed-step phase (``SG_HOLD_ITERATIONS``) and its relative tolerance
#: (``SG_HOLD_TOLERANCE``: Newton converges quadratically, so an update of 1e-8 leaves an
#: error at the rounding of the unknowns)
HOLD_ITERATIONS = 8
HOLD_TOLERANCE = 1e-8

#: the rounds of the last try of a step on a time groupoid (``SG_SETTLE_ITERATIONS``):
#: Newton on the time step along the fixed-step solutions (``<prefix>_settle_time``)
SETTLE_ITERATIONS = 12


@dataclass(frozen=True)
class TimeLayout:
    """The time of a step on a time groupoid: ``row``, the equation of the time section
    ∂/∂t, which the fixed-step phase replaces (−1: no phase — a step with constraints, or
    a nonholonomic one, whose rows combine the junction variation's), ``unknown`` the index
    of t_{k+1} among the unknowns, ``known`` and ``before`` those of t_k and t_{k−1} among
    the knowns."""

    row: int
    unknown: int
    known: int
    before: int

    def defines(self) -> dict[str, int]:
        """The kernel's macros (``<PREFIX>_TIME_ROW``, ...)."""
        return {"TIME_ROW": self.row, "TIME_UNKNOWN": self.unknown,
                "TIME_KNOWN": self.known, "TIME_BEFORE": self.before}


#: the macros of a step without time (every index −1: neither phase nor check)
NO_TIME = TimeLayout(-1, -1, -1, -1)


__all__ = ["HOLD_ITERATIONS", "HOLD_TOLERANCE", "NO_TIME", "SETTLE_ITERATIONS", "STEP_RATIO",
           "TimeLayout"]
