"""Reduced systems: a discrete system on G′ obtained from one on G by a morphism Φ: G → G′
(seed 000 Def. 4.2, Thm 4.5, Cor. 4.6, Remark 4.7; docs/conventions.md §13)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._arguments import finite_vector, instance_argument, real_array
from .._errors import DomainError, ShapeError, UnsupportedFeatureError
from .._parameters import parameter_vector
from ..derivation import check_forces, force_functions, reduce_functions
from ..groupoids import GROUP_TOLERANCE, GroupoidMorphism, check_morphism
from ._system import DiscreteSystem, forces_argument


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
    φ = φ′∘Φ (and, for a forced system, the A*Φ-relation of the forces, docs/conventions.md
    §13) were verified.  A reduced forced system has the reduced forces f′ and the inputs of
    the unreduced one; its states carry the inputs as the unreduced states do.
    :meth:`project` maps unreduced states to reduced ones (a solution to a solution,
    Cor. 4.6), :meth:`reconstruct` lifts a reduced trajectory from one unreduced arrow
    (Remark 4.7), :meth:`related_momenta` evaluates Theorem 4.5.
    """

    def __init__(self, unreduced: DiscreteSystem, morphism: GroupoidMorphism,
                 lagrangian: Callable, constraints: Callable | None,
                 parameters: Sequence[sp.Symbol], name: str, checks: list,
                 forces: Callable | None = None):
        instance_argument(unreduced, DiscreteSystem, "unreduced", "a DiscreteSystem (a "
                          "reduced system comes from system.reduce(morphism))",
                          owner="ReducedSystem")
        instance_argument(morphism, GroupoidMorphism, "morphism", "a GroupoidMorphism",
                          owner="ReducedSystem")
        step = getattr(unreduced, "time_step", None)
        kept = step is not None and str(step) in {str(p) for p in parameters}
        super().__init__(morphism.target, lagrangian, constraints, parameters, name,
                         time_step=step if kept else None, forces=forces,
                         inputs=list(unreduced.inputs) if forces is not None else ())
        self.unreduced, self.morphism, self.checks = unreduced, morphism, checks
        self._transforms: tuple | None = None

    # --- parameters and states --------------------------------------------------------------
    def parameter_values(self, params: Mapping | Sequence) -> dict:
        """{name: value} from a mapping (by name or symbol) or a sequence in
        ``self.parameters`` order; every parameter must be given, finite and with its
        symbol's assumptions (a :class:`ParameterError` otherwise).  A mapping may also name
        parameters of the unreduced system that this one does not read (a run's own)."""
        names = {str(s) for s in self.parameters}
        if isinstance(params, Mapping):
            theirs = {str(s) for s in self.unreduced.parameters} - names
            params = {k: v for k, v in params.items() if str(k) not in theirs}
        return parameter_vector(self.parameters, params, owner=self.name)[1]

    def _split_states(self, states, groupoid, what: str) -> tuple[np.ndarray, np.ndarray]:
        """(arrows, the rest): the rest is the multipliers, then for a system with inputs
        the inputs u_k of the arrow and the slot of u_{k+1} (docs/conventions.md §20), which
        reduction keeps as they are."""
        arr = np.atleast_2d(real_array(getattr(states, "states", states), f"the {what} states",
                                       owner=self.name))
        m = len(self.inputs)
        n = groupoid.arrow_dim + self.n_constraints + 2 * m
        if arr.shape[1] != n:
            inputs = f", {m} inputs and the slot of the next ones" if m else ""
            raise ShapeError(f"{self.name}: {what} states have {n} entries (an arrow of "
                             f"{groupoid.name}, {self.n_constraints} multipliers{inputs}); "
                             f"got shape {arr.shape}")
        bad = np.argwhere(~np.isfinite(arr))
        if len(bad):
            row, entry = (int(v) for v in bad[0])
            raise DomainError(f"{self.name}: {what} state {row} has a non-finite entry "
                              f"({entry}: {arr[row, entry]}); states must be finite")
        return arr[:, :groupoid.arrow_dim], arr[:, groupoid.arrow_dim:]

    def project(self, states, params: Mapping | Sequence) -> np.ndarray:
        """Reduced states (Φ(g_k), λ_k) of unreduced states (g_k, λ_k) — rows of a flat
        state array or a :class:`~symgroupoid.Trajectory`; a forced system's inputs are
        kept."""
        arrows, lam = self._split_states(states, self.unreduced.groupoid, "unreduced")
        off = self.unreduced.groupoid.off_group_rows(arrows, GROUP_TOLERANCE)
        if len(off):  # (Φ of 1.5·I was returned as an arrow: 2.25·I)
            raise DomainError(f"{self.name}: unreduced state {int(off[0])} is not an arrow of "
                              f"{self.unreduced.groupoid.name}: a group part is off its group "
                              f"by more than {GROUP_TOLERANCE:g} (|RᵀR − I|, |det R − 1|)")
        reduced = self.morphism.project(arrows, self.parameter_values(params))
        return np.hstack([reduced, lam])

    def reconstruct(self, states, initial: Sequence, params: Mapping | Sequence) -> np.ndarray:
        """Unreduced states (g_k, λ_k) with Φ(g_k) the reduced arrows, g_0 = ``initial``
        (an arrow of G projecting onto the first reduced arrow, or an unreduced state
        (g_0, λ_0) with the reduced multipliers) and each g_{k+1} in the α-fibre of
        β(g_k)."""
        kept = getattr(states, "step_indices", None)
        if kept is not None and np.any(np.diff(np.asarray(kept)) != 1):
            raise DomainError(f"{self.name}: the reconstruction composes every reduced arrow "
                              f"of the run, but this trajectory keeps only the states of steps "
                              f"{_shown_steps(kept)}; simulate with every=1")
        arrows, lam = self._split_states(states, self.groupoid, "reduced")
        g0 = np.asarray(initial, float).ravel()
        n = self.unreduced.groupoid.arrow_dim
        if lam.shape[1] and g0.size == n + lam.shape[1]:
            if not np.allclose(g0[n:], lam[0], rtol=1e-12, atol=1e-12):
                raise ShapeError(f"{self.name}: the initial state's multipliers (and inputs) "
                                 f"{g0[n:].tolist()} differ from the reduced ones "
                                 f"{lam[0].tolist()} (they are shared)")
            g0 = g0[:n]
        full = self.morphism.reconstruct(arrows, g0, self.parameter_values(params))
        return np.hstack([full, lam])

    def related_momenta(self, arrow: Sequence, multipliers: Sequence = (),
                        params: Mapping | Sequence = ()) -> MomentumRelation:
        """F±L of the unreduced system at (g, λ) and A*Φ of F±L′ at (Φ(g), λ)."""
        values = self.parameter_values(params)
        g = finite_vector(arrow, self.unreduced.groupoid.arrow_dim, "arrow", owner=self.name)
        lam = finite_vector(multipliers, self.n_constraints, "multipliers", owner=self.name)
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


