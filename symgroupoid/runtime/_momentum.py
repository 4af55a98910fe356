"""Initial states from a configuration and a discrete momentum.

Given the base point q₀ and a momentum p₀ in the dual of the section basis, find the first
arrow g₁ ∈ α⁻¹(q₀) and its multipliers λ₁ from (docs/conventions.md §3, §4)

    F⁻[L + λ₁·φ](g₁) = p₀,      φ(g₁) = 0,

(with holonomic constraints ψ, λ₁·ψ(α(g₁)) is part of λ₁·φ and the condition is ψ(β(g₁)) = 0,
docs/conventions.md §15),

with ⟨F⁻[L + λ·φ](g), X⟩ = X⃗[L + λ·φ](g) (``system.legendre().minus``).  The unknowns are the
α-fibre chart coordinates of g₁ and λ₁: the same square structure as a step, whose F⁺ side is
replaced by p₀, so the system is regular exactly where the step is.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from .._errors import (
    DomainError,
    InputNameError,
    InputTypeError,
    ShapeError,
    UnsupportedFeatureError,
)
from ..equations import momentum_program, second_order_momentum_program
from ._layout import StateLayout
from ._newton import ROUNDING_UPDATE, continued_newton, converged, newton  # noqa: F401 (re-exported)
from ._validate import arrow as checked_arrow
from ._validate import group_element, real_array

#: what a from-momentum solve reports when it fails
_SOLVING = "solving for the initial state from the momentum"
_NOT_FOUND = "no initial state found for this momentum"


def _numeric(value, label: str, owner: str) -> np.ndarray:
    """``value`` as a float array, or a :class:`ShapeError` naming ``label``
    (:func:`~symgroupoid._arguments.real_array`: no strings, booleans or complex values)."""
    return real_array(value, label, owner=owner)


class MomentumInitializer:
    """Solves F⁻L(g₁, λ₁) = p₀, φ(g₁) = 0 for a first-order step's initial state."""

    def __init__(self, step, layout: StateLayout, forced: bool = False):
        system = step.system
        if system is None or not hasattr(system, "legendre"):
            raise TypeError(f"{step.name}: starting from a momentum needs the DiscreteSystem "
                            f"that derived the step (step.system)")
        if step.order != 1:
            raise UnsupportedFeatureError(f"{step.name}: momentum initial data are implemented for "
                                      f"first-order systems; give consecutive configurations")
        self.name, self.layout = step.name, layout
        mp = momentum_program(step, forced)
        self.forced = "u" in mp.program.inputs
        position = {s: i for i, s in enumerate(step.knowns)}
        missing = [s for s in (*mp.arrow, *mp.multipliers) if s not in position]
        if missing:
            raise RuntimeError(f"{step.name}: Legendre transform symbols {missing} are not "
                               f"in the step's known state")
        self.rank, self.m, self.n_stages = mp.rank, mp.m, mp.n_stages
        self._inputs_symbols = list(mp.program.inputs.get("u", []))
        self.source_pos = np.array([position[s] for s in mp.source], dtype=np.int64)
        self.arrow_pos = np.array([position[s] for s in mp.arrow], dtype=np.int64)
        self.lam_pos = np.array([position[s] for s in mp.multipliers], dtype=np.int64)
        program = mp.program
        self._FJ = program.numpy_function(
            ["F", "J"], ["z", "q", "p", "params", *(["u"] if self.forced else [])])
        self._arrow = program.numpy_function(["arrow"], ["z", "q"])
        self._guess = program.numpy_function(["guess"], ["q"])
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
        state = np.zeros(self.layout.n_known)
        given = np.zeros(self.layout.n_known, bool)  # (a NaN value is not a missing one)
        if configuration is None:
            configuration = {}
        if not isinstance(configuration, Mapping):
            values = _numeric(configuration, "the configuration", self.name).ravel()
            if values.size != len(self.source_pos):
                raise ShapeError(f"{self.name}: the configuration has {len(self.source_pos)} "
                                 f"coordinates, got {values.size}")
            return values
        names = ", ".join(self._configuration) or "(none: the base is a point)"
        for key, value in configuration.items():
            if key not in self._configuration:
                raise InputNameError(f"{self.name}: {key!r} is not a coordinate of the "
                               f"configuration; expected {names}")
            part, o = self._configuration[key]
            arr = _numeric(value, f"configuration part {key!r}", self.name)
            if arr.shape != part.shape:
                raise ShapeError(f"{self.name}: configuration part {key!r} has shape "
                                 f"{arr.shape}, expected {part.shape}")
            if part.group is not None:  # in the group (or rounded to it), before any solve
                arr = group_element(part.group, arr, f"configuration part {key!r}",
                                    owner=self.name)
            idx = part.index[o]
            state[idx[idx >= 0]] = arr[idx >= 0] - part.fixed[idx >= 0]
            given[idx[idx >= 0]] = True
        if not given[self.source_pos].all():
            raise InputNameError(f"{self.name}: the configuration needs {names}")
        return state[self.source_pos]

    def solve(self, configuration, momentum: Sequence, params: np.ndarray,
              tol: float = 1e-14, max_iterations: int = 50,
              inputs: np.ndarray | None = None) -> np.ndarray:
        """The flat initial state (g₁, λ₁) for base point ``configuration`` and ``momentum``
        (a forced initializer: the forced momentum, with the ``inputs`` of g₁, zero when
        None)."""
        q = self._source_values(configuration)
        p = _numeric(momentum, "the momentum", self.name).ravel()
        if p.size != self.rank:
            raise ShapeError(f"{self.name}: the momentum has {self.rank} components (one per "
                             f"basis section), got {p.size}")
        for label, values in (("configuration", q), ("momentum", p)):
            if not np.isfinite(values).all():
                raise DomainError(f"{self.name}: non-finite {label} {values.tolist()}")
        z = np.concatenate([np.asarray(self._guess(q)[0], float).ravel(),
                            np.zeros(self.n_stages + self.m)])
        n = len(z)

        extra = ()
        if self.forced:
            m = len(self._inputs_symbols)
            extra = (np.zeros(m) if inputs is None else np.asarray(inputs, float).ravel(),)

        def residual(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            F, J = self._FJ(z, q, p, params, *extra)
            return np.asarray(F, float).ravel(), np.asarray(J, float).reshape(n, n)

        z = continued_newton(residual, z, tol, max_iterations, self.name, _SOLVING,
                             "F⁻L is not invertible at this configuration (singular Jacobian)",
                             _NOT_FOUND)
        _check_representable(residual, z, p, self.name)
        state = np.empty(self.layout.n_known)
        state[self.arrow_pos] = np.asarray(self._arrow(z, q)[0], float).ravel()
        state[self.lam_pos] = z[self.rank + self.n_stages:]
        return state


def _check_representable(residual: Callable, z: np.ndarray, p: np.ndarray, name: str) -> None:
    """A :class:`DomainError` where the solution's F⁻L terms overflow: Newton stops on a
    relative update, and at a configuration of 10³⁰⁸ (h = 0.1) the terms Σ_j |∂F/∂z_j||z_j|
    exceed the largest double, so the momentum (0.5 there) is below their rounding and the
    state returned had F⁻L = 6.9·10²⁹¹: no state represents the momentum there."""
    F, J = residual(z)
    with np.errstate(over="ignore", invalid="ignore"):
        terms = np.abs(J) @ np.abs(z)
    if not (np.isfinite(terms).all() and np.isfinite(F).all()):
        raise DomainError(f"{name}: at this configuration the terms of F⁻L overflow (their "
                          f"size exceeds the largest double), so no initial state represents "
                          f"the momentum {p.tolist()} there: give a configuration of the size "
                          f"the system is meant for")


class SecondOrderMomentumInitializer:
    """Initial state of a second-order step from a velocity-like arrow g₀ and a momentum.

    With the second-order transforms on the window (g₀, g₁, g₂) (multipliers λ₀, λ₁ of the
    terms (g₀, g₁), (g₁, g₂); ``second_order_legendre_forms``), solve

        F⁻[L + λ·Φ](g₀, g₁, g₂) = p₀ (2·rank components),   Φ(g₀, g₁) = Φ(g₁, g₂) = 0,

    for the fibre chart coordinates of g₁, g₂ and λ₀, λ₁.  The result is the step's known
    state (g_{k-1}, g_k, g_{k+1}, λ_{k-1}, λ_k) = (g₀, g₁, g₂, λ₀, λ₁).
    """

    def __init__(self, step, layout: StateLayout):
        G = step.groupoid
        mp = second_order_momentum_program(step)
        self.name, self.layout, self.rank = step.name, layout, G.rank
        self.groupoid = G
        self.m, self.n_chart = mp.m, mp.n_chart
        program = mp.program
        self._FJ = program.numpy_function(["F", "J", "fibres"], ["z", "q", "p", "params"])
        self._guess = program.numpy_function(["guess"], ["q"])

    def _residual(self, z, g0, p, params):
        F, J, f = (np.asarray(v, float).ravel() for v in self._FJ(z, g0, p, params))
        return F, J.reshape(len(F), len(z)), np.concatenate([g0, f, z[self.n_chart:]])

    def solve(self, arrow, momentum: Sequence, params: np.ndarray, tol: float = 1e-14,
              max_iterations: int = 50) -> np.ndarray:
        if isinstance(arrow, Mapping):
            raise InputTypeError(f"{self.name}: a second-order system starts from its first "
                                 "arrow g₀ (flat coordinates, as in step.arrows) and a "
                                 "momentum, not from a configuration")
        g0 = checked_arrow(self.groupoid, arrow, "the first arrow g₀", owner=self.name)
        p = _numeric(momentum, "the momentum", self.name).ravel()
        if p.size != 2 * self.rank:
            raise ShapeError(f"{self.name}: a second-order momentum has {2 * self.rank} "
                             f"components (two per basis section), got {p.size}")
        if not np.isfinite(p).all():
            raise DomainError(f"{self.name}: non-finite momentum {p.tolist()}")
        guess = np.asarray(self._guess(g0)[0], float).ravel()
        z = np.concatenate([guess, guess, np.zeros(2 * self.m)])
        z = continued_newton(lambda z: self._residual(z, g0, p, params)[:2], z, tol,
                             max_iterations, self.name, _SOLVING, "F⁻L is not invertible here",
                             _NOT_FOUND)
        return self._residual(z, g0, p, params)[2]
