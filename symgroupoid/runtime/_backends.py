"""Two interchangeable kernels behind a :class:`~symgroupoid.runtime.Simulator`.

:class:`CKernel` calls the compiled C (through cffi); :class:`NumpyKernel` evaluates the
lambdified SymPy forms and runs the *same* Newton iteration in Python (same convergence
tests, same row scaling, LU with partial pivoting and singularity threshold, same status
codes), so both backends give the same trajectories up to rounding and fail alike.

Every array handed to C goes through :func:`real_vector` (shape and value checks of user
input, naming the argument) and then :func:`c_buffer` (exact dtype, C-contiguity and
length of the buffer itself): nothing reaches the C side that could make it read or write
outside a buffer.
"""

from __future__ import annotations

import ctypes
import dataclasses
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from .._arguments import (
    flag_argument,
    instance_argument,
    integer_argument,
    real_argument,
    real_array,
)
from .._errors import ShapeError
from ..codegen._emit import DEFAULT_OPTIONS, MAX_THREADS

OK, SINGULAR_JACOBIAN, NOT_CONVERGED, NON_FINITE, INVALID_ARGUMENT, STALLED, BRANCH_JUMP = range(7)

#: the texts of ``<prefix>_status_message`` (the generated C returns the same strings)
STATUS_MESSAGES = {
    OK: "converged",
    SINGULAR_JACOBIAN: "singular Jacobian: a pivot vanished relative to its equation, so the "
                       "step equations do not determine the next state (the discrete "
                       "Lagrangian is not regular here)",
    NOT_CONVERGED: "Newton's method reached its iteration cap (max_iterations updates) without "
                   "converging",
    NON_FINITE: "non-finite value (overflow to infinity, or NaN) in the residual, the "
                "Jacobian, the Newton step or the next state",
    INVALID_ARGUMENT: "invalid argument (null buffer, negative step count, capacity below "
                      "n_steps + 1, bad option or warm start, or non-finite input)",
    STALLED: "Newton's method stalled: its update is at the rounding noise of the solve while "
             "the residual stays above its rounding floor",
    BRANCH_JUMP: "branch jump: the step's solution lies far outside the region the last steps "
                 "predict (the nearby root of the step equations has disappeared; reduce the "
                 "step)",
}

#: the least motion the trust region of a step allows for (``<P>_TRUST_FLOOR``)
TRUST_FLOOR = 1e-2

#: largest value of a C ``int`` (Newton iteration caps and counts are ints in the kernel)
C_INT_MAX = 2**31 - 1


