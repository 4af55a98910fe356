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
from .derivation import SystemFunctions
from .equations import (
    DiscreteSystem,
    LegendreTransforms,
    LiePoissonEquations,
    NoetherQuantity,
    NonholonomicSystem,
    ReducedSystem,
    SecondOrderSystem,
    StepEquations,
    UnusedAbbreviationWarning,
    check_system_morphism,
    latex,
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
    "BranchJumpError", "NewtonOptions",
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
    "UnusedAbbreviationWarning", "DegenerateLagrangianWarning", "TimeStepError",
    "check_axioms", "check_morphism", "check_system_morphism", "compile_step", "diagnostics",
    "emit_c", "hat3", "latex", "left_derivative", "plot_conservation", "plot_trajectory",
    "right_derivative", "solve_boundary_value", "sweep", "sweep_boundary_value",
    "verify_stationary",
    "Status",
]
