"""What every entry point goes through, checked inside: one validation path
(runtime/_validate.py) — counts, parameters with their declared assumptions, group elements,
configurations, flat states and the constraints of an initial state, the same rule and
message wherever the input is given — and the progress of long work (symgroupoid/_progress.py,
a batch's installments in runtime/_batch_progress.py, the demo's word on kernel builds).

Progress reports start only after ``DELAY`` seconds; the tests set it to 0 to see them.
"""

from __future__ import annotations

import io
import logging
import sys
import time
import types

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SEED_DATA,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
    seed_step,
    seed_system,
)
from test_batch import RIGID, assert_same_run, rotation

import symgroupoid as sg

# white-box tests of what every entry point goes through: the validation path
# (runtime/_validate.py, _arguments.py), a trusted state's key (runtime/_fast_step.py), the
# progress reporter (_progress.py), a batch's installments (runtime/_batch_progress.py) and
# the demo's note; their subjects are these modules' own functions, none of them public
from symgroupoid import DomainError, InputNameError, ParameterError, _arguments, _progress
from symgroupoid._demo import build_note
from symgroupoid._progress import Task, reported
from symgroupoid.equations import magnitude
from symgroupoid.runtime import _batch_progress, _validate, parameter_vector
from symgroupoid.runtime._fast_step import _used_index
from symgroupoid.runtime._validate import (
    ConstraintCheck,
    check_assumptions,
    configuration,
    group_element,
    integer_argument,
    real_argument,
)

h = sp.Symbol("h", positive=True)


# --- numbers and parameters ---------------------------------------------------------------------

def test_integer_argument():
    assert integer_argument(1e7, "steps") == 10**7
    assert integer_argument(np.int64(3), "steps") == 3
    for bad, message in ((2.5, "must be an integer, got 2.5"), (True, "boolean"),
                         (np.nan, "finite integer"), (-1, "at least 0"), ("3", "got str")):
        with pytest.raises(sg.ShapeError, match=message):
            integer_argument(bad, "steps")


def test_real_argument():
    assert real_argument(sp.Rational(1, 4), "x") == 0.25
    assert real_argument(np.float32(2.0), "x") == 2.0
    for bad in ("0.1", 1j, True, np.array([1.0, 2.0]), np.inf, sp.Symbol("y")):
        with pytest.raises(sg.ShapeError, match="x must be"):
            real_argument(bad, "x")


def test_parameter_names_counts_and_values():
    m = sp.Symbol("m", nonnegative=True)
    values, named = parameter_vector([h, m], {h: 0.1, "m": 0})
    assert values.tolist() == [0.1, 0.0] and named == {"h": 0.1, "m": 0.0}
    assert parameter_vector([h, m], np.array([0.1, 2.0]))[0].tolist() == [0.1, 2.0]
    cases = [({"h": 0.1}, "missing parameter m"),
             ({"h": 0.1, "m": 1, "k": 2}, "unknown parameter k; the parameters are h, m"),
             ({h: 0.1, "h": 0.2, "m": 1}, "parameter h given twice"),
             ([0.1], r"1 parameter values given, expected 2 \(h, m\)"),
             (0.1, "parameters must be a mapping name → value or a sequence of 2 values"),
             ({"h": "0.1", "m": 1}, "parameter h must be a real number, got str"),
             ({"h": np.nan, "m": 1}, "non-finite parameter h"),
             ({"h": 0.0, "m": 1}, "parameter h is declared positive, got h = 0.0"),
             ({"h": 0.1, "m": -1e-300}, "parameter m is declared nonnegative")]
    for params, message in cases:
        with pytest.raises(ParameterError, match=message) as info:
            parameter_vector([h, m], params, owner="sys")
        assert str(info.value).startswith("sys: ")
        assert isinstance(info.value, (KeyError, ValueError))


