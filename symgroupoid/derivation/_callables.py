"""Evaluation of user callables (Lagrangians, constraints) on symbolic arrows, with checks."""

from __future__ import annotations

import linecache
import math
import re
import sys
from collections.abc import Callable, Iterable, Sequence

import sympy as sp

from .._arguments import shown_value
from .._errors import (
    CallableError,
    InvalidExpressionError,
    ParameterDeclarationError,
    ShapeError,
    SymgroupoidError,
    UndeclaredSymbolError,
    UnsupportedExpressionError,
)
from .._symbols import (
    is_difference_name,
    is_multiplier_name,
    latex_name,
    misread_name,
    reads_as_power,
    reads_as_step_value,
    scalar_expression,
    unspelled_character,
)

#: values that make an expression non-finite, with how messages describe them
_NON_FINITE = {sp.nan: "nan (not a number)", sp.zoo: "zoo (complex infinity)",
               sp.oo: "oo (infinity)", -sp.oo: "-oo (minus infinity)"}


def checked_callable(func: Callable) -> Callable:
    """Mark ``func`` as built by the library from expressions already checked by
    :func:`call_user` (e.g. a Galerkin discrete Lagrangian made of the user's L evaluated
    once on generic symbols, docs/conventions.md §22): its values are not traversed again,
    which on large shared expression trees costs more than everything else."""
    func.symgroupoid_checked = True
    return func


def call_user(system_name: str, what: str, func: Callable, *arrows, smooth: bool = False,
              display: dict | None = None):
    """Call ``func(*arrows)``; wrap any exception with the system name and ``what`` (a
    :class:`~symgroupoid.SymgroupoidError` is already named and passes unchanged).

    A numeric function (``math.cos``, ``np.cos``) applied to a symbolic coordinate is
    reported as such, with what to use instead (SymPy's functions).  With ``smooth`` (a
    Lagrangian or constraints, whose derivatives define the step) a non-smooth function in
    the value is an :class:`UnsupportedExpressionError` (:func:`check_smooth`).
    ``display``: how messages name the symbols the arrows are made of (default: the named
    coordinates of g_k, g_{k+1}, … for arrows of a groupoid).
    """
    if not callable(func):
        raise CallableError(
            f"{system_name}: the {what} must be a function of the arrow (e.g. "
            f"lambda g: ...), got a {type(func).__name__}")
    try:
        value = func(*arrows)
    except SymgroupoidError:  # the library's own, already named (a wrapped user function:
        raise  # a continuous force's length, a call_user inside it), never wrapped again
    except Exception as exc:  # noqa: BLE001 - re-raised with context
        hint = _numeric_function_hint(exc)
        if hint is not None:
            raise CallableError(f"{system_name}: the {what} {hint}") from exc
        raise CallableError(
            f"{system_name}: evaluating the {what} on symbolic arrows raised "
            f"{type(exc).__name__}: {exc}") from exc
    if getattr(func, "symgroupoid_checked", False):
        return value
    check_values(system_name, what, value, arrows, display)
    if smooth:
        check_smooth(system_name, what, value, display if display is not None
                     else _display(arrows))
    return value


#: what TypeError says when a numeric function is given a SymPy symbol: math's functions
#: cannot convert it to a float, NumPy's ufuncs look for a method of that name on it
_MATH_FAILURE = re.compile(r"Cannot convert (expression|complex) to float|must be real "
                           r"number, not")
_UFUNC_FAILURE = re.compile(r"has no callable (\w+) method")
#: a call of a numeric module's function in a line of source
_NUMERIC_CALL = re.compile(r"\b(math|cmath|np|numpy|scipy(?:\.\w+)*)\.(\w+)\s*\(")


def _numeric_function_hint(exc: BaseException) -> str | None:
    """What to say when ``exc`` comes from a numeric function (``math.cos``, ``np.cos``)
    given a SymPy coordinate; None for any other exception."""
    if not isinstance(exc, (TypeError, AttributeError)):
        return None
    text = str(exc)
    ufunc = _UFUNC_FAILURE.search(text)
    if ufunc is None and not _MATH_FAILURE.search(text):
        return None
    line = _user_line(exc)
    called = _NUMERIC_CALL.search(line or "")
    if called is not None:
        module, function = called.group(1), called.group(2)
    else:
        module, function = ("np", ufunc.group(1)) if ufunc else ("math", None)
    shown = f"{module}.{function}" if function else f"a function of the {module} module"
    instead = f"sp.{function}" if function else "sp.cos, sp.sin, sp.exp, sp.sqrt, …"
    where = f" (in `{line}`)" if line else ""
    return (f"calls {shown} on a symbolic coordinate{where}; the coordinates are SymPy "
            f"symbols, so a Lagrangian or constraint must use SymPy's functions: write "
            f"{instead} (import sympy as sp) instead of {shown}")


