"""Two-point boundary-value problems: the whole discrete trajectory at once.

Discrete optimal control problems (seed 000 §6.1–6.2, seed 001 §3.3) fix the end
configurations (second order: also the first and last arrows) and ask for a critical point
of Σ [L + λ·φ].  The unknowns are, for every free junction j, a variation δ_j ∈ R^rank that
moves the arrows as

    g_j ↦ g_j · h(δ_j),   g_{j+1} ↦ h(δ_j)⁻¹ · g_{j+1},    h(δ) ⊂ α⁻¹(β(g_j)),

— the junction variation of the derivation — so every iterate stays composable with the
end points fixed, plus the multipliers of every term.  The equations are the junction
residuals and the constraints of every term; each depends only on a window of neighbouring
unknowns, so the Jacobian is block-banded.  Its blocks are X⃖ and X⃗ derivatives of the
window residual, derived symbolically once and compiled to C through the same cffi build
cache as the step kernels (evaluated for all windows in one call; NumPy, vectorised over the
windows, without a compiler); the banded system is solved in time linear in N (LAPACK's
banded solver through SciPy when installed, a block-tridiagonal elimination in NumPy
otherwise).

A forced system (docs/conventions.md §20) adds f⁺(g_j) + f⁻(g_{j+1}) to every junction
residual (the discrete Lagrange–d'Alembert principle), with the inputs of every term given
(``inputs=``, checked in ``_inputs``) as named inputs of the window programs.  Its equations
are not the critical points of the action, so its solve is the fast path alone, without the
globalised iteration or the second-order condition below.

The derivatives are exact but never expanded into expression trees: the window's junction
residual is built on the expression graph from the window action the steps are derived from
(:class:`symgroupoid.derivation.WindowAction`), and its slot derivatives by algorithmic
differentiation along the section fields — one differentiation in the library, for steps and
windows alike; the programs come from :func:`symgroupoid.equations.window_programs`.

The solver never returns a non-solution.  Inputs are checked before anything is assembled
(runtime/_validate.py, the path the simulator's inputs take too).  The default initial path
follows geodesics (exp(s·log g) on a Lie group), so a half-turn between the ends is split into
N small turns instead of meeting the cut locus of the Cayley chart.  Success means the residual
criterion: every equation at most ROUNDING_FACTOR times its rounding floor (or ``tol``), the
floor computed alongside the residual from its running-error bound
(:func:`symgroupoid.ir.rounding_error`), which also counts the rounding of the stored
coordinates and multipliers.  Newton's method is the fast path; when it stalls in damped
steps or finds no decrease, the solve restarts — from the fast path's iterate of least ℓ₁
merit, else (or when that fails) from the initial path — with Newton steps regularised by
the inertia of the KKT matrix and a line search on an ℓ₁ merit function (a descent method
on the action).  The solution reports its cost and whether it is a local minimum (the inertia of
the Hessian of the Lagrangian on the admissible variations tangent to the constraints, by a
banded LDLᵀ: runtime/_banded.py).  Anything else — the iteration cap, a stalled update, a
line search without decrease, a singular Jacobian, a half-turn in the initial path — raises
an error carrying the iterations and the residual.

The solver is built around one solver state (:class:`~._state._SolverState`: the problem —
kernels, layout, structure maps, parameters, options —, the iterate — arrows, multipliers,
the assembled residual and Jacobian — and the run's counters), which the modules take:

- ``_kernels``: the window and cost kernels over the programs, the numeric structure maps;
- ``_layout``: where the unknowns δ_j, λ_t and the equations sit in the banded system;
- ``_linear``: the banded and block-tridiagonal solves;
- ``_inputs``: the input table of a forced system's problem, checked;
- ``_guess``: boundary data, the geodesic initial path, the checks of a guess and of the
  cut locus;
- ``_assembly``: F, its Jacobian (a gather through a fixed sparsity pattern), the rounding
  floors and the residual criterion;
- ``_state``: the solver state, its updates, its run and its errors;
- ``_fast``: the Newton fast path and the restart points of a handover;
- ``_globalised``: the inertia-corrected Newton path on the ℓ₁ merit function;
- ``_inertia``: the second-order condition;
- ``_solution``: :class:`BoundaryValueSolution`;
- ``_solve``: :func:`solve_boundary_value`, the one loop over the phases.
"""

from ._assembly import ROUNDING_FACTOR
from ._guess import CUT_LOCUS_TOLERANCE, interpolate_arrows
from ._kernels import CostKernel, WindowKernel, cost_kernel, window_kernel
from ._solution import BoundaryValueSolution
from ._solve import boundary_steps, solve_boundary_value
from ._state import MAX_HALVINGS

__all__ = ["CUT_LOCUS_TOLERANCE", "MAX_HALVINGS", "ROUNDING_FACTOR", "BoundaryValueSolution",
           "CostKernel", "WindowKernel", "cost_kernel", "interpolate_arrows",
           "boundary_steps", "solve_boundary_value", "window_kernel"]
