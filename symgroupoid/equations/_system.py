"""DiscreteSystem: a groupoid, a discrete Lagrangian and constraints."""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Callable, Sequence

import sympy as sp

from .._arguments import (
    MAX_DIMENSION,
    choice_argument,
    counted,
    instance_argument,
    integer_argument,
    name_argument,
    sequence_argument,
)
from .._collector import collector_paused
from .._errors import (
    CallableError,
    DomainError,
    InputNameError,
    InputTypeError,
    ShapeError,
    UnsupportedFeatureError,
)
from .._progress import reported
from .._symbols import multiplier_symbols, scalar_expression
from ..derivation import (
    NONHOLONOMIC_METHODS,
    NoetherForms,
    SystemFunctions,
    call_user,
    check_metric,
    check_nonholonomic_dimensions,
    check_symbols,
    check_values,
    conserved_quantities,
    energy_momentum_step,
    evaluate_system,
    impulse_form,
    impulse_section,
    input_arguments,
    input_symbols,
    junction_step,
    legendre_forms,
    lie_poisson_forms,
    matrix_form_residuals,
    may_be_step,
    named,
    noether_ends,
    noether_forms,
    nonholonomic_step,
    pair_impulse_form,
    time_step_candidates,
    vanishes_on_restriction,
    vanishing_check,
)
from ..groupoids import Groupoid
from ._forcing import check_force_step
from ._momenta import LegendreTransforms, LiePoissonEquations, NoetherQuantity
from ._programs import RestrictedArrows, holonomic_projection_program, noether_nodes
from ._regularity import check_step
from ._step import StepEquations


def system_arguments(name, groupoid, parameters) -> tuple[str, Groupoid, list]:
    """The name (a non-empty string), the groupoid (a :class:`Groupoid`) and the parameters
    (a list or tuple; its entries are checked to be SymPy symbols with the expressions) of
    a system, or a :class:`~symgroupoid.SymgroupoidError` naming the argument."""
    name = name_argument(name, "the system's name", owner="system")
    instance_argument(groupoid, Groupoid, "groupoid", "a symgroupoid Groupoid (e.g. "
                      "PairGroupoid(EuclideanSpace('q')), SO3('W'))", owner=name)
    if isinstance(parameters, sp.Symbol):
        parameters = [parameters]
    return name, groupoid, sequence_argument(parameters, "parameters", owner=name)


def time_step_argument(name: str, groupoid: Groupoid, time_step, parameters: Sequence
                       ) -> sp.Symbol | None:
    """The declared time step: a parameter (its symbol or name) that may be a positive real
    number; None when not declared.  A time groupoid has no step parameter (its step is each
    arrow's t₁ − t₀, docs/conventions.md §7)."""
    if time_step is None:
        return None
    if groupoid.timed:
        raise UnsupportedFeatureError(
            f"{name}: on the time groupoid {groupoid.name} the time step is each arrow's "
            f"t₁ − t₀ (g.step), an unknown of the step, not a parameter; leave time_step= "
            f"out (its energy is −∂L/∂t₁, docs/conventions.md §7)")
    if not isinstance(time_step, (str, sp.Symbol)):
        raise InputTypeError(f"{name}: time_step must be the step parameter (a SymPy symbol of "
                             f"the parameters, or its name), got {type(time_step).__name__} "
                             f"{time_step!r}")
    by_name = {str(p): p for p in parameters}
    symbol = by_name.get(str(time_step))
    if symbol is None:
        raise InputNameError(f"{name}: time_step={str(time_step)!r} is not one of the "
                             f"parameters ({', '.join(by_name) or 'none'}); declare it in "
                             f"parameters=[...]")
    if not may_be_step(symbol):
        raise DomainError(f"{name}: time_step={symbol} is declared integer, zero or "
                          f"negative; a time step is a positive real number")
    return symbol


def distribution_elements(name: str, groupoid: Groupoid, distribution,
                          parameters: Sequence = ()) -> list:
    """The basis of D_c: a list whose elements are lists of section coefficients or
    functions of the base point returning them.  Each function is called once here on a
    symbolic base point, so that one that raises, or coefficients that are not finite real
    expressions or use symbols that are neither the base point's nor declared parameters,
    are reported now with the element's index."""
    elements = sequence_argument(distribution, "distribution", owner=name)
    q = tuple(sp.Dummy(f"q{i}", real=True) for i in range(groupoid.base_dim))
    for i, element in enumerate(elements):
        what = f"distribution element {i}"
        if callable(element):
            what = f"{what} (the value of its function)"
            element = call_user(name, what, element, q)
        _coefficients(name, what, element, groupoid.rank)
        check_symbols(name, what, [sp.sympify(c) for c in element], q, parameters)
    return elements


