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

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from .._errors import (
    DomainError,
    InputNameError,
    InputTypeError,
    NewtonDivergenceError,
    ShapeError,
    SingularJacobianError,
    UnsupportedFeatureError,
)
from .._lambdify import NUMPY_MODULES
from ._layout import StateLayout
from ._validate import arrow as checked_arrow
from ._validate import real_array

#: a Newton update at most this size (relative to the iterate) that is not 10 times smaller
#: than the one before it is rounding: quadratic convergence has ended at a solution
ROUNDING_UPDATE = 1e-9


def converged(dz: np.ndarray, before: float, z: np.ndarray, tol: float) -> bool:
    """Whether Newton has converged after the update ``dz`` (the one before it had size
    ``before``): the update is below ``tol`` relative to the iterate, or it is rounding —
    below ROUNDING_UPDATE relative and no longer shrinking (a badly scaled system, e.g.
    rows of size 1/h³ next to constraint rows of size 1, stalls above ``tol``)."""
    size, scale = float(np.abs(dz).max()), 1.0 + float(np.abs(z).max())
    return size <= tol * scale or (size <= ROUNDING_UPDATE * scale and size > 0.1 * before)


def _numeric(value, label: str, owner: str) -> np.ndarray:
    """``value`` as a float array, or a :class:`ShapeError` naming ``label``
    (:func:`~symgroupoid._arguments.real_array`: no strings, booleans or complex values)."""
    return real_array(value, label, owner=owner)


