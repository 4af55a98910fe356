"""The compiled kernel of a step behind a :class:`~symgroupoid.runtime.Simulator`: the Python
face of the C library (``symgroupoid/stepper``) built into a kernel and loaded with cffi.

Every array handed to C goes through :func:`~._backends.real_vector` (shape and value
checks of user input, naming the argument) and then :func:`~._backends.c_buffer` (exact
dtype, C-contiguity and length of the buffer itself): nothing reaches the C side that could
make it read or write outside a buffer.
"""

from __future__ import annotations

import ctypes
import functools
import threading

import numpy as np

from .._arguments import integer_argument
from .._errors import ShapeError
from ..stepper import MAX_THREADS, Status
from ._backends import INVALID_ARGUMENT, _Kernel, _run_buffers, c_buffer, real_vector
from ._options import NewtonOptions
from ._runs import OK, BatchRun, ChunkRun, RawRun

#: the most states, and doubles, per block of :meth:`CKernel.result_rows` (a control
#: loop's states, up to 64 at a time: a state kept keeps its block, at most 32 KiB)
RESULT_BLOCK, RESULT_BLOCK_DOUBLES = 64, 4096


class CKernel(_Kernel):
    """The compiled kernel of a step (a cffi extension module)."""

    name = "c"

    def __init__(self, module, prefix: str, n_unknowns: int, n_knowns: int,
                 n_parameters: int | None = None):
        self.module, self.ffi, self.lib = module, module.ffi, module.lib
        self.prefix, self.n_u, self.n_k = prefix, n_unknowns, n_knowns
        self.n_p = int(getattr(self.lib, f"{prefix.upper()}_N_PARAMETERS")) \
            if n_parameters is None else n_parameters
        self.n_in = int(getattr(self.lib, f"{prefix.upper()}_N_INPUTS", 0))
        #: the columns <prefix>_input_jacobian writes (the inputs of every term it reads)
        self.n_input_columns = int(getattr(self.lib, f"{prefix.upper()}_N_INPUT_COLUMNS", 0))
        self._f = {n: getattr(self.lib, f"{prefix}_{n}") for n in (
            "residual", "residual_jacobian", "predict", "next_knowns", "solve_step",
            "simulate", "reconstruct")}
        self._warm_type = self.ffi.typeof(f"{prefix}_warm_start *")
        self._stepper = None  # stepper(), made on first use
        self._held_options: dict = {}  # NewtonOptions -> its C struct (see _options)
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
                       options: NewtonOptions, threads: int | None = None,
                       inputs: np.ndarray | None = None) -> BatchRun:
        """:meth:`_Kernel.simulate_batch` in one call of ``<prefix>_simulate_batch``, the
        runs shared among ``threads`` OpenMP threads (None: the OpenMP default, all cores)
        when the module was built with ``-fopenmp``."""
        fn = getattr(self.lib, f"{self.prefix}_simulate_batch", None)
        if fn is None:  # a module built before the batched entry point existed
            return super().simulate_batch(known0, p, n_steps, every, options, threads,
                                          inputs)
        known0, p = self._batch_inputs(known0, p)
        n_steps = integer_argument(n_steps, "n_steps", maximum=self.max_steps)
        every = integer_argument(every, "every", minimum=1, maximum=self.max_steps)
        inputs = self._batch_sequence(inputs, len(known0), n_steps)
        threads = 0 if threads is None else integer_argument(threads, "threads", minimum=1,
                                                             maximum=MAX_THREADS)
        B = len(known0)
        out = self._batch_buffers(B, n_steps, every)
        if B == 0:
            return out
        rows = out.states.shape[1]
        status = fn(
            B, self._buf(known0, B * self.n_k, "known0"),
            self._buf(p, p.size, "p"), 0 if p.ndim == 1 else self.n_p,
            *self._input_buffer(inputs, n_steps), n_steps, every, self._options(options),
            self._buf(out.states, B * rows * self.n_k, "states"), rows,
            *self._batch_outputs(out, B, rows), threads)
        if status != OK:
            raise ValueError(f"{self.prefix}_simulate_batch: {Status(int(status)).message}")
        return out

    def _input_buffer(self, inputs: np.ndarray | None, n_steps: int) -> tuple:
        """The C arguments ``u, u_stride`` of the batched entry points: NULL, 0 without
        inputs; else the inputs (n_steps, m) of every run (stride 0) or (B, n_steps, m)
        (stride n_steps·m), m the kernel's ``N_INPUTS``."""
        if inputs is None:
            if self.n_in and n_steps:
                raise ShapeError(f"{self.prefix}: the kernel has {self.n_in} inputs; pass "
                                 f"inputs of shape (B, {n_steps}, {self.n_in})")
            return self.ffi.NULL, 0
        if inputs.shape[-1] != self.n_in:
            raise ShapeError(f"{self.prefix}: the kernel has {self.n_in} inputs, the batch's "
                             f"inputs {inputs.shape[-1]} per step")
        if inputs.size == 0:
            return self.ffi.NULL, 0
        return (self._buf(inputs, inputs.size, "inputs"),
                0 if inputs.ndim == 2 else n_steps * self.n_in)

    def _batch_outputs(self, out, B: int, rows: int) -> tuple:
        """The C views of a batch's per-step and per-run outputs, in the order of the
        batched entry points' arguments after ``states, rows``."""
        return (
            self._buf(out.iterations if rows > 1 else np.zeros(1, np.longlong),
                      max(B * (rows - 1), 1), "iterations", "long long"),
            self._buf(out.residual_norms if rows > 1 else np.zeros(1),
                      max(B * (rows - 1), 1), "residual_norms"),
            self._buf(out.kept, B, "kept", "long"), self._buf(out.status, B, "status", "int"),
            self._buf(out.failed_step, B, "failed_step", "long"),
            self._buf(out.failed_iterations, B, "failed_iterations", "int"),
            self._buf(out.failed_residual_norms, B, "failed_residual_norm"),
            self._buf(out.last_iterate, B * self.n_u, "last_iterate"))

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

    def step_entry(self):
        """:meth:`_Kernel.step_entry` in C: ``<prefix>_step`` (five arguments: the state,
        the parameters, the inputs (NULL), the options, the next state), ``ffi.from_buffer``
        for the vectors and the options' C struct; in a module built before
        ``<prefix>_step`` existed, the base class's (through :meth:`stepper`)."""
        entry = getattr(self.lib, f"{self.prefix}_step", None)
        if entry is None:
            return super().step_entry()
        return (entry, functools.partial(self.ffi.from_buffer, "double[]"), self._options,
                self.ffi.NULL)

    def result_rows(self, n: int):
        """:meth:`_Kernel.result_rows` in C: the rows of blocks of up to :data:`RESULT_BLOCK`
        states (and :data:`RESULT_BLOCK_DOUBLES` doubles), one C view per block and a
        pointer into it per row (``ffi.from_buffer`` costs more than the step of a small
        kernel).  Each row is a view of its block, which
        it keeps alive with the memory its pointer points at; a row is handed out once."""
        pending: list = []
        view_of = functools.partial(self.ffi.from_buffer, "double[]")
        rows_per_block = max(1, min(RESULT_BLOCK, RESULT_BLOCK_DOUBLES // max(n, 1)))

        def row():
            try:
                return pending.pop()
            except IndexError:  # a new block (list.pop is atomic: no row is given twice)
                block = np.empty((rows_per_block, n))
                view = view_of(block)
                rows = [(r, view + i * n) for i, r in enumerate(block)]
                rows.reverse()
                first = rows.pop()
                pending.extend(rows)
                return first

        return row

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
                    threads: int | None = None, inputs: np.ndarray | None = None) -> None:
        """:meth:`_Kernel.batch_until` in one call of ``<prefix>_simulate_batch_until``
        (which writes the kept rows, status and failure data of ``out`` itself; a
        KeyboardInterrupt is seen only after the call returns)."""
        fn = self._until_entry()
        if fn is None:
            return super().batch_until(cursors, known0, p, n_steps, every, until, options,
                                       out, threads, inputs)
        B = len(known0)
        if B == 0:
            return None
        inputs = self._batch_sequence(inputs, B, n_steps)
        if not (isinstance(cursors, self.ffi.CData)
                and self.ffi.typeof(cursors) is self.ffi.typeof(f"{self.prefix}_batch_cursor[]")
                and len(cursors) >= B):
            raise ShapeError(f"{self.prefix}: the cursors must come from batch_cursors({B})")
        threads = 0 if threads is None else integer_argument(threads, "threads", minimum=1,
                                                             maximum=MAX_THREADS)
        self._parameter_table(p, B)
        rows = out.states.shape[1]
        status = fn(
            B, cursors, self._buf(known0, B * self.n_k, "known0"), self._buf(p, p.size, "p"),
            0 if p.ndim == 1 else self.n_p, *self._input_buffer(inputs, n_steps), n_steps,
            every, until, self._options(options),
            self._buf(out.states, B * rows * self.n_k, "states"), rows,
            *self._batch_outputs(out, B, rows), threads)
        if status != OK:
            raise ValueError(f"{self.prefix}_simulate_batch_until: "
                             f"{Status(int(status)).message}")
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
        """The ``<prefix>_options`` of ``options`` (read-only to C: the kernel takes a const
        pointer), made once per value of the options and kept (a few at most)."""
        held = self._held_options.get(options)
        if held is None:
            if len(self._held_options) >= 8:
                self._held_options.clear()
            held = self._held_options[options] = self._new_options(options)
        return held

    def _new_options(self, options: NewtonOptions):
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
        # the buffers were checked by simulate_into (_run_buffers, real_vector): views at once
        view = self.ffi.from_buffer
        base = view("double[]", states) + start * self.n_k
        last = np.zeros(self.n_u)
        failed = self.ffi.new("long *")
        status = int(self._f["simulate"](
            base, view("double[]", p), self.ffi.NULL, n_steps, self._options(options),
            warm, base, rows - start, view("int[]", iterations) + start,
            view("double[]", residual_norms) + start, failed, view("double[]", last)))
        k = int(failed[0])
        return ChunkRun(status, n_steps if status == OK else max(k, 0), k, last)

    def simulate_inputs(self, states, iterations, residual_norms, p, inputs, upcoming,
                        options: NewtonOptions, warm) -> ChunkRun:
        """:meth:`_Kernel.simulate_inputs` in one ``<prefix>_simulate`` call, which reads
        the inputs of step k from row k of ``inputs`` (docs/conventions.md §20)."""
        rows = _run_buffers(states, iterations, residual_norms, self.n_k)
        p = real_vector(p, self.n_p, "p")
        inputs = self._input_table(inputs, self.n_in)
        if len(inputs) > rows - 1 or not (np.isfinite(states[0]).all()
                                          and np.isfinite(p).all()):
            return ChunkRun(INVALID_ARGUMENT, 0, -1, np.zeros(self.n_u))
        self._check_warm(warm)
        n = self.n_k
        base = self._buf(states, rows * n, "states")
        its = self._buf(iterations, rows - 1, "iterations", "int")
        norms = self._buf(residual_norms, rows - 1, "residual_norms")
        pb, opts = self._buf(p, self.n_p, "p"), self._options(options)
        last = np.zeros(self.n_u)
        lastb, failed = self._buf(last, self.n_u, "last_iterate"), self.ffi.new("long *")
        ub = self._buf(inputs, inputs.size, "inputs")
        status = int(self._f["simulate"](base, pb, ub, len(inputs), opts, warm, base, rows, its,
                                         norms, failed, lastb))
        if status != OK:
            k = max(int(failed[0]), 0)
            return ChunkRun(status, k, k, last)
        return ChunkRun(OK, len(inputs), -1, last)

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

    def _input_jacobian(self, u, known, p, columns: int) -> np.ndarray:
        if columns != self.n_input_columns or not self.n_input_columns:
            raise ShapeError(f"{self.prefix}: the kernel's input Jacobian has "
                             f"{self.n_input_columns} columns (the inputs of the terms a step "
                             f"reads), not {columns}")
        J = np.empty((self.n_u, columns))
        getattr(self.lib, f"{self.prefix}_input_jacobian")(
            self._buf(u, self.n_u, "u"), self._buf(known, self.n_k, "known"),
            self._buf(p, self.n_p, "p"), self._buf(J, self.n_u * columns, "J_inputs"))
        return J

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

    def _domain(self, u, known, p) -> np.ndarray:
        n = int(getattr(self.lib, f"{self.prefix.upper()}_N_DOMAIN", 0))
        out = np.empty(n)
        if n:
            getattr(self.lib, f"{self.prefix}_domain")(
                self._buf(u, self.n_u, "u"), self._buf(known, self.n_k, "known"),
                self._buf(p, self.n_p, "p"), self._buf(out, n, "D"))
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
            self._buf(known0, self.n_k, "known0"), self._buf(p, self.n_p, "p"), self.ffi.NULL,
            n_steps,
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
            status = step_function(at, held[3], ffi.NULL, held[1], view)
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
        status = simulate(at, held[3], null, 1, held[1], null, view, 2, block[0], block[1], null,
                          null)
        after = out[1]
        returned[0] = (after, view + n_k)
        return status, after

    return step_by_simulate


__all__ = ["CKernel"]
