"""Named views of the flat known state of a step.

The known state of a first-order step is the arrow g_k followed by the multipliers λ_k
(a second-order step: g_{k-1}, g_k, g_{k+1}, λ_{k-1}, λ_k).  Users name its parts as the
groupoid names them (``groupoid.symbols_by_name``).  A part that occurs at several steps of
the state is given as the sequence of its consecutive values, oldest first:

- a coordinate of a pair-groupoid factor, g_k = (q_{k-1}, q_k): two consecutive
  configurations ``"x": (x_0, x_1)``;
- a matrix part (a Lie-group factor, ``"g"``, ``"W"``): its matrix (checked to be in the
  group);
- another coordinate (the point Γ of an action groupoid): its value; a vector part
  (``"Gamma"``) as the whole vector or by components (``"Gamma_1"``, …);
- the multipliers: ``"lambda"``, m values (required when there are constraints; when all
  of them are holonomic they enter no step and default to 0, docs/conventions.md §15).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from .._errors import DomainError, InputNameError, ShapeError
from .._symbols import multiplier_symbols, step_label
from ..equations import structure_program
from ..groupoids import MatrixLieGroup
from ._validate import (
    GROUP_TOLERANCE,
    arrow,
    assumptions_test,
    real_array,
    rounded_group_matrix,
    violated_assumption,
)

__all__ = ["GROUP_TOLERANCE", "JOIN_ROUNDING", "MULTIPLIER_KEYS", "Part", "StateLayout"]

#: how closely (relative to 1 + |value|) consecutive states of a run must join
#: (:meth:`StateLayout.unjoined_row`): to the rounding of the structure maps
JOIN_ROUNDING = 64 * float(np.finfo(float).eps)

MULTIPLIER_KEYS = ("lambda", "λ", "multipliers")
_OFFSETS = range(-3, 4)


@dataclass
class Part:
    """One named part: ``index[o]`` are the positions of its entries at ``offsets[o]``.

    An index of -1 marks a fixed entry with value ``fixed`` (e.g. the last row of an SE(n)
    matrix); elsewhere ``fixed`` is the constant an entry adds to its coordinate (the 1 on
    the diagonal of an increment F stored as F − I: value = state + fixed).  ``shape`` is
    the shape of one value ((), (n,) or (n, n)).
    """

    name: str
    offsets: tuple
    index: np.ndarray
    fixed: np.ndarray
    group: MatrixLieGroup | None = None

    @property
    def shape(self) -> tuple:
        return self.index.shape[1:]

    @property
    def is_sequence(self) -> bool:
        return len(self.offsets) > 1


def _group_parts(groupoid) -> dict[str, MatrixLieGroup]:
    """Part name → the matrix group its values lie in (every groupoid names its groups:
    Lie groups, the configurations of a pair groupoid of groups, the increments of
    :class:`TrivialisedPairGroupoid`, action and product groupoids)."""
    try:
        return dict(groupoid.named_groups())
    except Exception:  # noqa: BLE001 - a user groupoid without named groups
        return {}


def _indices(value, position: dict) -> tuple[np.ndarray, np.ndarray] | None:
    """Index and fixed-value arrays of a symbol, list or matrix; None unless it is known.
    An entry is a known coordinate, a number, or a known coordinate plus a number."""
    if isinstance(value, sp.MatrixBase):
        entries = value
    elif isinstance(value, (list, tuple)):
        entries = sp.Matrix(list(value))
    else:
        entries = sp.Matrix([value])
    idx = np.full(entries.shape, -1, dtype=np.int64)
    fixed = np.zeros(entries.shape)
    for i, j in np.ndindex(*entries.shape):
        e = sp.sympify(entries[i, j])
        shift, e = e.as_coeff_Add() if e.is_Add else (sp.S.Zero, e)
        if e in position:
            idx[i, j], fixed[i, j] = position[e], float(shift)
        elif e.is_number:
            fixed[i, j] = float(e + shift)
        else:
            return None
    if (idx < 0).all():
        return None
    if isinstance(value, sp.MatrixBase) and value.shape[1] != 1:
        return idx, fixed
    if isinstance(value, (sp.MatrixBase, list, tuple)):
        return idx[:, 0], fixed[:, 0]
    return idx.reshape(()), fixed.reshape(())


def _part(name: str, values: dict, position: dict, group) -> Part | None:
    found = {o: _indices(v, position) for o, v in values.items()}
    found = {o: f for o, f in found.items() if f is not None}
    if not found:
        return None
    offsets = tuple(sorted(found))
    index = np.stack([found[o][0] for o in offsets])
    return Part(name, offsets, index, found[offsets[0]][1], group)


class StateLayout:
    """The named parts of a step's known state and conversions to and from it."""

    def __init__(self, step):
        self.step_name = step.name
        self.equations = step  # the StepEquations (diagnostics evaluate its system's L, φ)
        self.groupoid = step.groupoid
        self.n_known = len(step.knowns)
        self.n_multipliers = step.n_constraints
        self.n_holonomic = getattr(step, "n_holonomic", 0)
        position = {s: i for i, s in enumerate(step.knowns)}
        #: positions in the flat state of the coordinates of each known arrow, by offset
        self.arrow_index = {o: np.array([position[c] for c in a], dtype=np.int64)
                            for o, a in sorted(step.arrows.items())
                            if all(c in position for c in a)}
        groups = _group_parts(step.groupoid)
        tables = {o: step.groupoid.symbols_by_name(o) for o in _OFFSETS}
        names = list(dict.fromkeys(n for o in _OFFSETS for n in tables[o]))
        self.parts: dict[str, Part] = {}
        for name in names:
            values = {o: tables[o][name] for o in _OFFSETS if name in tables[o]}
            part = _part(name, values, position, groups.get(name))
            if part is not None:
                self.parts[name] = part
        self.names = list(self.parts)
        self.multiplier_part = None
        if self.n_multipliers:
            values = {o: multiplier_symbols(self.n_multipliers, o) for o in _OFFSETS}
            self.multiplier_part = _part("lambda", values, position, None)
        self._input_layout(step)

    def _input_layout(self, step) -> None:
        """A forced system's inputs (docs/conventions.md §20): the part named after each
        input holds u_k, the input of the state's arrow (``input_index``); after it the
        state holds the input of the arrow the next step computes (``upcoming_index``),
        which a run writes before each step."""
        self.input_symbols = tuple(getattr(step, "inputs", []))
        #: a fast test of one step's inputs against their symbols' assumptions (None: none)
        self.input_test = assumptions_test(self.input_symbols)
        inputs = [str(u) for u in self.input_symbols]
        self.input_names = inputs
        # the knowns end with the inputs of the known terms (first order u_k; second order
        # u_{k-1}, u_k), then u_{k+1}
        m, n, order = len(inputs), self.n_known, getattr(step, "order", 1)
        now, new = list(range(n - 2 * m, n - m)), list(range(n - m, n))
        self.input_index = np.array(now, dtype=np.int64)
        self.upcoming_index = np.array(new, dtype=np.int64)
        offsets = tuple(range(1 - order, 1))
        for i, name in enumerate(inputs):
            index = [n - m * (2 - o) + i for o in offsets]
            self.parts[name] = Part(name, offsets, np.array(index, dtype=np.int64),
                                    np.zeros(()), None)
        self.names = list(self.parts)

    @property
    def n_inputs(self) -> int:
        """Inputs per arrow (0 for a system without inputs)."""
        return len(getattr(self, "input_index", ()))

    # --- user input → flat state --------------------------------------------------------------
    def pack(self, initial: Mapping) -> np.ndarray:
        """The flat known vector from named parts (see the module docstring)."""
        state = np.full(self.n_known, np.nan)
        given = np.zeros(self.n_known, dtype=bool)
        multipliers = None
        for key, value in initial.items():
            key = str(key)
            if key in MULTIPLIER_KEYS:
                multipliers = value
                continue
            if key not in self.parts:
                raise InputNameError(f"{self.step_name}: unknown state part {key!r}; the parts are "
                               f"{', '.join(self.names)}"
                               + (" and 'lambda'" if self.n_multipliers else ""))
            if key in self.input_names and np.size(value) == 1:
                value = np.reshape(np.asarray(value, dtype=object), ())[()]  # u or [u]
            self._assign(state, given, self.parts[key], value)
        self._pack_multipliers(state, given, multipliers)
        if self.n_inputs:  # until a run writes the next arrow's input: the state's own
            state[self.upcoming_index] = state[self.input_index]
        missing = [p.name for p in self.parts.values()
                   if not given[p.index[p.index >= 0]].all()]
        if missing:
            raise InputNameError(f"{self.step_name}: the initial state misses {', '.join(missing)}")
        self.check_finite(state)
        return state

    def check_finite(self, state: np.ndarray) -> None:
        """A :class:`DomainError` naming the non-finite entries of a flat state, or an input
        value (of its arrow or the next) that violates an assumption its symbol is declared
        with (:func:`check_input_values`)."""
        indices = np.flatnonzero(~np.isfinite(state))
        if self.n_inputs:  # the next arrow's copy of a bad input of the state: named once
            copies = {int(n) for n, i in zip(self.upcoming_index, self.input_index)
                      if not np.isfinite(state[i])}
            indices = [i for i in indices if int(i) not in copies]
        bad = [self.describe(i) for i in indices]
        if bad:
            raise DomainError(f"{self.step_name}: non-finite initial data in {', '.join(bad)}")
        if self.n_inputs:
            index = np.stack([self.input_index, self.upcoming_index])
            check_input_values(self.input_symbols, state[index], self.step_name,
                               lambda row, i: f"in the state ({self.describe(index[row, i])})")

    def rounded(self, state: np.ndarray) -> np.ndarray:
        """A flat state whose group parts are given to a few digits, with each replaced by
        the nearest element of its group (a warning says so; :func:`rounded_group_matrix`),
        as named parts are; a part farther from its group is left to :meth:`check_arrows`,
        which reports it."""
        out = state
        for part in self.parts.values():
            if part.group is None:
                continue
            index = np.where(part.index >= 0, part.index, 0)
            values = np.where(part.index >= 0, state[index] + part.fixed, part.fixed)
            for o, value in enumerate(values):  # one value per offset the part is held at
                near = rounded_group_matrix(part.group, value, repr(part.name),
                                            owner=self.step_name, check=False)
                if near is not value:
                    out = out.copy() if out is state else out
                    mask = part.index[o] >= 0
                    out[part.index[o][mask]] = (near - part.fixed)[mask]
        return out

    def check_arrows(self, state: np.ndarray) -> None:
        """Every known arrow of a flat state checked as named parts are (:func:`arrow`:
        each matrix part in its group; then every group part, e.g. the configurations of
        a pair groupoid of rotations, which are not matrix parts of the arrow)."""
        for o, index in self.arrow_index.items():
            arrow(self.groupoid, state[index], f"the arrow g_{step_label(o)} of the state",
                  owner=self.step_name)
        for part in self.parts.values():
            if part.group is not None:
                index = np.where(part.index >= 0, part.index, 0)
                for value in np.where(part.index >= 0, state[index] + part.fixed, part.fixed):
                    rounded_group_matrix(part.group, value, f"the state's {part.name!r} part",
                                         owner=self.step_name)

    def off_group_rows(self, states: np.ndarray) -> np.ndarray:
        """The rows of ``states`` (N, n_known) whose group parts are not in their groups to
        :data:`GROUP_TOLERANCE` (|RᵀR − I|, det R − 1, SE(n)'s last row), computed for all
        rows at once: the rows :meth:`check_arrows` has to look at (the rest pass it)."""
        states = np.asarray(states, float)
        bad = np.zeros(len(states), dtype=bool)
        for part in self.parts.values():
            group = part.group
            if group is None:
                continue
            index = np.where(part.index >= 0, part.index, 0)
            values = np.where(part.index >= 0, states[:, index] + part.fixed, part.fixed)
            M = values.reshape(len(states), -1, group.n, group.n)
            bad |= ~(group.deviations(M) <= GROUP_TOLERANCE).all(axis=-1)
        return np.flatnonzero(bad)

    def unjoined_row(self, states: np.ndarray, steps: np.ndarray,
                     params: np.ndarray) -> int | None:
        """The first row k of ``states`` (N, n_known), kept at the steps ``steps``, whose
        arrows do not join those of row k + 1 kept at the next step: the arrows a
        second-order state shares with the next differ, or the target of its newest arrow
        is not the source of the next state's newest, beyond :data:`JOIN_ROUNDING` of
        1 + |value| (the rounding of the structure maps: a step copies or computes the new
        arrow's source exactly as its program does); None when every such pair joins.
        ``params``: the parameter values, which a groupoid's maps may read."""
        states = np.asarray(states, float)
        rows = np.flatnonzero(np.diff(np.asarray(steps)) == 1)
        offsets = list(self.arrow_index)
        if not len(rows) or not offsets:
            return None
        here, there = states[rows], states[rows + 1]
        bad = np.zeros(len(rows), dtype=bool)
        for older, newer in zip(offsets, offsets[1:]):  # a second-order state's shared arrow
            bad |= ~_close(here[:, self.arrow_index[newer]], there[:, self.arrow_index[older]])
        a = here[:, self.arrow_index[offsets[-1]]].T
        b = there[:, self.arrow_index[offsets[-1]]].T
        target, inverse = _structure_maps(self.groupoid, tuple(self.equations.parameters))
        p = np.asarray(params, float)
        with np.errstate(all="ignore"):
            ends = np.asarray(target(a, p)[0], float).reshape(-1, len(rows))
            starts = np.asarray(target(np.asarray(inverse(b, p)[0], float), p)[0],
                                float).reshape(-1, len(rows))
        bad |= ~_close(ends.T, starts.T)
        return int(rows[np.argmax(bad)]) if bad.any() else None

    def _assign(self, state, given, part: Part, value) -> None:
        arr = self._as_array(part, value)
        arr = np.stack([self._check_group(part, a) for a in arr])
        mask = part.index >= 0
        idx = part.index[mask]
        if given[idx].any():
            raise InputNameError(f"{self.step_name}: state part {part.name!r} given twice (it "
                             f"overlaps another part given)")
        state[idx] = (arr - part.fixed)[mask]
        given[idx] = True

    def _as_array(self, part: Part, value) -> np.ndarray:
        """Values of ``part`` as an array of shape (len(offsets),) + part.shape."""
        arr = real_array(value, f"state part {part.name!r}", owner=self.step_name)
        expected = part.index.shape if part.is_sequence else part.shape
        if arr.shape != expected:
            count = len(part.offsets)
            steps = ", ".join(f"{part.name}_{{k{o:+d}}}" if o else f"{part.name}_k"
                              for o in part.offsets)
            what = (f"{count} consecutive values, oldest first ({steps}), each "
                    + ("a number" if part.shape == () else f"of shape {part.shape}")
                    if part.is_sequence else f"shape {part.shape}")
            got = ("a single value" if part.is_sequence and arr.shape == part.shape
                   else f"shape {arr.shape}")
            raise ShapeError(f"{self.step_name}: state part {part.name!r} needs {what}; got "
                             f"{got}")
        return arr if part.is_sequence else arr[None]

    def _check_group(self, part: Part, arr: np.ndarray) -> np.ndarray:
        """One value of a part: its fixed entries checked, and a group element (given to a
        few digits: the nearest one, with a warning)."""
        mask = part.index[0] < 0
        if mask.any() and not np.allclose(arr[mask], part.fixed[mask], rtol=0,
                                          atol=GROUP_TOLERANCE):
            raise DomainError(f"{self.step_name}: {part.name!r} must have the fixed entries "
                             f"{part.fixed[mask].tolist()}")
        group = part.group
        if group is None or not np.isfinite(arr).all():
            return arr
        return rounded_group_matrix(group, arr, repr(part.name), owner=self.step_name)

    def _pack_multipliers(self, state, given, multipliers) -> None:
        part = self.multiplier_part
        if part is None:
            if multipliers is not None and np.size(multipliers) != 0:
                raise ShapeError(f"{self.step_name}: the system has no constraints, hence no "
                                 f"multipliers; got lambda={multipliers!r}")
            return
        if multipliers is None and self.n_holonomic == self.n_multipliers:
            # only holonomic multipliers: those of the known arrows sit at their sources,
            # nodes no step varies again, so they enter no step (docs/conventions.md §15)
            multipliers = np.zeros(part.index.shape if part.is_sequence else part.shape)
        if multipliers is None:
            raise InputNameError(f"{self.step_name}: the initial state misses lambda "
                           f"({self.n_multipliers} multipliers per step); give them, or start "
                           f"from a momentum (Simulator.from_momentum) to have them solved for")
        self._assign(state, given, part, multipliers)

    # --- flat states → named arrays -------------------------------------------------------------
    def arrows(self, states: np.ndarray) -> np.ndarray:
        """The arrows of consecutive states, oldest first: the known arrows of the first
        state, then the newest known arrow of every later state (first order: g_0 … g_N;
        second order: g_{-1}, g_0, g_1, …, g_{N+1})."""
        states = np.asarray(states, float)
        offsets = list(self.arrow_index)
        if not offsets:
            raise ShapeError(f"{self.step_name}: the state holds no complete arrow")
        first = [states[0, self.arrow_index[o]] for o in offsets[:-1]]
        newest = states[:, self.arrow_index[offsets[-1]]]
        return np.vstack(first + [newest]) if first else newest

    def view(self, states: np.ndarray, name: str) -> np.ndarray:
        """A part over consecutive states: its values at all the steps they cover.

        A part held at several offsets (q_{k-1}, q_k) gives the oldest values of the first
        state followed by the newest value of every state: q_0, q_1, …, q_{N+1}.
        """
        part = self.multiplier_part if name in MULTIPLIER_KEYS else self.parts[name]
        if part is None:
            return np.zeros((len(states), 0))
        idx = np.where(part.index >= 0, part.index, 0)
        values = np.where(part.index >= 0, states[:, idx] + part.fixed, part.fixed)
        return np.concatenate([values[0, :-1], values[:, -1]], axis=0)

    def describe(self, index: int) -> str:
        """Human name of a flat state entry, e.g. ``g[0, 2]`` or ``x (step k-1)``."""
        parts = list(self.parts.values())
        if self.multiplier_part is not None:
            parts.append(self.multiplier_part)
        for part in parts:
            hits = np.argwhere(part.index == index)
            if len(hits):
                o, *pos = (int(v) for v in hits[0])
                where = f"[{', '.join(map(str, pos))}]" if pos else ""
                label = f" (step k{part.offsets[o]:+d})" if part.offsets[o] else ""
                return f"{part.name}{where}{label}"
        upcoming = np.flatnonzero(getattr(self, "upcoming_index", np.zeros(0)) == index)
        if upcoming.size:  # the slot of the input the next step reads, u_{k+1}
            return f"{self.input_names[int(upcoming[0])]} (step k+1)"
        return f"known[{index}]"


