"""examples/embed: a C program linking generated/plate_ball.c agrees with the Simulator.

The program runs in chunks of 1024 steps through a fixed buffer, carrying the Newton warm
start from one ``plate_ball_simulate`` call to the next.
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
