"""The step's residuals with the pair arrows of its window written in named pieces.

For a discrete Lagrangian written with midpoints and difference quotients (L_d = h·L(q̄, Δq))
the papers print the junction variation of the window action (seed 000 Thm 2.13;
docs/conventions.md §2) in those pieces: the arrow g_j = (q_{j−1}, q_j) of a pair groupoid
is written as

    q_{j−1} = q̄_{j−1/2} − (τ/2) Δq_{j−1/2},    q_j = q̄_{j−1/2} + (τ/2) Δq_{j−1/2},

*before* the variation is substituted into the named arrows, so the derivative of L comes
out in q̄_{k∓1/2} and Δq_{k∓1/2}.  Both forms here come from the one
:class:`~symgroupoid.derivation.WindowAction` and its junction variation, as the step does:

- :func:`piece_residuals`: the residuals in the pieces;
- :func:`partial_residuals`: the first-order residual through the partial derivatives of
  L(q̄, Δq), by the chain rule through the pieces,

      ∂L/∂q₁ = ½ ∂L/∂q̄ + (1/τ) ∂L/∂Δq,    ∂L/∂q₀ = ½ ∂L/∂q̄ − (1/τ) ∂L/∂Δq,

  each partial a named symbol at q̄_{k∓1/2}, Δq_{k∓1/2} (the coefficients ±½, ±1/τ come from
  varying the pieces themselves, so the groupoid's sign conventions carry over).

The printed names of the pieces and partials are the caller's (``names``): the derivation
gives the expressions, the printers choose and format them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import sympy as sp

from ..groupoids import Groupoid, PairCoordinate
from ._assembly import WindowAction
from ._junction import junction_variation
from ._step import SystemFunctions, tidy

#: the symbols (q̄, Δq) of a pair coordinate at a window offset (None: without index)
PieceNames = Callable[[PairCoordinate, "int | None"], tuple]


@dataclass(frozen=True)
class PieceRule:
    """How a pair arrow (q₀, q₁) is written in named pieces, Δq = (q₁ − q₀)/τ:

    - ``midpoint``: q̄ = (q₀ + q₁)/2 and Δq; q₀ = q̄ − τΔq/2, q₁ = q̄ + τΔq/2;
    - ``source``: q₀ kept and Δq; q₁ = q₀ + τΔq;
    - ``target``: q₁ kept and Δq; q₀ = q₁ − τΔq.
    """

    kind: str
    tau: sp.Expr

    def coordinates(self, q0, q1, mid, diff) -> tuple:
        """(q₀, q₁) in the pieces."""
        if self.kind == "midpoint":
            return mid - self.tau * diff / 2, mid + self.tau * diff / 2
        if self.kind == "source":
            return q0, q0 + self.tau * diff
        return q1 - self.tau * diff, q1

    def definitions(self, q0, q1, mid, diff) -> list[tuple[sp.Expr, sp.Expr]]:
        """(piece, its value) pairs; the values are unevaluated, as printed."""
        difference = sp.Add(q1, sp.Mul(-1, q0, evaluate=False), evaluate=False)
        quotient = (difference if self.tau == 1 else
                    sp.Mul(difference, sp.Pow(self.tau, -1, evaluate=False), evaluate=False))
        rows = [(diff, quotient)]
        if self.kind == "midpoint":
            total = sp.Add(q0, q1, evaluate=False)
            rows.insert(0, (mid, sp.Mul(total, sp.Pow(sp.Integer(2), -1, evaluate=False),
                                        evaluate=False)))
        return rows


@dataclass
class WindowPieces:
    """The window's variation with its pair arrows written in pieces: the rows (one per
    basis section, then the constraints on the newest arrow), the slots, and the
    substitution slot → named arrow (pair coordinates → pieces) with the pieces' values."""

    rows: list
    constraints: list
    slots: dict
    substitution: dict
    values: dict
    offsets: list


