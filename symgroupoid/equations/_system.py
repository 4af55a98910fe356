"""DiscreteSystem: a groupoid, a discrete Lagrangian and constraints."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import sympy as sp

from .._errors import CallableError
from ..derivation._first_order import (
    evaluate_system,
    first_order_matrix_form,
    first_order_step,
)
from ..groupoids import Groupoid
from ._step import StepEquations


class DiscreteSystem:
    """A discrete constrained Lagrangian system (G, N, L) (seed 000 Def. 3.2).

    Parameters
    ----------
    groupoid : the Lie groupoid G ⇉ Q.
    lagrangian : callable ``L(g) -> expr`` on a symbolic arrow.
    constraints : optional callable ``φ(g) -> [expr, …]``; N = {φ = 0}.
    parameters : symbols the expressions may use besides the arrow's coordinates.
    name : used in messages and generated code.
    """

    def __init__(self, groupoid: Groupoid, lagrangian: Callable,
                 constraints: Callable | None = None, parameters: Sequence[sp.Symbol] = (),
                 name: str = "system"):
        if not isinstance(groupoid, Groupoid):
            raise TypeError(f"{name}: groupoid must be a symgroupoid Groupoid, got "
                            f"{type(groupoid).__name__}")
        self.groupoid, self.name = groupoid, name
        self.lagrangian, self.constraints = lagrangian, constraints
        self.parameters = list(parameters)
        self._fs = evaluate_system(name, groupoid, lagrangian, constraints, self.parameters)

    @property
    def n_constraints(self) -> int:
        return len(self._fs.constraints)

    def euler_lagrange(self) -> StepEquations:
        """The step (g_k, λ_k) → (g_{k+1}, λ_{k+1}) (seed 000 §3.3; EQUATIONS.md §4)."""
        step = StepEquations(first_order_step(self.name, self.groupoid, self._fs,
                                              self.parameters))
        step.system = self
        try:
            step.structured = first_order_matrix_form(
                self.name, self.groupoid, self.lagrangian, self.constraints, self.parameters,
                step.residuals)
        except CallableError:
            step.structured = None  # user code needs explicit matrices: print entries
        return step

    def __repr__(self) -> str:
        return (f"DiscreteSystem({self.name!r} on {self.groupoid.name}, "
                f"{self.n_constraints} constraints)")
