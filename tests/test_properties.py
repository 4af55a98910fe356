"""Property tests (hypothesis) of derived steps (the groupoids' own properties, among them
[X⃖, Y⃗] = 0, run over every groupoid in test_groupoid_properties.py).

2. The exact step Jacobian agrees with central finite differences of the residual through
   ``StepEquations.evaluate`` at random points: plate-ball (seed 000 §6.2), heavy top (seed 002),
   optimal control on SE(2) with the Cayley retraction (seed 000 §6.1).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from _systems import (
    heavy_top_system,
    plate_ball_system,
    se2_control_system,
)
from hypothesis import given, settings
from hypothesis import strategies as st

import symgroupoid as sg

SETTINGS = settings(max_examples=20, deadline=None)
seeds = st.integers(min_value=0, max_value=2**32 - 1)

# --- 2. Jacobian against finite differences ------------------------------------------------

@functools.cache
def _step(name: str) -> sg.StepEquations:
    return {"plate_ball": plate_ball_system, "heavy_top": heavy_top_system,
            "oc_se2": se2_control_system}[name]().euler_lagrange()


def _random_state(step: sg.StepEquations, rng: np.random.Generator):
    """Random knowns (an arrow g_k of the groupoid and λ_k), unknowns and positive parameters."""
    G = step.groupoid
    m = step.n_constraints
    known = np.concatenate([G.random_arrow(rng), rng.uniform(-1.0, 1.0, m)])
    unknown = np.concatenate([G.random_chart(rng), rng.uniform(-1.0, 1.0, m)])
    params = rng.uniform(0.2, 1.5, len(step.parameters))
    return unknown, known, params


# Central differences with δ = 1e-5: truncation error δ²/6·|F'''| ≈ 2e-11·|F'''| and rounding
# error ≈ ε_mach·|F|/δ ≈ 2e-11·|F|; with residuals and their derivatives of order 1–100 at
# these points the FD error is ≲ 1e-8.  The tolerance 1e-7 (times the scale of J) leaves a
# margin while any wrong Jacobian entry (an O(1) discrepancy) fails by orders of magnitude.
FD_STEP = 1e-5
FD_TOL = 1e-7


@pytest.mark.parametrize("name", ["plate_ball", "heavy_top", "oc_se2"])
@SETTINGS
@given(seed=seeds)
def test_jacobian_matches_finite_differences(name: str, seed: int) -> None:
    """The exact Jacobian ∂F/∂(unknowns) through the α-fibre chart (docs/conventions.md §2) equals
    central differences of F at random points (seed 000 §6.2, seed 002, seed 000 §6.1)."""
    step = _step(name)
    rng = np.random.default_rng(seed)
    u, known, params = _random_state(step, rng)
    F0, J = step.evaluate(u, known, params)
    assert J.shape == (len(step), len(step.unknowns))
    fd = np.empty_like(J)
    for j in range(len(u)):
        du = np.zeros_like(u)
        du[j] = FD_STEP
        fp, _ = step.evaluate(u + du, known, params)
        fm, _ = step.evaluate(u - du, known, params)
        fd[:, j] = (fp - fm) / (2 * FD_STEP)
    scale = max(1.0, float(np.abs(J).max()))
    assert np.abs(fd - J).max() <= FD_TOL * scale, np.abs(fd - J).max()
