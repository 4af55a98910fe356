"""The pair groupoid of SO(n) or SE(n) in increment coordinates (TrivialisedPairGroupoid,
docs/conventions.md §18): its axioms, the same equations as the pair groupoid, its state
layout and checks, and the Noether momentum of the 3D chain at the rounding floor over 10⁵
steps."""

from __future__ import annotations

import functools
import pickle

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SESSION_CACHE,
    isolated_cache,
    needs_cc,
)

import symgroupoid as sg
from symgroupoid import systems

H, G = 0.01, 9.81
PARAMS = {"h": H, "g": G}
E3 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
COMPLEX_STEP = 1e-30


def cayley(x) -> np.ndarray:
    x = np.asarray(x, float)
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)
    return np.eye(3) + 4 / (4 + x @ x) * (X + X @ X / 2)


@functools.cache
def chain_step(n: int, increments: bool) -> sg.StepEquations:
    constructor = systems.spherical_chain_increments if increments else systems.spherical_chain
    return constructor(n).euler_lagrange()


@functools.cache
def chain_simulator(n: int) -> sg.Simulator:
    return chain_step(n, True).compile(backend="c", cache_dir=SESSION_CACHE)


# --- the groupoid ---------------------------------------------------------------------------------

GROUPS = [sg.SO3("R"), sg.SO3("R", retraction="exp"), sg.SO2("r"), sg.SE3("g"),
          sg.SE2("g"), sg.SE3("g", retraction="exp"), sg.SE2("g", retraction="exp")]
GROUP_IDS = ["SO3", "SO3-exp", "SO2", "SE3", "SE2", "SE3-exp", "SE2-exp"]


@pytest.mark.parametrize("group", GROUPS, ids=GROUP_IDS)
def test_chart_is_the_retraction_minus_identity(group) -> None:
    """D(x) = τ(x) − I against the group's own τ (numerically), and τ⁻¹(I + D) gives x
    back numerically and symbolically, for every group."""
    G = sg.TrivialisedPairGroupoid(group)
    x = np.linspace(0.3, -0.4, group.rank)
    D = G.offset_matrix(G.numeric_fibre_chart(x))
    np.testing.assert_allclose(np.array(D, float), group.numeric_tau(x) - np.eye(group.n),
                               atol=1e-15)
    f = [float(v) for v in G.fibre_of(G.numeric_fibre_arrow(G.random_base_point(
        np.random.default_rng(2)), x))]
    np.testing.assert_allclose(G.fibre_chart_inverse(f), x, atol=1e-14)
    symbolic = [float(v) for v in G.chart_of_fibre([sp.Float(v, 30) for v in f])]
    np.testing.assert_allclose(symbolic, x, atol=1e-14)


def test_chart_and_its_inverses_agree() -> None:
    """D = τ(x) − I; the numeric inverse vee(2D(2I + D)⁻¹) and the symbolic one
    2 vee(D − Dᵀ)/(4 + tr D) give x back; the chart is the group's Cayley map minus I."""
    G = sg.TrivialisedPairGroupoid(sg.SO3("R"))
    x = np.array([0.3, -0.7, 0.45])
    D = np.array(G.numeric_fibre_chart(x), float)
    np.testing.assert_allclose(D.reshape(3, 3), cayley(x) - np.eye(3), atol=1e-15)
    np.testing.assert_allclose(G.fibre_chart_inverse(D), x, atol=1e-15)
    symbolic = [float(v) for v in G.chart_of_fibre([sp.Float(v) for v in D])]
    np.testing.assert_allclose(symbolic, x, atol=1e-15)


