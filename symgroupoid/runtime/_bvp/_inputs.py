"""The inputs of a forced system's boundary-value problem (docs/conventions.md §20).

A forced system's junction residual between g_j and g_{j+1} carries f⁺(g_j) + f⁻(g_{j+1})
(first order), the forces of each term at the junction node, and each term's forces read the
inputs of that term: u_t belongs to the term starting at the arrow g_t (first order: the
arrow g_t itself, as at run time, runtime/_inputs.py).  A problem of N arrows has N − a + 1
terms (a the order), so its inputs are a table (N − a + 1, m): (N, m) for first order.  They
are data of the problem, fixed during the solve, and reach the window programs as their
named inputs (:func:`symgroupoid.equations.window_programs`); the runtime derives nothing.
"""

from __future__ import annotations

import numpy as np

from ..._arguments import counted, input_rows, named_columns, real_array
from ..._errors import DomainError, ShapeError
from .._layout import check_input_values


def _force_functions(system):
    """The system's forces (:class:`~symgroupoid.derivation.ForceFunctions`) or None."""
    return getattr(system._fs, "forces", None)


def input_names(system) -> list[str]:
    """The names of the system's inputs (none for a system without forces or inputs)."""
    forces = _force_functions(system)
    return [] if forces is None else [str(u) for u in forces.inputs]


def input_table(system, inputs, n_terms: int, *, owner: str) -> np.ndarray:
    """The inputs of the N − a + 1 = ``n_terms`` terms of a problem, checked before any solve:
    an array (n_terms, m), row t the inputs u_t of the term starting at g_t.

    ``inputs``: shape (n_terms, m); (m,) for inputs held constant; (n_terms,) or a number when
    m = 1; finite real numbers.  A system without inputs (unforced, or forces without inputs
    such as damping) takes none (``inputs=None``; a table (n_terms, 0) is returned); a system
    with inputs must be given them.  Raises :class:`ShapeError` (missing, not wanted, wrong
    shape or type) or :class:`DomainError` (not finite)."""
    names = input_names(system)
    m = len(names)
    if m == 0:
        if inputs is not None:
            what = ("its forces take no inputs" if _force_functions(system) is not None
                    else "it is not forced")
            raise ShapeError(f"{owner}: the system has no inputs ({what}); leave inputs= out "
                             f"(declare inputs=[...] with forces=... on the system to drive "
                             f"it)")
        return np.zeros((n_terms, 0))
    listed = ", ".join(names)
    if inputs is None:
        raise ShapeError(f"{owner}: the system has inputs ({listed}); pass inputs= with one "
                         f"row of {counted(m, 'value')} per term of the action ({n_terms} rows: "
                         f"row t the inputs of the term starting at arrow t), or "
                         f"{counted(m, 'value')} held for every term")
    arr = input_rows(inputs, m, n_terms, owner=owner, names=names)
    if arr.shape != (n_terms, m):
        raise ShapeError(f"{owner}: inputs need shape ({n_terms}, {m}) (one row of the inputs "
                         f"{listed} per term of the action, row t for the term starting at "
                         f"arrow t) or ({m},) for inputs held constant; got shape "
                         f"{np.shape(arr)}")
    bad = np.argwhere(~np.isfinite(arr))
    if len(bad):
        t, i = (int(v) for v in bad[0])
        raise DomainError(f"{owner}: input {names[i]} of term {t} is {arr[t, i]}; inputs "
                          f"must be finite")
    check_input_values(_force_functions(system).inputs, arr, owner,
                       lambda t, i: f"for the term starting at arrow {t}")
    out = np.array(arr, dtype=float)  # a copy: the caller's array may change after the call
    out.flags.writeable = False
    return out





def run_inputs(system, inputs, n_terms: int, runs: int, *, owner: str) -> list:
    """The input tables of the ``runs`` runs of a boundary-value sweep, each checked as
    :func:`input_table` checks one (before any solve): ``inputs`` is one input table for
    every run (what :func:`input_table` takes), or an array (runs, n_terms, m), one table per
    run in the runs' order.  A list of ``runs`` tables ((n_terms, 0) without inputs)."""
    if inputs is None or not input_names(system):
        return [input_table(system, inputs, n_terms, owner=owner)] * runs
    # labelled tables (one for all, or one per run) by the inputs' names, never by place
    arr = real_array(named_columns(inputs, input_names(system), owner=owner), "inputs",
                     owner=owner)
    if arr.ndim != 3:
        return [input_table(system, arr, n_terms, owner=owner)] * runs
    if arr.shape[0] != runs:
        raise ShapeError(f"{owner}: per-run inputs need one table per run: shape ({runs}, "
                         f"{n_terms}, {len(input_names(system))}); got shape {arr.shape}")
    out = []
    for r, table in enumerate(arr):
        try:
            out.append(input_table(system, table, n_terms, owner=owner))
        except (ShapeError, DomainError) as exc:
            raise type(exc)(f"{exc} (run {r})") from None
    return out
__all__ = ["input_names", "input_table", "run_inputs"]
