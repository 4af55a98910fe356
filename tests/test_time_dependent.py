"""Time-dependent systems on R×R×G (seed 000 §6.3; docs/conventions.md §7)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from conftest import newton, predicted

import symgroupoid as sg

h, k_ = sp.symbols("h kappa", positive=True)


def _pendulum_lagrangian(dt, q0, q1):
    """(t₁−t₀)[½((q₁−q₀)/(t₁−t₀))² − V((q₀+q₁)/2)], V(q) = −κ cos q."""
    v = (q1 - q0) / dt
    return dt * (v ** 2 / 2 + k_ * sp.cos((q0 + q1) / 2))


def test_fixed_step_decouples_and_equals_time_independent_del():
    """Example 6.2: with φ = t₁ − t₀ − h the time equation only fixes the multiplier and the
    remaining rows are the ordinary DEL of L(q₀, q₁) = L_R(0, h, q₀, q₁)."""
    Q = sg.EuclideanSpace("q")
    GR = sg.TimeGroupoid(sg.PairGroupoid(Q))
    timed = sg.DiscreteSystem(
        GR, lambda g: _pendulum_lagrangian(g.t1 - g.t0, g.source[0], g.target[0]),
        constraints=lambda g: [g.t1 - g.t0 - h], parameters=[h, k_], name="fixed")
    plain = sg.DiscreteSystem(
        sg.PairGroupoid(Q), lambda g: _pendulum_lagrangian(h, g.source[0], g.target[0]),
        parameters=[h, k_], name="plain")
    st, sp_ = timed.euler_lagrange(), plain.euler_lagrange()
    t = {o: st.symbol("t", o) for o in (-1, 0, 1)}
    lam = {o: st.symbol("lambda", o)[0] for o in (0, 1)}
    on_grid = {t[0]: t[-1] + h, t[1]: t[-1] + 2 * h}
    time_row, space_row, constraint = st.residuals
    assert sp.simplify(space_row.xreplace(on_grid) - sp_.residuals[0]) == 0
    assert not space_row.has(lam[0]) and not space_row.has(lam[1])
    assert time_row.has(lam[1])  # the time equation determines λ_{k+1}: decoupled
    assert sp.simplify(constraint - (t[1] - t[0] - h)) == 0


def _adaptive():
    Q = sg.EuclideanSpace("q")
    GR = sg.TimeGroupoid(sg.PairGroupoid(Q))
    return sg.DiscreteSystem(
        GR, lambda g: _pendulum_lagrangian(g.t1 - g.t0, g.source[0], g.target[0]),
        parameters=[k_], name="adaptive")


def test_adaptive_step_time_equation_is_energy_balance():
    """Example 6.1 / docs/conventions.md §7: the time row is E(g_{k+1}) − E(g_k) with the discrete
    energy E = ⟨dl(ξ), ξ⟩ − l(ξ) = ½v² + V, written symbolically."""
    st = _adaptive().euler_lagrange()
    t = {o: st.symbol("t", o) for o in (-1, 0, 1)}
    q = {o: st.symbol("q", o) for o in (-1, 0, 1)}

    def E(ta, tb, qa, qb):
        v = (qb - qa) / (tb - ta)
        return v ** 2 / 2 - k_ * sp.cos((qa + qb) / 2)

    expected = E(t[0], t[1], q[0], q[1]) - E(t[-1], t[0], q[-1], q[0])
    assert sp.simplify(st.residuals[0] - expected) == 0 or \
        sp.simplify(st.residuals[0] + expected) == 0


def _adaptive_rigid_body():
    """Example 6.1 on SO(3): L = (t₁−t₀) l(cay⁻¹(W)/(t₁−t₀)), l(ξ) = ½ξᵀIξ."""
    inertia = sp.diag(1, 2, 3)

    def L(g):
        dt = g.t1 - g.t0
        xi = g.coordinates / dt
        return dt * (xi.T * inertia * xi)[0, 0] / 2

    return sg.DiscreteSystem(sg.TimeGroupoid(sg.SO3("W")), L, name="adaptive_rigid_body")


def _rb_energy(known) -> float:
    """⟨dl(ξ), ξ⟩ − l(ξ) = ½ξᵀIξ with ξ = cay⁻¹(W)/(t₁ − t₀) (docs/conventions.md §7)."""
    dt, W = known[1] - known[0], np.asarray(known[2:11]).reshape(3, 3)
    X = 2 * (W - W.T) / (1 + np.trace(W))
    xi = np.array([X[2, 1], X[0, 2], X[1, 0]]) / dt
    return 0.5 * xi @ np.diag([1.0, 2.0, 3.0]) @ xi


def _run_adaptive(n: int):
    st = _adaptive_rigid_body().euler_lagrange()
    W = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    known = np.concatenate([[0.0, 0.05], W.ravel()])
    E0, steps, errors = _rb_energy(known), [], []
    for _ in range(n):
        u = newton(st, predicted(st, known, []), known, [])
        known = st.advance(u, known, [])
        steps.append(known[1] - known[0])
        errors.append(_rb_energy(known) - E0)
    return np.array(steps), np.array(errors)


@pytest.mark.slow
def test_adaptive_step_conserves_energy_while_the_step_varies():
    """Example 6.1: the discrete energy is conserved to solver tolerance, every step is
    forward in time, and the step size varies (by several per cent within 150 steps)."""
    steps, errors = _run_adaptive(150)
    assert np.max(np.abs(errors)) < 1e-11
    assert steps.min() > 0
    assert np.ptp(steps) > 0.03 * steps.mean()


def _rounding_floor(st, known) -> float:
    """ε·(E + Σ_j |J_ij||u_j|) at the solved step from ``known``, E the running-error bound of
    the residual program (:func:`symgroupoid.ir.rounding_error`): the smallest residual the
    step can be certified to reach.  It grows with t here (the unknown t_{k+1} is rounded
    relative to t, not to the step), so the last state bounds every step."""
    from symgroupoid.ir import Program, rounding_error

    P = st.program
    bound = Program(P.graph, P.inputs, {"F": P.outputs["F"], "J": P.outputs["J"],
                                        "E": rounding_error(P.graph, P.outputs["F"])})
    f = bound.numpy_function(["F", "E", "J"], ["u", "known", "p"])
    u = np.asarray(st.program.numpy_function(["predict"], ["known", "p"])(known, [])[0])
    for _ in range(12):
        F, E, J = f(u, known, [])
        u = u - np.linalg.solve(J.reshape(len(F), len(F)), F)
    F, E, J = f(u, known, [])
    C = np.abs(J.reshape(len(F), len(F))) @ np.abs(u)
    return float(np.finfo(float).eps * np.max(E + C))


def test_adaptive_step_conserves_energy_over_10k_steps(tmp_path, monkeypatch):
    """The same over 10⁴ steps with the compiled stepper.  Each step's residual sits at its
    rounding floor (default Newton options), so the energy error is a random walk of that
    size: ~1e-10 after 10⁴ steps, far below the O(h²) ≈ 1e-3 energy error of a fixed-step
    scheme — and every step is forward in time while h varies."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    st = _adaptive_rigid_body().euler_lagrange()
    W = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    known = np.concatenate([[0.0, 0.05], W.ravel()])
    traj = st.compile().simulate(known, 10_000, [])
    assert traj.residual_norms.max() <= _rounding_floor(st, traj.states[-1])
    steps = np.diff(traj.states[:, :2], axis=1).ravel()
    errors = np.array([_rb_energy(s) for s in traj.states]) - _rb_energy(known)
    assert np.max(np.abs(errors)) < 3e-10
    assert steps.min() > 0 and np.ptp(steps) > 0.05 * steps.mean()


