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
"""

from __future__ import annotations

import collections
import functools
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import sympy as sp

from .._arguments import choice_argument, ndim, real_array
from .._errors import (
    BoundaryValueDivergenceError,
    CutLocusError,
    DomainError,
    InputTypeError,
    NewtonDivergenceError,
    NotComposableError,
    ShapeError,
    SingularJacobianError,
)
from .._progress import note as progress_note
from .._progress import reported
from ..equations import cost_program, structure_program, window_programs
from ..ir import Program
from . import _lapack
from ._banded import Inertia, banded_inertia
from ._programs import ProgramEvaluator
from ._validate import arrow as checked_arrow
from ._validate import (
    check_holonomic_nodes,
    configuration,
    integer_argument,
    parameter_vector,
    real_argument,
)

# --- window kernels ----------------------------------------------------------------------

def _functions(system):
    """The system's evaluated functions (L, φ on slot arrows)."""
    return system._fs


def _vectorised(label: str, program: Program, inputs: str, outputs: str) -> ProgramEvaluator:
    """Evaluate ``program``'s output for W windows: (W, n_in) → (W, n_out).

    Compiled to C through the kernel cache (the same build path as the step kernels) when a
    compiler is available; until the kernel is built — in the background, so that a first
    solve never waits for the compiler — and without a compiler, the program's NumPy form
    (vectorised over windows), which computes the same bits (:class:`ProgramEvaluator`).
    ``SYMGROUPOID_BACKEND`` = ``numpy`` or ``c`` forces one of the two (``c``: build first)."""
    backend = choice_argument(os.environ.get("SYMGROUPOID_BACKEND", "auto") or "auto",
                              ("auto", "c", "numpy"), "SYMGROUPOID_BACKEND", owner=label)
    return ProgramEvaluator(label, program, inputs, outputs, backend)


class WindowKernel:
    """Residuals of one junction and of one term, with their slot derivatives.

    For the junction residual r (rank rows) and each slot o of the window:
    ``left[o]`` = X⃖_b[r_i] on slot o and ``right[o]`` = X⃗_b[r_i] on slot o (rank × rank),
    and ``dlam[s]`` = ∂r/∂λ_s; likewise for the constraints of the term starting at 0.

    The programs are those of :func:`~symgroupoid.equations.window_programs`: the window
    action S = Σ_s [L + λ_s·Φ](terms starting at s) (seed 001 eq. (17)), its junction
    residual r_b = X⃖_b[S](g_j) − X⃗_b[S](g_{j+1}) (docs/conventions.md §2) and each block a
    derivative of r along one section field on one slot; evaluated here in C or NumPy.
    """

    def __init__(self, system):
        programs = window_programs(system)
        self.groupoid = system.groupoid
        self.rank, self.m, self.held = programs.rank, programs.m, programs.held
        self.arity, self.offsets, self.starts = programs.arity, programs.offsets, programs.starts
        self.parameters = programs.parameters
        self._junction = _vectorised(f"{system.name}_junction", programs.junction, "a",
                                     "junction")
        self._term = None
        if programs.term is not None:
            self._term = _vectorised(f"{system.name}_term", programs.term, "a", "term")

    def junction(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray):
        """All junction blocks for W windows: windows (W, slots, arrow_dim), lams (W, starts, m)."""
        return self.junction_terms(windows, lams, params)[:4]

    def junction_terms(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray):
        """:meth:`junction`'s blocks and the rounding bound E of each residual (W, rank): its
        rounding error is at most about ε·E (:func:`symgroupoid.ir.rounding_error`)."""
        return self.split_junction(self.junction_values(windows, lams, params))

    def junction_values(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray
                        ) -> np.ndarray:
        """The junction program's outputs for W windows, one row each (see
        :meth:`split_junction`)."""
        W = len(windows)
        vals = np.hstack([windows.reshape(W, -1), lams.reshape(W, -1),
                          np.broadcast_to(params, (W, len(params)))])
        return self._junction(vals)  # (W, total)

    def split_junction(self, out: np.ndarray):
        """(residuals, left, right, dlam, rounding bounds) as views of the outputs ``out``."""
        W, r, k = len(out), self.rank, 0
        res = out[:, k:k + r]
        k += r
        left, right = {}, {}
        for o in self.offsets:
            blk = out[:, k:k + 2 * r * r].reshape(W, r, 2, r)
            left[o], right[o] = blk[:, :, 0, :], blk[:, :, 1, :]
            k += 2 * r * r
        dlam = {}
        for s in self.starts:
            dlam[s] = out[:, k:k + r * self.m].reshape(W, r, self.m)
            k += r * self.m
        return res, left, right, dlam, out[:, k:k + r]

    def term(self, windows: np.ndarray, params: np.ndarray):
        """Constraint values and slot derivatives for T terms: windows (T, arity, arrow_dim)."""
        return self.term_terms(windows, params)[:3]

    def term_terms(self, windows: np.ndarray, params: np.ndarray):
        """:meth:`term`'s values and blocks and the rounding bound of each constraint value
        (T, m)."""
        return self.split_term(self.term_values(windows, params))

    def term_values(self, windows: np.ndarray, params: np.ndarray) -> np.ndarray:
        """The term program's outputs for T windows, one row each (see :meth:`split_term`)."""
        T = len(windows)
        return self._term(np.hstack([windows.reshape(T, -1),
                                     np.broadcast_to(params, (T, len(params)))]))

    def split_term(self, out: np.ndarray):
        """(constraint values, left, right, rounding bounds) as views of the outputs ``out``."""
        T, m, r = len(out), self.m, self.rank
        res = out[:, :m]
        left, right, k = {}, {}, m
        for o in range(self.arity):
            blk = out[:, k:k + 2 * m * r].reshape(T, m, 2, r)
            left[o], right[o] = blk[:, :, 0, :], blk[:, :, 1, :]
            k += 2 * m * r
        return res, left, right, out[:, k:k + m]


@functools.lru_cache(maxsize=8)
def window_kernel(system) -> WindowKernel:
    """The (cached) window kernel of a system."""
    return WindowKernel(system)


class CostKernel:
    """The discrete cost S = Σ_k L(g_k, …, g_{k+arity−1}) of an arrow sequence: the
    system's Lagrangian on the expression graph, evaluated with NumPy for all terms at once
    (no compiler: it is a single value per term)."""

    def __init__(self, system):
        self.arity = len(_functions(system).slots)
        self._f = cost_program(system).numpy_function(["cost"], ["a"])

    def terms(self, arrows: np.ndarray, params: np.ndarray) -> np.ndarray:
        """L on every window of ``arity`` consecutive arrows."""
        T = len(arrows) - self.arity + 1
        windows = np.hstack([arrows[o:o + T] for o in range(self.arity)])
        values = np.hstack([windows, np.broadcast_to(params, (T, len(params)))])
        with np.errstate(all="ignore"):
            out = self._f(values.T)[0]
        return np.broadcast_to(np.asarray(out, float).reshape(-1), (T,))

    def __call__(self, arrows: np.ndarray, params: np.ndarray) -> float:
        return float(np.sum(self.terms(arrows, params)))


@functools.lru_cache(maxsize=8)
def cost_kernel(system) -> CostKernel:
    """The (cached) cost kernel of a system."""
    return CostKernel(system)


# --- numeric structure maps ------------------------------------------------------------------

@functools.lru_cache(maxsize=16)
def _maps(G) -> _Maps:
    return _Maps(G)


class _Maps:
    def __init__(self, G):
        self.G = G
        program = structure_program(G)
        self._mul = program.numpy_function(["multiply"], ["a", "b"])
        self._inv = program.numpy_function(["inverse"], ["a"])
        self._flow = program.numpy_function(["flow"], ["a", "d"])

    def multiply(self, A, B):
        return self._mul(A.T, B.T)[0].T

    def inverse(self, A):
        return self._inv(A.T)[0].T

    def flow_at_target(self, A, D):
        """h(δ) ⊂ α⁻¹(β(A)) for each row."""
        return self._flow(A.T, D.T)[0].T


# --- the solution --------------------------------------------------------------------------

