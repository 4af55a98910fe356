"""Many trajectories at once: checked input tables and :meth:`Simulator.simulate_batch`.

A batch is B independent runs of the same step, from the rows of a state table with the rows
of a parameter table (or one parameter set for all).  The compiled kernel advances them by
``<prefix>_simulate_batch_until`` (see symgroupoid/stepper/batch.c): each run by the very function
:meth:`Simulator.simulate` uses, in installments with the Newton warm start carried across
them, so the states are bitwise those of B separate ``simulate`` calls (and of one
``<prefix>_simulate_batch`` call).  :class:`BatchProgress` shares groups of runs among
threads (the kernel releases the GIL) in calls of about :data:`CALL_SECONDS`, so Ctrl-C, or
a sweep's stop, takes effect within a call, with the partial batch.

Layout: the states of run b are one contiguous block (rows × n_known, row-major), the runs one
after the other.  The Newton solve of a step is branchy (pivoting, chord or refactor, the
convergence tests differ per run), so interleaving runs lane by lane (structure of arrays)
would run every lane through every branch; what the compiler vectorises is the straight-line
residual and Jacobian code within a run, which this layout keeps on contiguous memory.

Inputs are checked as :meth:`Simulator.state` and :meth:`Simulator.parameters` check one
state and one parameter set, but vectorised over the rows: every row is screened with NumPy
against half of each tolerance, and a row the screen flags goes through the scalar check,
which decides and raises its own error, prefixed with the row's index.  Rows the screen
passes are far inside the tolerances, so the outcome is the scalar check's for every row.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Mapping, Sequence

import numpy as np

from .._arguments import ndim
from .._errors import (
    DomainError,
    InputTypeError,
    ParameterError,
    ShapeError,
    SymgroupoidError,
)
from ..stepper import MAX_THREADS
from ._options import NewtonOptions
from ._runs import INTERRUPTED, OK, BatchRun, batch_rows
from ._trajectory import Trajectory
from ._validate import (
    _CHECKED_ASSUMPTIONS,
    CONSTRAINT_ROUNDING,
    GROUP_TOLERANCE,
    _declared,
    constraint_check,
    integer_argument,
    offset_element,
    real_array,
)

_EPS = float(np.finfo(float).eps)

#: seconds of work aimed at per kernel call of a batch: bounds the delay of Ctrl-C and of a
#: sweep's cancel (long runs are split across calls, the warm start carried between them)
CALL_SECONDS = 0.05
#: runs per group of a batch: a thread advances a group of runs at a time (their cursors
#: held), in pieces of many steps (few runs per call, long pieces: the runs' data stays in
#: cache and the per-call cost is spread over many steps)
GROUP_RUNS = 32


class RunIndexError(ShapeError, IndexError):
    """A run number outside a batch (also an ``IndexError``)."""


def _at_row(error: Exception, what: str, index) -> Exception:
    """``error`` (from the scalar check of one row) with the row named in front."""
    label = index if isinstance(index, tuple) else (index,)
    text = f"{what} {', '.join(str(i) for i in label)}: {error}"
    try:
        return type(error)(text)
    except TypeError:  # an error class with another constructor: keep it as it is
        return error


# --- parameters ---------------------------------------------------------------------------------

def _is_scalar(value) -> bool:
    return ndim(value) == 0 and not isinstance(value, (Mapping, str, bytes))


def _looks_like_one_set(params, n_params: int) -> bool:
    """A single parameter set: None, a mapping of scalars, or a flat sequence of numbers."""
    if params is None:
        return True
    if isinstance(params, Mapping):
        return all(_is_scalar(v) for v in params.values())
    if hasattr(params, "columns") and hasattr(params, "to_numpy"):  # a DataFrame
        return False
    if isinstance(params, np.ndarray):
        return params.ndim <= 1
    if isinstance(params, Sequence) and not isinstance(params, (str, bytes)):
        return all(_is_scalar(v) for v in params)  # (a wrong count: the set's own error)
    return True


def _column_rows(sim, table: Mapping) -> list[dict]:
    """The rows of a mapping name → column (all columns of one length)."""
    lengths = {str(k): len(v) if ndim(v) == 1 else None for k, v in table.items()}
    bad = [k for k, n in lengths.items() if n is None]
    if bad:
        raise ParameterError(f"{sim.name}: a parameter table maps each name to a column of "
                             f"values (one per set); {', '.join(bad)} is not a 1-D column")
    if len(set(lengths.values())) > 1:
        raise ParameterError(f"{sim.name}: the parameter columns have different lengths "
                             f"{lengths}")
    n = next(iter(lengths.values()), 0)
    return [{k: v[i] for k, v in table.items()} for i in range(n)]


def parameter_table(sim, params) -> tuple[np.ndarray, bool]:
    """(P, one): the parameter sets as rows of P (m, n_params), checked, and whether
    ``params`` was a single set (m = 1).

    ``params``: one set (as :meth:`Simulator.parameters` takes it), or a table of sets: a
    sequence of sets, a 2-D array (m, n_params), a mapping name → column of m values, or a
    pandas DataFrame with one column per parameter.
    """
    n_p = len(sim.parameter_names)
    if _looks_like_one_set(params, n_p):
        return sim.parameters(params)[None, :], True
    if hasattr(params, "columns") and hasattr(params, "to_numpy"):
        params = {str(c): np.asarray(params[c].to_numpy()) for c in params.columns}
    if isinstance(params, Mapping):
        rows: Sequence = _column_rows(sim, params)
        if not rows:
            raise ParameterError(f"{sim.name}: the parameter table is empty")
        sim.parameters(rows[0])  # names: unknown, missing, repeated
        columns = [np.asarray(params[k] if k in params else params[_key(params, k)])
                   for k in sim.parameter_names]
        values = _numeric_columns(columns, len(rows))
        return _checked_rows(sim, values, lambda i: rows[i]), False
    if isinstance(params, np.ndarray) and params.ndim == 2 and params.dtype.kind in "iuf":
        if params.shape[1] != n_p:
            raise ParameterError(f"{sim.name}: a parameter table has one column per parameter "
                                 f"({n_p}: {', '.join(sim.parameter_names) or 'none'}); got "
                                 f"shape {params.shape}")
        values = np.array(params, dtype=float)
        return _checked_rows(sim, values, lambda i: params[i]), False
    if isinstance(params, (np.ndarray, Sequence)) and not isinstance(params, (str, bytes)):
        sets = list(params)
        if not sets:
            raise ParameterError(f"{sim.name}: the parameter table is empty")
        out = np.empty((len(sets), n_p))
        for i, one in enumerate(sets):
            try:
                out[i] = sim.parameters(one)
            except SymgroupoidError as err:
                raise _at_row(err, "parameter set", i) from err
        return out, False
    raise ParameterError(f"{sim.name}: parameters must be one set (a mapping name → value or "
                         f"a sequence of {n_p} values) or a table of sets, got "
                         f"{type(params).__name__}")


def _key(table: Mapping, name: str):
    return next(k for k in table if str(k) == name)


def _numeric_columns(columns: list[np.ndarray], n: int) -> np.ndarray:
    """Float columns (m, n_params); NaN marks an entry that is not a real number (the scalar
    check of its row then reports it)."""
    out = np.empty((n, len(columns)))
    for j, col in enumerate(columns):
        if col.dtype.kind in "iuf":
            out[:, j] = col.astype(float)
        else:
            out[:, j] = np.nan
    return out


def _assumption_holds(key: str, v: np.ndarray) -> np.ndarray | None:
    """Whether the exact rational numbers ``v`` have the property ``key``; None when not
    vectorised (then every row goes through the scalar check)."""
    integral = np.floor(v) == v
    tests = {
        "positive": v > 0, "negative": v < 0, "nonnegative": v >= 0, "nonpositive": v <= 0,
        "zero": v == 0, "nonzero": v != 0, "integer": integral, "noninteger": ~integral,
        "even": integral & (np.fmod(v, 2) == 0), "odd": integral & (np.abs(np.fmod(v, 2)) == 1),
    }
    return tests.get(key)


def _checked_rows(sim, values: np.ndarray, row) -> np.ndarray:
    """``values`` (m, n_params) after the vectorised screen; a flagged row is checked by
    :meth:`Simulator.parameters` (``row(i)``: the row as given), which raises."""
    flagged = ~np.isfinite(values).all(axis=1)
    with np.errstate(invalid="ignore"):
        for j, symbol in enumerate(sim.equations.parameters):
            for key, expected in _declared(symbol) if hasattr(symbol, "assumptions0") else ():
                if key not in _CHECKED_ASSUMPTIONS:
                    continue
                holds = _assumption_holds(key, values[:, j])
                flagged |= np.ones(len(values), bool) if holds is None else holds != expected
    for i in np.flatnonzero(flagged):
        try:
            values[i] = sim.parameters(row(int(i)))
        except SymgroupoidError as err:
            raise _at_row(err, "parameter set", int(i)) from err
    return values


# --- states -------------------------------------------------------------------------------------

def _group_matrices(group, coords: np.ndarray) -> np.ndarray:
    """The matrices (B, n, n) of arrow coordinates (B, arrow_dim) of a matrix Lie group."""
    free = getattr(group, "_free", None)
    if free is not None and len(free) == coords.shape[1]:
        M = np.broadcast_to(np.eye(group.n), (len(coords), group.n, group.n)).copy()
        for k, (i, j) in enumerate(free):
            M[:, i, j] = coords[:, k]
        return M
    return np.array([group.numeric_matrix(c) for c in coords]).reshape(-1, group.n, group.n)


def _group_screen(group, M: np.ndarray) -> np.ndarray:
    """Rows whose matrix is not clearly in ``group`` (half of :data:`GROUP_TOLERANCE`)."""
    half = GROUP_TOLERANCE / 2
    n = group.n - 1 if group.affine else group.n
    flagged = np.zeros(len(M), bool)
    if group.affine:
        last = np.zeros(group.n)
        last[-1] = 1.0
        flagged |= ~(np.abs(M[:, -1, :] - last).max(axis=1) <= half)
    R = M[:, :n, :n]
    with np.errstate(all="ignore"):
        off = np.abs(np.einsum("bki,bkj->bij", R, R) - np.eye(n)).max(axis=(1, 2))
        flagged |= ~(off <= half)
        flagged |= ~(np.abs(np.linalg.det(R) - 1.0) <= half)
    return flagged


def state_table(sim, initial) -> tuple[np.ndarray, bool]:
    """(S, one): the initial states as rows of S (B, n_known), each checked as
    :meth:`Simulator.state` checks it (without the constraints, which need the parameters:
    :func:`check_constraints`), and whether ``initial`` was a single state.

    ``initial``: one state (a mapping of named parts, or a flat vector), or a table: a 2-D
    array (B, n_known), or a sequence of states.  Entries are read by the one rule for real
    arrays (:func:`~symgroupoid._arguments.real_array`): strings, booleans, complex
    numbers and dates are refused, as :meth:`Simulator.state` refuses them.
    """
    n_k = sim.layout.n_known
    if isinstance(initial, (Mapping, str, bytes)) or initial is None:
        return sim.state(initial)[None, :], True  # one state, or the state's own error
    if isinstance(initial, np.ndarray) and initial.ndim != 2:
        if initial.ndim <= 1:
            return sim.state(initial)[None, :], True
        raise ShapeError(f"{sim.name}: a table of flat states has shape (B, {n_k}) (the "
                         f"knowns {', '.join(s.name for s in sim.equations.knowns)}); got "
                         f"shape {initial.shape}")
    if not isinstance(initial, (Sequence, np.ndarray)):
        return sim.state(initial)[None, :], True  # refused there, with its message
    rows = list(initial)
    if not isinstance(initial, np.ndarray):
        if rows and all(_is_scalar(v) for v in rows):
            return sim.state(initial)[None, :], True
        if not rows:
            raise ShapeError(f"{sim.name}: the table of initial states is empty")
    if all(not isinstance(r, Mapping) for r in rows):
        try:
            arr = real_array(rows if rows else initial, "the table of initial states",
                             owner=sim.name)
        except ShapeError:
            arr = None  # each row is checked below, and reported by its index
        if arr is not None and arr.ndim == 2 and arr.shape[1] == n_k:
            return _screened_states(sim, arr), False
        if isinstance(initial, np.ndarray) and arr is not None:
            raise ShapeError(f"{sim.name}: a table of flat states has shape (B, {n_k}) (the "
                             f"knowns {', '.join(s.name for s in sim.equations.knowns)}); "
                             f"got shape {arr.shape}")
    out = np.empty((len(rows), n_k))
    for i, one in enumerate(rows):
        try:
            out[i] = sim.state(one)
        except SymgroupoidError as err:
            raise _at_row(err, "initial state", i) from err
    return out, False


def _screened_states(sim, S: np.ndarray) -> np.ndarray:
    """Flat states (B, n_known): finiteness and every matrix part of every known arrow
    screened in bulk, flagged rows checked (and reported) by :meth:`Simulator.state`."""
    flagged = ~np.isfinite(S).all(axis=1)
    groupoid = sim.layout.groupoid
    safe = np.where(np.isfinite(S), S, 0.0)
    for index in sim.layout.arrow_index.values():
        for start, group in groupoid.matrix_parts():
            coords = safe[:, index[start:start + group.arrow_dim]]
            flagged |= _group_screen(group, _group_matrices(group, coords))
        for start, group in groupoid.offset_parts():  # increments stored as F − I
            offsets = safe[:, index[start:start + group.arrow_dim]]
            flagged |= _group_screen(group, offset_element(group, offsets))
    for part in sim.layout.parts.values():  # every group part (a pair groupoid's R_k too)
        if part.group is not None:
            index = np.where(part.index >= 0, part.index, 0)
            values = np.where(part.index >= 0, safe[:, index] + part.fixed, part.fixed)
            for o in range(values.shape[1]):
                flagged |= _group_screen(part.group, values[:, o])
    if flagged.any():
        S = np.array(S, dtype=float)  # flagged rows become what simulate starts from
    for i in np.flatnonzero(flagged):
        try:
            S[i] = sim.state(S[i])  # a group part given to a few digits: its nearest element
        except SymgroupoidError as err:
            raise _at_row(err, "initial state", int(i)) from err
    return S


def check_constraints(sim, S: np.ndarray, P: np.ndarray, atol: float,
                      labels=None) -> None:
    """The system's constraints on every pair (S[i], P[i]) (rows of equal count, or one
    parameter row for all), as :meth:`Simulator.state` checks them with parameters; the
    first violating pair raises the scalar check's :class:`DomainError`, naming the row
    (``labels(i)``: its index as the caller shows it)."""
    check = constraint_check(sim.equations)
    if not check.windows or not len(S):
        return
    P = np.broadcast_to(P, (len(S), P.shape[-1]))
    flagged = np.zeros(len(S), bool)
    try:
        for _, index in check.windows:
            X = S[:, index].T
            cols = list(P.T)
            with np.errstate(all="ignore"):
                values = [np.broadcast_to(np.asarray(v, float), (len(S),))
                          for v in check._phi(X, cols)]
                sizes = [np.broadcast_to(np.asarray(v, float), (len(S),))
                         for v in check._size(X, cols)]
            for v, size in zip(values, sizes):
                tol = np.maximum(atol, CONSTRAINT_ROUNDING * _EPS * np.nan_to_num(size))
                flagged |= ~(np.abs(v) <= tol / 2)
    except (TypeError, ValueError, IndexError):  # not vectorisable: every row is checked
        flagged[:] = True
    for i in np.flatnonzero(flagged):
        try:
            check(S[i], P[i], atol=atol, owner=sim.name)
        except DomainError as err:
            if labels is None:
                raise _at_row(err, "initial state", int(i)) from err
            state, pset = labels(int(i))
            raise _at_row(err, f"initial state {state} with parameter set", pset) from err


# --- the batch ----------------------------------------------------------------------------------

class TrajectoryBatch:
    """B runs of :meth:`Simulator.simulate_batch`: arrays indexed by run, and each run as the
    :class:`Trajectory` that :meth:`Simulator.simulate` returns for it.

    - ``batch.states`` (B, R, n_known): the kept states of every run (state 0, every e-th,
      the last), R = 1 + ⌈steps/e⌉; ``batch.kept`` (B,): the valid rows of each run.  A run
      that failed at step s ends with state s and has fewer valid rows: its rows past
      ``kept[b]`` are NaN (and its ``newton_iterations`` there −1): they are not data.
    - ``batch.newton_iterations``, ``batch.residual_norms`` (B, R − 1): per interval between
      kept states, as in :class:`Trajectory`;
    - ``batch.status`` (B,): 0 for a completed run, else the kernel's status
      (1 singular Jacobian, 2 Newton's iteration cap, 3 non-finite value, 5 Newton stalled
      above the rounding floor, 6 a branch jump: :class:`~symgroupoid.Status`, with its
      ``message``), or ``INTERRUPTED`` (10) for a run that Ctrl-C stopped (in the partial
      batch of an interrupted call); ``batch.ok``; ``batch.failed_step`` (B,): the failing
      step s (the step an interrupted run reached), −1 for a completed run;
    - ``batch[b]``: run b as a :class:`Trajectory` (a failed run: up to state s, as
      ``err.trajectory`` of the error ``simulate`` raises); ``batch.error(b)``: that error;
    - ``batch.final_states`` (B, n_known): the last state each run reached;
    - ``batch.parameters`` (B, n_params): the parameters of each run.
    """

    def __init__(self, sim, raw: BatchRun, parameters: np.ndarray, steps: int, every: int,
                 options: NewtonOptions | None = None, *, fill: bool = True):
        """(``fill=False`` leaves the rows past each run's end as they are: for a caller
        that hands out each run's own rows only, ``batch[b]``, as sweeps do.)"""
        self._sim = sim
        self._options = sim.options if options is None else options
        self._raw = raw
        self.steps, self.every = int(steps), int(every)
        self.parameters = np.broadcast_to(parameters, (len(raw.kept), parameters.shape[-1]))
        self.states = raw.states
        self.kept = raw.kept
        self.newton_iterations = raw.iterations
        self.residual_norms = raw.residual_norms
        self.status = raw.status.astype(np.int64)
        self.failed_step = raw.failed_step
        rows = self.states.shape[1]
        short = np.flatnonzero(self.kept < rows) if fill and self.states.flags.writeable \
            else ()
        for b in short:
            k = int(self.kept[b])
            self.states[b, k:] = np.nan
            self.newton_iterations[b, max(k - 1, 0):] = -1
            self.residual_norms[b, max(k - 1, 0):] = np.nan
        for arr in (self.states, self.kept, self.newton_iterations, self.residual_norms,
                    self.status, self.failed_step):
            arr.setflags(write=False)

    def __len__(self) -> int:
        return len(self.kept)

    @property
    def ok(self) -> np.ndarray:
        """(B,) True for the runs that completed every step."""
        return self.status == OK

    @property
    def final_states(self) -> np.ndarray:
        """(B, n_known) the last state each run reached (state N, or s for a failed run)."""
        return self.states[np.arange(len(self)), self.kept - 1].copy()

    def step_indices(self, b: int) -> np.ndarray:
        """The step index of each kept state of run b."""
        b = self._run(b)
        k = int(self.kept[b])
        out = np.arange(k, dtype=np.int64) * self.every
        if k > 1:
            out[-1] = self.steps if self.status[b] == OK else int(self.failed_step[b])
        return out

    def _run(self, b) -> int:
        """``b`` as a run number 0 … B − 1 (negative counts from the end)."""
        if isinstance(b, (bool, np.bool_)) or not isinstance(b, (int, np.integer)):
            raise InputTypeError(f"{self._sim.name}: a batch is indexed by run number, got "
                                 f"{type(b).__name__} {b!r}")
        run = int(b) + (len(self) if b < 0 else 0)
        if not 0 <= run < len(self):
            raise RunIndexError(f"{self._sim.name}: run {int(b)} out of range for a batch of "
                                f"{len(self)}")
        return run

    def __getitem__(self, b: int) -> Trajectory:
        b = self._run(b)
        k = int(self.kept[b])
        sim = self._sim
        return sim._trajectory(self.states[b, :k], self.newton_iterations[b, :k - 1],
                               self.residual_norms[b, :k - 1], self.parameters[b],
                               self.step_indices(b), self.every)

    def __iter__(self):
        return (self[b] for b in range(len(self)))

    def error(self, b: int) -> Exception | None:
        """The error :meth:`Simulator.simulate` raises for run b (None if it completed), with
        ``.trajectory`` the run up to the failing step."""
        b = self._run(b)
        if self.status[b] == OK:
            return None
        if self.status[b] == INTERRUPTED:
            err = KeyboardInterrupt(f"{self._sim.name}: run {b} was interrupted at step "
                                    f"{int(self.failed_step[b])}")
            err.trajectory = self[b]
            return err
        raw = self._raw
        run = self[b]
        err = self._sim._failure(int(self.status[b]), int(self.failed_step[b]),
                                 int(raw.failed_iterations[b]),
                                 float(raw.failed_residual_norms[b]), raw.last_iterate[b],
                                 self._options,
                                 known=run.states[-1] if len(run.states) else None,
                                 p=self.parameters[b])
        err.trajectory = run
        return err

    def __repr__(self) -> str:
        failed = int((~self.ok).sum())
        return (f"<TrajectoryBatch {self._sim.name!r}: {len(self)} runs of {self.steps} steps"
                f"{f', every {self.every}' if self.every != 1 else ''}, {failed} failed>")


def available_memory() -> int | None:
    """Bytes this process may still allocate at most: the machine's physical memory,
    lowered by what the address-space and data-segment limits (``ulimit -v``,
    ``ulimit -d``) leave beyond what is mapped already; None when unknown."""
    try:
        limit = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        limit = None
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return limit
    mapped = _mapped_bytes()
    for which, used in (("RLIMIT_AS", mapped[0]), ("RLIMIT_DATA", mapped[1])):
        soft = resource.getrlimit(getattr(resource, which))[0]
        if soft not in (resource.RLIM_INFINITY, -1) and soft > 0:
            room = max(soft - used, 0)
            limit = room if limit is None else min(limit, room)
    return limit if limit is None or limit > 0 else 0


def _mapped_bytes() -> tuple[int, int]:
    """(address space, data segment) this process has mapped, from /proc/self/statm
    (zeros where it cannot be read)."""
    try:
        with open("/proc/self/statm") as f:
            fields = f.read().split()
        page = os.sysconf("SC_PAGE_SIZE")
        return int(fields[0]) * page, int(fields[5]) * page
    except (OSError, ValueError, IndexError):
        return 0, 0


def run_bytes(sim, rows: int) -> int:
    """Bytes a run of a batch holds with ``rows`` kept states (states, Newton summaries and
    its share of the per-run arrays)."""
    return rows * (8 * sim.layout.n_known + 16) + 8 * (len(sim.equations.unknowns) + 6)


#: what to do when the kept states do not fit
KEEP_FEWER = "keep fewer with every=k, or reduce each run on the fly with sweep(..., reduce=...)"


def _too_large(sim, runs: int, rows: int, steps: int, every: int, limit: int | None,
               held: str = "", failed: Exception | None = None,
               advice: str = KEEP_FEWER) -> Exception:
    from .._errors import TrajectoryTooLargeError

    needed = runs * run_bytes(sim, rows)
    if failed is not None:
        room = f"which could not be allocated ({type(failed).__name__}: {failed})"
    elif limit is not None:
        room = f"more than this process may allocate ({limit / 2**30:.1f} GiB)"
    else:
        room = "more than this process could allocate"
    return TrajectoryTooLargeError(
        f"{sim.name}: keeping {rows} states (steps={steps}, every={every}) of each of "
        f"{runs} runs{held} needs {needed / 2**30:.1f} GiB, {room}; {advice}")


def _check_memory(sim, runs: int, rows: int, steps: int, every: int, held: str = "",
                  advice: str = KEEP_FEWER) -> None:
    """A :class:`TrajectoryTooLargeError` up front when ``runs`` runs of ``rows`` kept
    states would not fit in :func:`available_memory`."""
    limit = available_memory()
    if limit is not None and runs * run_bytes(sim, rows) > limit:
        raise _too_large(sim, runs, rows, steps, every, limit, held, advice=advice)


def _view(raw: BatchRun, a: int, z: int) -> BatchRun:
    """Runs a … z − 1 of a batch's arrays (views)."""
    return BatchRun(*(getattr(raw, name)[a:z] for name in BatchRun.__dataclass_fields__))


class BatchProgress:
    """A batch advanced in kernel calls of about :data:`CALL_SECONDS` each, by one or more
    threads (lanes).

    The runs go in groups of at most :data:`GROUP_RUNS` (fewer when that leaves a lane
    idle); a lane takes the next group and advances it with
    ``<prefix>_simulate_batch_until`` (one thread per call) in pieces of steps sized so
    that a call takes about :data:`CALL_SECONDS` (the first piece one step, then at most
    four times the last), the Newton warm start of every run carried in its cursor from
    piece to piece, so the result is bitwise that of one ``<prefix>_simulate_batch`` call.
    The kernel releases the GIL, so lanes run in parallel; between calls a lane sees
    ``stop()`` (and Ctrl-C takes effect on the main thread); :meth:`so_far` is then the
    partial batch.  The arrays of all runs are allocated up front: a
    :class:`TrajectoryTooLargeError` (not a ``MemoryError``) when they cannot be.
    """

    def __init__(self, sim, S: np.ndarray, P: np.ndarray, steps: int, every: int,
                 options: NewtonOptions | None, lanes: int = 1):
        self.sim, self.kernel = sim, sim.kernel
        self.S = np.ascontiguousarray(S, dtype=np.float64)
        self.P = np.ascontiguousarray(P if len(P) > 1 else P[0], dtype=np.float64)
        self.steps, self.every = int(steps), int(every)
        self.options = options or sim.options
        rows = batch_rows(steps, every)
        try:
            self.out = self.kernel._batch_buffers(len(S), steps, every)
        except MemoryError as exc:
            raise _too_large(sim, len(S), rows, steps, every, None, failed=exc) from None
        B = len(S)
        self.group_runs = max(1, min(GROUP_RUNS, -(-B // max(lanes, 1))))
        self.lanes = max(1, min(lanes, -(-B // self.group_runs)))
        self.next_run = 0
        self.active: dict = {}  # lane → (first run, end, cursors) of the group it advances
        self._lock = threading.Lock()

    def _take(self, lane: int):
        with self._lock:
            a = self.next_run
            if a >= len(self.S):
                return None
            z = min(len(self.S), a + self.group_runs)
            group = (a, z, self.kernel.batch_cursors(z - a))
            self.next_run = z
            self.active[lane] = group
            return group

    def work(self, lane: int = 0, stop=None) -> bool:
        """Lane ``lane``: advance groups until none is left (True) or ``stop()`` (False)."""
        cost = None  # wall seconds per run-step of this lane
        while True:
            group = self._take(lane)
            if group is None:
                return True
            a, z, cursors = group
            view = _view(self.out, a, z)
            P = self.P[a:z] if self.P.ndim == 2 else self.P
            until = 0
            piece = 1 if cost is None else max(1, int(CALL_SECONDS / (cost * (z - a))))
            while True:
                target = min(self.steps, until + piece)
                t0 = time.perf_counter()
                self.kernel.batch_until(cursors, self.S[a:z], P, self.steps, self.every,
                                        target, self.options, view, 1)
                seconds = time.perf_counter() - t0
                if target > until and seconds > 0:
                    cost = seconds / ((z - a) * (target - until))
                    piece = max(1, min(4 * piece, int(CALL_SECONDS / (cost * (z - a)))))
                else:
                    piece *= 4
                until = target
                if until >= self.steps:
                    break
                if stop is not None and stop():
                    return False
            self.kernel.batch_sync(cursors, view)
            del self.active[lane]
            if stop is not None and self.next_run < len(self.S) and stop():
                return False

    def run(self, stop=None) -> bool:
        """Every lane (the first on this thread, the others on threads of their own) until
        the batch is done (True) or ``stop()`` (False).  Ctrl-C: the other lanes are
        stopped after their current call, then the ``KeyboardInterrupt`` propagates."""
        if self.lanes == 1:
            return self.work(0, stop)
        halt = threading.Event()

        def halted() -> bool:
            return halt.is_set() or (stop is not None and stop())

        errors: list = []

        def lane_work(lane: int) -> None:
            try:
                self.work(lane, halted)
            except BaseException as exc:  # noqa: BLE001 - re-raised on the calling thread
                errors.append(exc)
                halt.set()

        threads = [threading.Thread(target=lane_work, args=(lane,), daemon=True,
                                    name=f"symgroupoid-batch-{lane}")
                   for lane in range(1, self.lanes)]
        for thread in threads:
            thread.start()
        try:
            self.work(0, halted)
            for thread in threads:
                while thread.is_alive():
                    thread.join(0.1)
        finally:
            halt.set()
            for thread in threads:
                thread.join()
        if errors:
            raise errors[0]
        return self.next_run >= len(self.S) and not self.active

    def so_far(self) -> BatchRun:
        """The partial batch: completed and failed runs as they are, a run being advanced
        with the state it reached appended (status ``INTERRUPTED``, ``failed_step`` that
        step), a run not begun with state 0 (step 0); rows up to the furthest run's."""
        out = self.out
        kept, status, failed = out.kept.copy(), out.status.copy(), out.failed_step.copy()
        for a, z, cursors in list(self.active.values()):
            view = _view(out, a, z)
            self.kernel.batch_sync(cursors, view)
            kept[a:z], status[a:z], failed[a:z] = view.kept, view.status, view.failed_step
            reached = self.kernel.batch_reached(cursors, view)
            for j in np.flatnonzero((view.status == OK) & (view.kept > 0)):
                b = a + j
                if reached["done"][j] >= self.steps:
                    continue
                if reached["done"][j] != reached["last_kept"][j]:  # the state reached
                    r = int(kept[b])
                    out.states[b, r] = reached["known"][j]
                    out.iterations[b, r - 1] = reached["carry_iterations"][j]
                    out.residual_norms[b, r - 1] = reached["carry_norm"][j]
                    kept[b] = r + 1
                status[b], failed[b] = INTERRUPTED, reached["done"][j]
        fresh = np.flatnonzero((status == OK) & (kept == 0))
        out.states[fresh, 0] = self.S[fresh]
        kept[fresh], status[fresh], failed[fresh] = 1, INTERRUPTED, 0
        rows = max(int(kept.max(initial=1)), 1)  # (no row past the furthest run)
        return BatchRun(out.states[:, :rows], out.iterations[:, :rows - 1],
                        out.residual_norms[:, :rows - 1], kept, status, failed,
                        out.failed_iterations, out.failed_residual_norms, out.last_iterate)


def usable_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def batch_lanes(sim, threads: int | None) -> int:
    """Threads a batch runs on: ``threads``, or every core this process may use (one for
    the NumPy backend, which holds the GIL)."""
    if sim.backend != "c":
        return 1
    return usable_cores() if threads is None else threads


def run_batch(sim, S: np.ndarray, P: np.ndarray, steps: int, every: int,
              options: NewtonOptions | None, threads: int | None, stop=None) -> BatchRun:
    """Checked tables in, raw batch out (:class:`BatchProgress` on ``threads`` lanes):
    Ctrl-C takes effect within a kernel call, the ``KeyboardInterrupt`` carrying
    ``.raw_batch``, the partial batch; ``stop()`` (asked between calls) ends it early, with
    the partial batch as the result."""
    progress = BatchProgress(sim, S, P, steps, every, options, batch_lanes(sim, threads))
    try:
        complete = progress.run(stop)
    except KeyboardInterrupt as interrupt:
        interrupt.raw_batch = progress.so_far()
        raise
    return progress.out if complete else progress.so_far()


def simulate_batch(sim, states, steps: int, params, *, every: int = 1,
                   options: NewtonOptions | None = None,
                   threads: int | None = None) -> TrajectoryBatch:
    """See :meth:`Simulator.simulate_batch`."""
    steps = integer_argument(steps, "steps", owner=sim.name)
    every = integer_argument(every, "every", minimum=1, owner=sim.name)
    options = NewtonOptions.of(options, sim.options, owner=sim.name)
    if threads is not None:
        threads = integer_argument(threads, "threads", minimum=1, maximum=MAX_THREADS,
                                   owner=sim.name)
    S, _ = state_table(sim, states)
    P, one = parameter_table(sim, params)
    if not one and len(P) != len(S):
        raise ShapeError(f"{sim.name}: {len(S)} initial states but {len(P)} parameter sets; "
                         f"give one set for all, or one per state")
    from ._simulator import INITIAL_CONSTRAINT_TOLERANCE

    check_constraints(sim, S, P, INITIAL_CONSTRAINT_TOLERANCE)
    _check_memory(sim, len(S), batch_rows(steps, every), steps, every)
    try:
        raw = run_batch(sim, S, P, steps, every, options, threads)
    except KeyboardInterrupt as interrupt:
        interrupt.batch = TrajectoryBatch(sim, interrupt.raw_batch, P, steps, every, options)
        raise
    return TrajectoryBatch(sim, raw, P, steps, every, options)
