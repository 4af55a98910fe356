"""Time-extended groupoids G_R = R × R × G ⇉ R × Q (seed 000 §6.3).

α(t₀, t₁, g) = (t₀, α(g)), β = (t₁, β(g)), m((t₀,t₁,g),(t₁,t₂,h)) = (t₀, t₂, gh),
ε(t, q) = (t, t, ε(q)), i(t₀, t₁, g) = (t₁, t₀, g⁻¹).  Sections: ∂/∂t (curve (s, s+t, ε(q)))
and (0, X) for the sections X of G.  The arrow g_k is (t_{k-1}, t_k, g_k); a step solves for
t_{k+1} and the fibre chart of G.
"""

from __future__ import annotations

import numpy as np

from .._arguments import instance_argument, name_argument
from .._errors import CoordinateNameError
from .._symbols import StepSymbol, alias_words, latex_name, printable_name, subscripted
from ._base import Arrow, Groupoid


class TimeArrow(Arrow):
    """(t₀, t₁, g): ``.t0``, ``.t1``, ``.step`` = t₁ − t₀ and ``.arrow`` (the G part)."""

    @property
    def t0(self):
        return self.coords[0]

    @property
    def t1(self):
        return self.coords[1]

    @property
    def step(self):
        return self.coords[1] - self.coords[0]

    @property
    def arrow(self) -> Arrow:
        return self.groupoid.inner.view(self.coords[2:])

    def __getattr__(self, name):
        # delegate .source/.target/.matrix/... and indexing to the G part
        if name.startswith("_") or name in ("groupoid", "coords"):
            raise AttributeError(name)
        return getattr(self.arrow, name)

    def __getitem__(self, i):
        return self.arrow[i]


