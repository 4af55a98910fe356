"""Every public callable of the package, given anything where its required arguments
belong: a named :class:`~symgroupoid.SymgroupoidError` (naming the callable or an argument),
or a result — never another exception.

The other hostile suites draw malformed variants of valid calls entry point by entry point;
this one sweeps the whole public face (``symgroupoid.__all__``) with junk, so that a new
entry point is covered the day it is exported.  Found by it: ``hat3``, ``left_derivative``,
``right_derivative``, ``rayleigh_damping`` (an array as the rule), ``check_morphism``,
``check_system_morphism``, ``NamedMatrix``, ``Arrow``, ``AtiyahGroupoid`` and the result
types (``Simulator``, ``StepEquations``, ``LegendreTransforms``, ``NoetherQuantity``,
``LiePoissonEquations``) read attributes of whatever they were given and raised
AttributeError, TypeError, IndexError or ValueError.
"""

from __future__ import annotations

import enum
import inspect

import pytest
from _hostile import (
    PROFILES,
    judge,
    junk,
    profile,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from hypothesis import given
from hypothesis import strategies as st

import symgroupoid as sg


def _entries() -> dict:
    """name -> (callable, its required positional parameters, its required keyword-only
    ones): every callable exported by the package but the exception and warning classes,
    the status enumeration (whose lookup by value is Python's own) and the abstract base
    class (which Python refuses to instantiate)."""
    out = {}
    for name in sorted(sg.__all__):
        obj = getattr(sg, name)
        if not callable(obj) or (isinstance(obj, type) and (issubclass(
                obj, (BaseException, enum.Enum)) or inspect.isabstract(obj))):
            continue
        try:
            signature = inspect.signature(obj)
        except (TypeError, ValueError):
            continue
        required = [p.name for p in signature.parameters.values()
                    if p.default is p.empty
                    and p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
        keywords = [p.name for p in signature.parameters.values()
                    if p.default is p.empty and p.kind is p.KEYWORD_ONLY]
        out[name] = (obj, required, keywords)
    return out


ENTRIES = _entries()


def test_the_sweep_covers_the_public_face():
    """The sweep is not empty and reaches the constructors, the helpers and the
    functions a user calls first (so that the test can fail when one is left out)."""
    assert {"DiscreteSystem", "ContinuousSystem", "hat3", "compile_step", "sweep",
            "solve_boundary_value", "Simulator", "NamedMatrix"} <= set(ENTRIES)
    assert len(ENTRIES) >= 40


@pytest.mark.parametrize("name", sorted(ENTRIES))
@pytest.mark.parametrize("run", PROFILES)
def test_every_public_callable_refuses_junk_by_name(name, run):
    function, required, keywords = ENTRIES[name]

    @profile(run, 6, 120)
    @given(st.tuples(*[junk(4) for _ in required]),
           st.fixed_dictionaries({k: junk(4) for k in keywords}))
    def check(args, kwargs):
        judge(f"public.{name}", lambda: function(*args, **kwargs),
              [name, *required, *keywords])

    check()


def test_a_rational_is_not_a_product_of_factors():
    """Found by the sweep: SymPy's Rational has a method ``factors``, which was taken for a
    product's tuple of factors (TypeError: 'method' object is not iterable)."""
    import sympy as sp

    with pytest.raises(sg.SymgroupoidError, match="AtiyahGroupoid"):
        sg.AtiyahGroupoid(sp.Rational(1, 3), [])


GROUPS = {"SO2": sg.SO2("a"), "SO3": sg.SO3("R"), "SO3exp": sg.SO3("R", retraction="exp"),
          "SE2": sg.SE2("s"), "SE3": sg.SE3("T")}


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("method", ["cayley", "exp", "tau", "hat", "algebra_coordinates"])
@pytest.mark.parametrize("group", sorted(GROUPS))
def test_the_maps_from_a_groups_algebra_refuse_junk_by_name(group, method, run):
    """The maps the how-tos build group elements with.  ``SO3.cayley`` with two coordinates
    returned a matrix holding an internal symbol, with four dropped the fourth, with NaN
    gave a NaN matrix; ``exp`` and ``hat`` raised IndexError or SymPy's ShapeError."""
    import sympy as sp

    G = GROUPS[group]

    def verify(M):
        if method == "algebra_coordinates":  # the checked coordinates themselves
            assert isinstance(M, tuple) and len(M) == G.rank, M
            M = sp.Matrix(M)
        else:
            assert isinstance(M, sp.MatrixBase) and M.shape == (G.n, G.n), M
        assert not M.has(sp.nan, sp.zoo, sp.oo, -sp.oo), M
        assert not any(isinstance(s, sp.Dummy) for s in M.free_symbols), M

    numbers = st.floats(allow_nan=True, allow_infinity=True)

    @profile(run, 6, 120)
    @given(st.one_of(junk(4), st.lists(numbers, max_size=7)))
    def check(x):
        judge(f"{group}.{method}", lambda: getattr(G, method)(x), ["x", G.name, "hat"],
              verify=verify)

    check()
