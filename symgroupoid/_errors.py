"""Exceptions raised by symgroupoid.  Every message names the offending object."""

from __future__ import annotations


class SymgroupoidError(Exception):
    """Base class of all symgroupoid errors."""


class UndeclaredSymbolError(SymgroupoidError, ValueError):
    """A Lagrangian or constraint uses symbols that are neither coordinates nor parameters."""


class ShapeError(SymgroupoidError, ValueError):
    """An input has the wrong shape (constraint list, state vector, guess, ...)."""


class NotComposableError(SymgroupoidError, ValueError):
    """Two arrows g, h with β(g) ≠ α(h) were asked to compose."""


class AxiomError(SymgroupoidError, AssertionError):
    """A groupoid's structure maps violate a groupoid axiom (reported with the arrows)."""


class CallableError(SymgroupoidError, RuntimeError):
    """A user callable (Lagrangian, constraint, structure map) raised an exception."""


class SingularJacobianError(SymgroupoidError, ArithmeticError):
    """The step Jacobian is singular: the discrete Lagrangian is not regular there."""

    def __init__(self, message: str, *, step: int | None = None,
                 residual_norm: float | None = None, iterate=None):
        super().__init__(message)
        self.step = step
        self.residual_norm = residual_norm
        self.iterate = iterate


class NewtonDivergenceError(SymgroupoidError, ArithmeticError):
    """Newton's method did not converge (or produced non-finite values) at a step."""

    def __init__(self, message: str, *, step: int | None = None,
                 residual_norm: float | None = None, iterate=None):
        super().__init__(message)
        self.step = step
        self.residual_norm = residual_norm
        self.iterate = iterate


class LagrangianDomainError(NewtonDivergenceError):
    """A step's solution lies where the discrete Lagrangian is not defined: Newton solved the
    step equations, but a logarithm, square root, acos, … of L (or of a constraint) is not
    finite there (L = v²/2 − log x beyond x = 0, whose step equations hold 1/x, never
    log x).  The run stops there, with ``err.trajectory`` up to the step before;
    ``err.kinds`` says which values left their domain and on which term
    (docs/conventions.md §11, "Staying in the domain of L")."""

    kinds: tuple[str, ...] = ()


class BranchJumpError(NewtonDivergenceError):
    """A step's solution lies far outside the trust region of its guess, which the last
    steps' motion sets (``NewtonOptions.trust_factor``): the root of the step equations near
    the motion so far has disappeared (a fold of the step map: the step size no longer
    resolves the motion) and Newton converged to a root on another branch.  On a time
    groupoid also a solution whose time step reverses or changes by more than a factor 2
    (docs/conventions.md §7).  The run stops there, with ``err.trajectory`` up to the step
    before."""


class CacheError(SymgroupoidError, RuntimeError):
    """The kernel cache cannot be used: a lock timed out, or a kernel stays unloadable.

    The message names the cache path and what to do (remove it, or point
    ``SYMGROUPOID_CACHE`` to another directory).
    """


class TrajectoryTooLargeError(SymgroupoidError, MemoryError):
    """The states a simulation was asked to keep would not fit in this machine's memory."""


class ParameterDeclarationError(UndeclaredSymbolError, TypeError):
    """A declared parameter is not a SymPy symbol (e.g. a string), or the expressions use a
    symbol of the same name with other assumptions (so SymPy treats them as different)."""


class InvalidExpressionError(SymgroupoidError, ValueError):
    """A Lagrangian or constraint contains a non-finite or complex value (nan, ±oo, zoo, I)."""


class UnsupportedExpressionError(InvalidExpressionError):
    """An expression contains something compiled code cannot evaluate (a complex or infinite
    value, an undefined function, an unevaluated derivative, …); the message names it."""


class CoordinateNameError(SymgroupoidError, ValueError):
    """A coordinate name is reserved (the multipliers' "lambda", "λ", "multipliers") or
    names two different coordinates."""


class DegenerateSystemError(SymgroupoidError, ValueError):
    """The step equations cannot determine the step: equations identically zero, an unknown
    that enters no equation, or a step Jacobian singular everywhere (a Lagrangian that is
    not regular, dependent constraints, a multiplier no equation determines).

    ``findings`` lists what was found, each with ``cause``, ``equations`` and ``unknowns``.
    """

    def __init__(self, message: str, *, findings: tuple = ()):
        super().__init__(message)
        self.findings = tuple(findings)

    @property
    def causes(self) -> tuple[str, ...]:
        """The distinct causes found, in the order found."""
        return tuple(dict.fromkeys(f.cause for f in self.findings))


class MorphismError(AxiomError):
    """A map violates the conditions of a groupoid morphism (seed 000 Def. 4.1) or of a
    morphism of discrete constrained Lagrangian systems (Def. 4.2); reported with the arrows
    (``.axiom``, ``.arrows``) and the parameter values used (``.parameters``)."""


