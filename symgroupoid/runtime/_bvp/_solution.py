"""The solution of a two-point problem: arrows, multipliers, cost and the second-order
condition (computed when first asked for)."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from ..._arguments import counted
from .._banded import Inertia
from ._inertia import _inertia_at


@dataclass
class BoundaryValueSolution:
    """A solved two-point problem: arrows g_1 … g_N, multipliers per term, and diagnostics.

    ``arrows`` (N, arrow_dim); ``multipliers`` (terms, m) — the costates of optimal control;
    ``controls`` (N, rank) — chart coordinates of each arrow (Lie groups: τ⁻¹(g_k) = hξ_k);
    ``configurations`` — the N + 1 configurations from ``origin``, the first, along the
    arrows; ``sol[name]`` — a named part of every arrow (``"x"``: the target point of each
    arrow; ``"g"``: each arrow's matrix; …).

    What was found: ``cost`` — the discrete cost Σ_k L_d (the action without the multiplier
    terms, which vanish on the constraints); ``inertia`` — (positive, negative, zero)
    eigenvalue counts of the Hessian of the action restricted to the admissible variations
    (the junction variations δ_j, which keep the ends and the composability) and, with
    constraints, to those tangent to Φ = 0: the Hessian of the Lagrangian on the tangent
    space of the constraints (see :func:`_reduced_inertia`), or None when it is singular to
    rounding; ``is_local_minimum``; ``method`` — the iterations used.

    A forced system (docs/conventions.md §20): ``inputs`` — the inputs of every term the
    solve used (None without inputs); ``forced`` — True, and then there is no second-order
    condition (``inertia`` and ``is_local_minimum`` are None): the solution is a critical
    point of the Lagrange–d'Alembert principle, not of the action, and ``cost`` is Σ_k L_d
    along it, which it does not extremise.

    Internal stages (docs/conventions.md §22): ``stages`` — (N, n_stages), the stages ζ_k
    of every arrow at the solution (they solve its stage rows; None without stages); the
    state of the trajectory is the arrows alone.  There is no second-order condition
    (``inertia`` and ``is_local_minimum`` are None); ``cost`` is Σ_k L(g_k, ζ_k) = Σ_k L_d(g_k).

    The configurations and the second-order condition are computed when first asked for
    (the inertia from the KKT matrix re-assembled at the solution, the same matrix the
    solve ended with), so a solve whose caller needs neither does not pay for them.
    """

    system: object
    arrows: np.ndarray
    multipliers: np.ndarray
    origin: object
    parameters: dict
    iterations: int
    residual_norm: float
    history: list = field(default_factory=list)
    seconds: float = 0.0
    cost: float = float("nan")
    #: (the inertia,) once known, () until then (see :attr:`inertia`)
    second_order: tuple = ()
    method: str = "Newton"
    inputs: np.ndarray | None = None
    forced: bool = False
    stages: np.ndarray | None = None

    @property
    def steps(self) -> int:
        return len(self.arrows)

    @functools.cached_property
    def configurations(self) -> list:
        """The N + 1 configurations from :attr:`origin` along the arrows."""
        return self.system.groupoid.configurations_from(self.origin, self.arrows)

    @property
    def inertia(self) -> Inertia | None:
        """(positive, negative, zero) eigenvalue counts of the reduced Hessian (see the class
        docstring), or None when it is singular to rounding."""
        if self.forced or self.stages is not None:
            return None
        if not self.second_order:
            p = np.array([self.parameters[str(q)] for q in self.system.parameters], float)
            self.second_order = (_inertia_at(self.system, self.arrows, self.multipliers, p),)
        return self.second_order[0]

    @functools.cached_property
    def controls(self) -> np.ndarray:
        G = self.system.groupoid
        return np.array([G.fibre_chart_inverse(G.fibre_of(a), G.source(a))
                         for a in self.arrows], float)

    def __getitem__(self, name: str) -> np.ndarray:
        G = self.system.groupoid
        table = G.symbols_by_name(0)
        if name not in table:
            raise KeyError(f"no part named {name!r}; available: {sorted(table)}")
        position = {s: i for i, s in enumerate(G.named_arrow(0)) if isinstance(s, sp.Symbol)}
        value = table[name]
        entries = value if isinstance(value, sp.MatrixBase) else sp.Matrix([value])
        out = np.empty((len(self.arrows),) + entries.shape)
        for idx in np.ndindex(*entries.shape):
            e = entries[idx]
            out[(slice(None),) + idx] = (self.arrows[:, position[e]] if e in position
                                         else float(e))
        return out if isinstance(value, sp.MatrixBase) else out[:, 0, 0]

    @property
    def is_local_minimum(self) -> bool | None:
        """True: a strict local minimum of the cost among admissible paths that keep the
        constraints (the reduced Hessian is positive definite: the second-order sufficient
        condition); False: not a minimum (the reduced Hessian has a negative eigenvalue, so
        some admissible variation lowers the cost: a saddle or a maximum); None: not decided
        at second order (the reduced Hessian or the KKT matrix is singular to rounding)."""
        if self.inertia is None:
            return None
        return self.inertia.negative == 0

    @property
    def kind(self) -> str:
        """What the second-order condition says, in words (see :attr:`is_local_minimum`)."""
        if self.forced:
            return ("no second-order condition (forced: a critical point of the "
                    "Lagrange–d'Alembert principle, not of the action)")
        if self.stages is not None:
            return "no second-order condition (internal stages)"
        if self.inertia is None:
            return "undetermined (the reduced Hessian is singular to rounding)"
        k = self.inertia.negative
        if k == 0:
            return "local minimum"
        return f"NOT a local minimum: a saddle with {k} descent direction{'s' if k > 1 else ''}"

    def __repr__(self) -> str:
        return (f"<BoundaryValueSolution {self.system.name!r}: {self.steps} arrows, "
                f"{counted(self.iterations, 'iteration')} ({self.method}), |F| = "
                f"{self.residual_norm:.2e}, cost {self.cost:.10g}, {self.kind}>")

