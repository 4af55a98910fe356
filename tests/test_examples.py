"""Every example script under examples/ runs to completion (as a subprocess); the seed
verification scripts also report what they verified against (seed 000 §2.2, §6.1, §6.2;
seed 001 §2.2.5, App. D; seed 002 heavy top); the scripts that measure the order of a
variational integrator print observed orders that the tests read back.

The scripts are started together when the first test needs them, so the two cores run them in
parallel; each test then waits for its own script."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted(p.name for p in (ROOT / "examples").glob("*.py"))
# scripts that check their equations against a seed, and the reference they must print
VERIFYING = {
    "pair_groupoid.py": "verified against seed 000 §2.2",
    "plate_ball.py": "verified against seed 000 §6.2",
    "heavy_top.py": "verified against seed 002",
    "euler_poincare_so3.py": "verified against seed 001 §2.2.5 and seed 000 §6.1",
    "optimal_control_so3_se2.py": "verified against seed 000 §6.1 and seed 001 Appendix D",
}
# long-running demonstrations (boundary-value solves, long runs), run with the slow tests
# only; their systems are checked in the fast tests (heavy top: tests/test_seed_heavy_top.py,
# the 3D chain: tests/test_chains.py; the orders of the Galerkin schemes: tests/test_galerkin.py,
# order 4 on SO(3) with Gauss-Legendre 2 as in heavy_top_order4.py; the forced spherical
# chain of forced_chain.py and its Noether balance: tests/test_forced_chains.py, a controller
# stepping with sim.step(..., inputs=u): tests/test_forced_runs.py and tests/test_embed.py).
# forced_chain.py and heavy_top_order4.py were a third of the fast suite's examples' CPU time.
SLOW = {"optimal_control_lie_groups.py", "elroys_beanie.py", "euler_poincare_so3.py",
        "holonomic_constraints.py", "optimal_control_so3_se2.py", "heavy_top_rotors.py",
        "plate_ball_steering.py", "heavy_top.py", "pendulum_chain_3d.py", "chain_order4.py",
        "double_pendulum_order6.py", "forced_chain.py", "heavy_top_order4.py"}
# scripts that measure observed orders against an accurate reference: the theoretical order
# of each report they print ("observed order p (theoretical q)", docs/conventions.md §22)
ORDERS = {"heavy_top_order4.py": [4], "double_pendulum_order6.py": [6, 6],
          "chain_order4.py": [4]}
TIMEOUT = 300


def _start(name: str) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(ROOT), MPLBACKEND="Agg")
    return subprocess.Popen([sys.executable, str(ROOT / "examples" / name)], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def running() -> dict[str, subprocess.Popen]:
    procs = {name: _start(name) for name in EXAMPLES if name not in SLOW}
    yield procs
    for proc in procs.values():
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=TIMEOUT)
    return proc.returncode, out, err


def test_verifying_examples_exist() -> None:
    """Each seed verification and each order measurement has its runnable script."""
    assert set(VERIFYING) <= set(EXAMPLES) and set(ORDERS) <= set(EXAMPLES)


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.slow) if n in SLOW else n for n in EXAMPLES])
def test_example_runs(name: str, request: pytest.FixtureRequest) -> None:
    """The script exits with status 0; a verifying script ends with its "verified against
    seed …" line (it exits non-zero on any mismatch)."""
    proc = _start(name) if name in SLOW else request.getfixturevalue("running")[name]
    code, out, err = _finish(proc)
    assert code == 0, f"{name} exited with {code}:\n{err[-3000:]}"
    if name in VERIFYING:
        assert VERIFYING[name] in out.strip().splitlines()[-1], out[-2000:]
    if name in ORDERS:
        _check_orders(name, out)


ORDER_LINE = re.compile(r"observed order (\S+) \(theoretical (\d+)\)")
NUMBER = r"([-+0-9.e]+)"


def _check_orders(name: str, out: str) -> None:
    """Every order the script reports is within 0.1 of its scheme's, and the script's
    structure figures are at their floors (heavy top: a bounded energy error, the vertical
    angular momentum to rounding)."""
    found = [(float(p), int(q)) for p, q in ORDER_LINE.findall(out)]
    assert [q for _, q in found] == ORDERS[name], out
    for observed, theoretical in found:
        assert abs(observed - theoretical) < 0.1, out
    if name == "heavy_top_order4.py":
        energy = re.search(rf"energy error {NUMBER} \(last tenth / first tenth {NUMBER}\)",
                           out)
        momentum = re.search(rf"vertical angular momentum drift {NUMBER}", out)
        assert energy and momentum, out
        assert float(energy[1]) < 1e-3 and float(energy[2]) < 1.5, out
        assert float(momentum[1]) < 1e-12, out


@pytest.mark.slow
def test_the_three_body_chain_is_order_four() -> None:
    """``chain_order4.py --bodies 3``: the 3D three-body chain (pair groupoid of SO(3)³) at
    order 4 against its continuous equations (the script exits non-zero when the observed
    order misses 4 by more than 0.1)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run([sys.executable, str(ROOT / "examples" / "chain_order4.py"),
                          "--bodies", "3"], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=TIMEOUT)
    assert run.returncode == 0, run.stderr
    assert "3D 3-body pendulum" in run.stdout and "(theoretical 4)" in run.stdout
