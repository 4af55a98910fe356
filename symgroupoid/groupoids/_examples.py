"""Every kind of groupoid the library builds, one example each: the registry the property
tests run over ("every property × every groupoid")."""

from __future__ import annotations

from collections.abc import Callable

import sympy as sp

from ._action import ActionGroupoid
from ._atiyah import AtiyahGroupoid
from ._base import Groupoid
from ._pair import EuclideanSpace, PairGroupoid
from ._se2 import SE2
from ._se3 import SE3
from ._so2 import SO2
from ._so3 import SO3
from ._time import TimeGroupoid
from ._trivialised import TrivialisedPairGroupoid
from ._user import DefinedGroupoid

RETRACTIONS = ("cayley", "exp")
GROUPS = (SO2, SO3, SE2, SE3)


def defined_line() -> DefinedGroupoid:
    """The pair groupoid of ℝ written by its structure maps (seed 001 §2.1.1)."""
    return DefinedGroupoid(
        "line", base_names=["q"], fibre_names=["q"],
        source=lambda a: (a[0],), target=lambda a: (a[1],),
        multiply=lambda a, b: (a[0], b[1]), identity=lambda q: (q[0], q[0]),
        inverse=lambda a: (a[1], a[0]), sections=lambda q, t: [(q[0], q[0] + t)])


def defined_translations() -> DefinedGroupoid:
    """ℝ² ⇉ ℝ, the action groupoid of (ℝ, +) acting on ℝ by translation, by its structure
    maps: arrows (p, s), α = p, β = p + s, (p, s)(p + s, s′) = (p, s + s′)."""
    return DefinedGroupoid(
        "translations", base_names=["p"], fibre_names=["s"],
        source=lambda a: (a[0],), target=lambda a: (a[0] + a[1],),
        multiply=lambda a, b: (a[0], a[1] + b[1]), identity=lambda q: (q[0], 0),
        inverse=lambda a: (a[0] + a[1], -a[1]), sections=lambda q, t: [(q[0], t)],
        source_offset=0)


def heavy_top() -> ActionGroupoid:
    """S² × SO(3) ⇉ S² with Γ·W = WᵀΓ (seed 002)."""
    return ActionGroupoid(EuclideanSpace.vector("Gamma", 3), SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))


def _groups() -> dict[str, Callable[[], Groupoid]]:
    return {f"{cls.__name__} {ret}": (lambda cls=cls, ret=ret: cls("g", retraction=ret))
            for cls in GROUPS for ret in RETRACTIONS}


def _increments() -> dict[str, Callable[[], Groupoid]]:
    return {f"increments {cls.__name__} {ret}":
            (lambda cls=cls, ret=ret: TrivialisedPairGroupoid(cls("R", retraction=ret)))
            for cls in GROUPS for ret in RETRACTIONS}


def _atiyah() -> dict[str, Callable[[], Groupoid]]:
    def twist(s0, s1):
        return (3 * (s1[0] - s0[0]) / 10 + (s1[1] ** 2 - s0[1] ** 2) / 10,
                (s1[1] - s0[1]) / 5, 0)

    return {
        "atiyah (R2 x SO3)2/SO3 left": lambda: AtiyahGroupoid(
            (EuclideanSpace("x y"), SO3("W")), SO3),
        "atiyah (R2 x SO3)2/SO3 right twisted": lambda: AtiyahGroupoid(
            (EuclideanSpace("x y"), SO3("W")), SO3, action="right", connection=twist),
        "atiyah SO3 x SO3 / SO3": lambda: AtiyahGroupoid(SO3("W"), SO3),
        "atiyah (SE2 x R)2/SE2 beanie": lambda: AtiyahGroupoid(
            (SE2("g"), EuclideanSpace("psi")), SE2,
            connection=lambda s0, s1: ((s1[0] - s0[0]) / 2, 0, 0)),
    }


def examples() -> dict[str, Callable[[], Groupoid]]:
    """One constructor of each kind of groupoid, by a descriptive name.

    Pair groupoids of Euclidean spaces, of a Lie group and of a product of Lie groups; the
    matrix Lie groups SO(2), SO(3), SE(2), SE(3) with each retraction; their pair groupoids in
    increment coordinates; action groupoids; products; time groupoids; Atiyah groupoids
    (left, right, with a connection); groupoids defined by their structure maps.  Each call
    of a constructor builds a fresh groupoid.
    """
    return {
        "pair R": lambda: PairGroupoid(EuclideanSpace("q")),
        "pair R3": lambda: PairGroupoid(EuclideanSpace("x y z")),
        "pair SO3": lambda: PairGroupoid(SO3("R")),
        "pair SE2 x SO2": lambda: PairGroupoid(SE2("g", retraction="exp") * SO2("r")),
        **_groups(),
        **_increments(),
        "action S2 x SO3 (heavy top)": heavy_top,
        "action R2 x SO2": lambda: ActionGroupoid(EuclideanSpace("u v"), SO2("R"),
                                                  lambda p, R: tuple(R.T * sp.Matrix(p))),
        "product pair R2 x SO3 (plate-ball)":
            lambda: PairGroupoid(EuclideanSpace("x y")) * SO3("g"),
        "product SE2 x SO2 x pair R": lambda: SE2("s") * SO2("r") * PairGroupoid(
            EuclideanSpace("q")),
        "time R x R x SO3": lambda: TimeGroupoid(SO3("g")),
        "time R x R x pair R2": lambda: TimeGroupoid(PairGroupoid(EuclideanSpace("x y"))),
        **_atiyah(),
        "defined line": defined_line,
        "defined translations": defined_translations,
    }
