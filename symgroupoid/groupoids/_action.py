"""Action (transformation) groupoids P × H ⇉ P for a right action of a Lie group H on P.

Structure maps (seed 001 §2.1.1): α(p, W) = p, β(p, W) = p·W, (p, W)(p·W, W') = (p, WW'),
ε(p) = (p, I), (p, W)⁻¹ = (p·W, W⁻¹).  Sections: (p, τ(t E_a)).  The heavy top lives on
S² × SO(3) with Γ·W = WᵀΓ (seed 002, docs/conventions.md §9); the arrow g_k is (Γ_k, W_k).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp

from .._arguments import callable_argument, flag_argument, instance_argument
from .._errors import AxiomError, CallableError, ShapeError, SymgroupoidError
from ._base import Arrow, Groupoid, coordinate_values
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
    """P × H ⇉ P for a right action ``action(p, W) -> p·W`` (p a tuple, W a SymPy Matrix).

    The action axioms p·I = p and (p·W₁)·W₂ = p·(W₁W₂) are checked numerically when the
    groupoid is constructed (``check=False`` skips this).
    """

    def __init__(self, space: EuclideanSpace, group: MatrixLieGroup,
                 action: Callable[[tuple, sp.Matrix], Sequence], check: bool = True):
        owner = "ActionGroupoid"
        instance_argument(space, EuclideanSpace, "space", "an EuclideanSpace", owner=owner)
        instance_argument(group, MatrixLieGroup, "group", "a matrix Lie group (SO3('W'), …)",
                          owner=owner)
        self.space, self.group = space, group
        self.name = f"({', '.join(space.names)}) ⋊ {group.name}"
        self.action = callable_argument(action, "the action", owner=self.name)
        if flag_argument(check, "check", owner=owner):
            self._check_action()

    def _check_action(self, seed: int = 0, tol: float = 1e-9) -> None:
        """The action axioms at random points (seed 001 §2.1.1): p·I = p and
        (p·W₁)·W₂ = p·(W₁W₂); free symbols of the action get random values in (0.5, 2).
        An :class:`AxiomError` names the failing identity and the point (a left action
        W·p passed as a right action fails the second one); ``check=False`` skips this."""
        rng = np.random.default_rng(seed)
        p = tuple(sp.Float(v) for v in rng.normal(size=self.base_dim))
        w1, w2 = (self.group.random_arrow(rng) for _ in range(2))
        values: dict = {}

        def act(point, w) -> np.ndarray:
            out = []
            for c in self._act(point, w):
                e = sp.sympify(c)
                for sym in sorted(e.free_symbols - set(values), key=str):
                    values[sym] = sp.Float(rng.uniform(0.5, 2.0))
                e = sp.N(e.xreplace(values))
                if not (e.is_number and e.is_extended_real):
                    raise ShapeError(f"{self.name}: the action returned {c}, not a real "
                                     f"number, at p = {[float(v) for v in point]}")
                out.append(float(e))
            return np.array(out)

        def chosen() -> str:
            """The random values the action's free symbols got, for the message."""
            if not values:
                return ""
            named = ", ".join(f"{k}={float(v):.6g}" for k, v in values.items())
            return (f" with {named} (its symbols other than the point's coordinates chosen "
                    f"at random)")

        identity = act(p, self.group.identity(()))
        if not np.allclose(identity, np.asarray(p, float), atol=tol, rtol=tol):
            raise AxiomError(f"{self.name}: the action is not a right action: p·I ≠ p for "
                             f"p = {[float(v) for v in p]} (got {identity.tolist()}"
                             f"{chosen()}); check=False skips this check")
        stepwise = act(tuple(sp.Float(v) for v in act(p, w1)), w2)
        at_once = act(p, self.group.multiply(w1, w2))
        if not np.allclose(stepwise, at_once, atol=tol, rtol=tol):
            raise AxiomError(f"{self.name}: the action is not a right action: (p·W₁)·W₂ ≠ "
                             f"p·(W₁W₂) for p = {[float(v) for v in p]} ({stepwise.tolist()} "
                             f"≠ {at_once.tolist()}{chosen()}; a left action W·p gives W₂W₁p); "
                             f"check=False skips this check")

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
        except SymgroupoidError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise CallableError(f"{self.name}: the action raised {exc!r}") from exc
        if isinstance(out, (str, bytes)):
            raise ShapeError(f"{self.name}: the action returned the string {out!r}, not a "
                             f"tuple of coordinates")
        try:
            out = tuple(out)
        except TypeError as exc:
            raise ShapeError(f"{self.name}: the action returned {type(out).__name__} "
                             f"{out!r}, not a tuple of coordinates") from exc
        if len(out) != self.base_dim:
            raise ShapeError(f"{self.name}: the action returned {len(out)} coordinates, "
                             f"the space has {self.base_dim}")
        return coordinate_values(self.name, "action", out, sympified=False)

    def map_expressions(self, a):
        """The action at the arrow ``a``: its target p·W."""
        return list(self.target(a)), []

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

    def configuration(self, value, name, check):
        """``(p, R)``: a point of the space and an element of the group."""
        p, R = check.pieces(value, 2, name, f"a configuration (p, R) of {self.name}")
        return (check.point(p, self.base_dim, f"{name}[0]"),
                check.group_element(self.group, R, f"{name}[1]"))

    def partial_configuration(self, value, name, check):
        """``(p, R)``, either part None (determined by the arrows, or the identity)."""
        if value is None:
            return None
        p, R = check.pieces(value, 2, name, f"a configuration (p, R) of {self.name}")
        return (None if p is None else check.point(p, self.base_dim, f"{name}[0]"),
                None if R is None else check.group_element(self.group, R, f"{name}[1]"))

    def geodesic(self, total, s):
        """The point fixed at α(total), the group part along the group's geodesic."""
        n = self.base_dim
        return np.hstack([np.tile(total[:n], (len(s), 1)), self.group.geodesic(total[n:], s)])

    def named_vector_action(self):
        """(the vector's name, H) when the space is a named vector (``EuclideanSpace.vector``)."""
        if self.space.vector_name is None:
            return None
        return self.space.vector_name, self.group

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

    def increments(self, a):
        return self.group.increments(a[self.base_dim:])

    def configurations_along(self, arrows, start=None):
        """(the points p_k the arrows hold, stacked (N + 1, d); the group elements R_k from
        R_0 = ``start[1]`` or the identity along the group parts); ``start[0]``, if given,
        must be p_0."""
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        d = self.base_dim
        p0, R0 = (None, None) if start is None else start
        last = [float(v) for v in self.target(tuple(arrows[-1]))]
        points = np.vstack([arrows[:, :d], np.reshape(last, (1, d))])  # β(g_k) = α(g_{k+1})
        if p0 is not None and not np.allclose(np.asarray(p0, float), points[0], rtol=1e-12,
                                              atol=1e-12):
            from .._errors import DomainError

            raise DomainError(f"{self.name}: start[0] is not the point p_0 the first arrow "
                              f"holds (leave it None)")
        return points, self.group.configurations_along(arrows[:, d:], R0)

    def spatial_momenta(self, momenta, arrows, start=None):
        """The sections move the group part on the right: its momenta Ad*_{R⁻¹}μ."""
        arrows = np.asarray(arrows, float).reshape(-1, self.arrow_dim)
        R = self.configurations_along(arrows, start)[1][:-1]
        return self.group.body_to_spatial(momenta, R)

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