def test_structure_maps_are_those_of_the_pair_groupoid() -> None:
    """(q, q⁻¹p − I) ↦ (q, p) carries products, inverses and targets to the pair
    groupoid's."""
    G = sg.TrivialisedPairGroupoid(sg.SO3("R"))
    rng = np.random.default_rng(3)
    a = G.random_arrow(rng)
    b = G.random_arrow(rng, G.target(a))
    pair = [np.reshape(G.source(g), (3, 3)) for g in (a, b)]
    targets = [np.reshape([float(v) for v in G.target(g)], (3, 3)) for g in (a, b)]
    ab = [float(v) for v in G.multiply(a, b)]
    np.testing.assert_allclose(np.reshape(ab[:9], (3, 3)), pair[0], atol=1e-14)
    np.testing.assert_allclose(pair[0] @ (np.eye(3) + np.reshape(ab[9:], (3, 3))), targets[1],
                               atol=1e-13)
    inv = [float(v) for v in G.inverse(a)]
    np.testing.assert_allclose(np.reshape(inv[:9], (3, 3)), targets[0], atol=1e-14)
    np.testing.assert_allclose(np.reshape(inv[9:], (3, 3)), np.reshape(a[9:], (3, 3)).T,
                               atol=0)
    R0, R1 = cayley([0.2, 0.1, -0.3]), cayley([0.25, 0.05, -0.28])
    arrow = G.arrow_between(R0, R1)
    np.testing.assert_allclose(G.configuration_after(R0, arrow), R1, atol=1e-15)
    renormalised = G.renormalised_arrow(tuple(1.001 * np.asarray(arrow)))
    Q = np.reshape([float(v) for v in renormalised[:9]], (3, 3))
    assert np.abs(Q.T @ Q - np.eye(3)).max() < 1e-5  # 2e-3 before: one Newton–Schulz step


def test_groups_without_a_whole_rotation_block_are_refused() -> None:
    odd = type("Odd", (sg.SO2,), {"rotation_block": 0})("r")
    with pytest.raises(sg.InputTypeError, match="no rotation block"):
        sg.TrivialisedPairGroupoid(odd)


@functools.cache
def se3_rigid_body() -> tuple[sg.StepEquations, sg.StepEquations]:
    """A rigid body in space on SE(3), tr((I − F_R)J_d)/h + |R p|²/(2h) − h g e₃·(c + c⁺)/2
    with F = [[F_R, p], [0, 1]]: the step in increment coordinates and on PairGroupoid."""
    h, grav = sp.symbols("h g", positive=True)
    Jd = sp.diag(1, 2, 3)

    def rigid(R, F):  # R: the configuration; F: the increment, both 4×4
        rotation = ((sp.eye(3) - F[:3, :3]) * Jd).trace()
        move = R[:3, :3] * F[:3, 3]
        return (rotation + (move.T * move)[0, 0] / 2) / h - h * grav * (2 * R[2, 3] + move[2]) / 2

    ours = sg.DiscreteSystem(sg.TrivialisedPairGroupoid(sg.SE3("g")),
                             lambda a: rigid(a.source, a.increment), parameters=[h, grav],
                             name="se3_increments").euler_lagrange()
    pair = sg.DiscreteSystem(sg.PairGroupoid(sg.SE3("g")),
                             lambda a: rigid(a.source, sg.SE3("g")._inverse_matrix(a.source)
                                             * a.target), parameters=[h, grav],
                             name="se3_pair").euler_lagrange()
    return ours, pair


def test_se3_residual_and_jacobian_equal_the_pair_groupoids() -> None:
    """At random points, the same residual and Jacobian in both coordinates."""
    ours, pair = se3_rigid_body()
    rng = np.random.default_rng(5)
    G = sg.SE3("g")
    for _ in range(3):
        M0 = G.numeric_tau(rng.normal(size=6))
        F = G.numeric_tau(0.3 * rng.normal(size=6))
        u = 0.3 * rng.normal(size=6)
        free = G._free
        known_pair = np.array([M0[i, j] for i, j in free] + [(M0 @ F)[i, j] for i, j in free])
        known_ours = np.array([M0[i, j] for i, j in free]
                              + [(F - np.eye(4))[i, j] for i, j in free])
        params = [rng.uniform(0.01, 0.2), rng.uniform(1, 10)]
        F_pair, J_pair = pair.evaluate(u, known_pair, params)
        F_ours, J_ours = ours.evaluate(u, known_ours, params)
        np.testing.assert_allclose(F_ours, F_pair, rtol=0, atol=1e-12 * np.abs(F_pair).max())
        np.testing.assert_allclose(J_ours, J_pair, rtol=0, atol=1e-12 * np.abs(J_pair).max())