def _user_line(exc: BaseException) -> str | None:
    """The source line of the innermost frame of ``exc``'s traceback outside NumPy, SymPy
    and this package (the user's call that failed), if it can be read."""
    line = None
    tb = exc.__traceback__
    while tb is not None:
        filename = tb.tb_frame.f_code.co_filename
        if not re.search(r"[/\\](numpy|sympy|symgroupoid)[/\\]", filename):
            text = linecache.getline(filename, tb.tb_lineno).strip()
            line = text or line
        tb = tb.tb_next
    return line


#: functions that are not differentiable everywhere (the step's Newton iteration needs the
#: exact derivatives of L and φ, and the library differentiates them symbolically)
NON_SMOOTH = (sp.Abs, sp.sign, sp.Max, sp.Min, sp.Piecewise, sp.floor, sp.ceiling,
              sp.frac, sp.Heaviside, sp.DiracDelta, sp.Mod)


def check_smooth(system_name: str, what: str, value, display: dict | None = None) -> None:
    """An :class:`UnsupportedExpressionError` naming the first non-smooth function
    (``Abs``, ``sign``, ``Max``, ``Min``, ``Piecewise``, ``floor``, …) in a Lagrangian or
    constraint value, and the term that holds it, in the coordinates' names."""
    entries = value if isinstance(value, (list, tuple, sp.MatrixBase)) else [value]
    for entry in entries:
        try:
            expr = sp.sympify(entry)
        except (sp.SympifyError, TypeError):
            continue
        if not isinstance(expr, sp.Basic):
            continue
        found = sorted(expr.atoms(*NON_SMOOTH), key=sp.default_sort_key)
        if not found:
            continue
        bad = found[0]
        name = type(bad).__name__
        shown = bad.xreplace(display or {})
        raise UnsupportedExpressionError(
            f"{system_name}: {name} in the {what} ({shown}): non-smooth functions ("
            f"{', '.join(f.__name__ for f in NON_SMOOTH[:7])}, …) are not supported, "
            f"because the step is solved by Newton's method on the exact derivatives of L "
            f"and the constraints; write a smooth expression instead (e.g. sqrt(u**2 + "
            f"eps**2) for Abs(u))")


def _display(arrows: Sequence) -> dict:
    """Slot coordinates → the named coordinates of g_k, g_{k+1}, … (for messages)."""
    out: dict = {}
    for offset, arrow in enumerate(arrows):
        groupoid, coords = getattr(arrow, "groupoid", None), getattr(arrow, "coords", None)
        if groupoid is None or coords is None:
            continue
        out.update({c: n for c, n in zip(coords, groupoid.named_arrow(offset))
                    if isinstance(c, sp.Symbol)})
    return out


def check_values(system_name: str, what: str, value, arrows: Sequence = (),
                 display: dict | None = None) -> None:
    """:func:`check_finite_real` on a user return value: a scalar, or each entry of a list
    or matrix (entries that are not SymPy scalars are left to the shape checks)."""
    if isinstance(value, sp.MatrixBase):
        items = [(f"{what} (entry {i})", v) for i, v in enumerate(value)]
    elif isinstance(value, (list, tuple)):
        items = [(f"{what} (entry {i})", v) for i, v in enumerate(value)]
    else:
        items = [(what, value)]
    for label, item in items:
        try:
            expr = sp.sympify(item)
        except (sp.SympifyError, TypeError):
            continue
        if isinstance(expr, sp.Expr):
            if display is None:
                display = _display(arrows)
            check_finite_real(system_name, label, expr, display)


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
    if isinstance(value, (str, bytes)):
        raise ShapeError(f"{system_name}: the {what} returned the string {value!r}; it must "
                         f"be a SymPy expression (a string's symbols would not be the "
                         f"coordinates)")
    try:
        expr = sp.sympify(value)
    except (sp.SympifyError, TypeError, ValueError, AttributeError) as exc:
        # (SymPy raises ValueError for an array holding NaN, AttributeError for some junk)
        raise ShapeError(f"{system_name}: the {what} returned {shown_value(value)}, not a "
                         f"scalar") from exc
    if not isinstance(expr, sp.Expr):
        raise ShapeError(f"{system_name}: the {what} returned {shown_value(expr)}, not a "
                         f"scalar")
    return expr