class ReconstructionError(SymgroupoidError, ValueError):
    """A reduced trajectory cannot be lifted: no arrow of the unreduced groupoid with the
    required source maps to the reduced arrow (or the initial arrow does not project onto the
    first reduced arrow)."""


class DomainError(ShapeError):
    """An input has the right shape but lies outside its domain: a matrix that is not in its
    group, a non-finite number, an initial state off the constraints, a value that is not
    one of an option's choices.  ``violated``: for an initial state off the constraints, the
    kind of each violated one ("φ", "ψ∘α" at the first node, "ψ∘β"); empty otherwise."""

    violated: tuple[str, ...] = ()


class InputNameError(ShapeError, KeyError):
    """A named input is unknown, missing or given twice (a state part, a coordinate of a
    configuration, a parameter)."""

    def __str__(self) -> str:  # the message itself, not KeyError's repr of it
        return str(self.args[0]) if self.args else ""


class InputTypeError(ShapeError, TypeError):
    """An argument is an object of the wrong kind: a string where a groupoid, a function, a
    path or a list of names is expected (also a ``TypeError``)."""


class OutputError(SymgroupoidError, OSError):
    """A file cannot be written (its directory missing or read-only, a directory or a file
    in the way); the message names the path and the reason."""


class ParameterError(DomainError, InputNameError):
    """A parameter is unknown, missing, given twice, not a finite real number, or violates
    the assumptions its symbol is declared with (positive, integer, …)."""


class CutLocusError(SymgroupoidError, ArithmeticError):
    """An arrow lies on the cut locus of the chart the equations are written in (Cayley: a
    half-turn), where the Lagrangian or the constraints are not defined."""

    def __init__(self, message: str, *, arrows: tuple = (), iterate=None):
        super().__init__(message)
        self.arrows = tuple(arrows)
        self.iterate = iterate


class CutLocusStepError(CutLocusError, NewtonDivergenceError):
    """A step failed (non-finite values) because an increment of its known arrow is a
    half-turn: on the cut locus of the chart its unknowns are written in, where the
    prediction and the step are not defined.  Both a :class:`CutLocusError` and a
    :class:`NewtonDivergenceError` (with ``step``, ``residual_norm``, ``iterate``,
    ``trajectory``); ``parts`` names the increments at the cut locus."""

    def __init__(self, message: str, *, step: int | None = None,
                 residual_norm: float | None = None, iterate=None, parts: tuple = ()):
        SymgroupoidError.__init__(self, message)
        self.step = step
        self.residual_norm = residual_norm
        self.iterate = iterate
        self.arrows = () if step is None else (step,)
        self.parts = tuple(parts)


class TrajectoryFileError(SymgroupoidError, ValueError):
    """A trajectory file cannot be read (missing, damaged, not written by symgroupoid), or
    holds the trajectory of another system (its state columns are not this system's)."""


class GroupRoundingWarning(UserWarning):
    """A group element given to a few digits (``np.round(R, 8)``: off its group by more than
    rounding, by at most :data:`~symgroupoid.runtime._validate.ROUNDED_TOLERANCE`) was
    replaced by the nearest element of the group (``group.nearest_element``)."""


class UnsupportedFeatureError(SymgroupoidError, NotImplementedError):
    """A valid request the library does not implement for this kind of system (the message
    says which combination), e.g. reduction of a system with holonomic constraints."""


class BoundaryValueDivergenceError(NewtonDivergenceError):
    """The boundary-value Newton iteration ended without meeting the residual criterion: the
    iteration cap, a stalled update, or a line search that found no decrease.  ``iterations``
    and ``history`` (|F|∞ per iteration) say how far it got."""

    def __init__(self, message: str, *, iterations: int, history=(), step: int | None = None,
                 residual_norm: float | None = None, iterate=None):
        super().__init__(message, step=step, residual_norm=residual_norm, iterate=iterate)
        self.iterations = iterations
        self.history = list(history)


class DegenerateLagrangianWarning(UserWarning):
    """The velocity Hessian of the continuous limit of L_d is singular along some directions
    (restricted to the constraint directions), while velocity-linear terms of L make the
    step regular there: the continuous equations are of first order in those directions
    (point vortices, a charge in a strong field) and the two-step discrete flow carries
    parasitic modes beside them (docs/conventions.md §19).  A degenerate kinetic energy
    that only the potential regularises is a :class:`DegenerateSystemError`."""


class DiagnosticsError(SymgroupoidError, ValueError):
    """A diagnostic is not defined for this trajectory (no system attached to its equations,
    no step parameter for the energy, a second-order energy, …); the message says why."""


class TimeStepError(DiagnosticsError):
    """The discrete energy needs the time step, and the system neither declares it
    (``time_step=``) nor has exactly one parameter that behaves as the step in the
    continuous limit (docs/conventions.md §19); the message names the candidates and says
    to pass ``time_step=`` (or ``step_parameter=``)."""


class StatusCodeError(SymgroupoidError, ValueError):
    """``sg.Status(code)`` of a code that is no status of a run (the codes and their
    meanings: ``list(sg.Status)``, docs/reference/errors.md)."""
