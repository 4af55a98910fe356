"""Diagnostics along trajectories: is the structure preserved?

For a trajectory of a system's step (``traj = step.compile().simulate(...)``):

- :func:`energy` — the discrete energy E_d = −∂L_d/∂h for the time step h (declared with
  ``time_step=``, or the one parameter the continuous limit identifies as the step,
  docs/conventions.md §19; else a :class:`TimeStepError`), or on a
  :class:`~symgroupoid.TimeGroupoid` the energy conjugate to time −∂L/∂t₁ (seed 000 §6.3);
- :func:`momenta` — the discrete momenta F⁻L, F⁺L (seed 000 §3.3) at every state;
- :meth:`NoetherQuantity.along <symgroupoid.NoetherQuantity.along>` — a Noether quantity
  (seed 000 Thm 4.9) at every state;
- :func:`constraint_residuals` — φ at every state;
- :func:`conservation_summary` — the max drift of each conserved quantity against its
  rounding floor ε·(|Q|·√N + S), S the size of Q's terms (:func:`rounding_floor`), as a
  :class:`ConservationSummary` whose ``lines()`` are human-readable.

Each quantity is a small program over the expression graph, built from the system's own L
and φ and evaluated for all states at once; the same functions are methods of
:class:`~symgroupoid.Trajectory` (``traj.energy()``, ``traj.momenta()``, …).  Figures:
:mod:`symgroupoid.plotting`.
"""

from ._errors import DiagnosticsError, TimeStepError
from .runtime import (
    ConservationSummary,
    Drift,
    Momenta,
    conservation_summary,
    constraint_residuals,
    energy,
    energy_changes,
    energy_label,
    energy_magnitude,
    has_energy,
    momenta,
    rounding_floor,
)

__all__ = [
    "ConservationSummary", "DiagnosticsError", "Drift", "Momenta", "TimeStepError",
    "conservation_summary", "constraint_residuals", "energy", "energy_changes", "energy_label",
           "energy_magnitude",
    "has_energy", "momenta", "rounding_floor",
]
