"""The solve: inputs checked, the initial path, then the one loop over the phases.

:func:`solve_boundary_value` checks every input before anything is assembled, builds the
initial path and the solver state (:class:`~._state._SolverState`) and runs :func:`_solve`:
the fast path (:mod:`._fast`), then on its handover — or, for ``minimum``, at a stationary
point that is not a local minimum — the globalised path (:mod:`._globalised`), the
second-order condition deciding (:mod:`._inertia`).
"""

from __future__ import annotations

import time

import numpy as np

from ..._errors import (
    BranchJumpError,
    DiagnosticsError,
    LagrangianDomainError,
    NewtonDivergenceError,
    ShapeError,
    SingularJacobianError,
    TrajectoryTooLargeError,
    UnsupportedFeatureError,
)
from ..._progress import reported
from ...equations import solve_stages
from .._memory import available_memory
from .._validate import (
    MAX_COUNT,
    check_holonomic_nodes,
    integer_argument,
    parameter_vector,
    real_argument,
)
from ._fast import _fast_newton, _Handover, _restart_points
from ._globalised import _globalised_after
from ._guess import _boundary, _boundary_system, _check_cut_locus, _initial
from ._inertia import _describe, _is_minimum, _reduced_inertia
from ._inputs import input_table
from ._kernels import _functions, _maps
from ._solution import BoundaryValueSolution
from ._state import _Problem, _SolverState

#: the largest relative ``tol``: a residual of a percent of the terms is already no solution
#: of use; from about 1 the initial path itself is accepted
MAX_TOL = 1e-2


def boundary_steps(system, steps) -> int:
    """``steps`` as the number of arrows of a two-point problem of ``system``: an integer,
    at least 2·order (the junctions between fixed ends), or a :class:`ShapeError` that says
    so, for negative counts too."""
    a = len(_functions(system).slots)
    steps = integer_argument(steps, "steps", minimum=-MAX_COUNT, owner=system.name)
    if steps < 2 * a:
        raise ShapeError(f"{system.name}: a problem of order {a} needs at least {2 * a} "
                         f"steps, got {steps}")
    return steps


@reported(lambda step_equations, *args, **kwargs:
          f"{getattr(step_equations, 'name', 'system')}: boundary-value solve")
