"""The numeric questions an evaluator asks a groupoid, with the defaults every groupoid
inherits (they need only the structure maps and the α-fibre chart); each family overrides
what it knows better (a Lie group its logarithm, a product each factor, ...).

- ``geodesic(total, s)``: arrows P(sᵢ) in the α-fibre of α(total) from P(0) = ε(α(total)) to
  P(1) = total (the initial guess of a boundary-value problem interpolates along it);
- ``configuration(value, name, check)`` / ``partial_configuration``: a configuration given
  by a user, checked part by part with the evaluator's checks (:class:`ConfigurationChecks`);
- ``configurations_from(start, arrows)``: c₀ = start, c_{k+1} = c_k·g_k;
- ``pair_coordinates()``: where the coordinates of a pair groupoid of a Euclidean space sit
  in an arrow (the printers name their midpoints and differences);
- ``timed``, ``is_lie_group``, ``named_vector_action()``: what kind of groupoid it is, where
  a derivation or a printer treats a kind differently.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NoReturn, Protocol

import numpy as np


@dataclass(frozen=True)
class PairCoordinate:
    """A coordinate of a pair groupoid of a Euclidean space inside an arrow: the positions of
    its source and target values among the arrow's coordinates, and its name."""

    source: int
    target: int
    name: str


class ConfigurationChecks(Protocol):
    """The checks a configuration's parts pass (an evaluator's, with its error messages):
    a groupoid says what its configuration is made of, the checks say whether a value is one.
    """

    def point(self, value, dim: int, name: str) -> tuple:
        """``value`` as a point of ℝⁿ (n = ``dim``)."""

    def group_element(self, group, value, name: str) -> np.ndarray:
        """``value`` as the matrix of an element of the matrix Lie group ``group``."""

    def time(self, value, name: str) -> float:
        """``value`` as a time (a real number)."""

    def pieces(self, value, count: int, name: str, what: str) -> tuple:
        """``value`` as ``count`` parts (``what`` names the expected configuration)."""

    def no_configuration_space(self, groupoid, name: str) -> NoReturn:
        """Raise: ``groupoid`` has no configuration space, so ``name`` cannot be one."""


class GroupoidNumerics:
    """Defaults of the numeric methods of :class:`~symgroupoid.groupoids.Groupoid` (see the
    module docstring); the structure maps they use are the groupoid's own."""

    #: True on a time groupoid ℝ × ℝ × G: the step is each arrow's t₁ − t₀ (its first
    #: section is ∂/∂t), not a parameter (docs/conventions.md §7).
    timed: bool = False
    #: True on a matrix Lie group G ⇉ {e} (seed 000 §6.1: the Lie–Poisson form).
    is_lie_group: bool = False

    @property
    def generic_arrow(self) -> tuple:
        """Real symbols a₀, …, a_{n−1} standing for a generic arrow's coordinates (the
        invariant vector fields are derived at them)."""
        return self._generic_arrow

    def pair_coordinates(self) -> list[PairCoordinate]:
        """The coordinates of a pair groupoid of a Euclidean space in this groupoid's arrows
        (through products): none by default."""
        return []

    def named_vector_action(self) -> tuple[str, Any] | None:
        """(the vector's name, the acting matrix group H) on an action groupoid V × H ⇉ V of a
        named vector space V; None on other groupoids."""
        return None

    # --- paths ------------------------------------------------------------------------------
    def chart_path(self, total: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Arrows from ε(α(total)) to ``total`` interpolated linearly in the α-fibre chart:
        P(s) = arrow_from(q, τ_q(x_ε + s·(x_total − x_ε))), q = α(total)."""
        q = tuple(self.source(total))
        x_id = np.asarray(self.fibre_chart_inverse(self.fibre_of(self.identity(q)), q), float)
        x_end = np.asarray(self.fibre_chart_inverse(self.fibre_of(tuple(total)), q), float)
        return np.array([[float(v) for v in self.arrow_from(q, self.numeric_fibre_chart(
            x_id + (x_end - x_id) * t, q))] for t in s])

    def geodesic(self, total: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Arrows P(sᵢ) ∈ α⁻¹(α(total)), one row per entry of ``s`` ∈ [0, 1], from
        P(0) = ε(α(total)) to P(1) = ``total`` along a geodesic of each factor: exp(s·log g)
        on a matrix Lie group, a straight segment on a pair groupoid of ℝⁿ and in time, the
        group part of an action groupoid; by default a straight line in the fibre chart
        (:meth:`chart_path`)."""
        return self.chart_path(total, s)

    # --- configurations -----------------------------------------------------------------------
    def configurations_from(self, start, arrows: np.ndarray) -> list:
        """[c₀, …, c_N] with c₀ = ``start`` and c_{k+1} = c_k·g_k
        (:meth:`configuration_after`) for the rows g_k of ``arrows``."""
        out = [start]
        for g in arrows:
            out.append(self.configuration_after(out[-1], g))
        return out

    def configuration(self, value, name: str, check: ConfigurationChecks):
        """``value`` as a configuration of this groupoid, each part passed through ``check``
        (the library's groupoids: a point, a group element, a tuple of parts; see each).  By
        default ``value`` itself, given to :meth:`arrow_between`; a groupoid without
        :meth:`arrow_between` has no configuration space (``check.no_configuration_space``).
        """
        from ._base import Groupoid

        if type(self).arrow_between is Groupoid.arrow_between:
            check.no_configuration_space(self, name)
        return value

    def partial_configuration(self, value, name: str, check: ConfigurationChecks):
        """A first configuration for :meth:`configurations_along`, checked as
        :meth:`configuration` checks one, where None stands for a part the arrows determine:
        by default None or a whole configuration."""
        if value is None:
            return None
        return self.configuration(value, name, check)

