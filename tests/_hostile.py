"""The hostile-input suite's machinery: the invariant, its tally, and malformed values.

Every call made by the hostile-input tests goes through :func:`judge`, which enforces the
library's contract on bad input:

- the call succeeds and its result passes ``verify`` (finite, and correct by an independent
  check: step residuals through ``StepEquations.evaluate``, the stationarity of the action,
  the end points of a boundary-value solution, …), or
- it raises a :class:`~symgroupoid.SymgroupoidError` whose message names the offending
  argument or part (one of ``names``, as a whole word) — or, for a numerical failure of valid
  input (Newton, a singular Jacobian, the cut locus), names the system.

Anything else is a defect: another exception type (from NumPy, SymPy, cffi or Python itself),
a ``ComplexWarning`` (an imaginary part silently dropped), a non-finite or incorrect result.
Defects that live in code this suite may not change are listed in :data:`KNOWN` (a raw
exception) and :data:`KNOWN_RESULTS` (a wrong result), each with the strict ``xfail`` test
that reproduces it; :func:`judge` counts them separately instead of failing, so the
properties keep running over the rest of the input space.

:data:`TALLY` counts, per entry point, the examples tried, the clear errors, the valid calls,
the known defects and the defects; ``tests/conftest.py`` prints it at the end of the session.
"""

from __future__ import annotations

import math
import re
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pytest
import sympy as sp
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import symgroupoid as sg
from symgroupoid._errors import CutLocusError

# --- profiles -----------------------------------------------------------------------------------

_COMMON = dict(deadline=None, database=None, print_blob=True,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                      HealthCheck.filter_too_much,
                                      HealthCheck.function_scoped_fixture])
settings.register_profile("hostile-regular", derandomize=True, **_COMMON)
settings.register_profile("hostile-thorough", derandomize=False, **_COMMON)

#: the two runs of every property: few derandomized examples in the regular suite, many
#: random ones under ``-m slow``
PROFILES = [pytest.param("regular", id="regular"),
            pytest.param("thorough", id="thorough", marks=pytest.mark.slow)]


def profile(name: str, regular: int, thorough: int | None = None) -> settings:
    """Settings of a property in the run ``name`` ("regular" or "thorough")."""
    if name == "regular":
        return settings(settings.get_profile("hostile-regular"), max_examples=regular)
    return settings(settings.get_profile("hostile-thorough"),
                    max_examples=thorough if thorough is not None else 20 * regular)


# --- the tally ----------------------------------------------------------------------------------

@dataclass
class Counts:
    tried: int = 0
    clear: int = 0
    valid: int = 0
    known: int = 0
    defects: int = 0


class Tally(dict):
    """Entry point → :class:`Counts`."""

    def __missing__(self, key: str) -> Counts:
        self[key] = Counts()
        return self[key]

    def add(self, entry: str, **counts: int) -> None:
        c = self[entry]
        for key, value in counts.items():
            setattr(c, key, getattr(c, key) + int(value))

    def lines(self) -> list[str]:
        """The summary printed at the end of the session (empty when nothing ran): per entry
        point, the calls tried, those that returned a verified correct result, those that
        raised a clear error, and the defects (known ones listed in :data:`KNOWN`)."""
        if not self:
            return []
        total = Counts()
        width = max(len("entry point"), *map(len, self))
        rows = [f"  {'entry point':<{width}} {'tried':>7} {'correct':>8} {'clear error':>12} "
                f"{'known defect':>13} {'defect':>7}"]
        for entry in sorted(self):
            c = self[entry]
            for key in vars(total):
                setattr(total, key, getattr(total, key) + getattr(c, key))
            rows.append(f"  {entry:<{width}} {c.tried:7d} {c.valid:8d} {c.clear:12d} "
                        f"{c.known:13d} {c.defects:7d}")
        head = (f"hostile inputs: {total.tried} tried, {total.valid} correct results, "
                f"{total.clear} clear errors, {total.known} known defects (strict xfail "
                f"tests), {total.defects} defects")
        return [head, *rows]


TALLY = Tally()


# --- the invariant ------------------------------------------------------------------------------

#: numerical failures of valid input: their message must name the system
NUMERICAL = (sg.NewtonDivergenceError, sg.SingularJacobianError, CutLocusError)