def solve_boundary_value(step_equations, start, end, steps: int, guess=None, params=None, *,
                         inputs=None, tol: float = 0.0, tol_step: float = 0.0,
                         max_iterations: int = 100,
                         minimum: bool = False) -> BoundaryValueSolution:
    """Solve a discrete two-point problem for the system behind ``step_equations``.

    First order: ``start`` and ``end`` are the end configurations (pair groupoid: points;
    Lie group: matrices; products: tuples).  Second order: ``start = (c₀, c₁)`` and
    ``end = (c_{N−1}, c_N)``, fixing the first and last arrows too.  ``guess``: N arrows
    (N, arrow_dim), optionally with multipliers as ``(arrows, multipliers)``, composable and
    joining ``start`` to ``end`` to rounding (the solution keeps the guess's ends: a
    ``NotComposableError`` otherwise); default: the geodesic interpolation of
    :func:`interpolate_arrows` (it avoids the Cayley chart's cut locus, so a half-turn
    between the ends is solved) and zero multipliers.

    Every input is checked before any solve, as :meth:`Simulator.simulate` checks its own
    (runtime/_validate.py): the counts, the parameters (by name, with their declared
    assumptions), the configurations (points: shape and finiteness; group parts: in the
    group, det +1), the guess, the inputs.

    Forced systems (docs/conventions.md §20).  The equations are the junction residuals of
    the discrete Lagrange–d'Alembert principle, X⃖_b[L](g_j) − X⃗_b[L](g_{j+1}) + f⁺_b(g_j)
    + f⁻_b(g_{j+1}) (first order), with the constraints.  ``inputs``: the inputs of every
    term of the action — (N, m) for first order, row k the input u_k of the arrow g_k,
    k = 0 … N − 1, as at run time; (N − 1, m) for second order, row t the input of the pair
    starting at g_t —, or (m,) for inputs held constant; none for a system without inputs
    (unforced, or forces without inputs such as damping).  A forced system's solutions are
    not critical points of the action, so there is no descent method on it: the solve is the
    fast path alone (its failure raises), ``minimum=True`` is refused, and the solution has
    no second-order condition.

    Internal stages (a discrete Lagrangian L(g, ζ), e.g. a Galerkin discretisation,
    docs/conventions.md §22).  The unknowns gain the stages ζ_k of every arrow (from 0, the
    chord) and the equations their stage rows ∂L/∂ζ(g_k, ζ_k) (+ f_ζ when forced); the
    junction residuals read the stages of both their terms.  The Jacobian stays banded.
    Newton's method alone, as for a forced system: ``minimum=True`` is refused, a fast path
    that gives up raises, and there is no second-order condition.  The solution's arrows
    are the trajectory; its ``stages`` (N, n_stages) are the stages of each arrow there.

    The iteration.  Structured Newton on the necessary conditions (junction residuals and
    constraints; block-banded Jacobian, solved in time linear in N), each update backtracked
    until |F|₂ decreases (:func:`_line_search`), is the fast path.  When it finds no decrease
    or takes MAX_DAMPED damped steps in a row, the solve restarts with the globalised
    iteration (:func:`_globalised`) from the fast path's iterate of least ℓ₁ merit when it
    is below the initial path's, from the initial path otherwise and when the first restart
    finds no decrease (:func:`_restart_points`, :func:`_globalised_after`): Newton steps
    on the same banded system regularised until the Hessian of the Lagrangian is positive
    definite on the tangent space of the constraints (its inertia from a banded LDLᵀ), with
    a line search on the ℓ₁ merit function Σ L + ν‖Φ‖₁ — a descent method for the action,
    as an interior-point NLP solver is.  ``max_iterations`` bounds the iterations of all
    phases together.
    ``minimum=True`` asks for a local minimum: a stationary point that is not one (see
    :attr:`BoundaryValueSolution.is_local_minimum`) sends the solve to the globalised
    iteration from the initial path, and if that finds none either the solve raises.

    Converged only when the residual criterion holds: every equation's |F_i| is at most
    ROUNDING_FACTOR·floor_i, floor_i its rounding floor (ε times the terms that cancel in it
    and its sensitivity to the rounding of the coordinates; it grows like N² for a residual
    scaled like 1/h², which a fixed tolerance would miss).  ``tol`` is a relative tolerance
    on the same scale: above ROUNDING_FACTOR·ε it accepts |F_i| ≤ (tol/ε)·floor_i, the
    residual that a relative change ``tol`` of the terms and coordinates would leave, when
    also the Newton update from the iterate is at most ``tol``·(1 + max(|coordinates|,
    |λ|)): the residual of a smooth path is O(h²) of that scale, so the residual alone
    accepted the straight initial path of a spring at h = 10⁻³ for tol = 1e-6, 43 % of the
    way from the solution.  It is invariant under a rescaling of the Lagrangian or of h; it
    is at most :data:`MAX_TOL` (0.01), beyond which the terms themselves would be accepted
    as their residual.  The iteration has
    stalled when an update changes no stored value, two steps in a row were taken at the
    floor without meeting the criterion, or (``tol_step`` > 0) an update falls below
    ``tol_step``·(1 + |λ|∞).
    Raises :class:`BoundaryValueDivergenceError` (a :class:`NewtonDivergenceError`, with the
    iterations and the residual history) when the iteration cap is reached, the iteration
    stalls or both phases' line searches find no decrease; :class:`SingularJacobianError`
    for a singular Jacobian; :class:`CutLocusError` when an arrow of the initial path is a
    half-turn; :class:`LagrangianDomainError` for a solution of the equations where the
    discrete Lagrangian is not defined (a term's L_d not finite: a logarithm, square root,
    acos … of it outside its domain, docs/conventions.md §11).

    ``progress`` (keyword): report a solve taking longer than 2 s, with |F|∞ per iteration
    (see :mod:`symgroupoid._progress`).
    """
    system = _boundary_system(step_equations)
    owner = system.name
    a = len(_functions(system).slots)
    steps = boundary_steps(system, steps)
    _check_memory(system, steps, owner)
    max_iterations = integer_argument(max_iterations, "max_iterations", owner=owner)
    tol = real_argument(tol, "tol", minimum=0.0, owner=owner)
    if tol > MAX_TOL:  # a relative change of the terms themselves accepts any path
        raise ShapeError(f"{owner}: tol is relative to the size of each equation's terms "
                         f"(tol = 1e-8 accepts a residual of 1e-8 of them); at most "
                         f"{MAX_TOL:g}, got {tol:g}, which would accept the initial path")
    tol_step = real_argument(tol_step, "tol_step", minimum=0.0, owner=owner)
    if not isinstance(minimum, (bool, np.bool_)):
        raise ShapeError(f"{owner}: minimum must be True or False, got {minimum!r}")
    p, named = parameter_vector(system.parameters, params, owner=owner)
    table = input_table(system, inputs, steps - a + 1, owner=owner)
    forced = _functions(system).forces is not None
    if forced and minimum:
        raise UnsupportedFeatureError(
            f"{owner}: minimum=True asks for a local minimum of the action, but a forced "
            f"system's solutions are critical points of the Lagrange–d'Alembert principle, "
            f"not of the action (docs/conventions.md §20); leave minimum out")
    n_stages = len(_functions(system).stages)
    if n_stages and minimum:
        raise UnsupportedFeatureError(_NO_DESCENT.format(owner=owner, what="minimum=True"))
    m = len(_functions(system).constraints)
    data = _boundary(system, a, start, end)
    check_holonomic_nodes(system, [data.total] if a == 1 else [data.first, data.last],
                          [("start", "end")] if a == 1 else
                          [("start[0]", "start[1]"), ("end[0]", "end[1]")], p, owner=owner)
    maps = _maps(system.groupoid, tuple(system.parameters), tuple(map(float, p)))
    arrows, lam = _initial(system, a, m, data, steps, guess, maps)
    _check_cut_locus(system, arrows, "the initial path has" if guess is None
                     else "the guess has")
    problem = _Problem.of(system, steps, p, tol, tol_step, max_iterations, table)
    # the stages ζ_t of every term follow its multipliers, from ζ = 0: the chord (§22)
    lam = np.hstack([lam, np.zeros((len(lam), n_stages))])
    t0 = time.perf_counter()
    state = _SolverState.at(problem, arrows, lam)
    if not state.assembled.finite():
        worst = state.assembled.worst
        culprits = ("Lagrangian, the constraints or the forces"
                    if _functions(system).forces is not None
                    else "Lagrangian or the constraints")
        raise NewtonDivergenceError(
            f"{owner}: non-finite residual or Jacobian at the initial "
            f"{'path' if guess is None else 'guess'}, at configuration {worst}: the "
            f"{culprits} are not defined there", step=worst,
            residual_norm=float(np.nanmax(np.abs(state.assembled.F), initial=0.0)),
            iterate=arrows)
    # every value the iteration uses is tested for finiteness (trials, merits, directions,
    # inertias) and ends in a named error; NumPy's warnings of intermediate overflow (at a
    # time step near the smallest doubles, a guess near the largest) would only repeat it
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        inertia = _solve(state, minimum)
    multipliers, stages = state.lam[:, :m], state.lam[:, m:]
    if n_stages:
        _check_stage_branch(state, stages, owner)
    _check_domain(problem, state, p, stages, owner)
    return BoundaryValueSolution(
        system, state.arrows, multipliers, data.configurations[0], named, state.iterations,
        state.history[-1], state.history, time.perf_counter() - t0,
        cost=problem.cost(state.arrows, p, stages), second_order=inertia,
        method=" → ".join(state.methods), inputs=table if table.shape[1] else None,
        forced=forced, stages=stages if n_stages else None)


