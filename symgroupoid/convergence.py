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

from ._arguments import integer_argument, real_argument, real_array, sequence_argument
from ._errors import (
    DomainError,
    InputTypeError,
    ParameterError,
    ShapeError,
    UnsupportedFeatureError,
)
from ._parameters import parameter_vector

#: the reference run's step count, in multiples of the largest one measured
REFERENCE_FACTOR = 8
#: the most steps of one measured run (the reference run has up to 8× as many)
MAX_STEPS = 10**7
#: runs are simulated in chunks of this many steps (the memory of a run stays bounded)
CHUNK = 2**16

#: final-time errors below this × max(1, |q(T)|) are at the rounding floor and not fitted
ORDER_FLOOR = 1e-11


@dataclass(frozen=True)
class ConvergenceReport:
    """Step counts N, step sizes h = T/N, the final-time errors e(h), the orders between
    consecutive step sizes and their least-squares fit ``order``, the scheme's theoretical
    ``expected`` order (None when not known) and what the errors are measured against.

    The fit leaves out errors at the rounding floor (below :data:`ORDER_FLOOR` ×
    max(1, |q(T)|)): there they are the rounding the runs accumulate, not the scheme's
    error, and an order fitted through them means nothing.  ``fitted`` holds the step
    counts the fit used; with fewer than two, ``order`` is None and ``note`` says why."""

    steps: tuple
    step_sizes: tuple
    errors: tuple
    orders: tuple
    order: float | None
    expected: int | None
    reference: str
    reference_norm: float = 1.0  # |q(T)| of the reference, for the size of the errors
    motion: float | None = None  # max_k |q_k − q₀| of the finest run: how far it moves
    fitted: tuple = ()  # the step counts whose errors the fit used
    note: str = ""  # why errors were left out of the fit, or why there is no order

    def __str__(self) -> str:
        measured = ("order not measured" if self.order is None
                    else f"observed order {self.order:.3f}")
        lines = [measured + (f" (theoretical {self.expected})" if self.expected else "")
                 + f", errors against {self.reference}"]
        if self.note:
            lines.append(self.note)
        lines.append("       N            h        error     order")
        for i, (n, h, e) in enumerate(zip(self.steps, self.step_sizes, self.errors)):
            order = f" {self.orders[i - 1]:9.3f}" if i and self.orders[i - 1] is not None \
                else ""
            left = "" if n in self.fitted else "  (not fitted)"
            lines.append(f"{n:8d} {h:12.4e} {e:12.4e}{order}{left}")
        return "\n".join(lines)


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    """|a − b|₂ computed in units of the larger entry, so that it does not overflow where
    the entries' squares would (final configurations of 10¹⁶⁰: the order is the same at
    any scale)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    scale = max(float(np.max(np.abs(a), initial=0.0)), float(np.max(np.abs(b), initial=0.0)))
    if scale == 0.0:
        return 0.0
    return scale * float(np.linalg.norm(a / scale - b / scale))


def _configurations(traj, n: int) -> np.ndarray:
    """The configurations q_0 … q_n of the run ``traj`` of n steps, flat: one row each."""
    found = traj.configurations()
    parts = found if isinstance(found, tuple) else (found,)
    return np.concatenate([np.asarray(part, float)[:n + 1].reshape(n + 1, -1)
                           for part in parts], axis=1)


def _farthest(rows: np.ndarray, start: np.ndarray) -> float:
    """max_i |rows_i − start|₂, in units of the largest entry (as :func:`_distance`)."""
    scale = max(float(np.max(np.abs(rows), initial=0.0)),
                float(np.max(np.abs(start), initial=0.0)))
    if scale == 0.0:
        return 0.0
    return scale * float(np.max(np.linalg.norm(rows / scale - start / scale, axis=1)))


def _run(sim, initial, params: dict, steps: int, inputs=None) -> tuple:
    """The configuration q_N (time T) of the run of ``steps`` steps from (q₀, v₀), flat,
    and how far the run goes: max_k |q_k − q₀|.  The run is simulated in chunks of
    :data:`CHUNK` steps, each from the last state of the previous one.  ``inputs``: a
    forced system's inputs, held for every arrow (the first one's included), or None."""
    configuration, velocity = initial
    state = sim.from_velocity(configuration, velocity, params, inputs=inputs)
    left, start, motion = steps, None, 0.0
    while True:
        n = min(CHUNK, left)
        traj = sim.simulate(state, n, params, inputs=inputs)
        rows = _configurations(traj, n)
        start = rows[0] if start is None else start
        motion = max(motion, _farthest(rows, start))
        left -= n
        if not left:
            break
        state = traj.states[-1]
    return rows[-1], motion


def _held_inputs(sim, inputs) -> np.ndarray | None:
    """A system's inputs as the m values held over every arrow; None without inputs."""
    m = sim.layout.n_inputs
    if inputs is None and not m:
        return None
    if inputs is None:
        raise ShapeError(f"convergence_order: {sim.name} has inputs "
                         f"({', '.join(sim.layout.input_names)}): pass inputs= with "
                         f"{m} value{'s' if m > 1 else ''}, held over every arrow of every "
                         f"run")
    if not m:
        raise ShapeError(f"convergence_order: {sim.name} has no inputs; leave inputs= out")
    held = real_array(inputs, "inputs", owner="convergence_order")
    if held.shape != (m,) and not (m == 1 and held.ndim == 0):
        raise ShapeError(f"convergence_order: inputs= holds {m} value{'s' if m > 1 else ''}"
                         f" ({', '.join(sim.layout.input_names)}), held over every arrow (a "
                         f"sequence per step would differ at every N); got shape "
                         f"{held.shape}")
    if not np.all(np.isfinite(held)):
        raise DomainError("convergence_order: the inputs must be finite")
    return held.reshape(m)