class MomentumInitializer:
    """Solves F⁻L(g₁, λ₁) = p₀, φ(g₁) = 0 for a first-order step's initial state."""

    def __init__(self, step, layout: StateLayout):
        system = step.system
        if system is None or not hasattr(system, "legendre"):
            raise TypeError(f"{step.name}: starting from a momentum needs the DiscreteSystem "
                            f"that derived the step (step.system)")
        if step.order != 1:
            raise UnsupportedFeatureError(f"{step.name}: momentum initial data are implemented for "
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
        on_fibre = tuple(G.arrow_from(self.source, G.fibre_chart(x, self.source)))
        sub = dict(zip(arrow, on_fibre))
        phis = system._fs.rows_on(G, [arrow]) if self.m else []
        eqs = sp.Matrix([mi.xreplace(sub) - pi for mi, pi in zip(forms.minus, p)]
                        + [sp.sympify(f).xreplace(sub) for f in phis])
        unknowns = x + lam
        args = [unknowns, list(self.source), p, list(step.parameters)]
        self._F = sp.lambdify(args, eqs, NUMPY_MODULES, cse=True)
        self._J = sp.lambdify(args, eqs.jacobian(unknowns), NUMPY_MODULES, cse=True)
        self._arrow = sp.lambdify([x, list(self.source)], list(on_fibre), NUMPY_MODULES)
        identity = G.identity(self.source)
        self._guess = sp.lambdify([list(self.source)],
                                  list(G.chart_of_fibre(G.fibre_of(identity), self.source)),
                                  NUMPY_MODULES)
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
            idx = part.index[o]
            state[idx[idx >= 0]] = arr[idx >= 0] - part.fixed[idx >= 0]
        values = state[self.source_pos]
        if np.isnan(values).any():
            raise InputNameError(f"{self.name}: the configuration needs {names}")
        return values

    def solve(self, configuration, momentum: Sequence, params: np.ndarray,
              tol: float = 1e-14, max_iterations: int = 50) -> np.ndarray:
        """The flat initial state (g₁, λ₁) for base point ``configuration`` and ``momentum``."""
        q = self._source_values(configuration)
        p = _numeric(momentum, "the momentum", self.name).ravel()
        if p.size != self.rank:
            raise ShapeError(f"{self.name}: the momentum has {self.rank} components (one per "
                             f"basis section), got {p.size}")
        for label, values in (("configuration", q), ("momentum", p)):
            if not np.isfinite(values).all():
                raise DomainError(f"{self.name}: non-finite {label} {values.tolist()}")
        z = np.concatenate([np.asarray(self._guess(q), float).ravel(), np.zeros(self.m)])
        previous = np.inf
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
            if converged(dz, previous, z, tol):
                break
            previous = float(np.abs(dz).max())
        else:
            raise NewtonDivergenceError(f"{self.name}: no initial state found for this momentum "
                                        f"in {max_iterations} Newton iterations", step=0,
                                        residual_norm=float(np.abs(F).max()), iterate=z)
        state = np.empty(self.layout.n_known)
        state[self.arrow_pos] = np.asarray(self._arrow(z[:self.rank], q), float).ravel()
        state[self.lam_pos] = z[self.rank:]
        return state


class SecondOrderMomentumInitializer:
    """Initial state of a second-order step from a velocity-like arrow g₀ and a momentum.

    With the second-order transforms on the window (g₀, g₁, g₂) (multipliers λ₀, λ₁ of the
    terms (g₀, g₁), (g₁, g₂); ``second_order_legendre_forms``), solve

        F⁻[L + λ·Φ](g₀, g₁, g₂) = p₀ (2·rank components),   Φ(g₀, g₁) = Φ(g₁, g₂) = 0,

    for the fibre chart coordinates of g₁, g₂ and λ₀, λ₁.  The result is the step's known
    state (g_{k-1}, g_k, g_{k+1}, λ_{k-1}, λ_k) = (g₀, g₁, g₂, λ₀, λ₁).
    """

    def __init__(self, step, layout: StateLayout):
        from ..derivation._momenta import second_order_legendre_forms
        from ..derivation._step import chart_of, named, next_arrow

        system = step.system
        G, fs = step.groupoid, system._fs
        self.name, self.layout, self.rank = step.name, layout, G.rank
        self.groupoid = G
        self.m = len(fs.constraints)
        forms = second_order_legendre_forms(G, fs, offset=-1)
        g0 = named(G, -1, False)
        g1 = next_arrow(G, g0, 0, False)
        g2 = next_arrow(G, g1, 1, False)
        fib1, chart1, cmap1 = chart_of(G, 0, G.target(g0))
        fib2, chart2, cmap2 = chart_of(G, 1, G.target(g1))
        lam = list(forms.multipliers)
        p = [sp.Dummy(f"p{a}") for a in range(2 * self.rank)]
        eqs = [e - pi for e, pi in zip(forms.minus, p)]
        for a, b in ((g0, g1), (g1, g2)):
            eqs += fs.rows_on(G, [a, b])
        # differentiate through the charts, keeping the fibre variables as intermediates
        fibres, charts = list(fib1) + list(fib2), list(chart1) + list(chart2)
        sub = {**cmap1, **cmap2}
        E = sp.Matrix(eqs)
        args = [fibres + lam, list(g0), p, list(step.parameters)]
        self._F = sp.lambdify(args, E, NUMPY_MODULES, cse=True)
        self._J = sp.lambdify(args, E.jacobian(fibres + lam), NUMPY_MODULES, cse=True)
        values = sp.Matrix([sub.get(f, f) for f in fibres])
        self._fibres = sp.lambdify([charts], values, NUMPY_MODULES)
        self._dfibres = sp.lambdify([charts], values.jacobian(charts), NUMPY_MODULES)
        self.n_fibre, self.n_chart = len(fibres), len(charts)
        if [str(s) for s in step.knowns] != [str(s) for s in (*g0, *fib1, *fib2, *lam)]:
            raise RuntimeError(f"{step.name}: second-order state layout mismatch")
        self._guess = sp.lambdify([list(g0)], list(G.predict_chart(g0)), NUMPY_MODULES)

    def _residual(self, z, g0, p, params):
        x, lam = z[:self.n_chart], z[self.n_chart:]
        f = np.asarray(self._fibres(x), float).ravel()
        w = np.concatenate([f, lam])
        F = np.asarray(self._F(w, g0, p, params), float).ravel()
        Jw = np.asarray(self._J(w, g0, p, params), float).reshape(len(F), len(w))
        C = np.asarray(self._dfibres(x), float).reshape(self.n_fibre, self.n_chart)
        J = np.hstack([Jw[:, :self.n_fibre] @ C, Jw[:, self.n_fibre:]])
        return F, J, np.concatenate([g0, f, lam])

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
        guess = np.asarray(self._guess(g0), float).ravel()
        z = np.concatenate([guess, guess, np.zeros(2 * self.m)])
        previous = np.inf
        for _ in range(max_iterations):
            F, J, state = self._residual(z, g0, p, params)
            if not (np.isfinite(F).all() and np.isfinite(J).all()):
                raise NewtonDivergenceError(f"{self.name}: non-finite values solving for the "
                                            "initial state from the momentum", step=0,
                                            residual_norm=float(np.abs(F).max()), iterate=z)
            try:
                dz = np.linalg.solve(J, F)
            except np.linalg.LinAlgError:
                raise SingularJacobianError(f"{self.name}: F⁻L is not invertible here",
                                            step=0, residual_norm=float(np.abs(F).max()),
                                            iterate=z) from None
            z = z - dz
            if converged(dz, previous, z, tol):
                return self._residual(z, g0, p, params)[2]
            previous = float(np.abs(dz).max())
        raise NewtonDivergenceError(f"{self.name}: no initial state found for this momentum",
                                    step=0, residual_norm=float(np.abs(F).max()), iterate=z)