@dataclass(frozen=True)
class Known:
    """A defect in code this suite may not change, reproduced by a strict xfail test."""

    entries: tuple[str, ...]
    kind: type[BaseException] | tuple[type[BaseException], ...]
    pattern: str
    test: str

    def matches(self, entry: str, err: BaseException) -> bool:
        return (entry in self.entries and isinstance(err, self.kind)
                and not isinstance(err, sg.SymgroupoidError)
                and re.search(self.pattern, f"{type(err).__name__}: {err}") is not None)


#: defects in runtime/_bvp.py (not changed here), each with its strict xfail test; the fix
#: of each is described in the test's reason
_BVP = ("solve_boundary_value", "sweep_boundary_value")
KNOWN: list[Known] = []  # none open: each listed defect was fixed and its test kept


@dataclass(frozen=True)
class KnownResult:
    """A known defect that returns a wrong result instead of raising, recognised by a
    predicate on the result; reproduced by a strict xfail test."""

    entries: tuple[str, ...]
    predicate: Callable[[object], bool]
    test: str

    def matches(self, entry: str, result) -> bool:
        try:
            return entry in self.entries and bool(self.predicate(result))
        except Exception:  # noqa: BLE001 - a result the predicate cannot read: not this one
            return False


KNOWN_RESULTS: list[KnownResult] = []  # none open: those listed were fixed, their tests kept


def named(message: str, names: Sequence[str]) -> bool:
    """Whether ``message`` contains one of ``names`` as a whole word (case-insensitive)."""
    for n in names:
        pattern = rf"(?<![A-Za-z0-9]){re.escape(str(n))}(?![A-Za-z0-9])"
        if re.search(pattern, message, flags=re.IGNORECASE):
            return True
    return False


class Defect(AssertionError):
    """A call broke the contract on bad input."""


def judge(entry: str, call: Callable[[], object], names: Sequence[str], *,
          owner: str | None = None, verify: Callable[[object], None] | None = None,
          numerical: tuple[type[BaseException], ...] = NUMERICAL):
    """Run ``call`` and check the invariant (module docstring); return its result, or None
    after a clear error.  ``owner``: the system or groupoid name numerical failures name."""
    counts = TALLY[entry]
    counts.tried += 1
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", np.exceptions.ComplexWarning)
            warnings.simplefilter("ignore", RuntimeWarning)
            result = call()
    except sg.SymgroupoidError as err:
        text = str(err)
        accepted = list(names)
        if owner is not None and isinstance(err, numerical):
            accepted.append(owner)
        if not named(text, accepted):
            counts.defects += 1
            raise Defect(f"{entry}: {type(err).__name__} names none of {accepted}: "
                         f"{text!r}") from err
        counts.clear += 1
        return None
    except (KeyboardInterrupt, SystemExit):
        raise
    except BaseException as err:  # noqa: BLE001 - anything else is what this suite hunts
        if any(k.matches(entry, err) for k in KNOWN):
            counts.known += 1
            return None
        counts.defects += 1
        raise Defect(f"{entry}: raw {type(err).__name__}: {err}") from err
    if verify is not None:
        try:
            verify(result)
        except AssertionError:
            if any(k.matches(entry, result) for k in KNOWN_RESULTS):
                counts.known += 1
                return result
            counts.defects += 1
            raise
    counts.valid += 1
    return result


# --- malformed values ---------------------------------------------------------------------------

NON_FINITE = (math.nan, math.inf, -math.inf)
#: finite but extreme: overflow bait
HUGE = (1e308, -1e308, 2.0**1000, 2**70, -(2**64), 10**400)
TINY = (5e-324, -5e-324, 1e-300)

#: scalars of every kind that is not a plain real number, or a real number at an edge
ODD_SCALARS = [
    None, True, False, np.bool_(True), "", "1.5", "nan", "x", b"1", 1j, complex(1, 0),
    np.complex128(1 + 2j), sp.Symbol("q"), sp.nan, sp.oo, sp.zoo, sp.I, sp.Rational(1, 3),
    sp.Float("1e400"), sp.Integer(2), np.float16(0.5), np.float32(2.5), np.int8(-3),
    np.uint64(2**64 - 1), np.datetime64("2020-01-01"), np.timedelta64(3, "D"), Ellipsis,
    slice(1, 2), range(3), object(), {}, set(), [], (), np.array(2.0), np.array([]),
    print, type, *NON_FINITE, *HUGE, *TINY, 0, -1, 0.0, -0.0,
]

