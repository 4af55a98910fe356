"""Layer 1: Lie groupoids from structure maps, and their algebroid sections."""

from ._action import ActionArrow, ActionGroupoid
from ._atiyah import AtiyahArrow, AtiyahGroupoid
from ._axioms import check_axioms
from ._base import Arrow, Groupoid, derivation, left_derivative, right_derivative
from ._configuration_spaces import ConfigurationFactor, configuration_factors, pair_groupoid_of
from ._examples import examples
from ._matrix_form import (
    NamedMatrix,
    StructuredMatrix,
    is_constant_matrix,
    named_constants,
    to_explicit,
)
from ._matrix_groups import GROUP_TOLERANCE, MatrixArrow, MatrixLieGroup, hat3
from ._morphism import GroupoidMorphism, ParameterValues, check_morphism
from ._numerics import ConfigurationChecks, PairCoordinate
from ._pair import EuclideanSpace, PairArrow, PairGroupoid
from ._product import ProductArrow, ProductGroupoid
from ._se2 import SE2
from ._se3 import SE3
from ._so2 import SO2
from ._so3 import SO3
from ._time import TimeArrow, TimeGroupoid
from ._trivialised import TrivialisedArrow, TrivialisedPairGroupoid
from ._user import RESERVED_NAMES, DefinedGroupoid

__all__ = [
    "ConfigurationFactor", "configuration_factors", "pair_groupoid_of",
    "RESERVED_NAMES",
    "is_constant_matrix", "named_constants", "to_explicit",
    "ActionArrow", "ActionGroupoid", "Arrow", "AtiyahArrow", "AtiyahGroupoid",
    "DefinedGroupoid", "EuclideanSpace", "Groupoid", "GroupoidMorphism", "MatrixArrow",
    "ConfigurationChecks", "GROUP_TOLERANCE", "MatrixLieGroup", "NamedMatrix",
    "PairCoordinate", "StructuredMatrix",
    "PairArrow", "PairGroupoid", "ParameterValues",
    "ProductArrow", "ProductGroupoid", "SE2", "SE3", "SO2", "SO3", "TimeArrow", "TimeGroupoid",
    "TrivialisedArrow", "TrivialisedPairGroupoid",
    "check_axioms", "check_morphism", "derivation", "examples", "hat3", "left_derivative",
    "right_derivative",
]
