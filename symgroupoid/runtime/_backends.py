"""Two interchangeable kernels behind a :class:`~symgroupoid.runtime.Simulator`: their
Python faces (:class:`NumpyKernel` here, :class:`~._ckernel.CKernel` beside it).

:class:`~._ckernel.CKernel` calls the compiled C (through cffi); :class:`NumpyKernel`
evaluates the step's program with NumPy and runs the *same* Newton iteration with the NumPy
twin of the C library (``symgroupoid/stepper``: same convergence tests, same row scaling, LU
with partial pivoting and singularity threshold, same statuses), so both backends give the
same trajectories, bit for bit, and fail alike.  The input checks both share
(:class:`_Kernel`), and the checks of every buffer handed to C, live here.

Every array handed to C goes through :func:`real_vector` (shape and value checks of user
input, naming the argument) and then :func:`c_buffer` (exact dtype, C-contiguity and
length of the buffer itself): nothing reaches the C side that could make it read or write
outside a buffer.
"""

from __future__ import annotations

import ctypes
import dataclasses
from collections.abc import Callable

import numpy as np

from .._arguments import integer_argument, real_array
from .._errors import InputTypeError, ShapeError, TrajectoryTooLargeError
from ..codegen import band_order, time_layout
from ..stepper import (
    NumpyStepper,
    NumpyWarmStart,
    Status,
    StepFunctions,
)
from ._options import NewtonOptions
from ._runs import (
    BatchRun,
    ChunkRun,
    RawRun,
    RunCursor,
    batch_rows,
)

OK, SINGULAR_JACOBIAN, NOT_CONVERGED, NON_FINITE, INVALID_ARGUMENT, STALLED, BRANCH_JUMP = (
    s for s in Status if s <= Status.BRANCH_JUMP)


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


#: the NumPy dtype of each C type a buffer may hold
_C_DTYPES = {"double": np.dtype(np.float64), "int": np.dtype(np.intc),
             "long": np.dtype(ctypes.c_long), "long long": np.dtype(np.longlong)}


def c_buffer(ffi, array: np.ndarray, length: int, name: str, ctype: str = "double"):
    """A cffi pointer to ``array`` after checking it is exactly what C will access.

    ``array`` must be a NumPy array of the dtype matching ``ctype`` (``double``: float64,
    ``int``, ``long``, ``long long``: the platform C integers), C-contiguous and of exactly
    ``length`` elements; any other buffer is a :class:`ShapeError` (the C side would read or
    write past it).
    """
    dtype = _C_DTYPES[ctype]
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


def _options(options, entry: str) -> None:
    """An :class:`InputTypeError` unless ``options`` is :class:`NewtonOptions`."""
    if not isinstance(options, NewtonOptions):
        raise InputTypeError(f"{entry}: options must be NewtonOptions (e.g. NewtonOptions() "
                             f"or NewtonOptions(max_iterations=20)), got "
                             f"{type(options).__name__}")


def _fits(kernel, n_steps: int) -> None:
    """A :class:`TrajectoryTooLargeError` up front when the ``n_steps + 1`` states of a
    kernel's run would not fit in what this process may allocate (a MemoryError from NumPy
    otherwise, or the machine's memory exhausted)."""
    from ._memory import available_memory

    needed = (n_steps + 1) * 8 * kernel.n_k + n_steps * 16
    if needed <= 1 << 26:  # (64 MiB: not worth asking, on the per-step calls of forced runs)
        return
    room = available_memory()
    if room is not None and needed > room:
        raise TrajectoryTooLargeError(
            f"{kernel.name}: a run of {n_steps} steps keeps {n_steps + 1} states, "
            f"{needed / 2**30:.1f} GiB, more than this process may allocate "
            f"({room / 2**30:.1f} GiB); run it in pieces (Simulator.stream, simulate_into)")


