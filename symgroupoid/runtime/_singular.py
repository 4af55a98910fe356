"""Why a step can be non-finite before Newton's method starts, said in the user's terms.

A step whose prediction or residual is non-finite fails with the kernel's status
``NON_FINITE``.  Two causes are common and have a remedy the user can apply:

- an increment of the known arrow is a half-turn (:meth:`Groupoid.increments`): the cut
  locus of the Cayley map, cay⁻¹(R) = 2(R − I)(R + I)⁻¹, and of the logarithm, where the
  retraction coordinates of the step's unknowns and its prediction are not defined
  (det(I + R)/2ⁿ = Π cos²(θ_i/2) vanishes there) — the rotation per step is too large;
- a parameter the Lagrangian or the constraints divide by is zero (a time step h = 0 that
  was not declared positive, so its value was not refused when given).

:func:`non_finite_cause` finds them for :meth:`Simulator._failure`;
:func:`zero_divisors` lets :meth:`Simulator.parameters` refuse such a zero up front.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

from .._errors import (
    CutLocusStepError,
    LagrangianDomainError,
    NewtonDivergenceError,
    ParameterError,
)
from ..stepper import Status

#: an increment counts as a half-turn when det(I + R)/2ⁿ is at most this (SO(3): the angle
#: within 2·10⁻⁴ of π); only asked after the step gave non-finite values
HALF_TURN = 1e-8


def half_turns(groupoid, arrow: np.ndarray) -> list[tuple[str, object, float]]:
    """(part name, group, det(I + R)/2ⁿ) of each increment of ``arrow`` that is a
    half-turn (R its rotation block)."""
    out = []
    try:
        increments = groupoid.increments(tuple(float(v) for v in arrow))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):  # a singular matrix
        return out
    for name, group, M in increments:
        n = group.n - 1 if group.affine else group.n
        R = np.asarray(M, float)[:n, :n]
        closeness = abs(float(np.linalg.det(np.eye(n) + R))) / 2.0 ** n
        if closeness <= HALF_TURN:
            out.append((name, group, closeness))
    return out


@functools.lru_cache(maxsize=64)
def zero_divisors(step) -> dict[int, str]:
    """Parameter index → what divides by it (``"the Lagrangian"``, ``"constraint 2"``):
    the parameters at whose value 0 the system's Lagrangian or constraints are not finite.
    Empty for a step without its system (a restored simulator)."""
    fs = getattr(getattr(step, "system", None), "_fs", None)
    if fs is None:
        return {}
    functions = [("the Lagrangian", fs.lagrangian)] + [
        (f"constraint {i + 1}", c) for i, c in enumerate(fs.constraints)]
    out: dict[int, str] = {}
    for i, symbol in enumerate(step.parameters):
        if not isinstance(symbol, sp.Symbol) or symbol.is_zero is False:
            continue  # declared nonzero (positive, …): a zero is refused when given
        for what, f in functions:
            f = sp.sympify(f)
            if f.has(symbol) and f.subs(symbol, 0).has(sp.zoo, sp.nan, sp.oo, -sp.oo):
                out[i] = what
                break
    return out


def zero_parameter_text(step, index: int, what: str) -> str:
    """Why the parameter ``index`` may not be 0, and what to do."""
    symbol = step.parameters[index]
    return (f"the parameter {symbol} = 0 makes {what} non-finite (it divides by {symbol}); "
            f"give {symbol} a nonzero value, and declare it positive "
            f"(sp.Symbol({str(symbol)!r}, positive=True)) if it is, so that a zero is "
            f"refused when it is given")


def check_zero_divisors(step, p: np.ndarray, owner: str) -> None:
    """A :class:`ParameterError` when a parameter the equations divide by is 0."""
    for index, what in zero_divisors(step).items():
        if p[index] == 0:
            raise ParameterError(f"{owner}: {zero_parameter_text(step, index, what)}")


def non_finite_cause(sim, step_index: int, iterations: int, residual_norm: float,
                     iterate, known: np.ndarray, p: np.ndarray | None,
                     head: str) -> Exception | None:
    """The error of a step that failed with non-finite values at the known state
    ``known``, when a cause above explains it (else None): a :class:`CutLocusStepError`
    naming the half-turn and the remedy, or a :class:`NewtonDivergenceError` naming the
    zero parameter.  ``head``: the message's start ("name: step k failed")."""
    step = sim.equations
    layout = sim.layout
    for offset, index in layout.arrow_index.items():
        found = half_turns(step.groupoid, np.asarray(known, float)[index])
        if found:
            return CutLocusStepError(
                f"{head}: {_half_turn_text(found, offset, step_index == 0)}",
                step=int(step_index),
                residual_norm=float(residual_norm), iterate=np.array(iterate, dtype=float),
                parts=tuple(name for name, _, _ in found))
    if p is not None:
        for index, what in zero_divisors(step).items():
            if p[index] == 0:
                return NewtonDivergenceError(
                    f"{head}: {zero_parameter_text(step, index, what)}", step=int(step_index),
                    residual_norm=float(residual_norm),
                    iterate=np.array(iterate, dtype=float))
    return None