@dataclass
class BoundaryValueSolution:
    """A solved two-point problem: arrows g_1 … g_N, multipliers per term, and diagnostics.

    ``arrows`` (N, arrow_dim); ``multipliers`` (terms, m) — the costates of optimal control;
    ``controls`` (N, rank) — chart coordinates of each arrow (Lie groups: τ⁻¹(g_k) = hξ_k);
    ``configurations`` — the N + 1 configurations from ``origin``, the first, along the
    arrows; ``sol[name]`` — a named part of every arrow (``"x"``: the target point of each
    arrow; ``"g"``: each arrow's matrix; …).

    What was found: ``cost`` — the discrete cost Σ_k L_d (the action without the multiplier
    terms, which vanish on the constraints); ``inertia`` — (positive, negative, zero)
    eigenvalue counts of the Hessian of the action restricted to the admissible variations
    (the junction variations δ_j, which keep the ends and the composability) and, with
    constraints, to those tangent to Φ = 0: the Hessian of the Lagrangian on the tangent
    space of the constraints (see :func:`_reduced_inertia`), or None when it is singular to
    rounding; ``is_local_minimum``; ``method`` — the iterations used.

    The configurations and the second-order condition are computed when first asked for
    (the inertia from the KKT matrix re-assembled at the solution, the same matrix the
    solve ended with), so a solve whose caller needs neither does not pay for them.
    """

    system: object
    arrows: np.ndarray
    multipliers: np.ndarray
    origin: object
    parameters: dict
    iterations: int
    residual_norm: float
    history: list = field(default_factory=list)
    seconds: float = 0.0
    cost: float = float("nan")
    #: (the inertia,) once known, () until then (see :attr:`inertia`)
    second_order: tuple = ()
    method: str = "Newton"

    @property
    def steps(self) -> int:
        return len(self.arrows)

    @functools.cached_property
    def configurations(self) -> list:
        """The N + 1 configurations from :attr:`origin` along the arrows."""
        return self.system.groupoid.configurations_from(self.origin, self.arrows)

    @property
    def inertia(self) -> Inertia | None:
        """(positive, negative, zero) eigenvalue counts of the reduced Hessian (see the class
        docstring), or None when it is singular to rounding."""
        if not self.second_order:
            p = np.array([self.parameters[str(q)] for q in self.system.parameters], float)
            self.second_order = (_inertia_at(self.system, self.arrows, self.multipliers, p),)
        return self.second_order[0]

    @functools.cached_property
    def controls(self) -> np.ndarray:
        G = self.system.groupoid
        return np.array([G.fibre_chart_inverse(G.fibre_of(a), G.source(a))
                         for a in self.arrows], float)

    def __getitem__(self, name: str) -> np.ndarray:
        G = self.system.groupoid
        table = G.symbols_by_name(0)
        if name not in table:
            raise KeyError(f"no part named {name!r}; available: {sorted(table)}")
        position = {s: i for i, s in enumerate(G.named_arrow(0)) if isinstance(s, sp.Symbol)}
        value = table[name]
        entries = value if isinstance(value, sp.MatrixBase) else sp.Matrix([value])
        out = np.empty((len(self.arrows),) + entries.shape)
        for idx in np.ndindex(*entries.shape):
            e = entries[idx]
            out[(slice(None),) + idx] = (self.arrows[:, position[e]] if e in position
                                         else float(e))
        return out if isinstance(value, sp.MatrixBase) else out[:, 0, 0]

    @property
    def is_local_minimum(self) -> bool | None:
        """True: a strict local minimum of the cost among admissible paths that keep the
        constraints (the reduced Hessian is positive definite: the second-order sufficient
        condition); False: not a minimum (the reduced Hessian has a negative eigenvalue, so
        some admissible variation lowers the cost: a saddle or a maximum); None: not decided
        at second order (the reduced Hessian or the KKT matrix is singular to rounding)."""
        if self.inertia is None:
            return None
        return self.inertia.negative == 0

    @property
    def kind(self) -> str:
        """What the second-order condition says, in words (see :attr:`is_local_minimum`)."""
        if self.inertia is None:
            return "undetermined (the reduced Hessian is singular to rounding)"
        k = self.inertia.negative
        if k == 0:
            return "local minimum"
        return f"NOT a local minimum: a saddle with {k} descent direction{'s' if k > 1 else ''}"

    def __repr__(self) -> str:
        return (f"<BoundaryValueSolution {self.system.name!r}: {self.steps} arrows, "
                f"{self.iterations} iterations ({self.method}), |F| = "
                f"{self.residual_norm:.2e}, cost {self.cost:.10g}, {self.kind}>")


# --- linear algebra --------------------------------------------------------------------------

def _solve_banded(rows, cols, vals, n, rhs, band: _Band | None = None) -> np.ndarray:
    """Solve the sparse banded system (COO triplets) in time linear in its size: LAPACK's
    ``gbsv`` (LU with partial pivoting in banded storage) — NumPy's own LAPACK
    (:mod:`._lapack`), else SciPy's, else block elimination in NumPy; ``band``, the
    triplets' :class:`_Band` when known (a solve's every Jacobian shares one)."""
    band = _Band.of(rows, cols, n) if band is None else band
    ab = band.matrix(vals)
    solved = _lapack.dgbsv(band.kl, band.ku, ab, np.asarray(rhs, float))
    if solved is None:
        try:
            from scipy.linalg import lapack
        except ImportError:  # pragma: no cover - exercised by forcing the fallback in tests
            return _block_tridiagonal(rows, cols, vals, n, rhs, max(band.kl, band.ku))
        _, _, x, info = lapack.dgbsv(band.kl, band.ku, ab, np.array(rhs, float),
                                     overwrite_ab=True, overwrite_b=True)
    else:
        x, info = solved
    if info > 0:
        raise np.linalg.LinAlgError(f"singular banded matrix (zero pivot {info})")
    if info < 0:  # pragma: no cover - the arguments are built above
        raise ValueError(f"gbsv: illegal argument {-info}")
    return x