def check_finite_real(system_name: str, what: str, expr: sp.Expr,
                      display: dict | None = None) -> None:
    """Raise :class:`InvalidExpressionError` if ``expr`` contains nan, ±oo or zoo (also from
    non-finite Python or NumPy floats, which SymPy turns into these), a constant beyond the
    range of a double (``Float("1e400")``: compiled code would read it as infinity), or the
    imaginary unit (unless it cancels on expansion); the message names the value and the
    term of ``expr`` that contains it, with the coordinates shown through ``display``."""
    atoms = expr.atoms()
    bad = next((a for a in _NON_FINITE if a in atoms), None)
    huge = None if bad is not None else next(
        (a for a in sorted(atoms, key=sp.default_sort_key)
         if isinstance(a, sp.Number) and _beyond_double(a)), None)
    if bad is not None:
        described = _NON_FINITE[bad]
    elif huge is not None:
        bad = huge
        described = (f"the constant {sp.Float(huge, 3)}, beyond the range of a double "
                     f"(|c| > {sys.float_info.max:.4g}; compiled code would read it as "
                     f"infinity)")
    elif sp.I in atoms and sp.expand(expr).has(sp.I):
        bad, described = sp.I, "I (the imaginary unit; the expression must be real)"
    else:
        check_real_branches(system_name, what, expr, display)
        return
    if expr == bad:
        raise InvalidExpressionError(f"{system_name}: the {what} is {described}")
    term = next(t for t in sp.Add.make_args(expr) if t.has(bad))
    raise InvalidExpressionError(
        f"{system_name}: the {what} contains {described} in the term "
        f"{term.xreplace(display or {})}")


#: functions real only on part of the real line (and powers with a non-integer exponent)
_PARTIAL = (sp.log, sp.asin, sp.acos, sp.acosh, sp.atanh, sp.acoth, sp.asec, sp.acsc)


def check_real_branches(system_name: str, what: str, expr: sp.Expr,
                        display: dict | None = None) -> None:
    """Raise :class:`InvalidExpressionError` when a logarithm, inverse trigonometric
    function or fractional power in ``expr`` is not real at any real point (SymPy decides
    it from the assumptions: ``log(-1 - q**2)``, ``sqrt(-h)`` with h positive): such an
    expression is NaN wherever it is evaluated."""
    parts = [e for e in expr.atoms(sp.Function, sp.Pow)
             if isinstance(e, _PARTIAL) or (isinstance(e, sp.Pow) and e.exp.is_integer
                                            is False)]
    for e in sorted(parts, key=sp.default_sort_key):
        if e.is_extended_real is False:
            raise InvalidExpressionError(
                f"{system_name}: the {what} contains {e.xreplace(display or {})}, which is "
                f"not real for any real value of the coordinates and parameters (the "
                f"expression must be real)")


def _beyond_double(number: sp.Number) -> bool:
    """Whether a finite SymPy number is too large in magnitude for a double."""
    try:
        return not math.isfinite(float(number))
    except OverflowError:
        return True
    except TypeError:  # not real: reported as such by the caller
        return False


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
            raise ShapeError(f"{exc} — {what} must be a list of scalars") from exc
    return out


_WALKED = (sp.Add, sp.Mul, sp.Pow)


def free_symbols_of(exprs: Iterable[sp.Expr]) -> set:
    """The free symbols of ``exprs``, each shared subexpression visited once (SymPy's
    ``free_symbols`` visits a subtree once per occurrence, which costs minutes on the
    discrete Lagrangians and forces of Galerkin schemes on groups); sums, products, powers
    and applied functions are walked, anything else (which may bind symbols) is asked."""
    free: set = set()
    seen: set = set()
    stack = list(exprs)
    while stack:
        e = stack.pop()
        if e in seen:
            continue
        seen.add(e)
        if isinstance(e, sp.Symbol):
            free.add(e)
        elif isinstance(e, _WALKED) or (isinstance(e, sp.Function)
                                         and not getattr(e, "bound_symbols", ())):
            stack.extend(e.args)
        elif not e.is_Atom:
            free |= e.free_symbols
    return free


