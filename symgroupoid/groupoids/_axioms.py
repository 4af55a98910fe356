"""Numerical verification of the groupoid axioms on random arrows."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from .._arguments import instance_argument, integer_argument, real_argument
from .._errors import AxiomError, InputTypeError, ParameterError, ShapeError
from ._base import Groupoid


def _num(v: Sequence) -> np.ndarray:
    return np.array([float(sp.N(c)) for c in v], dtype=float)


def _close(a: Sequence, b: Sequence, tol: float) -> bool:
    a, b = _num(a), _num(b)
    return a.shape == b.shape and bool(np.allclose(a, b, atol=tol, rtol=tol))


def check_axioms(G: Groupoid, samples: int = 5, seed: int = 0, tol: float = 1e-9,
                 parameters: Mapping | None = None) -> None:
    """Check the groupoid axioms of ``G`` on random composable arrows.

    Verified: α, β of products; associativity; left and right identities; inverses;
    α∘ε = β∘ε = id; section curves lie in the α-fibre through ε(q) and their velocities are
    α-vertical and linearly independent (as many as the fibre dimension); the fibre chart
    lands in the α-fibre.  Raises :class:`AxiomError` naming the axiom and the arrows.

    Structure maps may contain free symbols besides the coordinates (parameters of the
    groupoid): ``parameters`` maps them (Symbols or their names) to values; symbols it does
    not give get random values respecting their assumptions (positive → (0.5, 2)), and a
    failure reports the values used.  ``samples`` (at least 1) and ``seed`` are counts
    (:func:`~symgroupoid._arguments.integer_argument`).
    """
    instance_argument(G, Groupoid, "G", "a Groupoid", owner="check_axioms")
    samples = integer_argument(samples, "samples", minimum=1, owner=G.name)
    seed = integer_argument(seed, "seed", maximum=2**63 - 2, owner=G.name)
    tol = real_argument(tol, "tol", minimum=0.0, owner=G.name)
    if parameters is not None and not isinstance(parameters, Mapping):
        raise InputTypeError(f"{G.name}: parameters must be a mapping symbol → value, got "
                             f"{type(parameters).__name__} {parameters!r}")
    values = _parameter_values(G, parameters or {})
    rng = np.random.default_rng(seed + 1)
    chosen: set = set()
    given = set(values)
    while True:
        try:
            evaluated = _Evaluated(G, values)
            _run(evaluated, samples, seed, tol)
            _all_used(G, given, evaluated.used)
            return
        except _FreeSymbols as free:
            for s in sorted(free.symbols, key=str):
                values[s] = _random_value(s, rng)
                chosen.add(s)
        except AxiomError as err:
            if values:
                shown = ", ".join(f"{s}={v:.6g}" for s, v in _sorted(values))
                how = (f"; {', '.join(sorted(map(str, chosen)))} chosen at random — pass "
                       "parameters={...} to check_axioms to choose them" if chosen else "")
                err.args = (f"{err} (with parameter values {shown}{how})",)
            err.parameters = {str(s): v for s, v in _sorted(values)}
            raise


def _run(G, samples: int, seed: int, tol: float) -> None:
    rng = np.random.default_rng(seed)
    t = sp.Dummy("t", real=True)
    G.curve_parameter = t
    for _ in range(samples):
        a = G.random_arrow(rng)
        b = G.random_arrow(rng, G.target(a))
        c = G.random_arrow(rng, G.target(b))
        _pair_checks(G, a, b, c, tol)
        q = G.random_base_point(rng)
        _identity_checks(G, q, tol)
        _section_checks(G, q, t, tol)


# --- parameters of the structure maps ---------------------------------------------------------

class _FreeSymbols(Exception):
    """A structure map returned free symbols on numeric input: parameters to be given values."""

    def __init__(self, symbols: set):
        super().__init__(", ".join(sorted(map(str, symbols))))
        self.symbols = symbols


def _sorted(values: Mapping) -> list:
    return sorted(values.items(), key=lambda kv: str(kv[0]))


def _parameter_values(G: Groupoid, parameters: Mapping) -> dict:
    """``parameters`` with every key a Symbol (names are kept as given until a symbol of that
    name shows up, see :class:`_Evaluated`) and every value a float."""
    out: dict = {}
    for key, value in parameters.items():
        if not isinstance(key, (sp.Symbol, str)):
            raise ShapeError(f"{G.name}: parameters must map SymPy symbols (or their names) to "
                             f"numbers, got the key {key!r}")
        out[key] = real_argument(value, f"the value of parameter {key}", owner=G.name)
    return out


def _all_used(G: Groupoid, given: set, used: set) -> None:
    """A :class:`ParameterError` naming the given parameters no structure map of ``G`` read
    (a misspelled name was ignored: the maps were checked at values chosen at random)."""
    unused = sorted(str(k) for k in given if k not in used)
    if unused:
        raise ParameterError(f"{G.name}: parameters {', '.join(unused)} are not symbols of "
                             f"its structure maps (they read "
                             f"{', '.join(sorted({str(u) for u in used})) or 'none'})")


def _random_value(s: sp.Symbol, rng: np.random.Generator) -> float:
    """Random value respecting the assumptions: negative → (−2, −0.5), else (0.5, 2)."""
    sign = -1.0 if (s.is_negative or s.is_nonpositive) else 1.0
    if s.is_integer:
        return sign * float(rng.integers(1, 4))
    return sign * float(rng.uniform(0.5, 2.0))


class _Evaluated:
    """``G`` with the parameter values substituted into every structure-map output; raises
    :class:`_FreeSymbols` when an output keeps a free symbol that has no value yet (the maps
    are only called on numbers here, except for the section curves' parameter t)."""

    def __init__(self, G: Groupoid, values: dict):
        self.inner, self.name, self.values = G, G.name, values
        self.curve_parameter = None
        self.used: set = set()  # the parameters (symbols and names) the maps read

    def _sub(self, coords: Sequence, what: str) -> tuple:
        out = []
        for c in coords:
            try:
                e = sp.sympify(c)
            except (sp.SympifyError, TypeError, ValueError) as exc:
                raise ShapeError(f"{self.name}: the {what} returned {c!r}, not a number or "
                                 f"expression") from exc
            free = e.free_symbols - {self.curve_parameter}
            if free:
                table = {s: self._value(s) for s in free}
                missing = {s for s, v in table.items() if v is None}
                if missing:
                    raise _FreeSymbols(missing)
                e = e.xreplace({s: sp.Float(v) for s, v in table.items()})
            if not e.free_symbols and _not_real(e):
                raise ShapeError(f"{self.name}: the {what} returned {e}, not a finite real "
                                 f"number (structure maps take real arrows to real arrows)")
            out.append(e)
        return tuple(out)

    def _value(self, s: sp.Symbol) -> float | None:
        if s in self.values:
            self.used.update((s, str(s)))
            return self.values[s]
        if str(s) in self.values:  # given by name: bind it to this symbol
            self.values[s] = self.values.pop(str(s))
            self.used.update((s, str(s)))
            return self.values[s]
        return None

    def source(self, a):
        return self._sub(self.inner.source(a), "source map")

    def target(self, a):
        return self._sub(self.inner.target(a), "target map")

    def multiply(self, a, b):
        return self._sub(self.inner.multiply(a, b), "multiply map")

    def identity(self, q):
        return self._sub(self.inner.identity(q), "identity map")

    def inverse(self, a):
        return self._sub(self.inner.inverse(a), "inverse map")

    def _curves(self, q, t):
        return [self._sub(h, f"section curve {i}")
                for i, h in enumerate(self.inner._curves(q, t))]

    def arrow_from(self, q, f):
        return self._sub(self.inner.arrow_from(q, f), "arrow_from map")

    def fibre_chart(self, x, source=None):
        return self._sub(self.inner.fibre_chart(x, source), "fibre chart")

    def random_base_point(self, rng):
        return self.inner.random_base_point(rng)

    def random_chart(self, rng, scale: float = 0.5):
        return self.inner.random_chart(rng, scale)

    def numeric_fibre_arrow(self, q, x):
        return Groupoid.numeric_fibre_arrow(self, q, x)  # through the substituted maps

    def random_arrow(self, rng, source=None):
        if type(self.inner).random_arrow is Groupoid.random_arrow:
            return Groupoid.random_arrow(self, rng, source)  # through the substituted maps
        return tuple(float(v) for v in self._sub(self.inner.random_arrow(rng, source),
                                                  "random arrow"))


def _not_real(e: sp.Expr) -> bool:
    """A number that is not a finite real one: complex, ±oo, zoo, nan."""
    if not e.is_number:
        return False
    return e.has(sp.nan, sp.zoo, sp.oo, -sp.oo) or e.is_extended_real is False or (
        e.is_extended_real is None and abs(complex(sp.N(e)).imag) > 0)


# --- the checks -----------------------------------------------------------------------------

def _fail(G: Groupoid, axiom: str, **arrows) -> AxiomError:
    """An :class:`AxiomError` naming the axiom and showing the failing arrows (or base point).

    The exception also carries ``.axiom`` and ``.arrows`` (name → tuple of floats) so that a
    caller can reproduce the failure.
    """
    values = {k: tuple(float(c) for c in _num(v)) for k, v in arrows.items()}
    shown = ", ".join(f"{k}=({', '.join(f'{c:.6g}' for c in v)})" for k, v in values.items())
    err = AxiomError(f"{G.name}: {axiom} fails for {shown}")
    err.axiom, err.arrows = axiom, values
    return err


def _pair_checks(G, a, b, c, tol):
    ab = G.multiply(a, b)
    if not _close(G.source(ab), G.source(a), tol):
        raise _fail(G, "α(ab) = α(a)", a=a, b=b)
    if not _close(G.target(ab), G.target(b), tol):
        raise _fail(G, "β(ab) = β(b)", a=a, b=b)
    if not _close(G.multiply(ab, c), G.multiply(a, G.multiply(b, c)), tol):
        raise _fail(G, "associativity (ab)c = a(bc)", a=a, b=b, c=c)
    if not _close(G.multiply(G.identity(G.source(a)), a), a, tol):
        raise _fail(G, "left identity ε(α(a))·a = a", a=a)
    if not _close(G.multiply(a, G.identity(G.target(a))), a, tol):
        raise _fail(G, "right identity a·ε(β(a)) = a", a=a)
    ai = G.inverse(a)
    if not _close(G.source(ai), G.target(a), tol) or not _close(G.target(ai), G.source(a), tol):
        raise _fail(G, "α(a⁻¹) = β(a), β(a⁻¹) = α(a)", a=a)
    if not _close(G.multiply(a, ai), G.identity(G.source(a)), tol):
        raise _fail(G, "a·a⁻¹ = ε(α(a))", a=a)
    if not _close(G.multiply(ai, a), G.identity(G.target(a)), tol):
        raise _fail(G, "a⁻¹·a = ε(β(a))", a=a)


def _identity_checks(G, q, tol):
    e = G.identity(q)
    if not _close(G.source(e), q, tol) or not _close(G.target(e), q, tol):
        raise _fail(G, "α(ε(q)) = β(ε(q)) = q", q=q)


def _section_checks(G, q, t, tol):
    curves = G._curves(q, t)
    vel = []
    for i, h in enumerate(curves):
        h0 = [sp.sympify(c).subs(t, 0) for c in h]
        if not _close(h0, G.identity(q), tol):
            raise _fail(G, f"section {i}: h(0) = ε(q)", q=q)
        ht = [sp.sympify(c).subs(t, sp.Rational(3, 10)) for c in h]
        if not _close(G.source(ht), q, tol):
            raise _fail(G, f"section {i}: h(t) in the α-fibre of q", q=q)
        vel.append(_num([sp.sympify(c).diff(t).subs(t, 0) for c in h]))
    if vel and np.linalg.matrix_rank(np.array(vel), tol=1e-8) != len(vel):
        raise _fail(G, "section velocities at ε(q) are linearly independent", q=q)
    rng = np.random.default_rng(1)
    x = [sp.Float(v) for v in G.random_chart(rng)]
    arrow = G.arrow_from(q, G.fibre_chart(x, q))
    if not _close(G.source(arrow), q, tol):
        raise _fail(G, "the fibre chart lands in the α-fibre of q", q=q)
