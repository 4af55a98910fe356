"""Per-step inputs of a forced system at run time (docs/conventions.md §20).

The state of a forced system holds the inputs u_k of its arrow g_k and, after them, a slot
for the inputs u_{k+1} of the arrow the next step computes (the step's residual reads both:
f⁺(g_k) + f⁻(g_{k+1})).  Step j of a run reads row j of the input sequence into that slot
of the state it starts from (in C, ``<prefix>_simulate`` reads u[j·m + i]); the states kept
hold their own inputs in the slot.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np

from .._arguments import counted, input_rows, named_columns
from .._errors import DomainError, ShapeError
from ._layout import check_input_values
from ._options import NewtonOptions
from ._runs import OK, RawRun
from ._validate import real_array

_FLOAT64 = np.dtype(np.float64)
_STEP = (8,)  # the strides of a C-contiguous float64 vector


def input_sequence(layout, inputs, steps: int, *, owner: str, one_step: bool = False,
                   held: bool = False) -> np.ndarray:
    """The inputs of a run as an array (steps, m): ``inputs`` of shape (steps, m), (m,)
    for inputs held constant, or (steps,) when m = 1; finite real numbers.  A system
    without inputs takes none.  ``held``: inputs held constant come back as a read-only
    view of their one row (stride 0), checked once, for callers that read the table a
    chunk at a time (a long sampled run then holds no table of its length)."""
    m = layout.n_inputs
    if m == 0:
        if inputs is not None:
            raise ShapeError(f"{owner}: the system has no inputs; leave inputs= out (declare "
                             f"inputs=[...] with forces=... on the system to drive it)")
        return np.zeros((steps, 0))
    names = ", ".join(layout.input_names)
    if inputs is None:
        raise ShapeError(f"{owner}: the system has inputs ({names}); pass inputs= with one "
                         f"row of {counted(m, 'value')} per step (row j: the input of the arrow "
                         f"step j computes), or {counted(m, 'value')} held for every step")
    arr = input_rows(inputs, m, steps, owner=owner, names=layout.input_names)
    if arr.ndim != 2 or arr.shape != (steps, m):
        more = (f" ({arr.shape[0]} rows for {steps} steps: row j is the input of the arrow "
                f"step j computes, so a longer table is a different run)"
                if arr.ndim == 2 and arr.shape[0] > steps and arr.shape[1] == m else "")
        raise ShapeError(f"{owner}: inputs need shape ({steps}, {m}) (one row of the inputs "
                         f"{names} per step) or ({m},) for inputs held constant; got shape "
                         f"{np.shape(inputs)}{more}")
    one_row = steps > 0 and arr.strides[0] == 0  # held constant: every row is the first
    checked = arr[:1] if one_row else arr
    bad = np.argwhere(~np.isfinite(checked))
    if len(bad):
        j, i = (int(v) for v in bad[0])
        raise DomainError(f"{owner}: input {layout.input_names[i]} of step {j} is "
                          f"{arr[j, i]}; inputs must be finite")
    check_input_values(layout.input_symbols, checked, owner,
                       lambda j, i: "for the step" if one_step else f"at step {j}")
    if held and one_row:
        return np.broadcast_to(np.array(arr[0], dtype=float), arr.shape)
    return np.ascontiguousarray(arr, dtype=float)


def batch_inputs(layout, inputs, n_batch: int, steps: int, *, owner: str
                 ) -> np.ndarray | None:
    """The inputs of a batch of ``n_batch`` runs: an array (B, steps, m), row j of run b
    the input of the arrow its step j computes; or what :func:`input_sequence` takes, the
    same for every run, kept as (steps, m).  None for a system without inputs (and none
    given)."""
    if inputs is None and layout.n_inputs == 0:
        return None
    inputs = named_columns(inputs, layout.input_names, owner=owner)
    arr = None if inputs is None else real_array(inputs, "inputs", owner=owner)
    m = layout.n_inputs
    if arr is None or arr.ndim != 3 or m == 0:
        try:
            return input_sequence(layout, arr, steps, owner=owner)
        except DomainError:  # a value (NaN, against an assumption): the shape was right
            raise
        except ShapeError as exc:
            if m == 0 or arr is None:
                raise
            raise ShapeError(f"{exc}; or ({n_batch}, {steps}, {m}) for inputs of each run "
                             f"(a table per run)") from None
    if arr.shape != (n_batch, steps, m):
        raise ShapeError(f"{owner}: per-run inputs need shape ({n_batch}, {steps}, {m}) (a "
                         f"row of the inputs {', '.join(layout.input_names)} per step of each "
                         f"of the {n_batch} runs); got shape {arr.shape}")
    bad = np.argwhere(~np.isfinite(arr))
    if len(bad):
        b, j, i = (int(v) for v in bad[0])
        raise DomainError(f"{owner}: input {layout.input_names[i]} of run {b}, step {j} is "
                          f"{arr[b, j, i]}; inputs must be finite")
    check_input_values(layout.input_symbols, arr, owner,
                       lambda row, i: f"in run {row // steps}, step {row % steps}")
    return np.ascontiguousarray(arr, dtype=float)


def step_inputs(layout, inputs, *, owner: str) -> np.ndarray | None:
    """The inputs of one step (:meth:`Simulator.step`): None for a system without inputs
    (and none given); a C-contiguous float64 vector of the m inputs, finite, passes as it
    is; anything else goes through :func:`input_sequence` (a labelled row, a pandas
    ``Series``, read by the inputs' names: :func:`~symgroupoid._arguments.named_columns`)."""
    if (type(inputs) is np.ndarray and inputs.dtype is _FLOAT64 and inputs.strides == _STEP
            and all(map(math.isfinite, inputs.tolist()))
            and inputs.shape == (layout.n_inputs,) and inputs.shape != (0,)
            and (layout.input_test is None or layout.input_test(inputs.tolist()))):
        return inputs
    if inputs is None and layout.n_inputs == 0:
        return None
    inputs = named_columns(inputs, layout.input_names, owner=owner)
    if inputs is not None and layout.n_inputs:
        _check_step_shape(layout, inputs, owner)
    return input_sequence(layout, None if inputs is None else [inputs], 1, owner=owner,
                          one_step=True)[0]


def _check_step_shape(layout, inputs, owner: str) -> None:
    """One step's inputs have shape (m,) (or are a number when m = 1): anything else is a
    :class:`ShapeError` in the shape the caller gave (the sequence check below would name
    the (1, …) it wraps them in)."""
    try:
        shape = np.shape(inputs)
    except ValueError:  # ragged: the sequence check names it
        return
    m = layout.n_inputs
    if shape == (m,) or (m == 1 and shape == ()):
        return
    raise ShapeError(f"{owner}: the inputs of one step need shape ({m},) (the inputs "
                     f"{', '.join(layout.input_names)} of the arrow the step computes); got "
                     f"shape {shape}")


def input_chunks(kernel, layout, known0: np.ndarray, p: np.ndarray, inputs: np.ndarray,
                 options: NewtonOptions, chunk_steps: int) -> Iterator[tuple[int, RawRun]]:
    """The run of ``len(inputs)`` steps in kernel calls of at most ``chunk_steps`` steps
    (the shape of :func:`~symgroupoid.runtime._runs.run_chunks`: (index of the call's first
    state, its :class:`RawRun`), stopping after a failed call): step j reads row j of the
    inputs (:meth:`~symgroupoid.runtime._backends._Kernel.simulate_inputs`), the Newton warm
    start carried from call to call, so the states are bitwise those of one call."""
    steps = len(inputs)
    warm = kernel.warm_start()
    known, done = known0, 0
    while done < steps:
        n = min(chunk_steps, steps - done)
        states = np.empty((n + 1, layout.n_known))
        states[0] = known
        iterations = np.zeros(n, dtype=np.intc)
        norms = np.zeros(n)
        chunk = kernel.simulate_inputs(states, iterations, norms, p, inputs[done:done + n],
                                       layout.upcoming_index, options, warm)
        if chunk.status != OK:
            k = max(chunk.failed_step, 0)
            yield done, RawRun(states[:k + 1], iterations[:k + 1], norms[:k + 1],
                               chunk.status, k, chunk.last_iterate)
            return
        yield done, RawRun(states, iterations, norms, OK, -1, np.zeros(0))
        known, done = states[-1], done + n


__all__ = ["batch_inputs", "input_chunks", "input_sequence", "step_inputs"]