def _check_domain(problem: _Problem, state: _SolverState, p: np.ndarray, stages: np.ndarray,
                  owner: str) -> None:
    """A :class:`LagrangianDomainError` when a term of the solution has a non-finite L_d:
    the equations hold L's derivatives only, which can have roots where L itself is not
    defined (L = v²/2 − log x on a path through x ≤ 0; docs/conventions.md §11)."""
    terms = problem.cost.terms(state.arrows, p, stages)
    bad = np.flatnonzero(~np.isfinite(terms))
    if not len(bad):
        return
    k = int(bad[0])
    more = f", as are {len(bad) - 1} more terms" if len(bad) > 1 else ""
    err = LagrangianDomainError(
        f"{owner}: the equations are solved, but the discrete Lagrangian is not defined at "
        f"the solution: its term {k} (from arrow {k}) is {terms[k]}{more} (a logarithm, "
        f"square root, acos … of L outside its domain; docs/conventions.md §11).  The "
        f"boundary-value equations hold only L's derivatives, which can have roots where L "
        f"is not defined; check that the ends lie inside L's domain, or give a guess inside "
        f"it", step=k, residual_norm=float(state.history[-1]), iterate=state.arrows.copy())
    err.kinds = (f"L_d not finite on term {k}",)
    raise err