@pytest.mark.parametrize("assumptions, good, bad, named", [
    ({"negative": True}, -1.0, 0.0, "negative"),
    ({"nonpositive": True}, 0.0, 1e-9, "nonpositive"),
    ({"integer": True}, 2.0, 2.5, "integer"),
    ({"integer": True, "positive": True}, 3.0, 0.0, "positive"),
    ({"even": True}, 4.0, 3.0, "even"),
    ({"odd": True}, 3.0, 4.0, "odd"),
    ({"prime": True}, 7.0, 9.0, "prime"),
    ({"nonzero": True}, -2.0, 0.0, "nonzero"),
    ({"positive": False}, -1.0, 1.0, "not positive"),
])
def test_declared_assumptions_are_checked(assumptions, good, bad, named):
    k = sp.Symbol("k", **assumptions)
    check_assumptions(k, good)
    with pytest.raises(ParameterError, match=f"parameter k is declared {named}, got k = {bad}"):
        check_assumptions(k, bad)


# --- group elements and configurations ----------------------------------------------------------

def test_group_elements():
    R = np.array(sg.SO3("t").cayley([0.1, -0.2, 0.3]).tolist(), float)
    assert np.array_equal(group_element(sg.SO3("g"), R, "R"), R)
    pose = np.eye(3)
    pose[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]
    pose[:2, 2] = [5.0, -7.0]
    group_element(sg.SE2("q"), pose, "pose")
    bad_row = pose.copy()
    bad_row[2, 0] = 0.5
    for group, M, message in (
            (sg.SO3("g"), np.diag([1.0, -1.0, 1.0]), "det = -1 .a reflection"),
            (sg.SO3("g"), R + 1e-6, "off orthonormal by"),
            (sg.SO2("s"), [[0.0, 1.0], [1.0, 0.0]], "det = -1"),
            (sg.SE2("q"), bad_row, r"its last row is \[0.5, 0.0, 1.0\]"),
            (sg.SE2("q"), np.eye(2), r"is a 3×3 matrix, got shape \(2, 2\)")):
        with pytest.raises(sg.ShapeError, match=message):
            group_element(group, M, "M")


def test_configurations_of_composite_groupoids():
    pair = sg.PairGroupoid(sg.EuclideanSpace("q"))
    assert configuration(pair, 2, "c") == (2.0,)
    assert configuration(pair, [2], "c") == (2.0,)
    timed = sg.TimeGroupoid(pair * sg.SO2("s"))
    t, (q, S) = configuration(timed, (1, (0.5, np.eye(2))), "c")
    assert t == 1.0 and q == (0.5,) and np.array_equal(S, np.eye(2))
    with pytest.raises(DomainError, match=r"c\[1\]\[1\] is not in SO2\(s\)"):
        configuration(timed, (1, (0.5, 2 * np.eye(2))), "c")
    with pytest.raises(sg.ShapeError, match=r"c must be a configuration \(t, c\)"):
        configuration(timed, 3.0, "c")
    line = sg.DefinedGroupoid("line", base_names=["q"], fibre_names=["q"],
                              source=lambda a: (a[0],), target=lambda a: (a[1],),
                              multiply=lambda a, b: (a[0], b[1]),
                              identity=lambda q: (q[0], q[0]), inverse=lambda a: (a[1], a[0]),
                              sections=lambda q, t: [(q[0], q[0] + t)])
    with pytest.raises(sg.ShapeError, match="line has no configuration space"):
        configuration(line, 1.0, "start")


def test_magnitude_sums_the_terms_that_cancel():
    x, y = sp.symbols("x y", real=True)
    M = sp.lambdify([x, y], magnitude(2 * (x - y) + sp.sin(x - y)))
    assert M(1e8, 1e8) == pytest.approx(2 * 2e8 + 2e8)  # |sin| + |cos|·(|x| + |y|)
    assert sp.lambdify([x], magnitude(x ** 2 - 1))(3.0) == pytest.approx(10.0)


# --- states: flat vectors, group parts and constraints -------------------------------------------

