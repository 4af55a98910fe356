"""The solver state: the problem of one boundary-value solve, its iterate and its run.

:class:`_SolverState` is what the assembly, the fast path, the globalised path and the
inertia work on.  It holds

- the problem (:class:`_Problem`, fixed during the solve): the window and cost kernels, the
  layout of the unknowns and equations, the numeric structure maps, the parameter values
  and the options (``tol``, ``tol_step``, ``max_iterations``);
- the iterate: the arrows g_1 … g_N, the multipliers λ of every term (with internal
  stages, docs/conventions.md §22: each term's row of ``lam`` holds its multipliers, then
  its stages ζ_t), and the residual F and its Jacobian assembled there
  (:class:`~._assembly._Assembled`);
- the run: |F|∞ before each update, the iterations counted against ``max_iterations``
  (across all phases), whether the iteration has stalled, and the phases used.

An update moves the iterate along the junction variations of the derivation,

    g_j ↦ g_j · h(δ_j),   g_{j+1} ↦ h(δ_j)⁻¹ · g_{j+1},    h(δ) ⊂ α⁻¹(β(g_j)),

and the multipliers (and stages) by their increments, so every iterate stays composable with
the end points fixed.  The stages are coordinates of their own (deviations from the chord,
§22), held fixed by the junction variations: the Jacobian's δ columns are the derivatives
along the section fields at fixed ζ, its ζ columns the partial derivatives.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..._arguments import counted
from ..._errors import BoundaryValueDivergenceError, ShapeError, SingularJacobianError
from ..._progress import note as progress_note
from ._assembly import (
    ROUNDING_FACTOR,
    _assemble,
    _Assembled,
    _excess,
    _rounding_floor,
    _within_floor,
)
from ._kernels import CostKernel, WindowKernel, _Maps, _maps, cost_kernel, window_kernel
from ._layout import _Layout, _layout
from ._linear import _solve_banded

#: at most this many halvings of a Newton step in the line search
MAX_HALVINGS = 30


@dataclass(frozen=True, eq=False)
class _Problem:
    """What stays fixed during one solve: the kernels, the layout of N steps, the structure
    maps, the parameter vector ``p``, the options, and a forced system's ``inputs``
    (terms, n_inputs): row t the inputs of the term starting at g_t (docs/conventions.md
    §20; (terms, 0) without inputs)."""

    owner: str
    kernel: WindowKernel
    cost: CostKernel
    lay: _Layout
    maps: _Maps
    p: np.ndarray
    tol: float = 0.0
    tol_step: float = 0.0
    max_iterations: int = 0
    inputs: np.ndarray | None = None

    @classmethod
    def of(cls, system, steps: int, p: np.ndarray, tol: float = 0.0, tol_step: float = 0.0,
           max_iterations: int = 0, inputs: np.ndarray | None = None) -> _Problem:
        """The problem of ``steps`` steps of ``system`` (its kernels and maps cached);
        ``inputs``: the checked input table (:func:`~._inputs.input_table`), None for a
        system without inputs."""
        kernel = window_kernel(system)
        shape = (steps, kernel.arity, kernel.rank, kernel.m)
        lay = _layout(*shape, kernel.n_stages) if kernel.n_stages else _layout(*shape)
        if inputs is None:
            inputs = np.zeros((len(lay.terms), kernel.n_inputs))
            if kernel.n_inputs:
                raise ShapeError(f"{system.name}: a problem of a system with inputs needs "
                                 f"them (inputs=)")
        maps = _maps(system.groupoid, tuple(system.parameters), tuple(map(float, p)))
        return cls(system.name, kernel, cost_kernel(system), lay, maps, p, tol, tol_step,
                   max_iterations, inputs)

    @property
    def forced(self) -> bool:
        """Whether the system is forced: its solutions are critical points of the
        Lagrange–d'Alembert principle, not of the action (docs/conventions.md §20)."""
        return self.kernel.forced

    @property
    def staged(self) -> bool:
        """Whether the system's terms have internal stages ζ, unknowns of the problem with
        their stage rows (docs/conventions.md §22)."""
        return bool(self.kernel.n_stages)

    @property
    def r(self) -> int:
        return self.kernel.rank

    @property
    def m(self) -> int:
        return self.kernel.m


class _Iterate(NamedTuple):
    """A point of the iteration: the arrows, the multipliers and the system assembled there."""

    arrows: np.ndarray
    lam: np.ndarray
    assembled: _Assembled


class _Step(NamedTuple):
    """An accepted step: the new iterate, its assembled system, the step length along dz,
    and whether it was taken only because |F| was at the rounding floor."""

    arrows: np.ndarray
    lam: np.ndarray
    assembled: _Assembled
    length: float
    dz: np.ndarray
    at_floor: bool = False


def _assembled_at(problem: _Problem, arrows, lam) -> _Assembled:
    """:func:`_assemble` with floating-point warnings silenced (non-finite values are
    checked by the caller)."""
    with np.errstate(all="ignore"):
        return _assemble(problem, arrows, lam)