def _coefficients(name: str, what: str, value, rank: int) -> None:
    """Check one element of D_c given as coefficients: a list or matrix of ``rank``
    finite real expressions (an :class:`InputTypeError` or :class:`ShapeError` otherwise)."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, sp.MatrixBase)):
        raise InputTypeError(f"{name}: {what} must be a list of {rank} section coefficients "
                             f"or a function of the base point returning one, got "
                             f"{type(value).__name__} {value!r}")
    entries = list(value)
    for j, entry in enumerate(entries):
        if scalar_expression(entry) is None:
            raise InputTypeError(f"{name}: {what}, coefficient {j} is not a real expression: "
                                 f"{type(entry).__name__} {entry!r}")
    check_values(name, what, entries)
    if len(entries) != rank:
        raise ShapeError(f"{name}: {what} has {len(entries)} coefficients; the algebroid "
                         f"has rank {rank}")


def forces_argument(name: str, forces, arity: int = 1):
    """The discrete forces of a system, or None: first order ``f(g) -> (f_minus, f_plus)``,
    second order ``f(g1, g2) -> (f0, f1, f2)`` (docs/conventions.md §20)."""
    if forces is None:
        return None
    if not callable(forces):
        example = ("a function of the arrow returning (f_minus, f_plus), e.g. lambda g: "
                   "([...], [...])" if arity == 1 else
                   "a function of the pair returning (f0, f1, f2), e.g. lambda g1, g2: "
                   "([...], [...], [...])")
        raise CallableError(f"{name}: forces must be {example}; got a "
                            f"{type(forces).__name__}")
    return forces


def _replaced(value, mapping: dict):
    """``value`` (nested lists and tuples of SymPy objects) with ``mapping`` applied."""
    if isinstance(value, (list, tuple)):
        return type(value)(_replaced(v, mapping) for v in value)
    return value.xreplace(mapping) if isinstance(value, sp.Basic) else value


def _flat(value):
    """The leaves of nested lists and tuples."""
    if isinstance(value, (list, tuple)):
        for v in value:
            yield from _flat(v)
    else:
        yield value


def _canonical_dummies(parts: list, ordered: list) -> dict:
    """The Dummy symbols of ``parts`` (slot, stage and base coordinates, fresh in every
    system) mapped to plain symbols numbered by position: first those of ``ordered``
    (nested sequences, in order), then the others by name."""
    first = [v for v in _flat(ordered) if isinstance(v, sp.Dummy)]
    found = set().union(*(v.atoms(sp.Dummy) for v in _flat(parts) if isinstance(v, sp.Basic)))
    rest = sorted(found - set(first), key=lambda d: (d.name, d.dummy_index))
    return {d: sp.Symbol(f"_{k}", **d.assumptions0)
            for k, d in enumerate(dict.fromkeys(first + rest))}


class _EvaluatedSystem:
    """A system whose Lagrangian and constraints were evaluated on slot arrows."""

    _functions: SystemFunctions

    @property
    def functions(self) -> SystemFunctions:
        """L_d and the constraints Φ = (φ, ψ∘α) on the slot arrows, ψ at a base point and
        the rows a step imposes (:class:`~symgroupoid.derivation.SystemFunctions`; seed 000
        §3.3, docs/conventions.md §15)."""
        return self._functions

    @property
    def _fs(self) -> SystemFunctions:
        """Deprecated alias of :attr:`functions`, kept while readers move to it."""
        return self._functions

    @functools.cached_property
    def fingerprint(self) -> str:
        """A digest of what the system's equations are built from: its kind and name,
        parameters, L_d, constraints, holonomic constraints, internal stages and forces on
        the slot arrows (SHA-256 of their SymPy ``srepr``, the same in every process).  Two
        systems with the same fingerprint derive the same equations; a Noether quantity
        refuses the run of a system with another (two systems may share a name)."""
        functions = self.functions
        parts = [type(self).__name__, self.name, list(self.parameters), functions.slots,
                 functions.lagrangian, functions.constraints, functions.holonomic,
                 functions.rows, functions.stages]
        forces = functions.forces
        if forces is not None:
            parts.append((forces.inputs, forces.nodes, forces.stage_forces))
        parts.extend(getattr(self, extra, None) for extra in ("distribution", "method"))
        canonical = _canonical_dummies(parts, [functions.slots, functions.stages,
                                               functions.base])
        digest = hashlib.sha256()
        for part in parts:
            data = (part if isinstance(part, str)
                    else sp.srepr(sp.sympify(part).xreplace(canonical)
                                  if isinstance(part, sp.Basic) else _replaced(part, canonical))
                    ).encode()
            digest.update(len(data).to_bytes(8, "little"))
            digest.update(data)
        return digest.hexdigest()


class DiscreteSystem(_EvaluatedSystem):
    """A discrete constrained Lagrangian system (G, N, L) (seed 000 Def. 3.2).

    On a Lie groupoid G ⇉ Q, with a discrete Lagrangian L: G → R and the constraints
    N = {φ = 0} ⊂ G, a motion is a composable sequence of arrows g_1, g_2, …
    (β(g_k) = α(g_{k+1})) in N that makes the action Σ_k L(g_k) stationary among such
    sequences with the same product.  Its variations move one junction at a time,
    g_k ↦ g_k·h_X(t), g_{k+1} ↦ h_X(t)⁻¹·g_{k+1}, along a curve h_X in the α-fibre through
    the identity that represents a section X of the Lie algebroid, and give the discrete
    Euler–Lagrange equations with multipliers λ (seed 000 §3.3, §5):

        X⃖[L + λ_k·φ](g_k) = X⃗[L + λ_{k+1}·φ](g_{k+1}),   φ(g_{k+1}) = 0,

    X⃖[f](g) = d/dt f(g·h_X(t))|₀ and X⃗[f](g) = −d/dt f(h_X(t)⁻¹·g)|₀ (seed 000 eqs.
    (1)–(2)), one equation per section of the basis.  On the pair groupoid Q × Q, whose
    arrows are consecutive configurations (q_{k−1}, q_k), they are the Marsden–West
    D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) = 0; on a Lie group, whose arrows are the
    increments W_k = R_k⁻¹R_{k+1} between consecutive configurations, the discrete
    Euler–Poincaré equations (seed 000 §6.1; a run's configurations R_k are
    ``Trajectory.configurations(R_0)``).  :meth:`euler_lagrange` derives the step
    (g_k, λ_k) ↦ (g_{k+1}, λ_{k+1}) as :class:`StepEquations` (residuals, exact Jacobian,
    LaTeX, ``compile()``)::

        system = sg.DiscreteSystem(G, L, constraints=phi, parameters=[h], name="ball")
        step = system.euler_lagrange()

    Parameters
    ----------
    groupoid : the Lie groupoid G ⇉ Q.
    lagrangian : callable ``L(g) -> expr`` on a symbolic arrow.
    constraints : optional callable ``φ(g) -> [expr, …]``; N = {φ = 0}.
    parameters : symbols the expressions may use besides the arrow's coordinates.
    name : used in messages and generated code.
    holonomic : optional callable ``ψ(q) -> [expr, …]`` on a base point q (as
        ``groupoid.base_view`` gives it: a tuple of coordinates, a matrix on the pair
        groupoid of a Lie group, a tuple of parts on a product): constraints on the
        configuration space, N = G|_M the restriction to M = {ψ = 0} (seed 000 §3.3,
        docs/conventions.md §15).  The multipliers of ψ follow those of φ; the multiplier
        of ψ on the arrow g_k sits at its source α(g_k).
    time_step : optional, the parameter that is the time step h (its symbol or name).  The
        discrete energy E_d = −∂L_d/∂h differentiates by it, and the derivation checks the
        velocity Hessian of the continuous limit lim L_d(g_h(q, v))/h with it.  Undeclared,
        the step is the one parameter for which that limit exists (docs/conventions.md §19);
        on a :class:`TimeGroupoid` the step is each arrow's t₁ − t₀ and no parameter.
    forces : optional callable ``f(g) -> (f_minus, f_plus)``: the discrete forces f⁻, f⁺:
        G → A*G, each a list of rank(AG) components in the basis sections' order (the order
        of the step's residuals).  The discrete Lagrange–d'Alembert principle adds
        f⁺(g_k) + f⁻(g_{k+1}) to the junction residuals (Marsden–West eq. (3.2.3) on Q × Q;
        docs/conventions.md §20).
    inputs : symbols the forces may use whose values change from arrow to arrow (controls):
        the value u_k belongs to the arrow g_k.  The state of a forced system carries the
        input of its arrow (the part named after the input), and each step reads the input
        of the new arrow.
    stages : the number of internal variables ζ of each arrow (default 0).  With stages the
        Lagrangian is ``L(g, zeta)`` (ζ a list of symbols) and the discrete Lagrangian is its
        stationary value over ζ, L_d(g) = ext_ζ L(g, ζ) (the Galerkin discrete Lagrangians
        of Marsden–West §2.6; docs/conventions.md §22).  The step solves ζ_k and ζ_{k+1}
        with g_{k+1} (the rows ∂L/∂ζ = 0 of both arrows); they are never part of the state.
        Its first guess for ζ is 0: write ζ as a deviation from a nearby value.  With
        stages the forces are ``f(g, zeta) -> (f_minus, f_plus, f_stages)``: f_ζ, one
        component per stage, is added to the stage rows (∂L/∂ζ + f_ζ = 0; the forced
        Galerkin scheme of docs/conventions.md §22).
    """

    @collector_paused
    def __init__(self, groupoid: Groupoid, lagrangian: Callable,
                 constraints: Callable | None = None, parameters: Sequence[sp.Symbol] = (),
                 name: str = "system", *, holonomic: Callable | None = None,
                 time_step: sp.Symbol | str | None = None, forces: Callable | None = None,
                 inputs: Sequence[sp.Symbol] = (), stages: int = 0):
        name, groupoid, parameters = system_arguments(name, groupoid, parameters)
        self.stages = integer_argument(stages, "stages", minimum=0, maximum=MAX_DIMENSION,
                                       owner=name)
        self.groupoid, self.name = groupoid, name
        self.lagrangian, self.constraints = lagrangian, constraints
        self.holonomic = holonomic
        self.parameters = parameters
        self.time_step = time_step_argument(name, groupoid, time_step, parameters)
        self.forces = forces_argument(name, forces, self._arity)
        check_force_step(name, forces, self.time_step)
        self.inputs = input_arguments(name, inputs, parameters, forces)
        self._functions = evaluate_system(name, groupoid, lagrangian, constraints,
                                          self.parameters, arity=self._arity,
                                          holonomic=holonomic, forces=forces,
                                          inputs=self.inputs, stages=self.stages)

    _arity = 1  # L: G -> R

    def _refuse_stages(self, what: str) -> None:
        """An :class:`UnsupportedFeatureError` for what a system with internal stages does
        not support yet (docs/conventions.md §22)."""
        if self.stages:
            raise UnsupportedFeatureError(
                f"{self.name}: {what} of a discrete Lagrangian with internal stages (a "
                f"Galerkin discretisation) is not supported yet; docs/conventions.md §22 "
                f"lists what is")

    @property
    def n_constraints(self) -> int:
        """Multipliers per arrow: the constraints φ, then the holonomic constraints ψ."""
        return len(self.functions.constraints)

    @property
    def n_holonomic(self) -> int:
        """The number of holonomic constraints ψ (the last ``n_holonomic`` multipliers)."""
        return self.functions.n_holonomic

    @reported(lambda self: f"{self.name}: deriving the equations")
    @collector_paused
    def euler_lagrange(self) -> StepEquations:
        """The step (g_k, λ_k) → (g_{k+1}, λ_{k+1}) (seed 000 §3.3; docs/conventions.md §4).

        ``progress`` (keyword): report a derivation that takes longer than 2 s (see
        :mod:`symgroupoid._progress`)."""
        step = StepEquations(junction_step(self.name, self.groupoid, self.functions,
                                           self.parameters))
        step.system = self
        if self.stages:  # the stage rows are not junction rows; the limit needs ζ
            check_step(step, stages=len(step.stages))
            origin = getattr(self, "continuous", None)
            if origin is not None:  # its continuous L: a degenerate kinetic energy (§19)
                origin.check_kinetic(step)
            return step
        check_step(step, time_steps=time_step_candidates(self))
        step.set_structured_source(self._matrix_form)
        return step

    def _matrix_form(self, explicit) -> list | None:
        """The residuals with matrix parts kept as matrices, for LaTeX (built on request)."""
        try:
            return matrix_form_residuals(
                self.name, self.groupoid, self.lagrangian, self.constraints, self.parameters,
                explicit, arity=self._arity, holonomic=self.holonomic)
        except CallableError:
            return None  # user code needs explicit matrices: print entries

    def legendre(self) -> LegendreTransforms:
        """F⁻L and F⁺L at (g_k, λ_k) in the section basis, multiplier terms included."""
        self._refuse_stages("the Legendre transforms in closed form")
        return LegendreTransforms(self._legendre_forms,
                                  self.parameters)

    @functools.cached_property
    def _legendre_forms(self):
        """F⁻L and F⁺L in closed form, derived once per system (each section's Noether
        quantity pairs them with its own coefficients)."""
        return legendre_forms(self.groupoid, self.functions)

    def noether(self, section, f=None) -> NoetherQuantity:
        """The Noether quantity of a section (seed 000 Def. 4.8, Thm 4.9).

        ``section``: a basis index, a list of coefficients, or a callable of the base point
        returning coefficients; ``f``: the quasi-invariance function on the base (callable
        or expression), default 0.  The result records whether X is verified symbolically
        to be a Noether symmetry.  With holonomic constraints ψ the defect carries the
        multiplier term −λ·dψ(α(g))(ρ(X)), and X is a symmetry when the defect vanishes on
        N = G|_M: X tangent to M = {ψ = 0} and L invariant there (docs/conventions.md §15).
        With internal stages F_X and the defect are taken at the stages ζ* of the arrow
        (interior multipliers included) and the symmetry is checked numerically at random
        arrows, of N with holonomic constraints (docs/conventions.md §22).
        """
        if self.stages or self._noether_on_graph():
            return self._graph_noether(section, f)
        forms = noether_forms(self.groupoid, self._legendre_forms,
                              section, f, self.parameters)
        ok, how = vanishing_check(forms.defect, self.groupoid, forms.arrow, forms.window)
        if not ok and vanishes_on_restriction(forms.defect, self.groupoid, forms.arrow,
                                              self.functions):
            ok, how = True, "symbolic on N = G|_M (ideal membership)"
        quantity = NoetherQuantity(forms, ok, self.parameters)
        self._own(quantity)
        quantity.verification = how
        forces = self.functions.forces
        if forces is not None and self._arity == 1:
            self._impulse(quantity, section)
        elif forces is not None:  # second order: the window's inputs u_{k−1}, u_k; u_{k+1}
            expr, a, b = pair_impulse_form(self.groupoid, forces, section, self.parameters)
            quantity.impulse_form = (expr, a, b, input_symbols(forces.inputs, -1)
                                     + input_symbols(forces.inputs, 0),
                                     input_symbols(forces.inputs, 1))
        return quantity

    def _impulse(self, quantity: NoetherQuantity, section) -> None:
        """The forces' impulse along ``section`` of a first-order system without stages
        (``quantity.impulse``): (f⁻(g_{k+1}) + f⁺(g_k))(X) with each arrow's inputs."""
        forces = self.functions.forces
        expr, a, b = impulse_form(self.groupoid, forces, section, self.parameters)
        quantity.impulse_form = (expr, a, b, input_symbols(forces.inputs, 0),
                                 input_symbols(forces.inputs, 1))

    def _noether_on_graph(self) -> bool:
        """Whether a Noether quantity of this system without stages is built on the
        expression graph and checked at random arrows, as with stages: a first-order system
        without holonomic constraints on a groupoid whose base holds a matrix group (a pair
        groupoid of SO(3), ``Groupoid.base_groups``).  There the SymPy forms of F±L
        differentiate L through the group's multiplication and retraction (the heavy top by
        the midpoint rule on the pair groupoid of SO(3): 45 s), and the defect is decided by
        random arrows in any case (a symbolic check treats the base points as arbitrary
        arrays); the forms are still built on request (``quantity.expr``, ``latex()``).  On
        a Lie group, an action groupoid or a product with them the symmetry is still
        decided symbolically where it can be (the heavy top on S² × SO(3), a satellite with
        a wheel)."""
        return (self._arity == 1 and not self.n_holonomic
                and bool(self.groupoid.base_groups()))

    def _own(self, quantity: NoetherQuantity) -> None:
        """Marks ``quantity`` as this system's: its runs are those of this name and inputs
        (:meth:`NoetherQuantity.along` refuses another system's)."""
        quantity.system_name = self.name
        quantity.n_inputs = len(self.inputs)
        quantity.system = self

    def _graph_noether(self, section, f) -> NoetherQuantity:
        """The Noether quantity of a system with internal stages, or without them where
        :meth:`_noether_on_graph` says so: F_X and the defect (at the stages ζ* of the
        arrow, docs/conventions.md §22), the symmetry checked there at random arrows.
        With forces and stages, F_X is evaluated at the forced stages of each arrow
        (∂L/∂ζ + f_ζ = 0 with that arrow's inputs), and the impulse of a step is the forces'
        along X at the junction plus the stage forces' term, minus the defect at the new
        arrow's forced stages (docs/conventions.md §22, "The forced Noether balance"); without
        stages, the impulse is that of :meth:`_impulse`.  With
        holonomic constraints ψ the stages include the interior multipliers Λ, solved with
        the arrow's other stages (the end multipliers enter no stage row), and the symmetry
        is checked at arrows of N = G|_M (docs/conventions.md §22, "The Noether quantity on
        N = G|_M").  F_X and the defect are built on the expression graph
        (:func:`~symgroupoid.equations.noether_nodes`); their SymPy forms only when asked
        for (``quantity.expr``, ``latex()``)."""
        G, fs = self.groupoid, self.functions
        arrow = tuple(named(G, 0, False))
        lam = multiplier_symbols(len(fs.constraints), 0)
        ends = noether_ends(G, section, f, self.parameters, arrow)
        quantity = NoetherQuantity(NoetherForms(None, None, arrow, lam), False, self.parameters)
        quantity.graph_forms = functools.partial(noether_nodes, self, ends, arrow, lam)

        def symbolic() -> NoetherForms:
            return noether_forms(G, self._legendre_forms, section, f, self.parameters)

        quantity.symbolic_forms = symbolic
        self._own(quantity)
        if self.n_holonomic:
            self._restrict_noether(quantity)
        quantity.stages = tuple(self.functions.stages)
        forces = self.functions.forces
        if forces is not None and not self.stages:
            self._impulse(quantity, section)
        elif forces is not None:  # large expressions: built on the graph, never substituted
            here, there = input_symbols(forces.inputs, 0), input_symbols(forces.inputs, 1)
            quantity.forces = forces
            quantity.stage_inputs = tuple(here)
            X, a, b = impulse_section(self.groupoid, section, self.parameters)
            quantity.impulse_form = (X, a, b, here, there)
            quantity.impulse_stages = (
                tuple(sp.Dummy(f"za{i}", real=True) for i in range(self.stages)),
                tuple(sp.Dummy(f"zb{i}", real=True) for i in range(self.stages)))
        quantity.is_symmetry, quantity.verification = quantity.check_on_graph(
            self.groupoid, getattr(self, "time_step", None))
        return quantity

    def _restrict_noether(self, quantity: NoetherQuantity) -> None:
        """Prepare the check of a Noether quantity of a system with stages and holonomic
        constraints on N = G|_M (docs/conventions.md §22): the arrows of N near random arrows
        (the source, then the target, projected onto M by Gauss–Newton in their α-fibres,
        as ``project_initial`` does, §15), and the coefficients −dψ_a(α(g))(ρ(X)) of the end
        multipliers λ_a of ψ in the defect, which is affine in them (they enter no stage
        row).  Constraints φ on the arrows as well are refused: the random arrows would have
        to lie on {φ = 0} ∩ G|_M."""
        held = self.n_holonomic
        if self.n_constraints > held:
            raise UnsupportedFeatureError(
                f"{self.name}: the Noether quantity of a discrete Lagrangian with internal "
                f"stages, holonomic constraints and constraints on the arrows is not "
                f"supported: its symmetry would be checked on {{φ = 0}} ∩ G|_M, whose "
                f"arrows are not constructed; docs/conventions.md §22 lists what is")
        residual = holonomic_projection_program(self.name, self.groupoid, self.functions,
                                                self.parameters)
        quantity.restriction = RestrictedArrows(
            self.groupoid, residual.numpy_function(["psi", "J"], ["x", "q", "p"]))
        quantity.tangency = tuple(quantity.multipliers[-held:])

    def lie_poisson(self) -> LiePoissonEquations:
        """The discrete constrained Lie–Poisson equations (seed 000 §6.1), Lie groups only."""
        self._refuse_stages("the Lie–Poisson form")
        equations = LiePoissonEquations(lie_poisson_forms(self.name, self.groupoid, self.functions,
                                                          self.parameters))
        check_step(equations.reconstruction, lie_poisson=True)
        return equations

    def __repr__(self) -> str:
        held = self.n_holonomic
        shown = (f"{counted(self.n_constraints - held, 'constraint')}, {held} holonomic"
                 if held else counted(self.n_constraints, "constraint"))
        return f"{type(self).__name__}({self.name!r} on {self.groupoid.name}, {shown})"

    def reduce(self, morphism, lagrangian: Callable | None = None,
               constraints: Callable | None = None, name: str | None = None,
               check: bool = True, forces: Callable | None = None):
        """The reduced system (G′, N′, L′) along a groupoid morphism Φ: G → G′ (seed 000
        Def. 4.2, Thm 4.5, Cor. 4.6; docs/conventions.md §13).

        L′ (and φ′) are given, or found by substitution L′ = L∘σ when Φ has a section σ;
        L = L′∘Φ and φ = φ′∘Φ are verified (symbolically, else numerically on random arrows),
        and, with ``check``, Φ's morphism axioms (:func:`check_morphism`).  The result is a
        :class:`ReducedSystem`: its ``euler_lagrange()`` are the reduced equations, and it
        projects and reconstructs trajectories.  A forced system needs its reduced forces
        ``forces`` = f′ (``f′(g′) -> (f′_minus, f′_plus)`` on G′, the same inputs), A*Φ-related
        to its own, f±(g) = M·f′±(Φ(g)) (verified numerically; docs/conventions.md §13).
        """
        from ._reduced import reduce_system

        self._refuse_stages("reduction")
        return reduce_system(self, morphism, lagrangian, constraints, name, check, forces)


