"""Holonomic constraints on the configuration space (docs/conventions.md §15; seed 000 §3.3
with N = G|_M the restriction of G to M = {ψ = 0}): the equations against the textbook
constrained DEL and against the anchor formula, the Legendre transforms and Noether
quantities with their multiplier terms, compiled stepping, boundary-value problems,
``verify_stationary``, initial and boundary data, and the errors."""

from __future__ import annotations

import functools

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
from symgroupoid.verification import verify_stationary

EPS = float(np.finfo(float).eps)
h, ell = sp.symbols("h ell", positive=True)
PENDULUM = {"h": 0.01, "ell": 1.0, "g": 9.81}


@functools.cache
def derived(name: str):
    """(system, step) of a system of ``symgroupoid.systems``, derived once."""
    system = systems.link_chain(3) if name == "link_chain" else getattr(systems, name)()
    return system, system.euler_lagrange()


@functools.cache
def compiled(name: str):
    """(system, step, simulator): the C kernel built once per test process."""
    system, step = derived(name)
    return system, step, step.compile(backend="c", cache_dir=SESSION_CACHE)


def pendulum():
    return derived("spherical_pendulum")


def plane(psi, lagrangian=None, **kwargs) -> sg.DiscreteSystem:
    def kinetic(g):
        return sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), lagrangian or kinetic,
                             parameters=[h, ell], name="plane", holonomic=psi, **kwargs)


# --- the equations -------------------------------------------------------------------------------

def test_textbook_constrained_del() -> None:
    """On Q×Q the step is D₂L(q_{k−1}, q_k) + D₁L(q_k, q_{k+1}) + λ·∇ψ(q_k) = 0 and
    ψ(q_{k+1}) = 0, exactly, for a nonlinear L and ψ; the multiplier of the step is the
    multiplier λ_{k+1} of the arrow g_{k+1} = (q_k, q_{k+1}) at its source q_k."""
    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h) - h * sp.cos(xm) * ym ** 3

    def psi(q):
        return [q[0] ** 2 + q[1] ** 4 - ell ** 2]

    step = plane(psi, L).euler_lagrange()
    a = sp.symbols("u0 v0 u1 v1 u2 v2", real=True)
    q0, q1, q2 = a[0:2], a[2:4], a[4:6]
    lam = sp.Symbol("lam", real=True)
    Lexpr = L(sg.PairGroupoid(sg.EuclideanSpace("x y")).view(q0 + q1))
    textbook = [sp.diff(Lexpr, q1[i]) + sp.diff(Lexpr.xreplace(
        dict(zip(q0 + q1, q1 + q2))), q1[i]) + lam * sp.diff(psi(q1)[0], q1[i]) for i in range(2)]
    textbook.append(psi(q2)[0])
    named = {**dict(zip(step.arrows[0], q0 + q1)), **dict(zip(step.arrows[1][2:], q2)),
             step.unknowns[-1]: lam}
    assert step.unknowns[-1] == step.symbol("lambda", "k+1")[0]
    assert len(step) == 3 and step.n_holonomic == 1
    for residual, expected in zip(step.residuals, textbook):
        assert sp.expand(residual.xreplace(named) - expected) == 0


