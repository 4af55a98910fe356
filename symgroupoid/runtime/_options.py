"""Newton options of a step: the C library's ``<prefix>_options``, checked once."""

from __future__ import annotations

import os
from dataclasses import dataclass

from .._arguments import (
    checked_keywords,
    choice_argument,
    flag_argument,
    instance_argument,
    integer_argument,
    real_argument,
)
from ..stepper import C_INT_MAX, DEFAULT_OPTIONS


@checked_keywords
@dataclass(frozen=True)
class NewtonOptions:
    """Newton options of a step (the kernels' ``<prefix>_newton``).

    Each step factors the Jacobian at the guess (so a singular step is always reported), then
    updates; an update reuses the last factorisation (a chord step) while the previous one
    reduced |F|_∞ at least tenfold, and refactors otherwise.  Converged:

    - after an update d_k (k ≥ 1) whose estimated remaining error ρ/(1 − ρ)·|d_k| is at most
      ``tol_step`` — ρ = |d_k|/|d_{k−1}| the observed contraction, |d| = max_j |d_j|/(1 + |u_j|)
      — or an update of at most 4ε (rounding noise of u); the update is applied and the
      residual evaluated there (reported), and the iterate is accepted only when that
      residual is at the rounding floor: every |F_i| ≤ ``floor_factor``·ε·Σ_j |J_ij|·
      min(|u_j|, |u_J,j|), or failing that the floor test below; otherwise Newton goes on (a
      small relative update at a runaway iterate, |u| ~ 10⁹⁰, is not convergence).  After a
      stop on the estimate whose error is above the rounding of u (ρ/(1 − ρ)·|d_j| > ε·|u_j|
      for some j), or made after the first two updates (ρ then a single ratio, which
      overstates the contraction when the first update also fixed the unknowns that enter
      linearly, such as multipliers), the accepted iterate takes one more chord update from that
      residual (no evaluation; counted as an update) when it is smaller than the last one
      and ``max_iterations`` allows one more:
      the remaining error, though within ``tol_step``, is systematic and above the rounding
      of u, and a conserved quantity would drift by it at every step;
    - when an update reduced |F|_∞ less than tenfold (Newton no longer converging fast)
      and was a Newton update (its Jacobian factored at the iterate it started from) — a
      chord update may contract slowly without any stall — and every |F_i| is at most
      ``floor_factor``·(C_i + N_i), C_i = ε·Σ_j |J_ij||u_J,j| (J the
      last factored Jacobian, evaluated at u_J) and N_i its change under a move of every
      unknown by 4 ulps: stalled at the rounding floor of the unknowns and of F's own
      operations;
    - when such an update (a Newton update that reduced |F|_∞ less than tenfold) leaves
      every |F_i| ≤ ``floor_factor``·ε·S_i, S_i the size of the terms F_i
      is computed from (:func:`symgroupoid.ir.term_magnitude`, the program's
      ``F_scale``): the residual is
      within the rounding of its own evaluation — a residual written in increments of
      positions far from the origin, (x_{k+1} − x_k)/h at |x| ~ 10⁴, cannot go below
      ε·|x|/h whatever the (small) unknowns;
    - when |F|_∞ ≤ ``tol_residual`` (absolute; 0, i.e. off, by default).

    Every floor test above also asks that the update the last factorisation gives for the
    residual be at most 10⁻⁶ relative to the smaller of the iterate and the guess
    (|d_j|/(1 + min(|u_j|, |g_j|))), and none accepts an iterate whose |F|_∞ exceeds the
    guess's a thousandfold (docs/conventions.md §11).

    Not converged: after ``max_iterations`` updates (status ``NOT_CONVERGED``, the iteration
    cap) at an iterate that is not at the rounding floor (the test after a final update
    above: at the floor the iterate is accepted, as a linear step is after its one update
    with ``max_iterations=1``, or a guess that already solves the step with 0), or when an
    update that did not reduce |F|_∞ tenfold was a Newton update of at most 64ε times the
    pivot ratio (the smaller of max/min |pivot| and the same with each pivot's column
    weighted by 1 + |u_J,j|: rounding noise of an update solved with that factorisation)
    while |F| is above every floor — Newton cannot improve the iterate (``STALLED``).

    ``trust_factor`` (10 by default; 0 turns the check off): a step solved from an
    extrapolated guess is accepted only within the guess's trust region,
    |u − guess| ≤ trust_factor·(m + 0.01), |·| relative to each unknown (max_j |d_j|/(1 +
    |u_j|) at the last solution) and m the larger motion of the last two steps (from a run's
    fourth step on); otherwise
    the step is retried from ``step.prediction`` and, if that solution lies outside too, the
    run stops with ``BRANCH_JUMP`` (:class:`~symgroupoid.BranchJumpError`): when the root
    near the last steps disappears (a fold of the step map, the step no longer resolving the
    motion), Newton can converge to a far root of another branch, and the run would go on
    there with converged residuals.  On a time groupoid a solved step must also keep the
    sign of its time step t_{k+1} − t_k and change it by at most a factor 2
    (``stepper.STEP_RATIO``), from the first step on (the time-reversed root g_k⁻¹ solves
    an adaptive step exactly; docs/conventions.md §7); ``trust_factor`` 0 turns this check
    off too.

    At most ``max_iterations`` updates (an integer in 0 … 2³¹ − 1, the range of a C ``int``;
    integral floats such as ``1e3`` are accepted).  With ``extrapolate`` the guess of step
    k ≥ 2 extrapolates the solutions of the steps before it (falling back to
    ``step.prediction`` if Newton fails from there): linearly, 2u_{k−1} − u_{k−2}, or, from
    step 4 on, quadratically, 3(u_{k−1} − u_{k−2}) + u_{k−3}, whichever would have guessed
    u_{k−1} more closely — O(h³) instead of O(h²) on smooth motion (the planar 16-link
    chain: 8.9 → 5.7 Newton updates per step), the linear guess on an oscillation of fewer
    than about six steps per period, where higher order extrapolates worse; otherwise every
    step starts from ``step.prediction``.
    """

    tol_residual: float = DEFAULT_OPTIONS["tol_residual"]
    tol_step: float = DEFAULT_OPTIONS["tol_step"]
    max_iterations: int = DEFAULT_OPTIONS["max_iterations"]
    extrapolate: bool = True
    floor_factor: float = DEFAULT_OPTIONS["floor_factor"]
    trust_factor: float = DEFAULT_OPTIONS["trust_factor"]

    def __post_init__(self):
        owner = "NewtonOptions"
        for name in ("tol_residual", "tol_step", "floor_factor", "trust_factor"):
            object.__setattr__(self, name, real_argument(getattr(self, name), name,
                                                         minimum=0.0, owner=owner))
        object.__setattr__(self, "max_iterations", integer_argument(
            self.max_iterations, "max_iterations", maximum=C_INT_MAX, owner=owner))
        object.__setattr__(self, "extrapolate", flag_argument(self.extrapolate,
                                                              "extrapolate", owner=owner))

    @classmethod
    def of(cls, options, default: NewtonOptions, *, owner: str = "") -> NewtonOptions:
        """``options`` as given to a solve: None (``default``) or a :class:`NewtonOptions`;
        anything else is an :class:`~symgroupoid.InputTypeError` naming ``options``."""
        if options is None:
            return default
        return instance_argument(options, cls, "options", "a NewtonOptions (or None)",
                                 owner=owner)


__all__ = ["NewtonOptions"]


#: the backends a kernel or program evaluator can be asked for
BACKENDS = ("auto", "c", "numpy")


def environment_backend(owner: str) -> str:
    """The backend ``SYMGROUPOID_BACKEND`` asks for: ``"auto"`` (unset or empty), ``"c"`` or
    ``"numpy"``; any other value is a :class:`~symgroupoid.DomainError` naming them.  The
    one reading of the variable: the step kernels, the boundary-value windows and the
    program evaluators all ask here."""
    return choice_argument(os.environ.get("SYMGROUPOID_BACKEND", "") or "auto", BACKENDS,
                           "SYMGROUPOID_BACKEND", owner=owner)
