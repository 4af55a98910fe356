"""Helpers shared by the seed-verification tests: exact comparison of rational expressions and
the seeds' printed closed forms (Cayley map on SO(3) and SE(2)), written out independently of
the library's own implementations."""

from __future__ import annotations

import random
from collections.abc import Iterable, Mapping, Sequence

import sympy as sp


def substitute(expr: sp.Expr, values: Mapping) -> sp.Expr:
    """``expr.xreplace(values)`` with every substituted power base cancelled first.

    Rational expressions such as ``1/(1 + tr g)`` with ``g = cay(ω)`` collapse to a single
    fraction (``(4 + |ω|²)/16``) before the outer expression is combined, which keeps the final
    :func:`sympy.cancel` small.  The result is exactly equal to ``expr.xreplace(values)``.
    """
    keys = set(values)
    pows = [p for p in expr.atoms(sp.Pow) if p.base.free_symbols & keys]
    bases = {p: sp.factor(sp.cancel(p.base.xreplace(values))) ** p.exp for p in pows}
    return expr.xreplace(bases).xreplace(values)


def is_zero(expr: sp.Expr) -> bool:
    """True iff the rational expression ``expr`` is identically zero."""
    return sp.cancel(sp.together(expr)) == 0


def nonzero_somewhere(expr: sp.Expr, seed: int = 0) -> bool:
    """True if ``expr`` is nonzero at a random rational point (so not identically zero).

    Exact rational arithmetic: a nonzero value is a proof, unlike a floating-point one.
    """
    rng = random.Random(seed)
    point = {s: sp.Rational(rng.randint(1, 97), rng.randint(1, 13))
             for s in sorted(expr.free_symbols, key=str)}
    value = sp.cancel(expr.xreplace(point))
    return bool(value != 0 and value.is_finite)  # a pole is no evidence either way


def constant_ratio(derived: sp.Expr, printed: sp.Expr, variables: Iterable[sp.Symbol]) -> sp.Expr:
    """``derived / printed`` if it is a nonzero constant (free of ``variables``); else raise.

    "Equal up to a nonzero constant factor per equation" made precise: the quotient is
    cancelled to lowest terms and must not depend on any coordinate or multiplier.
    """
    assert sp.expand(printed) != 0, "printed equation is identically zero"
    ratio = sp.factor(sp.cancel(sp.together(derived / printed)))
    variables = set(variables)
    assert ratio != 0, f"ratio is zero: derived {derived} vs printed {printed}"
    assert not (ratio.free_symbols & variables), (
        f"not proportional: derived / printed = {ratio} depends on "
        f"{sorted(map(str, ratio.free_symbols & variables))}")
    return ratio


# --- SO(3): seed 001 Appendix D, eqs. (63)-(64) --------------------------------------------

def hat(w: Sequence) -> sp.Matrix:
    """ω̂ with ω̂ v = ω × v (seed 000 §6.2: ω̂ = ω_x E₁ + ω_y E₂ + ω_z E₃)."""
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def axial(M: sp.Matrix) -> sp.Matrix:
    """The vector Π with Π̂ = M for a skew 3×3 matrix M."""
    return sp.Matrix([M[2, 1], M[0, 2], M[1, 0]])


def cay_so3(w: Sequence) -> sp.Matrix:
    """cay(ω̂) = I₃ + 4/(4 + |ω|²)(ω̂ + ω̂²/2) — seed 001 eq. (63)."""
    w = sp.Matrix(w)
    n2 = (w.T * w)[0, 0]
    W = hat(w)
    return (sp.eye(3) + 4 / (4 + n2) * (W + W * W / 2)).applyfunc(sp.cancel)


def dcay_so3_right(w: Sequence) -> sp.Matrix:
    """Right-trivialised dcay_ω = 2/(4 + |ω|²)(2I₃ + ω̂) — seed 001 eq. (64)."""
    w = sp.Matrix(w)
    return 2 / (4 + (w.T * w)[0, 0]) * (2 * sp.eye(3) + hat(w))


def dcay_inv_so3_right(w: Sequence) -> sp.Matrix:
    """Right-trivialised dcay⁻¹_ω = I₃ − ω̂/2 + ωωᵀ/4 — seed 001 eq. (64)."""
    w = sp.Matrix(w)
    return sp.eye(3) - hat(w) / 2 + w * w.T / 4


# --- SE(2): seed 001 Appendix D, general form ------------------------------------------------

def hat_se2(x: Sequence) -> sp.Matrix:
    """(ω, v₁, v₂) ↦ [[0, −ω, v₁], [ω, 0, v₂], [0, 0, 0]]."""
    return sp.Matrix([[0, -x[0], x[1]], [x[0], 0, x[2]], [0, 0, 0]])


def vee_se2(M: sp.Matrix) -> sp.Matrix:
    """Inverse of :func:`hat_se2` on se(2)."""
    return sp.Matrix([M[1, 0], M[0, 2], M[1, 2]])


def cay_se2(x: Sequence) -> sp.Matrix:
    """cay(ξ) = (e − ξ/2)⁻¹(e + ξ/2) — seed 001 App. D (and seed 000 §6.1)."""
    X, e = hat_se2(x), sp.eye(3)
    return ((e - X / 2).inv() * (e + X / 2)).applyfunc(sp.cancel)


def dcay_inv_se2_right(x: Sequence) -> sp.Matrix:
    """Matrix of y ↦ dcay⁻¹_x y = (e − x/2) y (e + x/2) (right-trivialised, seed 001 App. D)."""
    X, e = hat_se2(x), sp.eye(3)
    cols = [vee_se2((e - X / 2) * hat_se2(e[:, j]) * (e + X / 2)) for j in range(3)]
    return sp.Matrix.hstack(*cols).applyfunc(sp.expand)


def dcay_se2_right(x: Sequence) -> sp.Matrix:
    """Matrix of y ↦ dcay_x y = (e − x/2)⁻¹ y (e + x/2)⁻¹ (right-trivialised, seed 001 App. D)."""
    X, e = hat_se2(x), sp.eye(3)
    A, B = (e - X / 2).inv(), (e + X / 2).inv()
    cols = [vee_se2(A * hat_se2(e[:, j]) * B) for j in range(3)]
    return sp.Matrix.hstack(*cols).applyfunc(sp.cancel)


def gradient(f: sp.Expr, x: Sequence) -> sp.Matrix:
    """Column of partial derivatives ∂f/∂x_a."""
    return sp.Matrix([sp.diff(f, v) for v in x])
