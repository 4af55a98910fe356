"""Trajectory: the result of :meth:`Simulator.simulate`, with named arrays."""

from __future__ import annotations

import numpy as np

from ._layout import MULTIPLIER_KEYS, StateLayout


class Trajectory:
    """N steps from an initial state: N + 1 states and per-step solver data.

    - ``traj.states``: (N+1, n_known) flat states (g_k, λ_k), k = 0..N;
    - ``traj[name]``: a named part per state, e.g. ``traj["g"]`` (N+1, 3, 3),
      ``traj["Gamma"]`` (N+1, 3); a coordinate of a pair-groupoid factor gives all its
      positions q_0, q_1, …, q_{N+1} (the two initial ones and one per step: N+2 values);
    - ``traj.multipliers``: (N+1, m) multipliers λ_k of each state;
    - ``traj.newton_iterations`` (N,) and ``traj.residual_norms`` (N,): Newton updates and
      final |F|_∞ of each step;
    - ``traj.parameters``: the parameter values used, by name.
    """

    def __init__(self, layout: StateLayout, states: np.ndarray, iterations: np.ndarray,
                 residual_norms: np.ndarray, parameters: dict, backend: str):
        self._layout = layout
        self.states = states
        self.newton_iterations = iterations
        self.residual_norms = residual_norms
        self.parameters = parameters
        self.backend = backend
        for arr in (states, iterations, residual_norms):
            arr.setflags(write=False)

    @property
    def steps(self) -> int:
        """Number of steps N."""
        return len(self.newton_iterations)

    def __len__(self) -> int:
        return len(self.states)

    @property
    def multipliers(self) -> np.ndarray:
        return self._layout.view(self.states, "lambda")

    def keys(self) -> list[str]:
        return list(self._layout.names) + (["lambda"] if self._layout.n_multipliers else [])

    def __getitem__(self, name: str) -> np.ndarray:
        if name not in self._layout.parts and name not in MULTIPLIER_KEYS:
            raise KeyError(f"no part named {name!r}; available: {', '.join(self.keys())}")
        return self._layout.view(self.states, name)

    def __contains__(self, name: str) -> bool:
        return name in self._layout.parts or name in MULTIPLIER_KEYS

    def final_state(self) -> np.ndarray:
        """The last flat state (a valid initial state for a continuation)."""
        return self.states[-1].copy()

    def __repr__(self) -> str:
        return (f"<Trajectory {self._layout.step_name!r}: {self.steps} steps, parts "
                f"{', '.join(self.keys())}; backend {self.backend}>")