def check_input_values(symbols: Sequence, values: np.ndarray, owner: str, where) -> None:
    """A :class:`DomainError` when an input value violates an assumption its symbol is
    declared with (``positive=True``, ``integer=True``, …): the forces were derived under it
    (√(w²) is w for a positive w), so a run with another value would solve equations the
    user did not write.  ``values`` (…, m), column i the values of input ``symbols[i]``;
    ``where(row, i)`` words the place of the first violation (row: its flat row index)."""
    table = np.asarray(values, dtype=float).reshape(-1, len(symbols))
    for i, symbol in enumerate(symbols):
        found = violated_assumption(symbol, table[:, i])
        if found is not None:
            row, what = found
            raise DomainError(f"{owner}: input {symbol} is declared {what}, got "
                              f"{float(table[row, i])!r} {where(row, i)}; the forces were derived "
                              f"under that assumption")


def _close(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Per row, whether ``x`` and ``y`` agree to :data:`JOIN_ROUNDING` of 1 + |value|."""
    scale = 1.0 + np.maximum(np.abs(x), np.abs(y))
    return (np.abs(x - y) <= JOIN_ROUNDING * scale).all(axis=-1)


@functools.lru_cache(maxsize=16)
def _structure_maps(groupoid, parameters: tuple) -> tuple:
    """The NumPy forms of the target and the inverse of ``groupoid``'s structure program
    (:func:`~symgroupoid.equations.structure_program`), each also reading ``p``."""
    program = structure_program(groupoid, parameters)
    return (program.numpy_function(["target"], ["a", "p"]),
            program.numpy_function(["inverse"], ["a", "p"]))