def test_anchor_enters_on_a_base_that_is_not_euclidean() -> None:
    """S² × SO(3) ⇉ S² with ψ(Γ) = Γ₃ − c: residual b is X⃖_b[L](g_k) − X⃗_b[L](g_{k+1}) +
    λ·dψ(β(g_k))(ρ(E_b)), the anchor ρ(E_b)(q) = d/dt β(h_b(t)) computed here from the
    section curves (seed 000 §3.3 with N = G|_M); the E₃ row has no multiplier (tangent)."""
    system, step = derived("tilted_top")
    G = system.groupoid
    g0, g1 = step.arrows[0], step.arrows[1]
    lam = step.symbol("lambda", "k+1")[0]
    left = sg.left_derivative(G, system.lagrangian, g0)
    slot = tuple(sp.Dummy(f"a{i}", real=True) for i in range(G.arrow_dim))
    right = [e.xreplace(dict(zip(slot, g1)))  # g1's source is an expression: differentiate
             for e in sg.right_derivative(G, system.lagrangian, slot)]  # on a slot
    t = sp.Symbol("t", real=True)
    q = G.target(g0)
    c = next(s for s in system.parameters if str(s) == "c")
    for b, curve in enumerate(G.section_curves(q, t)):
        anchor = [sp.diff(e, t).subs(t, 0) for e in G.target(curve)]
        term = lam * anchor[2]  # dψ = dΓ₃
        assert sp.expand(step.residuals[b] - (left[b] - right[b] + term)) == 0
    assert lam not in step.residuals[2].free_symbols
    assert sp.expand(step.residuals[3] - (G.target(g1)[2] - c)) == 0


def test_second_order_holonomic_step_and_boundary_value_problem() -> None:
    """L on G₂: D₃L(q_{k−2}, q_{k−1}, q_k) + D₂L(q_{k−1}, q_k, q_{k+1}) + D₁L(q_k, q_{k+1},
    q_{k+2}) + λ∇ψ(q_k) = 0 and ψ(q_{k+2}) = 0; the boundary-value problem keeps every free
    node on the circle and is stationary."""
    def acceleration(g1, g2):
        return sum((c2 - 2 * b + a0) ** 2 for a0, b, c2 in
                   zip(g1.source, g1.target, g2.target)) / (2 * h ** 3)

    system = sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), acceleration,
                                  parameters=[h, ell], name="circle2",
                                  holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - ell ** 2])
    step = system.euler_lagrange()
    x = [step.symbol("x", o) for o in range(-2, 3)]
    lam = step.symbol("lambda", "k+1")[0]
    expected = (x[4] - 4 * x[3] + 6 * x[2] - 4 * x[1] + x[0]) / h ** 3 + 2 * lam * x[2]
    assert sp.expand(step.residuals[0] - expected) == 0
    assert step.unknowns[-1] == lam
    start = ((1.0, 0.0), (np.cos(0.02), np.sin(0.02)))
    end = ((np.cos(1.0), np.sin(1.0)), (np.cos(1.02), np.sin(1.02)))
    sol = sg.solve_boundary_value(step, start, end, 24, params={"h": 0.05, "ell": 1.0},
                                  tol=1e-13)
    nodes = np.array(sol.configurations)
    assert np.max(np.abs(np.sum(nodes ** 2, axis=1) - 1.0)) <= 1e-13
    assert np.all(sol.multipliers[:2] == 0.0)  # their nodes are fixed by the boundary data
    assert verify_stationary(sol, system, {"h": 0.05, "ell": 1.0})
    sim = step.compile(backend="numpy")  # a start from a momentum: λ₀, λ₁ take its normal part
    state = sim.from_momentum((1.0, 0.0, np.cos(0.01), np.sin(0.01)), [0.0, 1.0, 0.0, 1.0],
                              {"h": 0.01, "ell": 1.0})
    traj = sim.simulate(state, steps=10, params={"h": 0.01, "ell": 1.0})
    assert np.max(np.abs(np.hypot(traj["x"], traj["y"]) - 1.0)) <= 4 * EPS


# --- momenta and Noether ---------------------------------------------------------------------

def test_legendre_transforms_carry_the_multiplier() -> None:
    """F⁻L(g_k, λ_k) = −D₁L − λ_k∇ψ(q_{k−1}) (the multiplier at the source), F⁺L = D₂L."""
    system, step = pendulum()
    forms = system.legendre()
    (x0, y0, z0), (x1, y1, z1) = step.arrows[0][:3], step.arrows[0][3:]
    lam = step.symbol("lambda", "k")[0]
    hh = system.parameters[0]
    grav = system.parameters[2]
    minus = [(x1 - x0) / hh - 2 * lam * x0, (y1 - y0) / hh - 2 * lam * y0,
             (z1 - z0) / hh + hh * grav / 2 - 2 * lam * z0]
    plus = [(x1 - x0) / hh, (y1 - y0) / hh, (z1 - z0) / hh - hh * grav / 2]
    assert all(sp.expand(a - b) == 0 for a, b in zip(forms.minus, minus))
    assert all(sp.expand(a - b) == 0 for a, b in zip(forms.plus, plus))


