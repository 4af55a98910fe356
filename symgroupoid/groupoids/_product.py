"""Products G₁ × G₂ ⇉ Q₁ × Q₂ (componentwise structure maps; e.g. the plate-ball's
R² × R² × SO(3) ⇉ R², seed 000 §6.2).  ``G1 * G2`` builds one; arrows are indexed by factor."""

from __future__ import annotations

from itertools import accumulate

import numpy as np

from .._arguments import instance_argument
from .._errors import CoordinateNameError, ShapeError
from .._symbols import alias_words, latex_name
from ._base import Arrow, Groupoid
from ._numerics import PairCoordinate


class ProductArrow(Arrow):
    """An arrow of a product groupoid; ``g[i]`` is the arrow of factor i."""

    def __getitem__(self, i: int) -> Arrow:
        G = self.groupoid
        lo, hi = G._arrow_slices[i]
        return G.factors[i].view(self.coords[lo:hi])

    def __len__(self) -> int:
        return len(self.groupoid.factors)

    def __iter__(self):
        return (self[i] for i in range(len(self)))


def _refuse_shared_names(name: str, parts: list[tuple[str, dict]]) -> None:
    """A :class:`CoordinateNameError` when two factors of a product name a part alike
    (``SO3("R") * SO3("R")``, also within nested products, which are flattened first): the
    state, the initial data and the Lagrangian address parts by name, so a shared name
    would make two parts one symbol and the Lagrangian degenerate."""
    owner: dict[str, tuple[int, str]] = {}
    for i, (factor, names) in enumerate(parts):
        for part in names:
            key = latex_name(part)  # θ and theta are one symbol, \theta
            if key in owner:
                j, other = owner[key]
                raise CoordinateNameError(
                    f"{name}: factor {j} ({parts[j][0]}) and factor {i} ({factor}) name a part "
                    f"alike ({alias_words((other, part))}); the parts of a product need "
                    f"distinct names (e.g. SO3(\"R1\") * SO3(\"R2\"))")
        owner.update({latex_name(part): (i, part) for part in names})


def _slices(sizes):
    ends = list(accumulate(sizes))
    return [(e - s, e) for s, e in zip(sizes, ends)]