@dataclass(eq=False)
class _SolverState:
    """The problem, the current iterate and the run of one solve (see the module docstring)."""

    problem: _Problem
    arrows: np.ndarray
    lam: np.ndarray
    assembled: _Assembled
    history: list = field(default_factory=list)
    iterations: int = 0
    stalled: str = ""
    methods: list = field(default_factory=list)
    at_floor: int = 0  # consecutive steps taken only because |F| was at the rounding floor

    @classmethod
    def at(cls, problem: _Problem, arrows, lam) -> _SolverState:
        """The state of ``problem`` at (arrows, λ), assembled there, before any iteration."""
        return cls(problem, arrows, lam, _assembled_at(problem, arrows, lam))

    # --- the iterate ---------------------------------------------------------------------

    @property
    def iterate(self) -> _Iterate:
        return _Iterate(self.arrows, self.lam, self.assembled)

    def move_to(self, arrows, lam, assembled: _Assembled | None = None) -> None:
        """Make (arrows, λ) the iterate, assembled there unless ``assembled`` is given."""
        if assembled is None:
            assembled = self.assemble(arrows, lam)
        self.arrows, self.lam, self.assembled = arrows, lam, assembled

    def assemble(self, arrows, lam) -> _Assembled:
        """F and its Jacobian at (arrows, λ) (not made the iterate)."""
        return _assembled_at(self.problem, arrows, lam)

    def update(self, dz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The iterate moved by dz = (δ, dλ): new arrays g_j·h(δ_j), h(δ_j)⁻¹·g_{j+1}, λ + dλ."""
        lay, maps, r, m = self.problem.lay, self.problem.maps, self.problem.r, self.problem.m
        arrows = self.arrows.copy()
        moved = lay.moved
        if len(moved):
            D = dz[lay.delta_at[moved][:, None] + np.arange(r)]
            H = maps.flow_at_target(arrows[moved], D)
            arrows[moved] = maps.multiply(arrows[moved], H)  # g_j · h(δ_j)
            arrows[moved + 1] = maps.multiply(maps.inverse(H), arrows[moved + 1])  # h⁻¹ · g_{j+1}
        lam = self.lam.copy()
        terms = lay.multiplied
        if m and len(terms):
            lam[terms, :m] += dz[lay.lam_at[terms][:, None] + np.arange(m)]
        staged, nz = lay.staged, self.problem.kernel.n_stages
        if nz and len(staged):  # the stages ζ_t, after the multipliers (§22)
            lam[staged, m:] += dz[lay.zeta_at[staged][:, None] + np.arange(nz)]
        return arrows, lam

    def trial(self, dz: np.ndarray) -> _Iterate:
        """The iterate moved by dz and the system assembled there."""
        arrows, lam = self.update(dz)
        return _Iterate(arrows, lam, self.assemble(arrows, lam))

    def backtrack(self, dz: np.ndarray, accept) -> _Step | None:
        """The step along dz from length t = 1, halved at most MAX_HALVINGS times, until
        ``accept(t, arrows, assembled, f)`` holds at a finite trial (f = |F|₂² there, itself
        finite: above |F| ≈ 1e154 the square overflows and no decrease can be told, so the
        step is halved) or the trial is within the rounding floor (taken at once,
        ``at_floor``: comparing two residuals there is comparing noise) without a larger
        |F| than the iterate's own, or than its floor (a trial far out, where the rounding
        of huge coordinates excuses any residual, is not noise: it was taken, and |F| rose
        from 5e14 to 3e30 in a "converged" step); None when neither happens."""
        here = self.assembled
        with np.errstate(over="ignore"):
            f_here = float(here.F @ here.F)
        length = 1.0
        for _ in range(MAX_HALVINGS):
            arrows, lam, trial = self.trial(length * dz)
            if trial.finite():
                f = float(trial.F @ trial.F)
                # |F| above 1e154: |F|₂² overflows and compares equal to an overflowed
                # |F₀|₂²; such a trial is not a decrease anyone can tell, so it is halved
                if f < np.inf and accept(length, arrows, trial, f):
                    return _Step(arrows, lam, trial, length, dz)
                if _within_floor(trial, f) and (f <= f_here or _within_floor(here, f)):
                    return _Step(arrows, lam, trial, length, dz, at_floor=True)
            length /= 2
        return None

    def excess(self) -> float:
        """The iterate's residual in units of the accepted one (:func:`_excess`): at most 1
        when its residual criterion holds."""
        return _excess(self.assembled.F, _rounding_floor(self.assembled), self.problem.tol)

    def converged(self) -> bool:
        """Whether the iterate is a solution: its residual at the rounding floor, or within
        a ``tol`` looser than that and the Newton update from it at most ``tol`` of
        1 + max(|coordinates|, |λ|).  A residual criterion alone accepts what is no
        solution: the DEL residual of a smooth path is O(h²) of its terms' sensitivity to
        the coordinates, so tol = 1e-6 accepted the straight initial path of a spring at
        h = 10⁻³, 43 % of the way from the solution."""
        F, floor = self.assembled.F, _rounding_floor(self.assembled)
        if _excess(F, floor, 0.0) <= 1.0:
            return True
        if _excess(F, floor, self.problem.tol) > 1.0:
            return False
        try:
            dz = self.newton_direction()
        except SingularJacobianError:
            return False
        scale = 1.0 + max(float(np.max(np.abs(self.arrows), initial=0.0)),
                          float(np.max(np.abs(self.lam), initial=0.0)))
        return float(np.max(np.abs(dz), initial=0.0)) <= self.problem.tol * scale

    def newton_direction(self, rows=None, cols=None, vals=None) -> np.ndarray:
        """The solution dz of J·dz = −F at the iterate (J given as COO triplets, default the
        Jacobian), or a :class:`SingularJacobianError`."""
        state = self.assembled
        rows = state.rows if rows is None else rows
        cols = state.cols if cols is None else cols
        vals = state.vals if vals is None else vals
        try:
            with np.errstate(all="ignore"):
                dz = _solve_banded(rows, cols, vals, self.problem.lay.size, -state.F,
                                   state.band if vals is state.vals else None)
        except np.linalg.LinAlgError as exc:
            raise self.singular() from exc
        if not np.isfinite(dz).all():
            raise self.singular()
        return dz

    # --- the run -------------------------------------------------------------------------

    def record(self) -> float:
        """Note |F|∞ of the iterate in the history (and in the progress report)."""
        norm = float(np.max(np.abs(self.assembled.F), initial=0.0))
        self.history.append(norm)
        progress_note(f"iteration {self.iterations}, |F|∞ = {norm:.2e}")
        return norm

    def take(self, step: _Step) -> None:
        """Count the step, decide whether the iteration has stalled, and move to it.

        Stalled: an update below ``tol_step``·(1 + |λ|∞), one that changed no stored value,
        or a second step in a row that did not decrease |F| but was taken because |F| is at
        the rounding floor (where the comparison of residuals is noise) without meeting the
        criterion."""
        tol_step = self.problem.tol_step
        self.iterations += 1
        self.at_floor = self.at_floor + 1 if step.at_floor else 0
        scale = 1.0 + float(np.max(np.abs(step.lam), initial=0.0))
        size = step.length * float(np.max(np.abs(step.dz), initial=0.0))
        if size <= tol_step * scale:
            self.stalled = f"the update fell below tol_step = {tol_step:g}"
        elif np.array_equal(self.arrows, step.arrows) and np.array_equal(self.lam, step.lam):
            self.stalled = "the update changed no stored value"
        elif self.at_floor >= 2:
            self.stalled = ("|F| stopped decreasing at the rounding floor: the floor estimate is "
                            "below the residual's actual noise there")
        self.move_to(step.arrows, step.lam, step.assembled)

    def check_budget(self, excess: float) -> None:
        """Raise when the iteration has stalled or used ``max_iterations``."""
        if self.stalled:
            raise self.divergence(f"stalled: {self.stalled}", excess)
        if self.iterations >= self.problem.max_iterations:
            raise self.divergence(
                f"did not converge in {counted(self.problem.max_iterations, 'iteration')}",
                excess)

    # --- the errors ----------------------------------------------------------------------

    def divergence(self, why: str, excess: float) -> BoundaryValueDivergenceError:
        """The error of an iteration that ends without a solution at the iterate."""
        state = self.assembled
        norm = float(np.max(np.abs(state.F), initial=0.0))
        return BoundaryValueDivergenceError(
            f"{self.problem.owner}: boundary-value iteration {why}; after "
            f"{counted(self.iterations, 'iteration')} |F|∞ = {norm:.3e}, worst at "
            f"configuration {state.worst}, "
            f"{excess:.1e} times the accepted residual max(tol/ε, {ROUNDING_FACTOR:g})·"
            f"rounding floor: not a solution",
            iterations=self.iterations, history=self.history, step=state.worst,
            residual_norm=norm, iterate=self.arrows)

    def singular(self) -> SingularJacobianError:
        """The error of a singular Jacobian at the iterate."""
        state = self.assembled
        norm = float(np.max(np.abs(state.F), initial=0.0))
        where = ("at the initial path (the path between the ends, or the guess): the "
                 "gradients of the constraints may vanish along it (a straight path through "
                 "the centre of a circle of constraint) — pass guess= a path that follows "
                 "them — or " if self.iterations == 0 else "")
        return SingularJacobianError(
            f"{self.problem.owner}: singular boundary-value Jacobian at iteration "
            f"{self.iterations} (|F|∞ = {norm:.3e}, worst at configuration {state.worst}); "
            f"{where}the boundary data may violate the constraints or the Lagrangian is not "
            f"regular there", step=state.worst, residual_norm=norm, iterate=self.arrows)