@needs_cc
def test_a_flat_state_is_checked_like_named_parts():
    sim = compiled("plate_ball")
    state = initial_state(sim, "plate_ball")
    assert np.array_equal(sim.state(state), state)
    bad = state.copy()
    bad[4:13] *= 1.01  # the 'g' block scaled off SO(3)
    with pytest.raises(DomainError, match=r"plate_ball: the arrow g_k of the state \(its 'g' "
                                          r"part\) is not in SO3\(g\)"):
        sim.state(bad)
    with pytest.raises(DomainError, match="not in SO3"):
        sim.simulate(bad, 1, SEED_DATA["plate_ball"][0])
    reflected = state.copy()
    reflected[4:13] = np.diag([1.0, 1.0, -1.0]).ravel()
    with pytest.raises(DomainError, match="det = -1"):
        sim.state(reflected)
    with pytest.raises(DomainError, match=r"'g' is not in SO3\(g\): det = -1"):
        sim.state({"x": (0.0, 0.01), "y": (0.0, 0.0), "g": np.diag([1.0, -1.0, -1.0]) * -1,
                   "lambda": [0, 0, 0]})


@needs_cc
def test_an_initial_state_off_the_constraints_is_reported_per_constraint():
    """φ(g_k) at the known arrow, from the system's own constraints, with the violation of
    each constraint that does not hold; consistent states pass."""
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")  # from a momentum: consistent
    sim.state(state, params)
    sim.state(sim.simulate(state, 50, params).final_state(), params)
    off = state.copy()
    off[2] += 1e-6  # x_k moved: φ_2 = h(c + …) + (x_k − x_{k-1}) changes by 10⁻⁶,
    #                 φ_1 through its term −hΩ(x_{k-1} + x_k)/2 by −hΩ/2·10⁻⁶
    with pytest.raises(DomainError, match=r"violates the constraints \(with the parameters "
                                          r"h=0.01, r=1, Omega=0.1, c=0.02\): "
                                          r"φ_1\(g_k\) = -5.000e-10 "
                                          r"\(tolerance 1.0e-10\); φ_2\(g_k\) = 1.000e-06"):
        sim.state(off, params)
    check = ConstraintCheck(sim.equations)
    violated = check.violations(off, sim.parameters(params), 1e-11)
    assert [i for _, i, _, _ in violated] == [0, 1]
    assert violated[1][2] == pytest.approx(1e-6, rel=1e-6)


def test_second_order_constraints_are_checked_on_each_known_pair():
    """Φ(g_{k-1}, g_k) and Φ(g_k, g_{k+1}) on the second-order state."""
    system = sg.SecondOrderSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a, b: (b.target[0] - 2 * a.target[0] + a.source[0]) ** 2 / h ** 3,
        constraints=lambda a, b: [b.target[0] - a.target[0] - (a.target[0] - a.source[0])
                                  - h ** 2],
        parameters=[h], name="accel")
    sim = system.euler_lagrange().compile(backend="numpy")
    q = [0.0, 0.1, 0.21, 0.33]  # second differences 0.01 = h²
    sim.state({"q": q, "lambda": [[0.0], [0.0]]}, {"h": 0.1})
    with pytest.raises(DomainError, match=r"φ_1\(g_k, g_k\+1\) = 1.000e-03"):
        sim.state({"q": [0.0, 0.1, 0.21, 0.331], "lambda": [[0.0], [0.0]]}, {"h": 0.1})
    with pytest.raises(DomainError, match=r"φ_1\(g_k-1, g_k\) = -1.000e-03 \(tolerance "
                                          r".*\); φ_1\(g_k, g_k\+1\) = 3.000e-03"):
        sim.state({"q": [0.0, 0.1, 0.209, 0.331], "lambda": [[0.0], [0.0]]}, {"h": 0.1})


# --- one rule for every entry point -------------------------------------------------------------

