"""examples/embed: C programs linking the shipped kernels agree with the Simulator.

``main.c`` (generated/plate_ball.c) runs in chunks of 1024 steps through a fixed buffer,
carrying the Newton warm start from one ``plate_ball_simulate`` call to the next.
``closed_loop.c`` (generated/satellite_wheel.c, a forced kernel) is a PD controller that
computes the reaction wheel's torque from each state and calls ``satellite_wheel_step``: it
reaches its target attitude, and its trajectory is the Simulator's bit for bit.
"""

from __future__ import annotations

import subprocess

import numpy as np
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    SEED_DATA,
    SESSION_CACHE,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
)

pytestmark = needs_cc


def test_embedded_program_reproduces_the_simulator(tmp_path):
    exe = tmp_path / "embed_demo"
    build = subprocess.run(
        ["cc", "-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror",
         f"-I{REPO / 'generated'}",
         str(REPO / "examples" / "embed" / "main.c"), str(REPO / "generated" / "plate_ball.c"),
         "-lm", "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr

    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    steps = 2500  # three calls of plate_ball_simulate
    stdin = (" ".join(repr(float(v)) for v in sim.parameters(params)) + "\n"
             + " ".join(repr(float(v)) for v in state) + "\n")
    run = subprocess.run([str(exe), str(steps)], input=stdin, capture_output=True, text=True,
                         check=True)
    table = np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])
    assert table.shape == (steps + 1, 3 + len(state))
    assert np.array_equal(table[:, 0], np.arange(steps + 1))

    traj = sim.simulate(state, steps, params)
    scale = max(1.0, np.abs(traj.states).max())
    assert np.abs(table[:, 3:] - traj.states).max() <= 1e-12 * scale
    assert np.array_equal(table[1:, 1], traj.newton_iterations)
    assert np.abs(table[1:, 2] - traj.residual_norms).max() <= 1e-12


def test_embedded_program_reports_bad_input(tmp_path):
    exe = tmp_path / "embed_demo"
    subprocess.run(["cc", "-std=c99", "-O2", f"-I{REPO / 'generated'}",
                    str(REPO / "examples" / "embed" / "main.c"),
                    str(REPO / "generated" / "plate_ball.c"), "-lm", "-o", str(exe)], check=True)
    run = subprocess.run([str(exe), "5"], input="0.01 1 0.1", capture_output=True, text=True)
    assert run.returncode == 2 and "expected 4 parameters and 16 state values" in run.stderr
    run = subprocess.run([str(exe), "5"], input="0.01 1 0.1 0.02 " + "nan " * 16,
                         capture_output=True, text=True)
    assert run.returncode == 1 and "invalid argument" in run.stderr
    for steps in ("99999999999999999999", "-1", "1e3", "", "7 "):
        run = subprocess.run([str(exe), steps], input="", capture_output=True, text=True)
        assert run.returncode == 2 and "usage" in run.stderr, steps


# --- examples/embed/closed_loop.c: a PD controller around satellite_wheel_step --------------

#: the constants of closed_loop.c: time step, gains, target rotation about the wheel's axis
LOOP = {"h": 0.02, "I": 2.0, "I3": 3.0, "Iw": 0.1}
KP, KD, TARGET = 6.75, 9.0, 1.0


def _build_closed_loop(tmp_path):
    exe = tmp_path / "closed_loop"
    build = subprocess.run(
        ["cc", "-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off",
         f"-I{REPO / 'generated'}", str(REPO / "examples" / "embed" / "closed_loop.c"),
         str(REPO / "generated" / "satellite_wheel.c"), "-lm", "-o", str(exe)],
        capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    return exe


def _axial(A):
    """The rotation angle about the third axis (closed_loop.c's axial_angle)."""
    return np.arctan2(A[1, 0] - A[0, 1], A[0, 0] + A[1, 1])


def test_the_closed_loop_program_reaches_the_target_with_the_simulator_s_bits(tmp_path):
    from symgroupoid.systems import satellite_with_wheel

    exe, path = _build_closed_loop(tmp_path), tmp_path / "trajectory.txt"
    steps = 750
    run = subprocess.run([str(exe), str(steps), str(path)], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    lines = run.stdout.splitlines()
    assert lines[-1].startswith("final attitude error") and lines[-1].endswith(": reached")
    table = np.array([[float(v) for v in line.split()] for line in lines[1:-1]])
    assert np.array_equal(table[:, 0], np.arange(0, steps + 1, 50))
    assert table[0, 2] > 0.9 and table[-1, 2] < 1e-6  # the attitude error, in radians
    assert (np.diff(table[2:, 2]) < 0).all()  # settling: decreasing after the first second

    traj = np.loadtxt(path)
    assert traj.shape == (steps + 1, 16) and np.array_equal(traj[:, 0], np.arange(steps + 1))
    states, U = traj[:, 1:], traj[1:, 14]  # state k holds tau_k in its last two entries
    assert np.array_equal(states[1:, 13], U)
    sim = satellite_with_wheel().euler_lagrange().compile(cache_dir=SESSION_CACHE)
    state = sim.state(states[0], LOOP)
    assert np.array_equal(state, states[0])
    for k in range(steps):  # the Simulator, step by step, with the program's torques
        state = sim.step(state, LOOP, inputs=[U[k]])
        assert np.array_equal(state, states[k + 1]), k

    # the torques are the PD law of the state (to rounding: the attitude is a product)
    W = states[:, :9].reshape(-1, 3, 3)
    R = W[0].copy()
    c, s = np.cos(TARGET), np.sin(TARGET)
    target = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    law = []
    for k in range(steps):
        law.append(KP * _axial(target.T @ R) + KD * _axial(W[k]) / LOOP["h"])
        R = R @ W[k + 1]
    assert np.abs(np.array(law) - U).max() < 1e-12
    assert np.abs(U).max() > 0.5


def test_the_closed_loop_program_fails_short_of_the_target_and_on_bad_arguments(tmp_path):
    exe = _build_closed_loop(tmp_path)
    run = subprocess.run([str(exe), "100"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 1 and run.stdout.splitlines()[-1].endswith("NOT reached")
    for args in (["0"], ["-3"], ["1e3"], [], ["5", "a", "b"], ["5", str(tmp_path / "no" / "f")]):
        run = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=60)
        assert run.returncode == 2 and run.stderr, args
