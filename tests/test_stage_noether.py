"""The forced Noether balance of systems with internal stages (docs/conventions.md §22, "The
forced Noether balance"): J = ⟨F⁺L, X(β)⟩ at the stages each arrow's step solved (the forced
stage rows with that arrow's inputs) changes over a step by

    I_k = Σ_b X^b(β(g_k))·(f⁺_b(g_k) + f⁻_b(g_{k+1})) − D(g_{k+1}),

D the symmetry defect at the new arrow's forced stages, which is the stage forces' work
f_ζ·Y along the stages' motion Y under the symmetry.  Checked to rounding on the plane (a
central field, damping and an input torque, GaussLegendre(2) and LobattoIIIAB(3)), against
GaussLegendre(2) written by hand with its stages solved here (Y_j = Aζ_j for the rotation
X(q) = Aq); with internal forces the impulse telescopes and the forced momentum
⟨F⁺L + f⁺, X(β)⟩ is conserved (a translation's J itself); on SO(3) with an input torque and
on two rotors joined by a driven, damped joint (slow)."""

import functools

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
c = sp.Symbol("c", real=True)
k = sp.Symbol("k", real=True)
u = sp.Symbol("u", real=True)
C, DT, STEPS = 0.3, 0.05, 150
A = np.array([[0.0, -1.0], [1.0, 0.0]])  # the rotation X(q) = Aq of the plane


def _lagrangian(q, v):
    r2 = q[0] ** 2 + q[1] ** 2
    return (v[0] ** 2 + v[1] ** 2) / 2 - r2 / 2 - r2 ** 2 / 4


def _force(q, v, damping=c, drive=u):
    """Damping −c v and a torque u about the origin, u·(−y, x)."""
    return [-damping * v[0] - drive * q[1], -damping * v[1] + drive * q[0]]


@functools.cache
def _particle(scheme) -> sg.DiscreteSystem:
    return sg.ContinuousSystem(sg.EuclideanSpace("x y"), _lagrangian, parameters=[h, c],
                               forces=_force, inputs=[u], name="particle").discretize(h, scheme)


def _run(system, steps=STEPS, seed=4):
    sim = system.euler_lagrange().compile(backend="numpy")
    drive = np.random.default_rng(seed).uniform(-1, 1, steps + 1)
    return sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.06), "u": [drive[0]]}, steps,
                        {"h": DT, "c": C}, inputs=drive[1:, None])


@functools.cache
def _by_hand():
    """GaussLegendre(2) on the plane by hand (Marsden–West's control points q₀, q₀ + Δ/2 +
    ζ, q₁; f⁻ = f₀ + f₁/2, f⁺ = f₂ + f₁/2, f_ζ = f₁): numeric functions of (q₀, q₁, ζ, u)
    (each a 2-vector, u a number) giving the forced stage rows, their ζ-Jacobian, f⁻, f⁺,
    f_ζ and ∂L/∂q₁ (F⁺L on Q × Q)."""
    tau, uu = sp.symbols("tau uu", real=True)
    q0, q1, z = (sp.Matrix(sp.symbols(f"{n}0:2", real=True)) for n in ("a", "b", "z"))
    nodes = [sp.Rational(1, 2) - sp.sqrt(3) / 6, sp.Rational(1, 2) + sp.sqrt(3) / 6]
    times = [0, sp.Rational(1, 2), 1]
    ell = [sp.prod([(tau - times[i]) / (times[j] - times[i]) for i in range(3) if i != j])
           for j in range(3)]
    P = [q0, q0 + (q1 - q0) / 2 + z, q1]
    at = [(sum((e.subs(tau, ci) * p for e, p in zip(ell, P)), sp.zeros(2, 1)),
           sum((sp.diff(e, tau).subs(tau, ci) * p for e, p in zip(ell, P)), sp.zeros(2, 1))
           / DT) for ci in nodes]
    L = DT * sum(_lagrangian(q, v) for q, v in at) / 2
    f = [DT * sum((e.subs(tau, ci) * sp.Matrix(_force(q, v, C, uu))
                   for ci, (q, v) in zip(nodes, at)), sp.zeros(2, 1)) / 2 for e in ell]
    f_minus, f_plus, f_zeta = f[0] + f[1] / 2, f[2] + f[1] / 2, f[1]
    rows = sp.Matrix([sp.diff(L, s) for s in z]) + f_zeta
    args = (*q0, *q1, *z, uu)
    exprs = [rows, rows.jacobian(z), f_minus, f_plus, f_zeta,
             sp.Matrix([sp.diff(L, s) for s in q1])]
    return [sp.lambdify(args, e, "numpy") for e in exprs]


