"""Reduced systems: a discrete system on G′ obtained from one on G by a morphism Φ: G → G′
(seed 000 Def. 4.2, Thm 4.5, Cor. 4.6, Remark 4.7; docs/conventions.md §13)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._arguments import instance_argument
from .._errors import DomainError, ShapeError, UnsupportedFeatureError
from ..derivation import reduce_functions
from ..groupoids import GroupoidMorphism, check_morphism
from ._system import DiscreteSystem


@dataclass
class MomentumRelation:
    """Theorem 4.5 (ii)–(iii) at one arrow g with multipliers λ: F⁻L(g) = A*Φ_{α(g)}
    F⁻L′(Φ(g)) and F⁺L(g) = A*Φ_{β(g)} F⁺L′(Φ(g)).  ``defect``: the largest difference
    relative to the momenta's size."""

    minus: np.ndarray
    plus: np.ndarray
    minus_from_reduced: np.ndarray
    plus_from_reduced: np.ndarray

    @property
    def defect(self) -> float:
        scale = 1.0 + max(np.abs(self.minus).max(initial=0.0), np.abs(self.plus).max(initial=0.0))
        return max(np.abs(self.minus - self.minus_from_reduced).max(initial=0.0),
                   np.abs(self.plus - self.plus_from_reduced).max(initial=0.0)) / scale


class ReducedSystem(DiscreteSystem):
    """(G′, N′, L′) obtained by reducing (G, N, L) along Φ: G → G′ (see
    :meth:`DiscreteSystem.reduce`).

    ``unreduced`` is (G, N, L); ``morphism`` is Φ; ``checks`` records how L = L′∘Φ and
    φ = φ′∘Φ were verified.  :meth:`project` maps unreduced states to reduced ones (a
    solution to a solution, Cor. 4.6), :meth:`reconstruct` lifts a reduced trajectory from one
    unreduced arrow (Remark 4.7), :meth:`related_momenta` evaluates Theorem 4.5.
    """

    def __init__(self, unreduced: DiscreteSystem, morphism: GroupoidMorphism,
                 lagrangian: Callable, constraints: Callable | None,
                 parameters: Sequence[sp.Symbol], name: str, checks: list):
        step = getattr(unreduced, "time_step", None)
        kept = step is not None and str(step) in {str(p) for p in parameters}
        super().__init__(morphism.target, lagrangian, constraints, parameters, name,
                         time_step=step if kept else None)
        self.unreduced, self.morphism, self.checks = unreduced, morphism, checks
        self._transforms: tuple | None = None

    # --- parameters and states --------------------------------------------------------------
    def parameter_values(self, params: Mapping | Sequence) -> dict:
        """{name: value} from a mapping (by name or symbol) or a sequence in
        ``self.parameters`` order; every parameter must be given."""
        names = [str(s) for s in self.parameters]
        if isinstance(params, Mapping):
            given = {str(k): float(v) for k, v in params.items()}
            missing = [n for n in names if n not in given]
            if missing:
                raise KeyError(f"{self.name}: missing parameter(s) {', '.join(missing)}")
            return {n: given[n] for n in names}
        values = [float(v) for v in params]
        if len(values) != len(names):
            raise ShapeError(f"{self.name}: {len(values)} parameter values given, expected "
                             f"{len(names)} ({', '.join(names)})")
        return dict(zip(names, values))

    def _split_states(self, states, groupoid, what: str) -> tuple[np.ndarray, np.ndarray]:
        arr = np.atleast_2d(np.asarray(getattr(states, "states", states), float))
        n = groupoid.arrow_dim + self.n_constraints
        if arr.shape[1] != n:
            raise ShapeError(f"{self.name}: {what} states have {n} entries (an arrow of "
                             f"{groupoid.name} and {self.n_constraints} multipliers); got "
                             f"shape {arr.shape}")
        return arr[:, :groupoid.arrow_dim], arr[:, groupoid.arrow_dim:]

    def project(self, states, params: Mapping | Sequence) -> np.ndarray:
        """Reduced states (Φ(g_k), λ_k) of unreduced states (g_k, λ_k) — rows of a flat
        state array or a :class:`~symgroupoid.Trajectory`."""
        arrows, lam = self._split_states(states, self.unreduced.groupoid, "unreduced")
        reduced = self.morphism.project(arrows, self.parameter_values(params))
        return np.hstack([reduced, lam])

    def reconstruct(self, states, initial: Sequence, params: Mapping | Sequence) -> np.ndarray:
        """Unreduced states (g_k, λ_k) with Φ(g_k) the reduced arrows, g_0 = ``initial``
        (an arrow of G projecting onto the first reduced arrow, or an unreduced state
        (g_0, λ_0) with the reduced multipliers) and each g_{k+1} in the α-fibre of
        β(g_k)."""
        arrows, lam = self._split_states(states, self.groupoid, "reduced")
        g0 = np.asarray(initial, float).ravel()
        n = self.unreduced.groupoid.arrow_dim
        if self.n_constraints and g0.size == n + self.n_constraints:
            if not np.allclose(g0[n:], lam[0], rtol=1e-12, atol=1e-12):
                raise ShapeError(f"{self.name}: the initial state's multipliers "
                                 f"{g0[n:].tolist()} differ from the reduced ones "
                                 f"{lam[0].tolist()} (the multipliers are shared)")
            g0 = g0[:n]
        full = self.morphism.reconstruct(arrows, g0, self.parameter_values(params))
        return np.hstack([full, lam])

    def related_momenta(self, arrow: Sequence, multipliers: Sequence = (),
                        params: Mapping | Sequence = ()) -> MomentumRelation:
        """F±L of the unreduced system at (g, λ) and A*Φ of F±L′ at (Φ(g), λ)."""
        values = self.parameter_values(params)
        g = np.asarray(arrow, float)
        lam = np.asarray(multipliers, float)
        if self._transforms is None:
            self._transforms = (self.unreduced.legendre(), self.legendre())
        unreduced, reduced = self._transforms
        full = [values[str(s)] for s in self.unreduced.parameters]
        minus, plus = unreduced.evaluate(g, lam, full)
        gr = self.morphism.project(g[None], values)[0]
        rminus, rplus = reduced.evaluate(gr, lam, [values[str(s)] for s in self.parameters])
        G = self.unreduced.groupoid
        alpha = [float(sp.N(c)) for c in G.source(tuple(g))]
        beta = [float(sp.N(c)) for c in G.target(tuple(g))]
        return MomentumRelation(minus, plus,
                                self.morphism.pull_back_momentum(alpha, rminus, values),
                                self.morphism.pull_back_momentum(beta, rplus, values))

    def __repr__(self) -> str:
        return (f"ReducedSystem({self.name!r} on {self.groupoid.name}, reduced from "
                f"{self.unreduced.name!r} by {self.morphism.name})")