@needs_cc
def test_unknown_parameters_are_rejected_identically_everywhere():
    """simulate, solve, from_momentum and solve_boundary_value give the same message."""
    sim = compiled("plate_ball")
    params, config, momentum = SEED_DATA["plate_ball"]
    state = initial_state(sim, "plate_ball")
    bad = {**params, "omega": 1.0}
    calls = [lambda: sim.simulate(state, 1, bad), lambda: sim.solve(state, bad),
             lambda: sim.from_momentum(config, momentum, bad),
             lambda: sg.solve_boundary_value(seed_system("plate_ball"),
                                             ((0.0, 0.0), np.eye(3)), ((0.1, 0.0), np.eye(3)),
                                             4, params=bad)]
    messages = set()
    for call in calls:
        with pytest.raises(ParameterError) as info:
            call()
        messages.add(str(info.value))
    assert messages == {"plate_ball: unknown parameter omega; the parameters are h, r, "
                        "Omega, c"}
    negative = {**params, "h": -0.01}
    for call in (lambda: sim.simulate(state, 1, negative),
                 lambda: sim.from_momentum(config, momentum, negative)):
        with pytest.raises(ParameterError, match="parameter h is declared positive, got "
                                                 "h = -0.01"):
            call()


@needs_cc
def test_from_momentum_names_its_bad_inputs():
    sim = compiled("plate_ball")
    params, config, momentum = SEED_DATA["plate_ball"]
    with pytest.raises(InputNameError, match="'z' is not a coordinate of the configuration"):
        sim.from_momentum({"z": 0.0}, momentum, params)
    with pytest.raises(sg.ShapeError, match="the momentum must hold real numbers"):
        sim.from_momentum(config, ["a", 0, 0, 0, 0], params)


# --- one rule for arguments, wherever they are given ----------------------------------------------

def test_a_zero_dimensional_array_is_not_a_configuration_of_a_product():
    G = sg.PairGroupoid(sg.EuclideanSpace("x")) * sg.SO3("g")
    with pytest.raises(sg.ShapeError, match="start must be a configuration .* got ndarray"):
        configuration(G, np.array(2.0), "start")


@pytest.mark.parametrize("value", [np.timedelta64(3, "D"), np.timedelta64(1),
                                   np.datetime64("2020-01-01")])
def test_numpy_durations_are_not_counts_or_flags(value):
    """(``np.timedelta64`` is a ``numbers.Integral``: ``int()`` of it raised TypeError.)"""
    with pytest.raises(sg.ShapeError, match="steps must be an integer"):
        integer_argument(value, "steps")
    with pytest.raises(sg.ShapeError, match="progress must be True or False"):
        _arguments.flag_argument(value, "progress")


def test_argument_checks_build_their_messages_only_on_failure(monkeypatch):
    """A valid argument is accepted without formatting it: the repr of a 10⁴-row state
    table once cost a sweep 12 % of its run time."""
    def never(value):
        raise AssertionError("a message was built for a valid argument")

    monkeypatch.setattr(_arguments, "shown_value", never)
    table = np.arange(12.0).reshape(4, 3)
    assert _arguments.real_array(table, "states").shape == (4, 3)
    assert _arguments.real_argument(np.float64(0.5), "h") == 0.5
    monkeypatch.undo()
    with pytest.raises(sg.ShapeError, match="states must be an array of real numbers"):
        _arguments.real_array("x", "states")


def test_parameter_screen_is_exact_for_every_assumption():
    """The float tests of the declared assumptions give SymPy's answer on the exact
    rational number a float is."""
    keys = ["positive", "negative", "nonnegative", "nonpositive", "zero", "nonzero",
            "integer", "noninteger", "even", "odd", "prime", "composite"]
    values = [0.0, -0.0, 1.0, -1.0, 2.0, 3.0, -3.0, 4.0, 0.5, -2.5, 1e300, 7.0, 9.0, 5e-324]
    for key in keys:
        for expected in (True, False):
            symbol = sp.Symbol("a", **{key: expected})
            test = _validate.assumption_test(symbol)
            for v in values:
                try:
                    _validate.check_assumptions(symbol, v)
                    accepted = True
                except sg.ParameterError:
                    accepted = False
                exact = all(getattr(sp.Rational(v), f"is_{k}") in (None, e)
                            for k, e in _validate.declared_assumptions(symbol))
                assert test(v) == accepted == exact, (key, expected, v)