def _hand_stages(states) -> np.ndarray:
    rows, jac = _by_hand()[:2]
    z = np.zeros((len(states), 2))
    for _ in range(30):
        for i, s in enumerate(states):
            args = (*s[:4], *z[i], s[4])
            z[i] -= np.linalg.solve(np.asarray(jac(*args), float),
                                    np.asarray(rows(*args), float).ravel())
    return z


@pytest.mark.slow
def test_the_balance_of_a_rotation_is_the_hand_written_one():
    """GaussLegendre(2): J = ⟨F⁺L, Aq_k⟩ at the forced stages and the impulse
    X(q_k)·(f⁺(g_k) + f⁻(g_{k+1})) + f_ζ(g_{k+1})·Aζ_{k+1} written by hand agree with the
    library's to rounding, and np.diff(J) equals the impulse; the stage term is not
    negligible (the balance fails without it)."""
    system = _particle(sg.GaussLegendre(2))
    rotation = system.noether(lambda q: [-q[1], q[0]])
    assert rotation.is_symmetry
    run = _run(system)
    J, impulse = rotation.along(run), rotation.impulse(run)
    states = run.states
    z = _hand_stages(states)
    _, _, f_minus, f_plus, f_zeta, d_plus = _by_hand()
    at = [(*s[:4], *zi, s[4]) for s, zi in zip(states, z)]
    X = states[:, 2:4] @ A.T  # X(β(g_k)) = A q_k
    hand_J = [x @ np.ravel(d_plus(*a)) for x, a in zip(X, at)]
    np.testing.assert_allclose(J, hand_J, rtol=0, atol=1e-13)
    junction = np.array([x @ (np.ravel(f_plus(*a)) + np.ravel(f_minus(*b)))
                         for x, a, b in zip(X[:-1], at[:-1], at[1:])])
    stage = np.array([np.ravel(f_zeta(*b)) @ (A @ zi) for b, zi in zip(at[1:], z[1:])])
    np.testing.assert_allclose(impulse, junction + stage, rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-14)
    assert np.abs(impulse).max() > 1e-2  # the torque and the damping act
    assert np.abs(stage).max() > 1e-7  # ... and the stage forces' term is needed


def test_the_balance_with_lobatto_and_without_inputs():
    """LobattoIIIAB(3), and damping alone (a forced system without inputs): np.diff(J)
    equals the impulse to rounding."""
    rotation_of = {}
    lobatto = _particle(sg.LobattoIIIAB(3))
    rotation_of["lobatto"] = lobatto.noether(lambda q: [-q[1], q[0]])
    run = _run(lobatto)
    J, impulse = rotation_of["lobatto"].along(run), rotation_of["lobatto"].impulse(run)
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-14)
    damped = sg.ContinuousSystem(sg.EuclideanSpace("x y"), _lagrangian, parameters=[h, c],
                                 forces=lambda q, v: _force(q, v, drive=0),
                                 name="damped").discretize(h, sg.GaussLegendre(2))
    rotation = damped.noether(lambda q: [-q[1], q[0]])
    sim = damped.euler_lagrange().compile(backend="numpy")
    run = sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.06)}, STEPS, {"h": DT, "c": C})
    J, impulse = rotation.along(run), rotation.impulse(run)
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-14)
    assert J[-1] < 0.8 * J[0]  # the damping takes angular momentum away


