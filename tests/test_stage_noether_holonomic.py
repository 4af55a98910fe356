"""The Noether quantity of a Galerkin discretisation with holonomic constraints
(docs/conventions.md §22, "The Noether quantity on N = G|_M"): with ψ at every node of
LobattoIIIAB(s), the interior multipliers Λ are internal stages of the arrow, solved with
its other stages (the end multipliers λ enter no stage row), and

    F_X(g) = ⟨F⁺L(g, ζ*(g)), X(β(g))⟩,

which carries Λ* and not λ, is conserved when the defect D(g, ζ*, λ) = D₀(g, ζ*) −
λ·dψ(α(g))(X) vanishes on N = G|_M: X tangent to M and the constrained L_d invariant on N.

The spherical pendulum in Cartesian coordinates (ψ = |q|² − ℓ², gravity along e₃) with
LobattoIIIAB(3): the rotation about e₃ is a symmetry and F_X is kept to the rule of the
other Noether tests (10⁻¹²·|F_X|) over 400 steps in C and NumPy; F_X is the quantity
written by hand from the three-node Lobatto curve (its ζ and Λ solved here), and without
its Λ term it is not conserved; the rotation about e₁ (gravity) is no symmetry and a
translation is not tangent to the sphere; a constraint function whose zero set is the
sphere but which the rotation does not keep elsewhere: the symmetry is decided on N.  Two
particles joined by a rigid rod (LobattoIIIAB(4)): rotations and translations.  A forced
pendulum: the balance np.diff(F_X) = I_k.  The diagnostics' stage solve of the same run."""

import functools

import numpy as np
import pytest
import sympy as sp
from kernel_support import BACKENDS

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
grav, ell, c, u = sp.symbols("g ell c u", real=True)
PARAMS = {"h": 0.05, "g": 9.81, "ell": 1.0}
STEPS = 400
A = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])  # X(q) = Aq about e₃


def _lagrangian(q, v):
    return (v[0] ** 2 + v[1] ** 2 + v[2] ** 2) / 2 - grav * q[2]


def _sphere(q):
    return [q[0] ** 2 + q[1] ** 2 + q[2] ** 2 - ell ** 2]


@functools.cache
def _pendulum() -> sg.DiscreteSystem:
    return sg.ContinuousSystem(sg.EuclideanSpace("x y z"), _lagrangian,
                               parameters=[h, grav, ell], holonomic=_sphere,
                               name="spherical").discretize(h, sg.LobattoIIIAB(3))


@functools.cache
def _vertical() -> sg.NoetherQuantity:
    return _pendulum().noether(lambda q: [-q[1], q[0], 0])


@functools.cache
def _run(backend: str = "numpy"):
    sim = _pendulum().euler_lagrange().compile(backend=backend)
    start = sim.from_velocity({"x": np.sin(1.0), "y": 0.0, "z": -np.cos(1.0)},
                              [0.0, 1.5, 0.4], PARAMS)
    return sim.simulate(start, STEPS, PARAMS)