class ProductGroupoid(Groupoid):
    """G₁ × ⋯ × G_n with componentwise α, β, m, ε, i and the union of the factors' sections."""

    def __init__(self, *factors: Groupoid):
        if not factors:
            raise ShapeError("ProductGroupoid needs at least one factor")
        for i, f in enumerate(factors):
            instance_argument(f, Groupoid, f"factor {i}", "a Groupoid",
                              owner="ProductGroupoid")
        flat: list[Groupoid] = []
        for f in factors:
            flat.extend(f.factors if isinstance(f, ProductGroupoid) else [f])
        self.factors = tuple(flat)
        self.name = " × ".join(f.name for f in self.factors)
        _refuse_shared_names(self.name, [(f.name, f.symbols_by_name(0)) for f in self.factors])
        self._arrow_slices = _slices([f.arrow_dim for f in self.factors])
        self._base_slices = _slices([f.base_dim for f in self.factors])
        self._fibre_slices = _slices([f.fibre_dim for f in self.factors])
        self._chart_slices = _slices([f.rank for f in self.factors])

    @property
    def arrow_dim(self):
        return sum(f.arrow_dim for f in self.factors)

    @property
    def base_dim(self):
        return sum(f.base_dim for f in self.factors)

    @property
    def rank(self):
        return sum(f.rank for f in self.factors)

    @property
    def fibre_dim(self):
        return sum(f.fibre_dim for f in self.factors)

    def _parts(self, v, slices):
        return [tuple(v[lo:hi]) for lo, hi in slices]

    def _map(self, name, *args_slices):
        parts = [self._parts(v, s) for v, s in args_slices]
        out: tuple = ()
        for i, f in enumerate(self.factors):
            out += tuple(getattr(f, name)(*(p[i] for p in parts)))
        return out

    def map_expressions(self, a):
        exprs: list = []
        placeholders: list = []
        for f, part in zip(self.factors, self._parts(a, self._arrow_slices)):
            e, p = f.map_expressions(part)
            exprs += e
            placeholders += p
        return exprs, placeholders

    def source(self, a):
        return self._map("source", (a, self._arrow_slices))

    def target(self, a):
        return self._map("target", (a, self._arrow_slices))

    def multiply(self, a, b):
        return self._map("multiply", (a, self._arrow_slices), (b, self._arrow_slices))

    def identity(self, q):
        return self._map("identity", (q, self._base_slices))

    def inverse(self, a):
        return self._map("inverse", (a, self._arrow_slices))

    def arrow_from(self, q, f):
        return self._map("arrow_from", (q, self._base_slices), (f, self._fibre_slices))

    def fibre_of(self, a):
        return self._map("fibre_of", (a, self._arrow_slices))

    def _with_source(self, name, v, slices, source):
        parts = self._parts(v, slices)
        qs = (self._parts(source, self._base_slices) if source is not None
              else [None] * len(self.factors))
        return sum((tuple(getattr(f, name)(p, q)) for f, p, q in zip(self.factors, parts, qs)),
                   ())

    def fibre_chart(self, x, source=None):
        return self._with_source("fibre_chart", x, self._chart_slices, source)

    def fibre_chart_inverse(self, f, source=None):
        return self._with_source("fibre_chart_inverse", f, self._fibre_slices, source)

    def chart_of_fibre(self, f, source=None):
        return self._with_source("chart_of_fibre", f, self._fibre_slices, source)

    def predict_chart(self, a):
        return self._map("predict_chart", (a, self._arrow_slices))

    def renormalised_fibre(self, f):
        return self._map("renormalised_fibre", (f, self._fibre_slices))

    def renormalised_arrow(self, a):
        return self._map("renormalised_arrow", (a, self._arrow_slices))

    def configuration(self, value, name, check):
        """One configuration per factor, named ``name[i]``."""
        parts = check.pieces(value, len(self.factors), name,
                             f"a configuration of {self.name}, one per factor")
        return tuple(f.configuration(c, f"{name}[{i}]", check)
                     for i, (f, c) in enumerate(zip(self.factors, parts)))

    def partial_configuration(self, value, name, check):
        """One partial configuration per factor (None for a part the arrows determine)."""
        if value is None:
            return None
        parts = check.pieces(value, len(self.factors), name,
                             f"a configuration of {self.name}, one per factor (None for a "
                             f"part the state determines)")
        return tuple(f.partial_configuration(c, f"{name}[{i}]", check)
                     for i, (f, c) in enumerate(zip(self.factors, parts)))

    def geodesic(self, total, s):
        """Each factor along its own geodesic."""
        return np.hstack([f.geodesic(total[lo:hi], s)
                          for f, (lo, hi) in zip(self.factors, self._arrow_slices)])

    def pair_coordinates(self):
        """The factors' pair coordinates, shifted to the factors' places in the arrow."""
        out = []
        for factor, (start, _) in zip(self.factors, self._arrow_slices):
            out += [PairCoordinate(start + c.source, start + c.target, c.name)
                    for c in factor.pair_coordinates()]
        return out

    def named_groups(self):
        out: dict = {}
        for f in self.factors:
            out.update(f.named_groups())
        return out

    def base_groups(self):
        out: dict = {}
        for f in self.factors:
            out.update(f.base_groups())
        return out

    def arrow_between(self, c0, c1):
        """Configurations are tuples with one configuration per factor."""
        return sum((tuple(f.arrow_between(a, b)) for f, a, b in zip(self.factors, c0, c1)), ())

    def configurations_along(self, arrows, start=None):
        """One entry per factor (``start``: None, or one entry per factor, None where the
        factor's arrows determine it)."""
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        starts = [None] * len(self.factors) if start is None else list(start)
        return tuple(f.configurations_along(arrows[:, lo:hi], s)
                     for f, (lo, hi), s in zip(self.factors, self._arrow_slices, starts))

    def spatial_momenta(self, momenta, arrows, start=None):
        arrows, momenta = np.asarray(arrows, float), np.asarray(momenta, float)
        starts = [None] * len(self.factors) if start is None else list(start)
        return np.hstack([f.spatial_momenta(momenta[:, a:b], arrows[:, lo:hi], s)
                          for f, (lo, hi), (a, b), s in zip(self.factors, self._arrow_slices,
                                                            self._chart_slices, starts)])

    def increments(self, a):
        parts = self._parts(a, self._arrow_slices)
        return [i for f, p in zip(self.factors, parts) for i in f.increments(p)]

    def configuration_after(self, c0, a):
        parts = self._parts(a, self._arrow_slices)
        return tuple(f.configuration_after(c, p) for f, c, p in zip(self.factors, c0, parts))

    def section_curves(self, q, t):
        qs = self._parts(q, self._base_slices)
        units = [f.identity(qi) for f, qi in zip(self.factors, qs)]
        curves = []
        for i, f in enumerate(self.factors):
            for h in f.section_curves(qs[i], t):
                curves.append(sum((h if j == i else units[j]
                                   for j in range(len(self.factors))), ()))
        return curves

    def field_nodes(self, g, side, coords, parameters=None):
        """Each factor's fields at its part of the arrow, zero on the other factors: the
        product's section h_b(t) moves one factor and holds the others at ε, so
        m(a, h_b(t)) and m(h_b(t)⁻¹, a) move only that factor's part."""
        parts = self._parts(list(coords), self._arrow_slices)
        out = []
        for i, f in enumerate(self.factors):
            for v in f.field_nodes(g, side, parts[i], parameters):
                out.append([c for j, part in enumerate(parts)
                            for c in (v if j == i else [g.zero] * len(part))])
        return out

    def matrix_parts(self):
        return [(lo + o, g) for f, (lo, _) in zip(self.factors, self._arrow_slices)
                for o, g in f.matrix_parts()]

    def offset_parts(self):
        return [(lo + o, g) for f, (lo, _) in zip(self.factors, self._arrow_slices)
                for o, g in f.offset_parts()]

    def _named(self, name, offset):
        return sum((tuple(getattr(f, name)(offset)) for f in self.factors), ())

    def named_fibre(self, offset):
        return self._named("named_fibre", offset)

    def named_source(self, offset):
        return self._named("named_source", offset)

    def named_chart(self, offset):
        return self._named("named_chart", offset)

    def named_arrow(self, offset):
        return self._named("named_arrow", offset)

    def symbols_by_name(self, offset):
        out: dict = {}
        for f in self.factors:
            out.update(f.symbols_by_name(offset))
        return out

    def random_base_point(self, rng):
        return sum((tuple(f.random_base_point(rng)) for f in self.factors), ())

    def view(self, coords):
        return ProductArrow(self, coords)

    def base_view(self, coords):
        """One base point per factor: ``q[i]`` is the base point of factor i."""
        return tuple(f.base_view(p) for f, p in zip(self.factors,
                                                      self._parts(coords, self._base_slices)))

    def __repr__(self):
        return " * ".join(repr(f) for f in self.factors)
