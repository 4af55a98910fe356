"""Pair groupoid Q × Q ⇉ Q: the derived equations are the Marsden–West discrete Euler–Lagrange
equations D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) = 0 for an *arbitrary* discrete Lagrangian
(seed 000 §2.2, the equation after Remark 2.14; docs/conventions.md §2), and their constrained form
(seed 000 §3.3; docs/conventions.md §4)."""

from __future__ import annotations

import pytest
import sympy as sp

import symgroupoid as sg


def _partial(F: sp.Function, n: int, slot: int, point: tuple) -> sp.Expr:
    """∂F/∂(argument ``slot``) of the undefined function F of ``n`` variables, at ``point``."""
    u = sp.symbols(f"u0:{n}", real=True)
    return sp.diff(F(*u), u[slot]).subs(dict(zip(u, point)), simultaneous=True).doit()


def _marsden_west(F: sp.Function, dim: int, qm: tuple, q: tuple, qp: tuple) -> list[sp.Expr]:
    """D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}), componentwise, for L = F(q₀…, q₁…)."""
    return [_partial(F, 2 * dim, dim + j, qm + q) + _partial(F, 2 * dim, j, q + qp)
            for j in range(dim)]


@pytest.mark.parametrize("names", ["q", "x y", "x y z"])
def test_arbitrary_lagrangian_gives_marsden_west(names: str) -> None:
    """Seed 000 §2.2 (after Remark 2.14): D₂L(q_{k−1},q_k) + D₁L(q_k,q_{k+1}) = 0 for every L.

    L is an undefined function of all 2n coordinates, so nothing about its form can make the
    comparison pass by accident; the residual must equal the Marsden–West expression up to sign.
    """
    space = sg.EuclideanSpace(names)
    n = space.dim
    F = sp.Function("L_d")
    system = sg.DiscreteSystem(sg.PairGroupoid(space), lambda g: F(*g.source, *g.target),
                               name="pair")
    step = system.euler_lagrange()
    qm, q, qp = (tuple(step.symbol(s, off) for s in space.names) for off in ("k-1", "k", "k+1"))
    expected = _marsden_west(F, n, qm, q, qp)
    assert len(step.residuals) == n
    for res, exp in zip(step.residuals, expected):
        # "up to sign": with the convention X⃖[L](g_k) − X⃗[L](g_{k+1}) and the pair-groupoid
        # fields X⃖ = ∂/∂q₁, X⃗ = −∂/∂q₀ (docs/conventions.md §1) the sign is +.
        assert sp.expand(res - exp) == 0
    # the unknowns are q_{k+1}; the knowns are (q_{k−1}, q_k)
    assert step.unknowns == list(qp)
    assert step.knowns == list(qm) + list(q)


def test_wrong_slot_is_detected() -> None:
    """Control for the test above (seed 000 §2.2): D₁L(q_{k−1},q_k) + D₂L(q_k,q_{k+1}) — the
    slots swapped — is *not* what is derived, so the comparison can fail."""
    F = sp.Function("L_d")
    step = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")),
                             lambda g: F(*g.source, *g.target)).euler_lagrange()
    qm, q, qp = (step.symbol("q", s) for s in ("k-1", "k", "k+1"))
    swapped = _partial(F, 2, 0, (qm, q)) + _partial(F, 2, 1, (q, qp))
    assert sp.expand(step.residuals[0] - swapped) != 0
    assert sp.expand(step.residuals[0] + swapped) != 0


def test_constrained_pair_groupoid_arbitrary_functions() -> None:
    """Seed 000 §3.3 / docs/conventions.md §4 on Q × Q with L and φ arbitrary functions on R² × R²:
    D₂(L + λ_k·φ)(q_{k−1}, q_k) + D₁(L + λ_{k+1}·φ)(q_k, q_{k+1}) = 0 and φ(q_k, q_{k+1}) = 0."""
    space = sg.EuclideanSpace("x y")
    F, Phi = sp.Function("L_d"), sp.Function("phi")
    system = sg.DiscreteSystem(sg.PairGroupoid(space), lambda g: F(*g.source, *g.target),
                               constraints=lambda g: [Phi(*g.source, *g.target)], name="cpair")
    step = system.euler_lagrange()
    qm, q, qp = (tuple(step.symbol(s, off) for s in "xy") for off in ("k-1", "k", "k+1"))
    (lk,), (lk1,) = step.symbol("lambda", "k"), step.symbol("lambda", "k+1")
    expected = [_partial(F, 4, 2 + j, qm + q) + lk * _partial(Phi, 4, 2 + j, qm + q)
                + _partial(F, 4, j, q + qp) + lk1 * _partial(Phi, 4, j, q + qp)
                for j in range(2)]
    expected.append(Phi(*q, *qp))
    assert len(step.residuals) == 3
    for res, exp in zip(step.residuals, expected):
        assert sp.expand(res - exp) == 0
    assert step.unknowns == list(qp) + [lk1]