@functools.cache
def _by_hand():
    """LobattoIIIAB(3) with ψ at the middle node, by hand: nodes 0, 1/2, 1, weights 1/6,
    2/3, 1/6, the quadratic through q₀, P = (q₀ + q₁)/2 + ζ, q₁, and the action
    h Σ_i b_i L(q_i, v_i) + Λ ψ(P).  Numeric functions of (q₀, q₁, ζ, Λ): the stage rows
    (∂/∂ζ, ∂/∂Λ = ψ(P)), their Jacobian, ∂/∂q₁ (F⁺L on Q × Q), and the Λ term of ∂/∂q₁,
    Λ ∇ψ(P)/2 (P moves by half of q₁)."""
    dt, g0, length = PARAMS["h"], PARAMS["g"], PARAMS["ell"]
    tau = sp.Symbol("tau")
    q0, q1, z = (sp.Matrix(sp.symbols(f"{n}0:3", real=True)) for n in ("a", "b", "z"))
    lam = sp.Symbol("Lam", real=True)
    ell_j = [2 * (tau - sp.Rational(1, 2)) * (tau - 1), -4 * tau * (tau - 1),
             2 * tau * (tau - sp.Rational(1, 2))]
    P = [q0, (q0 + q1) / 2 + z, q1]
    action = sp.S.Zero
    for node, weight in zip((0, sp.Rational(1, 2), 1), (sp.Rational(1, 6), sp.Rational(2, 3),
                                                       sp.Rational(1, 6))):
        q = sum((e.subs(tau, node) * p for e, p in zip(ell_j, P)), sp.zeros(3, 1))
        v = sum((sp.diff(e, tau).subs(tau, node) * p for e, p in zip(ell_j, P)),
                sp.zeros(3, 1)) / dt
        action += dt * weight * (v.dot(v) / 2 - g0 * q[2])
    action += lam * (P[1].dot(P[1]) - length ** 2)
    unknowns = [*z, lam]
    rows = sp.Matrix([sp.diff(action, s) for s in unknowns])
    args = (*q0, *q1, *unknowns)
    exprs = [rows, rows.jacobian(unknowns), sp.Matrix([sp.diff(action, s) for s in q1]),
             lam * P[1]]
    return [sp.lambdify(args, e, "numpy") for e in exprs]


def _hand_quantity(states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """F_X = (Aq₁)·∂L_d/∂q₁ at the stages (ζ, Λ) solved by Newton here, and the part of it
    that the interior multiplier contributes, (Aq₁)·Λ∇ψ(P)/2."""
    rows, jac, d_plus, lam_term = _by_hand()
    J, part = [], []
    for s in states:
        w = np.zeros(4)
        for _ in range(30):
            w -= np.linalg.solve(np.asarray(jac(*s[:6], *w), float),
                                 np.asarray(rows(*s[:6], *w), float).ravel())
        X = A @ s[3:6]
        J.append(X @ np.ravel(d_plus(*s[:6], *w)))
        part.append(X @ np.ravel(lam_term(*s[:6], *w)))
    return np.array(J), np.array(part)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_rotation_about_the_vertical_is_conserved(backend):
    """The rotation about e₃ is verified a symmetry on N = G|_M, and F_X along 400 steps is
    constant within 10⁻¹²·|F_X| (the rule of tests/test_galerkin.py and
    tests/test_holonomic.py for Noether quantities); the run stays on the sphere."""
    vertical = _vertical()
    assert vertical.is_symmetry and "N = G|_M" in vertical.verification
    run = _run(backend)
    q = run.states[:, 3:6]
    assert np.abs(np.linalg.norm(q, axis=1) - 1.0).max() < 1e-14
    J = vertical.along(run)
    assert len(J) == STEPS + 1 and abs(J[0]) > 1.0  # x₀·v_y: sin(1)·1.5
    assert np.abs(J - J[0]).max() <= 1e-12 * abs(J[0])


def test_the_quantity_is_the_hand_written_one_with_its_interior_multiplier():
    """F_X equals (Aq_k)·D₂L_d(q_{k−1}, q_k) of the scheme written by hand to 10⁻¹³, and
    the interior multiplier's term is needed: without it the quantity moves by more than
    10⁻³ along the same run (its stages solved by the test's own Newton)."""
    run = _run()
    J = _vertical().along(run)
    hand, part = _hand_quantity(run.states)
    np.testing.assert_allclose(J, hand, rtol=0, atol=1e-13)
    without = hand - part
    assert np.abs(without - without[0]).max() > 1e-3
    assert np.abs(hand - hand[0]).max() <= 1e-12 * abs(hand[0])


def test_the_diagnostics_solve_the_interior_multipliers():
    """The stages of every arrow of the constrained run are solved by the diagnostics too:
    the interior multipliers' Newton updates stall some tens of ulps from the root and are
    accepted as rounding (they raised DiagnosticsError when 8 ulps were demanded); the
    energy stays within 10⁻⁴ (relative) over the run and the momenta match to rounding."""
    run = _run()
    E = sg.diagnostics.energy(run)
    assert np.abs(E - E[0]).max() <= 1e-4 * abs(E[0])
    momenta = run.momenta()
    assert np.abs(momenta.matching()).max() <= 1e-13 * np.abs(momenta.plus).max()


def test_the_diagnostics_solve_every_arrow_of_a_long_constrained_run():
    """The stage solve stops arrow by arrow: it stopped only at an iteration where every
    arrow's update was rounding at once, which a double pendulum in Cartesian coordinates
    (LobattoIIIAB(3), two rods) never reached over 5,000 arrows (DiagnosticsError: "the
    internal stages of some arrow could not be solved").  Its energy stays within 10⁻⁴."""
    system = sg.ContinuousSystem(
        sg.EuclideanSpace("x1 y1 x2 y2"),
        lambda q, v: sum(vi ** 2 for vi in v) / 2 - grav * (q[1] + q[3]),
        parameters=[h, grav],
        holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1,
                             (q[2] - q[0]) ** 2 + (q[3] - q[1]) ** 2 - 1],
        name="cartesian_double").discretize(h, sg.LobattoIIIAB(3))
    sim = system.euler_lagrange().compile()
    params = {"h": 0.01, "g": 9.81}
    a, b = 1.1, -0.4
    q0 = {"x1": np.sin(a), "y1": -np.cos(a), "x2": np.sin(a) + np.sin(b),
          "y2": -np.cos(a) - np.cos(b)}
    v0 = [0.3 * np.cos(a), 0.3 * np.sin(a), 0.3 * np.cos(a) + 1.2 * np.cos(b),
          0.3 * np.sin(a) + 1.2 * np.sin(b)]
    run = sim.simulate(sim.from_velocity(q0, v0, params), 5000, params)
    E = sg.diagnostics.energy(run)
    assert len(E) == 5001 and np.abs(E - E[0]).max() <= 1e-4 * abs(E[0])
    assert np.isfinite(sg.diagnostics.momenta(run).plus).all()


