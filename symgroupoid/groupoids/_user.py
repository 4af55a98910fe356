"""Groupoids defined by a user from their structure maps and section curves only."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .._arguments import callable_argument, checked_keywords, name_argument, names_argument
from .._errors import (
    AxiomError,
    CallableError,
    CoordinateNameError,
    DomainError,
    ShapeError,
    SymgroupoidError,
)
from .._symbols import (
    alias_words,
    aliased_names,
    is_multiplier_name,
    latex_name,
    printable_name,
    scalar_symbol,
)
from ._base import Groupoid, coordinate_values

#: names that ``StepEquations.symbol`` reserves for the multipliers λ
RESERVED_NAMES = ("lambda", "λ", "multipliers")


@checked_keywords
class DefinedGroupoid(Groupoid):
    """A groupoid given by callables on coordinate tuples.

    The arrow coordinates are ``base_names`` (the source point) followed by ``fibre_names``
    (coordinates of the α-fibre); a step solves for the fibre coordinates of g_{k+1}.
    The invariant derivations, Legendre transforms and axiom checks are derived from the
    maps; nothing else has to be written.

    The axioms are checked when the groupoid is constructed (:func:`check_axioms` on random
    composable arrows; free symbols in the maps get random positive values); ``check=False``
    skips this, e.g. to call ``check_axioms(G, parameters={...})`` with chosen values.

    Example (the pair groupoid of R, written by hand)::

        G = DefinedGroupoid("line", base_names=["q"], fibre_names=["q"],
            source=lambda a: (a[0],), target=lambda a: (a[1],),
            multiply=lambda a, b: (a[0], b[1]), identity=lambda q: (q[0], q[0]),
            inverse=lambda a: (a[1], a[0]),
            sections=lambda q, t: [(q[0], q[0] + t)])
    """

    def __init__(self, name: str, *, base_names: Sequence[str], fibre_names: Sequence[str],
                 source: Callable, target: Callable, multiply: Callable, identity: Callable,
                 inverse: Callable, sections: Callable, source_offset: int = -1,
                 check: bool = True):
        self.name = name_argument(name, "the groupoid's name", owner="DefinedGroupoid")
        self.base_names = names_argument(base_names, "base_names", owner=name)
        self.fibre_names = names_argument(fibre_names, "fibre_names", owner=name)
        if not self.fibre_names:
            raise ShapeError(f"{name}: fibre_names is empty; the α-fibres need at least one "
                             f"coordinate (a step solves for them)")
        if not isinstance(source_offset, (int, np.integer)) or isinstance(
                source_offset, (bool, np.bool_)) or source_offset not in (-1, 0):
            raise DomainError(f"{name}: source_offset must be -1 (the source of g_k is the "
                              f"configuration at step k-1, as for a pair groupoid) or 0 (at "
                              f"step k, as for an action groupoid), got {source_offset!r}")
        self.source_offset = int(source_offset)
        self._check_names()
        maps = dict(source=source, target=target, multiply=multiply, identity=identity,
                    inverse=inverse, sections=sections)
        for key, value in maps.items():
            callable_argument(value, f"the {key} map", owner=name)
        self._maps = maps
        # the section count must equal the fibre dimension (checked early, with a clear error)
        t = sp.Dummy("t")
        q = tuple(sp.Dummy(f"q{i}") for i in range(self.base_dim))
        self._curves(q, t)
        if check:
            self._check_axioms()

    def _check_axioms(self) -> None:
        from ._axioms import check_axioms

        try:
            check_axioms(self, samples=3)
        except AxiomError as err:
            err.args = (f"{err} (DefinedGroupoid checks the groupoid axioms when it is "
                        "constructed; check=False skips this)",)
            raise

    def _check_names(self) -> None:
        """Coordinate names must not be the multipliers' (``RESERVED_NAMES``) and must name
        distinct symbols: distinct within the base and the fibre, and — with
        ``source_offset=0``, where the source of g_k and its fibre carry the same step label —
        distinct between them."""
        for kind, names in (("base", self.base_names), ("fibre", self.fibre_names)):
            for n in names:
                if is_multiplier_name(n):
                    raise CoordinateNameError(
                        f"{self.name}: the {kind} coordinate name {n!r} is reserved for the "
                        f"multipliers ({', '.join(map(repr, RESERVED_NAMES))} all name λ in "
                        "step.symbol); rename the coordinate")
                printable_name(n, f"the {kind} coordinate name", self.name, part=False)
            aliased = aliased_names(names)
            if aliased is not None:
                noun = "name" if aliased[0] == aliased[1] else "names"
                raise CoordinateNameError(
                    f"{self.name}: the {kind} coordinate {noun} {alias_words(aliased)}; each "
                    "coordinate needs its own name")
        fibre = {latex_name(n): n for n in self.fibre_names}
        shared = [(n, fibre[latex_name(n)]) for n in self.base_names if latex_name(n) in fibre]
        if shared and self.source_offset == 0:
            base, other = shared[0]
            named = repr(base) if base == other else f"{base!r} (as {other!r})"
            raise CoordinateNameError(
                f"{self.name}: {named} names both a base and a fibre coordinate with "
                "source_offset=0, so both would be the same symbol at every step; rename one")

    @property
    def arrow_dim(self):
        return len(self.base_names) + len(self.fibre_names)

    @property
    def base_dim(self):
        return len(self.base_names)

    @property
    def rank(self):
        return len(self.fibre_names)

    def _call(self, map_name: str, size: int, *args) -> tuple:
        """Call the user's ``map_name`` map; wrap exceptions and check the result's length."""
        try:
            out = self._maps[map_name](*args)
        except SymgroupoidError:
            raise
        except Exception as exc:  # noqa: BLE001 - re-raised with context
            raise CallableError(f"{self.name}: the {map_name} map raised "
                                f"{type(exc).__name__}: {exc}") from exc
        if isinstance(out, (str, bytes)):
            raise ShapeError(f"{self.name}: the {map_name} map returned the string {out!r}, "
                             f"not a tuple of coordinates")
        try:
            out = tuple(out)
        except TypeError as exc:
            raise ShapeError(f"{self.name}: the {map_name} map returned "
                             f"{type(out).__name__}, not a tuple of coordinates") from exc
        if len(out) != size:
            what = "base point" if size == self.base_dim else "arrow"
            raise ShapeError(f"{self.name}: the {map_name} map returned {len(out)} "
                             f"coordinates; a {what} has {size}")
        return coordinate_values(self.name, f"{map_name} map", out, sympified=False)

    def source(self, a):
        return self._call("source", self.base_dim, tuple(a))

    def target(self, a):
        return self._call("target", self.base_dim, tuple(a))

    def multiply(self, a, b):
        return self._call("multiply", self.arrow_dim, tuple(a), tuple(b))

    def identity(self, q):
        return self._call("identity", self.arrow_dim, tuple(q))

    def inverse(self, a):
        return self._call("inverse", self.arrow_dim, tuple(a))

    def section_curves(self, q, t):
        # exceptions are wrapped (with the groupoid's name) by Groupoid._curves
        return [tuple(h) for h in self._maps["sections"](tuple(q), t)]

    def map_expressions(self, a):
        """Every structure map at the arrow ``a``: source, target, inverse, the identity and
        the section curves at its source (in a curve parameter t), and its product with a
        composable arrow of placeholder fibre coordinates."""
        t = sp.Dummy("t")
        fibre = tuple(sp.Dummy(f"f{i}") for i in range(self.rank))
        q, after = self.source(a), self.target(a)
        exprs = [*q, *after, *self.inverse(a), *self.identity(q),
                 *self.multiply(a, self.arrow_from(after, fibre)),
                 *(c for curve in self.section_curves(q, t) for c in curve)]
        return exprs, [t, *fibre]

    def arrow_from(self, q, f):
        return tuple(q) + tuple(f)

    def fibre_of(self, a):
        return tuple(a[self.base_dim:])

    def named_fibre(self, offset):
        return tuple(scalar_symbol(latex_name(n), offset) for n in self.fibre_names)

    def named_source(self, offset):
        return tuple(scalar_symbol(latex_name(n), offset + self.source_offset)
                     for n in self.base_names)

    def symbols_by_name(self, offset):
        out = {n: scalar_symbol(latex_name(n), offset + self.source_offset)
               for n in self.base_names}
        out.update({n: scalar_symbol(latex_name(n), offset) for n in self.fibre_names})
        return out