def _check_memory(system, steps: int, owner: str) -> None:
    """Refuse up front a problem whose path and Jacobian alone cannot be allocated (the
    machine's memory, lowered by ``ulimit -v`` / ``-d``: ``available_memory``, as
    ``simulate`` checks it); a lower bound: per arrow its coordinates and a band of three
    blocks of its unknowns (variations, multipliers, stages) squared, 8 bytes each."""
    room = available_memory()
    fs = _functions(system)
    unknowns = system.groupoid.rank + len(fs.constraints) + len(fs.stages)
    needed = steps * 8 * (system.groupoid.arrow_dim + 3 * unknowns * unknowns)
    if room is not None and needed > room:
        raise TrajectoryTooLargeError(
            f"{owner}: a boundary-value problem of {steps} steps needs at least "
            f"{needed / 2**30:.1f} GiB (its path and the band of its Jacobian), more than "
            f"this process may allocate ({room / 2**30:.1f} GiB); take fewer steps")


#: how far (relative to 1 + |ζ|) the solution's stages may lie from those the chord's
#: Newton reaches: both are roots of the same rows to rounding when they are one root
STAGE_BRANCH_TOLERANCE = 1e-6


def _check_stage_branch(state: _SolverState, stages: np.ndarray, owner: str) -> None:
    """A :class:`BranchJumpError` unless the solution's stages are, at every arrow, the root
    of its stage rows that the discrete Lagrangian is defined by: the one Newton reaches
    from ζ = 0, the chord (docs/conventions.md §22; the initial-value step starts its
    stages there too).  The boundary-value iteration moves arrows and stages together, and a
    large motion can carry an arrow's stages to another root of its rows: a stationary path
    of Σ L(g_k, ζ_k) on another branch, not a solution of L_d.  The rows are the solve's
    own stage kernel (:meth:`WindowKernel.stage_values`), compiled once with it."""
    problem = state.problem
    kernel, arrows = problem.kernel, np.asarray(state.arrows, float)
    T, n = len(arrows), kernel.n_stages
    inputs = np.zeros((T, 0)) if problem.inputs is None else problem.inputs

    def rows(known, zeta, p):
        F, _, _, J, _ = kernel.split_stage(kernel.stage_values(arrows, zeta.T, inputs,
                                                               problem.p))
        return F.T, J.reshape(T, n * n).T

    try:
        near = solve_stages(rows, arrows.T, problem.p[:, None], n, owner).T
    except DiagnosticsError:
        near = np.full_like(stages, np.nan)
    far = ~(np.abs(near - stages) <= STAGE_BRANCH_TOLERANCE * (1.0 + np.abs(stages)))
    if far.any():
        k = int(np.flatnonzero(far.any(axis=1))[0])
        reached = (f"which Newton reaches from the chord ζ = 0 ({near[k].tolist()})"
                   if np.isfinite(near[k]).all() else
                   "and Newton reaches none from the chord ζ = 0")
        raise BranchJumpError(
            f"{owner}: the solution's internal stages at arrow {k} ({stages[k].tolist()}) "
            f"solve its stage rows at another root than the one the discrete Lagrangian is "
            f"defined by, {reached} (docs/conventions.md §22): a stationary path on another "
            f"branch, not a solution.  Take more steps (a smaller h) so that each arrow's "
            f"motion stays small, or give a guess", step=k, iterate=np.asarray(arrows))


