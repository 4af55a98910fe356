"""The window and cost kernels of a system, and its numeric structure maps.

The window kernel evaluates the programs of :func:`~symgroupoid.equations.window_programs`
— the junction residual of the window action and its slot derivatives, and the constraints
of a term with theirs — for all windows of a trajectory in one call, compiled to C through
the same cffi build cache as the step kernels, or in NumPy (the same bits) without a
compiler.  The cost kernel evaluates the discrete cost Σ_k L_d; the structure maps evaluate
multiplication, inversion and the junction flow h(δ) ⊂ α⁻¹(β(g)) of the groupoid.
"""

from __future__ import annotations

import functools

import numpy as np

from ..._errors import ShapeError
from ...equations import cost_program, structure_program, window_programs
from ...ir import Program
from .._options import environment_backend
from .._programs import ProgramEvaluator


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
    return ProgramEvaluator(label, program, inputs, outputs, environment_backend(label))


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
        self.forced, self.n_inputs = programs.forced, programs.n_inputs
        self.n_stages = programs.n_stages
        self._junction = _vectorised(f"{system.name}_junction", programs.junction, "a",
                                     "junction")
        self._term = None
        if programs.term is not None:
            self._term = _vectorised(f"{system.name}_term", programs.term, "a", "term")
        self._stage = None
        if programs.stage is not None:
            self._stage = _vectorised(f"{system.name}_stage", programs.stage, "a", "stage")

    def junction(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray,
                 inputs: np.ndarray | None = None):
        """All junction blocks for W windows: windows (W, slots, arrow_dim), lams (W, starts, m),
        inputs (W, starts, n_inputs) for a system with inputs (docs/conventions.md §20)."""
        return self.junction_terms(windows, lams, params, inputs)[:4]

    def junction_terms(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray,
                       inputs: np.ndarray | None = None):
        """:meth:`junction`'s blocks and the rounding bound E of each residual (W, rank): its
        rounding error is at most about ε·E (:func:`symgroupoid.ir.rounding_error`); a system
        without internal stages (the stages' blocks are in :meth:`split_junction`)."""
        res, left, right, dlam, _, sizes = self.split_junction(
            self.junction_values(windows, lams, params, inputs))
        return res, left, right, dlam, sizes

    def junction_values(self, windows: np.ndarray, lams: np.ndarray, params: np.ndarray,
                        inputs: np.ndarray | None = None, zetas: np.ndarray | None = None
                        ) -> np.ndarray:
        """The junction program's outputs for W windows, one row each (see
        :meth:`split_junction`); ``inputs`` (W, starts, n_inputs): the inputs of each term of
        each window (None: none, for a system without inputs); ``zetas`` (W, starts,
        n_stages): the internal stages of each term (docs/conventions.md §22; None without)."""
        W = len(windows)
        if inputs is None:
            inputs = np.zeros((W, len(self.starts), 0))
        if zetas is None:
            zetas = np.zeros((W, len(self.starts), 0))
        if inputs.shape != (W, len(self.starts), self.n_inputs):
            raise ShapeError(f"{self.groupoid.name}: the window program takes the inputs of "
                             f"{len(self.starts)} terms of {self.n_inputs} values per window; "
                             f"got shape {inputs.shape} for {W} windows")
        if zetas.shape != (W, len(self.starts), self.n_stages):
            raise ShapeError(f"{self.groupoid.name}: the window program takes the stages of "
                             f"{len(self.starts)} terms of {self.n_stages} values per window; "
                             f"got shape {zetas.shape} for {W} windows")
        vals = np.hstack([windows.reshape(W, -1), lams.reshape(W, -1), zetas.reshape(W, -1),
                          inputs.reshape(W, -1), np.broadcast_to(params, (W, len(params)))])
        return self._junction(vals)  # (W, total)

    def split_junction(self, out: np.ndarray):
        """(residuals, left, right, dlam, dzeta, rounding bounds) as views of the outputs
        ``out`` (``dzeta[s]`` = ∂r/∂ζ_s, (W, rank, n_stages))."""
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
        dzeta, nz = {}, self.n_stages
        for s in self.starts:
            dzeta[s] = out[:, k:k + r * nz].reshape(W, r, nz)
            k += r * nz
        return res, left, right, dlam, dzeta, out[:, k:k + r]

    def stage_values(self, arrows: np.ndarray, zetas: np.ndarray, inputs: np.ndarray,
                     params: np.ndarray) -> np.ndarray:
        """The stage program's outputs for T terms (docs/conventions.md §22): arrows
        (T, arrow_dim), their stages (T, n_stages), their inputs (T, n_inputs); one row each
        (see :meth:`split_stage`)."""
        T = len(arrows)
        return self._stage(np.hstack([arrows.reshape(T, -1), zetas.reshape(T, -1),
                                      inputs.reshape(T, -1),
                                      np.broadcast_to(params, (T, len(params)))]))

    def split_stage(self, out: np.ndarray):
        """(stage rows, left, right, ∂/∂ζ, rounding bounds) as views of the outputs ``out``:
        rows (T, n), left and right (T, n, rank) along X⃖_c and X⃗_c on the term's arrow,
        ∂/∂ζ (T, n, n)."""
        T, n, r = len(out), self.n_stages, self.rank
        blk = out[:, n:n + 2 * n * r].reshape(T, n, 2, r)
        k = n + 2 * n * r
        return (out[:, :n], blk[:, :, 0, :], blk[:, :, 1, :],
                out[:, k:k + n * n].reshape(T, n, n), out[:, k + n * n:k + n * n + n])

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
        self.n_stages = len(_functions(system).stages)
        self._f = cost_program(system).numpy_function(["cost"], ["a"])

    def terms(self, arrows: np.ndarray, params: np.ndarray,
              zetas: np.ndarray | None = None) -> np.ndarray:
        """L on every window of ``arity`` consecutive arrows; with internal stages
        (docs/conventions.md §22) L(g_k, ζ_k), ``zetas`` (T, n_stages) the stages of every
        term (at the solution of the stage rows, L_d(g_k))."""
        T = len(arrows) - self.arity + 1
        windows = np.hstack([arrows[o:o + T] for o in range(self.arity)])
        if self.n_stages:
            windows = np.hstack([windows, np.asarray(zetas, float).reshape(T, -1)])
        values = np.hstack([windows, np.broadcast_to(params, (T, len(params)))])
        with np.errstate(all="ignore"):
            out = self._f(values.T)[0]
        return np.broadcast_to(np.asarray(out, float).reshape(-1), (T,))

    def __call__(self, arrows: np.ndarray, params: np.ndarray,
                 zetas: np.ndarray | None = None) -> float:
        return float(np.sum(self.terms(arrows, params, zetas)))


