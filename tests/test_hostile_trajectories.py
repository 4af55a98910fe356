"""Hostile input at the entry points that take a state or a trajectory:
``Simulator.project_initial``, the diagnostics (``traj.energy()``, ``traj.momenta()``,
``traj.constraint_residuals()``, ``traj.conservation_summary()``, ``traj[name]``,
``NoetherQuantity.along``), the figures (``plot_trajectory``, ``plot_conservation``) and
``verify_stationary`` on trajectories and arrays of arrows.

Malformed input: states off the constraints or off their group, malformed parts, unknown
names, parameters, iteration caps and step parameters of the wrong kind, sections that are
not sections, Noether quantities of another system, paths that cannot be written or whose
format is unknown, trajectories that are not trajectories, arrows with NaN, strings or
complex entries, multipliers of the wrong shape.

The invariant (tests/_hostile.py): a clear SymgroupoidError, or a correct result checked
independently — a projected state satisfies the constraints (evaluated from the system's
own SymPy constraints) with its source and multipliers unchanged; the energy is
−∂L_d/∂h of the SymPy Lagrangian; the momenta match along the run (F⁺L(g_k) = F⁻L(g_{k+1}),
the DEL); the constraint residuals vanish along a run; a solution from ``simulate`` is
stationary and a path that is not a solution is not.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from _hostile import (
    PROFILES,
    assert_finite,
    judge,
    junk,
    near,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from _hostile_cases import CASES, Case, case_of, counts, initial_states, parameter_sets
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg

# --- independent evaluations ------------------------------------------------------------------


@functools.cache
def constraint_values(name: str):
    """φ(g_k) of a first-order case from the system's SymPy constraints, as a function of
    (known state, parameters)."""
    step = case_of(name).step
    phis = step.system.constraints(step.groupoid.view(step.arrows[0]))
    return sp.lambdify([step.knowns, step.parameters], sp.Matrix(list(phis)), "numpy")


@functools.cache
def energy_function(name: str, h: str):
    """−∂L_d/∂h at the newest arrow of a first-order state, from the SymPy Lagrangian."""
    step = case_of(name).step
    L = sp.sympify(step.system.lagrangian(step.groupoid.view(step.arrows[0])))
    symbol = next(s for s in step.parameters if str(s) == h)
    return sp.lambdify([step.knowns, step.parameters], -sp.diff(L, symbol), "numpy")


@functools.cache
def run_of(name: str):
    case = case_of(name)
    return case.sim.simulate(case.flat, 6, case.params)


def parameter_vector(case: Case, params) -> np.ndarray:
    return case.sim.parameters(params)


# --- project_initial ----------------------------------------------------------------------------

@st.composite
def off_constraint_states(draw, case: Case):
    """(value, names): a valid state with the newest configuration moved (off the
    constraints), or a malformed state."""
    if draw(st.booleans()):
        return draw(initial_states(case))
    state = dict(case.named)
    for key, value in case.named.items():
        arr = np.asarray(value, float)
        if key != "lambda" and arr.ndim == 1 and arr.shape[0] == 2:
            moved = arr.copy()
            moved[-1] += draw(st.sampled_from([1e-3, -0.05, 0.3, 1e-12, 5.0]))
            state[key] = moved
    if draw(st.booleans()):
        state.pop("lambda", None)
    return state, ["state", "constraints", "project_initial"]


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_project_initial(name, run):
    case = case_of(name)
    sim = case.sim

    @profile(run, 5)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["initial", "initial", "params", "max_iterations"]))
        initial, params, cap, names = case.named, case.params, 50, []
        if which == "initial":
            initial, names = data.draw(off_constraint_states(case))
        elif which == "params":
            params, names = data.draw(parameter_sets(case))
        else:
            cap, names = data.draw(st.one_of(counts, st.integers(1, 60))), ["max_iterations"]
            cap = 40 if isinstance(cap, int) and cap > 10**6 else cap
        names = names + ["project_initial", "constraints"]

        def verify(state):
            assert_finite(state, "project_initial")
            p = parameter_vector(case, params)
            start = initial
            if isinstance(initial, dict) and sim.layout.n_multipliers \
                    and "lambda" not in initial:
                start = {**initial, "lambda": np.zeros(sim.layout.n_multipliers)}
            before = sim.state(start)
            G = case.step.groupoid
            new, old = sim.layout.arrows(state[None])[0], sim.layout.arrows(before[None])[0]
            assert np.array_equal(np.asarray(G.source(new), float),
                                  np.asarray(G.source(old), float)), \
                "the projection moved the source α(g_k)"
            if sim.layout.n_multipliers:
                assert np.array_equal(sim.layout.view(state[None], "lambda"),
                                      sim.layout.view(before[None], "lambda"))
            if case.step.n_constraints and case.step.order == 1:
                phi = np.asarray(constraint_values(name)(state, p), float).ravel()
                # zero to 1e-8, or to the rounding of coordinates as large as 1.8e16 (whose
                # ulp is 4: φ evaluated in another order differs by units there)
                floor = 1e-8 + 16 * np.finfo(float).eps * float(np.max(np.abs(state)))
                assert np.abs(phi).max() <= floor, f"φ = {phi} after the projection"

        judge("Simulator.project_initial",
              lambda: sim.project_initial(initial, params, max_iterations=cap), names,
              owner=sim.name, verify=verify)

    prop()


# --- diagnostics ----------------------------------------------------------------------------------

def check_energy(name: str, traj, step_parameter, values) -> None:
    assert np.shape(values) == (len(traj),) and np.isfinite(values).all(), values
    step = case_of(name).step
    h = "h" if step_parameter is None else str(step_parameter)
    if step.order != 1 or isinstance(step.groupoid, sg.TimeGroupoid):
        return
    p = case_of(name).sim.parameters(traj.parameters)
    want = np.array([float(energy_function(name, h)(s, p)) for s in traj.states])
    assert np.allclose(values, want, rtol=1e-9, atol=1e-12 * (1 + np.abs(want).max())), \
        (values, want)


def check_momenta(name: str, traj, momenta) -> None:
    step = case_of(name).step
    assert momenta.minus.shape == momenta.plus.shape == (len(traj), step.groupoid.rank
                                                         * step.order)
    assert np.isfinite(momenta.minus).all() and np.isfinite(momenta.plus).all()
    lag = 1 if step.order == 1 else 2
    mismatch = np.abs(momenta.matching(lag)).max(initial=0.0)
    scale = max(np.abs(momenta.minus).max(), np.abs(momenta.plus).max(), 1.0)
    assert mismatch <= 1e-8 * scale, f"F⁺L(g_k) ≠ F⁻L(g_k+{lag}): {mismatch:.2e}"


@st.composite
def diagnostic_calls(draw, name: str):
    """(label, call, names, verify) of one diagnostic with hostile arguments."""
    case = case_of(name)
    traj = run_of(name)
    system = case.step.system
    step_parameters = st.one_of(st.sampled_from([None, "h", "k", "zeta", "", "H"]), scalars,
                                junk(max_leaves=2))
    sections = st.one_of(st.integers(-2, 7), near([1.0] * case.step.groupoid.rank),
                         junk(max_leaves=2))
    kind = draw(st.sampled_from(["energy", "energy size", "momenta", "constraints",
                                 "summary", "part", "noether", "noether value"]))
    if kind == "energy":
        h = draw(step_parameters)
        return ("Trajectory.energy", lambda: traj.energy(h),
                ["step_parameter", "h", "energy", str(h)],
                lambda v: check_energy(name, traj, h, v))
    if kind == "energy size":
        h = draw(step_parameters)
        target = draw(st.one_of(st.just(traj), junk(max_leaves=2)))

        def verify_size(sizes):  # the size of E's terms bounds |E|
            assert np.shape(sizes) == (len(traj),) and np.isfinite(sizes).all()
            assert (sizes >= np.abs(traj.energy(h)) * (1 - 1e-12)).all()
        return ("diagnostics.energy_magnitude",
                lambda: sg.diagnostics.energy_magnitude(target, h),
                ["step_parameter", "h", "energy", "trajectory", "Trajectory", str(h)],
                verify_size)
    if kind == "momenta":
        return ("Trajectory.momenta", traj.momenta, ["momenta"],
                lambda m: check_momenta(name, traj, m))
    if kind == "constraints":
        def verify(values):
            assert values.shape == (len(traj), case.step.n_constraints)
            assert np.abs(values).max(initial=0.0) <= 1e-8, values
        return ("Trajectory.constraint_residuals", traj.constraint_residuals, ["constraints"],
                verify)
    if kind == "summary":
        energy = draw(st.one_of(st.sampled_from([None, True, False]), scalars))
        noether = draw(st.one_of(st.just(()), st.lists(sections, max_size=2), junk()))
        h = draw(st.one_of(st.none(), step_parameters))

        def verify(summary):
            assert all(isinstance(line, str) for line in summary.lines())
            for q in summary.quantities:
                assert np.isfinite(q.values).all() and np.isfinite(q.max_drift)
        return ("Trajectory.conservation_summary",
                lambda: traj.conservation_summary(energy=energy, noether=noether,
                                                  step_parameter=h),
                ["energy", "noether", "section", "step_parameter", "h", "coefficients"],
                verify)
    if kind == "part":
        key = draw(st.one_of(st.sampled_from(sorted(case.named)), st.text(max_size=3),
                             scalars))

        def verify(values):  # a pair coordinate: q_0 … q_{N+1}, one more than the states
            assert len(values) >= len(traj)
            assert_finite(values, f"traj[{key!r}]")
        return ("Trajectory[name]", lambda: traj[key], ["part", str(key)], verify)
    if kind == "noether value":
        return noether_value_call(draw, traj, system, draw(sections))
    section = draw(sections)
    target = draw(st.one_of(st.just(traj), junk(max_leaves=2)))
    method = draw(st.sampled_from(["along", "term_magnitude", "along_with_magnitude"]))

    def call():
        quantity = system.noether(section)
        return getattr(quantity, method)(target)

    def verify(values):
        values = values if method == "along_with_magnitude" else (values,)
        for v in values:
            assert np.shape(v) == (len(traj),) and np.isfinite(v).all()
        if method == "along_with_magnitude":  # the size of F_X's terms bounds |F_X|
            assert (values[1] >= np.abs(values[0]) * (1 - 1e-12)).all()
    return (f"NoetherQuantity.{method}", call,
            ["section", "coefficients", "trajectory", f"NoetherQuantity.{method}"], verify)


def noether_value_call(draw, traj, system, section):
    """``NoetherQuantity.evaluate`` at a state of the run (its arrow and multipliers, the
    run's parameters), each argument possibly replaced by junk or non-finite numbers."""
    row = draw(st.integers(0, len(traj) - 1))
    hostile = st.one_of(st.none(), junk(max_leaves=2),
                        st.lists(st.sampled_from([np.nan, np.inf, 1e308, -0.0]), max_size=4))
    arrow, multipliers, params = (None, None, None) if draw(st.booleans()) else (
        draw(hostile) for _ in range(3))

    def call():
        quantity = system.noether(section)
        a, m = len(quantity.arrow), len(quantity.multipliers)
        state = np.asarray(traj.states[row], float)
        given = [traj.parameters[str(s)] for s in quantity.parameters]
        return quantity.evaluate(state[:a] if arrow is None else arrow,
                                 state[a:a + m] if multipliers is None else multipliers,
                                 given if params is None else params)

    def verify(value):
        assert isinstance(value, float) and np.isfinite(value), value
    return ("NoetherQuantity.evaluate", call,
            ["section", "coefficients", "arrow", "multipliers", "params",
             "NoetherQuantity.evaluate"], verify)


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_diagnostics(name, run):
    case = case_of(name)

    @profile(run, 6)
    @given(call=diagnostic_calls(name))
    def prop(call):
        label, fn, names, verify = call
        judge(label, fn, names, owner=case.sim.name, verify=verify)

    prop()


# --- figures ------------------------------------------------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
def test_figures(run):
    """``plot_trajectory`` and ``plot_conservation``: parts, paths, switches (the valid
    figures are drawn: few examples)."""
    name = "diagonal"
    traj = run_of(name)
    paths = st.one_of(st.none(), st.sampled_from(["fig.png", "fig.pdf", "fig.xyz", "",
                                                  "missing/dir/fig.png", "fig", 3, b"f.png",
                                                  "a\0b.png", "."]), junk(max_leaves=2))

    @profile(run, 2, 60)
    @given(data=st.data())
    def prop(data):
        path = data.draw(paths)
        if data.draw(st.booleans()):
            parts = data.draw(st.one_of(st.none(), st.sampled_from(
                [["x"], "x", ["x", "nope"], [], [1], ["lambda"]]), junk(max_leaves=2)))
            max_parts = data.draw(st.one_of(st.just(6), counts))
            label, call = "plot_trajectory", lambda: sg.plot_trajectory(
                traj, parts, path=path, max_parts=max_parts)
            names = ["parts", "path", "max_parts", "part"]
        else:
            energy = data.draw(st.one_of(st.sampled_from([None, True, False]), scalars))
            constraints = data.draw(st.one_of(st.sampled_from([None, True, False]), scalars))
            momenta = data.draw(st.one_of(st.just(()), st.sampled_from([[0], [[1, 1]], [7]]),
                                          junk(max_leaves=2)))
            label, call = "plot_conservation", lambda: sg.plot_conservation(
                traj, energy, momenta, constraints=constraints, path=path)
            names = ["energy", "noether", "constraints", "path", "section", "coefficients",
                     "plot"]

        def verify(fig):
            assert len(fig.axes) >= 1
            if path is not None:
                import pathlib

                assert pathlib.Path(path).stat().st_size > 0

        judge(label, call, names, owner=name, verify=verify)

    prop()


# --- verify_stationary ------------------------------------------------------------------------

@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", ["oscillator", "diagonal", "accel"])
def test_verify_stationary(name, run):
    case = case_of(name)
    system = case.step.system
    traj = run_of(name)
    arrows = traj._layout.arrows(traj.states)
    lam = traj.multipliers
    straight = None
    if name == "oscillator":  # q_k = 0.1·k + 0.3: composable, not a solution
        q = 0.3 + 0.1 * np.arange(len(arrows) + 1)
        straight = np.stack([q[:-1], q[1:]], axis=1)

    @profile(run, 6)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["trajectory", "arrows", "straight", "system",
                                           "params", "multipliers", "eps", "seed"]))
        args = {"trajectory": traj, "system": system, "params": None, "multipliers": None,
                "eps": 1e-3, "seed": 0}
        expect = True
        names = [which]
        if which == "trajectory":
            args["trajectory"] = data.draw(junk())
            # raw arrows carry no parameters, nor multipliers (for a constrained system): with
            # params=None and multipliers=None either is the error to name
            names = ["trajectory", "arrows", "parameters", "multipliers"]
        elif which == "arrows":
            args["trajectory"] = data.draw(near(arrows))
            args["multipliers"], args["params"] = lam, case.params
            names = ["arrows", "trajectory", "multipliers"]
            expect = None  # a moved arrow: no claim either way
        elif which == "straight":
            if straight is None:
                return
            args["trajectory"], args["params"] = straight, case.params
            expect = False
        elif which == "system":
            args["system"] = data.draw(st.one_of(junk(), st.just(sg.SO3("R"))))
        elif which == "params":
            args["params"], names = data.draw(parameter_sets(case))
        elif which == "multipliers":
            args["multipliers"] = data.draw(st.one_of(near(lam), junk()))
        elif which == "eps":
            args["eps"] = data.draw(st.one_of(scalars, st.floats(1e-6, 1e-2)))
        else:
            args["seed"] = data.draw(st.one_of(scalars, st.integers(-5, 2**70)))
        value_given = args["trajectory"] is traj and which in ("params", "multipliers")

        def verify(report):
            assert isinstance(report, sg.StationarityReport)
            if expect is True and not value_given:
                assert report, f"{name}: a solution from simulate is not stationary: {report}"
            if expect is False:
                assert not report, f"{name}: a straight path that is no solution is " \
                                   f"reported stationary: {report}"

        judge("verify_stationary", lambda: sg.verify_stationary(**args), names,
              owner=system.name, verify=verify)

    prop()