def _block_tridiagonal(rows, cols, vals, n, rhs, band) -> np.ndarray:
    """Block elimination with blocks of size ``band`` (≥ the bandwidth), so the matrix is
    block tridiagonal; each diagonal block is LU-factorised with pivoting by NumPy."""
    b = max(band, 1)
    nb = -(-n // b)
    size = nb * b
    D = np.zeros((nb, b, b))
    L = np.zeros((nb, b, b))
    U = np.zeros((nb, b, b))
    bi, bj = rows // b, cols // b
    for arr, mask in ((D, bi == bj), (L, bi == bj + 1), (U, bi + 1 == bj)):
        np.add.at(arr, (bi[mask], rows[mask] % b, cols[mask] % b), vals[mask])
    pad = np.arange(n, size)
    D[pad // b, pad % b, pad % b] = 1.0
    y = np.zeros(size)
    y[:n] = rhs
    y = y.reshape(nb, b)
    for k in range(1, nb):
        F = np.linalg.solve(D[k - 1].T, L[k].T).T
        D[k] -= F @ U[k - 1]
        y[k] -= F @ y[k - 1]
    x = np.zeros_like(y)
    x[-1] = np.linalg.solve(D[-1], y[-1])
    for k in range(nb - 2, -1, -1):
        x[k] = np.linalg.solve(D[k], y[k] - U[k] @ x[k + 1])
    return x.ravel()[:n]


# --- the solver --------------------------------------------------------------------------------

#: accept the iterate when every |F_i| ≤ max(tol/ε, ROUNDING_FACTOR)·floor_i, floor_i the rounding
#: floor of equation i (:func:`_rounding_floor`): ε·M_i, M_i the size of the terms that cancel
#: in F_i (every operation of its evaluation rounded once), plus the effect of the rounding of
#: the coordinates.  ε·M_i bounds the rounding of F_i up to the depth of the evaluation, while
#: rounding errors mostly cancel one another: at solutions |F_i| sits at 0.01–0.5 of floor_i
#: (measured on SO(3), SE(3) with translations up to 10⁴, SE(2), plate-ball, second-order
#: rigid body with N up to 1000, heavy top with rotors, time groupoid with t ≈ 10³).
#: A factor 8 leaves a margin of ≥ 16 over those, and a residual below 8·floor_i is a
#: solution to within 8 roundings of its own terms.
ROUNDING_FACTOR = 8.0

#: at most this many halvings of a Newton step in the line search
MAX_HALVINGS = 30

#: an arrow with cos²(θ/2) ≤ this for a rotation block (θ its largest rotation angle) is a
#: half-turn to rounding, on the cut locus of the Cayley chart and of the logarithm
CUT_LOCUS_TOLERANCE = 1e-12

_EPS = float(np.finfo(float).eps)


@dataclass
class _Layout:
    """Positions of the unknowns (δ_j, λ_t) and equations (DEL_j, Φ_t) in the banded system."""

    junctions: np.ndarray
    terms: np.ndarray
    delta_index: dict
    lam_index: dict
    size: int

    @functools.cached_property
    def delta_at(self) -> np.ndarray:
        """delta_index as an array over positions 0 … n (−1: not an unknown)."""
        return _index_array(self.delta_index, len(self.terms) + len(self.junctions) + 2)

    @functools.cached_property
    def lam_at(self) -> np.ndarray:
        return _index_array(self.lam_index, len(self.terms) + len(self.junctions) + 2)

    @functools.cached_property
    def moved(self) -> np.ndarray:
        """The positions j with a variation δ_j, increasing."""
        return np.array(sorted(self.delta_index), dtype=np.int64)

    @functools.cached_property
    def multiplied(self) -> np.ndarray:
        """The terms t with multipliers λ_t, increasing."""
        return np.array(sorted(self.lam_index), dtype=np.int64)


def _index_array(index: dict, n: int) -> np.ndarray:
    out = np.full(max(n, max(index, default=-1) + 2), -1, dtype=np.int64)
    for position, k in index.items():
        out[position] = k
    return out


@functools.lru_cache(maxsize=16)
def _layout(n: int, arity: int, rank: int, m: int) -> _Layout:
    """The positions of the unknowns and equations of N = ``n`` steps (cached: the layout
    and its index arrays are read-only and shared by the solves of one size)."""
    junctions = np.arange(arity - 1, n - arity)
    terms = np.arange(0, n - arity + 1)
    junctions.flags.writeable = terms.flags.writeable = False
    delta_index, lam_index, k = {}, {}, 0
    term_set = set(terms.tolist())
    for p in range(n + 1):  # interleave by position: λ_p then δ_p
        if m and p in term_set:
            lam_index[p] = k
            k += m
        if arity - 1 <= p < n - arity:
            delta_index[p] = k
            k += rank
    return _Layout(junctions, terms, delta_index, lam_index, k)


# --- the initial guess: geodesic interpolation -------------------------------------------------

def interpolate_arrows(G, total: Sequence, steps: int) -> np.ndarray:
    """N arrows g_k = P_{k−1}⁻¹ P_k whose product is ``total``: P_k = P(k/N) on the geodesic
    (``G.geodesic``) from the identity ε(α(total)) to ``total`` (on a Lie group
    g_k = exp(log(total)/N), so a half-turn is split into N turns by π/N and the guess stays
    off the cut locus of the Cayley chart)."""
    total = np.asarray(total, float)
    P = G.geodesic(total, np.arange(steps + 1) / steps)
    P[0] = np.asarray(G.identity(tuple(G.source(total))), float)
    P[-1] = total
    maps = _maps(G)
    return maps.multiply(maps.inverse(P[:-1]), P[1:])


# --- boundary data -----------------------------------------------------------------------------

@dataclass
class _Boundary:
    """Validated boundary data: the configurations, the arrow from the first to the last one,
    and (second order) the fixed first and last arrows and the arrow between them."""

    configurations: tuple
    total: np.ndarray
    first: np.ndarray | None = None
    last: np.ndarray | None = None
    inner: np.ndarray | None = None


def _boundary(system, a: int, start, end) -> _Boundary:
    """``start``/``end`` checked as states are (:func:`configuration`), before any solve."""
    G, owner = system.groupoid, system.name
    if a == 1:
        c0 = configuration(G, start, "start", owner=owner)
        cn = configuration(G, end, "end", owner=owner)
        return _Boundary((c0, cn), np.asarray(G.arrow_between(c0, cn), float))
    pairs = []
    for label, value in (("start", start), ("end", end)):
        if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)) \
                or (isinstance(value, np.ndarray) and value.ndim == 0) or len(value) != 2:
            raise ShapeError(f"{owner}: second-order boundary data are two configurations at "
                             f"each end: start=(c0, c1), end=(cN-1, cN); {label} is not a pair")
        pairs.append(tuple(configuration(G, c, f"{label}[{i}]", owner=owner)
                           for i, c in enumerate(value)))
    (c0, c1), (cn1, cn) = pairs
    arrow_of = lambda x, y: np.asarray(G.arrow_between(x, y), float)  # noqa: E731
    return _Boundary((c0, c1, cn1, cn), arrow_of(c0, cn), arrow_of(c0, c1), arrow_of(cn1, cn),
                     arrow_of(c1, cn1))


def _boundary_system(step_equations):
    """The system behind the first argument of :func:`solve_boundary_value` (a system, or
    its step equations), or an :class:`InputTypeError` naming what was given."""
    system = getattr(step_equations, "system", step_equations)
    if not all(hasattr(system, a) for a in ("_fs", "groupoid", "name", "parameters")):
        raise InputTypeError(
            f"solve_boundary_value: the first argument must be a system (DiscreteSystem, "
            f"SecondOrderSystem, …) or its step equations (system.euler_lagrange()), got "
            f"{type(step_equations).__name__}")
    return system


def _split_guess(guess, steps: int):
    """(arrows, multipliers or None) of a guess: an (N, arrow_dim) table of arrows, or the
    pair ``(arrows, multipliers)``, a 2-tuple whose first entry is itself a table (a tuple
    of N arrows is arrows)."""
    if isinstance(guess, tuple) and len(guess) == 2 and ndim(guess[0]) == 2:
        return guess
    return guess, None


def _initial(system, a: int, m: int, data: _Boundary, steps: int, guess):
    """The initial arrows and multipliers: ``guess`` (checked) or the geodesic
    interpolation with zero multipliers."""
    G, owner = system.groupoid, system.name
    n_terms = steps - a + 1
    if guess is None:
        if a == 1:
            return interpolate_arrows(G, data.total, steps), np.zeros((n_terms, m))
        inner = interpolate_arrows(G, data.inner, steps - 2)
        return np.vstack([data.first, inner, data.last]), np.zeros((n_terms, m))
    arrows, lam = _split_guess(guess, steps)
    arrows = real_array(arrows, "guess", owner=owner)
    if arrows.shape != (steps, G.arrow_dim):
        raise ShapeError(f"{owner}: guess must have shape ({steps}, {G.arrow_dim}) "
                         f"(one arrow per step), got {arrows.shape}")
    for k, row in enumerate(arrows):
        checked_arrow(G, row, f"guess[{k}]", owner=owner)
    if lam is None:
        lam = np.zeros((n_terms, m))
    else:
        lam = real_array(lam, "the multiplier guess", owner=owner)
        if lam.shape != (n_terms, m):
            raise ShapeError(f"{owner}: multiplier guess must have shape "
                             f"({n_terms}, {m}), got {lam.shape}")
        if not np.isfinite(lam).all():
            raise DomainError(f"{owner}: the multiplier guess has non-finite entries")
    _check_guess(system, arrows, data.total, data.first, data.last)
    return arrows, lam


def _check_guess(system, arrows, total, first, last):
    G = system.groupoid
    maps = _maps(G)
    for k in range(1, len(arrows)):
        if not np.allclose(G.target(arrows[k - 1]), G.source(arrows[k]), atol=1e-9):
            raise NotComposableError(f"{system.name}: guess arrows {k - 1} and {k} are not "
                                     "composable (β(g_{k-1}) ≠ α(g_k))")
    product = arrows[0:1]
    for k in range(1, len(arrows)):
        product = maps.multiply(product, arrows[k:k + 1])
    if not np.allclose(product[0], total, atol=1e-8):
        raise NotComposableError(f"{system.name}: the guess does not join the boundary "
                                 "configurations (its product differs from start⁻¹·end)")
    if first is not None and not (np.allclose(arrows[0], first) and
                                  np.allclose(arrows[-1], last)):
        raise ShapeError(f"{system.name}: a second-order guess must keep the fixed first and "
                         "last arrows")


# --- the cut locus -----------------------------------------------------------------------------

def _half_turns(G, arrows: np.ndarray) -> list[tuple[int, str, float]]:
    """(arrow index, part name, det(I + R)/2ⁿ) of every matrix part of ``arrows`` whose
    rotation block R is a half-turn to rounding: det(I + R)/2ⁿ = Π cos²(θ_i/2) over the
    rotation angles θ_i (SO(3): cos²(θ/2)) vanishes exactly on the cut locus of the Cayley
    chart cay⁻¹(R) = 2(R − I)(R + I)⁻¹, which is also where the logarithm is not unique."""
    out = []
    for start, group in G.matrix_parts():
        n = group.n - 1 if group.affine else group.n
        R = group.numeric_matrices(arrows[:, start:start + group.arrow_dim])[:, :n, :n]
        closeness = np.abs(np.linalg.det(np.eye(n) + R)) / 2.0 ** n
        out += [(int(k), group.symbol_name, float(closeness[k]))
                for k in np.flatnonzero(closeness <= CUT_LOCUS_TOLERANCE)]
    return sorted(out)