#: why a problem with internal stages has no descent method on the action (§22)
_NO_DESCENT = (
    "{owner}: {what} needs a descent method on the action, and with internal stages the "
    "action Σ L(g_k, ζ_k) is not the discrete action Σ L_d(g_k) away from the stages' "
    "solutions: a descent over arrows and stages together is one for L_d only where every "
    "ζ*(g) minimises L(g, ·), which nothing guarantees (docs/conventions.md §22); the solve "
    "with internal stages is Newton's method alone, without a second-order condition: "
    "leave minimum out")


def _solve(state: _SolverState, minimum: bool) -> tuple:
    """The fast path, then (on its failure, or for ``minimum`` at a non-minimum) the
    globalised iteration, leaving ``state`` at the solution; returns the second-order
    condition: ``(inertia,)`` when it was computed, ``()`` when it is left for the solution
    to compute on request."""
    initial = state.iterate
    try:
        _fast_newton(state)
    except _Handover as why:
        if state.problem.forced or state.problem.staged:
            _no_globalisation(state, why)
        _globalised_after(state, _restart_points(state, initial, why.iterates), str(why))
        return (_reduced_inertia(state),)
    if state.problem.forced or state.problem.staged:
        return ()
    if not minimum:
        return ()
    inertia = _reduced_inertia(state)
    if not _is_minimum(inertia):
        _globalised_after(state, [initial[:2]], "it reached a stationary point "
                          f"that is not a local minimum ({_describe(inertia)})")
        inertia = _reduced_inertia(state)
        if not _is_minimum(inertia):
            raise state.divergence("found no local minimum: the globalised iteration "
                                   f"reached a stationary point that is not one "
                                   f"({_describe(inertia)})", 0.0)
    return (inertia,)


def _no_globalisation(state: _SolverState, why: _Handover) -> None:
    """The end of a forced system's solve, or one with internal stages, whose fast path gave
    up: the globalised iteration descends the action, and a forced system's solutions are
    not critical points of it (docs/conventions.md §20), nor is a descent over arrows and
    stages one of L_d (§22).  Raises the singular Jacobian that ended the fast path, or a
    divergence error."""
    if isinstance(why.__cause__, SingularJacobianError):
        raise why.__cause__
    reason = ("a forced system has no action to descend (its solutions are critical points "
              "of the Lagrange–d'Alembert principle, docs/conventions.md §20)"
              if state.problem.forced else
              "with internal stages there is no action to descend (Σ L(g_k, ζ_k) is L_d "
              "only at the stages' solutions, docs/conventions.md §22)")
    raise state.divergence(
        f"(Newton) {why}; {reason}, so there is no globalised iteration: give a guess closer "
        f"to the solution (e.g. a simulated trajectory) or solve with more steps",
        state.excess())
