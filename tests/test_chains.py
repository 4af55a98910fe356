"""The multibody chains of ``symgroupoid.systems`` are the intended models.

- ``planar_chain(n)``: the residual is the Marsden–West DEL D₂L_d(θ_{k−1}, θ_k) +
  D₁L_d(θ_k, θ_{k+1}) (docs/conventions.md §2) of the midpoint discrete Lagrangian, with L_d
  written independently here through the chain's mass matrix M_jl = n + 1 − max(j, l):
  L = ½ Σ_jl M_jl θ̇_j θ̇_l cos(θ_j − θ_l) + g Σ_j (n + 1 − j) cos θ_j.
- ``spherical_chain(n)``: the residual is the derivative of the action sum
  L_d(R_k, R_{k+1}) + L_d(R_{k+1}, R_{k+2}) along R_{k+1,i} ↦ R_{k+1,i}(I + tE_a) (the junction
  variation of seed 000 Thm 2.13 on the pair groupoid of SO(3)ⁿ), with L_d written
  independently from
  the configurations; along a trajectory of the compiled kernel this residual vanishes, the
  discrete Noether momentum of rotations about the vertical is conserved and the energy error
  stays small.

Derivatives of the independent Lagrangians are complex-step derivatives, exact to rounding.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SESSION_CACHE,
    isolated_cache,
    needs_cc,
)

import symgroupoid as sg
from symgroupoid import systems

H, G = 0.01, 9.81
STEP = 1e-30  # complex step
E = [np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0]], float),
     np.array([[0, 0, 1], [0, 0, 0], [-1, 0, 0]], float),
     np.array([[0, -1, 0], [1, 0, 0], [0, 0, 0]], float)]


def cayley(x) -> np.ndarray:
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)
    return np.eye(3) + 4 / (4 + x @ x) * (X + X @ X / 2)


@functools.cache
def chain_step(kind: str, n: int) -> sg.StepEquations:
    constructor = systems.planar_chain if kind == "planar" else systems.spherical_chain
    return constructor(n).euler_lagrange()


# --- planar chain -----------------------------------------------------------------------------


def planar_Ld(q0, q1, h, g):
    """h·L((q₀+q₁)/2, (q₁−q₀)/h) through the mass matrix (complex-safe)."""
    n = len(q0)
    q, v = (q0 + q1) / 2, (q1 - q0) / h
    j = np.arange(1, n + 1)
    M = n + 1 - np.maximum.outer(j, j)
    T = 0.5 * np.sum(M * np.outer(v, v) * np.cos(np.subtract.outer(q, q)))
    return h * (T + g * np.sum((n + 1 - j) * np.cos(q)))


def partial(f, x, i):
    """∂f/∂x_i by the complex step."""
    z = np.asarray(x, complex).copy()
    z[i] += 1j * STEP
    return f(z).imag / STEP


def marsden_west(qm, qk, qp, h, g):
    """D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1})."""
    n = len(qk)
    return np.array([partial(lambda z: planar_Ld(qm, z, h, g), qk, i)
                     + partial(lambda z: planar_Ld(z, qp, h, g), qk, i) for i in range(n)])


@pytest.mark.parametrize("n", [1, 2])
def test_planar_chain_is_marsden_west(n: int) -> None:
    """At random points (off any trajectory) the library's residual is the textbook DEL."""
    step = chain_step("planar", n)
    assert len(step) == n and len(step.knowns) == 2 * n and [str(p) for p in
                                                              step.parameters] == ["h", "g"]
    rng = np.random.default_rng(n)
    for _ in range(5):
        qm, qk, qp = (rng.uniform(-2, 2, n) for _ in range(3))
        h, g = rng.uniform(0.01, 0.2), rng.uniform(1, 10)
        F, _ = step.evaluate(qp, np.concatenate([qm, qk]), [h, g])
        expected = marsden_west(qm, qk, qp, h, g)
        np.testing.assert_allclose(F, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


def test_planar_chain_docstring_and_validation() -> None:
    """The constructor states L_d and rejects a bad size by naming it."""
    assert "L_d(θ⁰, θ¹) = h · L((θ⁰ + θ¹)/2, (θ¹ − θ⁰)/h)" in systems.planar_chain.__doc__
    for bad in (0, 1.5, True):
        with pytest.raises(sg.ShapeError, match="n must"):
            systems.planar_chain(bad)
        with pytest.raises(sg.ShapeError, match="n must"):
            systems.spherical_chain(bad)


# --- spherical chain --------------------------------------------------------------------------


def inertia(i: int) -> np.ndarray:
    return np.array([1 + i / 10, 1.2 + i / 10, 0.5 + i / 20])


def centres(R) -> list:
    """Centres of mass of the pinned chain, joint-to-joint (0, 0, −1), centre (0, 0, −½)."""
    out, joint = [], 0
    for Ri in R:
        out.append(joint + Ri @ np.array([0, 0, -0.5]))
        joint = joint + Ri @ np.array([0, 0, -1.0])
    return out


def spherical_Ld(Ra, Rb, h, g):
    """L_d(R_k, R_{k+1}) with F_i = R_{k,i}ᵀR_{k+1,i} (complex-safe)."""
    total = 0
    for i, (A, B, ca, cb) in enumerate(zip(Ra, Rb, centres(Ra), centres(Rb)), start=1):
        J = inertia(i)
        Jd = np.diag(J.sum() / 2 - J)
        total = total + np.trace((np.eye(3) - A.T @ B) @ Jd) / h
        total = total + (cb - ca) @ (cb - ca) / (2 * h) - h / 2 * g * (ca[2] + cb[2])
    return total


def varied(R, i: int, direction: np.ndarray) -> list:
    """R with R_i ↦ R_i (I + iε·direction) (complex step along a body-frame rotation)."""
    out = [np.asarray(r, complex) for r in R]
    out[i] = out[i] @ (np.eye(3) + 1j * STEP * direction)
    return out


def action_residual(R0, R1, R2, h, g) -> np.ndarray:
    """d/dt [L_d(R0, R1(t)) + L_d(R1(t), R2)], R1,i(t) = R1,i(I + tE_a), for each (i, a)."""
    out = []
    for i in range(len(R1)):
        for Ea in E:
            V = varied(R1, i, Ea)
            out.append((spherical_Ld(R0, V, h, g) + spherical_Ld(V, R2, h, g)).imag / STEP)
    return np.array(out)


def vertical_momentum(Ra, Rb, h, g) -> float:
    """Discrete Noether momentum J⁺ = d/ds L_d(R_k, (I + s ê₃)R_{k+1}) at s = 0."""
    V = [(np.eye(3) + 1j * STEP * E[2]) @ B for B in Rb]
    return spherical_Ld(Ra, V, h, g).imag / STEP


def discrete_energy(Ra, Rb, h, g) -> float:
    """Σ (1/h²) tr((I − F_i)J_{d,i}) + |Δc_i|²/(2h²) + g e₃·(c_i + c_i⁺)/2."""
    total = 0.0
    for i, (A, B, ca, cb) in enumerate(zip(Ra, Rb, centres(Ra), centres(Rb)), start=1):
        J = inertia(i)
        total += np.trace((np.eye(3) - A.T @ B) @ np.diag(J.sum() / 2 - J)) / h**2
        total += (cb - ca) @ (cb - ca) / (2 * h**2) + g * (ca[2] + cb[2]) / 2
    return float(total)


def configurations(known: np.ndarray, n: int) -> tuple[list, list]:
    """(R_{k−1}, R_k) from a known state (every body's R_{k−1}, then every body's R_k,
    row-major: the arrow of the pair groupoid of SO(3)ⁿ)."""
    R = [known[9 * i: 9 * i + 9].reshape(3, 3) for i in range(n)]
    R1 = [known[9 * (n + i): 9 * (n + i) + 9].reshape(3, 3) for i in range(n)]
    return R, R1


def spherical_residual_at(step, n: int, rng, h: float, g: float) -> tuple[np.ndarray, ...]:
    R = [cayley(rng.normal(size=3)) for _ in range(n)]
    F = [cayley(0.3 * rng.normal(size=3)) for _ in range(n)]
    u = 0.3 * rng.normal(size=3 * n)
    R1 = [r @ f for r, f in zip(R, F)]
    known = np.concatenate([r.ravel() for r in R] + [r.ravel() for r in R1])
    R2 = [r @ cayley(u[3 * i: 3 * i + 3]) for i, r in enumerate(R1)]
    library, _ = step.evaluate(u, known, [h, g])
    return library, action_residual(R, R1, R2, h, g)


@pytest.mark.parametrize("n", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_spherical_chain_is_variational(n: int) -> None:
    """At random points the library's residual is the junction derivative of the action."""
    step = chain_step("3d", n)
    assert len(step) == 3 * n and len(step.knowns) == 18 * n
    rng = np.random.default_rng(10 + n)
    for _ in range(4):
        h, g = rng.uniform(0.01, 0.2), rng.uniform(1, 10)
        library, expected = spherical_residual_at(step, n, rng, h, g)
        np.testing.assert_allclose(library, expected, rtol=1e-11,
                                   atol=1e-11 * np.abs(expected).max())


def spherical_initial(n: int, spin: float = 1.0) -> np.ndarray:
    R = [cayley(np.array([0.4 * np.cos(i), 0.3 * np.sin(i), 0.2 * i])) for i in range(1, n + 1)]
    F = [cayley(spin * H * np.array([0.7 * np.sin(i), -0.5, 1.1])) for i in range(1, n + 1)]
    return np.concatenate([r.ravel() for r in R] + [(r @ f).ravel() for r, f in zip(R, F)])


@needs_cc
@pytest.mark.parametrize("n", [1, pytest.param(2, marks=pytest.mark.slow)])
def test_spherical_chain_trajectory(n: int) -> None:
    """Along 400 compiled steps: the independent DEL residual vanishes, the vertical
    angular momentum is conserved to ~1e-10 and the energy error stays bounded."""
    sim = chain_step("3d", n).compile(backend="c", cache_dir=SESSION_CACHE)
    traj = sim.simulate(spherical_initial(n), 400, {"h": H, "g": G})
    pairs = [configurations(s, n) for s in traj.states]
    scale = max((inertia(i).sum() / 2 - inertia(i)).max() for i in range(1, n + 1)) / H
    for (R0, R1), (_, R2) in zip(pairs[:-1], pairs[1:]):
        assert np.abs(action_residual(R0, R1, R2, H, G)).max() < 1e-10 * scale
    momentum = np.array([vertical_momentum(Ra, Rb, H, G) for Ra, Rb in pairs])
    assert abs(momentum[0]) > 0.1  # a genuinely rotating chain
    assert np.abs(momentum - momentum[0]).max() < 1e-10 * max(1.0, abs(momentum[0]))
    energy = np.array([discrete_energy(Ra, Rb, H, G) for Ra, Rb in pairs])
    kinetic = energy[0] - sum(G * (a[2] + b[2]) / 2 for a, b in zip(centres(pairs[0][0]),
                                                                      centres(pairs[0][1])))
    assert np.abs(energy - energy[0]).max() < 1e-2 * kinetic
    for states in traj.states:  # the attitudes stay rotations
        for R in configurations(states, n)[0]:
            np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


@needs_cc
def test_spherical_chain_stays_on_the_group() -> None:
    """The stored attitudes are renormalised each step (docs/conventions.md §16): over 5000
    steps RᵀR − I stays at a few roundings, where a plain product R_k·cay(u) lets it
    random-walk (to ~1e-14 here) and the Noether identity with it."""
    sim = chain_step("3d", 1).compile(backend="c", cache_dir=SESSION_CACHE)
    traj = sim.simulate(spherical_initial(1), 5000, {"h": H, "g": G}, every=50)
    defect = max(np.abs(R.T @ R - np.eye(3)).max()
                 for s in traj.states for R in sum(configurations(s, 1), []))
    assert defect <= 4 * np.finfo(float).eps, defect


@needs_cc
def test_the_vertical_momentum_drifts_only_by_rounding_over_long_runs() -> None:
    """10⁵ default steps of the chain of 2 bodies from six initial spins: the vertical angular
    momentum drifts by the random walk of the state layout's rounding (measured: 6.7e-12 to
    2.0e-11 relative), not by Newton's stopping error.  A Newton that stops once its
    estimated remaining error is within tol_step, without the polishing update from the
    accepted residual, leaves a systematic error (~4e-17 in Cayley coordinates of ~1e-2,
    above their rounding) at the faster spins, and the momentum drifts linearly: 2.7e-11 to
    3.0e-10, median 4.5e-11."""
    n = 2
    sim = chain_step("3d", n).compile(backend="c", cache_dir=SESSION_CACHE)
    drifts = []
    for spin in (1.2, 1.4, 1.6, 1.8, 2.0, 2.2):
        traj = sim.simulate(spherical_initial(n, spin), 100_000, {"h": H, "g": G}, every=100)
        pairs = [configurations(s, n) for s in traj.states]
        momentum = np.array([vertical_momentum(Ra, Rb, H, G) for Ra, Rb in pairs])
        drifts.append(np.abs(momentum - momentum[0]).max() / abs(momentum[0]))
    assert np.median(drifts) < 3e-11 and max(drifts) < 6e-11, drifts


def test_renormalised_matrix_is_the_identity_on_the_group() -> None:
    """Q(3I − QᵀQ)/2 on the rotation block: exactly M on SO(3), SE(3); an orthogonality
    defect δ goes to O(δ²); groups' own arrows are left alone."""
    import sympy as sp

    for group, x in ((sg.SO3("R"), [0.3, -0.2, 0.5]), (sg.SE3("g"), [0.3, -0.2, 0.5, 1, 2, 3]),
                     (sg.SE2("g"), [0.4, 1.0, -2.0]), (sg.SO2("r"), [0.7])):
        M = group.cayley([sp.Rational(str(v)) for v in x])
        assert sp.simplify(group.renormalised_matrix(M) - M) == sp.zeros(*M.shape)
        m = group.rotation_block
        A = np.array(M.evalf(), float)
        A[:m, :m] += 1e-6 * np.arange(m * m).reshape(m, m) / m**2
        B = np.array(group.renormalised_matrix(sp.Matrix(A)), float)
        before = np.abs(A[:m, :m].T @ A[:m, :m] - np.eye(m)).max()
        after = np.abs(B[:m, :m].T @ B[:m, :m] - np.eye(m)).max()
        assert before > 1e-7 and after < 1e-11, (group, before, after)
        np.testing.assert_array_equal(B[m:], A[m:])  # translation rows untouched
    pair = sg.PairGroupoid(sg.SO3("R"))
    f = sp.symbols("f0:9")
    assert sg.SO3("R").renormalised_fibre(f) == tuple(f)  # a Lie group's own arrows: as they are
    assert pair.renormalised_fibre(f) != tuple(f)


def _rotation_section(n: int, row: int):
    """The rotation of every body about the space axis e_row: X(R) = (R_iᵀ e_row)_i in the
    left-trivialised basis R ê_a of each factor (row ``row`` of each R_i, stored row-major)."""
    return lambda q: [q[9 * i + 3 * row + j] for i in range(n) for j in range(3)]


@needs_cc
def test_noether_on_the_pair_groupoid_of_so3_knows_its_rotations() -> None:
    """The vertical rotation is a Noether symmetry of the 3D pendulum (checked on G, whose
    base points are rotations, not arbitrary arrays), the horizontal one is not; the library's
    own Noether quantity equals the independent complex-step momentum and, along compiled
    steps, changes per step only at the rounding level of the DEL residual.

    Measured (h = 0.01): per-step changes 1.2e-13 rms, the rounding level of the DEL residual
    itself (written in F = R_kᵀR_{k+1}, whose I − F cancels to ε/(h|ω|) relative; any Newton
    options give the same): 1.8e-10 relative after 2000 steps, 2e-9 after 10⁵."""
    system = systems.spherical_chain(1)
    vertical = system.noether(_rotation_section(1, 2))
    assert vertical.is_symmetry and "random arrows" in vertical.verification
    horizontal = system.noether(_rotation_section(1, 0))
    assert not horizontal.is_symmetry
    sim = chain_step("3d", 1).compile(backend="c", cache_dir=SESSION_CACHE)
    traj = sim.simulate(spherical_initial(1), 2000, {"h": H, "g": G})
    F = vertical.along(traj)
    assert abs(F[0]) > 0.1
    pairs = [configurations(s, 1) for s in traj.states]
    np.testing.assert_allclose(F[::100], [vertical_momentum(a, b, H, G) for a, b in pairs[::100]],
                               rtol=1e-12)
    jumps = np.diff(F)
    assert np.sqrt(np.mean(jumps ** 2)) < 1e-12 * abs(F[0]) / 0.2  # ~5ε·|F⁺L| per step
    assert np.abs(F - F[0]).max() < 4e-10 * abs(F[0])


def test_a_quantity_on_a_matrix_group_without_stages_is_built_on_the_graph() -> None:
    """On a groupoid whose base holds a matrix group F_X and the defect are built on the
    expression graph and checked at random arrows (the SymPy forms of F±L differentiate L
    through the group's multiplication and retraction: 45 s for the heavy top by the
    midpoint rule); the SymPy
    form, built on request, has the graph's values along a run, and the defect of a
    rotation that is no symmetry is found at a random arrow."""
    import sympy as sp

    system = systems.spherical_chain(1)
    vertical = system.noether(_rotation_section(1, 2))
    assert vertical.verification.startswith("numerical: zero to 1e-09 relative at 8 random "
                                            "arrows of pair groupoid of SO3")
    # where the base holds no group (the heavy top on S² × SO(3), seed 002) the symmetry is
    # still decided symbolically
    assert systems.heavy_top().noether(lambda q: list(q)).verification == "symbolic"
    horizontal = system.noether(_rotation_section(1, 0))
    assert (horizontal.is_symmetry, horizontal.verification) == (False,
                                                                "nonzero at a random arrow")
    sim = chain_step("3d", 1).compile(backend="numpy")
    traj = sim.simulate(spherical_initial(1), 20, {"h": H, "g": G})
    for quantity, symmetric in ((vertical, True), (horizontal, False)):
        values = quantity.along(traj)
        symbols = [*quantity.arrow, *quantity.parameters]
        form, defect = (sp.lambdify(symbols, e) for e in (quantity.expr, quantity.defect))
        params = [traj.parameters[str(p)] for p in quantity.parameters]
        np.testing.assert_allclose([form(*state, *params) for state in traj.states], values,
                                   rtol=1e-12, atol=1e-14)
        at = abs(defect(*traj.states[3], *params))
        assert at < 1e-12 if symmetric else at > 1e-3, at
