"""benchmarks/mujoco.py, the library against MuJoCo on the 3D chain: the Cayley inverse and
the start velocities of MuJoCo's run, the ball joints' attitudes, the steps per round, the
growth exponents and the issue's targets; the import of MuJoCo's own package while the
script's folder is on ``sys.path`` (the script bears the package's name); the message when
MuJoCo is missing; and a quick run of the script (slow: it builds a kernel)."""

import importlib.machinery
import importlib.util
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

REPO = Path(__file__).resolve().parents[1]
BENCHMARKS = REPO / "benchmarks"
SCRIPT = BENCHMARKS / "mujoco.py"
#: MuJoCo's own package is installed (looked up past benchmarks/, which holds mujoco.py)
HAVE_MUJOCO = importlib.machinery.PathFinder.find_spec(
    "mujoco", [p for p in sys.path if Path(p or ".").resolve() != BENCHMARKS]) is not None
needs_mujoco = pytest.mark.skipif(not HAVE_MUJOCO, reason="mujoco is not installed")


def _load_benchmark():
    """benchmarks/mujoco.py as a module under another name than MuJoCo's package."""
    name = "mujoco_benchmark"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, SCRIPT)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


mb = _load_benchmark()
scaling = sys.modules["scaling"]
models = sys.modules["_chain_models"]


def test_the_cayley_inverse_inverts_the_benchmarks_cayley_map():
    """inverse_cayley(cay(x)) = x, up to rotations of nearly π (|x| = 2 tan(θ/2))."""
    rng = np.random.default_rng(3)
    for scale in (1e-3, 0.1, 1.0, 10.0):
        for _ in range(5):
            x = scale * rng.normal(size=3)
            assert np.allclose(mb.inverse_cayley(scaling.cayley(x)), x, rtol=1e-12,
                               atol=1e-15)


def test_the_body_velocities_of_the_library_state_are_the_first_arrows():
    """initial_state("3d", n) builds R_{i,1} = R_{i,0} cay(h ω_i): the velocities of its
    arrow are the ω_i."""
    n, h = 3, scaling.PARAMS["h"]
    j = np.arange(1, n + 1)
    omega = np.stack([0.6 * np.sin(j), -0.4 * np.cos(2 * j), 0.8 + 0 * j], axis=1).ravel()
    xi = mb.body_velocities(scaling.initial_state("3d", n), n, h)
    assert np.abs(xi - omega).max() < 1e-13