@needs_cc
def test_se3_states_and_trajectory() -> None:
    """SE(3) increments: F's last row is fixed (0, 0, 0, 1) in named states, its offset is
    checked in flat ones, and 300 steps agree with the pair groupoid's."""
    ours, pair = (s.compile(backend="c", cache_dir=SESSION_CACHE) for s in se3_rigid_body())
    G = sg.SE3("g")
    M0 = G.numeric_tau([0.1, 0.2, 0.3, 1.0, 2.0, 3.0])
    F = G.numeric_tau([0.01, 0.02, -0.01, 0.1, 0.0, -0.05])
    a = ours.simulate({"g": M0, "Fg": F}, 300, PARAMS)
    b = pair.simulate({"g": (M0, M0 @ F)}, 300, PARAMS)
    ours_g = ours.layout.view(a.states, "g")
    pair_g = pair.layout.view(b.states, "g")
    np.testing.assert_allclose(ours_g, pair_g[:-1], atol=1e-11)
    np.testing.assert_array_equal(ours.layout.view(a.states, "Fg")[:, 3], [[0, 0, 0, 1]] * 301)
    bad = F.copy()
    bad[3, 3] = 2.0
    with pytest.raises(sg.DomainError, match="fixed entries"):
        ours.state({"g": M0, "Fg": bad})
    flat = ours.state({"g": M0, "Fg": F})
    flat[12] += 1e-3
    with pytest.raises(sg.DomainError, match="increment, stored as F − I"):
        ours.simulate(flat, 2, PARAMS)


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(sg.InputTypeError, match="other than the group"):
        sg.TrivialisedPairGroupoid(sg.SO3("R"), increment="R")
    with pytest.raises(sg.InputTypeError):
        sg.TrivialisedPairGroupoid(sg.EuclideanSpace("x y"))
    for junk in (3, "", "F\0", sp.Symbol("F")):
        with pytest.raises(sg.SymgroupoidError, match="increment"):
            sg.TrivialisedPairGroupoid(sg.SO3("R"), increment=junk)
    assert sg.TrivialisedPairGroupoid(sg.SO3("R7")).increment_name == "F7"
    assert sg.TrivialisedPairGroupoid(sg.SO3("g")).increment_name == "Fg"


# --- the same equations as the pair groupoid --------------------------------------------------

