"""Shared systems for the tests: the seed examples, built once per session."""

from __future__ import annotations

import importlib.util
import os
import pathlib
import signal
import sys
import threading

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import systems

EXAMPLES = pathlib.Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(autouse=True, scope="session")
def sigint_raises():
    """SIGINT raises KeyboardInterrupt, as in an interactive session.  A process started in
    the background by a non-interactive shell (``make test &`` in a script, some CI runners)
    inherits SIGINT ignored, and Python leaves it ignored: the tests that send themselves
    SIGINT to check Ctrl-C would then wait forever (a reduce that sleeps 1000 s, or a long
    sweep, is what they interrupt)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def load_example(name: str):
    """Import ``examples/<name>.py`` as a module (the examples are scripts, not a package)."""
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def plate_ball_system() -> tuple[sg.DiscreteSystem, tuple]:
    """Seed 000 §6.2: R²×R²×SO(3) ⇉ R² with the rolling constraints (``sg.systems``)."""
    system = systems.plate_ball()
    return system, tuple(system.parameters)


def heavy_top_system() -> tuple[sg.DiscreteSystem, tuple]:
    """Seed 002 / docs/conventions.md §9: S²×SO(3) with Γ·W = WᵀΓ,
    L = −tr(J_d W)/h − h m g l Γ·e."""
    h, m, g0, ell = sp.symbols("h m g_0 l", positive=True)
    I1, I2, I3 = sp.symbols("I_1 I_2 I_3", positive=True)
    inertia = sp.diag(I1, I2, I3)
    Jd = sg.NamedMatrix(inertia.trace() / 2 * sp.eye(3) - inertia, name="J_d")
    G = sg.ActionGroupoid(sg.EuclideanSpace.vector("Gamma", 3), sg.SO3("W"),
                          lambda p, W: tuple(W.T * sp.Matrix(p)))

    def L(a):
        return -(Jd * a.matrix).trace() / h - h * m * g0 * ell * a.point[2]

    system = sg.DiscreteSystem(G, L, parameters=[h, m, g0, ell, I1, I2, I3], name="heavy_top")
    return system, (h, m, g0, ell, I1, I2, I3)


def newton(step: sg.StepEquations, u0, known, params, tol=1e-13, maxit=30) -> np.ndarray:
    """A plain Newton solve of one step through ``StepEquations.evaluate`` (test helper)."""
    u = np.asarray(u0, float).copy()
    for _ in range(maxit):
        F, J = step.evaluate(u, known, params)
        du = np.linalg.solve(J, -F)
        u += du
        if np.linalg.norm(du) < tol * (1 + np.linalg.norm(u)):
            break
    F, _ = step.evaluate(u, known, params)
    assert np.linalg.norm(F) < 1e-10, f"Newton did not converge: |F| = {np.linalg.norm(F)}"
    return u


def predicted(step: sg.StepEquations, known, params) -> np.ndarray:
    """The step's own first guess for the unknowns."""
    f = sp.lambdify([step.knowns, step.parameters], step.prediction, "numpy")
    return np.asarray(f(np.asarray(known, float), np.asarray(params, float)), float)


@pytest.fixture(scope="session")
def plate_ball():
    return plate_ball_system()


@pytest.fixture(scope="session")
def plate_ball_step(plate_ball):
    return plate_ball[0].euler_lagrange()


@pytest.fixture(scope="session")
def heavy_top():
    return heavy_top_system()


@pytest.fixture(scope="session")
def heavy_top_step(heavy_top):
    return heavy_top[0].euler_lagrange()


#: the test files that take longest (CPU seconds of a fresh run, their subprocesses included),
#: longest first.  ``make test`` hands whole files to the workers in collection order
#: (``--dist loadfile --no-loadscope-reorder``): these go first, so that no long file starts
#: last while the other core idles; the documentation script and the examples, which run in
#: child processes, also overlap the most work that way.  An order, not a selection: a file
#: missing here still runs, after them.
LONG_FIRST = (
    "test_docs.py", "test_build.py", "test_cache_faults.py", "test_examples.py",
    "test_bvp.py", "test_sweep.py", "test_groupoid_properties.py", "test_latex_layout.py",
    "test_forces.py", "test_cache_safety.py", "test_galerkin.py", "test_trivialised.py",
    "test_cache.py", "test_newton_floors.py", "test_morphisms.py", "test_codegen.py",
    "test_forces_kinds.py", "test_hostile_files.py", "test_hostile_runtime.py",
    "test_latex_pdf.py", "test_group_templates.py", "test_seed_lie_groups.py",
)


def pytest_configure(config: pytest.Config) -> None:
    """In a pytest-xdist worker: the kernel cache of ``kernel_support.SESSION_CACHE`` is one
    directory of the run's temporary root (beside the workers' own), so that a kernel both
    workers build (the seed systems', the documentation's) is compiled once."""
    basetemp = config.option.basetemp
    if os.environ.get("PYTEST_XDIST_WORKER") and basetemp:
        os.environ["SYMGROUPOID_TEST_SESSION_KERNELS"] = str(
            pathlib.Path(basetemp).resolve().parent / "session-kernels")


@pytest.hookimpl(wrapper=True)
def pytest_collection(session: pytest.Session):
    """The test modules are collected with bytecode writing on, also where the environment
    turns it off (PYTHONDONTWRITEBYTECODE): pytest then keeps each module with its assertions
    rewritten in tests/__pycache__ (checked against the source, rewritten again when that
    changes), and a later run, and each pytest-xdist worker of it, loads them instead of
    rewriting 3,600 assertions again (about 10 s of each worker's collection).  Only the
    collection: what the tests themselves import or run is as the environment says."""
    before = sys.dont_write_bytecode
    sys.dont_write_bytecode = False
    try:
        return (yield)
    finally:
        sys.dont_write_bytecode = before


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """The files of :data:`LONG_FIRST` first, in its order; the others after them in the
    order they were collected (a stable sort: within a file nothing moves)."""
    rank = {name: i for i, name in enumerate(LONG_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONG_FIRST)))


def pytest_terminal_summary(terminalreporter) -> None:
    """The tally of the hostile-input tests (tests/_hostile.py), when any of them ran."""
    import sys

    hostile = sys.modules.get("_hostile")
    for line in hostile.TALLY.lines() if hostile is not None else []:
        terminalreporter.write_line(line)


@pytest.fixture
def chunk(monkeypatch):
    """Set the steps per kernel call of a simulation."""
    import symgroupoid.runtime._simulator as simulator_module

    def set_chunk(n: int) -> None:
        monkeypatch.setattr(simulator_module, "CHUNK_STEPS", n)
    return set_chunk

