"""The observed order of a variational integrator (docs/conventions.md §21).

:func:`convergence_order` discretises a :class:`~symgroupoid.ContinuousSystem` with one
scheme, runs it to a final time T with several step counts N (h = T/N) from the same initial
data (q₀, v₀) (:meth:`Simulator.from_velocity`), and fits the error of the configuration at T
against h on a log–log scale: e ≈ C·h^p.  The error is measured against a reference the
caller gives (e.g. an accurate ODE solution of the continuous equations), else against a run
of the same scheme with 8× the largest N (whose own error, (1/8)^p of the finest run's,
biases the finest error by at most 2 % for p ≥ 2).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ._arguments import integer_argument
from ._errors import InputTypeError, ShapeError

#: the reference run's step count, in multiples of the largest one measured
REFERENCE_FACTOR = 8


@dataclass(frozen=True)
class ConvergenceReport:
    """Step counts N, step sizes h = T/N, the final-time errors e(h), the orders between
    consecutive step sizes and their least-squares fit ``order``, the scheme's theoretical
    ``expected`` order (None when not known) and what the errors are measured against."""

    steps: tuple
    step_sizes: tuple
    errors: tuple
    orders: tuple
    order: float
    expected: int | None
    reference: str

    def __str__(self) -> str:
        lines = [f"observed order {self.order:.3f}"
                 + (f" (theoretical {self.expected})" if self.expected else "")
                 + f", errors against {self.reference}", "       N            h        error"
                 "    order"]
        for i, (n, h, e) in enumerate(zip(self.steps, self.step_sizes, self.errors)):
            order = f"{self.orders[i - 1]:9.3f}" if i else ""
            lines.append(f"{n:8d} {h:12.4e} {e:12.4e}{order}")
        return "\n".join(lines)


def _final_configuration(sim, initial, params: dict, steps: int) -> np.ndarray:
    """The configuration at step ``steps`` (time T) of the run from (q₀, v₀), flat."""
    configuration, velocity = initial
    state = sim.from_velocity(configuration, velocity, params)
    traj = sim.simulate(state, steps, params)
    found = traj.configurations()
    parts = found if isinstance(found, tuple) else (found,)
    return np.concatenate([np.ravel(np.asarray(part, float)[steps]) for part in parts])


def convergence_order(system, scheme, initial, params: Mapping, T: float,
                      steps: Sequence[int], *, step=None, reference=None,
                      backend: str = "c") -> ConvergenceReport:
    """The observed order of ``system.discretize(step, scheme)`` (see the module docstring).

    ``initial``: (configuration, velocity) as :meth:`Simulator.from_velocity` takes them;
    ``params``: the parameters other than the step; ``T``: the final time; ``steps``: at
    least two step counts; ``step``: the step parameter (default: the system's one
    parameter named ``h``); ``reference``: the configuration at T (flat: a Euclidean
    factor's coordinates, a group factor's matrix entries row by row, factor after factor),
    or None for the finer run of the same scheme.
    """
    from .equations import ContinuousSystem

    if not isinstance(system, ContinuousSystem):
        raise InputTypeError(f"convergence_order: system must be a ContinuousSystem, got "
                             f"{type(system).__name__}")
    counts = sorted({integer_argument(n, "steps", minimum=1, owner="convergence_order")
                     for n in steps})
    if len(counts) < 2:
        raise ShapeError("convergence_order: give at least two different step counts")
    T = float(T)
    if not np.isfinite(T) or T <= 0:
        raise ShapeError(f"convergence_order: T must be a positive time, got {T}")
    step = "h" if step is None else step
    discrete = system.discretize(step, scheme)
    sim = discrete.euler_lagrange().compile(backend=backend)
    name = str(discrete.time_step)

    def final(n: int) -> np.ndarray:
        return _final_configuration(sim, initial, {**params, name: T / n}, n)

    if reference is None:
        target, against = final(REFERENCE_FACTOR * counts[-1]), (
            f"the same scheme with N = {REFERENCE_FACTOR * counts[-1]}")
    else:
        target, against = np.asarray(reference, float).ravel(), "the reference given"
    errors = []
    for n in counts:
        value = final(n)
        if value.shape != target.shape:
            raise ShapeError(f"convergence_order: the reference has {target.size} entries, "
                             f"the configuration {value.size}")
        errors.append(float(np.linalg.norm(value - target)))
    h = np.array([T / n for n in counts])
    e = np.array(errors)
    logs = np.log(np.where(e > 0, e, np.finfo(float).tiny))
    orders = tuple(float(v) for v in np.diff(logs) / np.diff(np.log(h)))
    order = float(np.polyfit(np.log(h), logs, 1)[0])
    expected = getattr(scheme, "order", 2 if isinstance(scheme, str) else None)
    return ConvergenceReport(tuple(counts), tuple(h.tolist()), tuple(errors), orders, order,
                             expected, against)


__all__ = ["ConvergenceReport", "convergence_order"]