def check_symbols(system_name: str, what: str, exprs: Iterable[sp.Expr],
                  coordinates: Sequence, parameters: Sequence, inputs: Sequence = (),
                  forces: bool = False) -> None:
    """Raise :class:`UndeclaredSymbolError` naming symbols that are neither coordinates
    nor declared parameters, and :class:`ParameterDeclarationError` for parameters that are
    not SymPy symbols or that match a used symbol by name but not by assumptions.
    ``inputs``: the system's inputs, which ``exprs`` (not forces) may not use: the message
    says where they belong; ``forces``: ``exprs`` are forces, which may also use inputs."""
    free = free_symbols_of(exprs)
    check_parameters(system_name, what, parameters, free)
    allowed = set(coordinates) | set(parameters)
    bad = sorted((s for s in free - allowed), key=str)
    if bad:
        _check_assumptions(system_name, what, bad, parameters)
        names = ", ".join(str(s) for s in bad)
        declared = [s for s in bad if s in set(inputs)]
        if declared:
            raise UndeclaredSymbolError(
                f"{system_name}: the {what} uses {', '.join(map(str, declared))}, declared "
                f"as input(s): an input enters only through the forces (its value belongs "
                f"to each arrow); use it in forces=, or declare it among the parameters "
                f"(fixed for a run) instead of the inputs")
        also = (" (or, for a value that changes from step to step, in inputs=[...])"
                if forces else "")
        raise UndeclaredSymbolError(
            f"{system_name}: the {what} uses symbol(s) {names} that are neither coordinates of "
            f"the arrow nor declared parameters; pass them in parameters=[...]{also}")


def _shown(s: sp.Symbol) -> str:
    """A symbol with the assumptions it was declared with: ``Symbol('h', positive=True)``."""
    return sp.srepr(s)


def check_parameters(system_name: str, what: str, parameters: Sequence,
                     used: Iterable[sp.Symbol] = ()) -> None:
    """Every declared parameter must be a SymPy Symbol; a string (or any other object) is
    reported with what to pass instead — and, when ``what`` uses a symbol of that name,
    with that symbol."""
    by_name = {str(s): s for s in used}
    seen: set[str] = set()
    printed: dict[str, sp.Symbol] = {}
    for p in parameters:
        if isinstance(p, sp.Symbol):
            if str(p) in seen:
                raise ParameterDeclarationError(
                    f"{system_name}: parameter {p} is declared twice; parameters are given "
                    f"by name, so each name may appear once")
            seen.add(str(p))
            _check_parameter_name(system_name, p, printed)
        if isinstance(p, sp.Symbol):
            continue
        if isinstance(p, str):
            hint = (f"; the {what} uses {_shown(by_name[p])}: pass that Symbol object"
                    if p in by_name else "")
            raise ParameterDeclarationError(
                f"{system_name}: parameters must be SymPy symbols, not strings: got {p!r} — "
                f"pass the symbols the expressions use, e.g. {p} = sympy.Symbol({p!r}, "
                f"positive=True) and parameters=[{p}]{hint}")
        raise ParameterDeclarationError(
            f"{system_name}: parameters must be SymPy symbols; got {p!r} "
            f"({type(p).__name__})")


#: a subscript that reads as a step index: x_{k}, x_{k+1}, (x)_{k-2}
def step_subscript(tex: str) -> bool:
    """Whether a name printed ``tex`` reads as a value at a step (x_k, x_{k+1}, x_j:
    :func:`~symgroupoid._symbols.reads_as_step_value`)."""
    return reads_as_step_value(tex)


def check_parameters_unlike_coordinates(system_name: str, groupoid, parameters: Sequence,
                                        constrained: bool = False) -> None:
    """A parameter written as a scalar coordinate of the arrows is (x beside x_{k}) would
    read as that coordinate in the printed equations, and in a ``constrained`` system one
    written λ as the multipliers (λ beside (λ_{k})_{1}): a
    :class:`ParameterDeclarationError`.  (A group's name, whose arrows print as matrices
    and their entries, (g_{k})_{12}, may also name a scalar parameter: gravity g beside
    SE(3)'s g; and without constraints λ names no multiplier: Lamé's λ.)"""
    taken = {latex_name(n): n for o in (0, 1) for n, value in groupoid.symbols_by_name(o).items()
             if isinstance(value, sp.Symbol)}
    for p in parameters:
        if not isinstance(p, sp.Symbol):
            continue
        key = latex_name(p.name.strip())
        if constrained and (is_multiplier_name(p.name.strip())
                            or re.match(r"\\lambda[_^]", key)):  # λ, and λ_1 beside (λ_k)_1
            raise _name_refused(system_name, p, f"is written {key}, as the multipliers of the "
                                f"constraints are ((\\lambda_{{k}})_{{1}}), which the printed "
                                f"equations would not tell apart")
        if key in taken:
            raise _name_refused(system_name, p, f"is written {key}, as the coordinate "
                                f"{taken[key]!r} of {groupoid.name} is (whose values print "
                                f"{key}_{{k}}), which the printed equations would not tell "
                                f"apart")