@pytest.mark.slow
def test_internal_forces_telescope():
    """Two particles in the plane joined by a spring and a damper along the line between
    them, with equal and opposite drives: the forces' work along a translation or a rotation
    vanishes on every arrow.  A translation's J is conserved (its weights are the same for
    both particles); a rotation's J changes by P_k − P_{k+1}, P = f⁺·X(β), so the forced
    momentum ⟨F⁺L + f⁺, X(β)⟩ (``momenta().plus`` paired with X) is conserved to rounding."""

    def L(q, v):
        (a, b), (va, vb) = q, v
        return (va.dot(va) + vb.dot(vb)) / 2 - k * (a - b).dot(a - b) / 2

    def F(q, v):
        (a, b), (va, vb) = q, v
        d = a - b
        f = -c * (va - vb).dot(d) * d + u * d  # along the line: central
        return [f[0], f[1], -f[0], -f[1]]

    pair = sg.ContinuousSystem([sg.EuclideanSpace("x1 y1"), sg.EuclideanSpace("x2 y2")], L,
                               parameters=[h, c, k], forces=F, inputs=[u],
                               name="pair").discretize(h, sg.GaussLegendre(2))
    translation = pair.noether([1, 0, 1, 0])
    rotation = pair.noether(lambda q: [-q[1], q[0], -q[3], q[2]])
    assert translation.is_symmetry and rotation.is_symmetry
    sim = pair.euler_lagrange().compile(backend="numpy")
    drive = np.random.default_rng(5).uniform(-1, 1, STEPS + 1)
    run = sim.simulate({"x1": (1.0, 1.0), "y1": (0.0, 0.06), "x2": (-1.0, -1.03),
                        "y2": (0.2, 0.2), "u": [drive[0]]}, STEPS,
                       {"h": DT, "c": C, "k": 2.0}, inputs=drive[1:, None])
    P = translation.along(run)
    assert np.abs(P - P[0]).max() < 1e-13 and np.abs(translation.impulse(run)).max() < 1e-15
    J, impulse = rotation.along(run), rotation.impulse(run)
    plus = run.momenta().plus
    scale = np.abs(run.states[:, :8]).max() * np.abs(plus).max()  # J's terms' size
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-13 * scale)
    assert np.abs(J - J[0]).max() > 1e-6  # J alone is not kept ...
    end = run.states[:, [2, 3, 6, 7]]  # the arrow is (x₁, y₁ at k − 1, k; x₂, y₂ at k − 1, k)
    X = np.column_stack([-end[:, 1], end[:, 0], -end[:, 3], end[:, 2]])
    forced = np.einsum("kb,kb->k", plus, X)
    assert np.abs(forced - forced[0]).max() < 1e-13 * scale  # ... the forced momentum is


@pytest.mark.parametrize("gravity", [1, 0])
def test_holonomic_constraints_with_stages_are_decided_on_the_constraint_set(gravity):
    """With holonomic constraints the symmetry is decided at the stages (interior
    multipliers included) of random arrows of N = G|_M (docs/conventions.md §22; the
    quantities along runs: tests/test_stage_noether_holonomic.py): the rotation of the
    planar pendulum is a symmetry without gravity and not with it."""
    pendulum = sg.ContinuousSystem(
        sg.EuclideanSpace("x y"), lambda q, v: (v[0] ** 2 + v[1] ** 2) / 2 - gravity * q[1],
        parameters=[h], holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - 1],
        name="pendulum").discretize(h, sg.LobattoIIIAB(3))
    rotation = pendulum.noether(lambda q: [-q[1], q[0]])
    assert rotation.is_symmetry == (gravity == 0)
    assert rotation.verification.endswith("random arrows of N = G|_M")


def test_along_needs_the_inputs_of_each_arrow():
    rotation = _particle(sg.GaussLegendre(2)).noether(lambda q: [-q[1], q[0]])
    run = _run(_particle(sg.GaussLegendre(2)), steps=3)

    class Stripped:
        states = run.states[:, :4]
        parameters = run.parameters
        _layout = run._layout

    with pytest.raises(sg.ShapeError, match="forced stages"):
        rotation.along(Stripped())


# --- on groups (slow: the Noether forms of the forced step on SO(3) take ~2 min, F^±L in SymPy) -

@pytest.mark.slow
def test_the_balance_of_an_input_torque_on_so3():
    """A rigid body with a body-frame input torque and damping, GaussLegendre(2) on the pair
    groupoid of SO(3): the spatial angular momentum about e₃ changes by the impulse to
    rounding (the symmetry moves no stage: they live in the chart at the source)."""
    inertia = sp.diag(*sp.symbols("J1:4", positive=True))
    d, torque = sp.Symbol("d", real=True), sp.symbols("tau1:4", real=True)
    body = sg.ContinuousSystem(
        sg.SO3("R"), lambda R, xi: (xi.T * inertia * xi)[0, 0] / 2,
        parameters=[h, *inertia.diagonal(), d],
        forces=lambda R, xi: [-d * xi[a] + torque[a] for a in range(3)],
        inputs=list(torque), name="body").discretize(h, sg.GaussLegendre(2))
    spatial = body.noether(lambda q: [q[6], q[7], q[8]])
    assert spatial.is_symmetry
    sim = body.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.05, "J1": 1.0, "J2": 2.0, "J3": 3.0, "d": 0.3}
    U = np.random.default_rng(2).normal(size=(101, 3))
    start = sim.from_velocity({"R": np.eye(3)}, [0.3, 1.0, 0.4], params, inputs=U[0])
    run = sim.simulate(start, 100, params, inputs=U[1:])
    J, impulse = spatial.along(run), spatial.impulse(run)
    assert np.abs(impulse).max() > 1e-2
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-13)