class _Kernel:
    """Input checks shared by both kernels; subclasses implement the ``_raw`` methods."""

    name = ""
    n_u = n_k = n_p = 0
    #: largest step count of one ``simulate`` call
    max_steps = 2**53

    def _inputs(self, known, p, u=None, *, with_u: bool = False) -> tuple[np.ndarray, ...]:
        """``known``, ``p`` and (``with_u``, or given) ``u`` as vectors of their lengths."""
        arrays = [real_vector(known, self.n_k, "known"), real_vector(p, self.n_p, "p")]
        if u is not None or with_u:
            arrays.append(real_vector(u, self.n_u, "u"))
        return tuple(arrays)

    def residual(self, u, known, p) -> np.ndarray:
        """F(u; known, p), shape (n_unknowns,)."""
        known, p, u = self._inputs(known, p, u, with_u=True)
        return self._residual(u, known, p)

    def residual_jacobian(self, u, known, p) -> tuple[np.ndarray, np.ndarray]:
        """F and its exact Jacobian J[i, j] = ∂F_i/∂u_j."""
        known, p, u = self._inputs(known, p, u, with_u=True)
        return self._residual_jacobian(u, known, p)

    def input_jacobian(self, u, known, p, columns: int) -> np.ndarray:
        """∂F/∂(the inputs in the last ``columns`` entries of ``known``), exact, shape
        (n_unknowns, columns): what the kernel's ``<prefix>_input_jacobian`` writes
        (docs/conventions.md §20)."""
        known, p, u = self._inputs(known, p, u, with_u=True)
        return self._input_jacobian(u, known, p, columns)

    def predict(self, known, p) -> np.ndarray:
        """The first Newton guess of a step."""
        known, p = self._inputs(known, p)
        return self._predict(known, p)

    def next_knowns(self, u, known, p) -> np.ndarray:
        """The next known state from a solved step."""
        known, p, u = self._inputs(known, p, u, with_u=True)
        return self._next_knowns(u, known, p)

    def domain(self, u, known, p) -> np.ndarray:
        """The values of the window's terms defined on part of the real line only (the
        logarithms, square roots, acos, … of L; ``step.domain_kinds`` says which), at the
        unknowns u: all finite exactly where the terms are defined (docs/conventions.md §11;
        empty when L is defined everywhere)."""
        known, p, u = self._inputs(known, p, u, with_u=True)
        return self._domain(u, known, p)

    def solve_step(self, known, p, u0, options: NewtonOptions):
        """Newton's method from ``u0``: (status, last iterate, iterations, residual norm).

        Non-finite ``known``, ``p`` or ``u0`` give ``INVALID_ARGUMENT`` (as in C);
        ``options`` must be :class:`NewtonOptions` (an :class:`InputTypeError` otherwise).
        """
        known, p, u = self._inputs(known, p, u0, with_u=True)
        _options(options, "solve_step")
        if not all(np.isfinite(a).all() for a in (known, p, u)):
            return INVALID_ARGUMENT, u, 0, float("nan")
        return self._solve_step(known, p, u, options)

    def simulate(self, known0, p, n_steps: int, options: NewtonOptions,
                 warm=None) -> RawRun:
        """``n_steps`` steps from ``known0``, continuing the Newton warm start ``warm``
        (from :meth:`warm_start`; None: a fresh start), which is updated in place."""
        known0, p = real_vector(known0, self.n_k, "known0"), real_vector(p, self.n_p, "p")
        n_steps = integer_argument(n_steps, "n_steps", maximum=self.max_steps)
        _options(options, "simulate")
        _fits(self, n_steps)
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

    def simulate_inputs(self, states: np.ndarray, iterations: np.ndarray,
                        residual_norms: np.ndarray, p, inputs: np.ndarray,
                        upcoming: np.ndarray, options: NewtonOptions, warm) -> ChunkRun:
        """A run of a forced system in the buffers of :meth:`simulate_into` (R = steps + 1
        rows), as ``<prefix>_simulate`` runs it with inputs: step k starts from state k with
        row k of ``inputs`` in its entries ``upcoming`` (the slot of the next arrow's inputs,
        docs/conventions.md §20), the stored state keeping its own; the warm start is
        carried.  Returns after the first failing step (``failed_step`` its index)."""
        inputs = self._input_table(inputs, self.n_in)
        for k in range(len(inputs)):
            current = states[k].copy()
            current[upcoming] = inputs[k]
            run = self.simulate(current, p, 1, options, warm)
            iterations[k], residual_norms[k] = run.iterations[0], run.residual_norms[0]
            if run.status != OK:
                return ChunkRun(run.status, k, k, run.last_iterate)
            states[k + 1] = run.states[1]
        return ChunkRun(OK, len(inputs), -1, np.zeros(self.n_u))

    def _parameter_table(self, p: np.ndarray, n_batch: int) -> None:
        """A :class:`ShapeError` unless ``p`` is one set of parameters or one per run (a
        single row for several runs would be read past its end)."""
        if p.shape not in ((self.n_p,), (n_batch, self.n_p)):
            raise ShapeError(f"{self.name} kernel: parameters of shape {p.shape}, not "
                             f"({self.n_p},) or ({n_batch}, {self.n_p}): one set, or one "
                             f"per run")

    def _input_table(self, inputs, m: int) -> np.ndarray:
        """``inputs`` as a C-contiguous float64 table of one row of ``m`` inputs per step; a
        :class:`ShapeError` for another shape (a short row would be read past its end)."""
        inputs = np.ascontiguousarray(inputs, dtype=float)
        if inputs.ndim != 2 or inputs.shape[1] != m:
            raise ShapeError(f"{self.name} kernel: inputs of shape {inputs.shape}, not "
                             f"(steps, {m}): one row of the {m} inputs per step")
        return inputs

    def step_once(self, known: np.ndarray, p: np.ndarray, options: NewtonOptions
                  ) -> tuple[int, np.ndarray]:
        """One step from a fresh warm start, as ``simulate(known, p, 1, options)`` computes
        it (the same bits): (status, the next state).  For callers that have checked their
        inputs already (:meth:`Simulator.step`): ``known`` and ``p`` are C-contiguous
        float64 vectors of the right lengths; a non-finite one gives INVALID_ARGUMENT."""
        run = self.simulate(known, p, 1, options)
        return run.status, run.states[1]

    def step_entry(self) -> tuple[Callable, Callable, Callable, object]:
        """What a control loop calls per step with the least Python around it (see
        :mod:`~symgroupoid.runtime._fast_step`): (``entry(known, p, u, options, out)`` →
        status, writing the next state into ``out``; ``view_of(array)``, what ``entry``
        takes for a vector; ``options_of(options)``, what it takes for
        :class:`NewtonOptions`; what it takes for "no inputs" as ``u``).  Here the vectors
        and options themselves, through :meth:`step_once`."""
        def entry(known, p, u, options, out) -> int:
            if u is not None:  # the inputs of the new arrow in the state's last slot
                known = known.copy()
                known[len(known) - len(u):] = u
            status, after = self.step_once(known, p, options)
            if status == OK:
                out[:] = after
            return status

        return entry, _itself, _itself, None

    def result_rows(self, n: int) -> Callable[[], tuple[np.ndarray, object]]:
        """A source of fresh states for :meth:`step_entry`'s ``out``: each call gives a new
        float64 vector of ``n`` entries (never handed out before) and what ``entry`` takes
        for it.  Here a new array, itself."""
        def row() -> tuple[np.ndarray, object]:
            out = np.empty(n)
            return out, out

        return row

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
                       options: NewtonOptions, threads: int | None = None,
                       inputs: np.ndarray | None = None) -> BatchRun:
        """B runs of ``n_steps`` steps from the rows of ``known0`` (B, n_known) with the
        rows of ``p`` (B, n_params), or one parameter vector ``p`` (n_params,) for all;
        every ``every``-th state kept (see :class:`BatchRun`).  Each run is computed
        exactly as :meth:`simulate` computes it.  ``threads``: ignored here (one run after
        the other); the compiled kernel shares runs among OpenMP threads.  ``inputs``
        (a forced kernel's, docs/conventions.md §20): (B, n_steps, m), or (n_steps, m)
        for all runs, row k of a run read by its step k (:meth:`simulate_inputs`)."""
        known0, p = self._batch_inputs(known0, p)
        n_steps = integer_argument(n_steps, "n_steps", maximum=self.max_steps)
        every = integer_argument(every, "every", minimum=1, maximum=self.max_steps)
        inputs = self._batch_sequence(inputs, len(known0), n_steps)
        out = self._batch_buffers(len(known0), n_steps, every)
        cursors = self.batch_cursors(len(known0))
        self.batch_until(cursors, known0, p, n_steps, every, n_steps, options, out, threads,
                         inputs)
        return out

    def _batch_sequence(self, inputs, n_batch: int, n_steps: int) -> np.ndarray | None:
        """The inputs of a batch as a C-contiguous float64 array (n_steps, m) shared by
        every run, or (B, n_steps, m); None without inputs."""
        if inputs is None:
            return None
        u = np.ascontiguousarray(inputs, dtype=np.float64)
        m = self.n_in
        if u.ndim not in (2, 3) or u.shape[-2:] != (n_steps, m) or (u.ndim == 3
                                                                     and len(u) != n_batch):
            raise ShapeError(f"inputs must have shape ({n_batch}, {n_steps}, {m}) or "
                             f"({n_steps}, {m}), got {u.shape}")
        return u

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
                    threads: int | None = None, inputs: np.ndarray | None = None) -> None:
        """Advance the runs of ``out`` (checked inputs, :meth:`_batch_buffers`) to step
        min(until, n_steps) from their ``cursors``; called again with a larger ``until``
        they continue, bitwise as one call of ``n_steps``.  Each run's progress is
        committed by one assignment of its cursor (a KeyboardInterrupt between two runs
        leaves every run at a consistent step).  ``inputs``: see :meth:`simulate_batch`."""
        self._parameter_table(p, len(known0))
        for b in range(len(known0)):
            c = cursors[b]
            if c is not None and c.status != OK:
                continue
            u = None if inputs is None else inputs[b] if inputs.ndim == 3 else inputs
            c = self._run_until(c, known0[b], p[b] if p.ndim == 2 else p, n_steps, every,
                                until, options, out, b, u)
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
                   until: int, options: NewtonOptions, out: BatchRun, b: int,
                   u: np.ndarray | None = None) -> RunCursor:
        """Run b from its cursor (None: a fresh start) to min(until, n_steps), on a copy of
        the cursor (returned); states are written at rows from ``c.kept`` on; ``u``: the
        run's inputs (n_steps, m), or None."""
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
            run = self._piece(c.known, p, n, options, c.warm,
                              None if u is None else u[c.done:c.done + n])
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

    def _piece(self, known, p, n: int, options: NewtonOptions, warm,
               u: np.ndarray | None) -> RawRun:
        """:meth:`simulate` of ``n`` steps, or with inputs ``u`` (n, m) read into the last
        m entries of the state each step starts from (:meth:`simulate_inputs`)."""
        if u is None:
            return self.simulate(known, p, n, options, warm)
        states = np.empty((n + 1, self.n_k))
        states[0] = known
        iterations, norms = np.zeros(n, np.intc), np.zeros(n)
        chunk = self.simulate_inputs(states, iterations, norms, p, u,
                                     slice(self.n_k - u.shape[1], self.n_k), options, warm)
        return RawRun(states, iterations, norms, chunk.status,
                      chunk.failed_step if chunk.status != OK else -1, chunk.last_iterate)

    def copy_warm(self, warm):
        """An independent copy of a warm start."""
        return dataclasses.replace(warm)