@pytest.mark.parametrize("n", [1, 2])
def test_residual_and_jacobian_equal_the_pair_groupoids(n: int) -> None:
    """At random points (R_{k−1}, F_{k−1}, u), the increments chain's residual and Jacobian
    are the pair chain's at (R_{k−1}, R_{k−1}F_{k−1}, u): the same discrete equations."""
    pair, incr = chain_step(n, False), chain_step(n, True)
    rng = np.random.default_rng(20 + n)
    for _ in range(3):
        R = [cayley(rng.normal(size=3)) for _ in range(n)]
        F = [cayley(0.3 * rng.normal(size=3)) for _ in range(n)]
        u = 0.3 * rng.normal(size=3 * n)
        params = [rng.uniform(0.01, 0.2), rng.uniform(1, 10)]
        known_pair = np.concatenate([r.ravel() for r in R] + [(r @ f).ravel()
                                                              for r, f in zip(R, F)])
        known_incr = np.concatenate([np.concatenate([r.ravel(), (f - np.eye(3)).ravel()])
                                     for r, f in zip(R, F)])
        F_pair, J_pair = pair.evaluate(u, known_pair, params)
        F_incr, J_incr = incr.evaluate(u, known_incr, params)
        scale = np.abs(F_pair).max()
        np.testing.assert_allclose(F_incr, F_pair, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(J_incr, J_pair, rtol=0, atol=1e-12 * np.abs(J_pair).max())


@needs_cc
def test_trajectory_equals_the_pair_groupoids() -> None:
    """200 steps of the chain of two bodies from the same motion: the attitudes agree with
    the pair groupoid's to rounding (the layouts differ only in what they store)."""
    n = 2
    pair = chain_step(n, False).compile(backend="c", cache_dir=SESSION_CACHE)
    sim = chain_simulator(n)
    R = [cayley([0.4 * np.cos(i), 0.3 * np.sin(i), 0.2 * i]) for i in (1, 2)]
    F = [cayley(H * np.array([0.7 * np.sin(i), -0.5, 1.1])) for i in (1, 2)]
    a = pair.simulate({"R1": (R[0], R[0] @ F[0]), "R2": (R[1], R[1] @ F[1])}, 200, PARAMS)
    b = sim.simulate({"R1": R[0], "F1": F[0], "R2": R[1], "F2": F[1]}, 200, PARAMS)
    for i in (1, 2):
        attitudes = pair.layout.view(a.states, f"R{i}")  # R_0 … R_201
        ours = sim.layout.view(b.states, f"R{i}")  # R_0 … R_200
        increments = sim.layout.view(b.states, f"F{i}")
        np.testing.assert_allclose(ours, attitudes[:-1], atol=1e-12)
        np.testing.assert_allclose(ours[-1] @ increments[-1], attitudes[-1], atol=1e-12)


# --- states ------------------------------------------------------------------------------------

@needs_cc
def test_state_layout_stores_the_offset_and_shows_the_increment() -> None:
    sim = chain_simulator(1)
    R, F = cayley([0.1, 0.2, 0.3]), cayley([0.01, -0.02, 0.015])
    flat = sim.state({"R1": R, "F1": F})
    np.testing.assert_array_equal(flat[:9], R.ravel())
    np.testing.assert_allclose(flat[9:], (F - np.eye(3)).ravel(), atol=1e-16)
    traj = sim.simulate(flat, 3, PARAMS)
    np.testing.assert_allclose(sim.layout.view(traj.states, "F1")[0], F, atol=1e-16)
    assert sim.layout.describe(9) == "F1[0, 0] (step k-1)"


@needs_cc
def test_increments_off_the_group_are_refused_before_step_0() -> None:
    """Named, flat, pickled and batched states with an increment off SO(3): DomainError."""
    sim = chain_simulator(1)
    R, F = cayley([0.1, 0.2, 0.3]), cayley([0.01, -0.02, 0.015])
    bad = F.copy()
    bad[0, 0] += 1e-3
    flat = sim.state({"R1": R, "F1": F})
    flat[9] += 1e-3
    restored = pickle.loads(pickle.dumps(sim))
    for s in (sim, restored):
        with pytest.raises(sg.DomainError, match="'F1' is not in"):
            s.state({"R1": R, "F1": bad})
        with pytest.raises(sg.DomainError, match="increment, stored as F − I"):
            s.simulate(flat, 2, PARAMS)
        with pytest.raises(sg.DomainError, match="initial state 1: .*increment"):
            s.simulate_batch(np.vstack([sim.state({"R1": R, "F1": F}), flat]), 2, PARAMS)
    good = restored.simulate({"R1": R, "F1": F}, 5, PARAMS)
    np.testing.assert_array_equal(good.states, sim.simulate({"R1": R, "F1": F}, 5,
                                                            PARAMS).states)


# --- the Noether momentum over long runs ------------------------------------------------------

def _inertias(n: int) -> list[np.ndarray]:
    out = []
    for i in range(1, n + 1):
        J = np.array(systems.chain_inertia(i).diagonal(), float).ravel()
        out.append(np.diag(J.sum() / 2 - J))
    return out


def increments_Ld(R, D, Jd, h, g) -> complex:
    """L_d of ``spherical_chain_increments`` from attitudes R_i and offsets D_i = F_i − I
    (complex-safe, independent of the library)."""
    link, centre = np.array([0, 0, -1.0]), np.array([0, 0, -0.5])
    rotational = kinetic = potential = 0
    joint, moved = np.zeros(3), np.zeros(3)
    for Ri, Di, J in zip(R, D, Jd):
        rotational = rotational - np.trace(Di @ J)
        dc = moved + Ri @ Di @ centre
        kinetic = kinetic + dc @ dc / 2
        potential = potential + (2 * (joint + Ri @ centre) + dc)[2] / 2
        joint, moved = joint + Ri @ link, moved + Ri @ Di @ link
    return (rotational + kinetic) / h - h * g * potential


def vertical_momentum(R, D, Jd) -> float:
    """J⁺ = d/ds L_d(R_k, e^{sê₃}R_{k+1}) at s = 0, with the increment's variation
    F ↦ F·η, η = skew(M⁻¹ê₃M), M = R_kF (the skew part keeps the measure tangent to
    SO(3) when RᵀR − I is a rounding)."""
    varied = []
    for Ri, Di in zip(R, D):
        M = Ri @ (np.eye(3) + Di)
        A = np.linalg.solve(M, E3 @ M)
        varied.append(Di + 1j * COMPLEX_STEP * (np.eye(3) + Di) @ (A - A.T) / 2)
    return increments_Ld(R, varied, Jd, H, G).imag / COMPLEX_STEP


@needs_cc
def test_the_vertical_momentum_stays_at_the_rounding_floor_over_1e5_steps() -> None:
    """10⁵ default steps of the chain of 2 bodies from the six initial spins of the pair
    groupoid's test (test_chains.py): the vertical angular momentum drifts by ≤ 1e-11
    relative at every spin (measured: 3.7e-13 to 2.1e-12; the pair groupoid's layout:
    6.7e-12 to 2.0e-11, and up to 4.7e-11 from other initial attitudes)."""
    n = 2
    sim, Jd = chain_simulator(n), _inertias(n)
    drifts = []
    for spin in (1.2, 1.4, 1.6, 1.8, 2.0, 2.2):
        state = {}
        for i in range(1, n + 1):
            state[f"R{i}"] = cayley([0.4 * np.cos(i), 0.3 * np.sin(i), 0.2 * i])
            state[f"F{i}"] = cayley(spin * H * np.array([0.7 * np.sin(i), -0.5, 1.1]))
        traj = sim.simulate(state, 100_000, PARAMS, every=100)
        R = [sim.layout.view(traj.states, f"R{i}") for i in range(1, n + 1)]
        F = [sim.layout.view(traj.states, f"F{i}") for i in range(1, n + 1)]
        momentum = np.array([vertical_momentum([r[k] for r in R],
                                               [f[k] - np.eye(3) for f in F], Jd)
                             for k in range(len(R[0]))])
        assert abs(momentum[0]) > 0.1  # a genuinely rotating chain
        drifts.append(np.abs(momentum - momentum[0]).max() / abs(momentum[0]))
        orthogonality = max(np.abs(r[-1].T @ r[-1] - np.eye(3)).max() for r in R)
        assert orthogonality <= 4 * np.finfo(float).eps, orthogonality
    assert max(drifts) <= 1e-11, drifts


@needs_cc
def test_noether_quantity_of_the_vertical_rotation() -> None:
    """``noether()`` finds the vertical rotation a symmetry of the increments chain, and its
    quantity along a trajectory is the vertical angular momentum measured above."""
    step = chain_step(1, True)
    vertical = step.system.noether(lambda q: [q[6 + j] for j in range(3)])  # X(R) = Rᵀe₃
    assert vertical.is_symmetry
    sim = chain_simulator(1)
    start = {"R1": cayley([0.4, 0.3, 0.2]), "F1": cayley(H * np.array([0.7, -0.5, 1.1]))}
    traj = sim.simulate(start, 200, PARAMS)
    R, F = sim.layout.view(traj.states, "R1"), sim.layout.view(traj.states, "F1")
    expected = [vertical_momentum([r], [f - np.eye(3)], _inertias(1)) for r, f in zip(R, F)]
    np.testing.assert_allclose(vertical.along(traj)[::20], expected[::20], rtol=1e-9)


def test_boundary_value_problem_matches_the_pair_groupoids() -> None:
    """A two-point problem between two attitudes: the increments system and the pair
    groupoid's give the same attitudes at every node (the same discrete equations)."""
    R0, RN = cayley([0.1, 0.2, 0.3]), cayley([0.3, -0.1, 0.5])
    ours = sg.solve_boundary_value(chain_step(1, True), R0, RN, 12, params=PARAMS)
    pair = sg.solve_boundary_value(chain_step(1, False), R0, RN, 12, params=PARAMS)
    nodes = [np.reshape(a[:9], (3, 3)) for a in ours.arrows]
    last = ours.arrows[-1]
    nodes.append(np.reshape(last[:9], (3, 3)) @ (np.eye(3) + np.reshape(last[9:], (3, 3))))
    expected = [np.reshape(a[:9], (3, 3)) for a in pair.arrows] + [
        np.reshape(pair.arrows[-1][9:], (3, 3))]
    np.testing.assert_allclose(nodes, expected, atol=1e-11)
    np.testing.assert_allclose(nodes[-1], RN, atol=1e-12)
    off = RN.copy()
    off[0, 1] += 1e-3
    with pytest.raises(sg.DomainError, match="end"):
        sg.solve_boundary_value(chain_step(1, True), R0, off, 12, params=PARAMS)


def test_unknowns_of_indexed_groups_are_well_formed_latex() -> None:
    """A group or increment named with an index (R1, F1) is parenthesised before the step
    subscript in the unknowns' names, as in the knowns': (τ⁻¹ (F_{1})_{k})_a, not F_{1}_{k}."""
    names = [str(u) for u in chain_step(1, True).unknowns]
    names += [str(u) for u in chain_step(1, False).unknowns]
    names += [str(c) for c in sg.SO3("R1").named_chart(1)]
    assert names[0] == r"(\tau^{-1} (F_{1})_{k})_{1}"
    assert all("}_{k" not in n.replace(")_{k", "") for n in names), names