def test_noether_symmetry_needs_tangency_to_the_constraint_set() -> None:
    """X = (1, y) with ψ = y is tangent to M = {y = 0} only on M and L is invariant only on
    N = G|_M: verified on N (ideal reduction), not on G; X = ∂_y is not tangent: refused."""
    system = plane(lambda q: [q[1]])
    tangent_on_m = system.noether(lambda q: [1, q[1]])
    assert tangent_on_m.is_symmetry
    assert sp.expand(tangent_on_m.defect) != 0  # not a symmetry off N
    assert not system.noether(1).is_symmetry
    assert not systems.spherical_pendulum().noether(0).is_symmetry  # not tangent to the sphere
    # many constraints: no Gröbner basis (minutes for five links); gravity breaks the symmetry
    chain = systems.link_chain(5)
    assert not chain.noether(lambda q: [c for i in range(5) for c in (-q[2 * i + 1], q[2 * i])]
                             ).is_symmetry


# --- compiled stepping ---------------------------------------------------------------------------

@needs_cc
def test_spherical_pendulum_compiled() -> None:
    """|q_k| = ℓ at every node to rounding; the angular momentum about the vertical (a
    Noether quantity) is conserved to rounding; the energy is bounded; F⁺L(g_k) =
    F⁻L(g_{k+1}, λ_{k+1}) along the run; the run is stationary for Σ L + λ·ψ."""
    system, step, sim = compiled("spherical_pendulum")
    start = sim.from_momentum({"x": np.sin(0.8), "y": 0.0, "z": -np.cos(0.8)}, [0.0, 1.2, 0.0],
                              PENDULUM)
    traj = sim.simulate(start, steps=4000, params=PENDULUM)
    q = np.stack([traj["x"], traj["y"], traj["z"]], axis=1)
    assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1.0)) <= 4 * EPS
    vertical = system.noether(lambda p: [-p[1], p[0], 0])
    assert vertical.is_symmetry
    Lz = vertical.along(traj)
    assert abs(Lz[0]) > 0.5 and np.max(np.abs(Lz - Lz[0])) <= 1e-12 * abs(Lz[0])
    E = traj.energy()
    assert np.max(np.abs(E - E[0])) <= 1e-3 * abs(E[0])
    late = E[-1000:]
    assert abs(late.mean() - E[:1000].mean()) <= 1e-4 * abs(E[0])  # no drift
    momenta = traj.momenta()
    assert np.max(np.abs(momenta.matching())) <= 1e-12 * np.max(np.abs(momenta.plus))
    assert np.max(np.abs(traj.constraint_residuals())) <= 4 * EPS
    short = sim.simulate(start, steps=120, params=PENDULUM)
    assert verify_stationary(short, system)


