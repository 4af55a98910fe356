"""Names of the printed pieces, and the rule the pieces are chosen by.

For a discrete Lagrangian written with midpoints and difference quotients (L_d = h·L(q̄, Δq)),
the arrow g_j = (q_{j−1}, q_j) of a pair groupoid prints in the pieces q̄_{j−1/2},
Δq_{j−1/2} (:class:`~symgroupoid.derivation.PieceRule`; the residuals in them come from the
derivation, :func:`~symgroupoid.derivation.piece_residuals`).  Here are their printed names
(q̄_{k−1/2}, Δq_{k+1/2}, (∂_{q̄} L)_{k−1/2}), the generic index j of the "where" list, and
the choice of the rule — and which parameter divides the differences — as the one in which
L and the constraints are shortest.
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp
from sympy.printing.conventions import split_super_sub

from .._symbols import StepSymbol, latex_name
from ..derivation import PieceRule
from ..groupoids import PairCoordinate

# --- names -------------------------------------------------------------------------------------


def indexed_name(base_latex: str, label: str) -> str:
    """``base`` with the subscript ``label``, parenthesised when ``base`` has one already
    (the convention of the step symbols: x_{k+1}, (θ_{1})_{k+1})."""
    if "_" in base_latex or "^" in base_latex:
        return f"({base_latex})_{{{label}}}"
    return f"{base_latex}_{{{label}}}"


def half_label(index: str, offset: int) -> str:
    """The subscript of the midpoint of the arrow g_{index+offset} = (q_{…−1}, q_{…}):
    ``k-1/2`` for offset 0, ``k+1/2`` for 1, ``k+3/2`` for 2."""
    twice = 2 * offset - 1
    return f"{index}{'+' if twice > 0 else '-'}{abs(twice)}/2"


def arrow_label(index: str, offset: int) -> str:
    """``k``, ``k+1``, ``j-1``: the subscript of a step index plus an offset."""
    return index if offset == 0 else f"{index}{offset:+d}"


def accented(name: str, accent: str) -> str:
    """LaTeX of a coordinate name with an accent on its root: ``theta1`` →
    ``\\bar{\\theta}_{1}``."""
    root, sups, subs = split_super_sub(name)
    tex = f"{accent}{{{latex_name(root)}}}"
    if sups:
        tex += "^{" + " ".join(latex_name(s) for s in sups) + "}"
    if subs:
        tex += "_{" + " ".join(latex_name(s) for s in subs) + "}"
    return tex


# --- pair coordinates and the rules that name their pieces --------------------------------------


def pair_coordinates(G) -> list[PairCoordinate]:
    """The pair-of-Euclidean-space coordinates of G's arrows (through products;
    ``G.pair_coordinates()``)."""
    return G.pair_coordinates()


def piece_roots(coord: PairCoordinate) -> tuple[str, str]:
    """The LaTeX of q̄ and Δq of one coordinate, without index: ``\\bar{\\theta}_{1}``,
    ``\\Delta\\theta_{1}``."""
    return accented(coord.name, "\\bar"), f"\\Delta {latex_name(coord.name)}"


def piece_symbols(coord: PairCoordinate, label: str | None) -> tuple[StepSymbol, StepSymbol]:
    """q̄ and Δq of one coordinate at the subscript ``label`` (None: without index, the
    arguments of L(q̄, Δq) in the "where" rows of its partial derivatives)."""
    mid, diff = piece_roots(coord)
    if label is None:
        return StepSymbol(mid), StepSymbol(diff)
    return StepSymbol(indexed_name(mid, label)), StepSymbol(indexed_name(diff, label))


def window_piece_symbols(coord: PairCoordinate, offset: int | None
                         ) -> tuple[StepSymbol, StepSymbol]:
    """q̄ and Δq of one coordinate on the window arrow g_{k+offset}, subscript k+offset−1/2
    (None: without index): the names the derivation writes the pieces in."""
    return piece_symbols(coord, None if offset is None else half_label("k", offset))


def _rule_score(fs, coords: Sequence[PairCoordinate], rule: PieceRule | None) -> int:
    """Operation count of L + Σφ with every slot written by ``rule`` (None: as given)."""
    expr = fs.lagrangian + sum(fs.constraints, sp.S.Zero)
    if rule is None:
        return sp.count_ops(expr)
    sub: dict = {}
    for s, slot in enumerate(fs.slots):
        for i, c in enumerate(coords):
            mid, diff = sp.Dummy(f"m{s}_{i}"), sp.Dummy(f"d{s}_{i}")
            sub[slot[c.source]], sub[slot[c.target]] = rule.coordinates(
                slot[c.source], slot[c.target], mid, diff)
    return sp.count_ops(expr.xreplace(sub))


def best_rule(fs, coords: Sequence[PairCoordinate], parameters: Sequence) -> PieceRule | None:
    """The rule in which L and the constraints are shortest, if shorter than as written:
    the pieces are those "L is written with"."""
    if not coords:
        return None
    best, score = None, _rule_score(fs, coords, None)
    for kind in ("midpoint", "source", "target"):
        for tau in [*parameters, sp.S.One]:
            rule = PieceRule(kind, tau)
            s = _rule_score(fs, coords, rule)
            if s < score:
                best, score = rule, s
    return best


def partial_symbol(root: str, label: str | None) -> StepSymbol:
    """(∂_{root} L)_{label}: a partial derivative of the discrete Lagrangian, evaluated at the
    arrow whose pieces carry ``label`` (None: ∂_{root} L itself, a function of the pieces)."""
    name = f"\\partial_{{{root}}} L"
    return StepSymbol(name if label is None else indexed_name(name, label))


def window_partial_symbol(coord: PairCoordinate, which: int, offset: int) -> StepSymbol:
    """(∂_{q̄} L)_{k+offset−1/2} (``which`` 0) or (∂_{Δq} L)_{k+offset−1/2} (1) of one
    coordinate: the names the derivation writes the partials of L in."""
    return partial_symbol(piece_roots(coord)[which], half_label("k", offset))


def generic_arrow(G) -> tuple:
    """g_j: the named arrow g_k with the index k renamed j (every coordinate)."""
    return tuple(sp.sympify(c).xreplace(generic_renaming(G)) for c in G.named_arrow(0))


def generic_renaming(G) -> dict:
    """The named coordinates at k−1 and k → the same names at j−1 and j (scalars by name,
    matrix parts entry by entry: (W_{k})_{12} → (W_{j})_{12})."""
    rename: dict = {}
    for offset in (-1, 0):
        label = arrow_label("j", offset)
        for name, s in G.symbols_by_name(offset).items():
            if isinstance(s, sp.Symbol):
                rename[s] = StepSymbol(indexed_name(latex_name(name), label))
            elif isinstance(s, sp.MatrixBase) and s.shape[1] > 1:
                base = indexed_name(latex_name(name), label)
                for (i, j), entry in zip(((i, j) for i in range(s.rows) for j in range(s.cols)),
                                         s):
                    rename[entry] = StepSymbol(f"({base})_{{{i + 1}{j + 1}}}")
    return rename