def _name_refused(system_name: str, p: sp.Symbol, why: str) -> ParameterDeclarationError:
    """The :class:`ParameterDeclarationError` of a parameter whose printed name ``why``
    cannot stand."""
    return ParameterDeclarationError(f"{system_name}: parameter {p.name!r} {why}; name it "
                                     f"otherwise")


def _check_parameter_name(system_name: str, p: sp.Symbol, printed: dict) -> None:
    """A parameter is printed by its name: two parameters written alike (theta and θ, a
    Dummy and a Symbol both k, "k" and "k "), a name that reads as a value at a step
    (x_{k+1}), or one written Δ as the differences are, would print one equation as
    another."""
    odd = unspelled_character(p.name.strip())
    if odd is not None:
        raise _name_refused(system_name, p, f"holds the character {odd!r}, which LaTeX does "
                            f"not typeset in mathematics (the printed equations would not "
                            f"compile; Greek letters, ℓ, ħ, µ and accented letters such as ẋ "
                            f"are spelt as commands)")
    misread = misread_name(p.name.strip())
    if misread is not None:
        raise _name_refused(system_name, p, misread)
    if reads_as_power(p.name.strip()):
        raise _name_refused(system_name, p, f"prints as {latex_name(p.name.strip())}, which "
                            f"reads as a power (a superscript of digits or letters): "
                            f"write the index as a subscript (m_2)")
    key = latex_name(p.name.strip())
    if key in printed:
        raise ParameterDeclarationError(
            f"{system_name}: parameters {printed[key]!r} and {p!r} are both written {key} in "
            f"the printed equations; give them names that differ")
    printed[key] = p
    if step_subscript(key):
        raise ParameterDeclarationError(
            f"{system_name}: parameter {p.name!r} is written {key}, as a value at a step "
            f"(x_{{k+1}}) is; a parameter is fixed for a run: name it otherwise")
    if is_difference_name(p.name.strip()):
        raise ParameterDeclarationError(
            f"{system_name}: parameter {p.name!r} is written \\Delta, as the printed "
            f"equations write the differences of the coordinates (\\Delta q for "
            f"q_{{k+1}} - q_k); name it otherwise")


def _check_assumptions(system_name: str, what: str, undeclared: Sequence[sp.Symbol],
                       declared: Sequence) -> None:
    """An undeclared symbol with the name of a declared parameter differs from it in its
    assumptions: say so, showing both."""
    by_name: dict = {}
    for s in declared:
        by_name.setdefault(str(s), s)
    for s in undeclared:
        other = by_name.get(str(s))
        if other is not None:
            raise ParameterDeclarationError(
                f"{system_name}: the {what} uses {_shown(s)} but the declared symbol is "
                f"{_shown(other)}: the names match but the assumptions differ, so SymPy treats "
                f"them as different symbols; declare the parameter with the same assumptions "
                f"(pass the very Symbol the {what} uses)")


def as_matrix(system_name: str, what: str, value) -> sp.Matrix:
    """A SymPy matrix from a user value: a SymPy or NumPy matrix, or a list of equal-length
    rows of scalars; anything else (a ragged or empty table, a row that is not a list, a
    string) is a :class:`ShapeError` naming ``what``, never an error from SymPy's parser."""
    bad = ShapeError(f"{system_name}: the {what} must be a matrix (a list of equal-length "
                     f"rows of scalars), got {type(value).__name__} {value!r}"[:300])
    if isinstance(value, sp.MatrixBase):
        return sp.Matrix(value)
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) and not (
            hasattr(value, "tolist") and getattr(value, "ndim", 0) == 2):
        raise bad
    rows = value.tolist() if hasattr(value, "tolist") else list(value)
    if not rows or any(isinstance(r, (str, bytes)) or not isinstance(r, (list, tuple))
                       for r in rows) or len({len(r) for r in rows}) != 1 or not rows[0]:
        raise bad
    if not all(_is_scalar_expression(c) for r in rows for c in r):
        raise bad
    try:
        return sp.Matrix(rows)
    except (TypeError, ValueError, ArithmeticError, sp.SympifyError) as exc:
        raise bad from exc


def _is_scalar_expression(value) -> bool:
    """A number or SymPy scalar expression (not a string, boolean, None or container)."""
    if isinstance(value, (bool, list, tuple, dict, set)) or value is None:
        return False
    return scalar_expression(value) is not None