@needs_cc
def test_initial_data_on_the_constraint_set() -> None:
    """A start must have both nodes of its arrow on M (each named); the multipliers of a
    holonomic-only state may be left out (they enter no step); project_initial moves the
    target onto M; a momentum start at a base point off M is refused."""
    system, step, sim = compiled("spherical_pendulum")
    th = 0.4
    named = {"x": (np.sin(th), np.sin(th + 0.01)), "y": (0.0, 0.0),
             "z": (-np.cos(th), -np.cos(th + 0.01))}
    traj = sim.simulate(named, steps=5, params=PENDULUM)
    assert traj["lambda"][0, 0] == 0.0 and traj["lambda"][1, 0] != 0.0
    with pytest.raises(sg.ShapeError, match=r"ψ_1\(β\(g_k\)\)") as err:
        sim.simulate({**named, "z": (-np.cos(th), -0.9)}, steps=5, params=PENDULUM)
    assert "ψ_1(α(g_k))" not in str(err.value)
    with pytest.raises(sg.ShapeError, match=r"ψ_1\(α\(g_k\)\)"):
        sim.simulate({**named, "z": (-0.9, -np.cos(th + 0.01))}, steps=5, params=PENDULUM)
    moved = sim.project_initial({**named, "z": (-np.cos(th), -0.9)}, PENDULUM)
    q1 = moved[step.knowns.index(step.symbol("x", "k")):][:3]
    assert abs(np.linalg.norm(q1) - 1.0) <= 4 * EPS
    with pytest.raises(sg.ShapeError, match=r"ψ_1\(α\(g_k\)\)"):
        sim.from_momentum({"x": 0.5, "y": 0.0, "z": -0.5}, [0.0, 1.0, 0.0], PENDULUM)


@needs_cc
def test_link_chain_keeps_its_links() -> None:
    """A planar chain of three links in Cartesian coordinates: every link keeps its length at
    every node to rounding, the energy is bounded; without gravity the angular momentum
    about the pivot (a Noether quantity: rotations are tangent to M) is conserved."""
    system, step, sim = compiled("link_chain")
    lengths = np.array([1.0, 0.8, 0.6])
    hh = 0.005
    angles, rates = np.array([0.6, 1.1, 1.5]), np.array([0.5, -0.4, 0.8])

    def tips(th):
        return np.cumsum(lengths[:, None] * np.stack([np.sin(th), -np.cos(th)], axis=1), axis=0)

    p0, p1 = tips(angles), tips(angles + hh * rates)
    initial = {f"{c}{i + 1}": (p0[i, j], p1[i, j]) for i in range(3) for j, c in enumerate("xy")}
    pivot = system.noether(lambda q: [c for i in range(3) for c in (-q[2 * i + 1], q[2 * i])])
    for g in (9.81, 0.0):
        params = {"h": hh, "g": g, "l1": 1.0, "l2": 0.8, "l3": 0.6}
        traj = sim.simulate(initial, steps=3000, params=params)
        p = np.stack([np.stack([traj[f"x{i}"], traj[f"y{i}"]], axis=1) for i in (1, 2, 3)],
                     axis=1)
        joints = np.concatenate([np.zeros_like(p[:, :1]), p], axis=1)
        links = np.linalg.norm(np.diff(joints, axis=1), axis=2)
        assert np.max(np.abs(links - lengths)) <= 8 * EPS
        E = traj.energy()
        assert np.max(np.abs(E - E[0])) <= 1e-2 * max(1.0, abs(E[0]))
        J = pivot.along(traj)
        drift = np.max(np.abs(J - J[0])) / abs(J[0])
        assert (drift <= 1e-11) if g == 0.0 else (drift > 1e-3)


@needs_cc
def test_tilted_top_compiled() -> None:
    """The heavy top with Γ₃ held at cos θ₀ on S² × SO(3) ⇉ S²: Γ₃ fixed to rounding, the
    energy bounded, the run stationary; for I₁ = I₂ the spin about e₃ is conserved."""
    system, step, sim = compiled("tilted_top")
    tilt = 0.5
    spin = system.noether(2)
    for i2 in (1.4, 1.0):
        params = {"h": 0.01, "mgl": 1.0, "I1": 1.0, "I2": i2, "I3": 0.5, "c": np.cos(tilt)}
        start = sim.from_momentum({"Gamma": (0.0, np.sin(tilt), np.cos(tilt))},
                                  (0.2, 0.1, 3.0), params)
        traj = sim.simulate(start, steps=2000, params=params)
        gamma = traj["Gamma"]
        assert np.max(np.abs(gamma[:, 2] - np.cos(tilt))) <= 4 * EPS
        assert np.ptp(gamma[:, 0]) > 0.5  # it precesses
        E = traj.energy()
        assert np.max(np.abs(E - E[0])) <= 1e-8 * abs(E[0])
        S = spin.along(traj)
        drift = np.max(np.abs(S - S[0])) / abs(S[0])
        assert (drift <= 1e-12) if i2 == 1.0 else (drift > 1e-6)
    assert verify_stationary(sim.simulate(start, steps=60, params=params), system)