def _forced_arity(system: DiscreteSystem) -> None:
    """Forced reduction is derived for first-order systems (f(g) -> (f⁻, f⁺))."""
    if getattr(system, "forces", None) is not None and system._arity != 1:
        raise UnsupportedFeatureError(f"{system.name}: reduction is implemented for "
                                      f"first-order systems (L: G → R)")


def _forces_given(system: DiscreteSystem, morphism: GroupoidMorphism, forces) -> None:
    """Reduced forces are given exactly when the system is forced (a forced system reduced
    without them would lose its forces)."""
    if getattr(system, "forces", None) is None:
        if forces is not None:
            raise ShapeError(f"{system.name}: the system has no forces; reduced forces were "
                             f"given")
        return
    if forces is None:
        raise ShapeError(
            f"{system.name}: the system is forced; give its reduced forces, "
            f"reduce(Φ, forces=f′) with f′(g′) -> (f′_minus, f′_plus) on "
            f"{morphism.target.name} and f±(g) = M·f′±(Φ(g)), M the algebroid matrix of Φ "
            f"(docs/conventions.md §13)")


def _reduced_forces(system: DiscreteSystem, morphism: GroupoidMorphism, forces,
                    parameters: Sequence, name: str) -> tuple:
    """The reduced forces f′ (the user's callable on arrows of G′) and how their relation to
    the system's was verified; (None, []) for a system without forces."""
    _forces_given(system, morphism, forces)
    if forces is None:
        return None, []
    reduced = force_functions(name, morphism.target, forces_argument(name, forces), system.inputs,
                              parameters)
    return forces, [check_forces(system.name, morphism, system.functions.forces, reduced)]


