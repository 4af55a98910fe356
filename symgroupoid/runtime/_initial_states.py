"""The initial data of a run (part of :class:`~symgroupoid.runtime.Simulator`): a state
from a base point and a discrete momentum (the discrete Legendre transform, seed 000 §3),
from a configuration and a velocity (the continuous one first, docs/conventions.md §21),
or from a state off the constraints (its projection onto them)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .._arguments import flag_argument
from .._errors import DomainError, NewtonDivergenceError, UnsupportedFeatureError
from ._backends import real_vector
from ._inputs import step_inputs
from ._validate import integer_argument


class InitialStates:
    """:meth:`from_momentum`, :meth:`from_velocity` and :meth:`project_initial` of a
    :class:`~symgroupoid.runtime.Simulator` (which supplies ``equations``, ``layout``,
    ``name``, ``parameters``, ``state`` and the ``_momentum`` slot)."""

    def from_momentum(self, configuration, momentum: Sequence, params, *, inputs=None,
                      forced: bool = False) -> np.ndarray:
        """The initial state (g_1, λ_1) from a base point q_0 and a discrete momentum p_0.

        Solves F⁻[L + λ_1·φ](g_1) = p_0 and φ(g_1) = 0 for g_1 ∈ α⁻¹(q_0) and λ_1 (so the
        multipliers of a constrained system are determined by the momentum).  ``momentum``
        has one component per basis section (``system.legendre().minus`` order);
        ``configuration`` names the base point's coordinates, e.g. ``{"x": 0, "y": 0}``
        (plate-ball), ``{"Gamma": (0, 0, 1)}`` (heavy top), or None when the base is a point.

        Second-order systems: ``configuration`` is the velocity-like first arrow g₀ (flat
        coordinates) and ``momentum`` has two components per section (F⁻L of the window
        g₀, g₁, g₂); the result is the state (g₀, g₁, g₂, λ₀, λ₁).

        A forced system with inputs takes ``inputs``: the m inputs u_1 of the arrow g_1
        (second order: held for both known pairs), which the state carries
        (docs/conventions.md §20).  The momentum is F⁻L, which the forces do not enter,
        so they do not change g_1 and λ_1.  ``forced=True`` (first order) solves the forced
        discrete Legendre transform F⁻L(g_1) − f⁻(g_1) = p_0 instead (Marsden–West eq.
        (3.2.4), as :meth:`from_velocity` does): the momentum of the forced discrete
        trajectory at q_0 is then p_0, which keeps a forced run from a physical momentum
        p(0) at its order (from F⁻L = p(0) the start is O(h) away and the order drops to 1).
        """
        forced = flag_argument(forced, "forced", owner=self.name)
        if forced and self.equations.order == 2 and self._has_forces():
            raise UnsupportedFeatureError(
                f"{self.name}: from_momentum(forced=True) is for first-order systems; a "
                f"second-order system's momentum is F⁻L of its window (forced=False)")
        return self._from_momentum(configuration, momentum, params, inputs, forced=forced)

    def _has_forces(self) -> bool:
        fs = getattr(getattr(self.equations, "system", None), "functions", None)
        return fs is not None and fs.forces is not None

    def _from_momentum(self, configuration, momentum: Sequence, params, inputs,
                       forced: bool) -> np.ndarray:
        """:meth:`from_momentum`; ``forced``: through the forced discrete Legendre transform
        F⁻L − f⁻ (first order; :meth:`from_velocity`)."""
        p = self.parameters(params)
        u = step_inputs(self.layout, inputs, owner=self.name)
        initializer = (self._forced_momentum_initializer() if forced
                       else self._momentum_initializer())
        state = (initializer.solve(configuration, momentum, p, inputs=u)
                 if getattr(initializer, "forced", False)
                 else initializer.solve(configuration, momentum, p))
        if u is not None:  # the state's own inputs, and the slot of the next term's
            state = np.concatenate([state, np.zeros(self.layout.n_known - len(state))])
            for name, value in zip(self.layout.input_names, u):
                state[self.layout.parts[name].index] = value
            state[self.layout.upcoming_index] = u
        try:
            return self.state(state, p)
        except DomainError as err:  # Newton stopped at its step test, not on φ = 0
            if "ψ∘α" in err.violated:  # the given base point is off M: an
                raise                                    # input error, not a failed solve
            raise NewtonDivergenceError(
                f"{self.name}: no consistent initial state found for the momentum "
                f"{np.asarray(momentum, dtype=object).ravel().tolist()}: the state solved from "
                f"it does not satisfy the constraints (the momentum may be too large for "
                f"double precision); {err}", step=0, iterate=state) from err

    def _momentum_initializer(self):
        """The solver of :meth:`from_momentum` (made on first use)."""
        if self._momentum is None:
            from ._momentum import MomentumInitializer, SecondOrderMomentumInitializer

            kind = (SecondOrderMomentumInitializer if self.equations.order == 2
                    else MomentumInitializer)
            self._momentum = kind(self.equations, self.layout)
        return self._momentum

    def _forced_momentum_initializer(self):
        """The solver of the forced discrete Legendre transform (made on first use): that
        of :meth:`from_momentum` for systems without forces or of second order."""
        if self.equations.order == 2 or not self._has_forces():
            return self._momentum_initializer()
        if getattr(self, "_forced_momentum", None) is None:
            from ._momentum import MomentumInitializer

            self._forced_momentum = MomentumInitializer(self.equations, self.layout,
                                                        forced=True)
        return self._forced_momentum

    def from_velocity(self, configuration, velocity: Sequence, params, *, inputs=None
                      ) -> np.ndarray:
        """The initial state from a configuration q₀ and a velocity v₀ (on a group the body
        velocity ξ₀; on a product the components factor after factor), for a system
        discretised from a :class:`~symgroupoid.ContinuousSystem`: the continuous Legendre
        transform p₀ = ∂L/∂v(q₀, v₀) (the step's ``velocity_momentum`` program), then
        :meth:`from_momentum` (the discrete one), so that the discrete trajectory is the
        integrator's from the initial data (q₀, p₀) (docs/conventions.md §21).  A forced
        system starts through the forced discrete Legendre transform, F⁻L(g₁) − f⁻(g₁) = p₀
        (Marsden–West eq. (3.2.4)), with its stages solving the forced stage rows: without
        f⁻ the start is O(h) away and a run's order drops to 1.
        ``configuration`` as :meth:`from_momentum` takes it, and ``inputs`` (the inputs of
        the first arrow of a system with inputs) too."""
        program = self.equations.velocity_momentum
        if program is None:
            raise UnsupportedFeatureError(
                f"{self.name}: from_velocity needs a system discretised from a "
                f"ContinuousSystem (system.discretize(...)); use from_momentum")
        p = self.parameters(params)
        q = self._momentum_initializer()._source_values(configuration)
        v = real_vector(velocity, len(program.inputs["v"]), "velocity", owner=self.name,
                        finite=True)
        momentum = program.numpy_function(["momentum"], ["q", "v", "p"])(q, v, p)[0]
        return self._from_momentum(configuration, np.asarray(momentum, float).ravel(), params,
                                   inputs, forced=True)

    def project_initial(self, initial, params, *, max_iterations: int = 50) -> np.ndarray:
        """A consistent initial state from one that violates the constraints.

        ``initial`` is given as for :meth:`state` (named parts or a flat vector); the
        multipliers may be left out (then λ_k = 0).  The known arrow g_k is moved within the
        α-fibre of its source to a nearby zero of φ: Gauss–Newton with minimum-norm steps in
        the fibre chart, x ← x − J⁺φ, with the exact constraint Jacobian J from the
        expression graph (to first order the orthogonal projection in the chart).  On a
        pair groupoid, (q₀, q₁) keeps q₀ and corrects q₁.  With holonomic constraints ψ(q) = 0
        the configuration α(g_k) is first moved onto M = {ψ = 0} (the nearest point in the
        chart, the target kept), so that configurations typed to a few digits can be given;
        group parts given to a few digits are replaced by the nearest group element (a
        :class:`~symgroupoid.GroupRoundingWarning` says so).  λ_k is kept as given.

        Returns the flat state, checked like any initial state (:meth:`state` with
        ``params``).  First-order steps only; a :class:`~symgroupoid.runtime._projection.
        ProjectionError` (a :class:`DomainError`) when no zero of φ is found nearby.
        ``max_iterations``: the Gauss–Newton iteration cap, an integer in 1 … 10⁶.
        """
        from ._projection import projection

        max_iterations = integer_argument(max_iterations, "max_iterations", minimum=1,
                                          maximum=10**6, owner=self.name)
        p = self.parameters(params)
        if (isinstance(initial, Mapping) and self.layout.n_multipliers
                and not any(k in initial for k in ("lambda", "λ", "multipliers"))):
            initial = {**initial, "lambda": np.zeros(self.layout.n_multipliers)}
        state = self.state(initial)
        moved = projection(self.equations, self.layout)(state, p, max_iterations)
        return self.state(moved, p)