def test_mixed_constraints_and_holonomic_numpy() -> None:
    """Constraints on arrows and on configurations together: the multipliers of φ then ψ,
    all required in a state; φ and ψ hold along the run."""
    def L(g):
        return sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h)

    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("x y z")), L,
        constraints=lambda g: [g.target[2] - g.source[2] - h], parameters=[h, ell], name="helix",
        holonomic=lambda q: [q[0] ** 2 + q[1] ** 2 - ell ** 2])
    assert repr(system).endswith("1 constraint, 1 holonomic)")
    step = system.euler_lagrange()
    assert (step.n_constraints, step.n_holonomic) == (2, 1)
    sim = step.compile(backend="numpy")
    params = {"h": 0.1, "ell": 1.0}
    initial = {"x": (1.0, np.cos(0.1)), "y": (0.0, np.sin(0.1)), "z": (0.0, 0.1)}
    with pytest.raises(sg.ShapeError, match="misses lambda"):
        sim.simulate(initial, steps=3, params=params)
    traj = sim.simulate({**initial, "lambda": [0.0, 0.0]}, steps=50, params=params)
    assert np.max(np.abs(np.hypot(traj["x"], traj["y"]) - 1.0)) <= 4 * EPS
    assert np.max(np.abs(np.diff(traj["z"]) - 0.1)) <= 1e-14
    assert "\\ell^{2}" in step.latex().splitlines()[-2]


# --- boundary-value problems ---------------------------------------------------------------------

@needs_cc
def test_boundary_value_problem_on_the_sphere() -> None:
    """The spherical pendulum between two points of the sphere: every node on M, the
    multiplier of the first term (its node is fixed) 0, stationary; ends off M refused."""
    system, step = pendulum()
    q0, qn = (np.sin(0.5), 0.0, -np.cos(0.5)), (0.0, np.sin(0.6), -np.cos(0.6))
    sol = sg.solve_boundary_value(step, q0, qn, 40, params=PENDULUM, tol=1e-13)
    nodes = np.array(sol.configurations)
    assert np.max(np.abs(np.linalg.norm(nodes, axis=1) - 1.0)) <= 1e-13
    assert sol.multipliers[0, 0] == 0.0 and np.all(sol.multipliers[1:, 0] != 0.0)
    assert verify_stationary(sol, system, PENDULUM)
    with pytest.raises(sg.ShapeError, match=r"ψ_1\(end\)"):
        sg.solve_boundary_value(step, q0, (0.0, 0.5, -0.5), 40, params=PENDULUM)


# --- errors --------------------------------------------------------------------------------------

def test_input_errors() -> None:
    """Each bad holonomic input is named when the system is built."""
    with pytest.raises(sg.ShapeError, match="single base point"):
        sg.DiscreteSystem(sg.SO3("W"), lambda g: g.matrix.trace(), holonomic=lambda q: [1])
    with pytest.raises(sg.ShapeError, match="does not depend on the configuration"):
        plane(lambda q: [ell - 1])
    with pytest.raises(sg.ShapeError, match="more constraints than unknowns"):
        plane(lambda q: [q[0], q[1], q[0] + q[1]])
    with pytest.raises(sg.UndeclaredSymbolError, match="holonomic constraints uses symbol"):
        plane(lambda q: [q[0] - sp.Symbol("R")])
    with pytest.raises(sg.ShapeError, match="list of scalar"):
        plane(lambda q: q[0] ** 2 + q[1] ** 2 - 1)
    with pytest.raises(sg.CallableError, match="holonomic constraints"):
        plane(lambda q: [q[5]])
    with pytest.raises(sg.CallableError, match="function of the base point"):
        plane([1])


