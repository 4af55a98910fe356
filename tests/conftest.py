"""Shared systems for the tests: the seed examples, built once per session."""

from __future__ import annotations

import importlib.util
import pathlib
import signal
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