class TimeGroupoid(Groupoid):
    """R × R × G ⇉ R × Q for a groupoid G."""

    timed = True

    def __init__(self, inner: Groupoid, time_name: str = "t"):
        self.inner = instance_argument(inner, Groupoid, "the inner groupoid", "a Groupoid",
                                       owner="TimeGroupoid")
        time_name = printable_name(name_argument(time_name, "time_name", owner="TimeGroupoid"),
                                   "time_name", "TimeGroupoid")
        taken = {latex_name(n): n for o in (0, 1) for n in self.inner.symbols_by_name(o)}
        if latex_name(time_name) in taken:
            other = taken[latex_name(time_name)]
            raise CoordinateNameError(f"TimeGroupoid: the time and a part of {inner.name} are "
                                      f"named alike ({alias_words((other, time_name))}); name "
                                      f"the time otherwise (time_name=...)")
        self.time_name = time_name
        self.time_latex = latex_name(time_name)
        self.name = f"R×R×({inner.name})"

    @property
    def arrow_dim(self):
        return 2 + self.inner.arrow_dim

    @property
    def base_dim(self):
        return 1 + self.inner.base_dim

    @property
    def rank(self):
        return 1 + self.inner.rank

    @property
    def fibre_dim(self):
        return 1 + self.inner.fibre_dim

    def source(self, a):
        return (a[0],) + tuple(self.inner.source(a[2:]))

    def target(self, a):
        return (a[1],) + tuple(self.inner.target(a[2:]))

    def multiply(self, a, b):
        return (a[0], b[1]) + tuple(self.inner.multiply(a[2:], b[2:]))

    def identity(self, q):
        return (q[0], q[0]) + tuple(self.inner.identity(q[1:]))

    def inverse(self, a):
        return (a[1], a[0]) + tuple(self.inner.inverse(a[2:]))

    def arrow_between(self, c0, c1):
        """Configurations (t, c) with c a configuration of the inner groupoid."""
        (t0, i0), (t1, i1) = c0, c1
        return (float(t0), float(t1)) + tuple(self.inner.arrow_between(i0, i1))

    def configuration_after(self, c0, a):
        return (float(a[1]), self.inner.configuration_after(c0[1], a[2:]))

    def increments(self, a):
        return self.inner.increments(a[2:])

    def configurations_along(self, arrows, start=None):
        """(the times t_0, …, t_N the arrows hold, the inner configurations from
        ``start[1]``)."""
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        inner = None if start is None else start[1]
        times = np.concatenate([arrows[:1, 0], arrows[:, 1]])
        return times, self.inner.configurations_along(arrows[:, 2:], inner)

    def spatial_momenta(self, momenta, arrows, start=None):
        """The time component as it is, the inner groupoid's in its spatial frame."""
        arrows, momenta = np.asarray(arrows, float), np.asarray(momenta, float)
        inner = None if start is None else start[1]
        return np.hstack([momenta[:, :1], self.inner.spatial_momenta(momenta[:, 1:],
                                                                     arrows[:, 2:], inner)])

    def section_curves(self, q, t):
        unit = tuple(self.inner.identity(q[1:]))
        curves = [(q[0], q[0] + t) + unit]
        curves += [(q[0], q[0]) + tuple(h) for h in self.inner.section_curves(q[1:], t)]
        return curves

    def arrow_from(self, q, f):
        return (q[0], f[0]) + tuple(self.inner.arrow_from(q[1:], f[1:]))

    def fibre_of(self, a):
        return (a[1],) + tuple(self.inner.fibre_of(a[2:]))

    @staticmethod
    def _inner_source(source):
        return None if source is None else tuple(source[1:])

    def fibre_chart(self, x, source=None):
        return (x[0],) + tuple(self.inner.fibre_chart(x[1:], self._inner_source(source)))

    def fibre_chart_inverse(self, f, source=None):
        return (f[0],) + tuple(self.inner.fibre_chart_inverse(f[1:],
                                                              self._inner_source(source)))

    def chart_of_fibre(self, f, source=None):
        return (f[0],) + tuple(self.inner.chart_of_fibre(f[1:], self._inner_source(source)))

    def configuration(self, value, name, check):
        """``(t, c)``: a time and a configuration of the inner groupoid."""
        t, c = check.pieces(value, 2, name, f"a configuration (t, c) of {self.name}")
        return (check.time(t, f"{name}[0] (the time)"),
                self.inner.configuration(c, f"{name}[1]", check))

    def partial_configuration(self, value, name, check):
        """``(t, c)``: the time comes from the arrows, c as the inner groupoid's partial one."""
        if value is None:
            return None
        t, c = check.pieces(value, 2, name, f"a configuration (t, c) of {self.name}")
        return (None, self.inner.partial_configuration(c, f"{name}[1]", check))

    def geodesic(self, total, s):
        """The time along the straight segment t₀ + s(t₁ − t₀), the inner arrow along its
        geodesic."""
        t0, t1 = total[0], total[1]
        return np.column_stack([np.full(len(s), t0), t0 + s * (t1 - t0),
                                self.inner.geodesic(total[2:], s)])

    def named_groups(self):
        return self.inner.named_groups()

    def base_groups(self):
        return self.inner.base_groups()

    def predict_chart(self, a):
        return (2 * a[1] - a[0],) + tuple(self.inner.predict_chart(a[2:]))

    def matrix_parts(self):
        return [(2 + o, g) for o, g in self.inner.matrix_parts()]

    def renormalised_arrow(self, a):
        return tuple(a[:2]) + tuple(self.inner.renormalised_arrow(a[2:]))

    def offset_parts(self):
        return [(2 + o, g) for o, g in self.inner.offset_parts()]

    def _time(self, offset):
        return (StepSymbol(subscripted(self.time_latex, offset)),)

    def named_fibre(self, offset):
        return self._time(offset) + tuple(self.inner.named_fibre(offset))

    def named_source(self, offset):
        return self._time(offset - 1) + tuple(self.inner.named_source(offset))

    def named_chart(self, offset):
        return self._time(offset) + tuple(self.inner.named_chart(offset))

    def named_arrow(self, offset):
        return self._time(offset - 1) + self._time(offset) + tuple(
            self.inner.named_arrow(offset))

    def symbols_by_name(self, offset):
        return {self.time_name: self._time(offset)[0], **self.inner.symbols_by_name(offset)}

    def random_base_point(self, rng):
        return (float(rng.uniform(0, 1)),) + tuple(self.inner.random_base_point(rng))

    def random_chart(self, rng, scale=0.5):
        return (float(rng.uniform(0.1, 1.0)),) + tuple(self.inner.random_chart(rng, scale))

    def random_arrow(self, rng, source=None):
        q = self.random_base_point(rng) if source is None else tuple(source)
        inner = self.inner.random_arrow(rng, q[1:])
        return (q[0], q[0] + float(rng.uniform(0.1, 1.0))) + tuple(inner)

    def view(self, coords):
        return TimeArrow(self, coords)

    def base_view(self, coords):
        """(t, q): the time and the inner groupoid's base point."""
        return (coords[0], self.inner.base_view(tuple(coords[1:])))