def reduce_system(system: DiscreteSystem, morphism: GroupoidMorphism,
                  lagrangian: Callable | None = None, constraints: Callable | None = None,
                  name: str | None = None, check: bool = True,
                  forces: Callable | None = None) -> ReducedSystem:
    """The reduced system (see :meth:`DiscreteSystem.reduce`); a forced system's reduced
    forces ``forces`` = f′ are checked to be A*Φ-related to its own (:func:`check_forces`)."""
    _no_holonomic(system)
    _forced_arity(system)
    instance_argument(morphism, GroupoidMorphism, "morphism", "a GroupoidMorphism (reduce "
                      "needs one)", owner=system.name)
    if system._arity != 1:
        raise UnsupportedFeatureError(f"{system.name}: reduction is implemented for first-order "
                                  f"systems (L: G → R)")
    if morphism.source is not system.groupoid:
        raise DomainError(f"{system.name}: the morphism {morphism.name} starts at "
                          f"{morphism.source.name}, not at the system's groupoid "
                          f"{system.groupoid.name}")
    _forces_given(system, morphism, forces)
    name = name or f"{system.name}_reduced"
    if check:
        check_morphism(morphism, samples=3)
    red = reduce_functions(name, morphism, system.lagrangian, system.constraints,
                           system.parameters, lagrangian, constraints)
    reduced_forces, force_checks = _reduced_forces(system, morphism, forces, red.parameters,
                                                   name)
    return ReducedSystem(system, morphism, red.lagrangian, red.constraints, red.parameters,
                         name, red.checks + force_checks, reduced_forces)


def check_system_morphism(morphism: GroupoidMorphism, system: DiscreteSystem,
                          other: DiscreteSystem) -> list:
    """Check that Φ is a morphism of the discrete constrained Lagrangian systems
    ``system`` = (G, N, L) and ``other`` = (G′, N′, L′) (seed 000 Def. 4.2): Φ is a groupoid
    morphism, L = L′∘Φ and φ = φ′∘Φ.  Returns how each identity was verified; raises
    :class:`~symgroupoid.MorphismError` otherwise."""
    instance_argument(morphism, GroupoidMorphism, "morphism", "a GroupoidMorphism",
                      owner="check_system_morphism")
    for name, value in (("system", system), ("other", other)):
        instance_argument(value, DiscreteSystem, name, "a DiscreteSystem",
                          owner="check_system_morphism")
    if morphism.source is not system.groupoid or morphism.target is not other.groupoid:
        raise DomainError(f"{morphism.name} does not map {system.groupoid.name} to "
                          f"{other.groupoid.name}")
    _no_holonomic(system)
    _no_holonomic(other)
    _forced_arity(system)
    _forced_arity(other)
    forced = [getattr(s, "forces", None) is not None for s in (system, other)]
    if forced[0] != forced[1]:
        raise ShapeError(f"{system.name} and {other.name}: one has forces, the other not; "
                         f"a morphism of forced systems relates both systems' forces "
                         f"(docs/conventions.md §13)")
    if forced[0] and [str(u) for u in system.inputs] != [str(u) for u in other.inputs]:
        raise ShapeError(f"{system.name} and {other.name}: the inputs differ "
                         f"({', '.join(map(str, system.inputs)) or 'none'} against "
                         f"{', '.join(map(str, other.inputs)) or 'none'}); related forces "
                         f"read the same inputs")
    check_morphism(morphism)
    if (system.constraints is None) != (other.constraints is None):
        raise ShapeError(f"{system.name} and {other.name}: one has constraints, the other "
                         f"not; N = Φ⁻¹(N′) needs both")
    red = reduce_functions(system.name, morphism, system.lagrangian, system.constraints,
                           system.parameters, other.lagrangian, other.constraints)
    checks = red.checks
    if forced[0]:
        checks = checks + [check_forces(system.name, morphism, system.functions.forces,
                                        other.functions.forces)]
    return checks


def _shown_steps(kept) -> str:
    """The first kept step indices, for a message."""
    kept = [int(k) for k in np.asarray(kept)[:4]]
    return ", ".join(map(str, kept)) + ", …"