@pytest.mark.slow
def test_joint_torques_between_two_rotors():
    """Two rotors on SO(2) × SO(2) joined by a driven, damped joint (torque τ on one, −τ on
    the other): the common rotation's impulse telescopes, and the forced momentum
    ⟨F⁺L + f⁺, X⟩ is conserved to rounding."""

    def L(q, v):
        (a, b), (va, vb) = q, v
        return (va[0] ** 2 + 2 * vb[0] ** 2) / 2 + k * (a.T * b)[0, 0]

    def F(q, v):
        (_, _), (va, vb) = q, v
        t = -c * (va[0] - vb[0]) + u
        return [t, -t]

    rotors = sg.ContinuousSystem([sg.SO2("A"), sg.SO2("B")], L, parameters=[h, c, k],
                                 forces=F, inputs=[u],
                                 name="rotors").discretize(h, sg.GaussLegendre(2))
    common = rotors.noether([1, 1])
    assert common.is_symmetry
    sim = rotors.euler_lagrange().compile(backend="numpy")

    def R(a):
        return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])

    drive = np.random.default_rng(1).normal(size=STEPS + 1)
    run = sim.simulate({"A": (R(0.1), R(0.15)), "B": (R(-0.4), R(-0.42)), "u": [drive[0]]},
                       STEPS, {"h": DT, "c": C, "k": 2.0}, inputs=drive[1:, None])
    J, impulse = common.along(run), common.impulse(run)
    np.testing.assert_allclose(np.diff(J), impulse, rtol=0, atol=1e-14)
    forced = run.momenta().plus.sum(axis=1)
    assert np.abs(forced - forced[0]).max() < 1e-13


def test_the_quantity_on_the_graph_is_its_symbolic_form_at_the_solved_stages():
    """noether() of a system with stages builds F_X and the defect on the expression graph
    (the symbolic Legendre transforms of a Galerkin step on SO(3) took minutes); the SymPy
    form, built when asked for, has the same values at the stages ζ* of each arrow."""
    system = sg.ContinuousSystem(sg.EuclideanSpace("x y"), _lagrangian, parameters=[h],
                                 name="plane").discretize(h, sg.GaussLegendre(2))
    nq = system.noether(lambda q: [-q[1], q[0]])
    assert nq.is_symmetry and "expression graph" in repr(nq)
    assert not system.noether([1, 0]).is_symmetry  # a translation: the potential breaks it
    sim = system.euler_lagrange().compile(backend="numpy")
    traj = sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.06)}, 40, {"h": DT})
    on_graph = nq.along(traj)
    zeta = sg.verification.stage_values(system, traj.states, np.zeros((len(traj.states), 0)),
                                        [DT])
    f = sp.lambdify([list(nq.arrow), list(nq.stages), [h]], nq.expr)
    symbolic = np.array([f(s, z, [DT]) for s, z in zip(traj.states, zeta)])
    np.testing.assert_allclose(on_graph, symbolic, rtol=1e-12, atol=1e-13)
    assert np.ptp(on_graph) < 1e-12 and "F_X = " in repr(nq) and "graph" not in repr(nq)


def test_evaluate_takes_the_arrow_at_its_stages():
    """``NoetherQuantity.evaluate`` of a quantity with stages raised NameError (the generic
    stages ζ were free in the SymPy form it evaluated); it is F_X at the arrow's stages ζ*,
    as ``along`` takes them (without forces: the unforced stages), and arrays of other
    lengths are ShapeErrors."""
    free = sg.ContinuousSystem(sg.EuclideanSpace("x y"), _lagrangian, parameters=[h],
                               name="free_particle").discretize(h, sg.GaussLegendre(2))
    nq = free.noether(lambda q: [-q[1], q[0]])
    sim = free.euler_lagrange().compile(backend="numpy")
    run = sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.06)}, 5, {"h": DT})
    values = [nq.evaluate(state, [], [DT]) for state in run.states]
    np.testing.assert_allclose(values, nq.along(run), rtol=1e-13)
    for arrow, params in (([1.0, 0.0], [DT]), ([1.0, 1.0, 0.0, 0.06], [])):
        with pytest.raises(sg.ShapeError, match="NoetherQuantity.evaluate"):
            nq.evaluate(arrow, [], params)
