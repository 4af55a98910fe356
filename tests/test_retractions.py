"""Retractions and their trivialised tangents, checked by finite differences of the group
maps themselves (docs/conventions.md §5: derive dτ from τ, do not trust one printed form)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg


@pytest.mark.parametrize("group,retraction", [
    (sg.SO3, "cayley"), (sg.SE2, "cayley"), (sg.SE2, "exp"),
    pytest.param(sg.SO3, "exp", marks=pytest.mark.slow),  # ~70 s: large exact dexp⁻¹
])
def test_dtau_is_the_trivialised_tangent(group, retraction):
    """T_xτ(y) = τ(x)·dτ_x(y) (left) and dτ_x(y)·τ(x) (right), by central differences of the
    numeric retraction; dτ⁻¹ inverts dτ; both are regular at x = 0 (smooth forms)."""
    G = group("g", retraction=retraction)
    x = sp.symbols(f"x1:{G.rank + 1}", real=True)
    rng = np.random.default_rng(4)
    x0, y = rng.normal(scale=0.4, size=G.rank), rng.normal(size=G.rank)
    tau = [G.numeric_matrix(G.numeric_fibre_chart(v)) for v in (x0, x0 + 1e-6 * y,
                                                                x0 - 1e-6 * y)]
    dT = (tau[1] - tau[2]) / 2e-6
    for side in ("left", "right"):
        D = sp.lambdify([x], G.dtau(x, side), "numpy")
        Dinv = sp.lambdify([x], G.dtau_inverse(x, side), "numpy")
        v = np.asarray(D(x0), float) @ y
        hat = np.array(G.hat(list(v)).tolist(), float)
        expected = tau[0] @ hat if side == "left" else hat @ tau[0]
        assert np.allclose(dT, expected, atol=1e-8)
        assert np.allclose(np.asarray(Dinv(x0), float) @ np.asarray(D(x0), float),
                           np.eye(G.rank), atol=1e-12)
        assert np.allclose(np.asarray(Dinv(np.zeros(G.rank)), float), np.eye(G.rank))