def configuration_size(system) -> int:
    """The entries of a configuration of a ContinuousSystem as the reference gives it: a
    Euclidean factor's coordinates, a group factor's matrix entries."""
    return sum(f.space.n ** 2 if f.is_group else f.dim for f in system.factors)


def _counts_and_time(steps: Sequence[int], T: float) -> tuple[list[int], float]:
    """The step counts, sorted and distinct (at least two, each at most
    :data:`MAX_STEPS`), and the final time T > 0."""
    owner = "convergence_order"
    counts = sorted({integer_argument(n, "steps", minimum=1, maximum=MAX_STEPS, owner=owner)
                     for n in sequence_argument(steps, "steps", owner=owner)})
    if len(counts) < 2:
        raise ShapeError(f"convergence_order: steps must hold at least two different step "
                         f"counts, got {counts}")
    T = real_argument(T, "T", owner=owner)
    if T <= 0:
        raise ShapeError(f"convergence_order: T must be a positive time, got {T}")
    return counts, T


def _common_arguments(initial, params) -> tuple[tuple, dict]:
    """``initial`` as (configuration, velocity) and ``params`` as a dict."""
    if isinstance(initial, (str, bytes, Mapping)) or not isinstance(initial, Sequence) \
            or len(initial) != 2:
        raise InputTypeError(f"convergence_order: initial must be a pair (configuration, "
                             f"velocity), got {type(initial).__name__} {initial!r:.80}")
    if not isinstance(params, Mapping):
        raise InputTypeError(f"convergence_order: params must be a mapping of parameter "
                             f"values by name, got {type(params).__name__}")
    return tuple(initial), dict(params)


def _no_step(params: dict, name: str, T: float, counts: list) -> None:
    """A :class:`ParameterError` when ``params`` gives the step ``name``, which each run
    sets to T/N (it was silently replaced)."""
    if name in params:
        raise ParameterError(f"convergence_order: params gives the step {name} = "
                             f"{params[name]!r}, which each run sets to T/N ({name} = "
                             f"{T / counts[0]:g} … {T / counts[-1]:g} here): leave it out of "
                             f"params")


def _reference(reference, size: int | None) -> np.ndarray:
    """The reference configuration at T, flat and finite, with ``size`` entries (when
    known)."""
    target = real_array(reference, "reference", owner="convergence_order").ravel()
    if not np.all(np.isfinite(target)):
        raise ShapeError("convergence_order: the reference configuration must be finite")
    if size is not None and target.size != size:
        raise ShapeError(f"convergence_order: the reference has {target.size} entries, "
                         f"the configuration {size}")
    return target


