"""Parameter values checked against their symbols: by name or in order, finite, and with
the assumptions the symbols are declared with (positive, integer, …).  Shared by every layer
that takes parameter values (the step equations' NumPy evaluations, the runtime's entry
points; :mod:`symgroupoid.runtime._validate` gathers the runtime's checks)."""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from ._arguments import real_argument, where
from ._errors import ParameterError

# --- parameters ---------------------------------------------------------------------------------

#: assumptions checked on parameter values, in the order they are reported (a float is a
#: rational number, so ``rational``/``irrational``/``algebraic`` say nothing about it)
CHECKED_ASSUMPTIONS = ("positive", "negative", "nonnegative", "nonpositive", "zero",
                        "nonzero", "integer", "noninteger", "even", "odd", "prime",
                        "composite")


@functools.lru_cache(maxsize=1024)
def declared_assumptions(symbol: sp.Symbol) -> list[tuple[str, bool]]:
    """The checkable assumptions a symbol was declared with (``extended_`` forms included)."""
    given = getattr(symbol, "_assumptions_orig", None)
    if given is None:  # older SymPy: every known fact about the symbol
        given = symbol.assumptions0
    out = []
    for key, value in given.items():
        key = key.removeprefix("extended_")
        if key in CHECKED_ASSUMPTIONS and value is not None:
            out.append((key, bool(value)))
    return sorted(set(out), key=lambda kv: (CHECKED_ASSUMPTIONS.index(kv[0]), kv[1]))


#: the checkable assumptions as tests of a finite float ``{v}`` (Python source), exact for
#: the rational number it is (SymPy's answer for ``sp.Rational(v)``); prime and composite
#: are left to SymPy
_FLOAT_SOURCE = {
    "positive": "{v} > 0", "negative": "{v} < 0", "nonnegative": "{v} >= 0",
    "nonpositive": "{v} <= 0", "zero": "{v} == 0", "nonzero": "{v} != 0",
    "integer": "{v}.is_integer()", "noninteger": "not {v}.is_integer()",
    "even": "({v}.is_integer() and {v} % 2 == 0)",
    "odd": "({v}.is_integer() and {v} % 2 == 1)",
}


def _exact_assumption(key: str, v: float) -> bool:
    """SymPy's answer for the rational number ``v`` (prime, composite)."""
    return bool(getattr(sp.Rational(v), f"is_{key}"))


#: the table's tests on an array of finite floats (elementwise, the same answers)
_ARRAY_TESTS = {
    "positive": lambda c: c > 0, "negative": lambda c: c < 0,
    "nonnegative": lambda c: c >= 0, "nonpositive": lambda c: c <= 0,
    "zero": lambda c: c == 0, "nonzero": lambda c: c != 0,
    "integer": lambda c: c == np.floor(c), "noninteger": lambda c: c != np.floor(c),
    "even": lambda c: (c == np.floor(c)) & (np.fmod(c, 2) == 0),
    "odd": lambda c: (c == np.floor(c)) & (np.abs(np.fmod(c, 2)) == 1),
}


def violated_assumption(symbol: sp.Symbol, values: np.ndarray) -> tuple[int, str] | None:
    """The first entry of the finite float array ``values`` (flat index) that violates an
    assumption ``symbol`` is declared with, and that assumption's words ("positive", "not
    integer"), or None: :func:`check_assumptions` on every entry, vectorised."""
    flat = np.asarray(values, dtype=float).ravel()
    for key, expected in declared_assumptions(symbol):
        if key in _ARRAY_TESTS:
            holds = _ARRAY_TESTS[key](flat)
        else:
            holds = np.array([_exact_assumption(key, v) for v in flat.tolist()], dtype=bool)
        bad = np.flatnonzero(holds != expected)
        if len(bad):
            return int(bad[0]), key if expected else f"not {key}"
    return None


@functools.lru_cache(maxsize=1024)
def assumption_test(symbol: sp.Symbol):
    """A function of a finite float that is True exactly when the value satisfies every
    checkable assumption ``symbol`` is declared with (None when it is declared with none):
    the screen of :func:`check_assumptions`, without SymPy arithmetic."""
    return assumptions_test((symbol,), lambda i: "v")


