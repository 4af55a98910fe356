"""One validation path for the numeric inputs of every runtime entry point.

``simulate``, ``solve``, ``from_momentum``, ``solve_boundary_value``, ``verify_stationary``
and the command line check counts, parameters, configurations, arrows and states through the
functions here, so a malformed input gets the same message, naming the argument, wherever it
is given:

- :func:`integer_argument`, :func:`real_argument`, :func:`real_array` — counts, real
  numbers and arrays of them (symgroupoid/_arguments.py, shared with the other layers);
- :func:`parameter_vector` — parameters by name or in order, with the assumptions their
  symbols are declared with (positive, integer, …);
- :func:`group_element`, :func:`check_group_matrix` — matrices of a matrix Lie group;
- :func:`configuration` — a boundary configuration (a point, a group element, or a tuple
  of them for products, action and time groupoids), per factor;
- :func:`arrow` — flat arrow coordinates (shape, finiteness, every matrix part in its group);
- :class:`ConstraintCheck` — the constraints of a system on a known state.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp

from .._arguments import (  # noqa: F401  (MAX_COUNT: one rule for counts)
    MAX_COUNT,
    caller_level,
    instance_argument,
    integer_argument,
    real_argument,
    real_array,
)
from .._errors import DomainError, GroupRoundingWarning, ShapeError
from .._parameters import (  # noqa: F401  (the runtime's checks gathered here)
    CHECKED_ASSUMPTIONS,
    assumption_test,
    assumptions_test,
    check_assumptions,
    declared_assumptions,
    parameter_names,
    parameter_vector,
    violated_assumption,
)
from ..equations import constraint_program, holonomic_program
from ..groupoids import GROUP_TOLERANCE, Groupoid, MatrixLieGroup

#: a group element off its group by more than GROUP_TOLERANCE but at most this (a rotation
#: given to six digits or more, ``np.round(R, 8)``) is replaced by the nearest element of
#: the group, with a :class:`~symgroupoid.GroupRoundingWarning`
ROUNDED_TOLERANCE = 1e-6

#: a constraint value counts as zero when |φ_i| ≤ max(atol, CONSTRAINT_ROUNDING·ε·M_i), M_i the
#: magnitude of φ_i's terms (:func:`symgroupoid.equations.magnitude`): evaluating φ_i rounds
#: each term by a few ε, so a consistent state computed in floating point (by hand, from a
#: momentum, or as the last state of a run) is never rejected, while a violation above that
#: is reported
CONSTRAINT_ROUNDING = 1e3

_EPS = float(np.finfo(float).eps)


def _where(owner: str) -> str:
    return f"{owner}: " if owner else ""


# --- systems ------------------------------------------------------------------------------------

def system_argument(value, name: str, *, owner: str = ""):
    """The discrete system behind ``value``: a :class:`~symgroupoid.DiscreteSystem` (also
    second-order, reduced) or :class:`~symgroupoid.NonholonomicSystem`, or the step equations
    derived from one (their ``.system``); an :class:`~symgroupoid.InputTypeError` naming
    ``name`` for anything else (a string, a groupoid, equations with no system attached)."""
    from ..equations import DiscreteSystem, NonholonomicSystem, StepEquations

    if isinstance(value, StepEquations):
        value = getattr(value, "system", None) or value
    return instance_argument(value, (DiscreteSystem, NonholonomicSystem), name,
                             "a discrete system (DiscreteSystem, SecondOrderSystem, "
                             "NonholonomicSystem) or the step equations derived from one",
                             owner=owner)


# --- arrays and group elements ------------------------------------------------------------------

def _float_array(value, name: str, owner: str) -> np.ndarray:
    return real_array(value, name, owner=owner)


def _finite(arr: np.ndarray, name: str, owner: str) -> np.ndarray:
    if not np.isfinite(arr).all():
        raise DomainError(f"{_where(owner)}{name} has non-finite entries: {arr.tolist()}")
    return arr


def group_deviation(group: MatrixLieGroup, M: np.ndarray) -> tuple[float, float, float]:
    """How far the finite matrix ``M`` is from ``group``: (|RᵀR − I|_max, det R, the
    largest deviation of SE(n)'s last row from (0, …, 0, 1)) of its rotation block R."""
    n = group.n - 1 if group.affine else group.n
    R = M[:n, :n]
    row = 0.0
    if group.affine:
        row = float(np.abs(M[-1] - np.eye(group.n)[-1]).max())
    return float(np.abs(R.T @ R - np.eye(n)).max()), float(np.linalg.det(R)), row


_FIX = ("; if it is an element given to a few digits, give more digits or pass "
        "{group}.nearest_element(M), the nearest element of the group (matrices off by at "
        "most {rounded:g} are replaced by it, with a GroupRoundingWarning)")


def check_group_matrix(group: MatrixLieGroup, M: np.ndarray, name: str, *,
                       owner: str = "") -> None:
    """A :class:`DomainError` unless the finite n×n matrix ``M`` lies in ``group``: its
    rotation block R orthonormal with det R = +1 (a reflection is not in SO(n)), and for
    SE(n) the last row (0, …, 0, 1) — each to :data:`GROUP_TOLERANCE`."""
    where = _where(owner)
    off, det, row = group_deviation(group, M)
    fix = _FIX.format(group=f"sg.{type(group).__name__}({group.symbol_name!r})",
                      rounded=ROUNDED_TOLERANCE)
    if row > GROUP_TOLERANCE:
        last = np.eye(group.n)[-1]
        raise DomainError(f"{where}{name} is not in {group.name}: its last row is "
                          f"{M[-1].tolist()}, not {last.tolist()}{fix}")
    if off > GROUP_TOLERANCE:
        raise DomainError(f"{where}{name} is not in {group.name}: its rotation block is off "
                          f"orthonormal by {off:.2e} (|RᵀR − I|, tolerance "
                          f"{GROUP_TOLERANCE:g}){fix}")
    if abs(det - 1.0) > GROUP_TOLERANCE:
        kind = " (a reflection, not a rotation)" if det < 0 else ""
        raise DomainError(f"{where}{name} is not in {group.name}: det = {det:.6g}{kind}")


def rounded_group_matrix(group: MatrixLieGroup, M: np.ndarray, name: str, *,
                         owner: str = "", check: bool = True) -> np.ndarray:
    """The finite n×n matrix ``M`` as an element of ``group``: itself when it lies in the
    group to :data:`GROUP_TOLERANCE`; the nearest element (``group.nearest_element``) with
    a :class:`~symgroupoid.GroupRoundingWarning` when it is off by at most
    :data:`ROUNDED_TOLERANCE` with det R > 0 (a rotation given to a few digits); else the
    :class:`DomainError` of :func:`check_group_matrix`, which says how to fix it (with
    ``check=False``: ``M`` itself, for the caller's own check)."""
    off, det, row = group_deviation(group, M)
    if max(off, row, abs(det - 1.0)) <= GROUP_TOLERANCE:
        return M
    if max(off, row) <= ROUNDED_TOLERANCE and det > 0:
        nearest = group.nearest_element(M)
        warnings.warn(GroupRoundingWarning(
            f"{_where(owner)}{name} is off {group.name} by {max(off, row):.1e} (given to a few "
            f"digits?); it was replaced by the nearest element of the group (entries changed "
            f"by up to {float(np.abs(nearest - M).max()):.1e})"), stacklevel=caller_level())
        return nearest
    if check:
        check_group_matrix(group, M, name, owner=owner)
    return M


def group_element(group: MatrixLieGroup, value, name: str, *, owner: str = "") -> np.ndarray:
    """``value`` as the n×n matrix of an element of ``group``: :class:`ShapeError` for a
    wrong shape, :class:`DomainError` for non-finite entries or a matrix not in the group;
    one given to a few digits is replaced by the nearest element, with a warning
    (:func:`rounded_group_matrix`)."""
    M = _float_array(value, name, owner)
    if M.shape != (group.n, group.n):
        raise ShapeError(f"{_where(owner)}{name}: a configuration of {group.name} is a "
                         f"{group.n}×{group.n} matrix, got shape {M.shape}")
    _finite(M, name, owner)
    return rounded_group_matrix(group, M, name, owner=owner)


def point(value, dim: int, name: str, *, owner: str = "") -> tuple:
    """``value`` as a point of Rⁿ (n = ``dim``): a number when n = 1, else n numbers."""
    arr = _float_array(value, name, owner)
    if arr.shape != (dim,) and not (dim == 1 and arr.shape == ()):
        expected = "a number or 1 coordinate" if dim == 1 else f"{dim} coordinates"
        raise ShapeError(f"{_where(owner)}{name}: a point here has {expected} (shape "
                         f"({dim},)), got an array of shape {arr.shape}")
    return tuple(float(v) for v in _finite(arr.reshape(dim), name, owner))


def _pieces(value, count: int, name: str, what: str, owner: str) -> tuple:
    """``value`` as a tuple of ``count`` pieces (a configuration of a composite groupoid)."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence,
                                                                          np.ndarray)) \
            or (isinstance(value, np.ndarray) and value.ndim == 0):
        raise ShapeError(f"{_where(owner)}{name} must be {what}, got {type(value).__name__}")
    if len(value) != count:
        raise ShapeError(f"{_where(owner)}{name} must be {what}: {count} parts, got "
                         f"{len(value)}")
    return tuple(value)


class _Checks:
    """The checks of a configuration's parts (``groupoid.configuration`` says what the parts
    are), with messages that name ``owner``."""

    def __init__(self, owner: str):
        self.owner = owner

    def point(self, value, dim: int, name: str) -> tuple:
        return point(value, dim, name, owner=self.owner)

    def group_element(self, group, value, name: str) -> np.ndarray:
        return group_element(group, value, name, owner=self.owner)

    def time(self, value, name: str) -> float:
        return real_argument(value, name, owner=self.owner)

    def pieces(self, value, count: int, name: str, what: str) -> tuple:
        return _pieces(value, count, name, what, self.owner)

    def no_configuration_space(self, groupoid, name: str):
        raise ShapeError(f"{_where(self.owner)}{groupoid.name} has no configuration space "
                         f"(arrow_between), so {name} cannot be given as a configuration")


def configuration(groupoid: Groupoid, value, name: str, *, owner: str = ""):
    """A boundary configuration of ``groupoid``, checked as states are checked, per part
    (``groupoid.configuration``).

    Pair groupoid: a point of its manifold (Rⁿ: shape, finiteness; a matrix Lie group: a
    group element, :func:`group_element`; a product: one per factor); matrix Lie group and
    the pair groupoid of one in increment coordinates: a group element; action groupoid:
    ``(p, R)``; time groupoid: ``(t, c)``; product: one configuration per factor.  Pieces
    are named ``name[i]``.  Groupoids without a configuration space raise
    :class:`ShapeError`; other user groupoids are passed on to their own ``arrow_between``.
    """
    return groupoid.configuration(value, name, _Checks(owner))


def partial_configuration(groupoid: Groupoid, value, name: str, *, owner: str = ""):
    """A first configuration for :meth:`Groupoid.configurations_along`, checked as
    :func:`configuration` checks one, where None stands for a part the arrows determine
    (or that defaults to the identity): None, or for a product one entry per factor, for an
    action groupoid (p, R), for a time groupoid (t, c), each entry None or a configuration
    (``groupoid.partial_configuration``)."""
    return groupoid.partial_configuration(value, name, _Checks(owner))


def offset_element(group, offsets: np.ndarray) -> np.ndarray:
    """The group element I + D of offsets D on the group's free entries (the last row of
    SE(n) is (0, …, 0, 1)); ``offsets`` of shape (arrow_dim,) or (B, arrow_dim)."""
    offsets = np.asarray(offsets, float)
    M = np.broadcast_to(np.eye(group.n), offsets.shape[:-1] + (group.n, group.n)).copy()
    for k, (i, j) in enumerate(group.free_entries):
        M[..., i, j] += offsets[..., k]
    return M


def arrow(groupoid: Groupoid, value, name: str, *, owner: str = "") -> np.ndarray:
    """Flat arrow coordinates: shape (arrow_dim,), finite, and every matrix part of the
    arrow (``groupoid.matrix_parts()``) in its group (:func:`check_group_matrix`)."""
    a = _float_array(value, name, owner)
    if a.shape != (groupoid.arrow_dim,):
        raise ShapeError(f"{_where(owner)}{name}: an arrow of {groupoid.name} has "
                         f"{groupoid.arrow_dim} coordinates, got shape {a.shape}")
    _finite(a, name, owner)
    for start, group in groupoid.matrix_parts():
        M = group.numeric_matrix(a[start:start + group.arrow_dim])
        check_group_matrix(group, M, f"{name} (its {group.symbol_name!r} part)", owner=owner)
    for start, group in groupoid.offset_parts():
        M = offset_element(group, a[start:start + group.arrow_dim])
        check_group_matrix(group, M, f"{name} (its increment, stored as F − I)", owner=owner)
    return a


# --- constraints on a known state ---------------------------------------------------------------

class ConstraintCheck:
    """The system's own constraints on the known arrows of a step's state.

    First order: φ(g_k) on the known arrow; second order: Φ on each pair of consecutive known
    arrows (Φ(g_{k-1}, g_k), Φ(g_k, g_{k+1})); nonholonomic systems: ψ(g_k) (g_k ∈ M_c).
    Holonomic constraints ψ(q) at both ends of each window, ψ(α(first arrow)) and
    ψ(β(last arrow)), so every node of the known arrows lies on M (docs/conventions.md §15).
    Evaluated from ``step.system._fs`` (the constraints on slot coordinates), not from the
    derived equations.
    """

    def __init__(self, step):
        system = getattr(step, "system", None)
        fs = getattr(system, "_fs", None)
        self.name = step.name
        self.windows: list[tuple[tuple[int, ...], np.ndarray]] = []
        self.used: list[tuple[int, str]] = []
        if fs is None or not fs.constraints:
            return
        position = {s: i for i, s in enumerate(step.knowns)}
        known = sorted(o for o, a in step.arrows.items() if all(c in position for c in a))
        arity = len(fs.slots)
        for i in range(len(known) - arity + 1):
            offsets = tuple(known[i:i + arity])
            if offsets[-1] - offsets[0] != arity - 1:
                continue
            index = np.array([position[c] for o in offsets for c in step.arrows[o]])
            self.windows.append((offsets, index))
        held = fs.n_holonomic
        plain = len(fs.constraints) - held
        functions = list(fs.constraints) + list(fs.rows[plain:])
        self._labels = ([(f"φ_{i + 1}", "{}") for i in range(plain)]
                        + [(f"ψ_{a + 1}", "α({first})") for a in range(held)]
                        + [(f"ψ_{a + 1}", "β({last})") for a in range(held)])
        #: what each constraint is: "φ", "ψ∘α" (ψ at the first node) or "ψ∘β"; a
        #: DomainError raised by __call__ carries the kinds of the violated ones as .violated
        self._kinds = ["φ"] * plain + ["ψ∘α"] * held + ["ψ∘β"] * held
        #: (position, name) of the parameters the constraints depend on (named in messages)
        self.used = [(i, str(p)) for i, p in enumerate(step.parameters)
                     if any(sp.sympify(c).has(p) for c in functions)]
        program = constraint_program(step)
        self._phi = program.numpy_function(["values"], ["a", "p"])
        self._size = program.numpy_function(["sizes"], ["a", "p"])

    def label(self, offsets: tuple[int, ...], i: int) -> str:
        """How a message names constraint ``i`` on the window of arrows at ``offsets``:
        φ_1(g_k), φ_1(g_{k-1}, g_k), ψ_1(α(g_k)), ψ_1(β(g_k))."""
        from .._symbols import step_label

        arrows = ["g_" + step_label(o) for o in offsets]
        name, where = self._labels[i]
        return name + "(" + where.format(", ".join(arrows), first=arrows[0],
                                          last=arrows[-1]) + ")"

    def violations(self, known: np.ndarray, params: np.ndarray, atol: float
                   ) -> list[tuple[tuple[int, ...], int, float, float]]:
        """(arrow offsets, constraint index, value, tolerance) of every violated constraint."""
        out = []
        for offsets, index in self.windows:
            x = np.asarray(known, float)[index]
            with np.errstate(all="ignore"):
                values = np.asarray(self._phi(x, params)[0], float).ravel()
                sizes = np.asarray(self._size(x, params)[0], float).ravel()
            tol = np.maximum(atol, CONSTRAINT_ROUNDING * _EPS * np.nan_to_num(sizes))
            for i, (v, t) in enumerate(zip(values, tol)):
                if not abs(v) <= t:
                    out.append((offsets, i, float(v), float(t)))
        return out

    def values(self, states: np.ndarray, params: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """|φ_i| on every known arrow of each row of ``states``, and the rounding level
        CONSTRAINT_ROUNDING·ε·M_i it is judged against: two (rows, windows·m) arrays."""
        states = np.atleast_2d(np.asarray(states, float))
        rows = len(states)
        values, levels = [np.zeros((rows, 0))], [np.zeros((rows, 0))]
        for _, index in self.windows:
            x = states[:, index].T
            with np.errstate(all="ignore"):
                phi = [np.broadcast_to(np.asarray(v, float), (rows,))
                       for v in self._phi(x, params)[0]]
                size = [np.broadcast_to(np.asarray(v, float), (rows,))
                        for v in self._size(x, params)[0]]
            values.append(np.abs(np.stack(phi, axis=1)))
            levels.append(CONSTRAINT_ROUNDING * _EPS * np.nan_to_num(np.stack(size, axis=1)))
        return np.hstack(values), np.hstack(levels)

    def __call__(self, known: np.ndarray, params: np.ndarray, *, atol: float,
                 owner: str = "") -> None:
        """A :class:`DomainError` listing the violation of each constraint that does not
        hold on ``known`` (|φ_i| > max(atol, CONSTRAINT_ROUNDING·ε·M_i))."""
        bad = self.violations(known, params, atol)
        if not bad:
            return
        lines = [f"{self.label(offsets, i)} = {v:.3e} (tolerance {t:.1e})"
                 for offsets, i, v, t in bad]
        values = np.asarray(params, float).ravel()
        given = (f" (with the parameters {', '.join(f'{n}={values[i]:.6g}' for i, n in self.used)})"
                 if self.used else "")
        error = DomainError(f"{_where(owner)}the initial state violates the constraints"
                            f"{given}: {'; '.join(lines)}; Simulator.project_initial(state, "
                            f"params) moves a nearby state onto them")
        error.violated = tuple(self._kinds[i] for _, i, _, _ in bad)
        raise error


@functools.lru_cache(maxsize=32)
def constraint_check(step) -> ConstraintCheck:
    """The (cached) :class:`ConstraintCheck` of a step."""
    return ConstraintCheck(step)


#: boundary configurations must satisfy the holonomic constraints to this tolerance (or to
#: the rounding level of evaluating ψ there, when larger), as initial states do
BOUNDARY_CONSTRAINT_TOLERANCE = 1e-10


def check_holonomic_nodes(system, arrows: Sequence, labels: Sequence[tuple[str, str]],
                          params, *, atol: float = BOUNDARY_CONSTRAINT_TOLERANCE,
                          owner: str = "") -> None:
    """A :class:`DomainError` unless ψ(α(a)) = 0 = ψ(β(a)) for every arrow a of ``arrows``
    (numeric flat coordinates; ``labels``: how to name the source and the target of each):
    boundary data of a problem with holonomic constraints must lie on M = {ψ = 0}
    (docs/conventions.md §15).  Nothing to check without holonomic constraints."""
    program = holonomic_program(system)
    if program is None:
        return
    G = system.groupoid
    psi = program.numpy_function(["values"], ["q", "p"])
    size = program.numpy_function(["sizes"], ["q", "p"])
    p = np.asarray(params, float)
    bad = []
    for a, names in zip(arrows, labels):
        a = tuple(float(v) for v in a)
        for end, q in zip(names, (G.source(a), G.target(a))):
            with np.errstate(all="ignore"):
                values = np.asarray(psi(np.asarray(q, float), p)[0], float).ravel()
                sizes = np.asarray(size(np.asarray(q, float), p)[0], float).ravel()
            tol = np.maximum(atol, CONSTRAINT_ROUNDING * _EPS * np.nan_to_num(sizes))
            bad += [f"ψ_{i + 1}({end}) = {v:.3e} (tolerance {t:.1e})"
                    for i, (v, t) in enumerate(zip(values, tol)) if not abs(v) <= t]
    if bad:
        raise DomainError(f"{_where(owner)}the boundary data are not on the holonomic "
                          f"constraint set M = {{ψ = 0}}: {'; '.join(bad)}")
