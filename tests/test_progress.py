"""Progress of long work (symgroupoid/_progress.py), and the demo's word on kernel builds.

Reports start only after ``DELAY`` seconds; the tests set it to 0 to see them.
"""

from __future__ import annotations

import io
import logging
import sys
import time
import types

import pytest
import sympy as sp
from kernel_support import REPO, isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg

# unit tests of the progress reporter and of the demo's note
from symgroupoid import _progress
from symgroupoid._demo import build_note
from symgroupoid._progress import Task, reported

h, k = sp.symbols("h k", positive=True)


def spring() -> sg.DiscreteSystem:
    def L(g):
        (q0,), (q1,) = g.source, g.target
        return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                             name="spring")


@pytest.fixture
def immediate(monkeypatch):
    """Report at once (no 2 s wait)."""
    monkeypatch.setattr(_progress, "DELAY", 0.0)
    monkeypatch.setattr(_progress, "REFRESH", 0.02)


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_short_work_reports_nothing(capsys, caplog):
    caplog.set_level(logging.INFO, logger="symgroupoid")
    with Task("quick", progress=True):
        pass
    with Task("quick, logged"):
        pass
    assert capsys.readouterr().err == "" and caplog.records == []


def test_bars_on_a_pipe_write_lines(immediate, capsys):
    with Task("outer", progress=True) as task:
        task.note("stage 1")
        time.sleep(0.2)
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("outer — 0 s, stage 1")  # drawn by the reporting thread
    assert err[-1].startswith("outer: done in ") and err[-1].endswith("; stage 1")
    time.sleep(0.1)
    assert capsys.readouterr().err == ""  # nothing after the work ended


def test_bars_on_a_terminal_are_erased_when_done(immediate, monkeypatch):
    screen = Terminal()
    monkeypatch.setattr(sys, "stderr", screen)
    with Task("counting", total=4, unit="steps", progress=True) as task:
        for i in range(4):
            task.update(i + 1)
            time.sleep(0.05)
    text = screen.getvalue()
    assert "\rcounting — [" in text and "/4 steps" in text
    assert text.endswith("\r\x1b[K") and "done" not in text


def test_switch_off_and_inheritance(immediate, capsys, caplog):
    caplog.set_level(logging.INFO, logger="symgroupoid")
    with Task("outer", progress=False) as outer:
        with Task("inner") as inner:  # progress=None: follows the enclosing work
            pass
    assert outer.mode == inner.mode == "off"
    assert capsys.readouterr().err == "" and caplog.records == []
    assert Task("alone").mode == "log"
    previous = _progress.set_default(True)
    try:
        assert Task("alone").mode == "bar"
    finally:
        _progress.set_default(previous)


def test_library_entry_points_report(immediate, capsys, caplog, monkeypatch):
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")  # no compiler runs here
    caplog.set_level(logging.INFO, logger="symgroupoid")
    step = spring().euler_lagrange()
    assert any("spring: deriving the equations: done in" in r.getMessage()
               for r in caplog.records)
    caplog.clear()
    sim = step.compile(progress=False)
    params = {"h": 0.05, "k": 1.0}
    sim.simulate({"q": (1.0, 0.999)}, 50, params, progress=True)
    assert "spring: simulating: done (50 steps) in" in capsys.readouterr().err
    solution = sg.solve_boundary_value(step, 0.0, 1.0, 10, params=params, progress=True)
    last = capsys.readouterr().err.splitlines()[-1]
    assert last.startswith("spring: boundary-value solve: done in")
    assert f"iteration {solution.iterations}, |F|∞ = " in last
    assert caplog.records == []  # progress=True/False: no log messages


def test_tqdm_is_used_for_counted_work_when_installed(monkeypatch):
    made = []

    class FakeBar:
        def __init__(self, **kwargs):
            self.kwargs, self.n, self.closed = kwargs, 0, False
            made.append(self)

        def update(self, n):
            self.n += n

        def set_postfix_str(self, text, refresh=True):
            self.postfix = text

        def close(self):
            self.closed = True

    monkeypatch.setitem(sys.modules, "tqdm", types.SimpleNamespace(tqdm=FakeBar))
    with Task("simulating", total=100, unit="steps", progress=True) as task:
        task.update(40)
        task.update(100)
    (bar,) = made
    assert bar.kwargs["total"] == 100 and bar.kwargs["delay"] == _progress.DELAY
    assert bar.kwargs["file"] is sys.stderr and bar.kwargs["leave"] is False
    assert bar.n == 100 and bar.closed


def test_reported_adds_the_switch():
    seen = []

    @reported(lambda x: f"work on {x}")
    def work(x):
        seen.append(_progress.current().description)
        return 2 * x

    assert work(3, progress=False) == 6 and seen == ["work on 3"]
    assert _progress.current() is None


def test_command_line_turns_progress_on(immediate, capsys, tmp_path, monkeypatch):
    from symgroupoid.cli import main

    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    path = tmp_path / "spring.py"
    path.write_text("import sympy as sp\nimport symgroupoid as sg\n"
                    "h, k = sp.symbols('h k', positive=True)\n"
                    "def L(g):\n    (q0,), (q1,) = g.source, g.target\n"
                    "    return (q1 - q0) ** 2 / (2 * h) - h * k * (q0 ** 2 + q1 ** 2) / 4\n"
                    "spring = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace('q')), L, "
                    "parameters=[h, k], name='spring')\n")
    assert main(["simulate", str(path), "--steps", "20", "--params", "h=0.05,k=1",
                 "--initial", str(_initial(tmp_path))]) == 0
    err = capsys.readouterr().err
    assert "spring: deriving the equations: done" in err
    assert "spring: simulating: done (20 steps)" in err
    assert _progress._default is None  # the library default is restored


def _initial(folder):
    path = folder / "initial.json"
    path.write_text('{"q": [1.0, 0.999]}')
    return path


# --- the demo -----------------------------------------------------------------------------------

def test_demo_mentions_only_builds_that_happened():
    assert build_note(0) == ""
    assert build_note(1) == " (including the one-time kernel build)"
    assert build_note(2) == " (including 2 one-time kernel builds)"


