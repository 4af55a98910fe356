"""What the kernels return: a run of steps, a chunk of a run written in place, a batch,
the cursor of a batch run advanced in installments; and a run computed in chunks."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..stepper import Status
from ._options import NewtonOptions

OK = Status.OK
#: the status of a batch run stopped from outside before its last step (Ctrl-C, a sweep's
#: timeout): not a kernel status
INTERRUPTED = Status.INTERRUPTED


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


__all__ = ["BatchRun", "ChunkRun", "INTERRUPTED", "RawRun", "RunCursor", "batch_rows",
           "run_chunks"]
