"""Helpers shared by the code-generation and runtime tests (seed systems, compiled kernels).

Kernels of the seed systems are compiled once per test run into a temporary cache
(``SESSION_CACHE``: shared by the pytest-xdist workers of a run, else private to the process
and removed at exit); every test also gets its own empty
``SYMGROUPOID_CACHE`` (the autouse fixture ``isolated_cache``), so no test touches the
user's cache.
"""

from __future__ import annotations

import atexit
import functools
import importlib.util
import os
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from symgroupoid.systems import SEED_SYSTEMS

REPO = Path(__file__).resolve().parents[1]
#: names the kernel cache the test processes of one run share (set by tests/conftest.py in
#: each pytest-xdist worker: a directory of the run's temporary root, which pytest removes)
SHARED_KERNELS = "SYMGROUPOID_TEST_SESSION_KERNELS"


def _session_cache() -> Path:
    """The kernels of the seed systems and the tests' other shared kernels: the run's shared
    directory under pytest-xdist (a kernel both workers need is built once: the cache's lock
    lets one build while the other waits, then loads it), else a private temporary
    directory removed at exit."""
    shared = os.environ.get(SHARED_KERNELS)
    if shared:
        path = Path(shared)
        path.mkdir(mode=0o700, exist_ok=True)
        return path
    path = Path(tempfile.mkdtemp(prefix="symgroupoid-test-kernels-"))
    atexit.register(shutil.rmtree, path, True)
    return path


SESSION_CACHE = _session_cache()
HAVE_CC = shutil.which("cc") is not None
needs_cc = pytest.mark.skipif(not HAVE_CC, reason="no C compiler (cc) on PATH")
#: both step backends as a parametrisation (the C one needs a compiler)
BACKENDS = [pytest.param("c", marks=needs_cc), "numpy"]

#: parameters and momentum initial data (base point, p₀) of the seed systems
SEED_DATA = {
    "plate_ball": ({"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02}, {"x": 0.0, "y": 0.0},
                   (0.1, 0.05, 0.01, 0.02, 0.01)),
    "heavy_top": ({"h": 0.01, "mgl": 1.0, "I1": 1.0, "I2": 1.0, "I3": 0.5},
                  {"Gamma": (0.0, np.sin(0.5), np.cos(0.5))}, (0.2, 0.1, 3.0)),
    "rigid_body": ({"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}, None, (0.3, 0.2, 0.1)),
}


@functools.cache
def seed_system(name: str):
    return SEED_SYSTEMS[name]()


@functools.cache
def seed_step(name: str):
    return seed_system(name).euler_lagrange()


@pytest.fixture(autouse=True)
def isolated_cache(tmp_path, monkeypatch):
    """A fresh kernel cache for every test."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path / "sg-cache"))
    monkeypatch.delenv("SYMGROUPOID_BACKEND", raising=False)
    return tmp_path / "sg-cache"


@pytest.fixture(scope="module")
def module_cache_root(tmp_path_factory) -> Path:
    """A fresh kernel cache shared by the tests of one module (see :func:`module_cache`)."""
    return tmp_path_factory.mktemp("sg-module-cache") / "sg-cache"


@pytest.fixture(name="isolated_cache", autouse=True)
def module_cache(module_cache_root, monkeypatch):
    """In place of :func:`isolated_cache` for a module none of whose tests is about the cache:
    its tests share one fresh kernel cache, so a kernel several of them compile is built once
    (still never the user's cache)."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(module_cache_root))
    monkeypatch.delenv("SYMGROUPOID_BACKEND", raising=False)
    return module_cache_root


@pytest.fixture
def shared_kernels(isolated_cache, module_cache_root, monkeypatch):
    """For a test that is not about the cache and compiles a system that other tests of its
    module compile too (the command line's example files): the module's one fresh kernel
    cache (:func:`module_cache_root`) in place of the test's own, so that the system is
    built once per module (still never the user's cache)."""
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(module_cache_root))
    return module_cache_root


@functools.cache
def compiled(name: str, backend: str = "c"):
    """The simulator of a seed system (built once per test process)."""
    return seed_step(name).compile(backend=backend, cache_dir=SESSION_CACHE)


def initial_state(sim, name: str) -> np.ndarray:
    """The seed system's consistent initial state (from its momentum initial data)."""
    params, config, momentum = SEED_DATA[name]
    return sim.from_momentum(config, momentum, params)


def constraint_function(name: str):
    """φ(g_k) as a NumPy function of (known state, parameters)."""
    system, step = seed_system(name), seed_step(name)
    phis = system.constraints(step.groupoid.view(step.arrows[0]))
    return sp.lambdify([step.knowns, step.parameters], sp.Matrix(phis), "numpy")


def axial(A: np.ndarray) -> np.ndarray:
    """(A₃₂, A₁₃, A₂₁) of (a stack of) skew matrices: the inverse of the hat map."""
    return np.stack([A[..., 2, 1], A[..., 0, 2], A[..., 1, 0]], axis=-1)


def discrete_inertia(I1: float, I2: float, I3: float) -> np.ndarray:
    inertia = np.diag([I1, I2, I3])
    return np.trace(inertia) / 2 * np.eye(3) - inertia


def body_momentum(W: np.ndarray, Jd: np.ndarray) -> np.ndarray:
    """Π = axial(W J_d − J_d Wᵀ) (docs/conventions.md §9), for one or a stack of matrices."""
    return axial(W @ Jd - Jd @ np.swapaxes(W, -1, -2))


#: a one-unknown system as source text, for the scripts of the cache tests' subprocesses
OSCILLATOR = '''
import sympy as sp
import symgroupoid as sg


def oscillator(name="oscillator"):
    """A harmonic oscillator on the pair groupoid of the line (one unknown)."""
    h, k = sp.symbols("h k", positive=True)

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h * (((q1 - q0) / h) ** 2 / 2 - k * ((q0 + q1) / 2) ** 2 / 2)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                             name=name).euler_lagrange()
'''
_namespace: dict = {}
exec(OSCILLATOR, _namespace)
#: the same system in this process
oscillator = _namespace["oscillator"]


def subprocess_env(lock_timeout: int, **env: str | None) -> dict[str, str]:
    """The test environment for a child process: this checkout on its path, cache locks given
    up after ``lock_timeout`` seconds, and ``env`` applied (None removes a variable)."""
    out = {**os.environ, "PYTHONPATH": str(REPO), "SYMGROUPOID_LOCK_TIMEOUT": str(lock_timeout)}
    for name, value in env.items():
        if value is None:
            out.pop(name, None)
        else:
            out[name] = value
    return out


def step_inputs(step, rng) -> dict[str, np.ndarray]:
    """Four random points (columns) of a step's unknowns, knowns and parameters."""
    u = rng.uniform(-0.4, 0.4, (len(step.unknowns), 4))
    known = rng.normal(size=(len(step.knowns), 4))
    p = rng.uniform(0.5, 2.0, (len(step.parameters), 4))
    return {"u": u, "known": known, "p": p}


def benchmark_module(name: str):
    """``benchmarks/<name>.py`` as a module (the problem families the tests share with the
    benchmarks), loaded once per process."""
    benchmarks = Path(__file__).resolve().parent.parent / "benchmarks"
    if str(benchmarks) not in sys.path:
        sys.path.insert(0, str(benchmarks))
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, benchmarks / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module