def _check_cut_locus(system, arrows: np.ndarray, what: str) -> None:
    """A :class:`CutLocusError` naming the arrows of ``arrows`` that are half-turns."""
    bad = _half_turns(system.groupoid, arrows)
    if bad:
        listing = ", ".join(f"arrows[{k}] (its {name!r} part, det(I + R)/2ⁿ = {c:.1e})"
                            for k, name, c in bad[:6])
        verb = "is a half-turn" if len(bad) == 1 else "are half-turns"
        raise CutLocusError(
            f"{system.name}: {what} {listing} {verb}, on the cut locus of the Cayley chart "
            f"and of the logarithm, where "
            f"Lagrangians and constraints written in these charts are not defined; use a "
            f"guess that avoids half-turns (the default geodesic guess does) or more steps",
            arrows=tuple(k for k, _, _ in bad), iterate=arrows)


# --- assembly ----------------------------------------------------------------------------------

class _Assembled(NamedTuple):
    """The residual F, the Jacobian (COO triplets), the configuration where |F| is largest,
    and the magnitude of the terms that cancel in every equation."""

    F: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    vals: np.ndarray
    worst: int
    cancel: np.ndarray  # per equation: the magnitude of the terms that cancel in it
    band: _Band | None = None  # where each triplet lands in LAPACK's banded storage

    def finite(self) -> bool:
        return bool(np.isfinite(self.F).all() and np.isfinite(self.vals).all())


class _Band(NamedTuple):
    """LAPACK's general banded storage of a fixed sparsity pattern: the lower and upper
    bandwidths and, per triplet, its flat position in the (2·kl + ku + 1, n) array that
    ``gbsv`` factorises in place (the first kl rows are its workspace)."""

    kl: int
    ku: int
    index: np.ndarray
    n: int

    @classmethod
    def of(cls, rows: np.ndarray, cols: np.ndarray, n: int) -> _Band:
        kl = int(np.max(rows - cols, initial=0))
        ku = int(np.max(cols - rows, initial=0))
        return cls(kl, ku, (kl + ku + rows - cols) * n + cols, n)

    def matrix(self, vals: np.ndarray) -> np.ndarray:
        """The banded storage of the matrix with these triplet values (duplicates summed)."""
        size = (2 * self.kl + self.ku + 1) * self.n
        return np.bincount(self.index, weights=vals, minlength=size).reshape(-1, self.n)


class _Pattern(NamedTuple):
    """Where every output of the window programs lands in F and in the Jacobian, for one
    layout: the sparsity pattern is the same at every iterate, so the assembly is a gather.

    The outputs are read from the flat vector [junction outputs, term outputs, 1]: triplet
    k has the value sign[k]·flat[src[k]], equation f_rows[i] the residual flat[f_src[i]] and
    the cancelling magnitude flat[c_src[i]]; the rows ``pin_rows`` hold the holonomic
    multipliers λ[pin_terms, m − held:] of the terms with a fixed source node."""

    rows: np.ndarray
    cols: np.ndarray
    src: np.ndarray
    sign: np.ndarray
    f_rows: np.ndarray
    f_src: np.ndarray
    c_src: np.ndarray
    pin_rows: np.ndarray
    pin_terms: np.ndarray
    band: _Band


def _pattern(kernel, lay) -> _Pattern:
    """The :class:`_Pattern` of ``lay``: the scatter of :func:`_add` run once on the
    positions of the outputs (position + 1, negated where the block enters with a minus)."""
    a, r, m = kernel.arity, kernel.rank, kernel.m
    rows, cols, vals = [], [], []
    f_rows, f_src, c_src = [], [], []
    base = 0
    J = lay.junctions
    if len(J):
        width = r + 2 * r * r * len(kernel.offsets) + r * m * len(kernel.starts) + r
        positions = 1.0 + np.arange(len(J) * width, dtype=float).reshape(len(J), width)
        res, left, right, dlam, sizes = kernel.split_junction(positions)
        eq = lay.delta_at[J]
        f_rows.append((eq[:, None] + np.arange(r)).ravel())
        f_src.append(res.ravel())
        c_src.append(sizes.ravel())
        for o in kernel.offsets:  # arrow j+o moves with δ_{j+o} (left) and δ_{j+o−1} (right)
            _add(rows, cols, vals, lay.delta_at, eq, J + o, left[o], r)
            _add(rows, cols, vals, lay.delta_at, eq, J + o - 1, -right[o], r)
        for s in kernel.starts:
            _add(rows, cols, vals, lay.lam_at, eq, J + s, dlam[s], m)
        base = positions.size
    if m:
        T = lay.terms
        width = m + 2 * m * r * a + m
        positions = base + 1.0 + np.arange(len(T) * width, dtype=float).reshape(len(T), width)
        res, left, right, sizes = kernel.split_term(positions)
        eq = lay.lam_at[T]
        f_rows.append((eq[:, None] + np.arange(m)).ravel())
        f_src.append(res.ravel())
        c_src.append(sizes.ravel())
        for o in range(a):
            _add(rows, cols, vals, lay.delta_at, eq, T + o, left[o], r, m)
            _add(rows, cols, vals, lay.delta_at, eq, T + o - 1, -right[o], r, m)
        base += positions.size
    pin_rows, pin_terms = _pinned(kernel, lay)
    if len(pin_rows):  # the row λ = 0: a unit diagonal, read from the trailing 1
        rows.append(pin_rows)
        cols.append(pin_rows)
        vals.append(np.full(len(pin_rows), base + 1.0))
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    code = np.concatenate(vals)
    as_index = lambda parts: (np.concatenate(parts) - 1).astype(np.int64)  # noqa: E731
    pattern = _Pattern(rows, cols, (np.abs(code) - 1).astype(np.int64), np.sign(code),
                       np.concatenate(f_rows).astype(np.int64), as_index(f_src),
                       as_index(c_src), pin_rows, pin_terms, _Band.of(rows, cols, lay.size))
    for array in (*pattern[:-1], pattern.band.index):  # shared by every assembly
        array.flags.writeable = False
    return pattern


def _pinned(kernel, lay) -> tuple[np.ndarray, np.ndarray]:
    """The rows of the holonomic multipliers of the terms whose source node is fixed by the
    boundary data (``held`` per term, in order), and those terms.

    Their row ψ(α(g_t)) is a constant (checked to be 0) and they enter no junction, so the
    row becomes λ = 0 (docs/conventions.md §15).  A term's source node is free exactly when
    it is the node of a free junction, α(g_t) = β(g_{t−1}) with t − 1 a junction."""
    m, held = kernel.m, kernel.held
    if not held:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    free = set((lay.junctions + 1).tolist())
    fixed = [int(t) for t in lay.terms if int(t) not in free]
    rows = [lay.lam_index[t] + np.arange(m - held, m) for t in fixed]
    return (np.concatenate(rows).astype(np.int64) if rows else np.zeros(0, np.int64),
            np.array(fixed, np.int64))


#: the patterns of the layouts met lately, per kernel (a solve of N steps reuses its own)
_PATTERNS_KEPT = 8


def _pattern_of(kernel, lay) -> _Pattern:
    cache = kernel.__dict__.setdefault("_patterns", {})
    key = (lay.size, len(lay.junctions), len(lay.terms))
    if key not in cache:
        if len(cache) >= _PATTERNS_KEPT:
            cache.pop(next(iter(cache)))
        cache[key] = _pattern(kernel, lay)
    return cache[key]