def test_reduction_refuses_holonomic_systems() -> None:

    system, _ = pendulum()
    with pytest.raises(sg.UnsupportedFeatureError, match="holonomic"):
        system.reduce(object())  # refused before the morphism is looked at


def test_a_constraint_the_anchor_does_not_see_is_diagnosed() -> None:
    """SO(3) acting on the first three coordinates of R⁴ only: no section moves the fourth,
    so ψ = d − 1 has dψ(ρ(X)) = 0 for every X and its multiplier enters no equation; the
    message says so (it does not suggest holonomic=, which is what was used)."""
    G = sg.ActionGroupoid(sg.EuclideanSpace("a b c d"), sg.SO3("W"),
                          lambda p, W: (*(W.T * sp.Matrix(p[:3])), p[3]))
    with pytest.raises(sg.DegenerateSystemError) as err:
        sg.DiscreteSystem(G, lambda g: -g.matrix.trace() / h, parameters=[h], name="unseen",
                          holonomic=lambda q: [q[3] - 1]).euler_lagrange()
    text = str(err.value)
    assert "dψ(ρ(X)) = 0 for every basis section" in text and "holonomic=" not in text


# --- longer runs ----------------------------------------------------------------------------------

@needs_cc
def test_spherical_pendulum_long_run() -> None:
    """10⁵ steps: |q_k| = ℓ to rounding, L_z to 1e-11, the energy bounded without drift."""
    system, step, sim = compiled("spherical_pendulum")
    start = sim.from_momentum({"x": np.sin(1.2), "y": 0.0, "z": -np.cos(1.2)}, [0.0, 2.0, 0.0],
                              PENDULUM)
    traj = sim.simulate(start, steps=100_000, params=PENDULUM, every=10)
    q = np.stack([traj["x"], traj["y"], traj["z"]], axis=1)
    assert np.max(np.abs(np.linalg.norm(q, axis=1) - 1.0)) <= 4 * EPS
    Lz = system.noether(lambda p: [-p[1], p[0], 0]).along(traj)
    assert np.max(np.abs(Lz - Lz[0])) <= 1e-11 * abs(Lz[0])
    E = traj.energy()  # an O(h²) oscillation (a few 10⁻³ here), without drift
    assert np.max(np.abs(E - E[0])) <= 1e-2 * abs(E[0])
    assert abs(E[-1000:].mean() - E[:1000].mean()) <= 1e-4 * abs(E[0])


@pytest.mark.slow
@needs_cc
def test_plate_ball_kept_on_a_circle() -> None:
    """Seed 000 §6.2 on R² × R² × SO(3) ⇉ R² with ψ = x² + y² − R²: three rolling
    constraints and one holonomic; the ball stays on the circle, the rolling constraints
    hold, the run is stationary."""
    base = systems.plate_ball()
    R = sp.Symbol("R", positive=True)
    system = sg.DiscreteSystem(base.groupoid, base.lagrangian, constraints=base.constraints,
                               parameters=[*base.parameters, R], name="plate_ball_circle",
                               holonomic=lambda q: [q[0][0] ** 2 + q[0][1] ** 2 - R ** 2])
    sim = system.euler_lagrange().compile(backend="c", cache_dir=SESSION_CACHE)
    params = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02, "R": 2.0}
    start = sim.from_momentum({"x": 2.0, "y": 0.0}, (0.0, 0.5, 0.01, 0.02, 0.01), params)
    traj = sim.simulate(start, steps=20_000, params=params)
    assert np.max(np.abs(np.hypot(traj["x"], traj["y"]) - 2.0)) <= 8 * EPS
    assert np.max(np.abs(traj.constraint_residuals())) <= 1e-13
    assert verify_stationary(sim.simulate(start, steps=60, params=params), system)
