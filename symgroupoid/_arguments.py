"""Checks of plain arguments shared by every layer: counts, real numbers, real arrays, names,
callables, choices, instances, file-system paths.

Each check returns the argument in its canonical form or raises a
:class:`~symgroupoid.SymgroupoidError` subclass whose message names the argument (and the
owner: the system, groupoid or simulator it was given to):

- :class:`~symgroupoid.ShapeError` — not a number, the wrong shape, a value out of range;
- :class:`~symgroupoid.InputTypeError` — an object of the wrong kind (also a ``TypeError``);
- :class:`~symgroupoid.DomainError` — a value outside its domain or its choices.

One rule per kind of argument, wherever it is given: booleans are not numbers, strings are
not numbers (``"1.5"`` is refused, not parsed), complex values are refused even with a zero
imaginary part, and so are dates, durations and integers beyond the range of a double.
The module lives below every layer, so the groupoid checks (layer 1), the runtime (layer 5)
and the command line all read ``steps=1e7``, ``steps=-5`` or ``samples=2.5`` the same way.
"""

from __future__ import annotations

import numbers
import os
import unicodedata
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ._errors import DomainError, InputTypeError, ShapeError

#: NumPy dates and durations (``np.timedelta64`` is a ``numbers.Integral``)
_TIMES = (np.datetime64, np.timedelta64)

#: the largest dimension of a symbolic space (far beyond what can be derived; a dimension
#: such as 10¹² would otherwise allocate its coordinate names before failing)
MAX_DIMENSION = 100_000

#: the largest count accepted for steps, iterations and similar arguments (C ``long`` safe,
#: and far beyond what fits in memory or time)
MAX_COUNT = 2**53


def where(owner: str) -> str:
    """The ``"owner: "`` prefix of a message (empty without an owner)."""
    return f"{owner}: " if owner else ""


def counted(n: int, noun: str) -> str:
    """``n`` and the noun, plural unless n is 1: "1 constraint", "3 constraints"."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def shown_value(value) -> str:
    """``repr(value)`` shortened, or its type where the repr itself fails (a user object
    that cannot print itself)."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - any failure of a user object's repr
        return f"a {type(value).__name__} that cannot be printed"
    return text if len(text) <= 80 else text[:77] + "..."


# --- numbers ------------------------------------------------------------------------------------

def ndim(value) -> int | None:
    """The number of dimensions NumPy sees in ``value``; None for ragged nesting (where
    ``np.ndim`` raises)."""
    try:
        return np.ndim(value)
    except ValueError:
        return None


def integer_argument(value, name: str, *, minimum: int = 0, maximum: int = MAX_COUNT,
                     owner: str = "") -> int:
    """``value`` as an int, or a :class:`ShapeError` naming ``name``.

    Accepted: Python and NumPy integers, and real numbers with an integral value
    (``1e7``, ``np.float64(100.0)``) — one rule everywhere.  Rejected: booleans, NaN,
    infinities, non-integral values, values below ``minimum`` or above ``maximum``, and
    anything that is not a real number.
    """
    if type(value) is int and minimum <= value <= maximum:  # the common case, at once
        return value
    at = where(owner)
    if isinstance(value, (bool, np.bool_)):
        raise ShapeError(f"{at}{name} must be an integer, got the boolean {value!r}")
    if isinstance(value, _TIMES):  # NumPy durations are integers to `numbers`, not counts
        raise ShapeError(f"{at}{name} must be an integer, got {type(value).__name__} "
                         f"{shown_value(value)}")
    if isinstance(value, numbers.Integral):
        number = int(value)
    elif isinstance(value, numbers.Real):
        real = float(value)
        if not np.isfinite(real):
            raise ShapeError(f"{at}{name} must be a finite integer, got {value!r}")
        if real != int(real):
            raise ShapeError(f"{at}{name} must be an integer, got {value!r}")
        number = int(real)
    else:
        raise ShapeError(f"{at}{name} must be an integer, got {type(value).__name__} "
                         f"{shown_value(value)}")
    if number < minimum:
        raise ShapeError(f"{at}{name} must be at least {minimum}, got {number}")
    if number > maximum:
        raise ShapeError(f"{at}{name} must be at most {maximum}, got {number}")
    return number