def _assemble(kernel, lay, arrows, lam, p) -> _Assembled:
    """F, its Jacobian and the cancelling magnitudes at (arrows, λ): the window programs on
    every junction and term window, gathered into place by the layout's :class:`_Pattern`."""
    a, m = kernel.arity, kernel.m
    pattern = _pattern_of(kernel, lay)
    parts, worst_val, worst = [], -1.0, 0
    J = lay.junctions
    if len(J):
        windows = np.stack([arrows[J + o] for o in kernel.offsets], axis=1)
        lams = (np.stack([lam[J + s] for s in kernel.starts], axis=1) if m
                else np.zeros((len(J), len(kernel.starts), 0)))
        out = kernel.junction_values(windows, lams, p)
        parts.append(out.ravel())
        bad = np.max(np.abs(out[:, :kernel.rank]), axis=1)
        worst_val, worst = bad.max(), int(J[np.argmax(bad)]) + 1
    if m:
        T = lay.terms
        out = kernel.term_values(np.stack([arrows[T + o] for o in range(a)], axis=1), p)
        parts.append(out.ravel())
        bad = np.max(np.abs(out[:, :m]), axis=1)
        if bad.max() > worst_val:
            worst = int(T[np.argmax(bad)]) + 1
    parts.append(np.ones(1))
    flat = np.concatenate(parts)
    F = np.zeros(lay.size)
    cancel = np.zeros(lay.size)
    F[pattern.f_rows] = flat[pattern.f_src]
    cancel[pattern.f_rows] = flat[pattern.c_src]
    if len(pattern.pin_rows):  # the rows λ = 0 (docs/conventions.md §15, _pinned)
        F[pattern.pin_rows] = lam[pattern.pin_terms, m - kernel.held:].reshape(-1)
        cancel[pattern.pin_rows] = 0.0
    vals = pattern.sign * flat[pattern.src]
    return _Assembled(F, pattern.rows, pattern.cols, vals, worst, cancel, pattern.band)


def _rounding_floor(maps, lay, arrows, lam, state: _Assembled) -> np.ndarray:
    """The rounding floor of each equation: ε·E_i, E_i the running-error bound of its
    evaluation computed by the window kernels alongside it (:func:`symgroupoid.ir.rounding_error`)
    with the arrows' coordinates and the multipliers taken as rounded values themselves.

    So the floor counts every rounding of the evaluation — a junction residual
    r = X⃖[S](g_j) − X⃗[S](g_{j+1}) is the difference of two halves, each rounded — and, to
    first order, the residual's change when each stored coordinate a_m moves by ε·|a_m|
    (Σ_m |∂F_i/∂a_m|·|a_m|, propagated through the program with absolute values): an
    iterate cannot be held closer than that.  A residual scaled like 1/h² thus has a floor
    ~ N²·ε·|coordinates|, which a fixed tolerance would miss; a constraint on small chart
    coordinates computed from matrix entries near 1 feels the rounding of those entries
    although they do not move along the group (the rounding leaves the group), which the
    variations alone would miss.
    """
    with np.errstate(all="ignore"):
        return _EPS * np.nan_to_num(state.cancel, nan=np.inf)


def _add(rows, cols, vals, index, eq, targets, block, width, height=None):
    """Scatter ``block[w]`` (height × width) at equation row ``eq[w]`` and the unknowns of
    ``targets[w]`` in ``index`` (an array over positions, −1 where there is no unknown;
    targets that are not unknowns are skipped)."""
    height = block.shape[1] if height is None else height
    inside = (targets >= 0) & (targets < len(index))
    start = np.full(len(targets), -1)
    start[inside] = index[targets[inside]]
    keep = start >= 0
    if not keep.any():
        return
    start = start[keep]
    ii = eq[keep][:, None, None] + np.arange(height)[None, :, None]
    jj = start[:, None, None] + np.arange(width)[None, None, :]
    ii, jj = np.broadcast_arrays(ii, jj)
    rows.append(ii.ravel())
    cols.append(jj.ravel())
    vals.append(block[keep].reshape(-1))


def _update(maps, lay, arrows, lam, dz, r, m):
    arrows = arrows.copy()
    moved = lay.moved
    if len(moved):
        D = dz[lay.delta_at[moved][:, None] + np.arange(r)]
        H = maps.flow_at_target(arrows[moved], D)
        arrows[moved] = maps.multiply(arrows[moved], H)  # g_j · h(δ_j)
        arrows[moved + 1] = maps.multiply(maps.inverse(H), arrows[moved + 1])  # h⁻¹ · g_{j+1}
    lam = lam.copy()
    terms = lay.multiplied
    if m and len(terms):
        lam[terms] += dz[lay.lam_at[terms][:, None] + np.arange(m)]
    return arrows, lam


def _excess(F: np.ndarray, floor: np.ndarray, tol: float) -> float:
    """max_i |F_i| / (max(tol/ε, ROUNDING_FACTOR)·floor_i): at most 1 when converged.

    ``tol`` is relative, on the scale of ε: floor_i/ε is the size of the terms of F_i and of
    its sensitivity to the coordinates, so the criterion is invariant under a rescaling of
    the Lagrangian or of the step (an absolute tolerance accepts the initial path of
    equations whose terms are all below it)."""
    if not F.size:
        return 0.0
    with np.errstate(all="ignore"):
        ratio = np.abs(F) / (max(tol / _EPS, ROUNDING_FACTOR) * floor)
    ratio[F == 0] = 0.0  # an exact zero meets any floor, also a zero one (0/0)
    return float(np.nan_to_num(ratio, nan=np.inf).max())


# --- the iteration -----------------------------------------------------------------------------

#: the fast path hands over to the globalised iteration after this many consecutive damped
#: Newton steps (line-search length at most DAMPED_LENGTH)
MAX_DAMPED = 4
DAMPED_LENGTH = 0.25

#: at most this many trial regularisations μ per globalised iteration
MAX_CORRECTIONS = 40


@dataclass
class _Context:
    """What stays fixed during one solve."""

    owner: str
    kernel: WindowKernel
    cost: CostKernel
    lay: _Layout
    maps: _Maps
    p: np.ndarray
    tol: float
    tol_step: float
    max_iterations: int

    @property
    def r(self) -> int:
        return self.kernel.rank

    @property
    def m(self) -> int:
        return self.kernel.m

    def assemble(self, arrows, lam) -> _Assembled:
        with np.errstate(all="ignore"):
            return _assemble(self.kernel, self.lay, arrows, lam, self.p)

    def excess(self, arrows, lam, state: _Assembled) -> float:
        return _excess(state.F, _rounding_floor(self.maps, self.lay, arrows, lam, state),
                       self.tol)

    def update(self, arrows, lam, dz):
        return _update(self.maps, self.lay, arrows, lam, dz, self.r, self.m)


@dataclass
class _Run:
    """The iterations of one solve, across its phases: |F|∞ before each update, the count,
    whether the last update was below ``tol_step``, and the phases used."""

    history: list = field(default_factory=list)
    iterations: int = 0
    stalled: str = ""
    methods: list = field(default_factory=list)
    at_floor: int = 0  # consecutive steps taken only because |F| was at the rounding floor

    def record(self, state: _Assembled) -> float:
        norm = float(np.max(np.abs(state.F), initial=0.0))
        self.history.append(norm)
        progress_note(f"iteration {self.iterations}, |F|∞ = {norm:.2e}")
        return norm

    def step_taken(self, ctx: _Context, step: _Step, before: tuple) -> None:
        """Count the step and decide whether the iteration has stalled: an update below
        ``tol_step``·(1 + |λ|∞), one that changed no stored value, or a second step in a row
        that did not decrease |F| but was taken because |F| is at the rounding floor (where
        the comparison of residuals is noise) without meeting the criterion."""
        self.iterations += 1
        self.at_floor = self.at_floor + 1 if step.at_floor else 0
        scale = 1.0 + float(np.max(np.abs(step.lam), initial=0.0))
        size = step.length * float(np.max(np.abs(step.dz), initial=0.0))
        if size <= ctx.tol_step * scale:
            self.stalled = f"the update fell below tol_step = {ctx.tol_step:g}"
        elif np.array_equal(before[0], step.arrows) and np.array_equal(before[1], step.lam):
            self.stalled = "the update changed no stored value"
        elif self.at_floor >= 2:
            self.stalled = ("|F| stopped decreasing at the rounding floor: the floor estimate is "
                            "below the residual's actual noise there")


class _Step(NamedTuple):
    """An accepted step: the new iterate, its assembled system, the step length along dz,
    and whether it was taken only because |F| was at the rounding floor."""

    arrows: np.ndarray
    lam: np.ndarray
    state: _Assembled
    length: float
    dz: np.ndarray
    at_floor: bool = False


#: the fast path keeps its last this many iterates as restart points for the globalised
#: iteration (with the initial path: :func:`_restart_points`)
RESTART_CANDIDATES = 8


class _Handover(Exception):
    """The fast path gives up (no decrease, or damped steps only): the reason, and its last
    iterates (arrows, λ, state), oldest first."""

    def __init__(self, why: str, iterates: Sequence = ()):
        super().__init__(why)
        self.iterates = list(iterates)