@functools.lru_cache(maxsize=8)
def cost_kernel(system) -> CostKernel:
    """The (cached) cost kernel of a system."""
    return CostKernel(system)


def _maps(G, parameters: tuple = (), values: tuple = ()) -> _Maps:
    """The numeric structure maps of the groupoid ``G`` at the parameter ``values`` (which
    a groupoid's maps may use: an Atiyah groupoid's connection); their functions are
    cached per groupoid and parameters, the values bound for each problem."""
    return _Maps(G, _map_functions(G, parameters), values)


@functools.lru_cache(maxsize=16)
def _map_functions(G, parameters: tuple) -> tuple:
    """The NumPy forms of the multiplication, the inverse and the junction flow of
    :func:`~symgroupoid.equations.structure_program`, each also reading ``p``."""
    program = structure_program(G, parameters)
    return (program.numpy_function(["multiply"], ["a", "b", "p"]),
            program.numpy_function(["inverse"], ["a", "p"]),
            program.numpy_function(["flow"], ["a", "d", "p"]))


class _Maps:
    """Multiplication, inversion and the junction flow of a groupoid, on rows of arrows: the
    NumPy forms of its :func:`~symgroupoid.equations.structure_program`."""

    def __init__(self, G, functions: tuple, values: tuple = ()):
        self.G = G
        self._p = np.asarray(values, float)
        self._mul, self._inv, self._flow = functions

    def multiply(self, A, B):
        return self._mul(A.T, B.T, self._p)[0].T

    def inverse(self, A):
        return self._inv(A.T, self._p)[0].T

    def flow_at_target(self, A, D):
        """h(δ) ⊂ α⁻¹(β(A)) for each row."""
        return self._flow(A.T, D.T, self._p)[0].T