def real_argument(value, name: str, *, minimum: float | None = None, owner: str = "",
                  error: type[ShapeError] = ShapeError, finite: bool = True) -> float:
    """``value`` as a float, or ``error`` (a :class:`ShapeError` subclass) naming ``name``.

    Accepted: real numbers (Python, NumPy, SymPy numbers, 0-d arrays).  Rejected: booleans,
    strings, complex numbers, arrays and sequences, integers beyond the range of a double,
    values below ``minimum``, and (unless ``finite=False``) NaN and infinities.
    """
    at = where(owner)

    def bad() -> str:  # built only on failure: repr of a large array is not free
        return f"{at}{name} must be a real number, got {type(value).__name__} {shown_value(value)}"

    if isinstance(value, (bool, np.bool_, str, bytes, complex, np.complexfloating,
                          np.datetime64, np.timedelta64, Sequence, Mapping)):
        raise error(bad())
    try:
        if np.ndim(value) != 0 or np.asarray(value).dtype.kind not in "iufO":
            raise error(bad())
        real = float(value)
    except (TypeError, ValueError, AttributeError):
        raise error(bad()) from None
    except OverflowError:
        raise error(f"{at}{name} is beyond the range of a double, got "
                    f"{shown_value(value)}") from None
    if not finite:
        return real
    if not np.isfinite(real):
        raise error(f"{at}{name} must be finite, got {real!r}")
    if minimum is not None and real < minimum:
        raise error(f"{at}{name} must be at least {minimum}, got {real!r}")
    return real


