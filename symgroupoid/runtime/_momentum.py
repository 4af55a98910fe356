"""Initial states from a configuration and a discrete momentum.

Given the base point q₀ and a momentum p₀ in the dual of the section basis, find the first
arrow g₁ ∈ α⁻¹(q₀) and its multipliers λ₁ from (EQUATIONS.md §3, §4)

    F⁻[L + λ₁·φ](g₁) = p₀,      φ(g₁) = 0,

with ⟨F⁻[L + λ·φ](g), X⟩ = X⃗[L + λ·φ](g) (``system.legendre().minus``).  The unknowns are the
α-fibre chart coordinates of g₁ and λ₁: the same square structure as a step, whose F⁺ side is
replaced by p₀, so the system is regular exactly where the step is.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from .._errors import NewtonDivergenceError, ShapeError, SingularJacobianError
from ._layout import StateLayout


class MomentumInitializer:
    """Solves F⁻L(g₁, λ₁) = p₀, φ(g₁) = 0 for a first-order step's initial state."""

    def __init__(self, step, layout: StateLayout):
        system = step.system
        if system is None or not hasattr(system, "legendre"):
            raise TypeError(f"{step.name}: starting from a momentum needs the DiscreteSystem "
                            f"that derived the step (step.system)")
        if step.order != 1:
            raise NotImplementedError(f"{step.name}: momentum initial data are implemented for "
                                      f"first-order systems; give consecutive configurations")
        self.name, self.layout = step.name, layout
        G = step.groupoid
        forms = system.legendre()
        arrow, lam = tuple(forms.arrow), list(forms.multipliers)
        position = {s: i for i, s in enumerate(step.knowns)}
        missing = [s for s in (*arrow, *lam) if s not in position]
        if missing:
            raise RuntimeError(f"{step.name}: Legendre transform symbols {missing} are not "
                               f"in the step's known state")
        self.rank, self.m = G.rank, len(lam)
        self.source = tuple(G.source(arrow))
        self.source_pos = np.array([position[s] for s in self.source], dtype=np.int64)
        self.arrow_pos = np.array([position[s] for s in arrow], dtype=np.int64)
        self.lam_pos = np.array([position[s] for s in lam], dtype=np.int64)
        x = [sp.Dummy(f"x{a}", real=True) for a in range(self.rank)]
        p = [sp.Dummy(f"p{a}", real=True) for a in range(self.rank)]
        on_fibre = tuple(G.arrow_from(self.source, G.fibre_chart(x)))
        sub = dict(zip(arrow, on_fibre))
        phis = list(system.constraints(G.view(arrow))) if self.m else []
        eqs = sp.Matrix([mi.xreplace(sub) - pi for mi, pi in zip(forms.minus, p)]
                        + [sp.sympify(f).xreplace(sub) for f in phis])
        unknowns = x + lam
        args = [unknowns, list(self.source), p, list(step.parameters)]
        self._F = sp.lambdify(args, eqs, "numpy", cse=True)
        self._J = sp.lambdify(args, eqs.jacobian(unknowns), "numpy", cse=True)
        self._arrow = sp.lambdify([x, list(self.source)], list(on_fibre), "numpy")
        identity = G.identity(self.source)
        self._guess = sp.lambdify([list(self.source)],
                                  list(G.chart_of_fibre(G.fibre_of(identity))), "numpy")
        self._configuration = self._configuration_parts()

    def _configuration_parts(self) -> dict:
        """Parts of the state that are coordinates of the base point α(g₁)."""
        src = set(self.source_pos.tolist())
        out = {}
        for name, part in self.layout.parts.items():
            for o, idx in enumerate(part.index):
                known = idx[idx >= 0]
                if known.size and set(known.tolist()) <= src:
                    out[name] = (part, o)
        return out

    def _source_values(self, configuration) -> np.ndarray:
        state = np.full(self.layout.n_known, np.nan)
        if configuration is None:
            configuration = {}
        if not isinstance(configuration, Mapping):
            values = np.asarray(configuration, dtype=float).ravel()
            if values.size != len(self.source_pos):
                raise ShapeError(f"{self.name}: the configuration has {len(self.source_pos)} "
                                 f"coordinates, got {values.size}")
            return values
        names = ", ".join(self._configuration) or "(none: the base is a point)"
        for key, value in configuration.items():
            if key not in self._configuration:
                raise KeyError(f"{self.name}: {key!r} is not a coordinate of the "
                               f"configuration; expected {names}")
            part, o = self._configuration[key]
            arr = np.asarray(value, dtype=float)
            if arr.shape != part.shape:
                raise ShapeError(f"{self.name}: configuration part {key!r} has shape "
                                 f"{arr.shape}, expected {part.shape}")
            idx = part.index[o]
            state[idx[idx >= 0]] = arr[idx >= 0]
        values = state[self.source_pos]
        if np.isnan(values).any():
            raise KeyError(f"{self.name}: the configuration needs {names}")
        return values

    def solve(self, configuration, momentum: Sequence, params: np.ndarray,
              tol: float = 1e-14, max_iterations: int = 50) -> np.ndarray:
        """The flat initial state (g₁, λ₁) for base point ``configuration`` and ``momentum``."""
        q = self._source_values(configuration)
        p = np.asarray(momentum, dtype=float).ravel()
        if p.size != self.rank:
            raise ShapeError(f"{self.name}: the momentum has {self.rank} components (one per "
                             f"basis section), got {p.size}")
        for label, values in (("configuration", q), ("momentum", p)):
            if not np.isfinite(values).all():
                raise ValueError(f"{self.name}: non-finite {label} {values.tolist()}")
        z = np.concatenate([np.asarray(self._guess(q), float).ravel(), np.zeros(self.m)])
        for _ in range(max_iterations):
            F = np.asarray(self._F(z, q, p, params), float).ravel()
            J = np.asarray(self._J(z, q, p, params), float).reshape(len(z), len(z))
            if not (np.isfinite(F).all() and np.isfinite(J).all()):
                raise NewtonDivergenceError(f"{self.name}: non-finite values solving for the "
                                            f"initial state from the momentum", step=0,
                                            residual_norm=float(np.abs(F).max()), iterate=z)
            try:
                dz = np.linalg.solve(J, F)
            except np.linalg.LinAlgError:
                raise SingularJacobianError(
                    f"{self.name}: F⁻L is not invertible at this configuration (singular "
                    f"Jacobian)", step=0, residual_norm=float(np.abs(F).max()),
                    iterate=z) from None
            z = z - dz
            if np.abs(dz).max() <= tol * (1.0 + np.abs(z).max()):
                break
        else:
            raise NewtonDivergenceError(f"{self.name}: no initial state found for this momentum "
                                        f"in {max_iterations} Newton iterations", step=0,
                                        residual_norm=float(np.abs(F).max()), iterate=z)
        state = np.empty(self.layout.n_known)
        state[self.arrow_pos] = np.asarray(self._arrow(z[:self.rank], q), float).ravel()
        state[self.lam_pos] = z[self.rank:]
        return state
