"""``systems.spherical_chain_maximal(n)``: the 3D chain of ``spherical_chain(n)`` in maximal
coordinates (each body's attitude and centre of mass, ball joints as holonomic
constraints, docs/conventions.md §15).  On the constraint set its discrete Lagrangian is
the minimal chain's, so from the same initial arrow both give the same trajectory; from 16
bodies its step is factored in band form."""

from __future__ import annotations

import numpy as np
import pytest
from kernel_support import SESSION_CACHE, needs_cc

import symgroupoid as sg
from symgroupoid import codegen, systems

PARAMS = {"h": 0.01, "g": 9.81}
LINK, CENTRE = np.array([0.0, 0.0, -1.0]), np.array([0.0, 0.0, -0.5])


def _rotation(w: np.ndarray) -> np.ndarray:
    """exp(ŵ) by Rodrigues' formula."""
    angle = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]) / angle
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _arrow(n: int, seed: int = 1):
    """Attitudes R_0, R_1 = R_0·exp(0.01·random) of n bodies, and their centres of mass."""
    rng = np.random.default_rng(seed)
    R0 = [_rotation(0.3 * rng.normal(size=3)) for _ in range(n)]
    R1 = [R @ _rotation(0.01 * rng.normal(size=3)) for R in R0]

    def centres(R):
        out, joint = [], np.zeros(3)
        for Ri in R:
            out.append(joint + Ri @ CENTRE)
            joint = joint + Ri @ LINK
        return out

    return R0, R1, centres(R0), centres(R1)


@needs_cc
def test_the_maximal_chain_follows_the_minimal_chain():
    n, steps = 2, 300
    R0, R1, c0, c1 = _arrow(n)
    minimal = systems.spherical_chain(n).euler_lagrange().compile(cache_dir=SESSION_CACHE)
    maximal = systems.spherical_chain_maximal(n).euler_lagrange().compile(
        cache_dir=SESSION_CACHE)
    start = {f"R{i + 1}": (R0[i], R1[i]) for i in range(n)}
    named = dict(start)
    for i in range(n):
        named.update({f"{axis}{i + 1}": (c0[i][a], c1[i][a]) for a, axis in enumerate("xyz")})
    a = minimal.simulate(start, steps, PARAMS)
    b = maximal.simulate(named, steps, PARAMS)
    # each body's attitudes (R_{k−1}, R_k): the minimal state is sources then targets
    rows_a = np.concatenate([np.r_[9 * i:9 * i + 9, 9 * n + 9 * i:9 * n + 9 * i + 9]
                             for i in range(n)])
    rows_b = np.concatenate([np.arange(24 * i, 24 * i + 18) for i in range(n)])
    assert np.abs(a.states[:, rows_a] - b.states[:, rows_b]).max() < 1e-10
    assert np.abs(b.states[-1, rows_b] - b.states[0, rows_b]).max() > 1e-2  # it moved
    # the centres stay where the joints put them
    last = b.states[-1]
    joint = np.zeros(3)
    for i in range(n):
        R = last[24 * i + 9:24 * i + 18].reshape(3, 3)
        c = last[24 * i + 21:24 * i + 24]
        assert np.abs(c - R @ CENTRE - joint).max() < 1e-12
        joint = c + R @ (LINK - CENTRE)


def test_the_maximal_chain_refuses_a_bad_size():
    with pytest.raises(sg.SymgroupoidError):
        systems.spherical_chain_maximal(0)


@pytest.mark.slow
def test_from_16_bodies_the_maximal_chain_is_banded():
    step = systems.spherical_chain_maximal(16).euler_lagrange()
    band = codegen.band_order(step)
    assert len(step.unknowns) == 144 and (band.kl, band.ku) == (9, 9)
    assert codegen.band_order(systems.spherical_chain(16).euler_lagrange()) is None