class SecondOrderSystem(DiscreteSystem):
    """A second-order discrete system: L, Φ: G₂ → R on composable pairs (seed 001 §3).

    ``lagrangian(g1, g2)`` and ``constraints(g1, g2)`` take two composable symbolic arrows.
    :meth:`euler_lagrange` gives the step (g_{k-1}, g_k, g_{k+1}, λ_{k-1}, λ_k) →
    (g_{k+2}, λ_{k+1}) of seed 001 eqs. (13)/(15) and (18), from the same junction variation
    as the first-order equations.

    ``forces(g1, g2) -> (f0, f1, f2)``: the covectors at the pair's three base points
    α(g1), β(g1), β(g2), each a list of rank(AG) components; the residuals gain
    f²(g_{k-1}, g_k) + f¹(g_k, g_{k+1}) + f⁰(g_{k+1}, g_{k+2}) (docs/conventions.md §20).
    An input's value u_j belongs to the pair (g_j, g_{j+1}): the state carries u_{k-1},
    u_k and each step reads u_{k+1}.
    """

    _arity = 2

    def lie_poisson(self):
        raise UnsupportedFeatureError(f"{self.name}: the Lie–Poisson form is first order only")


class NonholonomicSystem(_EvaluatedSystem):
    """A discrete nonholonomic system (L_d, M_c, D_c) (seed 002; docs/conventions.md §10).

    ``constraints(g) -> [ψ…]`` define the discrete constraint submanifold M_c ⊂ G;
    ``distribution`` lists the basis of D_c ⊂ AG, each element a list of coefficients in the
    groupoid's section basis or a callable of the base point returning one.  The equations
    are not variational in the sense of :class:`DiscreteSystem`: no multipliers, and the
    flow is not Poisson in general.

    ``method="holder"`` (default): the discrete Hölder principle with M_c.
    ``method="energy_momentum"``: the integrator of Ferraro, Iglesias and Martín de Diego
    with the bundle metric ``metric`` = G_c on AG (a rank × rank matrix in the section basis,
    or a callable of the base point) and no M_c (``constraints=None``).

    ``time_step``: the step parameter, as for :class:`DiscreteSystem`.
    ``forces``, ``inputs``: discrete forces and their inputs, as for :class:`DiscreteSystem`
    (``method="holder"``): the rows along D_c gain f⁺(g_k) + f⁻(g_{k+1}) along each element.
    """

    @collector_paused
    def __init__(self, groupoid: Groupoid, lagrangian: Callable,
                 constraints: Callable | None = None, distribution: Sequence = (),
                 parameters: Sequence[sp.Symbol] = (), name: str = "nonholonomic", *,
                 method: str = "holder", metric=None,
                 time_step: sp.Symbol | str | None = None, forces: Callable | None = None,
                 inputs: Sequence[sp.Symbol] = ()):
        name, groupoid, parameters = system_arguments(name, groupoid, parameters)
        choice_argument(method, NONHOLONOMIC_METHODS, "method", owner=name)
        self.forces = forces_argument(name, forces)
        self.inputs = input_arguments(name, inputs, parameters, forces)
        if forces is not None and method != "holder":
            raise UnsupportedFeatureError(
                f"{name}: forces are supported with method='holder' (the discrete "
                f"Lagrange–d'Alembert–Hölder principle), not with {method!r}")
        self.groupoid, self.name = groupoid, name
        self.lagrangian, self.constraints = lagrangian, constraints
        self.distribution = distribution_elements(name, groupoid, distribution, parameters)
        self.parameters = parameters
        self.time_step = time_step_argument(name, groupoid, time_step, parameters)
        check_force_step(name, forces, self.time_step)
        self.method, self.metric = method, metric
        self._functions = evaluate_system(name, groupoid, lagrangian, constraints,
                                          self.parameters, forces=forces, inputs=self.inputs)
        if method == "energy_momentum":
            energy_momentum_step(name, groupoid, self.functions, self.distribution, metric,
                                 self.parameters)  # checks G_c and D now
        else:
            check_nonholonomic_dimensions(name, groupoid, len(self.distribution),
                                          len(self.functions.constraints))
            if metric is not None:  # kept for conserved_quantities(): checked now
                check_metric(name, groupoid, metric, self.parameters)

    @reported(lambda self: f"{self.name}: deriving the equations")
    @collector_paused
    def euler_lagrange(self) -> StepEquations:
        """The step g_k → g_{k+1}: the DEL along D_c and g_{k+1} ∈ M_c (``method="holder"``),
        or the energy–momentum equations on D ⊕ D⊥ (docs/conventions.md §14).  ``progress``
        (keyword): as for :meth:`DiscreteSystem.euler_lagrange`."""
        if self.method == "energy_momentum":
            derived = energy_momentum_step(self.name, self.groupoid, self.functions,
                                           self.distribution, self.metric, self.parameters)
        else:
            derived = nonholonomic_step(self.name, self.groupoid, self.functions, self.distribution,
                                        self.parameters)
        step = StepEquations(derived)
        step.system = self
        holder = self.method == "holder"  # energy–momentum rows are not the DEL along D_c
        check_step(step, distribution=len(self.distribution),
                   time_steps=time_step_candidates(self) if holder else ())
        return step

    def conserved_quantities(self, metric=None):
        """The energy ½‖F⁺L‖² (dual metric of G_c) and the momenta ⟨F⁺L, X_a⟩ of D's basis,
        with whether each is proven conserved by the energy–momentum method
        (docs/conventions.md §14).  ``metric`` defaults to the system's."""
        return conserved_quantities(self.name, self.groupoid, self.functions, self.distribution,
                                    self.metric if metric is None else metric,
                                    self.parameters)

    def legendre(self):
        raise self._not_here("legendre()", "the discrete Legendre transforms")

    def lie_poisson(self):
        raise self._not_here("lie_poisson()", "the Lie–Poisson form")

    def noether(self, *args, **kwargs):
        raise self._not_here("noether()", "Noether quantities")

    def reduce(self, *args, **kwargs):
        raise self._not_here("reduce()", "reduction by a morphism")

    def _not_here(self, call: str, what: str) -> UnsupportedFeatureError:
        """The refusal of a DiscreteSystem's method a nonholonomic system does not have (it
        was an AttributeError): what the library offers for one instead."""
        return UnsupportedFeatureError(
            f"{self.name}: {call} — {what} of a discrete Lagrangian system — is not defined "
            f"for a nonholonomic system here; its step is euler_lagrange() (the discrete "
            f"Hölder principle, or method='energy_momentum'), and its energy and momenta "
            f"are conserved_quantities() (docs/conventions.md §10, §14)")

    def __repr__(self) -> str:
        return f"NonholonomicSystem({self.name!r} on {self.groupoid.name})"