scalars = st.one_of(
    st.sampled_from(ODD_SCALARS),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**80), max_value=2**80),
    st.complex_numbers(allow_nan=True, allow_infinity=True),
    st.text(max_size=4),
)

_DTYPES = st.sampled_from([np.float64, np.float32, np.int64, np.int8, np.uint8, np.bool_,
                           np.complex128, "U3", "S2", "M8[D]", "m8[s]", np.float16])


def odd_arrays(max_dims: int = 3, max_side: int = 4):
    """NumPy arrays of every dtype and small shape (entries of every value the dtype has)."""
    return hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=max_dims, min_side=0,
                                                max_side=max_side))


def _hashable(value) -> bool:
    try:
        hash(value)
    except TypeError:
        return False
    return True


#: keys of hostile mappings: odd scalars that can be dictionary keys
keys = st.one_of(st.text(max_size=3), scalars.filter(_hashable))


def junk(max_leaves: int = 6):
    """Anything: odd scalars, arrays, and nested lists, tuples and dicts of them."""
    leaves = st.one_of(scalars, odd_arrays())
    return st.recursive(
        leaves,
        lambda inner: st.one_of(st.lists(inner, max_size=4), st.tuples(inner, inner),
                                st.dictionaries(keys, inner, max_size=3)),
        max_leaves=max_leaves)


@st.composite
def near(draw, valid, *, allow_valid: bool = True):
    """Hostile variants of a valid numeric value (a number or an array): one entry made
    non-finite, huge, complex, a string or None; an entry dropped or added; the shape
    changed; the dtype changed; or (``allow_valid``) the value as lists, integers, float32 —
    equivalent spellings that must be accepted."""
    arr = np.array(valid, dtype=float)
    flat = arr.ravel()
    kind = draw(st.sampled_from(
        ["entry", "drop", "add", "reshape", "dtype", "nest", "scale"]
        + (["spelling"] if allow_valid else [])))
    if kind == "entry" and flat.size:
        i = draw(st.integers(0, flat.size - 1))
        bad = draw(st.sampled_from([*NON_FINITE, *HUGE, *TINY, 1j, "a", None, True, "1.0",
                                    sp.Symbol("x"), sp.nan, [1.0], ()]))
        out = flat.astype(object)
        out[i] = bad
        shaped = out.reshape(arr.shape).tolist() if arr.ndim else out[0]
        return shaped
    if kind == "drop" and flat.size:
        return flat[:-1].tolist()
    if kind == "add":
        return [*flat.tolist(), draw(st.floats(-2, 2))]
    if kind == "reshape":
        shapes = [(flat.size, 1), (1, flat.size), (flat.size,), (), (0,), (flat.size, 0)]
        if arr.ndim == 2:
            return arr.T.tolist() if arr.shape[0] != arr.shape[1] else arr[None].tolist()
        shape = draw(st.sampled_from(shapes))
        if int(np.prod(shape)) == flat.size:
            return flat.reshape(shape)
        return np.zeros(shape)
    if kind == "dtype":
        dtype = draw(st.sampled_from([np.complex128, "U8", np.bool_, object, "M8[D]"]))
        if dtype == np.complex128:
            return arr.astype(complex) + draw(st.sampled_from([1j, 1e-3j]))
        if dtype == "M8[D]":
            return arr.astype(np.int64).astype("M8[D]")
        return arr.astype(dtype)
    if kind == "nest":
        return [arr.tolist()]
    if kind == "scale":  # to overflow on purpose: inf entries are part of the example
        factor = draw(st.sampled_from([1e300, -1e300, 1e-300, 1e150]))
        with np.errstate(over="ignore"):
            return arr * factor
    if kind == "spelling":
        style = draw(st.sampled_from(["list", "tuple", "float32", "int", "fortran"]))
        if style == "list":
            return arr.tolist()
        if style == "tuple":
            return tuple(flat.tolist()) if arr.ndim == 1 else arr.tolist()
        if style == "float32":
            return arr.astype(np.float32).astype(float) if arr.ndim else float(arr)
        if (style == "int" and np.array_equal(arr, np.round(arr))
                and np.all(np.abs(arr) < 2.0**62)):  # integers an int64 holds
            return arr.astype(np.int64)
        return np.asfortranarray(arr)
    return arr