def test_one_rule_for_counts_everywhere():
    """The runtime's count rule is the library's one rule (symgroupoid/_arguments.py)."""
    assert _validate.integer_argument is _arguments.integer_argument


# --- trusted states: the constraints' parameters in their key -----------------------------------

def test_the_parameters_the_constraints_use_are_taken_cheaply_and_exactly():
    """The tail of a trusted state's key: all parameters (None), none (b""), a contiguous
    run (a slice: no fancy indexing per call), else an index array; each gives the bytes of
    exactly the parameters the constraints use."""
    p = np.array([0.01, 2.0, 3.0, 4.0])
    for used, kind in (([0, 1, 2, 3], type(None)), ([], bytes), ([1, 2], slice),
                       ([0, 2], np.ndarray)):
        index = _used_index(used, 4)
        assert isinstance(index, kind)
        if index is None:
            continue
        key = index if type(index) is bytes else p[index].tobytes()
        assert key == p[used].tobytes()


# --- progress of long work (symgroupoid/_progress.py) ----------------------------------------

k = sp.Symbol("k", positive=True)


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
        deadline = time.monotonic() + 10  # the reporting thread draws within 0.02 s, unloaded
        while not task.shown and time.monotonic() < deadline:
            time.sleep(0.01)
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


# --- a batch in installments (runtime/_batch_progress.py): long runs split across kernel calls

@needs_cc
@pytest.mark.parametrize("backend", ["c", "numpy"])
@pytest.mark.parametrize("every", [1, 7])
def test_a_batch_in_installments_is_bitwise_one_call(backend, every, monkeypatch):
    """Calls of a single step each (the warm start crossing them), failing runs included,
    give the arrays of one call; the partial batch after a few calls is, run by run, the
    trajectory simulate gives for the steps reached."""
    sim = compiled("rigid_body") if backend == "c" else seed_step("rigid_body").compile(
        backend="numpy")
    thetas = [0.1, 1.0, 1.5, 0.3] if backend == "c" else [0.1, 1.5]
    S = np.array([sim.state({"W": rotation(t)}) for t in thetas])
    P = sim.parameters(RIGID)[None]
    steps = 40 if backend == "c" else 12
    whole = sim.kernel.simulate_batch(S, P[0], steps, every, sim.options, 1)
    assert not (whole.status == 0).all()
    monkeypatch.setattr(_batch_progress, "CALL_SECONDS", 1e-9)  # one step per call
    calls: list = []

    def stop_after(n):
        return lambda: calls.append(1) or len(calls) >= n

    progress = _batch_progress.BatchProgress(sim, S, P, steps, every, None)
    assert progress.work(0, stop_after(10**6))
    assert len(calls) == steps - 1  # asked between calls
    for name in whole.__dataclass_fields__:
        if name != "states":  # (rows past a failure are not written)
            assert np.array_equal(getattr(whole, name), getattr(progress.out, name)), name
    for b in range(len(S)):
        k = whole.kept[b]
        assert np.array_equal(whole.states[b, :k], progress.out.states[b, :k])
    calls.clear()
    progress = _batch_progress.BatchProgress(sim, S, P, steps, every, None)
    assert not progress.work(0, stop_after(9))
    partial = sg.TrajectoryBatch(sim, progress.so_far(), P, steps, every)
    for b in range(len(thetas)):
        if partial.status[b] == sg.Status.INTERRUPTED:
            reached = int(partial.failed_step[b])
            assert reached == 9
            assert_same_run(partial[b], sim.simulate(S[b], reached, RIGID, every=every))
            assert isinstance(partial.error(b), KeyboardInterrupt)
        else:
            assert partial.status[b] == whole.status[b] != 0


# --- the demo -----------------------------------------------------------------------------------

def test_demo_mentions_only_builds_that_happened():
    assert build_note(0) == ""
    assert build_note(1) == " (including the one-time kernel build)"
    assert build_note(2) == " (including 2 one-time kernel builds)"


