"""Checked input tables of a batch or a sweep: initial states and parameter sets as rows.

A table is checked as :meth:`Simulator.state` and :meth:`Simulator.parameters` check one
state and one parameter set, but vectorised over the rows: every row is screened with NumPy
against half of each tolerance, and a row the screen flags goes through the scalar check,
which decides and raises its own error, prefixed with the row's index.  Rows the screen
passes are far inside the tolerances, so the outcome is the scalar check's for every row.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .._arguments import ndim
from .._errors import DomainError, ParameterError, ShapeError, SymgroupoidError
from ._validate import (
    CHECKED_ASSUMPTIONS,
    CONSTRAINT_ROUNDING,
    GROUP_TOLERANCE,
    constraint_check,
    declared_assumptions,
    offset_element,
    real_array,
)

_EPS = float(np.finfo(float).eps)


def _at_row(error: Exception, what: str, index) -> Exception:
    """``error`` (from the scalar check of one row) with the row named in front."""
    label = index if isinstance(index, tuple) else (index,)
    text = f"{what} {', '.join(str(i) for i in label)}: {error}"
    try:
        return type(error)(text)
    except TypeError:  # an error class with another constructor: keep it as it is
        return error



def _checked_row(check, row, what: str, index: int):
    """``check(row)`` (the scalar check of one row), its error naming the row."""
    try:
        return check(row)
    except SymgroupoidError as err:
        raise _at_row(err, what, index) from err


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
            out[i] = _checked_row(sim.parameters, one, "parameter set", i)
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
            declared = (declared_assumptions(symbol) if hasattr(symbol, "assumptions0")
                        else ())
            for key, expected in declared:
                if key not in CHECKED_ASSUMPTIONS:
                    continue
                holds = _assumption_holds(key, values[:, j])
                flagged |= np.ones(len(values), bool) if holds is None else holds != expected
    for i in np.flatnonzero(flagged):
        values[i] = _checked_row(sim.parameters, row(int(i)), "parameter set", int(i))
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
    # (a 2-D array is read whole: split into a million row views, it took seconds)
    rows = None if isinstance(initial, np.ndarray) else list(initial)
    if rows is not None:
        if rows and all(_is_scalar(v) for v in rows):
            return sim.state(initial)[None, :], True
        if not rows:  # no states: an empty batch, as a (0, n_known) array gives
            return np.empty((0, n_k)), False
    if rows is None or all(not isinstance(r, Mapping) for r in rows):
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
    rows = list(initial) if rows is None else rows
    out = np.empty((len(rows), n_k))
    for i, one in enumerate(rows):
        out[i] = _checked_row(sim.state, one, "initial state", i)
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
    for i in np.flatnonzero(flagged):  # a group part given to a few digits: its nearest element
        S[i] = _checked_row(sim.state, S[i], "initial state", int(i))
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

