"""The discrete forces people write, from a continuous force (docs/conventions.md §20).

Each helper returns the callable ``f(g) -> (f_minus, f_plus)`` that
``DiscreteSystem(..., forces=f)`` takes.  On the pair groupoid of a Euclidean space, whose
arrows are consecutive configurations (q_k, q_{k+1}) a step h apart, the velocity of an
arrow is Δq/h and a continuous generalised force F(q, v) (which may use inputs) gives
(Marsden–West §3.2):

- :func:`midpoint_forces`: f⁻ = f⁺ = (h/2)·F(q̄, Δq/h), q̄ the midpoint — the forces of the
  midpoint rule L_d = h·L(q̄, Δq/h);
- :func:`trapezoid_forces`: f⁻ = (h/2)·F(q_k, Δq/h), f⁺ = (h/2)·F(q_{k+1}, Δq/h);
- :func:`rayleigh_damping`: F = −∂D/∂v for a dissipation function D(q, v) (Rayleigh), with
  either rule.

On a matrix Lie group, whose arrow is the increment W_k between consecutive attitudes,
:func:`body_torque` applies a body-frame torque τ (one component per basis section, i.e.
per direction of the Lie algebra's basis) held over the step: f⁻ = f⁺ = (h/2)·τ.
:func:`joint_torque` applies equal and opposite torques to two factors of a product (a
torque at the joint between two bodies), which are internal: they cancel along a symmetry
that moves both bodies alike.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import sympy as sp

from .._arguments import (
    MAX_DIMENSION,
    callable_argument,
    choice_argument,
    integer_argument,
    sequence_argument,
    shown_value,
)
from .._errors import CallableError, DomainError, InputTypeError, ShapeError
from ..derivation import as_scalar, as_scalar_list, check_values

_RULES = ("midpoint", "trapezoid")


def _points(g, what: str) -> tuple[list, list]:
    """(q_k, q_{k+1}) of an arrow of a pair groupoid of a Euclidean space."""
    try:
        q0, q1 = list(g.source), list(g.target)
    except (AttributeError, TypeError) as exc:
        raise InputTypeError(f"{what}: the arrow has no consecutive configurations "
                             f"(.source, .target as coordinate tuples): write the forces "
                             f"on a pair groupoid of a EuclideanSpace, or by hand") from exc
    if any(isinstance(q, sp.MatrixBase) for q in (*q0, *q1)):
        raise InputTypeError(f"{what}: the configurations are matrices; on a Lie group use "
                             f"body_torque, or write the forces by hand")
    return q0, q1


def _force(F: Callable, q: list, v: list, what: str) -> list:
    if not callable(F):
        raise CallableError(f"{what}: F must be a function F(q, v) -> [forces], got a "
                            f"{type(F).__name__}")
    value = as_scalar_list(what, "F(q, v)", F(q, v))
    if len(value) != len(q):
        raise ShapeError(f"{what}: F returned {len(value)} components for {len(q)} "
                         f"coordinates; one generalised force per coordinate")
    return value


def _step_argument(h, owner: str) -> sp.Expr:
    """The time step ``h`` of a force helper: a SymPy scalar (the system's time-step
    parameter, as a rule) or a real number; anything else is an
    :class:`~symgroupoid.InputTypeError` naming h."""
    try:
        value = sp.sympify(h, strict=True)
    except (sp.SympifyError, TypeError, ValueError, AttributeError):
        value = None
    if not isinstance(value, sp.Expr) or isinstance(value, sp.MatrixBase) \
            or value.is_real is False:
        raise InputTypeError(f"{owner}: h must be the time step (a SymPy symbol, as a rule), "
                             f"got {type(h).__name__} {shown_value(h)}")
    if value.is_number and not (value.is_finite and value.is_positive
                                and 0.0 < float(value) < math.inf):
        raise DomainError(f"{owner}: the time step h must be positive and finite (as a "
                          f"double), got {shown_value(h)}")
    if value.is_positive is False:
        sign = "zero" if value.is_zero else "negative"
        raise DomainError(f"{owner}: the time step h must be positive, got {value}, which "
                          f"its symbols' assumptions make {sign}")
    return value


def _with_step(forces: Callable, h: sp.Expr) -> Callable:
    """``forces`` marked with the time step h it was written for (``forces.time_step``),
    which a system with a declared time step compares with its own
    (:func:`check_force_step`)."""
    forces.time_step = h
    return forces


def check_force_step(name: str, forces, time_step: sp.Symbol | None) -> None:
    """A :class:`~symgroupoid.DomainError` when ``forces`` come from a helper written for
    another time step than the system's declared ``time_step``: with
    ``midpoint_forces(F, 0.01)`` in a system run at h = 0.05 every force was a fifth of
    what it should be, with no word."""
    step = getattr(forces, "time_step", None)
    if step is None or time_step is None or sp.sympify(step) == time_step:
        return
    shown = f"{float(step):g}" if sp.sympify(step).is_number else step
    raise DomainError(f"{name}: the forces were written for the time step {shown}, but the "
                      f"system's time step is {time_step}: the discrete forces (h/2)·F would "
                      f"be wrong at every other value; give the helper the time-step "
                      f"parameter itself (e.g. midpoint_forces(F, {time_step}))")


def midpoint_forces(F: Callable, h: sp.Symbol) -> Callable:
    """f⁻ = f⁺ = (h/2)·F(q̄, Δq/h): the discrete forces of the midpoint rule for the
    generalised force ``F(q, v)`` (lists of coordinates and velocities in, one force per
    coordinate out; it may use inputs and parameters)."""
    callable_argument(F, "F", owner="midpoint_forces")
    h = _step_argument(h, "midpoint_forces")

    def forces(g):
        q0, q1 = _points(g, "midpoint_forces")
        q = [(a + b) / 2 for a, b in zip(q0, q1)]
        v = [(b - a) / h for a, b in zip(q0, q1)]
        half = [h / 2 * f for f in _force(F, q, v, "midpoint_forces")]
        return half, list(half)

    return _with_step(forces, h)


def trapezoid_forces(F: Callable, h: sp.Symbol) -> Callable:
    """f⁻ = (h/2)·F(q_k, Δq/h), f⁺ = (h/2)·F(q_{k+1}, Δq/h): the discrete forces of the
    trapezoidal rule for the generalised force ``F(q, v)``."""
    callable_argument(F, "F", owner="trapezoid_forces")
    h = _step_argument(h, "trapezoid_forces")

    def forces(g):
        q0, q1 = _points(g, "trapezoid_forces")
        v = [(b - a) / h for a, b in zip(q0, q1)]
        return ([h / 2 * f for f in _force(F, q0, v, "trapezoid_forces")],
                [h / 2 * f for f in _force(F, q1, v, "trapezoid_forces")])

    return _with_step(forces, h)


def rayleigh_damping(D: Callable, h: sp.Symbol, rule: str = "midpoint") -> Callable:
    """The damping force F = −∂D/∂v of a dissipation function ``D(q, v)`` (Rayleigh; e.g.
    D = c·|v|²/2 gives F = −c·v), discretised by ``rule`` ("midpoint" or "trapezoid")."""
    callable_argument(D, "D", owner="rayleigh_damping")
    choice_argument(rule, _RULES, "rule", owner="rayleigh_damping")
    _step_argument(h, "rayleigh_damping")

    def F(q, v):
        dummies = [sp.Dummy(f"v{i}", real=True) for i in range(len(v))]
        value = as_scalar("rayleigh_damping", "dissipation function D(q, v)", D(q, dummies))
        check_values("rayleigh_damping", "dissipation function D(q, v)", value)
        return [-sp.diff(value, d).xreplace(dict(zip(dummies, v))) for d in dummies]

    return (midpoint_forces if rule == "midpoint" else trapezoid_forces)(F, h)


def body_torque(tau: Callable | Sequence, h: sp.Symbol) -> Callable:
    """f⁻ = f⁺ = (h/2)·τ on a matrix Lie group: the body-frame torque ``tau`` (a list of
    one component per basis section, or a function of the arrow returning one) held over
    the step, split equally between its ends."""
    if not callable(tau):
        tau = sequence_argument(tau, "tau", owner="body_torque")
    h = _step_argument(h, "body_torque")

    def forces(g):
        value = as_scalar_list("body_torque", "torque", tau(g) if callable(tau) else tau)
        half = [h / 2 * t for t in value]
        return half, list(half)

    return _with_step(forces, h)


def joint_torque(rank: int, first: Sequence[int], second: Sequence[int],
                 tau: Callable | Sequence, h: sp.Symbol) -> Callable:
    """Equal and opposite body torques at a joint: +τ on the sections ``first`` and −τ on
    the sections ``second`` (the indices, in the product's basis of ``rank`` sections, of
    the two bodies' directions the joint acts along), held over the step as
    :func:`body_torque`.  Such forces are internal: they cancel along a symmetry that moves
    both bodies alike, whose Noether quantity they leave conserved."""
    rank = integer_argument(rank, "rank", minimum=1, maximum=MAX_DIMENSION,
                            owner="joint_torque")
    first = [integer_argument(i, "first", owner="joint_torque")
             for i in sequence_argument(first, "first", owner="joint_torque")]
    second = [integer_argument(i, "second", owner="joint_torque")
              for i in sequence_argument(second, "second", owner="joint_torque")]
    if not callable(tau):
        tau = sequence_argument(tau, "tau", owner="joint_torque")
    h = _step_argument(h, "joint_torque")
    if len(first) != len(second):
        raise ShapeError(f"joint_torque: {len(first)} directions on the first body but "
                         f"{len(second)} on the second")
    if any(not 0 <= i < rank for i in (*first, *second)):
        raise ShapeError(f"joint_torque: section indices must lie in 0 … {rank - 1}")
    both = sorted(set(first) & set(second))
    if both:
        raise ShapeError(f"joint_torque: section(s) {both} are on both bodies: +τ and −τ on "
                         f"one section cancel, a force that is identically zero; give each "
                         f"body its own sections")

    def forces(g):
        value = as_scalar_list("joint_torque", "torque", tau(g) if callable(tau) else tau)
        if len(value) != len(first):
            raise ShapeError(f"joint_torque: {len(value)} torque components for "
                             f"{len(first)} directions")
        half = [sp.S.Zero] * rank
        for i, j, t in zip(first, second, value):
            half[i] += h / 2 * t
            half[j] -= h / 2 * t
        return half, list(half)

    return _with_step(forces, h)


__all__ = ["body_torque", "joint_torque", "midpoint_forces", "rayleigh_damping",
           "trapezoid_forces"]