def assumptions_test(symbols: Sequence, entry=lambda i: f"v[{i}]"):
    """One Python function testing every checkable assumption of ``symbols`` at once on
    floats: of the list of their values (``entry(i)`` its i-th item), True exactly when
    :func:`check_assumptions` accepts each value; None when no symbol declares one.  It is
    compiled from the fixed table :data:`_FLOAT_SOURCE` (about 0.1 µs a call, for the
    per-call checks of :meth:`Simulator.step`)."""
    terms = []
    for i, symbol in enumerate(symbols):
        declared = declared_assumptions(symbol) if isinstance(symbol, sp.Symbol) else ()
        for key, expected in declared:
            v = entry(i)
            test = (_FLOAT_SOURCE[key].format(v=v) if key in _FLOAT_SOURCE
                    else f"_exact({key!r}, {v})")
            terms.append(test if expected else f"not ({test})")
    if not terms:
        return None
    return eval(f"lambda v: {' and '.join(terms)}",  # noqa: S307 - built from the table
                {"__builtins__": {}, "_exact": _exact_assumption})


@functools.lru_cache(maxsize=256)
def parameter_names(parameters: tuple) -> tuple[str, ...]:
    """The names of a tuple of parameter symbols (``str`` of each; cached: SymPy's printer
    is slow)."""
    return tuple(str(s) for s in parameters)


def check_assumptions(symbol: sp.Symbol, value: float, *, owner: str = "") -> None:
    """A :class:`ParameterError` naming the parameter and the assumption when ``value``
    violates an assumption ``symbol`` is declared with (``positive=True``, ``integer=True``,
    …; the value is taken exactly, as the rational number a float is)."""
    test = assumption_test(symbol)
    if test is None or test(float(value)):
        return
    exact = sp.Rational(value)
    for key, expected in declared_assumptions(symbol):
        holds = getattr(exact, f"is_{key}")
        if holds is not None and bool(holds) != expected:
            what = key if expected else f"not {key}"
            raise ParameterError(f"{where(owner)}parameter {symbol} is declared {what}, "
                                 f"got {symbol} = {value!r}")


def parameter_vector(parameters: Sequence, params, *, owner: str = ""
                     ) -> tuple[np.ndarray, dict[str, float]]:
    """The parameter values in ``parameters`` order, and the same by name.

    ``params``: a mapping (keys: the parameter symbols or their names) naming every
    parameter exactly once, or a sequence of values in ``parameters`` order (None: no
    parameters).  Every value must be a finite real number satisfying the assumptions its
    symbol is declared with (:func:`check_assumptions`).  Raises :class:`ParameterError`
    (a ``KeyError`` and a ``ValueError``) naming the parameter otherwise: unknown names,
    missing or repeated ones, a wrong count, a non-number, NaN/inf, a violated assumption.
    """
    at = where(owner)
    names = list(parameter_names(tuple(parameters)))
    listing = ", ".join(names) if names else "none"
    if params is None:
        params = {}
    if isinstance(params, Mapping):
        given: dict[str, object] = {}
        for key, value in params.items():
            label = str(key)
            if label in given:
                raise ParameterError(f"{at}parameter {label} given twice")
            given[label] = value
        unknown = [k for k in given if k not in names]
        if unknown:
            noun = "parameter" if len(unknown) == 1 else "parameters"
            raise ParameterError(f"{at}unknown {noun} {', '.join(unknown)}; the parameters "
                                 f"are {listing}")
        missing = [n for n in names if n not in given]
        if missing:
            noun = "parameter" if len(missing) == 1 else "parameters"
            raise ParameterError(f"{at}missing {noun} {', '.join(missing)}")
        raw = [given[n] for n in names]
    else:
        if (params.ndim != 1 if isinstance(params, np.ndarray)
                else not isinstance(params, Sequence) or isinstance(params, (str, bytes))):
            raise ParameterError(f"{at}parameters must be a mapping name → value or a "
                                 f"sequence of {len(names)} values ({listing}), got "
                                 f"{type(params).__name__} {params!r}")
        raw = list(params)
        if len(raw) != len(names):
            raise ParameterError(f"{at}{len(raw)} parameter values given, expected "
                                 f"{len(names)} ({listing})")
    values = []
    for symbol, name, value in zip(parameters, names, raw):
        real = real_argument(value, f"parameter {name}", owner=owner, error=ParameterError,
                             finite=False)
        if not np.isfinite(real):
            raise ParameterError(f"{at}non-finite parameter {name} = {real!r}")
        if isinstance(symbol, sp.Symbol):
            check_assumptions(symbol, real, owner=owner)
        values.append(real)
    return np.array(values, dtype=float), dict(zip(names, values))