def _check_budget(ctx: _Context, run: _Run, state: _Assembled, excess: float, arrows) -> None:
    if run.stalled:
        raise _divergence(ctx.owner, f"stalled: {run.stalled}", state, excess, run, arrows)
    if run.iterations >= ctx.max_iterations:
        raise _divergence(ctx.owner, f"did not converge in {ctx.max_iterations} iterations",
                          state, excess, run, arrows)


def _newton_direction(ctx: _Context, state: _Assembled, run: _Run, arrows,
                      rows=None, cols=None, vals=None) -> np.ndarray:
    """The solution dz of J·dz = −F (J given as COO triplets, default the Jacobian)."""
    rows = state.rows if rows is None else rows
    cols = state.cols if cols is None else cols
    vals = state.vals if vals is None else vals
    try:
        with np.errstate(all="ignore"):
            dz = _solve_banded(rows, cols, vals, ctx.lay.size, -state.F,
                               state.band if vals is state.vals else None)
    except np.linalg.LinAlgError as exc:
        raise _singular(ctx.owner, state, run.iterations, arrows) from exc
    if not np.isfinite(dz).all():
        raise _singular(ctx.owner, state, run.iterations, arrows)
    return dz


def _fast_newton(ctx: _Context, arrows, lam, state: _Assembled, run: _Run):
    """Structured Newton on the necessary conditions, backtracking on |F|₂²: quadratic
    convergence from a good guess.  Raises :class:`_Handover` when the line search finds no
    decrease, MAX_DAMPED consecutive steps were damped (far from a solution, where the
    globalised iteration does better) or the Jacobian is singular (constraints that the
    boundary data make dependent, whose multipliers the globalised iteration regularises)."""
    run.methods.append("Newton")
    damped = 0
    recent = collections.deque(maxlen=RESTART_CANDIDATES)
    while True:
        run.record(state)
        recent.append((arrows, lam, state))
        excess = ctx.excess(arrows, lam, state)
        if excess <= 1.0:
            return arrows, lam, state
        _check_budget(ctx, run, state, excess, arrows)
        try:
            dz = _newton_direction(ctx, state, run, arrows)
        except SingularJacobianError as exc:  # e.g. constraints made dependent by the ends
            raise _Handover(f"a singular Jacobian ({exc})", recent) from exc
        step = _line_search(ctx.kernel, ctx.lay, ctx.maps, arrows, lam, dz, state, ctx.p)
        if step is None:
            raise _Handover("found no decrease of |F| along the Newton direction (line search)",
                            recent)
        run.step_taken(ctx, step, (arrows, lam))
        arrows, lam, state = step.arrows, step.lam, step.state
        damped = damped + 1 if step.length <= DAMPED_LENGTH else 0
        if damped >= MAX_DAMPED and not run.stalled:
            recent.append((arrows, lam, state))
            raise _Handover(f"{MAX_DAMPED} damped Newton steps in a row", recent)


def _restart_points(ctx: _Context, initial: tuple, iterates: Sequence) -> list:
    """Where the globalised iteration starts after a handover, in the order to try: the
    fast path's iterate of least ℓ₁ merit φ_ν = Σ L + ν‖Φ‖₁ (ν = 1.1·max|λ| over the
    candidates, the globalised iteration's own first weight) when it is below the initial
    path's, then the initial path (the fallback: a descent from there reaches the minimum
    the initial path leads to even when the fast path wandered off towards another
    stationary point)."""
    lam_rows = _multiplier_rows(ctx.lay, ctx.m)
    nu = 1.1 * max((float(np.max(np.abs(lam), initial=0.0)) for _, lam, _ in iterates),
                   default=0.0)

    def merit(point) -> float:
        arrows, _, state = point
        value = ctx.cost(arrows, ctx.p) + nu * float(np.abs(state.F[lam_rows]).sum())
        return value if np.isfinite(value) else np.inf

    best = min(iterates, key=merit, default=None)
    if best is None or merit(best) >= merit(initial):
        return [initial[:2]]
    return [best[:2], initial[:2]]


# --- the globalised iteration: inertia-corrected Newton on the action ---------------------------

def _gradient_of_cost(ctx: _Context, state: _Assembled, lam) -> np.ndarray:
    """∇S in the unknowns (zero in the multiplier rows): the junction residuals are ∂/∂δ of
    Σ [L + λ·Φ], so ∇S = F_δ − (∂F_δ/∂λ)·λ."""
    z = np.zeros(ctx.lay.size)
    for t, k in ctx.lay.lam_index.items():
        z[k:k + ctx.m] = lam[t]
    g = state.F - _apply(state.rows, state.cols, state.vals, z, ctx.lay.size)
    g[_multiplier_rows(ctx.lay, ctx.m)] = 0.0
    return g


def _apply(rows, cols, vals, z, n) -> np.ndarray:
    """A·z for A given by COO triplets."""
    out = np.zeros(n)
    np.add.at(out, rows, vals * z[cols])
    return out


def _multiplier_rows(lay: _Layout, m: int) -> np.ndarray:
    if not m or not lay.lam_index:
        return np.zeros(0, int)
    return (np.array(list(lay.lam_index.values()))[:, None] + np.arange(m)).ravel()


def _variation_rows(lay: _Layout, r: int) -> np.ndarray:
    if not lay.delta_index:
        return np.zeros(0, int)
    return (np.array(list(lay.delta_index.values()))[:, None] + np.arange(r)).ravel()


def _convexified_direction(ctx: _Context, state: _Assembled, run: _Run, arrows, mu_last):
    """The step of the globalised iteration and its regularisation μ ≥ 0.

    With K the Jacobian (the Hessian of the Lagrangian Σ [L + λ·Φ] in the variations δ,
    bordered by the constraint gradients: the KKT matrix of min Σ L s.t. Φ = 0), K + μ·I_δ
    is required to have the inertia (n_δ, n_λ, 0) — then its δ-block is positive definite on
    the tangent space of the constraints, and the step is a descent direction of the merit
    function (Nocedal–Wright §18.3; Ipopt's inertia correction).  μ = 0 when K itself has it
    (the step is then Newton's); else μ starts at max(μ_min, μ_last/3) and grows ×8.  A zero
    eigenvalue (dependent constraint gradients) also puts −δ_c·I on the multiplier block.
    Returns (dz, μ, pᵀ(H + μI)p) with p the δ part of dz."""
    lay = ctx.lay
    dvars, lvars = _variation_rows(lay, ctx.r), _multiplier_rows(lay, ctx.m)
    n_lam, (plus, minus) = _bordering(ctx, state)
    expected = (len(dvars) + plus, n_lam + minus, 0)
    diag = state.rows == state.cols
    scale = float(np.mean(np.abs(state.vals[diag]))) if diag.any() else 1.0
    mu, delta_c = 0.0, 0.0
    for _ in range(MAX_CORRECTIONS):
        rows = np.concatenate([state.rows, dvars, lvars])
        cols = np.concatenate([state.cols, dvars, lvars])
        vals = np.concatenate([state.vals, np.full(len(dvars), mu),
                               np.full(len(lvars), -delta_c)])
        inertia = banded_inertia(rows, cols, vals, lay.size)
        if inertia is not None and tuple(inertia) == expected:
            dz = _newton_direction(ctx, state, run, arrows, rows, cols, vals)
            p = np.zeros(lay.size)
            p[dvars] = dz[dvars]
            return dz, mu, float(np.sum(vals * p[rows] * p[cols]))
        if inertia is not None and inertia.zero and len(lvars):
            delta_c = 1e-8 * scale
        mu = max(1e-8 * scale, mu_last / 3.0) if mu == 0.0 else 8.0 * mu
    raise _singular(ctx.owner, state, run.iterations, arrows)


def _merit(ctx: _Context, arrows, state: _Assembled, nu: float) -> float:
    """φ_ν = Σ L + ν·‖Φ‖₁ (the exact ℓ₁ penalty function)."""
    phi = state.F[_multiplier_rows(ctx.lay, ctx.m)]
    return ctx.cost(arrows, ctx.p) + nu * float(np.abs(phi).sum())


