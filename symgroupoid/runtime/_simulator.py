"""Simulator: advance a step's equations from user-stated initial conditions."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .._errors import NewtonDivergenceError, ShapeError, SingularJacobianError
from ._backends import (
    INVALID_ARGUMENT,
    OK,
    SINGULAR_JACOBIAN,
    STATUS_MESSAGES,
    NewtonOptions,
)
from ._layout import StateLayout
from ._trajectory import Trajectory
from ._validate import constraint_check, parameter_vector


class Simulator:
    """Runs the step (g_k, λ_k) ↦ (g_{k+1}, λ_{k+1}) of a :class:`StepEquations`.

    Obtain one with ``step.compile()`` (or :func:`compile_step`).  Initial states are given
    by name (see :meth:`state`), parameters by name or in ``step.parameters`` order.

    >>> sim = step.compile()                                             # doctest: +SKIP
    >>> traj = sim.simulate({"x": (0.0, 0.01), "y": (0.0, 0.0), "g": W1,
    ...                      "lambda": [0, 0, 0]}, steps=1000,
    ...                     params={"h": 0.01, "r": 0.1, "Omega": 1.0, "c": 0.0})
    >>> traj["x"], traj["g"], traj.multipliers                          # doctest: +SKIP
    """

    def __init__(self, step, kernel, options: NewtonOptions | None = None,
                 cache_entry: Path | None = None):
        self.equations = step
        self.kernel = kernel
        self.options = options or NewtonOptions()
        self.cache_entry = cache_entry
        self.layout = StateLayout(step)
        self.parameter_names = [str(s) for s in step.parameters]
        self._momentum = None

    @property
    def backend(self) -> str:
        """``"c"`` (compiled kernel) or ``"numpy"``."""
        return self.kernel.name

    @property
    def name(self) -> str:
        return self.equations.name

    # --- inputs ---------------------------------------------------------------------------------
    def parameters(self, params: Mapping | Sequence | None) -> np.ndarray:
        """Parameter vector in ``step.parameters`` order from a mapping or a sequence.

        One rule for every entry point (:func:`~symgroupoid.runtime._validate.parameter_vector`):
        every parameter named exactly once (unknown names are rejected), finite real values
        satisfying the assumptions the symbols are declared with (``positive=True``, …).
        """
        return parameter_vector(self.equations.parameters, params, owner=self.name)[0]

    def state(self, initial: Mapping | Sequence | np.ndarray, params=None) -> np.ndarray:
        """The flat known state (g_k, λ_k) from named parts or a flat vector.

        Named parts (a mapping): each coordinate of a pair-groupoid factor as two consecutive
        configurations ``(q_0, q_1)``; a group part (``"g"``, ``"W"``) as its matrix, checked
        to lie in the group; other coordinates (``"Gamma"``) by value; the multipliers as
        ``"lambda"`` (required when the system has constraints).  A flat vector must have
        ``len(step.knowns)`` finite entries, ordered as ``step.knowns``; its group parts are
        checked as named ones are.

        With ``params`` (as for :meth:`simulate`) the known arrows must also satisfy the
        system's constraints (first order φ(g_k); second order Φ on each known pair;
        nonholonomic ψ(g_k)) to rounding: |φ_i| ≤ max(10·tol_residual,
        CONSTRAINT_ROUNDING·ε·M_i), M_i the size of φ_i's terms; a :class:`DomainError`
        gives the violation of each constraint that does not hold.
        """
        if isinstance(initial, Mapping):
            state = self.layout.pack(initial)
        else:
            if isinstance(initial, (str, bytes)):
                raise ShapeError(f"{self.name}: a state is a mapping of named parts or a flat "
                                 f"vector, got {initial!r}")
            try:
                arr = np.asarray(initial, dtype=float)
            except (TypeError, ValueError):
                raise ShapeError(f"{self.name}: a flat state must be numeric, got "
                                 f"{type(initial).__name__}") from None
            if arr.shape != (self.layout.n_known,):
                raise ShapeError(f"{self.name}: a flat state has shape ({self.layout.n_known},) "
                                 f"(the knowns {', '.join(s.name for s in self.equations.knowns)}"
                                 f"); got shape {arr.shape}")
            self.layout.check_finite(arr)
            self.layout.check_arrows(arr)
            state = arr.copy()
        if params is not None:
            p = self.parameters(params)
            constraint_check(self.equations)(state, p, atol=10 * self.options.tol_residual,
                                             owner=self.name)
        return state

    # --- running --------------------------------------------------------------------------------
    def simulate(self, initial, steps: int, params, *, options: NewtonOptions | None = None
                 ) -> Trajectory:
        """Advance ``steps`` steps from ``initial`` (see :meth:`state`).

        Raises :class:`SingularJacobianError` or :class:`NewtonDivergenceError` (with the
        failing step index, its residual norm and last Newton iterate) instead of returning
        non-finite values.
        """
        if isinstance(steps, bool) or int(steps) != steps or steps < 0:
            raise ValueError(f"{self.name}: steps must be a non-negative integer, got {steps!r}")
        known0 = np.ascontiguousarray(self.state(initial))
        p = np.ascontiguousarray(self.parameters(params))
        run = self.kernel.simulate(known0, p, int(steps), options or self.options)
        if run.status != OK:
            raise self._failure(run.status, run.failed_step, run.iterations[run.failed_step],
                                run.residual_norms[run.failed_step], run.last_iterate)
        values = dict(zip(self.parameter_names, p.tolist()))
        return Trajectory(self.layout, run.states, run.iterations, run.residual_norms, values,
                          self.backend)

    def step(self, state, params, *, options: NewtonOptions | None = None) -> np.ndarray:
        """One step: the next flat state from a state (named or flat)."""
        return self.simulate(state, 1, params, options=options).states[1].copy()

    def solve(self, state, params, *, guess=None, options: NewtonOptions | None = None):
        """Solve one step: (unknowns u, Newton iterations, residual norm); raises on failure."""
        known = np.ascontiguousarray(self.state(state))
        p = np.ascontiguousarray(self.parameters(params))
        u0 = self.kernel.predict(known, p) if guess is None else np.asarray(guess, float)
        status, u, it, rn = self.kernel.solve_step(known, p, u0, options or self.options)
        if status != OK:
            raise self._failure(status, 0, it, rn, u)
        return u, it, rn

    def from_momentum(self, configuration, momentum: Sequence, params) -> np.ndarray:
        """The initial state (g_1, λ_1) from a base point q_0 and a discrete momentum p_0.

        Solves F⁻[L + λ_1·φ](g_1) = p_0 and φ(g_1) = 0 for g_1 ∈ α⁻¹(q_0) and λ_1 (so the
        multipliers of a constrained system are determined by the momentum).  ``momentum``
        has one component per basis section (``system.legendre().minus`` order);
        ``configuration`` names the base point's coordinates, e.g. ``{"x": 0, "y": 0}``
        (plate-ball), ``{"Gamma": (0, 0, 1)}`` (heavy top), or None when the base is a point.

        Second-order systems: ``configuration`` is the velocity-like first arrow g₀ (flat
        coordinates) and ``momentum`` has two components per section (F⁻L of the window
        g₀, g₁, g₂); the result is the state (g₀, g₁, g₂, λ₀, λ₁).
        """
        if self._momentum is None:
            from ._momentum import MomentumInitializer, SecondOrderMomentumInitializer

            kind = (SecondOrderMomentumInitializer if self.equations.order == 2
                    else MomentumInitializer)
            self._momentum = kind(self.equations, self.layout)
        p = self.parameters(params)
        state = self._momentum.solve(configuration, momentum, p)
        return self.state(state, p)

    def _failure(self, status: int, step: int, iterations: int, residual_norm: float,
                 iterate: np.ndarray) -> Exception:
        text = (f"{self.name}: step {step} failed: {STATUS_MESSAGES[status]} (after "
                f"{int(iterations)} Newton iterations, |F|_inf = {residual_norm:.3e})")
        if status == SINGULAR_JACOBIAN:
            cls = SingularJacobianError
        elif status == INVALID_ARGUMENT:
            return ValueError(text)
        else:
            cls = NewtonDivergenceError
        return cls(text, step=int(step), residual_norm=float(residual_norm),
                   iterate=np.array(iterate, dtype=float))

    def __repr__(self) -> str:
        return (f"<Simulator {self.name!r}: {len(self.equations.unknowns)} unknowns, "
                f"backend {self.backend}>")