def hostile(valid, names_extra: int = 0):
    """A malformed value near ``valid`` or anything at all."""
    return st.one_of(near(valid), junk())


# --- the working directory -----------------------------------------------------------------------

@pytest.fixture(autouse=True)
def scratch_cwd(tmp_path, monkeypatch):
    """Every hostile call runs with a scratch working directory: a relative path drawn as a
    cache directory or an output file lands there, never in the repository."""
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    return work


# --- verification helpers -----------------------------------------------------------------------

def assert_finite(array, what: str) -> None:
    a = np.asarray(array, dtype=float)
    assert np.isfinite(a).all(), f"{what} has non-finite entries: {a}"


def step_residual_ok(step, u, known, params, *, rel: float = 1e-7) -> None:
    """The step equations hold at ``u``: |F_i| ≤ rel·Σ_j |J_ij|(1 + |u_j|) (F much smaller
    than the change a relative move of ``rel`` of the unknowns makes), evaluated through
    ``step.evaluate`` (the NumPy program, independent of the kernel's Newton iteration)."""
    with np.errstate(all="ignore"):
        F, J = step.evaluate(np.asarray(u, float), np.asarray(known, float),
                             np.asarray(params, float))
        F, J = np.asarray(F, float).ravel(), np.asarray(J, float)
        scale = np.abs(J) @ (1.0 + np.abs(np.asarray(u, float)))
    bound = rel * scale + 1e-12
    bad = ~(np.abs(F) <= bound)
    assert not bad.any(), (f"{step.name}: the step equations do not hold: F = {F}, "
                           f"bound = {bound} at u = {u}, known = {known}")


def chart_unknowns(groupoid, arrow, multipliers) -> np.ndarray:
    """The unknowns of the step that produced ``arrow``: its α-fibre chart coordinates, then
    the multipliers (docs/conventions.md §4)."""
    a = np.asarray(arrow, float)
    x = np.asarray(groupoid.fibre_chart_inverse(groupoid.fibre_of(a), groupoid.source(a)),
                   dtype=float).ravel()
    return np.concatenate([x, np.asarray(multipliers, float).ravel()])


def verify_trajectory(step, traj, params) -> None:
    """Every state finite, every step solving the step equations (first order: checked
    through ``step.evaluate`` from the arrows and multipliers the trajectory holds)."""
    assert_finite(traj.states, f"{step.name}: trajectory")
    assert_finite(traj.residual_norms, f"{step.name}: residual norms")
    if step.order != 1 or len(traj.states) < 2:
        return
    every = getattr(traj, "every", 1)
    if every != 1:
        return
    arrows = traj._layout.arrows(traj.states)
    lam = traj.multipliers
    for k in range(len(traj.states) - 1):
        u = chart_unknowns(step.groupoid, arrows[k + 1], lam[k + 1])
        step_residual_ok(step, u, traj.states[k], params)


# --- tiny systems (fast to derive; the seeds come from kernel_support) ---------------------------

H, K = sp.symbols("h k", positive=True)


def oscillator() -> sg.DiscreteSystem:
    """L = h(½((q₁ − q₀)/h)² − ½k((q₀ + q₁)/2)²) on the pair groupoid of R."""
    def L(g):
        (q0,), (q1,) = g.source, g.target
        return H * (((q1 - q0) / H) ** 2 / 2 - K * ((q0 + q1) / 2) ** 2 / 2)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[H, K],
                             name="oscillator")


def diagonal() -> sg.DiscreteSystem:
    """A free particle in R² held to the diagonal direction: φ = Δx − Δy (one multiplier)."""
    def L(g):
        return sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * H) \
            - H * K * g.target[0] ** 2 / 2

    def phi(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return [(x1 - x0) - (y1 - y0)]

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L, constraints=phi,
                             parameters=[H, K], name="diagonal")


def accel() -> sg.SecondOrderSystem:
    """A second-order system on the pair groupoid of R: L = (second difference)²/h³ with the
    constraint that the second difference is h² (docs/conventions.md §11)."""
    return sg.SecondOrderSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a, b: (b.target[0] - 2 * a.target[0] + a.source[0]) ** 2 / H ** 3,
        constraints=lambda a, b: [b.target[0] - a.target[0] - (a.target[0] - a.source[0])
                                  - H ** 2],
        parameters=[H], name="accel")