def convergence_order(system, scheme, initial, params: Mapping, T: float,
                      steps: Sequence[int], *, step=None, reference=None, inputs=None,
                      backend: str = "c") -> ConvergenceReport:
    """The observed order of ``system.discretize(step, scheme)`` (see the module docstring).

    ``initial``: (configuration, velocity) as :meth:`Simulator.from_velocity` takes them;
    ``params``: the parameters other than the step (each run sets the step to T/N: giving
    it is a :class:`ParameterError`); ``T``: the final time; ``steps``: at
    least two step counts; ``step``: the step parameter (default: the system's one
    parameter named ``h``); ``reference``: the configuration at T (flat: a Euclidean
    factor's coordinates, a group factor's matrix entries row by row, factor after factor),
    or None for the finer run of the same scheme; ``inputs``: a system with inputs runs
    with these m values held over every arrow (a sequence would be sampled differently at
    every N: its own discretisation error would be measured with the scheme's).
    """
    from .equations import ContinuousSystem

    if not isinstance(system, ContinuousSystem):
        raise InputTypeError(f"convergence_order: system must be a ContinuousSystem, got "
                             f"{type(system).__name__}")
    counts, T = _counts_and_time(steps, T)
    initial, params = _common_arguments(initial, params)
    if reference is not None:
        reference = _reference(reference, configuration_size(system))
    step = "h" if step is None else step
    _no_step(params, str(step), T, counts)
    discrete = system.discretize(step, scheme)
    # the parameters named before anything is compiled (a missing one was reported after)
    parameter_vector([p for p in discrete.parameters if str(p) != str(step)], params,
                     owner="convergence_order")
    sim = discrete.euler_lagrange().compile(backend=backend)
    expected = getattr(scheme, "order", 2 if isinstance(scheme, str) else None)
    return measure_order(sim, initial, params, T, counts, reference=reference,
                         expected=expected, inputs=inputs)


def measure_order(sim, initial, params: Mapping, T: float, steps: Sequence[int], *,
                  reference=None, expected: int | None = None, inputs=None
                  ) -> ConvergenceReport:
    """The observed order of the compiled simulator ``sim`` of a discretised system (as
    :func:`convergence_order`, which derives and compiles it): runs of ``steps`` (at least
    two different counts) to T with the step parameter ``sim``'s time step set to T/N,
    the other parameters from ``params``, a system's ``inputs`` held over every arrow."""
    counts, T = _counts_and_time(steps, T)
    initial, params = _common_arguments(initial, params)
    inputs = _held_inputs(sim, inputs)
    origin = getattr(getattr(sim.equations, "system", None), "continuous", None)
    if origin is None:
        raise UnsupportedFeatureError(f"{sim.name}: the observed order is measured for a "
                                      f"system discretised from a ContinuousSystem "
                                      f"(system.discretize(h, scheme))")
    name = str(origin.step)
    _no_step(params, name, T, counts)
    if reference is not None:
        reference = _reference(reference, configuration_size(origin.system))

    def run(n: int) -> tuple:
        return _run(sim, initial, {**params, name: T / n}, n, inputs)

    finest = REFERENCE_FACTOR * counts[-1]
    runs = [run(n) for n in counts]
    if reference is None:
        target, motion = run(finest)
        against = f"the same scheme with N = {finest}"
    else:
        (_, motion), target, against = runs[-1], reference, "the reference given"
    errors = [_distance(final, target) for final, _ in runs]
    h = np.array([T / n for n in counts])
    norm = _distance(target, np.zeros_like(target))
    floor = ORDER_FLOOR * max(1.0, norm)
    above = [i for i, e in enumerate(errors) if e > floor]
    orders = tuple(None if errors[i] <= floor or errors[i + 1] <= floor else
                   float(np.log(errors[i + 1] / errors[i]) / np.log(h[i + 1] / h[i]))
                   for i in range(len(counts) - 1))
    order, note = None, ""
    if len(above) >= 2:
        order = float(np.polyfit(np.log(h[above]), np.log([errors[i] for i in above]), 1)[0])
    if len(above) < len(counts):
        note = (f"errors at or below the rounding floor ({floor:.0e}) are not fitted: there "
                f"they are the rounding the runs accumulate, not the scheme's error")
        if order is None and motion <= floor:
            note += (f"; no configuration of the runs is farther than {motion:.1e} from the "
                     f"first, the rounding: nothing moves at these steps, so there is no "
                     f"order")
        elif order is None:
            note += "; fewer than two remain, so there is no order: take fewer steps or a " \
                    "longer T"
    return ConvergenceReport(tuple(counts), tuple(h.tolist()), tuple(errors), orders, order,
                             expected, against, norm, motion, tuple(counts[i] for i in above),
                             note)


__all__ = ["ORDER_FLOOR", "ConvergenceReport", "convergence_order", "measure_order"]
