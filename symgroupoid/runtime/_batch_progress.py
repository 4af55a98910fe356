"""A batch advanced in kernel calls of bounded length, on one or more threads (lanes).

The compiled kernel advances the runs of a batch by ``<prefix>_simulate_batch_until`` (see
symgroupoid/stepper/batch.c): each run by the very function :meth:`Simulator.simulate`
uses, in installments with the Newton warm start carried across them, so the states are
bitwise those of B separate ``simulate`` calls (and of one ``<prefix>_simulate_batch``
call).  :class:`BatchProgress` shares groups of runs among threads (the kernel releases the
GIL) in calls of about :data:`CALL_SECONDS`, so Ctrl-C, or a sweep's stop, takes effect
within a call, with the partial batch.
"""

from __future__ import annotations

import os
import threading
import time

import numpy as np

from ._memory import too_large
from ._options import NewtonOptions
from ._runs import INTERRUPTED, OK, BatchRun, batch_rows

#: seconds of work aimed at per kernel call of a batch: bounds the delay of Ctrl-C and of a
#: sweep's cancel (long runs are split across calls, the warm start carried between them)
CALL_SECONDS = 0.05
#: runs per group of a batch: a thread advances a group of runs at a time (their cursors
#: held), in pieces of many steps (few runs per call, long pieces: the runs' data stays in
#: cache and the per-call cost is spread over many steps)
GROUP_RUNS = 32


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
    ``U``: the inputs of a forced system's runs (B, steps, m), or (steps, m) for all, or
    None (docs/conventions.md §20).
    """

    def __init__(self, sim, S: np.ndarray, P: np.ndarray, steps: int, every: int,
                 options: NewtonOptions | None, lanes: int = 1, U: np.ndarray | None = None):
        self.sim, self.kernel = sim, sim.kernel
        self.S = np.ascontiguousarray(S, dtype=np.float64)
        self.P = np.ascontiguousarray(P if len(P) > 1 else P[0], dtype=np.float64)
        self.U = None if U is None else np.ascontiguousarray(U, dtype=np.float64)
        self.steps, self.every = int(steps), int(every)
        self.options = options or sim.options
        rows = batch_rows(steps, every)
        try:
            self.out = self.kernel._batch_buffers(len(S), steps, every)
        except MemoryError as exc:
            raise too_large(sim, len(S), rows, steps, every, None, failed=exc) from None
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
            U = self.U[a:z] if self.U is not None and self.U.ndim == 3 else self.U
            until = 0
            piece = 1 if cost is None else max(1, int(CALL_SECONDS / (cost * (z - a))))
            while True:
                target = min(self.steps, until + piece)
                t0 = time.perf_counter()
                self.kernel.batch_until(cursors, self.S[a:z], P, self.steps, self.every,
                                        target, self.options, view, 1, U)
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
              options: NewtonOptions | None, threads: int | None, stop=None,
              U: np.ndarray | None = None) -> BatchRun:
    """Checked tables in (``U``: the checked inputs, or None), raw batch out
    (:class:`BatchProgress` on ``threads`` lanes):
    Ctrl-C takes effect within a kernel call, the ``KeyboardInterrupt`` carrying
    ``.raw_batch``, the partial batch; ``stop()`` (asked between calls) ends it early, with
    the partial batch as the result."""
    progress = BatchProgress(sim, S, P, steps, every, options, batch_lanes(sim, threads), U)
    try:
        complete = progress.run(stop)
    except KeyboardInterrupt as interrupt:
        interrupt.raw_batch = progress.so_far()
        raise
    return progress.out if complete else progress.so_far()