#: the unit roundoff of double precision (C's DBL_EPSILON)
EPSILON = float(np.finfo(float).eps)


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
    - when an update reduced |F|_∞ less than tenfold (Newton no longer converging fast) and
      every |F_i| is at most ``floor_factor``·(C_i + N_i), C_i = ε·Σ_j |J_ij||u_J,j| (J the
      last factored Jacobian, evaluated at u_J) and N_i its change under a move of every
      unknown by 4 ulps: stalled at the rounding floor of the unknowns and of F's own
      operations;
    - when an update that reduced |F|_∞ less than tenfold was a Newton update (its Jacobian
      factored at the iterate it started from) or rounding noise (below), and every
      |F_i| ≤ ``floor_factor``·ε·S_i, S_i the size of the terms F_i is computed from
      (:func:`symgroupoid.ir.term_magnitude`, the program's ``F_scale``): the residual is
      within the rounding of its own evaluation — a residual written in increments of
      positions far from the origin, (x_{k+1} − x_k)/h at |x| ~ 10⁴, cannot go below
      ε·|x|/h whatever the (small) unknowns;
    - when |F|_∞ ≤ ``tol_residual`` (absolute; 0, i.e. off, by default).

    Not converged: after ``max_iterations`` updates (status ``NOT_CONVERGED``, the iteration
    cap), or when an update that did not reduce |F|_∞ tenfold was at most 64ε times the ratio
    of the largest to the smallest pivot (rounding noise of an update solved with that
    factorisation) while |F| is above every floor — Newton cannot improve the iterate
    (``STALLED``).

    ``trust_factor`` (10 by default; 0 turns the check off): a step solved from an
    extrapolated guess is accepted only within the guess's trust region,
    |u − guess| ≤ trust_factor·(m + 0.01), |·| relative to each unknown (max_j |d_j|/(1 +
    |u_j|) at the last solution) and m the larger motion of the last two steps (from a run's
    fourth step on); otherwise
    the step is retried from ``step.prediction`` and, if that solution lies outside too, the
    run stops with ``BRANCH_JUMP`` (:class:`~symgroupoid.BranchJumpError`): when the root
    near the last steps disappears (a fold of the step map, the step no longer resolving the
    motion), Newton can converge to a far root of another branch, and the run would go on
    there with converged residuals.

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


@dataclass
class RawRun:
    """What a kernel's ``simulate`` returns: n steps from one state.

    ``states`` has n + 1 rows; after a failure at step k only rows 0..k are valid (row k
    is the known state of the failed step) and ``iterations[k]``, ``residual_norms[k]``
    describe the failed step.
    """

    states: np.ndarray  # (n_steps + 1, n_known)
    iterations: np.ndarray  # (n_steps,) int64
    residual_norms: np.ndarray  # (n_steps,)
    status: int
    failed_step: int  # -1 on success
    last_iterate: np.ndarray  # (n_unknown,)

    @property
    def completed(self) -> int:
        """Steps solved: all of them, or the index of the failed step."""
        return len(self.iterations) if self.status == OK else self.failed_step


@dataclass
class ChunkRun:
    """What a kernel's ``simulate_into`` returns (its states, iterations and residual norms
    are written into the caller's buffers).

    ``completed`` steps were solved; on failure ``failed_step`` (counted from the chunk's
    first state) is the step that failed and ``last_iterate`` its last Newton iterate.
    """

    status: int
    completed: int
    failed_step: int  # -1 on success
    last_iterate: np.ndarray  # (n_unknown,)


@dataclass
class BatchRun:
    """What a kernel's ``simulate_batch`` returns: B runs of n steps, every e-th state kept.

    Trajectory b has ``kept[b]`` valid rows ``states[b, :kept[b]]`` (state 0, every e-th
    state, and the last state reached); ``iterations[b, r - 1]`` and
    ``residual_norms[b, r - 1]`` summarise the steps between kept rows r − 1 and r (Newton
    iterations summed, largest residual norm).  Rows past ``kept[b]`` hold no data (only a
    failed run has them).  ``status[b]`` is the run's status; a failed run stopped at step
    ``failed_step[b]``, whose own iterations, residual norm and last Newton iterate are
    ``failed_iterations``, ``failed_residual_norms`` and ``last_iterate``.  A run stopped
    from outside (status :data:`INTERRUPTED`: the partial batch of an interrupted call) ends
    with the state it reached, step ``failed_step[b]``.
    """

    states: np.ndarray  # (B, rows, n_known)
    iterations: np.ndarray  # (B, rows - 1) C long long
    residual_norms: np.ndarray  # (B, rows - 1)
    kept: np.ndarray  # (B,) C long
    status: np.ndarray  # (B,) C int
    failed_step: np.ndarray  # (B,) C long, -1 when the run completed
    failed_iterations: np.ndarray  # (B,) C int
    failed_residual_norms: np.ndarray  # (B,)
    last_iterate: np.ndarray  # (B, n_unknown)


def batch_rows(steps: int, every: int) -> int:
    """Rows kept of a complete run: state 0, every ``every``-th state and the last."""
    return 1 + -(-steps // every)


#: the status of a batch run stopped from outside before its last step (Ctrl-C, a sweep's
#: timeout): not a kernel status (those are 0 … 9)
INTERRUPTED = 10


@dataclass
class RunCursor:
    """The Python twin of ``<prefix>_batch_cursor`` (one run of a batch advanced in
    installments), with the run's kept rows, status and failure data, so that one
    assignment of the cursor commits a run's progress."""

    warm: object
    known: np.ndarray
    done: int = 0
    last_kept: int = 0
    carry_iterations: int = 0
    carry_norm: float = 0.0
    kept: int = 0
    status: int = OK
    failed_step: int = -1
    failed_iterations: int = 0
    failed_residual_norm: float = 0.0
    last_iterate: np.ndarray | None = None


# --- checks at the C boundary ----------------------------------------------------------------

def real_vector(value, length: int, name: str, *, owner: str = "",
                finite: bool = False) -> np.ndarray:
    """``value`` as a fresh C-contiguous float64 vector of ``length`` entries.

    Accepts any real array-like of shape ``(length,)`` (integers and floats are converted
    exactly); anything else — another shape (a scalar, a (2, 4) array, 20 entries),
    complex, boolean or non-numeric entries, and non-finite entries when ``finite`` — is a
    :class:`ShapeError` naming ``name``.
    """
    where = f"{owner}: " if owner else ""
    arr = real_array(value, name, owner=owner)
    if arr.shape != (length,):
        raise ShapeError(f"{where}{name} must have shape ({length},), got shape {arr.shape}")
    out = np.array(arr, dtype=np.float64, order="C", copy=True)
    if finite and not np.isfinite(out).all():
        bad = np.flatnonzero(~np.isfinite(out)).tolist()
        raise ShapeError(f"{where}{name} must be finite; entries {bad} are NaN or infinite")
    return out


def c_buffer(ffi, array: np.ndarray, length: int, name: str, ctype: str = "double"):
    """A cffi pointer to ``array`` after checking it is exactly what C will access.

    ``array`` must be a NumPy array of the dtype matching ``ctype`` (``double``: float64,
    ``int``, ``long``, ``long long``: the platform C integers), C-contiguous and of exactly
    ``length`` elements; any other buffer is a :class:`ShapeError` (the C side would read or
    write past it).
    """
    dtype = {"double": np.dtype(np.float64), "int": np.dtype(np.intc),
             "long": np.dtype(ctypes.c_long), "long long": np.dtype(np.longlong)}[ctype]
    if not isinstance(array, np.ndarray):
        raise ShapeError(f"{name}: the C buffer must be a NumPy array, got "
                         f"{type(array).__name__}")
    if array.dtype != dtype:
        raise ShapeError(f"{name}: the C buffer must have dtype {dtype}, got {array.dtype}")
    if not array.flags.c_contiguous:
        raise ShapeError(f"{name}: the C buffer must be C-contiguous")
    if array.size != length:
        raise ShapeError(f"{name}: the C buffer must hold {length} elements, got "
                         f"{array.size}")
    return ffi.from_buffer(f"{ctype}[]", array)


def _run_buffers(states, iterations, residual_norms, n_known: int) -> int:
    """The rows R of the buffers of :meth:`_Kernel.simulate_into`, after checking them:
    ``states`` a C-contiguous float64 (R, n_known) array with R ≥ 1, ``iterations`` and
    ``residual_norms`` C-contiguous 1-D arrays of R − 1 C ``int`` and float64 entries."""
    for name, array, dtype, ndim in (("states", states, np.float64, 2),
                                     ("iterations", iterations, np.intc, 1),
                                     ("residual_norms", residual_norms, np.float64, 1)):
        if not (isinstance(array, np.ndarray) and array.dtype == np.dtype(dtype)
                and array.ndim == ndim and array.flags.c_contiguous
                and array.flags.writeable):
            raise ShapeError(f"{name}: a run buffer must be a writeable C-contiguous "
                             f"{ndim}-D NumPy array of dtype {np.dtype(dtype)}, got "
                             f"{_describe(array)}")
    if states.shape[1:] != (n_known,) or len(states) < 1:
        raise ShapeError(f"states: a run buffer has shape (R, {n_known}) with R >= 1, got "
                         f"{states.shape}")
    rows = len(states)
    for name, array in (("iterations", iterations), ("residual_norms", residual_norms)):
        if array.shape != (rows - 1,):
            raise ShapeError(f"{name}: a run buffer of {rows} states has shape "
                             f"({rows - 1},), got {array.shape}")
    return rows


def _describe(array) -> str:
    if not isinstance(array, np.ndarray):
        return type(array).__name__
    layout = "C-contiguous" if array.flags.c_contiguous else "not C-contiguous"
    access = "" if array.flags.writeable else ", read-only"
    return f"a {array.ndim}-D {layout} array of dtype {array.dtype}{access}"


class _Kernel:
    """Input checks shared by both kernels; subclasses implement the ``_raw`` methods."""

    name = ""
    n_u = n_k = n_p = 0
    #: largest step count of one ``simulate`` call
    max_steps = 2**53

    def _inputs(self, known, p, u=None) -> tuple[np.ndarray, ...]:
        arrays = [real_vector(known, self.n_k, "known"), real_vector(p, self.n_p, "p")]
        if u is not None:
            arrays.append(real_vector(u, self.n_u, "u"))
        return tuple(arrays)

    def residual(self, u, known, p) -> np.ndarray:
        """F(u; known, p), shape (n_unknowns,)."""
        known, p, u = self._inputs(known, p, u)
        return self._residual(u, known, p)

    def residual_jacobian(self, u, known, p) -> tuple[np.ndarray, np.ndarray]:
        """F and its exact Jacobian J[i, j] = ∂F_i/∂u_j."""
        known, p, u = self._inputs(known, p, u)
        return self._residual_jacobian(u, known, p)

    def predict(self, known, p) -> np.ndarray:
        """The first Newton guess of a step."""
        known, p = self._inputs(known, p)
        return self._predict(known, p)

    def next_knowns(self, u, known, p) -> np.ndarray:
        """The next known state from a solved step."""
        known, p, u = self._inputs(known, p, u)
        return self._next_knowns(u, known, p)

    def solve_step(self, known, p, u0, options: NewtonOptions):
        """Newton's method from ``u0``: (status, last iterate, iterations, residual norm).

        Non-finite ``known``, ``p`` or ``u0`` give ``INVALID_ARGUMENT`` (as in C).
        """
        known, p, u = self._inputs(known, p, u0)
        if not all(np.isfinite(a).all() for a in (known, p, u)):
            return INVALID_ARGUMENT, u, 0, float("nan")
        return self._solve_step(known, p, u, options)

    def simulate(self, known0, p, n_steps: int, options: NewtonOptions,
                 warm=None) -> RawRun:
        """``n_steps`` steps from ``known0``, continuing the Newton warm start ``warm``
        (from :meth:`warm_start`; None: a fresh start), which is updated in place."""
        known0, p = real_vector(known0, self.n_k, "known0"), real_vector(p, self.n_p, "p")
        n_steps = integer_argument(n_steps, "n_steps", maximum=self.max_steps)
        if not (np.isfinite(known0).all() and np.isfinite(p).all()):
            return RawRun(np.zeros((n_steps + 1, self.n_k)), np.zeros(n_steps, np.int64),
                          np.zeros(n_steps), INVALID_ARGUMENT, -1, np.zeros(self.n_u))
        return self._simulate(known0, p, n_steps, options,
                              self.warm_start() if warm is None else warm)

    def simulate_into(self, states: np.ndarray, iterations: np.ndarray,
                      residual_norms: np.ndarray, start: int, n_steps: int, p,
                      options: NewtonOptions, warm) -> ChunkRun:
        """``n_steps`` steps from row ``start`` of ``states``, written in place: rows
        start + 1 … start + n of ``states`` and entries start … start + n − 1 of
        ``iterations`` and ``residual_norms`` (a failure at step k writes rows up to
        start + k, and entry start + k describes the failed step).  The Newton warm start
        ``warm`` (from :meth:`warm_start`) is continued and updated, as by :meth:`simulate`:
        calls on consecutive row ranges give bitwise the states of one call.

        The buffers of a whole run: ``states`` float64 (R, n_known), ``iterations`` C
        ``int`` (R − 1,), ``residual_norms`` float64 (R − 1,), all C-contiguous, with
        0 ≤ start and start + n_steps ≤ R − 1; anything else is a :class:`ShapeError`
        (nothing outside these buffers is ever written).  A non-finite row ``start`` or
        ``p`` gives ``INVALID_ARGUMENT`` with nothing written.
        """
        rows = _run_buffers(states, iterations, residual_norms, self.n_k)
        p = real_vector(p, self.n_p, "p")
        start = integer_argument(start, "start", maximum=rows - 1)
        n_steps = integer_argument(n_steps, "n_steps", maximum=min(rows - 1 - start,
                                                                   self.max_steps))
        if not (np.isfinite(states[start]).all() and np.isfinite(p).all()):
            return ChunkRun(INVALID_ARGUMENT, 0, -1, np.zeros(self.n_u))
        if n_steps == 0:
            return ChunkRun(OK, 0, -1, np.zeros(self.n_u))
        return self._simulate_into(states, iterations, residual_norms, start, n_steps, p,
                                   options, self.warm_start() if warm is None else warm)

    def step_once(self, known: np.ndarray, p: np.ndarray, options: NewtonOptions
                  ) -> tuple[int, np.ndarray]:
        """One step from a fresh warm start, as ``simulate(known, p, 1, options)`` computes
        it (the same bits): (status, the next state).  For callers that have checked their
        inputs already (:meth:`Simulator.step`): ``known`` and ``p`` are C-contiguous
        float64 vectors of the right lengths; a non-finite one gives INVALID_ARGUMENT."""
        run = self.simulate(known, p, 1, options)
        return run.status, run.states[1]

    def _simulate_into(self, states, iterations, residual_norms, start: int, n_steps: int,
                       p, options: NewtonOptions, warm) -> ChunkRun:
        """:meth:`simulate_into` through :meth:`_simulate` (its states copied in)."""
        run = self._simulate(states[start].copy(), p, n_steps, options, warm)
        m = run.completed
        written = m if run.status == OK else m + 1
        states[start + 1:start + m + 1] = run.states[1:m + 1]
        iterations[start:start + written] = run.iterations[:written]
        residual_norms[start:start + written] = run.residual_norms[:written]
        return ChunkRun(run.status, m, run.failed_step, run.last_iterate)

    def simulate_batch(self, known0: np.ndarray, p: np.ndarray, n_steps: int, every: int,
                       options: NewtonOptions, threads: int | None = None) -> BatchRun:
        """B runs of ``n_steps`` steps from the rows of ``known0`` (B, n_known) with the
        rows of ``p`` (B, n_params), or one parameter vector ``p`` (n_params,) for all;
        every ``every``-th state kept (see :class:`BatchRun`).  Each run is computed
        exactly as :meth:`simulate` computes it.  ``threads``: ignored here (one run after
        the other); the compiled kernel shares runs among OpenMP threads."""
        known0, p = self._batch_inputs(known0, p)
        n_steps = integer_argument(n_steps, "n_steps", maximum=self.max_steps)
        every = integer_argument(every, "every", minimum=1, maximum=self.max_steps)
        out = self._batch_buffers(len(known0), n_steps, every)
        cursors = self.batch_cursors(len(known0))
        self.batch_until(cursors, known0, p, n_steps, every, n_steps, options, out, threads)
        return out

    def _batch_inputs(self, known0, p) -> tuple[np.ndarray, np.ndarray]:
        known0 = np.ascontiguousarray(known0, dtype=np.float64)
        p = np.ascontiguousarray(p, dtype=np.float64)
        if known0.ndim != 2 or known0.shape[1] != self.n_k:
            raise ShapeError(f"known0 must have shape (B, {self.n_k}), got {known0.shape}")
        if p.shape not in ((self.n_p,), (len(known0), self.n_p)):
            raise ShapeError(f"p must have shape ({self.n_p},) or ({len(known0)}, "
                             f"{self.n_p}), got {p.shape}")
        return known0, p

    def _batch_buffers(self, n_batch: int, n_steps: int, every: int) -> BatchRun:
        """Zeroed arrays of a batch, of the C types ``<prefix>_simulate_batch`` writes."""
        rows = batch_rows(n_steps, every)
        long = np.dtype(ctypes.c_long)
        return BatchRun(
            np.empty((n_batch, rows, self.n_k)), np.zeros((n_batch, rows - 1), np.longlong),
            np.zeros((n_batch, rows - 1)), np.zeros(n_batch, long),
            np.zeros(n_batch, np.intc), np.full(n_batch, -1, long),
            np.zeros(n_batch, np.intc), np.zeros(n_batch), np.zeros((n_batch, self.n_u)))

    # --- a batch in installments (the logic of <prefix>_simulate_batch_until) ---------------
    def batch_cursors(self, n_batch: int) -> list:
        """Fresh cursors of ``n_batch`` runs for :meth:`batch_until`."""
        return [None] * n_batch

    def batch_until(self, cursors, known0: np.ndarray, p: np.ndarray, n_steps: int,
                    every: int, until: int, options: NewtonOptions, out: BatchRun,
                    threads: int | None = None) -> None:
        """Advance the runs of ``out`` (checked inputs, :meth:`_batch_buffers`) to step
        min(until, n_steps) from their ``cursors``; called again with a larger ``until``
        they continue, bitwise as one call of ``n_steps``.  Each run's progress is
        committed by one assignment of its cursor (a KeyboardInterrupt between two runs
        leaves every run at a consistent step)."""
        for b in range(len(known0)):
            c = cursors[b]
            if c is not None and c.status != OK:
                continue
            c = self._run_until(c, known0[b], p[b] if p.ndim == 2 else p, n_steps, every,
                                until, options, out, b)
            cursors[b] = c
        self.batch_sync(cursors, out)

    def batch_sync(self, cursors, out: BatchRun) -> None:
        """The kept rows, status and failure data of ``out`` from the cursors."""
        for b, c in enumerate(cursors):
            if c is None:
                continue
            out.kept[b], out.status[b], out.failed_step[b] = c.kept, c.status, c.failed_step
            out.failed_iterations[b] = c.failed_iterations
            out.failed_residual_norms[b] = c.failed_residual_norm
            if c.last_iterate is not None:
                out.last_iterate[b] = c.last_iterate

    def batch_reached(self, cursors, out: BatchRun) -> dict:
        """Per run (arrays over the batch): ``done`` (the step reached), ``last_kept``,
        ``carry_iterations``, ``carry_norm`` and ``known`` (the state reached)."""
        n = len(cursors)
        fields = {"done": np.zeros(n, np.int64), "last_kept": np.zeros(n, np.int64),
                  "carry_iterations": np.zeros(n, np.int64), "carry_norm": np.zeros(n),
                  "known": np.zeros((n, self.n_k))}
        for b, c in enumerate(cursors):
            if c is not None:
                for name, array in fields.items():
                    array[b] = getattr(c, name)
        return fields

    def _run_until(self, c: RunCursor | None, known0, p, n_steps: int, every: int,
                   until: int, options: NewtonOptions, out: BatchRun, b: int) -> RunCursor:
        """Run b from its cursor (None: a fresh start) to min(until, n_steps), on a copy of
        the cursor (returned); states are written at rows from ``c.kept`` on."""
        if c is None:
            if not (np.isfinite(known0).all() and np.isfinite(p).all()):
                return RunCursor(None, known0.copy(), status=INVALID_ARGUMENT)
            out.states[b, 0] = known0
            c = RunCursor(self.warm_start(), known0.copy(), kept=1)
        else:
            c = dataclasses.replace(c, warm=self.copy_warm(c.warm))
        until = min(until, n_steps)
        while c.done < until:
            n = min(until - c.done, 1 << 14)
            run = self.simulate(c.known, p, n, options, c.warm)
            if run.status == INVALID_ARGUMENT:
                c.status = run.status
                return c
            for j in range(1, run.completed + 1):
                k = c.done + j
                c.carry_iterations += int(run.iterations[j - 1])
                c.carry_norm = max(c.carry_norm, float(run.residual_norms[j - 1]))
                if k % every == 0 or k == n_steps:
                    r = c.kept
                    out.states[b, r] = run.states[j]
                    out.iterations[b, r - 1] = c.carry_iterations
                    out.residual_norms[b, r - 1] = c.carry_norm
                    c.kept, c.last_kept, c.carry_iterations, c.carry_norm = r + 1, k, 0, 0.0
            if run.status != OK:
                s = c.done + run.failed_step
                if s != c.last_kept:
                    r = c.kept
                    out.states[b, r] = run.states[run.failed_step]
                    out.iterations[b, r - 1] = c.carry_iterations
                    out.residual_norms[b, r - 1] = c.carry_norm
                    c.kept = r + 1
                c.status, c.failed_step = run.status, s
                c.failed_iterations = int(run.iterations[run.failed_step])
                c.failed_residual_norm = float(run.residual_norms[run.failed_step])
                c.last_iterate = run.last_iterate
                return c
            c.done += n
            c.known = run.states[n].copy()
        return c

    def copy_warm(self, warm):
        """An independent copy of a warm start."""
        return dataclasses.replace(warm)


class CKernel(_Kernel):
    """The compiled kernel of a step (a cffi extension module)."""

    name = "c"

    def __init__(self, module, prefix: str, n_unknowns: int, n_knowns: int,
                 n_parameters: int | None = None):
        self.module, self.ffi, self.lib = module, module.ffi, module.lib
        self.prefix, self.n_u, self.n_k = prefix, n_unknowns, n_knowns
        self.n_p = int(getattr(self.lib, f"{prefix.upper()}_N_PARAMETERS")) \
            if n_parameters is None else n_parameters
        self._f = {n: getattr(self.lib, f"{prefix}_{n}") for n in (
            "residual", "residual_jacobian", "predict", "next_knowns", "solve_step",
            "simulate", "reconstruct")}
        self._warm_type = self.ffi.typeof(f"{prefix}_warm_start *")
        self._stepper = None  # stepper(), made on first use
        self.max_steps = min(2**53, 2 ** (8 * self.ffi.sizeof("long") - 1) - 2)
        sizes = {"UNKNOWNS": n_unknowns, "KNOWNS": n_knowns, "EQUATIONS": n_unknowns,
                 "PARAMETERS": self.n_p}
        for what, n in sizes.items():
            compiled = int(getattr(self.lib, f"{prefix.upper()}_N_{what}"))
            if compiled != n:
                raise ShapeError(f"{prefix}: the compiled kernel has {compiled} {what.lower()}, "
                                 f"the step {n}")

    @property
    def openmp(self) -> bool:
        """Whether the module was built with OpenMP (``simulate_batch`` uses threads)."""
        return "-fopenmp" in getattr(self, "flags", ())

    def simulate_batch(self, known0: np.ndarray, p: np.ndarray, n_steps: int, every: int,
                       options: NewtonOptions, threads: int | None = None) -> BatchRun:
        """:meth:`_Kernel.simulate_batch` in one call of ``<prefix>_simulate_batch``, the
        runs shared among ``threads`` OpenMP threads (None: the OpenMP default, all cores)
        when the module was built with ``-fopenmp``."""
        fn = getattr(self.lib, f"{self.prefix}_simulate_batch", None)
        if fn is None:  # a module built before the batched entry point existed
            return super().simulate_batch(known0, p, n_steps, every, options, threads)
        known0, p = self._batch_inputs(known0, p)
        n_steps = integer_argument(n_steps, "n_steps", maximum=self.max_steps)
        every = integer_argument(every, "every", minimum=1, maximum=self.max_steps)
        threads = 0 if threads is None else integer_argument(threads, "threads", minimum=1,
                                                             maximum=MAX_THREADS)
        B = len(known0)
        out = self._batch_buffers(B, n_steps, every)
        if B == 0:
            return out
        rows = out.states.shape[1]
        status = fn(
            B, self._buf(known0, B * self.n_k, "known0"),
            self._buf(p, p.size, "p"), 0 if p.ndim == 1 else self.n_p, n_steps, every,
            self._options(options), self._buf(out.states, B * rows * self.n_k, "states"), rows,
            self._buf(out.iterations if rows > 1 else np.zeros(1, np.longlong),
                      max(B * (rows - 1), 1), "iterations", "long long"),
            self._buf(out.residual_norms if rows > 1 else np.zeros(1),
                      max(B * (rows - 1), 1), "residual_norms"),
            self._buf(out.kept, B, "kept", "long"), self._buf(out.status, B, "status", "int"),
            self._buf(out.failed_step, B, "failed_step", "long"),
            self._buf(out.failed_iterations, B, "failed_iterations", "int"),
            self._buf(out.failed_residual_norms, B, "failed_residual_norm"),
            self._buf(out.last_iterate, B * self.n_u, "last_iterate"), threads)
        if status != OK:
            raise ValueError(f"{self.prefix}_simulate_batch: {STATUS_MESSAGES[int(status)]}")
        return out

    def step_once(self, known: np.ndarray, p: np.ndarray, options: NewtonOptions
                  ) -> tuple[int, np.ndarray]:
        """:meth:`_Kernel.step_once` by :meth:`stepper`'s function."""
        return self.stepper()(known, p, options)

    def stepper(self):
        """A function (known, p, options) → (status, next state) making one
        ``<prefix>_simulate`` call of one step with the least Python around it (the
        per-call cost of a control loop): the caller's arrays are passed as they are
        (C-contiguous float64 vectors of the kernel's lengths, checked by the caller), a
        fresh start is a NULL warm start, the last options' C struct and the last parameter
        vector's C view are kept, the iteration count and residual norm (not read: a
        failed step is run again by the caller to report it) go to a block of the calling
        thread, and the failed step and last iterate are not asked for (NULL)."""
        if self._stepper is None:
            self._stepper = _one_step_caller(self)
        return self._stepper

    def _until_entry(self):
        """``<prefix>_simulate_batch_until``, or None in a module built before it existed
        (then batches in installments run through :meth:`simulate` in Python)."""
        return getattr(self.lib, f"{self.prefix}_simulate_batch_until", None)

    def batch_cursors(self, n_batch: int):
        """Fresh (zeroed) ``<prefix>_batch_cursor`` structs of ``n_batch`` runs."""
        if self._until_entry() is None:
            return super().batch_cursors(n_batch)
        return self.ffi.new(f"{self.prefix}_batch_cursor[]", max(n_batch, 1))

    def batch_until(self, cursors, known0: np.ndarray, p: np.ndarray, n_steps: int,
                    every: int, until: int, options: NewtonOptions, out: BatchRun,
                    threads: int | None = None) -> None:
        """:meth:`_Kernel.batch_until` in one call of ``<prefix>_simulate_batch_until``
        (which writes the kept rows, status and failure data of ``out`` itself; a
        KeyboardInterrupt is seen only after the call returns)."""
        fn = self._until_entry()
        if fn is None:
            return super().batch_until(cursors, known0, p, n_steps, every, until, options,
                                       out, threads)
        B = len(known0)
        if B == 0:
            return None
        if not (isinstance(cursors, self.ffi.CData)
                and self.ffi.typeof(cursors) is self.ffi.typeof(f"{self.prefix}_batch_cursor[]")
                and len(cursors) >= B):
            raise ShapeError(f"{self.prefix}: the cursors must come from batch_cursors({B})")
        threads = 0 if threads is None else integer_argument(threads, "threads", minimum=1,
                                                             maximum=MAX_THREADS)
        rows = out.states.shape[1]
        status = fn(
            B, cursors, self._buf(known0, B * self.n_k, "known0"), self._buf(p, p.size, "p"),
            0 if p.ndim == 1 else self.n_p, n_steps, every, until, self._options(options),
            self._buf(out.states, B * rows * self.n_k, "states"), rows,
            self._buf(out.iterations if rows > 1 else np.zeros(1, np.longlong),
                      max(B * (rows - 1), 1), "iterations", "long long"),
            self._buf(out.residual_norms if rows > 1 else np.zeros(1),
                      max(B * (rows - 1), 1), "residual_norms"),
            self._buf(out.kept, B, "kept", "long"), self._buf(out.status, B, "status", "int"),
            self._buf(out.failed_step, B, "failed_step", "long"),
            self._buf(out.failed_iterations, B, "failed_iterations", "int"),
            self._buf(out.failed_residual_norms, B, "failed_residual_norm"),
            self._buf(out.last_iterate, B * self.n_u, "last_iterate"), threads)
        if status != OK:
            raise ValueError(f"{self.prefix}_simulate_batch_until: "
                             f"{STATUS_MESSAGES[int(status)]}")
        return None

    def batch_sync(self, cursors, out: BatchRun) -> None:
        if not isinstance(cursors, self.ffi.CData):
            super().batch_sync(cursors, out)

    def batch_reached(self, cursors, out: BatchRun) -> dict:
        """The cursors' fields as NumPy arrays over the runs (views of the structs)."""
        if not isinstance(cursors, self.ffi.CData):
            return super().batch_reached(cursors, out)
        ctype = self.ffi.typeof(f"{self.prefix}_batch_cursor")
        names = ("done", "last_kept", "carry_iterations", "carry_norm", "known")
        formats = [np.dtype(ctypes.c_long), np.dtype(ctypes.c_long),
                   np.dtype(ctypes.c_longlong), np.float64, (np.float64, (self.n_k,))]
        dtype = np.dtype({"names": list(names), "formats": formats,
                          "offsets": [self.ffi.offsetof(ctype, n) for n in names],
                          "itemsize": self.ffi.sizeof(ctype)})
        n = len(out.kept)
        view = np.frombuffer(self.ffi.buffer(cursors, n * dtype.itemsize), dtype=dtype)
        return {name: view[name].copy() for name in names}

    def copy_warm(self, warm):
        self._check_warm(warm)
        copy = self.warm_start()
        self.ffi.memmove(copy, warm, self.ffi.sizeof(self._warm_type.item))
        return copy

    def _options(self, options: NewtonOptions):
        opts = self.ffi.new(f"{self.prefix}_options *")
        opts.tol_residual = options.tol_residual
        opts.floor_factor = options.floor_factor
        opts.tol_step = options.tol_step
        opts.max_iterations = int(options.max_iterations)
        opts.extrapolate = int(bool(options.extrapolate))
        opts.trust_factor = options.trust_factor
        return opts

    def _buf(self, array, length, name, ctype="double"):
        return c_buffer(self.ffi, array, length, f"{self.prefix}: {name}", ctype)

    def warm_start(self):
        """A zeroed ``<prefix>_warm_start`` (a fresh run)."""
        return self.ffi.new(self._warm_type)

    def _check_warm(self, warm) -> None:
        """A :class:`ShapeError` unless ``warm`` is a ``<prefix>_warm_start *`` (any other
        object, cdata of another type included, would be read and written by C)."""
        if not (isinstance(warm, self.ffi.CData) and self.ffi.typeof(warm) is self._warm_type):
            raise ShapeError(f"{self.prefix}: the warm start must be a "
                             f"{self._warm_type.cname} from warm_start(), got {warm!r}")

    def _simulate_into(self, states, iterations, residual_norms, start: int, n_steps: int,
                       p, options: NewtonOptions, warm) -> ChunkRun:
        """One ``<prefix>_simulate`` call writing straight into the run's buffers: its
        state buffer starts at row ``start`` and holds the capacity = R − start rows left
        (its iterations and residual norms the R − 1 − start entries left), exactly what
        the arrays hold from there on; row ``start`` is the call's initial state."""
        self._check_warm(warm)
        rows = len(states)
        base = self._buf(states, rows * self.n_k, "states") + start * self.n_k
        last = np.zeros(self.n_u)
        failed = self.ffi.new("long *")
        status = int(self._f["simulate"](
            base, self._buf(p, self.n_p, "p"), n_steps, self._options(options), warm, base,
            rows - start, self._buf(iterations, rows - 1, "iterations", "int") + start,
            self._buf(residual_norms, rows - 1, "residual_norms") + start, failed,
            self._buf(last, self.n_u, "last_iterate")))
        k = int(failed[0])
        return ChunkRun(status, n_steps if status == OK else max(k, 0), k, last)

    def _residual(self, u, known, p) -> np.ndarray:
        F = np.empty(self.n_u)
        self._f["residual"](self._buf(u, self.n_u, "u"), self._buf(known, self.n_k, "known"),
                            self._buf(p, self.n_p, "p"), self._buf(F, self.n_u, "F"))
        return F

    def _residual_jacobian(self, u, known, p) -> tuple[np.ndarray, np.ndarray]:
        F, J = np.empty(self.n_u), np.empty((self.n_u, self.n_u))
        self._f["residual_jacobian"](
            self._buf(u, self.n_u, "u"), self._buf(known, self.n_k, "known"),
            self._buf(p, self.n_p, "p"), self._buf(F, self.n_u, "F"),
            self._buf(J, self.n_u * self.n_u, "J"))
        return F, J

    def _predict(self, known, p) -> np.ndarray:
        u = np.empty(self.n_u)
        self._f["predict"](self._buf(known, self.n_k, "known"), self._buf(p, self.n_p, "p"),
                           self._buf(u, self.n_u, "u"))
        return u

    def _next_knowns(self, u, known, p) -> np.ndarray:
        out = np.empty(self.n_k)
        self._f["next_knowns"](self._buf(u, self.n_u, "u"), self._buf(known, self.n_k, "known"),
                               self._buf(p, self.n_p, "p"),
                               self._buf(out, self.n_k, "known_next"))
        return out

    def _solve_step(self, known, p, u, options: NewtonOptions):
        it, rn = self.ffi.new("int *"), self.ffi.new("double *")
        status = self._f["solve_step"](
            self._buf(known, self.n_k, "known"), self._buf(p, self.n_p, "p"),
            self._options(options), self._buf(u, self.n_u, "u"), it, rn)
        return int(status), u, int(it[0]), float(rn[0])

    def _simulate(self, known0, p, n_steps: int, options: NewtonOptions, warm) -> RawRun:
        self._check_warm(warm)
        rows = n_steps + 1
        states = np.empty((rows, self.n_k))
        iterations = np.zeros(max(n_steps, 1), dtype=np.intc)
        norms = np.zeros(max(n_steps, 1))
        last = np.zeros(self.n_u)
        failed = self.ffi.new("long *")
        status = self._f["simulate"](
            self._buf(known0, self.n_k, "known0"), self._buf(p, self.n_p, "p"), n_steps,
            self._options(options), warm, self._buf(states, rows * self.n_k, "states"), rows,
            self._buf(iterations, max(n_steps, 1), "iterations", "int"),
            self._buf(norms, max(n_steps, 1), "residual_norms"), failed,
            self._buf(last, self.n_u, "last_iterate"))
        return RawRun(states, iterations[:n_steps].astype(np.int64), norms[:n_steps],
                      int(status), int(failed[0]), last)


def _one_step_caller(kernel: CKernel):
    """:meth:`CKernel.stepper`'s function (its state in closure cells, the fastest Python
    has): one call of ``<prefix>_step`` (four arguments), or, in a module built before that
    entry point existed, of ``<prefix>_simulate`` for one step."""
    ffi, n_k = kernel.ffi, kernel.n_k
    from_buffer, empty = ffi.from_buffer, np.empty
    #: (options, their C struct, p, its C view) of the last call, and (the last state
    #: returned, its C view), each replaced as a whole (tuples: another thread never sees
    #: half of one); a C view keeps its array alive, so `is` identifies it surely
    last = [(None, None, None, None)]
    returned = [(None, None)]
    step_function = getattr(kernel.lib, f"{kernel.prefix}_step", None)

    def views(known, p, options):
        held = last[0]
        if held[0] is not options or held[2] is not p:
            held = last[0] = (options, kernel._options(options) if held[0] is not options
                              else held[1], p, from_buffer("double[]", p))
        previous = returned[0]
        return held, (previous[1] if previous[0] is known else from_buffer("double[]", known))

    if step_function is not None:
        def step(known: np.ndarray, p: np.ndarray, options: NewtonOptions):
            held = last[0]  # views(), inline
            if held[0] is not options or held[2] is not p:
                held = views(known, p, options)[0]
            previous = returned[0]
            at = previous[1] if previous[0] is known else from_buffer("double[]", known)
            after = empty(n_k)
            view = from_buffer("double[]", after)
            status = step_function(at, held[3], held[1], view)
            returned[0] = (after, view)
            return status, after

        return step

    simulate, null, get_ident = kernel._f["simulate"], ffi.NULL, threading.get_ident
    blocks: dict = {}  # thread id → (iterations, residual norm) outputs of that thread

    def step_by_simulate(known: np.ndarray, p: np.ndarray, options: NewtonOptions):
        block = blocks.get(get_ident())
        if block is None:
            block = blocks[get_ident()] = (ffi.new("int[1]"), ffi.new("double[1]"))
        held, at = views(known, p, options)
        out = empty((2, n_k))
        view = from_buffer("double[]", out)
        status = simulate(at, held[3], 1, held[1], null, view, 2, block[0], block[1], null,
                          null)
        after = out[1]
        returned[0] = (after, view + n_k)
        return status, after

    return step_by_simulate


def norm_inf(v: np.ndarray) -> float:
    """max |v_i|, or a non-finite value if any entry is NaN or infinite (as the C kernel)."""
    a = np.abs(np.asarray(v, dtype=float))
    if a.size == 0:
        return 0.0
    bad = ~np.isfinite(a)
    if bad.any():
        return float(a[np.argmax(bad)])
    return float(a.max())


@dataclass
class LUFactors:
    """The factors of :func:`lu_factor`: scaled, permuted and eliminated A (L below the
    diagonal, U on and above), row exponents, pivot rows and reciprocal pivots."""

    A: np.ndarray
    e: np.ndarray
    perm: np.ndarray
    inv: np.ndarray


def lu_factor(A: np.ndarray) -> tuple[int, LUFactors | None]:
    """(status, factors) exactly as ``<prefix>_lu_factor`` in the C kernel.

    Every row of A is scaled by the power of two 2^-e bringing the row's largest |entry|
    into [1/2, 1) (exact), so singularity is judged relative to each equation; then LU with
    partial pivoting (reciprocal pivots, zero multipliers skipped).  The status is
    ``SINGULAR_JACOBIAN`` for a zero row or a pivot not above n·ε, ``NON_FINITE`` when a
    value is infinite or NaN (overflow), else ``OK``.
    """
    A = np.array(A, dtype=float)
    n = len(A)
    tiny = n * EPSILON
    e = np.zeros(n, dtype=np.int64)
    with np.errstate(all="ignore"):
        for i in range(n):
            m = norm_inf(A[i])
            if not np.isfinite(m):
                return NON_FINITE, None
            if m == 0.0:
                return SINGULAR_JACOBIAN, None
            e[i] = int(np.frexp(m)[1])
            A[i] = A[i] * np.ldexp(1.0, -e[i]) if -1000 < e[i] < 1000 else np.ldexp(A[i],
                                                                                  -e[i])
        # entries now lie in [-1, 1]; partial pivoting grows them at most 2^(n-1): no overflow
        perm = np.zeros(n, dtype=np.int64)
        inv = np.empty(n)
        for k in range(n):
            column = np.abs(A[k:, k])
            piv = k + int(np.argmax(column))
            if not column[piv - k] > tiny:
                return SINGULAR_JACOBIAN, None
            perm[k] = piv
            if piv != k:
                A[[k, piv]] = A[[piv, k]]
            inv[k] = 1.0 / A[k, k]
            for i in range(k + 1, n):
                lik = A[i, k] * inv[k]
                A[i, k] = lik
                if lik != 0.0:
                    A[i, k + 1:] -= lik * A[k, k + 1:]
    return OK, LUFactors(A, e, perm, inv)


def lu_apply(factors: LUFactors, b: np.ndarray) -> tuple[int, np.ndarray]:
    """(status, x) solving A x = b with the factors, exactly as ``<prefix>_lu_apply``;
    ``NON_FINITE`` when x is not finite (in particular when b or its scaling is not)."""
    A, n = factors.A, len(factors.A)
    with np.errstate(all="ignore"):
        b = np.array(b, dtype=float)
        for i in range(n):
            e = int(factors.e[i])
            b[i] = b[i] * np.ldexp(1.0, -e) if -1000 < e < 1000 else np.ldexp(b[i], -e)
        # a non-finite entry of the scaled b stays non-finite through the substitutions
        # (finite multipliers, zero ones applied too, and pivots): one test of x covers it
        for k in range(n):  # the row swaps, in order (L's rows were swapped with them)
            piv = int(factors.perm[k])
            if piv != k:
                b[[k, piv]] = b[[piv, k]]
        for k in range(n):
            for i in range(k + 1, n):
                b[i] -= A[i, k] * b[k]
        for i in range(n - 1, -1, -1):
            t = b[i]
            for j in range(i + 1, n):
                t -= A[i, j] * b[j]
            b[i] = t * factors.inv[i]
    return (OK if np.isfinite(norm_inf(b)) else NON_FINITE), b


def coordinate_floor(J: np.ndarray, u: np.ndarray) -> np.ndarray:
    """C_i = ε·Σ_j |J_ij|·|u_j|, as ``<prefix>_coordinate_floor`` (the same summation order)."""
    C = np.zeros(len(J))
    for j in range(J.shape[1]):
        C = C + np.abs(J[:, j]) * abs(u[j])
    return EPSILON * C


def explained_by_rounding(F: np.ndarray, J: np.ndarray, u: np.ndarray, uJ: np.ndarray,
                          ratio: float) -> bool:
    """As ``<prefix>_explained_by_rounding``: every |F_i| ≤ 64ε·κ·Σ_j |J_ij|·(1 + m_j),
    m_j = min(|u_j|, |u_J,j|), κ the pivot ratio — the residual a rounding-level update of a
    solve with J (evaluated at u_J) would leave; the weights never exceed those at u_J, so a
    runaway iterate is not accepted for its small relative update (the same summation
    order).  The C kernel first compares |F_i| with the bound times max_j |J_ij| when every
    weight is finite (S_i is at least that as computed, rounding being monotone), and sums
    only when that does not decide: the answer is always this one."""
    bound = 64.0 * EPSILON * ratio
    m = 1.0 + np.minimum(np.abs(u), np.abs(uJ))
    S = np.zeros(len(J))
    for j in range(J.shape[1]):
        S = S + np.abs(J[:, j]) * m[j]
    return bool(np.all(np.abs(F) <= bound * S))


def pivot_ratio(factors: LUFactors) -> float:
    """max |pivot| / min |pivot| (from the reciprocal pivots), as ``<prefix>_pivot_ratio``."""
    return float(np.max(np.abs(factors.inv)) / np.min(np.abs(factors.inv)))


def polish(factors, F: np.ndarray, u: np.ndarray, last_step: float, it: int
           ) -> tuple[np.ndarray, int]:
    """The polishing update of ``<prefix>_newton``: one more chord update of an accepted
    iterate u from its residual F (no evaluation), when smaller than the last update;
    (u, updates made)."""
    status, du = lu_apply(factors, F)
    if status == OK and relative_norm(du, u) < last_step:
        return u - du, it + 1
    return u, it


def above_rounding(d: np.ndarray, u: np.ndarray, factor: float) -> bool:
    """As ``<prefix>_above_rounding``: some factor·|d_j| > ε·|u_j|."""
    return bool(np.any(factor * np.abs(d) > EPSILON * np.abs(u)))


def relative_norm(d: np.ndarray, u: np.ndarray) -> float:
    """max_j |d_j| / (1 + |u_j|), as ``<prefix>_relative_norm``."""
    with np.errstate(all="ignore"):
        return float(np.max(np.abs(d) / (1.0 + np.abs(u)), initial=0.0))


def lu_solve(A: np.ndarray, b: np.ndarray) -> tuple[int, np.ndarray]:
    """(status, x) of A x = b: :func:`lu_factor` then :func:`lu_apply`."""
    status, factors = lu_factor(A)
    if status != OK:
        return status, np.array(b, dtype=float)
    return lu_apply(factors, b)


@dataclass
class NumpyWarmStart:
    """The NumPy twin of ``<prefix>_warm_start``: the last three solved unknowns and whether
    the next guess extrapolates them quadratically (see :meth:`extrapolate`)."""

    count: int = 0
    u_last: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u_earlier: np.ndarray = field(default_factory=lambda: np.zeros(0))
    quadratic: bool = False

    def _linear(self) -> np.ndarray:
        return 2.0 * self.u_last - self.u_before

    def _quadratic(self) -> np.ndarray:
        return 3.0 * (self.u_last - self.u_before) + self.u_earlier

    def extrapolate(self) -> np.ndarray:
        """As ``<prefix>_extrapolate`` (count ≥ 2): the quadratic guess
        3(u_last − u_before) + u_earlier when three solutions are held and ``quadratic``,
        else the linear 2u_last − u_before."""
        return self._quadratic() if self.count == 3 and self.quadratic else self._linear()

    def trusts(self, guess: np.ndarray, u: np.ndarray, factor: float) -> bool:
        """As ``<prefix>_trusted``: whether the solution ``u`` of a step lies in the trust
        region of its extrapolated ``guess``, |u − guess| ≤ factor·(m + TRUST_FLOOR) (|·|
        relative to each unknown at ``u_last``; m the larger motion of the last two steps),
        or the check is off (factor 0, fewer than three solutions held: one motion alone can
        be the small one of an oscillation)."""
        if not factor > 0.0 or self.count < 3:
            return True
        scale = 1.0 + np.abs(self.u_last)
        motion = np.maximum(np.abs(self.u_last - self.u_before),
                            np.abs(self.u_before - self.u_earlier))
        radius = factor * (float(np.max(motion / scale, initial=0.0)) + TRUST_FLOOR)
        return bool(np.all(np.abs(u - guess) <= radius * scale))

    def remember(self, u: np.ndarray) -> None:
        """As ``<prefix>_remember``: adds the solution ``u``; with three solutions held,
        ``quadratic`` becomes whether the quadratic extrapolation would have guessed ``u``
        more closely than the linear one (relative norm): O(h³) against O(h²) on smooth
        motion, worse on an oscillation of fewer than about six steps per period."""
        if self.count == 3:
            self.quadratic = bool(relative_norm(u - self._quadratic(), u)
                                  < relative_norm(u - self._linear(), u))
        else:
            self.quadratic = False
        self.u_earlier, self.u_before = self.u_before, self.u_last
        self.u_last = np.array(u, dtype=float)
        self.count = min(self.count + 1, 3)


class NumpyKernel(_Kernel):
    """The same kernel evaluated with NumPy: the step's program (the same operations, in the
    same order, as the generated C) and Newton in Python."""

    name = "numpy"

    def __init__(self, step):
        self.step = step
        self.n_u, self.n_k = len(step.unknowns), len(step.knowns)
        self.n_p = len(step.parameters)
        program = step.program
        args = ["u", "known", "p"]
        self._F = program.numpy_function(["F"], args)
        self._S = program.numpy_function(["F_scale"], args)
        self._FJ = program.numpy_function(["F", "J"], args)
        self._next = program.numpy_function(["next_knowns"], args)
        self._pred = program.numpy_function(["predict"], ["known", "p"])

    def warm_start(self) -> NumpyWarmStart:
        return NumpyWarmStart(0, np.zeros(self.n_u), np.zeros(self.n_u), np.zeros(self.n_u))

    def _residual(self, u, known, p) -> np.ndarray:
        return self._F(u, known, p)[0].reshape(self.n_u)

    def _residual_jacobian(self, u, known, p):
        F, J = self._FJ(u, known, p)
        return F.reshape(self.n_u), J.reshape(self.n_u, self.n_u)

    def _predict(self, known, p) -> np.ndarray:
        return self._pred(known, p)[0].reshape(self.n_u)

    def _next_knowns(self, u, known, p) -> np.ndarray:
        return self._next(u, known, p)[0].reshape(self.n_k)

    def _solve_step(self, known, p, u0, options: NewtonOptions):
        """Newton's method exactly as ``<prefix>_newton`` in the C kernel."""
        with np.errstate(all="ignore"):
            return self._newton(known, p, np.array(u0, dtype=float), options)

    def _at_floor(self, u, known, p, F, C, factor: float) -> bool:
        """As ``<prefix>_at_floor``: every |F_i| ≤ factor·(C_i + N_i), N_i the larger change
        of F_i when every unknown moves by 4 ulps (alternating signs, both ways)."""
        move = 4.0 * EPSILON * np.where(np.abs(u) > np.finfo(float).tiny, np.abs(u), 1.0)
        signs = np.where(np.arange(len(u)) % 2 == 0, 1.0, -1.0)
        N = np.zeros(len(F))
        for sign in (-1.0, 1.0):
            G = self._residual(u + sign * signs * move, known, p)
            N = np.maximum(N, np.abs(G - F))
        return bool(np.all(np.abs(F) <= factor * (C + N)))

    def _within_scale(self, u, known, p, F, factor: float) -> bool:
        """As ``<prefix>_within_scale``: every |F_i| ≤ factor·ε·S_i, S the program's
        ``F_scale`` (the size of the terms F_i is computed from)."""
        S = self._S(u, known, p)[0].reshape(self.n_u)
        return bool(np.all(np.abs(F) <= factor * EPSILON * S))

    def _newton(self, known, p, u, options: NewtonOptions):
        """As ``<prefix>_newton`` (see :class:`NewtonOptions`)."""
        previous = last_step = 0.0
        factors = uJ = None
        done = 0  # 1: stopped on a rounding-noise update, 2: on the estimated error
        fresh = False  # the last update was a Newton update (J factored where it started)
        it = 0
        while True:
            here = False  # J factored at this iterate
            if it == 0:
                F, J = self._residual_jacobian(u, known, p)
            else:
                F = self._residual(u, known, p)
            rnorm = norm_inf(F)
            if not np.isfinite(rnorm):
                return NON_FINITE, u, it, rnorm
            if done:  # after the final update: accepted only at the rounding floor
                if explained_by_rounding(F, J, u, uJ, pivot_ratio(factors)) or self._at_floor(
                        u, known, p, F, coordinate_floor(J, uJ), options.floor_factor):
                    if done == 2 and it < options.max_iterations:
                        u, it = polish(factors, F, u, last_step, it)
                    return OK, u, it, rnorm
                done = 0  # a small update, a residual above the floor: iterate on
            if it == 0:  # factor J before any convergence test (a degenerate step fails)
                uJ, here = u, True
                status, factors = lu_factor(J)
                if status != OK:
                    return status, u, it, rnorm
            if rnorm <= options.tol_residual:
                return OK, u, it, rnorm
            slow = it > 0 and not rnorm <= 0.1 * previous
            ratio = pivot_ratio(factors)
            if slow and self._at_floor(u, known, p, F, coordinate_floor(J, uJ),
                                       options.floor_factor):
                return OK, u, it, rnorm
            noise = slow and last_step <= 64.0 * EPSILON * ratio  # rounding noise of a solve
            if slow and (fresh or noise) and self._within_scale(u, known, p, F,
                                                                options.floor_factor):
                return OK, u, it, rnorm  # at the rounding of the residual's own terms
            if noise:
                return (OK if explained_by_rounding(F, J, u, uJ, ratio) else STALLED,
                        u, it, rnorm)
            if it >= options.max_iterations:
                return NOT_CONVERGED, u, it, rnorm
            if slow:
                F, J = self._residual_jacobian(u, known, p)
                uJ, here = u, True
                status, factors = lu_factor(J)
                if status != OK:
                    return status, u, it, rnorm
            previous, fresh = rnorm, here
            status, du = lu_apply(factors, F)
            if status != OK:
                return status, u, it, rnorm
            step = relative_norm(du, u)
            u = u - du
            if step <= 4.0 * EPSILON:  # the update is rounding noise of u
                done = 1
            elif it > 0 and step < last_step:
                rho = step / last_step
                if rho / (1.0 - rho) * step <= options.tol_step:  # polished unless below
                    # rounding; always after the first two updates (rho, a single ratio,
                    # overstates the contraction when the first update also fixed the
                    # unknowns that enter linearly, such as multipliers)
                    done = 2 if it == 1 or above_rounding(du, u, rho / (1.0 - rho)) else 1
            last_step = step
            it += 1

    def _simulate(self, known0, p, n_steps: int, options: NewtonOptions,
                  warm: NumpyWarmStart) -> RawRun:
        """As ``<prefix>_simulate``: extrapolate from the warm start when it holds at least
        two solutions (and ``options.extrapolate``), else predict; retry from the prediction
        when Newton fails from an extrapolated guess or its solution lies outside the
        guess's trust region (:meth:`NumpyWarmStart.trusts`), and stop with ``BRANCH_JUMP``
        when the retry's does too."""
        if not isinstance(warm, NumpyWarmStart) or warm.count not in (0, 1, 2, 3) \
                or warm.quadratic not in (False, True):
            raise ShapeError(f"{self.step.name}: the warm start must come from "
                             f"warm_start(), got {warm!r}")
        states = np.empty((n_steps + 1, self.n_k))
        states[0] = known0
        iterations = np.zeros(n_steps, dtype=np.int64)
        norms = np.zeros(n_steps)
        for k in range(n_steps):
            current = states[k]
            extrapolated = bool(options.extrapolate) and warm.count >= 2
            with np.errstate(all="ignore"):
                guess = warm.extrapolate() if extrapolated else self._predict(current, p)
            status, u, iterations[k], norms[k] = self._solve_step(current, p, guess, options)
            jumped = (extrapolated and status == OK
                      and not warm.trusts(guess, u, options.trust_factor))
            if extrapolated and (status != OK or jumped):  # retry from the prediction
                far, far_norm = u, norms[k]
                with np.errstate(all="ignore"):
                    u0 = self._predict(current, p)
                status, u, more, norms[k] = self._solve_step(current, p, u0, options)
                iterations[k] = min(iterations[k] + more, C_INT_MAX)
                if status != OK and jumped:  # report the far solution
                    u, norms[k] = far, far_norm
                if (not warm.trusts(guess, u, options.trust_factor) if status == OK
                        else jumped):
                    status = BRANCH_JUMP
            if status == OK:
                with np.errstate(all="ignore"):
                    following = self._next_knowns(u, current, p)
                if not np.isfinite(norm_inf(following)):
                    status = NON_FINITE
            if status != OK:
                return RawRun(states, iterations, norms, status, k, u)
            states[k + 1] = following
            warm.remember(u)
        return RawRun(states, iterations, norms, OK, -1, np.zeros(self.n_u))


def run_chunks(kernel, known0: np.ndarray, p: np.ndarray, steps: int,
               options: NewtonOptions, chunk_steps: int) -> Iterator[tuple[int, RawRun]]:
    """Advance ``steps`` steps in kernel calls of at most ``chunk_steps`` steps each.

    Yields (index of the call's first state, its :class:`RawRun`) and stops after a failed
    call.  The Newton warm start is carried from call to call, so the states are bitwise
    those of one call of ``steps`` steps, while memory stays bounded by one chunk.
    """
    warm = kernel.warm_start()
    known, done = known0, 0
    while done < steps:
        n = min(chunk_steps, steps - done)
        run = kernel.simulate(known, p, n, options, warm)
        yield done, run
        if run.status != OK:
            return
        known, done = run.states[-1], done + n