# --- configurations, spatial momenta, files ------------------------------------------------------

#: a valid first configuration of each case's groupoid (None: the state determines it, or
#: the identity)
STARTS = {"rigid_body": np.eye(3), "plate_ball": (None, np.eye(3)),
          "heavy_top": (None, np.eye(3))}


def _entry(stacked, k: int):
    """Configuration k of a stacked result (arrays indexed, tuples entry by entry)."""
    if isinstance(stacked, tuple):
        return tuple(_entry(s, k) for s in stacked)
    return stacked[k]


def _flat(c) -> np.ndarray:
    if isinstance(c, tuple):
        return np.concatenate([_flat(x) for x in c]) if c else np.zeros(0)
    return np.asarray(c, float).ravel()


def check_configurations(name: str, traj, result) -> None:
    """Rebuilt independently: c_{k+1} = configuration_after(c_k, g_k), one arrow at a time,
    from the first configuration of the result."""
    G = case_of(name).step.groupoid
    arrows = traj._layout.arrows(traj.states)
    c = _entry(result, 0)
    for k, a in enumerate(arrows):
        c = G.configuration_after(c, tuple(a))
        want, got = _flat(c), _flat(_entry(result, k + 1))
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12), (k, got, want)


@st.composite
def reconstruction_calls(draw, name: str, folder):
    """(label, call, names, verify) of configurations / spatial_momenta / save / load /
    plot(time_step=…) with hostile arguments."""
    case = case_of(name)
    traj = run_of(name)
    valid = STARTS.get(name)
    starts = st.one_of(st.just(valid), st.just(None), junk(max_leaves=3),
                       near(np.eye(3)) if valid is not None else st.just(None))
    kind = draw(st.sampled_from(["configurations", "spatial", "save", "load", "time"]))
    if kind in ("configurations", "spatial"):
        start = draw(starts)
        names = ["start", "configuration", "configurations", "spatial", "every", "factor"]
        if kind == "configurations":
            return ("Trajectory.configurations", lambda: traj.configurations(start), names,
                    lambda r: check_configurations(name, traj, r))

        def verify(momenta):
            assert momenta.shape == (len(traj), case.step.groupoid.rank)
            assert_finite(momenta, "spatial momenta")
            if name == "rigid_body":  # R_k μ_k: conserved
                assert np.abs(momenta - momenta[0]).max() <= 1e-12 * np.abs(momenta).max()
        return ("Trajectory.spatial_momenta", lambda: traj.spatial_momenta(start), names,
                verify)
    if kind == "save":
        path = draw(st.one_of(st.sampled_from(["t.npz", "t.csv", "t.txt", "", "missing/t.npz",
                                               ".", "a\0b.npz", 3, b"t.npz"]),
                              junk(max_leaves=2)))

        def verify(_):
            back = sg.Trajectory.load(path, case.sim, params=case.params)
            assert np.array_equal(back.states, traj.states)
        return ("Trajectory.save", lambda: traj.save(path), ["path", "trajectory"], verify)
    if kind == "load":
        saved = folder / f"{name}.npz"
        if not saved.exists():
            traj.save(saved)
        with np.load(saved) as archive:
            arrays = dict(archive)
        how = draw(st.sampled_from(["valid", "csv", "bytes", "pickle", "array", "path",
                                    "simulator", "params", "other"]))
        path, sim, params, extra = saved, case.sim, None, []
        if how == "csv":
            path, params = folder / f"{name}.csv", draw(st.one_of(st.none(),
                                                                  st.just(case.params)))
            if not path.exists():
                traj.save(path)
        elif how == "bytes":
            path = folder / "junk.npz"
            path.write_bytes(draw(st.binary(max_size=60)))
        elif how in ("pickle", "array"):
            key = draw(st.sampled_from(sorted(arrays)))
            value = (np.array([object()], dtype=object) if how == "pickle"
                     else draw(st.one_of(junk(max_leaves=2), near(np.ones(2)))))
            path = folder / f"{how}.npz"
            try:
                np.savez(path, **{**arrays, key: value})
            except Exception:  # noqa: BLE001 - a value NumPy cannot store: nothing to test
                return ("Trajectory.load", lambda: None, [], lambda _: None)
        elif how == "path":
            path = draw(st.one_of(st.sampled_from(["absent.npz", ".", "", "x.txt"]),
                                  junk(max_leaves=2)))
        elif how == "simulator":
            sim = draw(st.one_of(junk(max_leaves=2), st.just(case_of("oscillator").sim)))
        elif how == "params":
            params, extra = draw(parameter_sets(case))
        else:
            path = folder / "other.npz"
            if not path.exists():
                run_of("oscillator").save(path)

        def verify(loaded):
            if loaded is None:
                return
            assert np.array_equal(loaded.states, traj.states)
            assert list(loaded.parameters) == [str(s) for s in case.step.parameters]
        return ("Trajectory.load", lambda: sg.Trajectory.load(path, sim, params=params),
                ["path", "file", "simulator", "parameter", "parameters", "params",
                 "trajectory", "npz", "csv", "columns", "states", "another system",
                 str(path), *extra], verify)
    time_step = draw(st.one_of(st.sampled_from([None, False, "h", "k", "zz"]), scalars))
    return ("plot_trajectory (time_step)",
            lambda: sg.plot_trajectory(traj, time_step=time_step),
            ["time_step"], lambda fig: None)


@pytest.mark.parametrize("run", PROFILES)
@pytest.mark.parametrize("name", CASES)
def test_configurations_and_files(name, run, tmp_path):
    case = case_of(name)

    @profile(run, 16)
    @given(call=reconstruction_calls(name, tmp_path))
    def prop(call):
        label, fn, names, verify = call
        judge(label, fn, names, owner=case.sim.name, verify=verify)

    prop()