def test_step_size_control_couples_the_equations():
    """End of §6.3: φ = t₁ − t₀ − h(g) makes X⃖[φ], X⃗[φ] nonzero; the space rows now carry
    the multipliers and the time step follows h(g)."""
    Q = sg.EuclideanSpace("q")
    GR = sg.TimeGroupoid(sg.PairGroupoid(Q))
    eps = sp.Symbol("epsilon", positive=True)
    system = sg.DiscreteSystem(
        GR, lambda g: _pendulum_lagrangian(g.t1 - g.t0, g.source[0], g.target[0]),
        constraints=lambda g: [g.t1 - g.t0 - eps / (1 + ((g.source[0] + g.target[0]) / 2) ** 2)],
        parameters=[k_, eps], name="controlled")
    st = system.euler_lagrange()
    lam1 = st.symbol("lambda", "k+1")[0]
    assert st.residuals[1].has(lam1)
    params = [4.0, 0.05]
    known = np.array([0.0, 0.05 / (1 + 1.1 ** 2), 1.0, 1.2, 0.0])
    for _ in range(20):
        u = newton(st, predicted(st, known, params), known, params)
        known = st.advance(u, known, params)
        mid = (known[2] + known[3]) / 2
        assert abs((known[1] - known[0]) - 0.05 / (1 + mid ** 2)) < 1e-12