def outside_domain_error(sim, step_index: int, iterations: int, residual_norm: float,
                         iterate, known, p, head: str) -> LagrangianDomainError:
    """The error of a step whose solution Newton found where the discrete Lagrangian is not
    defined (status ``OUTSIDE_DOMAIN``, docs/conventions.md §11): the kernel's ``domain``
    values at the solution say which logarithm, square root, … left its domain, and on which
    term of the window (``step.domain_kinds``)."""
    x = np.asarray(iterate, dtype=float)
    values = np.zeros(0)
    if known is not None and p is not None and np.isfinite(x).all():
        with np.errstate(all="ignore"):
            values = sim.kernel.domain(x, known, p)
    bad = np.flatnonzero(~np.isfinite(values))
    described = list(getattr(sim.equations, "domain_kinds", ()))
    kinds = tuple(described[i] if i < len(described) else f"domain value {i}" for i in bad)
    shown = "; ".join(f"{kind} is {values[i]}" for kind, i in zip(kinds, bad[:3]))
    more = f" (and {len(bad) - 3} more)" if len(bad) > 3 else ""
    initial = step_index == 0 and any("known arrow" in k for k in kinds)
    err = LagrangianDomainError(
        f"{head}: {Status.OUTSIDE_DOMAIN.message}: {shown or 'a domain value is not finite'}"
        f"{more} (|F|_inf = {residual_norm:.3e} after {iterations} updates).  The step "
        f"equations hold only L's derivatives, which can have roots outside L's domain; the "
        f"run stops before such a step (docs/conventions.md §11)"
        + ("; here the initial state itself lies outside it" if initial else
           ": a smaller time step may keep the motion inside the domain, or the motion "
           "itself leaves it"), step=int(step_index), residual_norm=float(residual_norm),
        iterate=x.copy())
    err.kinds = kinds
    return err


def _half_turn_text(found: list, offset: int, first: bool) -> str:
    from .._symbols import step_label

    name, group, closeness = found[0]
    n = group.n - 1 if group.affine else group.n
    chart = "Cayley map" if group.retraction == "cayley" else "logarithm (exponential chart)"
    where = f"the known arrow g_{step_label(offset)}" + (" of the initial state" if first
                                                          else "")
    text = (f"the increment {name!r} ({group.name}) of {where} is a half-turn "
            f"(det(I + R)/2^{n} = {closeness:.1e}): it lies on the cut locus "
            f"of the {chart}, where the retraction coordinates of the step's unknowns, and "
            f"its prediction, are not defined.  The rotation per step must stay below a "
            f"half-turn: take a smaller time step, or start from a slower rotation")
    if group.retraction == "cayley":
        text += (f"; near (not at) a half-turn the exponential retraction "
                 f"({type(group).__name__}({group.symbol_name!r}, retraction=\"exp\")), whose "
                 f"coordinates stay bounded up to the half-turn, is better conditioned than "
                 f"the Cayley map, whose coordinates grow without bound there")
    return text