def _no_holonomic(system: DiscreteSystem) -> None:
    """Reduction relates the Lagrangians and the constraints on the arrows (Def. 4.2); a
    system with holonomic constraints would need ψ = ψ′∘Φ₀ on the bases too."""
    if getattr(system, "n_holonomic", 0):
        raise UnsupportedFeatureError(
            f"{system.name}: reduction of systems with holonomic constraints is not "
            f"implemented (it would need ψ = ψ′∘Φ₀ on the bases, docs/conventions.md §15)")


def _no_forces(system: DiscreteSystem) -> None:
    """Reduction relates the Lagrangians and the constraints (Def. 4.2), not the forces: the
    reduced system of a forced one would lose its forces (docs/conventions.md §20)."""
    if getattr(system, "forces", None) is not None:
        raise UnsupportedFeatureError(
            f"{system.name}: reduction of forced systems is not implemented (the forces "
            f"would have to be related by the morphism too, docs/conventions.md §20); "
            f"reduce the system without forces=, or write the reduced forced system by hand")


def reduce_system(system: DiscreteSystem, morphism: GroupoidMorphism,
                  lagrangian: Callable | None = None, constraints: Callable | None = None,
                  name: str | None = None, check: bool = True) -> ReducedSystem:
    """The reduced system (see :meth:`DiscreteSystem.reduce`)."""
    _no_holonomic(system)
    _no_forces(system)
    instance_argument(morphism, GroupoidMorphism, "morphism", "a GroupoidMorphism (reduce "
                      "needs one)", owner=system.name)
    if system._arity != 1:
        raise UnsupportedFeatureError(f"{system.name}: reduction is implemented for first-order "
                                  f"systems (L: G → R)")
    if morphism.source is not system.groupoid:
        raise DomainError(f"{system.name}: the morphism {morphism.name} starts at "
                          f"{morphism.source.name}, not at the system's groupoid "
                          f"{system.groupoid.name}")
    name = name or f"{system.name}_reduced"
    if check:
        check_morphism(morphism, samples=3)
    red = reduce_functions(name, morphism, system.lagrangian, system.constraints,
                           system.parameters, lagrangian, constraints)
    return ReducedSystem(system, morphism, red.lagrangian, red.constraints, red.parameters,
                         name, red.checks)


def check_system_morphism(morphism: GroupoidMorphism, system: DiscreteSystem,
                          other: DiscreteSystem) -> list:
    """Check that Φ is a morphism of the discrete constrained Lagrangian systems
    ``system`` = (G, N, L) and ``other`` = (G′, N′, L′) (seed 000 Def. 4.2): Φ is a groupoid
    morphism, L = L′∘Φ and φ = φ′∘Φ.  Returns how each identity was verified; raises
    :class:`~symgroupoid.MorphismError` otherwise."""
    if morphism.source is not system.groupoid or morphism.target is not other.groupoid:
        raise DomainError(f"{morphism.name} does not map {system.groupoid.name} to "
                          f"{other.groupoid.name}")
    _no_holonomic(system)
    _no_holonomic(other)
    _no_forces(system)
    _no_forces(other)
    check_morphism(morphism)
    if (system.constraints is None) != (other.constraints is None):
        raise ShapeError(f"{system.name} and {other.name}: one has constraints, the other "
                         f"not; N = Φ⁻¹(N′) needs both")
    red = reduce_functions(system.name, morphism, system.lagrangian, system.constraints,
                           system.parameters, other.lagrangian, other.constraints)
    return red.checks
