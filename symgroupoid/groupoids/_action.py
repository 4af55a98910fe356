"""Action (transformation) groupoids P × H ⇉ P for a right action of a Lie group H on P.

Structure maps (seed 001 §2.1.1): α(p, W) = p, β(p, W) = p·W, (p, W)(p·W, W') = (p, WW'),
ε(p) = (p, I), (p, W)⁻¹ = (p·W, W⁻¹).  Sections: (p, τ(t E_a)).  The heavy top lives on
S² × SO(3) with Γ·W = WᵀΓ (seed 002, docs/conventions.md §9); the arrow g_k is (Γ_k, W_k).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .._errors import CallableError, ShapeError
from ._base import Arrow, Groupoid
from ._matrix_groups import MatrixLieGroup
from ._pair import EuclideanSpace


class ActionArrow(Arrow):
    """An arrow (p, W) of an action groupoid: ``.point`` = p, ``.matrix`` = W."""

    @property
    def point(self) -> tuple:
        return self.coords[: self.groupoid.base_dim]

    source = point

    @property
    def target(self) -> tuple:
        return self.groupoid.target(self.coords)

    @property
    def group(self):
        return self.groupoid.group.view(self.coords[self.groupoid.base_dim:])

    @property
    def matrix(self) -> sp.Matrix:
        return self.group.matrix

    @property
    def coordinates(self) -> sp.Matrix:
        return self.group.coordinates


class ActionGroupoid(Groupoid):
    """P × H ⇉ P for a right action ``action(p, W) -> p·W`` (p a tuple, W a SymPy Matrix)."""

    def __init__(self, space: EuclideanSpace, group: MatrixLieGroup,
                 action: Callable[[tuple, sp.Matrix], Sequence]):
        self.space, self.group, self.action = space, group, action
        self.name = f"({', '.join(space.names)}) ⋊ {group.name}"

    @property
    def arrow_dim(self):
        return self.space.dim + self.group.arrow_dim

    @property
    def base_dim(self):
        return self.space.dim

    @property
    def rank(self):
        return self.group.rank

    def _split(self, a):
        n = self.base_dim
        return tuple(a[:n]), tuple(a[n:])

    def _act(self, p, w) -> tuple:
        try:
            out = self.action(tuple(p), self.group.matrix(w))
        except Exception as exc:  # noqa: BLE001
            raise CallableError(f"{self.name}: the action raised {exc!r}") from exc
        out = tuple(out)
        if len(out) != self.base_dim:
            raise ShapeError(f"{self.name}: the action returned {len(out)} coordinates, "
                             f"the space has {self.base_dim}")
        return out

    def source(self, a):
        return self._split(a)[0]

    def target(self, a):
        p, w = self._split(a)
        return self._act(p, w)

    def multiply(self, a, b):
        p, w = self._split(a)
        return p + self.group.multiply(w, self._split(b)[1])

    def identity(self, q):
        return tuple(q) + self.group.identity(())

    def inverse(self, a):
        p, w = self._split(a)
        return self._act(p, w) + self.group.inverse(w)

    def section_curves(self, q, t):
        return [tuple(q) + h for h in self.group.section_curves((), t)]

    def arrow_from(self, q, f):
        return tuple(q) + tuple(f)

    def fibre_of(self, a):
        return self._split(a)[1]

    def fibre_chart(self, x, source=None):
        return self.group.fibre_chart(x)

    def fibre_chart_inverse(self, f, source=None):
        return self.group.fibre_chart_inverse(f)

    def chart_of_fibre(self, f, source=None):
        return self.group.chart_of_fibre(f)

    def named_groups(self):
        return self.group.named_groups()

    def matrix_parts(self):
        return [(self.base_dim + o, g) for o, g in self.group.matrix_parts()]

    def arrow_between(self, c0, c1):
        """Configurations (p, R): the arrow (p₀, R₀⁻¹R₁); p₁ must equal p₀·(R₀⁻¹R₁)."""
        from .._errors import NotComposableError

        (p0, R0), (p1, R1) = c0, c1
        w = self.group.arrow_between(R0, R1)
        reached = [float(v) for v in self._act(tuple(float(x) for x in p0), w)]
        if not np.allclose(reached, np.asarray(p1, float), atol=1e-9):
            raise NotComposableError(
                f"{self.name}: boundary configurations not connected by an arrow: "
                f"p₀·(R₀⁻¹R₁) = {np.round(reached, 9).tolist()} ≠ p₁ = {list(p1)}")
        return tuple(float(x) for x in p0) + tuple(w)

    def configuration_after(self, c0, a):
        p0, R0 = c0
        return (tuple(float(v) for v in self.target(a)),
                self.group.configuration_after(R0, a[self.base_dim:]))

    def named_fibre(self, offset):
        return self.group.named_fibre(offset)

    def named_source(self, offset):
        return self.space.point(offset)

    def named_chart(self, offset):
        return self.group.named_chart(offset)

    def symbols_by_name(self, offset):
        return {**self.space.symbols_by_name(offset), **self.group.symbols_by_name(offset)}

    def random_base_point(self, rng):
        p = rng.normal(size=self.base_dim)
        return tuple(p / max(float((p ** 2).sum()) ** 0.5, 1e-12))

    def view(self, coords):
        return ActionArrow(self, coords)
