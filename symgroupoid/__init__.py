"""symgroupoid: discrete constrained Lagrangian mechanics on Lie groupoids.

Describe a Lie groupoid by its structure maps, write a discrete Lagrangian and constraints
with SymPy, and derive the discrete Euler–Lagrange equations (seed 000 Thm 2.13, §3.3),
their Lie–Poisson form, exact Jacobians, LaTeX and C kernels.
"""

from . import diagnostics  # noqa: E402  (layer 6)
from ._errors import (
    AxiomError,
    BoundaryValueDivergenceError,
    BranchJumpError,
    CacheError,
    CallableError,
    CoordinateNameError,
    CutLocusError,
    CutLocusStepError,
    DegenerateLagrangianWarning,
    DegenerateSystemError,
    DomainError,
    GroupRoundingWarning,
    InputNameError,
    InputTypeError,
    InvalidExpressionError,
    LagrangianDomainError,
    MorphismError,
    NewtonDivergenceError,
    NotComposableError,
    OutputError,
    ParameterDeclarationError,
    ParameterError,
    ReconstructionError,
    ShapeError,
    SingularJacobianError,
    StatusCodeError,
    SymgroupoidError,
    TimeStepError,
    TrajectoryFileError,
    TrajectoryTooLargeError,
    UndeclaredSymbolError,
    UnsupportedExpressionError,
    UnsupportedFeatureError,
)
from ._version import __version__ as __version__
from .codegen import emit_c  # noqa: E402  (layer 4)
from .convergence import ConvergenceReport, convergence_order  # noqa: E402  (layer 6)
from .derivation import SystemFunctions
from .equations import (
    ContinuousSystem,
    DiscreteSystem,
    GaussLegendre,
    LegendreTransforms,
    LiePoissonEquations,
    LobattoIIIAB,
    NoetherQuantity,
    NonholonomicSystem,
    ReducedSystem,
    SecondOrderSystem,
    StepEquations,
    UnusedAbbreviationWarning,
    WideLinesWarning,
    body_torque,
    check_system_morphism,
    joint_torque,
    latex,
    midpoint_forces,
    rayleigh_damping,
    trapezoid_forces,
)
from .groupoids import (
    SE2,
    SE3,
    SO2,
    SO3,
    ActionGroupoid,
    Arrow,
    AtiyahGroupoid,
    DefinedGroupoid,
    EuclideanSpace,
    Groupoid,
    GroupoidMorphism,
    MatrixLieGroup,
    NamedMatrix,
    PairGroupoid,
    ProductGroupoid,
    TimeGroupoid,
    TrivialisedPairGroupoid,
    check_axioms,
    check_morphism,
    hat3,
    left_derivative,
    right_derivative,
)
from .plotting import plot_conservation, plot_trajectory  # noqa: E402
from .runtime import (  # noqa: E402  (layer 5)
    BoundaryValueSolution,
    CompilationError,
    NewtonOptions,
    Simulator,
    SweepResult,
    Trajectory,
    TrajectoryBatch,
    compile_step,
    solve_boundary_value,
    sweep,
    sweep_boundary_value,
)
from .stepper import Status  # noqa: E402  (the statuses of every run)
from .verification import StationarityReport, verify_stationary

__all__ = [
    "ActionGroupoid", "Arrow", "AtiyahGroupoid", "AxiomError", "BoundaryValueSolution",
    "CacheError", "CallableError", "CompilationError", "CoordinateNameError", "DefinedGroupoid",
    "DegenerateSystemError", "DiscreteSystem", "EuclideanSpace", "Groupoid", "GroupoidMorphism",
    "InputTypeError", "InvalidExpressionError", "LegendreTransforms", "LiePoissonEquations",
    "MatrixLieGroup", "MorphismError", "NamedMatrix", "NewtonDivergenceError",
    "BranchJumpError", "LagrangianDomainError", "NewtonOptions",
    "NoetherQuantity", "NonholonomicSystem", "NotComposableError", "OutputError", "PairGroupoid",
    "TrivialisedPairGroupoid",
    "ParameterDeclarationError", "ParameterError", "ProductGroupoid", "ReconstructionError",
    "ReducedSystem", "SE2", "SE3", "SO2", "SO3", "SecondOrderSystem", "ShapeError", "Simulator",
    "SingularJacobianError", "StationarityReport", "StatusCodeError", "StepEquations",
    "SweepResult",
    "SymgroupoidError", "SystemFunctions", "TimeGroupoid", "Trajectory", "TrajectoryBatch",
    "TrajectoryTooLargeError", "UndeclaredSymbolError", "UnsupportedExpressionError",
    "UnsupportedFeatureError", "BoundaryValueDivergenceError", "CutLocusError", "DomainError",
    "InputNameError", "CutLocusStepError", "GroupRoundingWarning", "TrajectoryFileError",
    "UnusedAbbreviationWarning", "WideLinesWarning", "DegenerateLagrangianWarning", "TimeStepError",
    "check_axioms", "check_morphism", "check_system_morphism", "compile_step", "diagnostics",
    "emit_c", "hat3", "latex", "left_derivative", "plot_conservation", "plot_trajectory",
    "right_derivative", "solve_boundary_value", "sweep", "sweep_boundary_value",
    "verify_stationary",
    "Status",
    "body_torque", "joint_torque", "midpoint_forces", "rayleigh_damping", "trapezoid_forces",
    "ContinuousSystem", "GaussLegendre", "LobattoIIIAB", "ConvergenceReport",
    "convergence_order",
]


def _check_the_calls() -> None:
    """Every call of the public face that cannot bind its arguments (a misspelled keyword
    ``extrapolat=``, a missing argument) is an :class:`InputNameError` naming the function
    or method and its parameters, not Python's ``TypeError``: the public functions are
    wrapped (:func:`~symgroupoid._arguments.checked_call`), and so are the constructors and
    public methods of the public classes and of the library's classes they inherit from
    (:func:`~symgroupoid._arguments.checked_calls`; errors, warnings and enums excepted)."""
    import enum
    import inspect

    from ._arguments import checked_call, checked_calls

    for name in __all__:
        value = globals()[name]
        if inspect.isclass(value) and not issubclass(value, (BaseException, Warning,
                                                             enum.Enum)):
            for cls in value.__mro__:
                if cls.__module__.startswith(__name__ + ".") and \
                        not cls.__dict__.get("_symgroupoid_checked", False):
                    checked_calls(cls)
                    cls._symgroupoid_checked = True
        elif inspect.isfunction(value):
            globals()[name] = checked_call(value, name)


_check_the_calls()
