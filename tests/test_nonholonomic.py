"""Discrete nonholonomic systems: the ball on a rotating table (seed 002;
docs/conventions.md §10)."""

from __future__ import annotations

import numpy as np
import sympy as sp
from conftest import newton, predicted

import symgroupoid as sg


def _ball_on_table():
    h, m, inertia, r, Om = sp.symbols("h m I r Omega", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y")) * sg.SO3("W")
    E1, E2, _ = sg.SO3.basis_matrices()

    def L(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return (m / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)
                - inertia / (2 * h ** 2) * W.trace())

    def Mc(g):
        (x0, y0), (x1, y1) = g[0].source, g[0].target
        W = g[1].matrix
        return [(x1 - x0) / h + r / (2 * h) * (W * E2).trace() + Om * (y1 + y0) / 2,
                (y1 - y0) / h - r / (2 * h) * (W * E1).trace() - Om * (x1 + x0) / 2]

    # sections s1 = ∂x, s2 = ∂y, s3..s5 = E1..E3;  D_c = ⟨s5, r s1 + s4, r s2 − s3⟩
    Dc = [[0, 0, 0, 0, 1], [r, 0, 0, 1, 0], [0, r, -1, 0, 0]]
    system = sg.NonholonomicSystem(G, L, Mc, Dc, parameters=[h, m, inertia, r, Om], name="ball")
    return system, (h, m, inertia, r, Om)


def test_ball_on_rotating_table_matches_printed_equations():
    """The solution of a step satisfies the slide's reduced equations:
    (x₂−2x₁+x₀)/h² + IΩ/(I+mr²)(y₂−y₀)/(2h) = 0, (y₂−2y₁+y₀)/h² − IΩ/(I+mr²)(x₂−x₀)/(2h) = 0,
    tr((W₁−W₂)E₃) = 0, and M_c at step 2."""
    system, _ = _ball_on_table()
    step = system.euler_lagrange()
    assert len(step) == 5 and len(step.unknowns) == 5
    vals = dict(h=0.05, m=1.0, I=0.4, r=0.5, Omega=0.7)
    params = [vals[str(s)] for s in step.parameters]
    W1 = np.array(sg.SO3("t").cayley([0.03, -0.02, 0.05]).tolist(), float)
    E1, E2, E3 = (np.array(E.tolist(), float) for E in sg.SO3.basis_matrices())
    hh, rr, oo = vals["h"], vals["r"], vals["Omega"]
    x0, y0 = 0.99, 1.0
    # choose (x1, y1) on M_c for the given W1: a 2×2 linear solve
    A = np.array([[1 / hh, oo / 2], [-oo / 2, 1 / hh]])
    b = np.array([x0 / hh - rr / (2 * hh) * np.trace(W1 @ E2) - oo * y0 / 2,
                  y0 / hh + rr / (2 * hh) * np.trace(W1 @ E1) + oo * x0 / 2])
    x1, y1 = np.linalg.solve(A, b)
    known = np.concatenate([[x0, y0, x1, y1], W1.ravel()])
    u = newton(step, predicted(step, known, params), known, params)
    nxt = step.advance(u, known, params)
    x2, y2, W2 = nxt[2], nxt[3], nxt[4:].reshape(3, 3)
    k = vals["I"] * oo / (vals["I"] + vals["m"] * rr ** 2)
    assert abs((x2 - 2 * x1 + x0) / hh ** 2 + k * (y2 - y0) / (2 * hh)) < 1e-9
    assert abs((y2 - 2 * y1 + y0) / hh ** 2 - k * (x2 - x0) / (2 * hh)) < 1e-9
    assert abs(np.trace((W1 - W2) @ E3)) < 1e-12
    assert abs((x2 - x1) / hh + rr / (2 * hh) * np.trace(W2 @ E2) + oo * (y2 + y1) / 2) < 1e-12
    assert abs(x2 - x1) > 1e-4  # the ball actually moved


def test_distribution_dimension_is_checked():
    system, _ = _ball_on_table()
    G = system.groupoid
    try:
        sg.NonholonomicSystem(G, system.lagrangian, system.constraints, [[0, 0, 0, 0, 1]],
                              parameters=system.parameters)
    except sg.ShapeError as exc:
        assert "dim D_c (1)" in str(exc)
    else:
        raise AssertionError("a too-small distribution was accepted")