def _globalised(ctx: _Context, arrows, lam, run: _Run):
    """Inertia-corrected Newton (SQP) steps with a backtracking search on the ℓ₁ merit
    function φ_ν = Σ L + ν‖Φ‖₁: every step decreases φ_ν, so the iteration descends the
    action (seeks a local minimum of Σ L on Φ = 0, as an interior-point NLP solver does)
    instead of any root of F; near a minimum μ = 0 and the full Newton step is taken
    whenever it decreases |F|₂ too, which keeps the convergence quadratic."""
    run.methods.append("inertia-corrected Newton")
    state = ctx.assemble(arrows, lam)
    if not state.finite():
        raise _divergence(ctx.owner, "met a non-finite residual", state, np.inf, run, arrows)
    nu, mu_last = 0.0, 0.0
    lam_rows = _multiplier_rows(ctx.lay, ctx.m)
    while True:
        run.record(state)
        excess = ctx.excess(arrows, lam, state)
        if excess <= 1.0:
            return arrows, lam, state
        _check_budget(ctx, run, state, excess, arrows)
        dz, mu, curvature = _convexified_direction(ctx, state, run, arrows, mu_last)
        mu_last = mu
        g = _gradient_of_cost(ctx, state, lam)
        violation = float(np.abs(state.F[lam_rows]).sum())
        lam_next = np.abs(_current_multipliers(ctx, lam) + dz)[lam_rows]
        nu = max(nu, 1.1 * float(np.max(lam_next, initial=0.0)))
        if violation > 0:  # Nocedal–Wright (18.36), ρ = 0.1
            nu = max(nu, (float(g @ dz) + max(curvature, 0.0) / 2) / (0.9 * violation))
        slope = float(g @ dz) - nu * violation
        step = _merit_search(ctx, arrows, lam, dz, state, nu, slope, newton=mu == 0.0)
        if step is None:
            raise _divergence(ctx.owner, "found no decrease of the merit function Σ L + ν‖Φ‖₁ "
                              "along the inertia-corrected Newton direction (line search)",
                              state, excess, run, arrows)
        run.step_taken(ctx, step, (arrows, lam))
        arrows, lam, state = step.arrows, step.lam, step.state


def _current_multipliers(ctx: _Context, lam) -> np.ndarray:
    z = np.zeros(ctx.lay.size)
    for t, k in ctx.lay.lam_index.items():
        z[k:k + ctx.m] = lam[t]
    return z


def _merit_search(ctx: _Context, arrows, lam, dz, state: _Assembled, nu: float, slope: float,
                  newton: bool):
    """Backtracking until φ_ν decreases by the Armijo fraction 10⁻⁴·t·|slope|; a full
    unregularised Newton step is also taken when it decreases |F|₂² (near a solution, where
    the merit function would reject it: the Maratos effect), and any step that lands within
    the rounding floor.  None when no step length gives a decrease."""
    phi0 = _merit(ctx, arrows, state, nu)
    f0 = float(state.F @ state.F)
    length = 1.0
    for _ in range(MAX_HALVINGS):
        new_arrows, new_lam = ctx.update(arrows, lam, length * dz)
        trial = ctx.assemble(new_arrows, new_lam)
        if trial.finite():
            f = float(trial.F @ trial.F)
            accept = slope < 0 and \
                _merit(ctx, new_arrows, trial, nu) <= phi0 + 1e-4 * length * slope
            if newton and length == 1.0:
                accept = accept or f <= (1 - 1e-4) * f0
            if accept:
                return _Step(new_arrows, new_lam, trial, length, dz)
            if _within_floor(ctx.maps, ctx.lay, new_arrows, new_lam, trial, f):
                return _Step(new_arrows, new_lam, trial, length, dz, at_floor=True)
        length /= 2
    return None


def _within_floor(maps, lay, arrows, lam, state: _Assembled, f: float) -> bool:
    """|F|₂² ≤ Σ (ROUNDING_FACTOR·floor_i)²: the residual is at its rounding floor, where
    comparing two residuals is comparing noise."""
    floor = ROUNDING_FACTOR * _rounding_floor(maps, lay, arrows, lam, state)
    return f <= float(floor @ floor)


# --- the solve ---------------------------------------------------------------------------------

@reported(lambda step_equations, *args, **kwargs:
          f"{getattr(step_equations, 'name', 'system')}: boundary-value solve")
def solve_boundary_value(step_equations, start, end, steps: int, guess=None, params=None, *,
                         tol: float = 0.0, tol_step: float = 0.0,
                         max_iterations: int = 100,
                         minimum: bool = False) -> BoundaryValueSolution:
    """Solve a discrete two-point problem for the system behind ``step_equations``.

    First order: ``start`` and ``end`` are the end configurations (pair groupoid: points;
    Lie group: matrices; products: tuples).  Second order: ``start = (c₀, c₁)`` and
    ``end = (c_{N−1}, c_N)``, fixing the first and last arrows too.  ``guess``: N arrows
    (N, arrow_dim), optionally with multipliers as ``(arrows, multipliers)``; default: the
    geodesic interpolation of :func:`interpolate_arrows` (it avoids the Cayley chart's cut
    locus, so a half-turn between the ends is solved) and zero multipliers.

    Every input is checked before any solve, as :meth:`Simulator.simulate` checks its own
    (runtime/_validate.py): the counts, the parameters (by name, with their declared
    assumptions), the configurations (points: shape and finiteness; group parts: in the
    group, det +1), the guess.

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
    residual that a relative change ``tol`` of the terms and coordinates would leave.  It is
    invariant under a rescaling of the Lagrangian or of h, so it never accepts the initial
    path of equations that are merely small.  The iteration has stalled when an update changes no
    stored value, two steps in a row were taken at the floor without meeting the criterion,
    or (``tol_step`` > 0) an update falls below ``tol_step``·(1 + |λ|∞).
    Raises :class:`BoundaryValueDivergenceError` (a :class:`NewtonDivergenceError`, with the
    iterations and the residual history) when the iteration cap is reached, the iteration
    stalls or both phases' line searches find no decrease; :class:`SingularJacobianError`
    for a singular Jacobian; :class:`CutLocusError` when an arrow of the initial path is a
    half-turn.

    ``progress`` (keyword): report a solve taking longer than 2 s, with |F|∞ per iteration
    (see :mod:`symgroupoid._progress`).
    """
    system = _boundary_system(step_equations)
    owner = system.name
    G = system.groupoid
    a = len(_functions(system).slots)
    steps = integer_argument(steps, "steps", owner=owner)
    if steps < 2 * a:
        raise ShapeError(f"{owner}: a problem of order {a} needs at least {2 * a} "
                         f"steps, got {steps}")
    max_iterations = integer_argument(max_iterations, "max_iterations", owner=owner)
    tol = real_argument(tol, "tol", minimum=0.0, owner=owner)
    tol_step = real_argument(tol_step, "tol_step", minimum=0.0, owner=owner)
    if not isinstance(minimum, (bool, np.bool_)):
        raise ShapeError(f"{owner}: minimum must be True or False, got {minimum!r}")
    p, named = parameter_vector(system.parameters, params, owner=owner)
    m = len(_functions(system).constraints)
    data = _boundary(system, a, start, end)
    check_holonomic_nodes(system, [data.total] if a == 1 else [data.first, data.last],
                          [("start", "end")] if a == 1 else
                          [("start[0]", "start[1]"), ("end[0]", "end[1]")], p, owner=owner)
    arrows, lam = _initial(system, a, m, data, steps, guess)
    _check_cut_locus(system, arrows, "the initial path has" if guess is None
                     else "the guess has")
    kernel = window_kernel(system)
    ctx = _Context(owner, kernel, cost_kernel(system), _layout(steps, a, kernel.rank, m),
                   _maps(G), p, tol, tol_step, max_iterations)
    t0, run = time.perf_counter(), _Run()
    state = ctx.assemble(arrows, lam)
    if not state.finite():
        raise NewtonDivergenceError(
            f"{owner}: non-finite residual or Jacobian at the initial "
            f"{'path' if guess is None else 'guess'}, at configuration {state.worst}: the "
            f"Lagrangian or the constraints are not defined there", step=state.worst,
            residual_norm=float(np.nanmax(np.abs(state.F), initial=0.0)), iterate=arrows)
    found, inertia = _solve(ctx, arrows, lam, state, run, minimum)
    arrows, lam, state = found
    return BoundaryValueSolution(
        system, arrows, lam, data.configurations[0], named, run.iterations, run.history[-1],
        run.history, time.perf_counter() - t0, cost=ctx.cost(arrows, p),
        second_order=inertia, method=" → ".join(run.methods))