class NumpyKernel(_Kernel):
    """The same kernel evaluated with NumPy: the step's program (the same operations, in the
    same order, as the generated C) and the NumPy twin of the C library
    (:class:`~symgroupoid.stepper.NumpyStepper`)."""

    name = "numpy"

    def __init__(self, step):
        self.step = step
        self.n_u, self.n_k = len(step.unknowns), len(step.knowns)
        self.n_p = len(step.parameters)
        self.n_in = len(getattr(step, "inputs", ()))
        program = step.program
        args = ["u", "known", "p"]
        self._F = program.numpy_function(["F"], args)
        self._S = program.numpy_function(["F_scale"], args)
        self._FJ = program.numpy_function(["F", "J"], args)
        self._next = program.numpy_function(["next_knowns"], args)
        self._pred = program.numpy_function(["predict"], ["known", "p"])
        self._D = (program.numpy_function(["domain"], args)
                   if program.outputs.get("domain") else None)
        self._stepper = NumpyStepper(StepFunctions(
            self._residual, self._residual_jacobian, self._residual_scale, self._predict,
            self._next_knowns, self._domain if self._D is not None else None), self.n_u,
            time_layout(step), band_order(step))

    def warm_start(self) -> NumpyWarmStart:
        return self._stepper.warm_start()

    def _residual(self, u, known, p) -> np.ndarray:
        return self._F(u, known, p)[0].reshape(self.n_u)

    def _input_jacobian(self, u, known, p, columns: int) -> np.ndarray:
        J = self.step.input_jacobian(u, known, p)
        if J.size != self.n_u * columns:
            raise ShapeError(f"numpy kernel: the input Jacobian has {J.size // self.n_u} "
                             f"columns (the inputs of the terms a step reads), not {columns}")
        return J.reshape(self.n_u, columns)

    def _residual_jacobian(self, u, known, p):
        F, J = self._FJ(u, known, p)
        return F.reshape(self.n_u), J.reshape(self.n_u, self.n_u)

    def _residual_scale(self, u, known, p) -> np.ndarray:
        return self._S(u, known, p)[0].reshape(self.n_u)

    def _predict(self, known, p) -> np.ndarray:
        return self._pred(known, p)[0].reshape(self.n_u)

    def _next_knowns(self, u, known, p) -> np.ndarray:
        return self._next(u, known, p)[0].reshape(self.n_k)

    def _domain(self, u, known, p) -> np.ndarray:
        if self._D is None:  # L defined everywhere: no values (as the C kernel's N_DOMAIN 0)
            return np.zeros(0)
        return np.asarray(self._D(u, known, p)[0], float).ravel()

    def _solve_step(self, known, p, u0, options: NewtonOptions):
        """Newton's method exactly as ``<prefix>_newton`` in the C kernel."""
        return self._stepper.solve_step(known, p, u0, options)

    def _simulate(self, known0, p, n_steps: int, options: NewtonOptions,
                  warm: NumpyWarmStart) -> RawRun:
        """As ``<prefix>_simulate`` (:meth:`NumpyStepper.simulate`), from a warm start of
        :meth:`warm_start`."""
        if not isinstance(warm, NumpyWarmStart) or warm.count not in (0, 1, 2, 3) \
                or warm.quadratic not in (False, True):
            raise ShapeError(f"{self.step.name}: the warm start must come from "
                             f"warm_start(), got {warm!r}")
        return RawRun(*self._stepper.simulate(known0, p, n_steps, options, warm))


#: the kernels' faces, and the names of the NumPy twin, the statuses and the run records that
#: runtime modules read from here
def _itself(value):
    """The value itself (:meth:`_Kernel.step_entry`'s views)."""
    return value


__all__ = ["BRANCH_JUMP", "INVALID_ARGUMENT", "NON_FINITE", "NOT_CONVERGED", "OK",
           "SINGULAR_JACOBIAN", "STALLED", "NumpyKernel", "c_buffer", "real_vector"]
