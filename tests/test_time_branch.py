"""The branch of an energy-preserving adaptive time step (seed 000 Example 6.1,
docs/conventions.md §7): the pendulum on R×R×(Q×Q), with the step length part of the arrow.

Its step equations have, besides the forward root, the time-reversed root
g_{k+1} = g_k⁻¹ (t_{k+1} = t_{k−1}, q_{k+1} = q_{k−1}): an exact solution for every
L_d with L_d(g⁻¹) = −L_d(g).  Both the energy row and the space row fix mainly the velocity
Δq/Δt, so the Jacobian is nearly singular along the step length and Newton from the linear
prediction (O(h²) off in q) went there at the first step: the run alternated between
t = 0 and t = h with converged residuals.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import symgroupoid as sg
from symgroupoid.stepper import NumpyStepper, Status, TimeLayout

kappa = sp.Symbol("kappa", positive=True)


def _system(potential: str) -> sg.DiscreteSystem:
    """(t₁−t₀)[½((q₁−q₀)/(t₁−t₀))² − V((q₀+q₁)/2)] on R×R×(R×R), no step constraint:
    V = −κ cos q (the pendulum) or ½κq² (the harmonic oscillator)."""
    def L(a):
        dt, q0, q1 = a.t1 - a.t0, a.source[0], a.target[0]
        mid = (q0 + q1) / 2
        V = -kappa * sp.cos(mid) if potential == "pendulum" else kappa * mid**2 / 2
        return dt * (((q1 - q0) / dt) ** 2 / 2 - V)

    groupoid = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    return sg.DiscreteSystem(groupoid, L, parameters=[kappa], name=f"adaptive_{potential}")


@pytest.fixture(scope="module")
def pendulum():
    return _system("pendulum").euler_lagrange()


@pytest.fixture(scope="module")
def oscillator():
    return _system("oscillator").euler_lagrange()


def _exact_start(rhs, h: float, q0: float = 1.0, v0: float = 0.5) -> np.ndarray:
    """The first arrow (0, h, q(0), q(h)) of the continuous motion from (q0, v0)."""
    end = solve_ivp(rhs, [0, h], [q0, v0], rtol=1e-13, atol=1e-13).y[0, -1]
    return np.array([0.0, h, q0, end])


def _pendulum_rhs(t, y):
    return [y[1], -np.sin(y[0])]


def _error_against_ode(step, rhs, h: float, steps: int, backend: str) -> tuple:
    """(the run's states, max |q_k − q(t_k)|) against the continuous motion (solve_ivp)."""
    known = _exact_start(rhs, h)
    traj = step.compile(backend=backend).simulate(known, steps, {"kappa": 1.0})
    t, q = traj.states[:, 1], traj.states[:, 3]
    reference = solve_ivp(rhs, [0, t[-1]], [1.0, 0.5], rtol=1e-12, atol=1e-12,
                          dense_output=True)
    return traj.states, float(np.abs(reference.sol(t)[0] - q).max())


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_the_adaptive_pendulum_moves_forward_in_time(pendulum, backend, tmp_path,
                                                     monkeypatch):
    """Every step forward, never more than 1 % from the last (it alternated ±0.05 before),
    the discrete energy kept, and the motion that of the continuous pendulum to O(h²)."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    states, error = _error_against_ode(pendulum, _pendulum_rhs, 0.05, 200, backend)
    h = states[:, 1] - states[:, 0]
    assert h.min() > 0.044 and h.max() < 0.051
    assert np.abs(h[1:] / h[:-1] - 1).max() < 0.01
    assert states[-1, 1] > 9.5  # 200 steps of about 0.05
    v, mid = (states[:, 3] - states[:, 2]) / h, (states[:, 2] + states[:, 3]) / 2
    energy = v**2 / 2 - np.cos(mid)
    assert np.ptp(energy) < 1e-12  # h_k is rounded relative to t_k: v²ε·t/h ≲ 1e-14 a step
    assert error < 2e-3  # measured 1.1e-3 (h = 0.05, t ≈ 9.8)


def test_the_compiled_and_numpy_runs_agree_bit_for_bit(pendulum, tmp_path, monkeypatch):
    """The fixed-step phase and the time step check are the same operations in C and
    NumPy."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    known = np.array([0.0, 0.05, 1.0, 1.025])
    runs = [pendulum.compile(backend=b).simulate(known, 300, [1.0]) for b in ("c", "numpy")]
    assert np.array_equal(runs[0].states, runs[1].states)
    assert np.array_equal(runs[0].residual_norms, runs[1].residual_norms)


@pytest.mark.slow
def test_the_adaptive_pendulum_converges_at_second_order(pendulum):
    """Halving the step quarters the error against the continuous pendulum (to t ≈ 18.6:
    8.5e-3, 2.1e-3, 5.4e-4 measured at h = 0.1, 0.05, 0.025)."""
    errors = [_error_against_ode(pendulum, _pendulum_rhs, h, round(18.6 / h), "numpy")[1]
              for h in (0.1, 0.05, 0.025)]
    assert 3.5 < errors[0] / errors[1] < 4.5 and 3.5 < errors[1] / errors[2] < 4.5


def _fixed_step_guess(step, known) -> np.ndarray:
    """An independent solve's first guess: the space row solved with t_{k+1} = 2t_k − t_{k−1}
    (plain Newton in q on ``step.evaluate``)."""
    u = np.array([2 * known[1] - known[0], 2 * known[3] - known[2]])
    for _ in range(40):
        F, J = step.evaluate(u, known, [1.0])
        u[1] -= F[1] / J[1, 1]
    return u


def _independent_step(step, known) -> np.ndarray:
    """The step solved by plain Newton on ``step.evaluate`` from :func:`_fixed_step_guess`."""
    u = _fixed_step_guess(step, known)
    for _ in range(40):
        F, J = step.evaluate(u, known, [1.0])
        u = u - np.linalg.solve(J, F)
    assert np.abs(step.evaluate(u, known, [1.0])[0]).max() < 1e-12
    return u


def test_each_step_is_the_forward_root_an_independent_newton_finds(pendulum):
    """The run's steps are roots of the discrete equations (residual at rounding) and the
    very roots a plain Newton on ``step.evaluate`` reaches from the fixed-step guess; the
    time-reversed arrow is a root too (residual 0 to rounding), the one the run used to
    take."""
    known = np.array([0.0, 0.05, 1.0, 1.025])
    traj = pendulum.compile(backend="numpy").simulate(known, 40, [1.0])
    for k in range(40):
        state, following = traj.states[k], traj.states[k + 1]
        u = _independent_step(pendulum, state)
        np.testing.assert_allclose(following[[1, 3]], u, rtol=0, atol=1e-12)
        reversed_root = state[[0, 2]]
        assert np.abs(pendulum.evaluate(reversed_root, state, [1.0])[0]).max() < 1e-12


def test_the_oscillator_keeps_its_fixed_step(oscillator):
    """The control: with a quadratic potential the midpoint discretisation keeps E_d exactly
    at a fixed step, so the energy-preserving step is h itself (to rounding), and the run is
    the harmonic motion to O(h²)."""
    known = _exact_start(lambda t, y: [y[1], -y[0]], 0.05)
    traj = oscillator.compile(backend="numpy").simulate(known, 400, {"kappa": 1.0})
    h = traj.states[:, 1] - traj.states[:, 0]
    assert np.abs(h - 0.05).max() < 1e-12
    t, q = traj.states[:, 1], traj.states[:, 3]
    exact = np.cos(t) + 0.5 * np.sin(t)
    assert np.abs(q - exact).max() < 5e-3  # the midpoint rule's phase error h²t/12 = 4.2e-3


@pytest.mark.parametrize("backend", ["numpy", "c"])
def test_a_lost_forward_root_is_a_named_branch_jump(pendulum, backend, tmp_path,
                                                    monkeypatch):
    """From q = 0.5 → 1.5 in h = 0.5 (over the top) the energy equation along the
    fixed-step solutions stays above 0.055 for every step in (0, 1.5]: no forward root near.
    Newton converges to a far one (a step of 9.0): a BranchJumpError at step 0 naming the
    time step check, not a run on it."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    sim = pendulum.compile(backend=backend)
    with pytest.raises(sg.BranchJumpError, match="time step check failed") as info:
        sim.simulate(np.array([0.0, 0.5, 0.5, 1.5]), 10, [1.0])
    assert info.value.step == 0 and len(info.value.trajectory.states) == 1


def _damped_spline():
    """A second-order adaptive step on R×R×(R × R): a spline with a negative velocity
    term and a spring, L = h̄(a²/2 − α(v₀² + v₁²)/4 + ω²q₁²/2) over (t₀, t₁, t₂),
    h̄ = (t₂ − t₀)/2, a the divided second difference."""
    alpha, omega = sp.symbols("alpha omega", positive=True)

    def L(g1, g2):
        (t0, t1, t2), (q0, q1, q2) = (g1.t0, g1.t1, g2.t1), (g1.source[0], g1.target[0],
                                                              g2.target[0])
        v0, v1 = (q1 - q0) / (t1 - t0), (q2 - q1) / (t2 - t1)
        mean = (t2 - t0) / 2
        return mean * (((v1 - v0) / mean) ** 2 / 2 - alpha * (v0 ** 2 + v1 ** 2) / 4
                       + omega ** 2 * q1 ** 2 / 2)

    return sg.SecondOrderSystem(sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q"))), L,
                                parameters=[alpha, omega], name="damped_spline")


def test_a_second_order_step_settles_on_its_energy_equation(tmp_path, monkeypatch):
    """The third step's forward root (a time step 1.62 times the last) was missed: Newton's
    first update from the held guess moved t_{k+1} and left the 1/h³ rows far off, and the
    run ended with a BranchJumpError saying the root had disappeared.  The last try, Newton
    on the energy equation along the fixed-step solutions, finds it, in C and NumPy alike;
    at the fourth step no forward root exists (the energy equation along the fixed-step
    solutions is positive for every step in the window), which is still a branch jump."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path))
    step = _damped_spline().euler_lagrange()
    t = 0.05 * np.arange(4)
    start, params = {"t": t, "q": np.cos(0.7 * t)}, {"alpha": 2.5, "omega": 1.0}
    runs = [step.compile(backend=b).simulate(start, 3, params) for b in ("c", "numpy")]
    assert np.array_equal(runs[0].states, runs[1].states)
    times, q = runs[0]["t"], runs[0]["q"]
    steps = np.diff(times)
    assert steps[-1] / steps[-2] == pytest.approx(1.6185, abs=1e-3)
    for k in range(3):  # each step solves the step equations at its state: node k + 4 new
        F, _ = step.evaluate([times[k + 4], q[k + 4]], runs[0].states[k], [2.5, 1.0])
        assert np.abs(F).max() < 1e-12
    with pytest.raises(sg.BranchJumpError, match="time step check failed") as info:
        step.compile().simulate(start, 4, params)
    assert info.value.step == 3


def test_the_time_step_check_refuses_the_reversed_root(pendulum):
    """Without the fixed-step phase (time row −1) Newton from the prediction reaches the
    time-reversed root g_k⁻¹, as every run did before; the time step check stops the run
    there with BRANCH_JUMP instead of going on."""
    kernel = pendulum.compile(backend="numpy").kernel
    stepper = NumpyStepper(kernel._stepper.f, 2, TimeLayout(-1, 0, 1, 0))
    known = np.array([0.0, 0.05, 1.0, 1.025])
    options = sg.NewtonOptions()
    states, _, _, status, failed, last = stepper.simulate(known, [1.0], 5, options,
                                                          stepper.warm_start())
    assert status == Status.BRANCH_JUMP and failed == 0
    np.testing.assert_allclose(last, [0.0, 1.0], atol=1e-12)  # (t_{k−1}, q_{k−1})
    off = sg.NewtonOptions(trust_factor=0)  # the check off: the old, alternating run
    states, _, _, status, _, _ = stepper.simulate(known, [1.0], 4, off, stepper.warm_start())
    assert status == Status.OK and np.allclose(states[:, 1], [0.05, 0.0, 0.05, 0.0, 0.05])


def test_solve_takes_the_forward_root_and_refuses_a_lost_one(pendulum):
    """``Simulator.solve`` from the prediction solves onto the fixed-step equations as
    ``simulate`` does (the same next state, bit for bit), and a far solution is a
    BranchJumpError."""
    sim = pendulum.compile(backend="numpy")
    known = np.array([0.0, 0.05, 1.0, 1.025])
    u, _, _ = sim.solve(known, [1.0])
    assert np.array_equal(u, sim.simulate(known, 1, [1.0]).states[1][[1, 3]])
    with pytest.raises(sg.BranchJumpError, match="time step check failed"):
        sim.solve([0.0, 0.5, 0.5, 1.5], [1.0])