def _solve(ctx: _Context, arrows, lam, state: _Assembled, run: _Run, minimum: bool):
    """The fast path, then (on its failure, or for ``minimum`` at a non-minimum) the
    globalised iteration; returns ((arrows, λ, state), second_order): ``(inertia,)`` when it
    was computed, ``()`` when it is left for the solution to compute on request."""
    initial = (arrows, lam, state)
    try:
        found = _fast_newton(ctx, arrows, lam, state, run)
    except _Handover as why:
        found = _globalised_after(ctx, _restart_points(ctx, initial, why.iterates), run,
                                  str(why))
        return found, (_reduced_inertia(ctx, found[2]),)
    if not minimum:
        return found, ()
    inertia = _reduced_inertia(ctx, found[2])
    if not _is_minimum(inertia):
        found = _globalised_after(ctx, [initial[:2]], run, "it reached a stationary point "
                                  f"that is not a local minimum ({_describe(inertia)})")
        inertia = _reduced_inertia(ctx, found[2])
        if not _is_minimum(inertia):
            raise _divergence(ctx.owner, "found no local minimum: the globalised iteration "
                              f"reached a stationary point that is not one "
                              f"({_describe(inertia)})", found[2], 0.0, run, found[0])
    return found, (inertia,)


def _globalised_after(ctx: _Context, starts: list, run: _Run, why: str):
    """The globalised iteration from each of ``starts`` (arrows, λ) in turn until one
    converges; the next start is tried after a line search without decrease, a non-finite
    residual or a singular Jacobian, not after a stall (the update fell below ``tol_step``
    or stopped changing the iterate: the caller's criterion, or the rounding floor) nor at
    the iteration cap, which counts every start.  The last one's errors name why the fast
    path ended too."""
    for k, start in enumerate(starts):
        run.at_floor = 0
        try:
            return _globalised(ctx, *start, run)
        except (BoundaryValueDivergenceError, SingularJacobianError) as exc:
            if k + 1 < len(starts) and not run.stalled and \
                    run.iterations < ctx.max_iterations:
                why = (f"{why}; from its best iterate, the globalised iteration "
                       f"{_first_line(exc)}")
                continue
            exc.args = (f"{exc.args[0]} (after the Newton fast path {why})",) + exc.args[1:]
            raise


def _first_line(exc: Exception) -> str:
    """What went wrong, in the words of ``exc`` without its owner prefix or its numbers."""
    text = str(exc.args[0]) if exc.args else type(exc).__name__
    text = text.split(": ", 1)[-1]
    return text.split(";", 1)[0]


def _divergence(owner: str, why: str, state: _Assembled, excess: float, run: _Run,
                arrows) -> BoundaryValueDivergenceError:
    norm = float(np.max(np.abs(state.F), initial=0.0))
    return BoundaryValueDivergenceError(
        f"{owner}: boundary-value iteration {why}; after {run.iterations} iterations "
        f"|F|∞ = {norm:.3e}, worst at configuration {state.worst}, {excess:.1e} times the "
        f"accepted residual max(tol/ε, {ROUNDING_FACTOR:g})·rounding floor: not a solution",
        iterations=run.iterations, history=run.history, step=state.worst,
        residual_norm=norm, iterate=arrows)


def _singular(owner: str, state: _Assembled, it: int, arrows) -> SingularJacobianError:
    norm = float(np.max(np.abs(state.F), initial=0.0))
    return SingularJacobianError(
        f"{owner}: singular boundary-value Jacobian at iteration {it} "
        f"(|F|∞ = {norm:.3e}, worst at configuration {state.worst}); the boundary data may "
        "violate the constraints or the Lagrangian is not regular there",
        step=state.worst, residual_norm=norm, iterate=arrows)


def _line_search(kernel, lay, maps, arrows, lam, dz, state: _Assembled, p):
    """Backtracking on |F|₂²: the full Newton step when it decreases the residual enough
    (Armijo: by the fraction 10⁻⁴·t of it, t the step length; always so near a solution,
    where convergence stays quadratic), else the step halved, at most MAX_HALVINGS times.
    Backtracking stops at the rounding floor: a trial whose |F|₂² is within the floor's
    (Σ (ROUNDING_FACTOR·floor_i)², where the comparison of two residuals is rounding noise)
    is taken at once, and the convergence test decides.

    Returns the accepted :class:`_Step`, or None when no step length gave a decrease with
    finite values: the caller then does not carry on from
    an iterate that is worse than the last (a Newton direction that is not a descent
    direction of |F|₂² means the Jacobian is wrong or the values are not smooth there, e.g.
    an arrow near the chart's cut locus).
    """
    r, m = kernel.rank, kernel.m
    f0 = float(state.F @ state.F)
    length = 1.0
    for _ in range(MAX_HALVINGS):
        new_arrows, new_lam = _update(maps, lay, arrows, lam, length * dz, r, m)
        with np.errstate(all="ignore"):
            trial = _assemble(kernel, lay, new_arrows, new_lam, p)
        if trial.finite():
            f = float(trial.F @ trial.F)
            if f <= (1 - 1e-4 * length) * f0:
                return _Step(new_arrows, new_lam, trial, length, dz)
            if _within_floor(maps, lay, new_arrows, new_lam, trial, f):
                return _Step(new_arrows, new_lam, trial, length, dz, at_floor=True)
        length /= 2
    return None


# --- what was found: the cost and the second-order condition ------------------------------------

def _reduced_inertia(ctx: _Context, state: _Assembled) -> Inertia | None:
    """The inertia of the Hessian of the Lagrangian Σ [L + λ·Φ] restricted to the admissible
    variations tangent to the constraints, from the KKT matrix K (the symmetric part of the
    Jacobian at the solution, :func:`banded_inertia`): when K is nonsingular the constraint
    gradients have full rank and inertia(K) = inertia(ZᵀHZ) + (n_λ, n_λ, 0) (Z a basis of
    their null space; Gould 1985), so ZᵀHZ has pos(K) − n_λ positive and neg(K) − n_λ
    negative eigenvalues.  None when K is numerically singular (the reduced Hessian and the
    constraint rank are then not determined by the inertia alone)."""
    inertia = banded_inertia(state.rows, state.cols, state.vals, ctx.lay.size)
    n_lam, (plus, minus) = _bordering(ctx, state)
    if inertia is None or inertia.zero or inertia.negative < n_lam + minus \
            or inertia.positive < n_lam + plus:
        return None
    return Inertia(inertia.positive - n_lam - plus, inertia.negative - n_lam - minus, 0)


class _Shape(NamedTuple):
    """The layout and the multiplier count: what :func:`_reduced_inertia` reads of a solve."""

    lay: _Layout
    m: int


def _inertia_at(system, arrows: np.ndarray, lam: np.ndarray, p: np.ndarray
                ) -> Inertia | None:
    """:func:`_reduced_inertia` at a solution (arrows, λ) of ``system``, its KKT matrix
    assembled there."""
    kernel = window_kernel(system)
    lay = _layout(len(arrows), kernel.arity, kernel.rank, kernel.m)
    with np.errstate(all="ignore"):
        state = _assemble(kernel, lay, arrows, lam, p)
    return _reduced_inertia(_Shape(lay, kernel.m), state)


def _bordering(ctx: _Context, state: _Assembled) -> tuple[int, tuple[int, int]]:
    """The multiplier rows that border the Hessian (n_λ), and the signs of those that are
    decoupled — a row and column with nothing but a diagonal entry d, such as a multiplier
    fixed by a boundary condition (row λ = 0): each adds one eigenvalue of the sign of d,
    not a ± pair."""
    lam_rows = _multiplier_rows(ctx.lay, ctx.m)
    if not len(lam_rows):
        return 0, (0, 0)
    off = (state.rows != state.cols) & (state.vals != 0)
    touched = np.zeros(ctx.lay.size, bool)
    touched[state.rows[off]] = touched[state.cols[off]] = True
    alone = lam_rows[~touched[lam_rows]]
    diag = np.bincount(state.rows[~off & (state.rows == state.cols)],
                       weights=state.vals[~off & (state.rows == state.cols)],
                       minlength=ctx.lay.size)[alone]
    return len(lam_rows) - len(alone), (int((diag > 0).sum()), int((diag < 0).sum()))


def _is_minimum(inertia: Inertia | None) -> bool:
    return inertia is not None and inertia.negative == 0


def _describe(inertia: Inertia | None) -> str:
    if inertia is None:
        return "degenerate: the reduced Hessian is singular to rounding"
    if inertia.negative == 0:
        return "a strict local minimum"
    return (f"a saddle: the reduced Hessian has {inertia.negative} negative "
            f"eigenvalue{'s' if inertia.negative > 1 else ''}")