def _arrows(h: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The first two library states (R_k, R_{k+1}), k = 0, 1, of one body moving as
    R(t) = exp((a t + b t²)^), whose body velocity at t = 0 is a."""
    R = [Rotation.from_rotvec(a * t + b * t * t).as_matrix() for t in (0.0, h, 2 * h)]
    return np.array([np.concatenate([R[0].ravel(), R[1].ravel()]),
                     np.concatenate([R[1].ravel(), R[2].ravel()])])


def test_the_start_velocity_is_second_order_and_the_first_arrows_first_order():
    """ξ(0) from the first two arrows converges like h² to the body velocity at t = 0; the
    first arrow's velocity (the one at t = h/2) only like h."""
    a, b = np.array([0.5, -0.3, 0.8]), np.array([1.1, 0.7, -0.9])
    errors = {"start": [], "arrow": []}
    for h in (0.02, 0.01, 0.005):
        states = _arrows(h, a, b)
        errors["start"].append(np.abs(mb.start_velocities(states, 1, h) - a).max())
        errors["arrow"].append(np.abs(mb.body_velocities(states[0], 1, h) - a).max())
    start = [math.log2(e0 / e1) for e0, e1 in zip(errors["start"], errors["start"][1:])]
    arrow = [math.log2(e0 / e1) for e0, e1 in zip(errors["arrow"], errors["arrow"][1:])]
    assert all(1.8 < p < 2.2 for p in start), start
    assert all(0.9 < p < 1.1 for p in arrow), arrow


def test_the_ball_joints_quaternions_give_back_the_attitudes():
    """(R_i, ξ_i) → MuJoCo's qpos (``_chain_models.mujoco_state``) → R_i, for five bodies."""
    rng = np.random.default_rng(5)
    attitudes = [scaling.cayley(rng.normal(size=3)) for _ in range(5)]
    qpos, _ = models.mujoco_state(attitudes, rng.normal(size=15))
    R = mb.attitudes_from_qpos(qpos, 5)
    assert R.shape == (1, 5, 3, 3)
    assert mb.attitude_difference(R, np.array(attitudes)[None]) < 1e-14


def test_the_mjcf_model_takes_the_integrator():
    """mjcf_chain(..., integrator=...) names it; RK4 stays the default (work_precision.py)."""
    assert 'integrator="RK4"' in models.mjcf_chain(2, 0.01)
    for name in mb.INTEGRATORS:
        assert f'integrator="{name}"' in models.mjcf_chain(2, 0.01, integrator=name)


@needs_mujoco
def test_the_models_integrators_and_start_are_mujocos():
    """The MuJoCo models run the integrator asked for, with the energy off, from the
    attitudes and velocities given."""
    mujoco = mb.mujoco_module()
    n = 3
    state = scaling.initial_state("3d", n)
    attitudes, xi = list(mb.attitudes_of(state, n)), np.arange(3.0 * n) / 10
    for name in mb.INTEGRATORS:
        chain = mb.MujocoChain(mujoco, n, name, attitudes, xi)
        assert chain.model.opt.integrator == int(getattr(mujoco.mjtIntegrator,
                                                         f"mjINT_{name.upper()}"))
        assert not chain.model.opt.enableflags & int(mujoco.mjtEnableBit.mjENBL_ENERGY)
        states = chain.run(2)
        assert states.shape[0] == 2
        start = chain.attitudes(chain.start[None, :])
        assert mb.attitude_difference(start, np.array(attitudes)[None]) < 1e-14


def test_the_steps_of_a_round():
    """About the round's seconds of library steps, clamped, and never past what the library
    can solve; a fixed --steps wins (but not past the solvable steps either)."""
    assert mb.round_steps(1e-5, 10**6, None, target=0.01) == 1000
    assert mb.round_steps(1e-2, 10**6, None, target=0.01) == mb.MIN_ROUND_STEPS
    assert mb.round_steps(1e-9, 10**6, None, target=0.01) == mb.MAX_ROUND_STEPS
    assert mb.round_steps(1e-5, 300, None, target=0.01) == 300
    assert mb.round_steps(1e-5, 10**6, 7) == 7
    assert mb.round_steps(1e-5, 5, 7) == 5


def _row(n: int, library: float, implicitfast: float) -> dict:
    us = {"library": library, "implicitfast": implicitfast, "Euler": implicitfast,
          "RK4": 3 * implicitfast}
    return {"n": n, "us_per_step": us}


def test_the_targets_and_the_growth_exponents():
    """n = 16, 32: library ≤ implicitfast; n = 64: ≤ half of it; sizes not run are neither
    passed nor failed; p between successive sizes is the log ratio."""
    rows = [_row(8, 10.0, 20.0), _row(16, 80.0, 80.0), _row(32, 640.0, 320.0),
            _row(64, 0.6 * 1000, 1000.0)]
    met = [t["met"] for t in mb.targets(rows)]
    assert met == [True, False, False]
    assert [t["met"] for t in mb.targets([_row(64, 499.0, 1000.0)])] == [None, None, True]
    assert mb.targets([{"n": 16, "error": "no root"}])[0] == {
        "target": "n = 16: library us/step <= MuJoCo implicitfast's", "met": None,
        "value": "no root"}
    mb.add_growth(rows)
    assert "growth" not in rows[0]
    assert math.isclose(rows[1]["growth"]["library"], 3.0)
    assert math.isclose(rows[2]["growth"]["implicitfast"], 2.0)


def test_the_maximal_chain_starts_where_the_minimal_chain_does():
    """--maximal: the maximal chain's start holds the minimal state's attitudes and the
    centres of mass they put the bodies at (on the joint constraints), and its attitudes
    are read back as the minimal chain's; its targets are judged on its own timing."""
    n = 3
    state = scaling.initial_state("3d", n)
    named = mb.maximal_state(state, n)
    assert sorted(named) == sorted([f"R{i}" for i in range(1, 4)]
                                   + [f"{a}{i}" for i in range(1, 4) for a in "xyz"])
    for which, R in enumerate((mb.attitudes_of(state, n), mb.attitudes_of(state[9 * n:], n))):
        joint = np.zeros(3)
        for i in range(n):
            assert np.array_equal(named[f"R{i + 1}"][which], R[i])
            c = np.array([named[f"{a}{i + 1}"][which] for a in "xyz"])
            assert np.allclose(c - R[i] @ [0, 0, -0.5], joint, atol=1e-15)
            joint = c + R[i] @ [0, 0, -0.5]
    flat = np.concatenate([np.r_[named[f"R{i}"][0].ravel(), named[f"R{i}"][1].ravel(),
                                 [named[f"{a}{i}"][0] for a in "xyz"],
                                 [named[f"{a}{i}"][1] for a in "xyz"]] for i in range(1, 4)])
    assert np.array_equal(mb.maximal_attitudes(flat[None], n)[0], mb.attitudes_of(state, n))
    row = _row(16, 80.0, 100.0)
    row["us_per_step"]["maximal"] = 40.0
    assert [t["met"] for t in mb.targets([row], "maximal")] == [True, None, None]


def test_importing_mujoco_with_the_benchmarks_on_the_path():
    """With benchmarks/ first on sys.path (as for a script there, or work_precision.py),
    ``import mujoco`` gives MuJoCo's own package (or, without it, ModuleNotFoundError), not
    this benchmark script."""
    code = (f"import sys; sys.path.insert(0, {str(BENCHMARKS)!r}); import mujoco; "
            "import mujoco.rollout; print(mujoco.__file__, hasattr(mujoco, 'MjModel'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    if HAVE_MUJOCO:
        assert out.returncode == 0, out.stderr
        path, has_model = out.stdout.split()
        assert Path(path).resolve().parent != BENCHMARKS and has_model == "True"
    # without site-packages MuJoCo is not found: a clean ModuleNotFoundError, from this file
    out = subprocess.run([sys.executable, "-S", "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode != 0
    assert "ModuleNotFoundError: No module named 'mujoco'" in out.stderr
    assert "mujoco.py" in out.stderr  # (the hand-over raised it)


def test_without_mujoco_the_script_says_so(monkeypatch):
    monkeypatch.setitem(sys.modules, "mujoco", None)  # import mujoco: ImportError
    with pytest.raises(SystemExit, match="MuJoCo is not installed"):
        mb.main(["--quick"])


def test_bad_arguments_are_refused(capsys):
    for argv in (["--sizes", "0"], ["--rounds", "0"], ["--steps", "0"],
                 ["--round-seconds", "-1"]):
        with pytest.raises(SystemExit) as exc:
            mb.parse_args(argv)
        assert exc.value.code == 2
    args = mb.parse_args(["--quick"])
    assert args.sizes == list(mb.QUICK_SIZES) and args.rounds == mb.QUICK_ROUNDS


@pytest.mark.slow
@needs_mujoco
def test_the_quick_run_prints_the_table(tmp_path):
    """The script itself: the two-body chain (one kernel build), the table and the targets
    (not run at n = 2), and the JSON."""
    out = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--sizes", "2",
                          "--output", str(tmp_path / "r.json")],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    assert mb.HEADER in out.stdout and "=== targets ===" in out.stdout
    line = next(ln for ln in out.stdout.splitlines() if ln.startswith(f"{2:>3} "))
    assert line.count("|") == mb.HEADER.count("|")
    us = line.split("|")[1].split()  # library, implicitfast, Euler, RK4, CasADi (not asked)
    assert all(float(v) > 0 for v in us[:4]) and us[4] == "-"
    assert "load average at the start" in out.stdout
    saved = json.loads((tmp_path / "r.json").read_text())
    row = saved["results"][0]
    assert row["n"] == 2 and row["check_steps"] == mb.COMPARE_STEPS
    assert set(row["us_per_step"]) == {"library", *mb.INTEGRATORS}
    assert row["difference"]["RK4"] < 1e-3  # the same chain (O(h²) apart from RK4)
    assert [t["met"] for t in saved["targets"]] == [None, None, None]
