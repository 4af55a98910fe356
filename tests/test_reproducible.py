"""Generated programs are functions of their input alone.

The C of the step kernels and of the boundary-value window kernels must be byte-identical in
every process, whatever ``PYTHONHASHSEED`` (no iteration over sets or hash-ordered dicts on
the way to code), so that a new process finds every kernel in the disk cache and runs the
compiler zero times, and rounds exactly as the last one did.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
from kernel_support import REPO, isolated_cache, needs_cc  # noqa: F401  (autouse fixture)

SOURCES = """
import hashlib, json
from symgroupoid.codegen import generate_c, generate_program_c
from symgroupoid.equations import window_programs
from symgroupoid.systems import plate_ball, rigid_body, spherical_chain

digests = {}
def capture(label, program, inputs, outputs):
    text = generate_program_c(label, program, inputs, outputs).source
    digests[label] = hashlib.sha256(text.encode()).hexdigest()
for system in (rigid_body(), plate_ball()):  # the window programs, as the solver labels them
    programs = window_programs(system)
    capture(f"{system.name}_junction", programs.junction, "a", "junction")
    if programs.term is not None:
        capture(f"{system.name}_term", programs.term, "a", "term")
for system in (plate_ball(), spherical_chain(1)):
    text = generate_c(system.euler_lagrange()).source
    digests[system.name + " step"] = hashlib.sha256(text.encode()).hexdigest()
print(json.dumps(digests, sort_keys=True))
"""

SOLVE = """
import json
import numpy as np
import symgroupoid as sg
from symgroupoid import systems
from symgroupoid.runtime import toolchain
system = systems.rigid_body()
end = np.array(sg.SO3("W").cayley([0.3, -0.2, 0.5]).tolist(), float)
sol = sg.solve_boundary_value(system.euler_lagrange(), np.eye(3), end, 40,
                              params={"h": 0.02, "I1": 1.0, "I2": 2.0, "I3": 3.0})
traj = system.euler_lagrange().compile(backend="c").simulate(
    {"W": sol.arrows[0].reshape(3, 3)}, 10, {"h": 0.02, "I1": 1.0, "I2": 2.0, "I3": 3.0})
print(json.dumps({**toolchain.STATS, "arrows": sol.arrows.tolist(),
                  "states": traj.states.tolist(), "iterations": sol.iterations}))
"""


def _run(script: str, seed: str, **env) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONHASHSEED": seed,
                                 "PYTHONPATH": str(REPO), **env})


def _result(proc: subprocess.Popen) -> dict:
    out, err = proc.communicate(timeout=240)
    assert proc.returncode == 0, err[-3000:]
    return json.loads(out.strip().splitlines()[-1])


def test_step_and_window_kernels_do_not_depend_on_the_hash_seed():
    """The same C text, kernel by kernel, under two hash seeds: the window kernels of the
    rigid body and of the plate-ball (with multipliers), and the step kernels of the
    plate-ball and of the 3D pendulum on the pair groupoid of SO(3)."""
    first, second = [_result(p) for p in [_run(SOURCES, "1"), _run(SOURCES, "4242")]]
    assert {"plate_ball step", "plate_ball_junction", "rigid_body_junction"} <= set(first)
    assert first == second


@needs_cc
@pytest.mark.slow
def test_a_second_process_runs_the_compiler_zero_times(tmp_path):
    """A boundary-value solve and a simulation in a fresh process with a warm cache: no
    compilation, and bitwise the same solution, iterations and trajectory.  (The cold
    process solves with the window programs' NumPy form while their kernel is built in the
    background; it exits only once that build is in the cache.)"""
    cache = {"SYMGROUPOID_CACHE": str(tmp_path / "cache")}
    cold = _result(_run(SOLVE, "7", **cache))
    warm = _result(_run(SOLVE, "8", **cache))
    assert cold["builds"] >= 1  # the step kernel (the window kernel in the background)
    assert warm["builds"] == 0 and warm["codegen"] == 0
    for key in ("arrows", "states", "iterations"):
        assert warm[key] == cold[key]


FINGERPRINTS = """
import json
import sympy as sp
import symgroupoid as sg
from symgroupoid import systems
h = sp.Symbol("h", positive=True)
staged = sg.ContinuousSystem(sg.SO3("R"), lambda R, xi: (xi.T * xi)[0, 0] / 2,
                             parameters=[h]).discretize(h, sg.GaussLegendre(2))
print(json.dumps([s.fingerprint for s in (systems.plate_ball(), systems.satellite_with_wheel(),
                                          staged)]))
"""


def test_system_fingerprints_do_not_depend_on_the_hash_seed():
    """A system's fingerprint (which tells a run of it from a run of another system of the
    same name) is the same in every process: a constrained system (the plate-ball), a forced
    one and one with internal stages, under two hash seeds."""
    first, second = [_result(p) for p in [_run(FINGERPRINTS, "1"), _run(FINGERPRINTS, "777")]]
    assert first == second and len(set(first)) == 3