def flag_argument(value, name: str, *, owner: str = "",
                  accepted: str = "True or False") -> bool:
    """``value`` as a bool: ``True``/``False`` (Python or NumPy) or the integers 0 and 1;
    anything else (a string such as ``"no"``, None) is a :class:`ShapeError` saying what is
    ``accepted``."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Integral) and not isinstance(value, _TIMES) \
            and int(value) in (0, 1):
        return bool(value)
    raise ShapeError(f"{where(owner)}{name} must be {accepted}, got "
                     f"{type(value).__name__} {shown_value(value)}")


#: NumPy dtype kinds holding real numbers (integers, unsigned integers, floats)
_REAL_KINDS = "iuf"


def real_array(value, name: str, *, owner: str = "") -> np.ndarray:
    """``value`` as a float64 array of the same shape, or a :class:`ShapeError` naming
    ``name``.

    Accepted: real numbers and (nested) sequences or arrays of them — Python, NumPy and SymPy
    numbers.  Rejected, whatever their values: strings (also numeric-looking ones), bytes,
    booleans, complex numbers (also with a zero imaginary part, which NumPy would drop with
    only a warning), dates and durations, None, mappings, sets, ragged nesting, and integers
    beyond the range of a double.  Values are not checked for finiteness here.
    """
    at = where(owner)

    def kind() -> str:  # built only on failure: repr of a large array is not free
        return f"an array of real numbers, got {type(value).__name__} {shown_value(value)}"

    if isinstance(value, (str, bytes, Mapping, set, frozenset)) or value is None:
        raise ShapeError(f"{at}{name} must be {kind()}")
    if isinstance(value, np.ma.MaskedArray) and np.ma.getmaskarray(value).any():
        where_masked = tuple(int(i) for i in np.argwhere(np.ma.getmaskarray(value))[0])
        raise ShapeError(f"{at}{name} has masked (missing) entries, the first at index "
                         f"{where_masked}; fill them (numpy.ma.filled) or drop them: their "
                         f"values are not data")
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError, OverflowError):
        raise ShapeError(f"{at}{name} must be {kind()}") from None
    if raw.dtype.kind == "O":
        for item in raw.flat:
            _check_real_item(item, name, at)
    elif isinstance(value, (list, tuple)) and _holds_bool(value):  # NumPy took True as 1.0
        raise ShapeError(f"{at}{name} must hold real numbers, got a bool among them "
                         f"({shown_value(value)})")
    elif raw.dtype.kind not in _REAL_KINDS:
        raise ShapeError(f"{at}{name} must hold real numbers, got dtype {raw.dtype} "
                         f"({shown_value(value)})")
    try:
        return np.array(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise ShapeError(f"{at}{name} must be {kind()}") from None
    except OverflowError:
        raise ShapeError(f"{at}{name} has an entry beyond the range of a double: "
                         f"{shown_value(value)}") from None


def finite_vector(value, size: int, name: str, *, owner: str = "") -> np.ndarray:
    """``value`` as ``size`` finite real numbers, flattened (:func:`real_array`); a
    :class:`ShapeError` for another count, a :class:`DomainError` for a non-finite entry,
    each naming ``name``."""
    arr = real_array(value, name, owner=owner).ravel()
    if arr.size != size:
        raise ShapeError(f"{where(owner)}{size} entries expected for the {name}, got "
                         f"{arr.size}")
    if not np.isfinite(arr).all():
        raise DomainError(f"{where(owner)}non-finite entries in the {name} ({arr.tolist()})")
    return arr


def input_rows(inputs, m: int, rows: int, *, owner: str = "", name: str = "inputs",
               names: Sequence[str] = ()) -> np.ndarray:
    """A forced system's inputs (docs/conventions.md §20) as real numbers in rows of ``m``:
    (m,) — or a number when m = 1 — held for all ``rows`` rows, (rows,) read as one column
    when m = 1, anything else as given (its shape is the caller's to check); not a real
    array: a :class:`ShapeError` naming ``name``.  A table with named columns (a pandas
    ``DataFrame``) is read by the inputs' ``names``, in any column order
    (:func:`named_columns`)."""
    arr = real_array(named_columns(inputs, names, owner=owner, name=name), name, owner=owner)
    if arr.shape == (m,) or (m == 1 and arr.ndim == 0):
        return np.broadcast_to(arr.reshape(1, m), (rows, m))
    if m == 1 and arr.shape == (rows,):
        return arr.reshape(rows, 1)
    return arr


def _label(label) -> str | None:
    """A table label as an input's name: a string, or a SymPy symbol's name; None for a
    label that names nothing (an integer position).  Any other label (a tuple of a
    MultiIndex, a float) names no input: its repr, which no input's name equals, so that
    the table is refused rather than read by position."""
    if isinstance(label, str):
        return label
    if getattr(label, "is_Symbol", False):
        return str(label.name)
    if isinstance(label, numbers.Integral) and not isinstance(label, (bool, np.bool_)):
        return None
    return repr(label)


def named_columns(table, names: Sequence[str], *, owner: str = "", name: str = "inputs"):
    """``table`` in the order of ``names`` when it is labelled by them: a table whose
    columns are labelled (a pandas ``DataFrame``: ``columns`` and ``to_numpy``) or a
    labelled row (a pandas ``Series``: ``index`` and ``to_numpy``, one dimension), labels
    being strings or SymPy symbols — so that a value is never read as another input because
    of its place.  Unlabelled (integer labels): its values as they stand, by position.
    Anything else unchanged.  A labelled table whose labels are not exactly ``names`` (a
    missing, an unknown or a repeated label) is an :class:`~symgroupoid.InputNameError`
    listing both.  A list or tuple holding labelled tables (one per run of a batch or a
    sweep) is read the same way, each by its own labels."""
    if names and isinstance(table, (list, tuple)) and any(
            callable(getattr(item, "to_numpy", None)) for item in table):
        return [named_columns(item, names, owner=owner, name=f"{name}[{i}]")
                for i, item in enumerate(table)]
    if names and isinstance(table, Mapping):
        return _named_mapping(table, names, owner, name)
    if not names or not callable(getattr(table, "to_numpy", None)):
        return table
    columns = getattr(table, "columns", None)
    if columns is None:
        columns = getattr(table, "index", None) if np.ndim(table) == 1 else None
        if columns is None:
            return table
    labels = [_label(label) for label in columns]
    if all(label is None for label in labels):
        return table.to_numpy()
    if None in labels or sorted(labels) != sorted(names) or len(set(labels)) != len(labels):
        from ._errors import InputNameError

        what = "table's columns" if hasattr(table, "columns") else "row's labels"
        raise InputNameError(f"{where(owner)}{name}: the {what} "
                             f"{', '.join(map(str, columns))} must be the inputs "
                             f"{', '.join(names)}, each once (in any order)")
    values = np.asarray(table.to_numpy())
    order = [labels.index(n) for n in names]
    return values[..., order] if hasattr(table, "columns") else values[order]


def _named_mapping(table: Mapping, names: Sequence[str], owner: str, name: str):
    """A mapping from the names (strings or SymPy symbols) to their values — one value each
    (one step) or one sequence each (a value per step) — as the array of its values in the
    order of ``names``, the names on the last axis; keys that are not exactly ``names`` are
    an :class:`~symgroupoid.InputNameError` listing both."""
    labels = [_label(key) for key in table]
    if None in labels or sorted(labels) != sorted(names) or len(set(labels)) != len(labels):
        from ._errors import InputNameError

        raise InputNameError(f"{where(owner)}{name}: the keys "
                             f"{', '.join(map(str, table))} must be the inputs "
                             f"{', '.join(names)}, each once (in any order)")
    by_label = dict(zip(labels, table.values()))
    columns = [np.asarray(by_label[n]) for n in names]
    if len({c.shape for c in columns}) != 1:
        from ._errors import ShapeError

        raise ShapeError(f"{where(owner)}{name}: the inputs' values have the shapes "
                         f"{', '.join(str(c.shape) for c in columns)}; give each input one "
                         f"value, or each the same number of values (one per step)")
    return np.stack(columns, axis=-1)


def _holds_bool(value) -> bool:
    """Whether a (nested) list or tuple holds a bool anywhere."""
    return any(isinstance(v, (bool, np.bool_)) or isinstance(v, (list, tuple)) and _holds_bool(v)
               for v in value)


def _check_real_item(item, name: str, at: str) -> None:
    """An entry of an object array: a real number (not a bool, string, complex, …)."""
    if isinstance(item, (bool, np.bool_, str, bytes, complex, np.complexfloating)) \
            or not isinstance(item, numbers.Real) and not _is_real_number(item):
        raise ShapeError(f"{at}{name} must hold real numbers, got the entry "
                         f"{type(item).__name__} {shown_value(item)}")
    try:
        float(item)
    except OverflowError:
        raise ShapeError(f"{at}{name} has an entry beyond the range of a double: "
                         f"{shown_value(item)}") from None
    except (TypeError, ValueError):
        raise ShapeError(f"{at}{name} must hold real numbers, got the entry "
                         f"{shown_value(item)}") from None


def _is_real_number(item) -> bool:
    """A SymPy number that is real (``Rational(1, 3)``, ``Float(2)``, ``pi``…)."""
    is_number = getattr(item, "is_number", False)
    return bool(is_number) and getattr(item, "is_extended_real", False) is True


# --- objects ------------------------------------------------------------------------------------

def name_argument(value, name: str, *, owner: str = "", empty: bool = False) -> str:
    """``value`` as a name: a string (non-empty unless ``empty``), without control
    characters (NUL, line breaks, tabs: a name is printed on one line of messages, TeX
    comments and C); an :class:`InputTypeError` or :class:`ShapeError` naming ``name``
    otherwise."""
    if not isinstance(value, str):
        raise InputTypeError(f"{where(owner)}{name} must be a string, got "
                             f"{type(value).__name__} {shown_value(value)}")
    if not value.strip() and not empty:
        raise ShapeError(f"{where(owner)}{name} must not be empty, got {value!r}")
    if any(unicodedata.category(c) == "Cc" for c in value):
        raise ShapeError(f"{where(owner)}{name} must not contain control characters (NUL, "
                         f"line breaks, tabs), got {value!r}")
    return value


def names_argument(value, name: str, *, owner: str = "") -> tuple[str, ...]:
    """A sequence of names (each :func:`name_argument`); a single string is refused (it
    would be read letter by letter)."""
    if isinstance(value, (str, bytes, Mapping)) or not _is_sequence(value):
        raise InputTypeError(f"{where(owner)}{name} must be a list of strings, got "
                             f"{type(value).__name__} {shown_value(value)}")
    return tuple(name_argument(v, f"{name}[{i}]", owner=owner) for i, v in enumerate(value))


def callable_argument(value, name: str, *, owner: str = "", none: bool = False):
    """``value`` if it is callable (or None when ``none``), else an :class:`InputTypeError`."""
    if value is None and none:
        return None
    if not callable(value):
        raise InputTypeError(f"{where(owner)}{name} must be a function, got "
                             f"{type(value).__name__} {shown_value(value)}")
    return value


def instance_argument(value, kinds, name: str, what: str, *, owner: str = ""):
    """``value`` if it is an instance of ``kinds``, else an :class:`InputTypeError` saying
    ``what`` is expected."""
    if not isinstance(value, kinds):
        raise InputTypeError(f"{where(owner)}{name} must be {what}, got "
                             f"{type(value).__name__} {shown_value(value)}")
    return value


def choice_argument(value, choices: Sequence, name: str, *, owner: str = ""):
    """``value`` if it is one of ``choices`` (compared as strings are: no conversion), else
    a :class:`DomainError` listing them."""
    if not isinstance(value, str) or value not in choices:
        raise DomainError(f"{where(owner)}{name} must be one of "
                          f"{', '.join(map(repr, choices))}, got {shown_value(value)}")
    return value


def path_argument(value, name: str, *, owner: str = "") -> Path:
    """``value`` as a :class:`~pathlib.Path`: a ``str`` or ``os.PathLike`` giving a string,
    non-empty and without NUL characters."""
    if isinstance(value, (bytes, bytearray)) or not isinstance(value, (str, os.PathLike)):
        raise InputTypeError(f"{where(owner)}{name} must be a path (str or os.PathLike), got "
                             f"{type(value).__name__} {shown_value(value)}")
    text = os.fspath(value)
    if not isinstance(text, str):
        raise InputTypeError(f"{where(owner)}{name} must be a path giving a str, got "
                             f"{type(text).__name__}")
    if not text:
        raise ShapeError(f"{where(owner)}{name} must not be empty")
    if "\0" in text:
        raise ShapeError(f"{where(owner)}{name} must not contain NUL characters, got "
                         f"{text!r}")
    return Path(text)


def sequence_argument(value, name: str, *, owner: str = "") -> list:
    """``value`` as a list: a list, tuple or other sequence (not a string, bytes, mapping or
    set, whose order or items are not those of a list); an :class:`InputTypeError`
    otherwise."""
    if isinstance(value, (str, bytes, Mapping, set, frozenset)) or not _is_sequence(value):
        raise InputTypeError(f"{where(owner)}{name} must be a list or tuple, got "
                             f"{type(value).__name__} {shown_value(value)}")
    return list(value)


def _is_sequence(value) -> bool:
    """A sequence, or a NumPy array with at least one dimension (a 0-d array is a
    scalar: it cannot be iterated)."""
    if isinstance(value, np.ndarray):
        return value.ndim > 0
    return isinstance(value, Sequence)


def caller_level() -> int:
    """The ``stacklevel`` of a warning issued by the caller that points at the first frame
    outside this package (the user's line)."""
    import os
    import sys

    package = os.path.dirname(os.path.abspath(__file__)) + os.sep
    frame, level = sys._getframe(2), 2
    while frame is not None and frame.f_code.co_filename.startswith(package):
        frame, level = frame.f_back, level + 1
    return level


__all__ = ["MAX_COUNT", "MAX_DIMENSION", "callable_argument", "caller_level", "choice_argument",
           "flag_argument", "input_rows", "instance_argument", "integer_argument",
           "name_argument", "named_columns", "names_argument", "path_argument",
           "real_argument", "real_array", "sequence_argument", "shown_value", "where"]


def checked_call(func, owner: str | None = None):
    """``func`` with a call it cannot bind — an argument it does not take (a misspelled
    option, ``maxiter=`` for ``max_iterations=``), a missing one, too many — an
    :class:`~symgroupoid.InputNameError` naming ``owner`` (default: the function's
    qualified name) and its parameters, not Python's ``TypeError``.  A ``TypeError`` raised
    inside ``func`` passes as it is (the arguments bind to its signature), and a call that
    binds pays one more Python frame only."""
    import functools
    import inspect

    from ._errors import InputNameError

    label = owner or func.__qualname__

    @functools.wraps(func)
    def checked(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except TypeError as exc:
            signature = inspect.signature(func)  # (through wrappers to the function)
            try:
                signature.bind(*args, **kwargs)
            except TypeError:
                pass
            else:
                raise  # the arguments bind: raised inside func
            names = [p.name for p in signature.parameters.values()
                     if p.name not in ("self", "cls")
                     and p.kind not in (inspect.Parameter.VAR_POSITIONAL,
                                        inspect.Parameter.VAR_KEYWORD)]
            raise InputNameError(f"{label}: {exc}; its arguments are "
                                 f"{', '.join(names) or 'none'}") from None

    return checked


def hot_path(func):
    """Marks a method whose every call counts (``Simulator.step`` in a control loop, with a
    budget of 2 µs of Python a call): :func:`checked_calls` leaves it unwrapped, so a
    misspelled keyword there is Python's ``TypeError``."""
    func._symgroupoid_hot = True
    return func


def checked_calls(cls):
    """A class decorator: ``__init__`` and every public method of ``cls`` (its own, plain,
    class and static methods) through :func:`checked_call`, named ``Class.method`` (the
    constructor by the class's name), except those marked :func:`hot_path`.  Subclasses
    that define their own methods are decorated themselves."""
    for name, value in list(vars(cls).items()):
        if (name != "__init__" and name.startswith("_")) or \
                getattr(value, "_symgroupoid_hot", False):
            continue
        label = cls.__name__ if name == "__init__" else f"{cls.__name__}.{name}"
        if isinstance(value, (classmethod, staticmethod)):
            setattr(cls, name, type(value)(checked_call(value.__func__, label)))
        elif callable(value) and not isinstance(value, type):
            setattr(cls, name, checked_call(value, label))
    return cls


#: (the decorator of the option classes: their constructors' calls checked)
checked_keywords = checked_calls
