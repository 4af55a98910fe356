"""The time layout of a step kernel on a time groupoid (see :mod:`symgroupoid.stepper._time`)."""

from __future__ import annotations

from ..stepper import NO_TIME, TimeLayout
from ._checks import step_argument


def time_layout(step) -> TimeLayout:
    """The :class:`TimeLayout` of ``step`` (a :class:`~symgroupoid.StepEquations`), or
    :data:`NO_TIME` when its groupoid is not a time groupoid.

    The unknown arrow g_{k+1} = (t_k, t_{k+1}, …) is the newest of ``step.arrows``, the
    last known one (t_{k−1}, t_k, …) the one before it.  The rows are the junction variation
    along the basis sections, the time section ∂/∂t first (``TimeGroupoid.section_curves``),
    for the steps of a :class:`~symgroupoid.DiscreteSystem` (and second-order ones); the
    fixed-step phase is for those without constraints (the energy-preserving step of seed
    000 Example 6.1): a constraint φ = t₁ − t₀ − h(g) fixes the step itself, and holding
    t_{k+1} would make φ solve for g instead; nor those with internal stages, whose stage
    rows follow the junction's (``row`` −1: the time step check only)."""
    from ..equations import DiscreteSystem

    step_argument(step, "time_layout")
    if not getattr(step.groupoid, "timed", False):
        return NO_TIME
    arrows = step.arrows
    newest = max(arrows)
    if newest - 1 not in arrows:
        return NO_TIME
    t_before, t_now = arrows[newest - 1][0], arrows[newest - 1][1]
    t_next = arrows[newest][1]
    unknowns, knowns = list(step.unknowns), list(step.knowns)
    if t_next not in unknowns or t_now not in knowns or t_before not in knowns:
        return NO_TIME
    system = getattr(step, "system", None)
    free = (isinstance(system, DiscreteSystem) and not step.n_constraints
            and not getattr(system, "stages", 0))
    row = 0 if free else -1
    return TimeLayout(row, unknowns.index(t_next), knowns.index(t_now),
                      knowns.index(t_before))


__all__ = ["time_layout"]