def window_in_pieces(G: Groupoid, fs: SystemFunctions, rule: PieceRule, names: PieceNames,
                     matrix_form: bool, lagrangian: bool = True) -> WindowPieces:
    """The junction variation of Σ_s [L + λ_s·φ](g_{k+s}) (``lagrangian=False``: of
    Σ_s λ_s·φ only) with each pair arrow written in the pieces of ``rule`` (named
    ``names(coordinate, offset)``) before the slots become the named arrows g_k, g_{k+1}, …"""
    action = WindowAction(G, fs)
    A = action.slots("p", matrix_form)
    variations = action.variation(A, lagrangian=lagrangian)
    arrows = action.named_arrows(matrix_form)
    sub = action.naming(A, arrows)
    values: dict = {}
    for o in action.offsets:
        for c in G.pair_coordinates():
            q0, q1 = arrows[o][c.source], arrows[o][c.target]
            mid, diff = names(c, o)
            sub[A[o][c.source]], sub[A[o][c.target]] = rule.coordinates(q0, q1, mid, diff)
            values.update({p: v.doit() for p, v in rule.definitions(q0, q1, mid, diff)})
    constraints = action.constraints_on(A)
    return WindowPieces([v.xreplace(sub) for v in variations],
                        [c.xreplace(sub) for c in constraints], A, sub, values, action.offsets)


def piece_residuals(G: Groupoid, fs: SystemFunctions, rule: PieceRule, names: PieceNames,
                    matrix_form: bool = False) -> tuple[list, WindowPieces]:
    """The step's residuals (junction rows, then the constraints on the newest arrow) with
    every pair arrow of the window in the pieces of ``rule``, and the window in pieces (its
    ``values``: each piece's value at the named arrows)."""
    w = window_in_pieces(G, fs, rule, names, matrix_form)
    return [tidy(r) for r in w.rows + w.constraints], w


@dataclass
class Partial:
    """∂L/∂(piece) of one pair coordinate (``which``: 0 for q̄, 1 for Δq): its value in
    the unindexed pieces, and its named symbol at each window offset with its value there."""

    coordinate: PairCoordinate
    which: int
    value: sp.Expr
    at: dict  # offset -> the named symbol
    values: dict  # named symbol -> its value in the pieces at that offset


def partial_residuals(G: Groupoid, fs: SystemFunctions, rule: PieceRule, names: PieceNames,
                      partial_names: Callable[[PairCoordinate, int, int], sp.Symbol]
                      ) -> tuple[list, list[Partial], WindowPieces]:
    """The first-order residual with each partial derivative of L(q̄, Δq) a named symbol
    (``partial_names(coordinate, which, offset)``), the partials, and the window of the
    multiplier terms in pieces (module docstring; ``rule`` is a midpoint rule)."""
    coords = G.pair_coordinates()
    w = window_in_pieces(G, fs, rule, names, False, lagrangian=False)
    dummies = [(sp.Dummy(f"m{i}"), sp.Dummy(f"d{i}")) for i in range(len(coords))]
    on_slot = {}
    for c, (mid, diff) in zip(coords, dummies):
        on_slot[fs.slots[0][c.source]], on_slot[fs.slots[0][c.target]] = rule.coordinates(
            None, None, mid, diff)
    ell = fs.lagrangian.xreplace(on_slot)
    rows = list(w.rows)
    partials: list[Partial] = []
    for c, pair in zip(coords, dummies):
        for which in (0, 1):
            partial = sp.diff(ell, pair[which])
            at = {o: partial_names(c, which, o) for o in w.offsets}
            values: dict = {}
            for o in w.offsets:
                A = w.slots[o]
                piece = [(A[c.source] + A[c.target]) / 2, (A[c.target] - A[c.source]) / rule.tau]
                X = junction_variation(G, piece[which], w.slots[0], w.slots[1])
                rows = [r + at[o] * x.xreplace(w.substitution) for r, x in zip(rows, X)]
                values[at[o]] = _in_pieces(partial, coords, dummies, names, o)
            partials.append(Partial(c, which, _in_pieces(partial, coords, dummies, names, None),
                                    at, values))
    return [tidy(r) for r in rows + w.constraints], partials, w


def _in_pieces(expr: sp.Expr, coords, dummies, names: PieceNames, offset: int | None
               ) -> sp.Expr:
    """``expr`` in the piece dummies, written in the named pieces at ``offset``."""
    sub = {}
    for c, (mid, diff) in zip(coords, dummies):
        sub[mid], sub[diff] = names(c, offset)
    return sp.expand(expr.xreplace(sub))
