"""Evaluation of user callables (Lagrangians, constraints) on symbolic arrows, with checks."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

import sympy as sp

from .._errors import CallableError, ShapeError, UndeclaredSymbolError


def call_user(system_name: str, what: str, func: Callable, *arrows):
    """Call ``func(*arrows)``; wrap any exception with the system name and ``what``."""
    if not callable(func):
        raise CallableError(
            f"{system_name}: the {what} must be a function of the arrow (e.g. "
            f"lambda g: ...), got a {type(func).__name__}")
    try:
        return func(*arrows)
    except Exception as exc:  # noqa: BLE001 - re-raised with context
        raise CallableError(
            f"{system_name}: evaluating the {what} on symbolic arrows raised "
            f"{type(exc).__name__}: {exc}") from exc


def as_scalar(system_name: str, what: str, value) -> sp.Expr:
    """A SymPy scalar from a user return value, or a :class:`ShapeError`."""
    if isinstance(value, sp.MatrixBase):
        if value.shape == (1, 1):
            return value[0, 0]
        raise ShapeError(f"{system_name}: the {what} returned a {value.shape[0]}×"
                         f"{value.shape[1]} matrix; it must be a scalar")
    if isinstance(value, (list, tuple, set, dict)):
        raise ShapeError(f"{system_name}: the {what} returned a {type(value).__name__}; "
                         "it must be a scalar")
    try:
        expr = sp.sympify(value)
    except (sp.SympifyError, TypeError) as exc:
        raise ShapeError(f"{system_name}: the {what} returned {value!r}, not a scalar") from exc
    if not isinstance(expr, sp.Expr):
        raise ShapeError(f"{system_name}: the {what} returned {expr!r}, not a scalar")
    return expr


def as_scalar_list(system_name: str, what: str, value) -> list[sp.Expr]:
    """A list of SymPy scalars (a list/tuple or a column matrix), or a :class:`ShapeError`."""
    if isinstance(value, sp.MatrixBase):
        if 1 not in value.shape:
            raise ShapeError(f"{system_name}: the {what} returned a {value.shape[0]}×"
                             f"{value.shape[1]} matrix; return a list of scalars")
        value = list(value)
    if not isinstance(value, (list, tuple)):
        raise ShapeError(f"{system_name}: the {what} must return a list of scalar "
                         f"expressions, got {type(value).__name__}")
    out = []
    for i, v in enumerate(value):
        try:
            out.append(as_scalar(system_name, f"{what} (entry {i})", v))
        except ShapeError as exc:
            raise ShapeError(f"{exc} — constraints must be a list of scalars") from exc
    return out


def check_symbols(system_name: str, what: str, exprs: Iterable[sp.Expr],
                  coordinates: Sequence, parameters: Sequence) -> None:
    """Raise :class:`UndeclaredSymbolError` naming symbols that are neither coordinates
    nor declared parameters."""
    allowed = set(coordinates) | set(parameters)
    free: set = set()
    for e in exprs:
        free |= e.free_symbols
    bad = sorted((s for s in free - allowed), key=str)
    if bad:
        names = ", ".join(str(s) for s in bad)
        raise UndeclaredSymbolError(
            f"{system_name}: the {what} uses symbol(s) {names} that are neither coordinates of "
            f"the arrow nor declared parameters; pass them in parameters=[...]")
