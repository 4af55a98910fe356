"""The discrete plate-ball system of seed 000 §6.2: the eight equations printed after eq. (8),
transcribed here by hand, against the equations symgroupoid derives from L and φ of eq. (8).

Transcription notes (the seed is OCR'd):

- the rotational rows are read as
  0 = −r(λ_k)₁ tr(g_k E_i E₁) + r(λ_{k+1})₁ tr(E_i g_{k+1} E₁) + r(λ_k)₂ tr(g_k E_i E₂)
      − r(λ_{k+1})₂ tr(E_i g_{k+1} E₂) − (λ_k)₃ tr(g_k E_i E₃) + (λ_{k+1})₃ tr(E_i g_{k+1} E₃),
  i = 1, 2, 3 (tr(g_k E_i E_i) is printed tr(g_k E_i²));
- the multiplier subscripts of the printed y-row are illegible in the OCR; the row is read as
  (y_{k+1} − 2y_k + y_{k−1})/h² + ((λ_{k+1})₁ − (λ_k)₁)/h − Ω((λ_{k+1})₂ + (λ_k)₂)/2, the
  mirror image of the legible x-row under (x, λ₂, Ω) ↔ (y, λ₁, −Ω) that φ¹, φ² of eq. (8) have.
"""

from __future__ import annotations

import pytest
import sympy as sp
from _seedcheck import constant_ratio
from _systems import E1, E2, E3, PB_PARAMETERS, plate_ball_system

import symgroupoid as sg

h, r, Omega, c = PB_PARAMETERS
PARAMETERS = PB_PARAMETERS
E = (E1, E2, E3)


@pytest.fixture(scope="module")
def step() -> sg.StepEquations:
    return plate_ball_system().euler_lagrange()


def printed_equations(step: sg.StepEquations, lambda3_sign: int = 1) -> list[sp.Expr]:
    """Right-hand sides of the eight printed equations 0 = … of seed 000 §6.2.

    ``lambda3_sign = -1`` replaces (λ)₃ by −(λ)₃ (at k and k+1) in the rotational rows: the
    printed rows belong to the constraint −φ³ (docs/conventions.md §6).  A multiplier is defined
    only up to the sign of its constraint, so this is the same set of equations.
    """
    xm, x, xp = (step.symbol("x", s) for s in ("k-1", "k", "k+1"))
    ym, y, yp = (step.symbol("y", s) for s in ("k-1", "k", "k+1"))
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    lk, lp = step.symbol("lambda", "k"), step.symbol("lambda", "k+1")
    tr = sp.Matrix.trace
    eqs = [
        (xp - 2 * x + xm) / h**2 + (lp[1] - lk[1]) / h + Omega * (lp[0] + lk[0]) / 2,
        (yp - 2 * y + ym) / h**2 + (lp[0] - lk[0]) / h - Omega * (lp[1] + lk[1]) / 2,
    ]
    s = lambda3_sign
    for Ei in E:
        eqs.append(-r * lk[0] * tr(gk * Ei * E1) + r * lp[0] * tr(Ei * gp * E1)
                   + r * lk[1] * tr(gk * Ei * E2) - r * lp[1] * tr(Ei * gp * E2)
                   - s * lk[2] * tr(gk * Ei * E3) + s * lp[2] * tr(Ei * gp * E3))
    eqs += [
        (yp - y) / h - r / (2 * h) * tr(gp * E1) - Omega * (xp + x) / 2,
        (xp - x) / h + r / (2 * h) * tr(gp * E2) + Omega * (yp + y) / 2,
        c + tr(gp * E3) / (2 * h),
    ]
    return eqs


def _variables(step: sg.StepEquations) -> set:
    return set(step.knowns) | set(step.unknowns) | set(step.fibre_unknowns)


def test_eight_equations_match_seed_up_to_constants(step: sg.StepEquations) -> None:
    """Seed 000 §6.2, the eight equations after eq. (8): each derived residual is a nonzero
    constant times the printed equation, with (λ)₃ → −(λ)₃ in the printed rotational rows."""
    printed = printed_equations(step, lambda3_sign=-1)
    assert len(step.residuals) == len(printed) == 8
    ratios = [constant_ratio(res, eq, _variables(step))
              for res, eq in zip(step.residuals, printed)]
    # The constants, for the record: DEL rows are −h (translational) and 1/2 (rotational)
    # times the printed ones; the constraint rows are φ(g_{k+1}) = h · printed.
    assert ratios == [-h, -h, sp.Rational(1, 2), sp.Rational(1, 2), sp.Rational(1, 2), h, h, h]


def test_printed_lambda3_sign_is_opposite(step: sg.StepEquations) -> None:
    """docs/conventions.md §6: taken literally, the printed rotational rows (seed 000 §6.2) are
    *not*
    proportional to the DEL of φ³ as printed in eq. (8) — the (λ)₃ terms have the wrong sign.
    This also shows the comparison above can fail."""
    literal = printed_equations(step, lambda3_sign=1)
    for res, eq in zip(step.residuals[2:5], literal[2:5]):
        with pytest.raises(AssertionError, match="not proportional"):
            constant_ratio(res, eq, _variables(step))


def test_symbols_used_are_the_step_symbols(step: sg.StepEquations) -> None:
    """The residuals use exactly the symbols that ``step.symbol`` returns (x, y at k−1, k, k+1;
    g at k, k+1; λ at k, k+1) plus the parameters; unknowns, knowns and reconstruction are
    consistent with them (seed 000 §6.2: eight equations in eight unknowns)."""
    pts = {n: [step.symbol(n, s) for s in ("k-1", "k", "k+1")] for n in ("x", "y")}
    gk, gp = step.symbol("g", "k"), step.symbol("g", "k+1")
    lk, lp = step.symbol("lambda", "k"), step.symbol("lambda", "k+1")
    named = set(pts["x"]) | set(pts["y"]) | set(gk) | set(gp) | set(lk) | set(lp)
    used = set().union(*(res.free_symbols for res in step.residuals))
    assert used - set(PARAMETERS) == named
    assert used & set(PARAMETERS) == set(PARAMETERS)
    assert step.unknowns[:2] == [pts["x"][2], pts["y"][2]]
    assert step.unknowns[-3:] == lp and len(step.unknowns) == 8
    assert step.knowns == [pts["x"][0], pts["y"][0], pts["x"][1], pts["y"][1], *gk, *lk]
    assert set(step.reconstruction) == set(gp) == set(step.fibre_unknowns[2:])
    # g_{k+1} is reconstructed from the three chart unknowns by the Cayley map
    chart = step.unknowns[2:5]
    for entry in gp:
        assert step.reconstruction[entry].free_symbols <= set(chart)
    with pytest.raises(KeyError, match="no coordinate named 'z'"):
        step.symbol("z", "k")