def test_what_is_not_a_symmetry_is_detected():
    """Under gravity along e₃ the rotation about e₁ is tangent to the sphere but no symmetry
    (the defect at ζ* on N is not zero); the translation along e₃ is not tangent to the
    sphere (the coefficient of the end multiplier, −dψ(X), is not zero on M); and along a
    run the rotation's quantity moves."""
    pendulum = _pendulum()
    about_e1 = pendulum.noether(lambda q: [0, -q[2], q[1]])
    assert not about_e1.is_symmetry
    assert about_e1.verification.startswith("numeric at the stages ζ*")
    lift = pendulum.noether([0, 0, 1])
    assert not lift.is_symmetry and "not tangent" in lift.verification
    J = about_e1.along(_run())
    assert np.abs(J - J[0]).max() > 1e-2


@pytest.mark.slow
def test_the_symmetry_is_decided_on_the_constraint_set():
    """ψ = (|q|² − ℓ²)(2 + x) has the sphere as its zero set but is not invariant under the
    rotation about e₃ off it (dψ(X) ≠ 0 there): the rotation is tangent to M and a symmetry
    of L_d on N = G|_M, so it is decided one on N, and F_X is conserved along a run."""
    skewed = sg.ContinuousSystem(
        sg.EuclideanSpace("x y z"), _lagrangian, parameters=[h, grav, ell],
        holonomic=lambda q: [(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 - ell ** 2) * (2 + q[0])],
        name="skewed").discretize(h, sg.LobattoIIIAB(3))
    vertical = skewed.noether(lambda q: [-q[1], q[0], 0])
    assert vertical.is_symmetry
    assert sp.simplify(vertical.tangency[0]) != 0  # not tangent off M
    sim = skewed.euler_lagrange().compile(backend="numpy")
    start = sim.from_velocity({"x": np.sin(1.0), "y": 0.0, "z": -np.cos(1.0)},
                              [0.0, 1.5, 0.4], PARAMS)
    J = vertical.along(sim.simulate(start, 200, PARAMS))
    assert np.abs(J - J[0]).max() <= 1e-12 * abs(J[0])


