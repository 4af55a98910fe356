"""The buffers a :meth:`~._simulator.Simulator.simulate` run fills: every state kept and
written in place by the kernel (:class:`WholeRun`), or every e-th state copied in from the
simulator's pieces (:class:`SampledRun`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .._progress import Task
from ._options import NewtonOptions
from ._runs import OK
from ._trajectory import Trajectory

if TYPE_CHECKING:
    from ._simulator import Simulator


class WholeRun:
    """The buffers of a run that keeps every state (``every`` = 1), filled in place.

    The kernel writes each chunk's states, Newton iterations and residual norms straight
    into the arrays of the result (:meth:`~symgroupoid.runtime._backends._Kernel.
    simulate_into`, its first state the last row written; a forced system's chunk
    :meth:`~symgroupoid.runtime._backends._Kernel.simulate_inputs` at the chunk's rows and
    inputs), so a state is written once and never copied; a chunk only marks where progress
    is reported, Ctrl-C is seen and a callback is called.
    """

    def __init__(self, sim: Simulator, known0: np.ndarray, p: np.ndarray, rows: int,
                 inputs: np.ndarray | None = None):
        self.sim, self.p, self.inputs = sim, p, inputs
        self.states = np.empty((rows, sim.layout.n_known))
        self.states[0] = known0
        self.iterations = np.zeros(rows - 1, dtype=np.intc)
        self.norms = np.zeros(rows - 1)
        self.filled = 1

    def advance(self, steps: int, options: NewtonOptions, task: Task, callback,
                chunk_steps: int) -> None:
        kernel, warm = self.sim.kernel, self.sim.kernel.warm_start()
        done = 0
        while done < steps:
            n = min(chunk_steps, steps - done)
            if self.inputs is None:
                chunk = kernel.simulate_into(self.states, self.iterations, self.norms, done,
                                             n, self.p, options, warm)
            else:  # the chunk's rows of the result, which the kernel fills in place
                chunk = kernel.simulate_inputs(
                    self.states[done:done + n + 1], self.iterations[done:done + n],
                    self.norms[done:done + n], self.p, self.inputs[done:done + n],
                    self.sim.layout.upcoming_index, options, warm)
            self.filled = done + chunk.completed + 1
            task.update(done + chunk.completed)
            if chunk.status != OK:
                err = self.sim._chunk_failure(chunk, done, self.iterations, self.norms,
                                              options, self.states, self.p)
                err.trajectory = self.so_far()
                raise err
            if callback is not None:
                callback(self._between(done, done + n))
            done += n

    def add_tail(self, tail) -> None:
        """Nothing to add: a failed chunk wrote its states in place."""

    def _between(self, first: int, last: int) -> Trajectory:
        """States first … last (views of the buffers), with the Newton data of the steps."""
        return self.sim._trajectory(
            self.states[first:last + 1], self.iterations[first:last].astype(np.int64),
            self.norms[first:last], self.p, np.arange(first, last + 1, dtype=np.int64), 1)

    def so_far(self) -> Trajectory:
        return self._between(0, self.filled - 1)


class SampledRun:
    """The buffers of a run that keeps state 0, every e-th state and the last: each chunk's
    kept states (a :class:`Sampler` piece, see :meth:`Simulator.stream`) are copied in."""

    def __init__(self, sim: Simulator, known0: np.ndarray, p: np.ndarray, rows: int,
                 every: int, inputs: np.ndarray | None = None):
        self.sim, self.p, self.every, self.inputs = sim, p, every, inputs
        self.known0 = known0
        self.states = np.empty((rows, sim.layout.n_known))
        self.indices = np.zeros(rows, dtype=np.int64)
        self.iterations = np.zeros(rows - 1, dtype=np.int64)
        self.norms = np.zeros(rows - 1)
        self.states[0] = known0
        self.filled = 1

    def advance(self, steps: int, options: NewtonOptions, task: Task, callback,
                chunk_steps: int) -> None:
        del chunk_steps  # the simulator's pieces are its chunks
        for piece in self.sim._pieces(self.known0, self.p, steps, self.every, options, task,
                                      self.inputs):
            self.add_tail(piece)
            if callback is not None:
                callback(piece)

    def add_tail(self, piece: Trajectory | None) -> None:
        """Append the states of ``piece`` after its first (the last state kept so far)."""
        if piece is None or len(piece) < 2:
            return
        f, r = self.filled, len(piece) - 1
        self.states[f:f + r] = piece.states[1:]
        self.indices[f:f + r] = piece.step_indices[1:]
        self.iterations[f - 1:f - 1 + r] = piece.newton_iterations
        self.norms[f - 1:f - 1 + r] = piece.residual_norms
        self.filled += r

    def so_far(self) -> Trajectory:
        f = self.filled
        return self.sim._trajectory(self.states[:f], self.iterations[:f - 1],
                                    self.norms[:f - 1], self.p, self.indices[:f], self.every)


__all__ = ["SampledRun", "WholeRun"]
