"""StepEquations: the residuals of one step, with unknowns, knowns, Jacobian and LaTeX."""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
import sympy as sp

from .._arguments import flag_argument, instance_argument, real_array
from .._errors import (
    DomainError,
    InputNameError,
    InputTypeError,
    ShapeError,
    UnsupportedFeatureError,
)
from .._parameters import parameter_vector
from .._symbols import multiplier_symbols, parse_step, step_label
from ..derivation import DerivedStep


class StepEquations:
    """The equations of one step of a discrete system, F(unknowns; knowns, parameters) = 0.

    Attributes
    ----------
    residuals : list of SymPy expressions, one per equation: the DEL for each basis section
        (X⃖[L + λ_k·φ](g_k) − X⃗[L + λ_{k+1}·φ](g_{k+1})), the stage rows ∂L/∂ζ of a
        Lagrangian with internal stages (docs/conventions.md §22), then the constraints
        φ(g_{k+1}) and the holonomic constraints ψ(β(g_{k+1})).
        They are written in the named fibre variables of the unknown arrow (e.g. the matrix
        entries of g_{k+1}), which :attr:`reconstruction` expresses in the unknowns.
    unknowns : chart coordinates of the unknown arrow, the internal stages ζ_k, ζ_{k+1}
        (if any), then the multipliers λ_{k+1}.
    knowns : coordinates of the known arrows (g_k; second order g_{k-1}, g_k, g_{k+1}),
        then the known multipliers.
    parameters : the declared parameters (step size, masses, …).
    inputs : the input symbols of a forced system (docs/conventions.md §20); its knowns end
        with the inputs u_k of the known arrow, then the inputs u_{k+1} of the new arrow.
    """

    def __init__(self, derived: DerivedStep):
        instance_argument(derived, DerivedStep, "derived", "a DerivedStep (the equations of "
                          "a step come from system.euler_lagrange())", owner="StepEquations")
        derived.build_graph()
        self._d = derived
        self.name: str = derived.name
        self.groupoid = derived.groupoid
        self.order: int = derived.order
        self.unknowns: list[sp.Symbol] = (list(derived.chart_unknowns)
                                          + list(derived.stage_unknowns)
                                          + list(derived.multipliers_next))
        #: the internal stages ζ_k, ζ_{k+1} of a discrete Lagrangian with internal stages
        #: (unknowns of the step, never part of the state; docs/conventions.md §22)
        self.stages: list[sp.Symbol] = list(derived.stage_unknowns)
        self.knowns: list[sp.Symbol] = list(derived.knowns)
        self.parameters: list[sp.Symbol] = list(derived.parameters)
        self.inputs: list[sp.Symbol] = list(derived.inputs)
        self.reconstruction: dict = dict(derived.chart_map)
        self.next_knowns: list[sp.Expr] = list(derived.next_knowns)
        self.n_constraints: int = derived.n_constraints
        #: the last ``n_holonomic`` constraints are holonomic: ψ at the target of the newest
        #: arrow, with the multipliers at its source (docs/conventions.md §15)
        self.n_holonomic: int = derived.n_holonomic
        self.prediction: list[sp.Expr] = list(derived.prediction)
        self._n = derived.n_equations or len(derived.sympy_residuals())
        self._structured: list | None = None
        self._structured_source = None  # computes the matrix-preserving forms on request
        self.system = None  # the DiscreteSystem that derived these equations, if any

    # --- sizes ------------------------------------------------------------------------------
    def __len__(self) -> int:
        return self._n

    @property
    def residuals(self) -> list[sp.Expr]:
        """The residuals as exact SymPy expressions (built on first request; code generation
        and numerics use :attr:`program` and never need them)."""
        return self._d.sympy_residuals()

    @property
    def structured(self) -> list | None:
        """The residuals with matrix parts kept as matrices (for LaTeX), verified to equal
        :attr:`residuals`; None when there is no such form.  Built on first request."""
        if self._structured_source is not None:
            source, self._structured_source = self._structured_source, None
            self._structured = source(self.residuals)
        return self._structured

    @structured.setter
    def structured(self, value: list | None) -> None:
        self._structured, self._structured_source = value, None

    def set_structured_source(self, source) -> None:
        """Defer the matrix form: ``source(explicit residuals) -> list | None``."""
        self._structured, self._structured_source = None, source

    @functools.cached_property
    def program(self):
        """The step as a program over the expression graph: inputs ``u`` (unknowns),
        ``known``, ``p``; outputs ``F`` (residuals), ``J`` (exact Jacobian, row-major),
        ``fibre`` (the chart), ``predict``, ``next_knowns`` and ``domain`` (the values of
        the window's terms defined on part of the real line only, :attr:`domain_kinds`)."""
        from ._programs import step_program

        return step_program(self)

    @property
    def domain_kinds(self) -> list[str]:
        """What each value of the program's ``domain`` output needs, in words, and on which
        term of the window ("log: its argument positive (the new arrow's term)"): a step's
        solution is accepted only where they are all finite (docs/conventions.md §11)."""
        window = self._d.window
        return list(window.domain_kinds) if window is not None else []

    @functools.cached_property
    def velocity_momentum(self):
        """For a system discretised from a :class:`ContinuousSystem`: the program of its
        continuous Legendre transform p = ∂L/∂v (inputs ``q``, ``v``, ``p``; output
        ``momentum``), which starts a trajectory from a configuration and a velocity
        (:meth:`Simulator.from_velocity`); None for other systems."""
        if getattr(self.system, "continuous", None) is None:
            return None
        from ._continuous import velocity_momentum_program

        return velocity_momentum_program(self.system)

    def input_jacobian(self, unknowns: Sequence, knowns: Sequence,
                       params: Sequence | dict = ()) -> np.ndarray:
        """∂F/∂(u_k, u_{k+1}) of a forced step at a point: (len(self), 2m), the columns of
        the inputs of the known arrow, then of the new arrow (docs/conventions.md §20); a
        second-order step's: (len(self), 3m), the inputs u_{k−1}, u_k of the known pairs,
        then u_{k+1} of the new pair."""
        m = len(self.inputs)
        if not m:
            raise UnsupportedFeatureError(f"{self.name}: the system has no inputs")
        u, k, p = self._point("input_jacobian", unknowns, knowns, params, batch=False)
        with np.errstate(all="ignore"):
            (J,) = self._input_jacobian_function(u, k, p)
        self._finite_result("input_jacobian", "∂F/∂u", J)
        return np.asarray(J, float).reshape(len(self), (self.order + 1) * m)

    @functools.cached_property
    def _input_jacobian_function(self):
        """The NumPy function of ∂F/∂(inputs), built once (a controller linearises every
        step)."""
        from ._programs import input_jacobian_program

        return input_jacobian_program(self).numpy_function(["J_inputs"], ["u", "known", "p"])

    @property
    def fibre_unknowns(self) -> tuple:
        """Named fibre variables of the unknown arrow (the symbols the residuals use)."""
        return self._d.fibre_unknowns

    @property
    def arrows(self) -> dict:
        """Named coordinates of the arrows in the step, by offset from k."""
        return dict(self._d.arrows)

    # --- symbols ----------------------------------------------------------------------------
    def symbol(self, name: str, step: str | int):
        """The SymPy symbol (or matrix, or multiplier list) named ``name`` at ``step``.

        ``step.symbol("x", "k+1")``, ``step.symbol("g", "k")`` (a Matrix for a group part
        named "g"), ``step.symbol("lambda", "k+1")`` (list of (λ_{k+1})_a).
        """
        offset = self._offset(step)
        if not isinstance(name, str):
            raise InputTypeError(f"{self.name}: a symbol's name must be a string, got "
                                 f"{type(name).__name__} {name!r}")
        if name in ("lambda", "λ", "multipliers"):
            return multiplier_symbols(self.n_constraints, offset)
        table = self.groupoid.symbols_by_name(offset)
        if not isinstance(name, str) or name not in table:
            raise InputNameError(f"{self.name}: no coordinate named {name!r}; known names: "
                                 f"{', '.join(sorted(table) + ['lambda'])}")
        return table[name]

    def _offset(self, step) -> int:
        """The offset from k of ``step`` ("k", "k+1", "k-1" or an int) among those of the
        step's symbols: from the source of its first arrow to its newest arrow."""
        first, newest = self._d.offsets
        if isinstance(step, bool) or not isinstance(step, (str, int, np.integer)):
            raise InputTypeError(f"{self.name}: step must be 'k', 'k+1', 'k-1', … or an "
                                 f"integer offset, got {type(step).__name__} {step!r}")
        try:
            offset = parse_step(step if isinstance(step, str) else int(step))
        except ValueError as err:
            raise ShapeError(f"{self.name}: {err}") from None
        if not first - 1 <= offset <= newest:
            raise ShapeError(f"{self.name}: the step's symbols run from "
                             f"{step_label(first - 1)} to {step_label(newest)}; got "
                             f"{step_label(offset)}")
        return offset

    # --- residuals in the unknowns ----------------------------------------------------------
    def residuals_in_unknowns(self) -> list[sp.Expr]:
        """Residuals with the reconstruction substituted: functions of the unknowns only."""
        return [r.xreplace(self.reconstruction) for r in self.residuals]

    @functools.cached_property
    def _jacobian(self) -> sp.Matrix:
        fibre = list(self.fibre_unknowns)
        chart = list(self._d.chart_unknowns)
        rest = list(self.stages) + list(self._d.multipliers_next)
        R = sp.Matrix(self.residuals)
        C = sp.Matrix([self.reconstruction.get(f, f) for f in fibre])
        Jx = R.jacobian(fibre) * C.jacobian(chart) if chart else sp.zeros(len(R), 0)
        Jl = R.jacobian(rest) if rest else sp.zeros(len(R), 0)
        return sp.Matrix.hstack(Jx, Jl)

    def jacobian(self, substitute: bool = False) -> sp.Matrix:
        """Exact ∂F/∂(unknowns), through the α-fibre chart.

        The entries use the fibre variables of the unknown arrow (as the residuals do);
        ``substitute=True`` replaces them by the chart (functions of the unknowns only).
        """
        substitute = flag_argument(substitute, "substitute", owner=self.name)
        J = self._jacobian
        return J.xreplace(self.reconstruction) if substitute else J

    # --- numerics -----------------------------------------------------------------------------
    def evaluate(self, unknowns: Sequence, knowns: Sequence, params: Sequence | dict = ()):
        """Numeric residual and Jacobian at a point (NumPy evaluation of :attr:`program`).

        Arrays may carry a trailing batch axis: unknowns (n_u, B), knowns (n_k, B), …
        give F (n, B) and J (n, n_u, B).  The arguments are checked first (:meth:`_point`:
        :class:`ShapeError`, :class:`DomainError`, :class:`ParameterError`), and a value
        that is not finite at finite arguments is a :class:`DomainError`, never returned;
        so for :meth:`advance` and :meth:`input_jacobian`.
        """
        u, k, p = self._point("evaluate", unknowns, knowns, params)
        f = self.program.numpy_function(["F", "J"], ["u", "known", "p"])
        with np.errstate(all="ignore"):
            F, J = f(u, k, p)
        self._finite_result("evaluate", "the residual F or its Jacobian J", F, J)
        return F, J.reshape((len(self), len(self.unknowns)) + J.shape[1:])

    def advance(self, unknowns: Sequence, knowns: Sequence, params: Sequence | dict = ()):
        """The next known state from a solved step (g_{k+1}, λ_{k+1} become the knowns)."""
        u, k, p = self._point("advance", unknowns, knowns, params)
        f = self.program.numpy_function(["next_knowns"], ["u", "known", "p"])
        with np.errstate(all="ignore"):
            (after,) = f(u, k, p)
        self._finite_result("advance", "the next known state", after)
        return after

    def _finite_result(self, entry: str, what: str, *values) -> None:
        """A :class:`DomainError` when ``values`` (what an evaluation at finite arguments
        gave) are not all finite: the arguments overflow the equations' arithmetic or leave
        the domain of their functions."""
        if not all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in values):
            raise DomainError(f"{self.name}.{entry}: {what} is not finite at the unknowns, "
                              f"knowns and parameters given: its values overflow, or leave "
                              f"the domain of the equations' functions (a square root of a "
                              f"negative number, a division by zero)")

    def _point(self, entry: str, unknowns, knowns, params, *, batch: bool = True
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The arguments of a NumPy evaluation, checked before anything is evaluated: the
        unknowns and knowns as real arrays of this step's lengths (``batch``: with a
        trailing batch axis allowed, the same for both) and finite, else a
        :class:`ShapeError` or :class:`DomainError`; the parameters by name or in order,
        finite and with their symbols' assumptions, else a :class:`ParameterError`."""
        owner = f"{self.name}.{entry}"
        arrays = []
        for name, value, want in (("unknowns", unknowns, len(self.unknowns)),
                                  ("knowns", knowns, len(self.knowns))):
            arr = real_array(value, name, owner=owner)
            if arr.ndim not in ((1, 2) if batch else (1,)) or arr.shape[0] != want:
                shape = f"({want},) or ({want}, B)" if batch else f"({want},)"
                raise ShapeError(f"{owner}: {name} must have shape {shape}, got shape "
                                 f"{arr.shape}")
            if not np.isfinite(arr).all():
                raise DomainError(f"{owner}: {name} has non-finite entries")
            arrays.append(arr)
        if arrays[0].shape[1:] != arrays[1].shape[1:]:
            raise ShapeError(f"{owner}: unknowns of shape {arrays[0].shape} and knowns of "
                             f"shape {arrays[1].shape} differ in their batch axis")
        p, _ = parameter_vector(self.parameters, params, owner=owner)
        return arrays[0], arrays[1], p

    # --- code generation and runtime (layers 4 and 5) ----------------------------------------
    def emit_c(self, path, **options):
        """Write ``path.c`` and ``path.h``: residual, Jacobian, chart and Newton stepper in C99."""
        from .. import codegen  # a convenience that looks up (docs/architecture.md)

        return codegen.emit_c(self, path, **options)

    def compile(self, **options):
        """Compile the C kernels with cffi (cached) and return a :class:`Simulator`."""
        from .. import runtime  # a convenience that looks up (docs/architecture.md)

        return runtime.compile_step(self, **options)

    # --- LaTeX --------------------------------------------------------------------------------
    def latex(self, document: bool = False, abbreviations=None, width=None) -> str:
        """The equations as a LaTeX ``align`` environment (or a standalone document).

        Printed in the papers' style (``equations/_printing.py``): named pieces (midpoints,
        difference quotients) where L is written with them, ``abbreviations``
        (``{name: expression or callable of an arrow}``) where they occur, terms collected by
        multipliers and parameters, rows broken to a page whose text is ``width`` pt wide
        (default 450, room left for the equation numbers), then a "where" list; every
        printed equation is verified to be the residual.  ``document``: a standalone
        article with that text width, displays breaking across pages, a line too wide to
        break set smaller.  Abbreviations that do not occur are reported with an
        :class:`~symgroupoid.UnusedAbbreviationWarning`.
        """
        from ._latex import step_latex

        return step_latex(self, document=document, abbreviations=abbreviations, width=width)

    def _repr_latex_(self) -> str | None:
        """The equations typeset in Jupyter, for steps whose residual program has at most
        ``DISPLAY_LIMIT`` operations (the printing derives and verifies SymPy forms, which
        large systems should not pay for on display); None (the plain repr) otherwise —
        :meth:`latex` prints any step on request."""
        from ._latex import DISPLAY_LIMIT, step_latex_aligned

        if self.program.size(["F"]) > DISPLAY_LIMIT:
            return None
        return step_latex_aligned(self)

    def __repr__(self) -> str:
        return (f"<StepEquations {self.name!r}: {len(self)} equations in "
                f"{len(self.unknowns)} unknowns on {self.groupoid.name}>")