@pytest.mark.slow
def test_rigid_rod_rotations_and_translations():
    """Two particles (masses 1 and 2) joined by a rod of length ℓ in the plane, without
    gravity, LobattoIIIAB(4) (two interior nodes, each with its multiplier): the common
    rotation and translation are symmetries and are kept within 10⁻¹²·max(|F_X|, 1) over
    300 steps; moving one particle alone is not tangent to the constraint set."""
    rod = sg.ContinuousSystem(
        sg.EuclideanSpace("x1 y1 x2 y2"),
        lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 + (v[2] ** 2 + v[3] ** 2),
        parameters=[h, ell], holonomic=lambda q: [(q[0] - q[2]) ** 2 + (q[1] - q[3]) ** 2
                                                  - ell ** 2],
        name="rod").discretize(h, sg.LobattoIIIAB(4))
    rotation = rod.noether(lambda q: [-q[1], q[0], -q[3], q[2]])
    translation = rod.noether([1, 0, 1, 0])
    assert rotation.is_symmetry and translation.is_symmetry
    one = rod.noether(lambda q: [-q[1], q[0], 0, 0])
    assert not one.is_symmetry and "not tangent" in one.verification
    sim = rod.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.1, "ell": 1.0}
    start = sim.from_velocity({"x1": 0.0, "y1": 0.0, "x2": 1.0, "y2": 0.0},
                              [0.3, 0.1, -0.2, 0.8], params)
    run = sim.simulate(start, 300, params)
    for quantity, expected in ((rotation, 1.6), (translation, 0.3 - 0.4)):
        J = quantity.along(run)
        assert abs(J[0] - expected) < 1e-12  # the continuous momentum at t = 0
        assert np.abs(J - J[0]).max() <= 1e-12 * max(abs(J[0]), 1.0)


def test_the_forced_balance_with_constraints():
    """A spherical pendulum with damping −cv and a torque u about e₃ (inputs per arrow):
    np.diff(F_X) equals the impulse I_k to rounding (docs/conventions.md §22, "The forced
    Noether balance", with the end multiplier's term of the defect, zero for X tangent)."""
    forced = sg.ContinuousSystem(
        sg.EuclideanSpace("x y z"), _lagrangian, parameters=[h, grav, ell, c],
        holonomic=_sphere, forces=lambda q, v: [-c * v[0] - u * q[1], -c * v[1] + u * q[0],
                                                -c * v[2]],
        inputs=[u], name="forced").discretize(h, sg.LobattoIIIAB(3))
    vertical = forced.noether(lambda q: [-q[1], q[0], 0])
    assert vertical.is_symmetry
    sim = forced.euler_lagrange().compile(backend="numpy")
    params = {**PARAMS, "c": 0.3}
    drive = np.random.default_rng(3).uniform(-1, 1, 201)
    start = sim.from_velocity({"x": np.sin(1.0), "y": 0.0, "z": -np.cos(1.0)},
                              [0.0, 1.5, 0.0], params, inputs=[drive[0]])
    run = sim.simulate(start, 200, params, inputs=drive[1:, None])
    J, impulse = vertical.along(run), vertical.impulse(run)
    assert np.abs(impulse).max() > 1e-2
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-14)


def test_constraints_on_the_arrows_as_well_are_refused():
    """With constraints φ on the arrows besides ψ, the symmetry would be decided on
    {φ = 0} ∩ G|_M, whose arrows are not constructed: UnsupportedFeatureError."""
    def lagrangian(g, zeta):
        (x0, y0), (x1, y1) = g.source, g.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h) + zeta[0] ** 2 / 2

    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("x y")), lagrangian, parameters=[h, ell],
        constraints=lambda g: [g.target[0] - g.source[0] - h], stages=1,
        holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - ell ** 2], name="both")
    with pytest.raises(sg.UnsupportedFeatureError, match="constraints on the arrows"):
        system.noether(lambda q: [-q[1], q[0]])
