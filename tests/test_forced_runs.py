"""Per-step inputs of a forced system through the entry points that run many steps or many
runs (docs/conventions.md §20): ``simulate_batch`` (per-run and shared inputs, in C and with
NumPy, in installments), ``sweep`` and the CLI's ``--inputs``; each bitwise the runs of
``simulate(..., inputs=U)``, and bad input tables refused before any step."""

import numpy as np
import pytest
import sympy as sp
from _systems import driven_oscillator
from kernel_support import (  # noqa: F401  (module_cache: autouse fixture)
    REPO,
    module_cache,
    module_cache_root,
    needs_cc,
)

import symgroupoid as sg
from symgroupoid import DomainError, ShapeError
from symgroupoid.cli import load_system, main

# none of these tests is about the cache: they share one fresh kernel cache
# (kernel_support.module_cache), so the command line's tests build
# examples/cli/driven_spring.py once, not once each

h, k = sp.symbols("h k", positive=True)
PARAMS = {"h": 0.05, "k": 2.0, "c": 0.3}
STEPS = 25


@pytest.fixture(scope="module")
def oscillator(module_cache_root):  # noqa: F811
    return driven_oscillator().euler_lagrange().compile(cache_dir=module_cache_root)


def _starts(n: int) -> list:
    return [{"x": (0.1 * b, 0.1 * b + 0.01), "u": 0.05 * b} for b in range(n)]


def _table(n: int) -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.uniform(-1, 1, (n, STEPS, 1))


@pytest.mark.parametrize("every", [1, 4])
def test_a_batch_with_per_run_inputs_is_bitwise_the_runs(oscillator, every):
    starts, U = _starts(5), _table(5)
    batch = oscillator.simulate_batch(starts, STEPS, PARAMS, inputs=U, every=every,
                                      threads=2)
    assert batch.ok.all()
    for b, start in enumerate(starts):
        run = oscillator.simulate(start, STEPS, PARAMS, inputs=U[b], every=every)
        assert np.array_equal(batch[b].states, run.states)
        assert np.array_equal(batch[b].newton_iterations, run.newton_iterations)


def test_a_table_per_run_without_its_last_axis_names_the_per_run_shape(oscillator):
    """(Inputs of shape (B, steps) for one input were refused with a message naming the
    shared shapes (steps, 1) and (1,) only.)"""
    with pytest.raises(sg.ShapeError, match=r"or \(5, 25, 1\) for inputs of each run"):
        oscillator.simulate_batch(_starts(5), STEPS, PARAMS, inputs=_table(5)[:, :, 0])


def test_inputs_shared_by_every_run_and_held_constant(oscillator):
    starts = _starts(3)
    U = _table(1)[0]
    shared = oscillator.simulate_batch(starts, STEPS, PARAMS, inputs=U)
    held = oscillator.simulate_batch(starts, STEPS, PARAMS, inputs=[0.4])
    for b, start in enumerate(starts):
        assert np.array_equal(shared[b].states,
                              oscillator.simulate(start, STEPS, PARAMS, inputs=U).states)
        assert np.array_equal(held[b].states,
                              oscillator.simulate(start, STEPS, PARAMS, inputs=[0.4]).states)


def test_the_numpy_kernel_and_installments_give_the_same_bits(oscillator, monkeypatch):
    starts, U = _starts(4), _table(4)
    batch = oscillator.simulate_batch(starts, STEPS, PARAMS, inputs=U, every=3)
    twin = oscillator.equations.compile(backend="numpy")
    other = twin.simulate_batch(starts, STEPS, PARAMS, inputs=U, every=3)
    assert np.array_equal(other.states, batch.states)
    # one step per kernel call: the runs are advanced in 25 installments each
    monkeypatch.setattr("symgroupoid.runtime._batch_progress.CALL_SECONDS", 0.0)
    pieces = oscillator.simulate_batch(starts, STEPS, PARAMS, inputs=U, every=3, threads=1)
    assert np.array_equal(pieces.states, batch.states)


def test_a_run_that_fails_stops_alone_with_its_inputs(oscillator):
    """Run 1's input overflows the residual at step 6: it stops there, bitwise the run
    before it; the others complete."""
    starts, U = _starts(3), _table(3)
    U[1, 6, 0] = 1e308
    batch = oscillator.simulate_batch(starts, STEPS, PARAMS, inputs=U)
    assert list(batch.ok) == [True, False, True]
    assert batch.failed_step[1] == 6
    good = oscillator.simulate(starts[1], 6, PARAMS, inputs=U[1, :6])
    assert np.array_equal(batch[1].states, good.states)


@pytest.mark.parametrize("bad, error", [
    (None, ShapeError),  # a forced system needs its inputs
    (np.zeros((2, STEPS, 1)), ShapeError),  # 2 runs' inputs for 3 runs
    (np.zeros((3, STEPS - 1, 1)), ShapeError),  # fewer rows than steps
    (np.zeros((3, STEPS, 2)), ShapeError),  # two inputs per step for one input
    (np.full((3, STEPS, 1), np.nan), DomainError),
    (np.array([[["a"]] * STEPS] * 3), sg.SymgroupoidError),
])
def test_bad_batch_inputs_are_refused_before_any_step(oscillator, bad, error):
    with pytest.raises(error):
        oscillator.simulate_batch(_starts(3), STEPS, PARAMS, inputs=bad)


def test_the_nan_names_the_run_and_the_step(oscillator):
    U = _table(3)
    U[2, 11, 0] = np.inf
    with pytest.raises(DomainError, match="run 2, step 11"):
        oscillator.simulate_batch(_starts(3), STEPS, PARAMS, inputs=U)


@pytest.mark.parametrize("run", ["batch", "sweep"])
def test_a_bad_value_in_a_shared_sequence_is_a_domain_error(oscillator, run):
    """A NaN in one sequence shared by every run was re-raised as a ShapeError that
    suggested a table per run: the shape was right, the value was not."""
    U = np.ones((STEPS, 1))
    U[4, 0] = np.nan
    with pytest.raises(DomainError, match="step 4 is nan") as caught:
        if run == "batch":
            oscillator.simulate_batch(_starts(3), STEPS, PARAMS, inputs=U)
        else:
            sg.sweep(oscillator, _starts(3), PARAMS, STEPS, inputs=U, progress=False)
    assert "for inputs of each run" not in str(caught.value)


def test_inputs_may_be_given_by_name(oscillator):
    """A mapping from the inputs' names to their values (one step) or sequences (a run)
    reads as the same table; it was refused with "need shape (1,) … got shape ()"."""
    start, U = _starts(1)[0], _table(1)[0]
    run = oscillator.simulate(start, STEPS, PARAMS, inputs=U)
    named = oscillator.simulate(start, STEPS, PARAMS, inputs={"u": U[:, 0]})
    assert np.array_equal(run.states, named.states)
    one = oscillator.step(start, PARAMS, inputs=[0.3])
    assert np.array_equal(oscillator.step(start, PARAMS, inputs={"u": 0.3}), one)
    with pytest.raises(sg.InputNameError, match="keys v must be the inputs u"):
        oscillator.step(start, PARAMS, inputs={"v": 0.3})
    for bad in ({"u": "a"}, {"u": None}, {"u": [0.1, np.nan]}, {"u": 1j}, {"u": [[0.1]]}):
        with pytest.raises(sg.ShapeError):  # DomainError, a ShapeError, for the NaN
            oscillator.step(start, PARAMS, inputs=bad)
    with pytest.raises(sg.ShapeError, match="steps|shape"):
        oscillator.simulate(start, STEPS, PARAMS, inputs={"u": U[:-1, 0]})


def test_the_c_batch_entry_point_checks_its_inputs(oscillator):
    """``<prefix>_simulate_batch`` of a forced kernel refuses a NULL u and a u_stride other
    than 0 or n_steps·m, writing nothing (INVALID_ARGUMENT = 4)."""
    kernel = oscillator.kernel
    lib, ffi, P = kernel.lib, kernel.ffi, kernel.prefix
    assert getattr(lib, f"{P.upper()}_N_INPUTS") == 1
    fn = getattr(lib, f"{P}_simulate_batch")
    known = np.array([oscillator.state(s, PARAMS) for s in _starts(2)])
    p = oscillator.parameters(PARAMS)
    U = _table(2)
    states = np.full(2 * (STEPS + 1) * known.shape[1], -7.0)
    its = np.zeros(2 * STEPS, np.longlong)
    norms = np.zeros(2 * STEPS)
    kept = np.zeros(2, np.dtype("l"))
    status = np.zeros(2, np.intc)

    def call(u, stride):
        return fn(2, ffi.from_buffer("double[]", known), ffi.from_buffer("double[]", p), 0,
                  u, stride, STEPS, 1, ffi.NULL, ffi.from_buffer("double[]", states),
                  STEPS + 1, ffi.from_buffer("long long[]", its),
                  ffi.from_buffer("double[]", norms), ffi.from_buffer("long[]", kept),
                  ffi.from_buffer("int[]", status), ffi.NULL, ffi.NULL, ffi.NULL, ffi.NULL, 1)

    ub = ffi.from_buffer("double[]", U)
    assert call(ffi.NULL, 0) == 4 and call(ub, STEPS + 1) == 4 and call(ub, 1) == 4
    assert np.all(states == -7.0)
    assert call(ub, STEPS) == 0 and list(status) == [0, 0]
    batch = oscillator.simulate_batch(_starts(2), STEPS, PARAMS, inputs=U)
    assert np.array_equal(states.reshape(batch.states.shape), batch.states)


@pytest.mark.parametrize("executor", ["thread", "process"])
def test_a_sweep_takes_one_input_sequence_per_run(oscillator, executor):
    """A product sweep of 3 states × 2 damping values, with a sequence per cell (and one
    sequence for all): each run bitwise ``simulate`` with its sequence."""
    starts = _starts(3)
    sets = [dict(PARAMS, c=0.3), dict(PARAMS, c=0.6)]
    U = _table(6).reshape(3, 2, STEPS, 1)
    result = sg.sweep(oscillator, starts, sets, STEPS, inputs=U, executor=executor,
                      workers=2, chunk_size=2)
    shared = sg.sweep(oscillator, starts, sets, STEPS, inputs=U[0, 0], workers=1)
    for i, start in enumerate(starts):
        for j, params in enumerate(sets):
            run = oscillator.simulate(start, STEPS, params, inputs=U[i, j])
            assert np.array_equal(result.trajectories[i, j].states, run.states)
            same = oscillator.simulate(start, STEPS, params, inputs=U[0, 0])
            assert np.array_equal(shared.trajectories[i, j].states, same.states)


def test_a_sweep_refuses_input_tables_of_the_wrong_shape(oscillator):
    with pytest.raises(ShapeError, match="per-run inputs"):
        sg.sweep(oscillator, _starts(3), [PARAMS, PARAMS], STEPS,
                 inputs=np.zeros((2, 3, STEPS, 1)))
    with pytest.raises(ShapeError, match="inputs"):
        sg.sweep(oscillator, _starts(3), PARAMS, STEPS)


# --- the command line ---------------------------------------------------------------------------

DRIVEN = REPO / "examples" / "cli" / "driven_spring.py"


def _cli(capsys, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _cli_run_is(capsys, table, steps: int, expected) -> None:
    """``simulate DRIVEN --steps N --inputs table`` writes bitwise the states ``expected``."""
    out = table.with_name(f"{table.name}.npz")
    code, _, err = _cli(capsys, "simulate", DRIVEN, "--steps", str(steps), "--inputs", table,
                        "-o", out)
    assert code == 0, err
    with np.load(out) as data:
        assert np.array_equal(data["states"], expected.states), table.name


@needs_cc
@pytest.mark.usefixtures("isolated_cache")
def test_the_cli_runs_a_forced_system_from_an_input_file(tmp_path, capsys):
    """``simulate --inputs U.npy`` and ``U.csv`` (with and without a header): bitwise the
    library's ``simulate(..., inputs=U)``."""
    U = np.sin(np.arange(40) / 5)[:, None]
    np.save(tmp_path / "u.npy", U)
    np.savetxt(tmp_path / "u.csv", U, delimiter=",", fmt="%.17g")
    np.savetxt(tmp_path / "named.csv", U, delimiter=",", fmt="%.17g", header="u", comments="")
    sim = load_system(str(DRIVEN)).system.euler_lagrange().compile()
    expected = sim.simulate({"q": [1.0, 0.999], "u": [0.0]}, 40,
                            {"h": 0.05, "k": 1.0, "c": 0.2}, inputs=U)
    for name in ("u.npy", "u.csv", "named.csv"):
        _cli_run_is(capsys, tmp_path / name, 40, expected)


@pytest.mark.parametrize("content, message", [
    (None, "no such file"),
    ("0.1\nabc\n", "not a number"),
    ("v\n0.1\n", "the system's inputs are u"),
    ("0.1,0.2\n0.3\n", "different numbers of columns"),
    # one row of two values for one input: it was held as two steps of u
    ("u\n1,2\n", "2 columns for the 1 input of"),
    ("1,2\n3,4\n", "2 columns for the 1 input of"),
])
@pytest.mark.usefixtures("isolated_cache")
def test_the_cli_refuses_bad_input_files(tmp_path, capsys, content, message):
    path = tmp_path / "u.csv"
    if content is not None:
        path.write_text(content)
    code, _, err = _cli(capsys, "simulate", DRIVEN, "--steps", "2", "--inputs", path)
    assert code != 0 and message in err and "Traceback" not in err


@pytest.mark.usefixtures("isolated_cache")
def test_the_cli_refuses_a_pickled_or_misnamed_input_file(tmp_path, capsys):
    np.save(tmp_path / "u.npy", np.array([{"u": 1}], dtype=object), allow_pickle=True)
    code, _, err = _cli(capsys, "simulate", DRIVEN, "--steps", "1", "--inputs",
                        tmp_path / "u.npy")
    assert code != 0 and "cannot be read" in err
    code, _, err = _cli(capsys, "simulate", DRIVEN, "--steps", "1", "--inputs",
                        tmp_path / "u.txt")
    assert code != 0 and ".npy or .csv" in err
    np.save(tmp_path / "short.npy", np.zeros((3, 1)))
    code, _, err = _cli(capsys, "simulate", DRIVEN, "--steps", "5", "--inputs",
                        tmp_path / "short.npy")
    assert code != 0 and "3 rows for --steps 5: give at least 5 rows" in err


def test_a_control_loop_refilling_one_input_array(oscillator):
    """``sim.step(state, p, inputs=u)`` with the same array refilled in place each call (the
    fast path keeps its C view): bitwise ``simulate``; a NaN put into it inside the loop, and
    an integer array, still go through the checks."""
    U = _table(1)[0]
    start = _starts(2)[1]
    p = oscillator.parameters(PARAMS)
    options = sg.NewtonOptions(extrapolate=False)
    run = oscillator.simulate(start, STEPS, p, inputs=U, options=options)
    state, u_k = oscillator.state(start, p), np.empty(1)
    n = oscillator.layout.n_known - 1  # (the last entry: the slot of the input to come)
    for j in range(STEPS):
        u_k[:] = U[j]
        state = oscillator.step(state, p, inputs=u_k, options=options)
        assert np.array_equal(state[:n], run.states[j + 1, :n])
    u_k[0] = np.nan
    with pytest.raises(DomainError, match="finite"):
        oscillator.step(state, p, inputs=u_k, options=options)
    whole = oscillator.step(state, p, inputs=np.array([2]), options=options)
    assert np.array_equal(whole, oscillator.step(state, p, inputs=[2.0], options=options))


def test_a_control_loop_with_inputs_as_lists_takes_the_fast_path(monkeypatch):
    """``inputs=[u]`` (a list or tuple of numbers, as a controller writes it) is converted on
    the fast path: bitwise the loop over arrays, and not one call through the checked path
    (which cost some 60 µs a call); a list of other things still goes through the checks."""
    sim = driven_oscillator().euler_lagrange().compile()
    p = sim.parameters(PARAMS)
    options = sg.NewtonOptions(extrapolate=False)
    start = sim.state(_starts(2)[1], p)
    U = _table(1)[0]
    arrays = [start]
    for j in range(STEPS):
        arrays.append(sim.step(arrays[-1], p, inputs=U[j].copy(), options=options))
    checked = []
    original = sim._checked_call

    def counting(*args, **kwargs):
        checked.append(args)
        return original(*args, **kwargs)

    monkeypatch.setattr(sim, "_checked_call", counting)
    for wrap in (lambda v: [float(v)], lambda v: (v,), lambda v: [np.float64(v)]):
        state = start
        for j in range(STEPS):
            state = sim.step(state, p, inputs=wrap(U[j, 0]), options=options)
            assert np.array_equal(state, arrays[j + 1])
    assert checked == []
    with pytest.raises(DomainError, match="finite"):
        sim.step(start, p, inputs=[float("nan")], options=options)
    with pytest.raises(sg.SymgroupoidError):
        sim.step(start, p, inputs=[True], options=options)
    with pytest.raises(sg.SymgroupoidError):
        sim.step(start, p, inputs=[10 ** 400], options=options)


def test_a_stream_of_no_steps_is_the_run_of_no_steps(oscillator):
    """(``stream(state, 0, ...)`` yielded nothing, where ``simulate`` returns state 0.)"""
    pieces = list(oscillator.stream(_starts(1)[0], 0, PARAMS, inputs=np.zeros((0, 1))))
    run = oscillator.simulate(_starts(1)[0], 0, PARAMS, inputs=np.zeros((0, 1)))
    assert len(pieces) == 1 and np.array_equal(pieces[0].states, run.states)
    assert list(pieces[0].step_indices) == list(run.step_indices) == [0]


def test_the_slot_of_the_next_input_has_a_name(oscillator):
    """(The column of u_{k+1} in a forced system's state was named ``known[3]`` in
    trajectory files and tables.)"""
    names = [oscillator.layout.describe(i) for i in range(oscillator.layout.n_known)]
    assert names == ["x (step k-1)", "x", "u", "u (step k+1)"]


def test_a_trajectory_file_with_the_former_column_name_still_loads(oscillator, tmp_path):
    """A file written before the slot was named (column ``known[3]``) is read as before."""
    run = oscillator.simulate(_starts(1)[0], STEPS, PARAMS, inputs=_table(1)[0])
    run.save(tmp_path / "new.npz")
    with np.load(tmp_path / "new.npz") as data:
        arrays = dict(data)
    arrays["columns"] = np.array(["x (step k-1)", "x", "u", "known[3]"])
    np.savez(tmp_path / "old.npz", **arrays)
    old = sg.Trajectory.load(tmp_path / "old.npz", oscillator)
    assert np.array_equal(old.states, run.states)


@needs_cc
@pytest.mark.parametrize("executor", ["thread", "process"])
def test_a_branch_jump_in_a_restored_simulator_is_reported_as_such(oscillator, executor):
    """(Building the message of a branch jump read the step's time layout from the symbolic
    step, which an unpickled simulator does not have: it raised InputTypeError, and a
    process sweep with one such run lost every run.)  A huge input makes run 1 jump at
    step 10; the restored simulator, a process sweep and a thread sweep all report it."""
    import pickle

    U = np.ones((3, STEPS, 1))
    U[1, 10, 0] = 1e308
    restored = pickle.loads(pickle.dumps(oscillator))
    with pytest.raises(sg.BranchJumpError):
        restored.simulate(_starts(3)[1], STEPS, PARAMS, inputs=U[1])
    result = sg.sweep(oscillator, _starts(3), PARAMS, STEPS, inputs=U, combine="zip",
                      executor=executor, workers=1)
    assert result.status.tolist() == [0, 6, 0]
    for b in (0, 2):
        run = oscillator.simulate(_starts(3)[b], STEPS, PARAMS, inputs=U[b])
        assert np.array_equal(result.trajectories[b].states, run.states)


@pytest.mark.parametrize("run", ["simulate", "batch", "sweep"])
def test_more_input_rows_than_steps_are_refused(oscillator, run):
    """Row j is the input of the arrow step j computes: a table with more rows than steps
    (an off-by-one, or node samples u(t_k) for k = 0 … N) is another run, refused by name
    rather than cut short."""
    U = _table(3)
    longer = np.concatenate([U, U[:, :1]], axis=1)  # STEPS + 1 rows per run
    with pytest.raises(ShapeError, match=f"{STEPS + 1} rows for {STEPS} steps"
                       if run == "simulate" else f"shape \\(3, {STEPS}, 1\\)"):
        if run == "simulate":
            oscillator.simulate(_starts(1)[0], STEPS, PARAMS, inputs=longer[0])
        elif run == "batch":
            oscillator.simulate_batch(_starts(3), STEPS, PARAMS, inputs=longer)
        else:
            sg.sweep(oscillator, _starts(3), PARAMS, STEPS, inputs=longer)


def test_batch_inputs_for_a_system_without_inputs_name_the_reason():
    sim = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x")),
                            lambda g: ((g.target[0] - g.source[0]) ** 2 / (2 * h)
                                       - h * k * g.source[0] ** 2 / 2),
                            parameters=[h, k]).euler_lagrange().compile(backend="numpy")
    with pytest.raises(ShapeError, match="the system has no inputs; leave inputs= out"):
        sim.simulate_batch([{"x": (0.1, 0.11)}], 5, {"h": 0.05, "k": 2.0},
                           inputs=np.zeros((1, 5, 1)))


@needs_cc
@pytest.mark.usefixtures("isolated_cache")
def test_the_cli_holds_a_single_row_and_cuts_a_longer_table(tmp_path, capsys):
    """docs/cli.md: a single row holds the inputs constant; a table of more than N rows
    gives its first N; a forced system without ``--inputs`` is told to pass the option."""
    sim = load_system(str(DRIVEN)).system.euler_lagrange().compile()
    params, start = {"h": 0.05, "k": 1.0, "c": 0.2}, {"q": [1.0, 0.999], "u": [0.0]}
    U = np.cos(np.arange(30) / 4)[:, None]
    cases = {"one.csv": (np.array([[0.7]]), [0.7]), "long.npy": (U, U[:20])}
    for name, (table, expected_inputs) in cases.items():
        if name.endswith(".csv"):
            np.savetxt(tmp_path / name, table, delimiter=",", fmt="%.17g")
        else:
            np.save(tmp_path / name, table)
        _cli_run_is(capsys, tmp_path / name, 20,
                    sim.simulate(start, 20, params, inputs=expected_inputs))
    code, _, err = _cli(capsys, "simulate", DRIVEN, "--steps", "5")
    assert code != 0 and "--inputs U.npy|U.csv" in err and "Traceback" not in err


def test_plot_conservation_shows_the_forced_noether_balance(tmp_path):
    """A point in the plane turned by a torque input about the origin: its angular momentum
    changes by the torque's impulse, so the figure plots the balance J_k − Σ I_j (at
    rounding) and J's own change (grey, far above it); the energy is not plotted."""
    pytest.importorskip("matplotlib")
    x, y, tau = sp.symbols("x y tau", real=True)
    G = sg.PairGroupoid(sg.EuclideanSpace(["x", "y"]))

    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        return h * ((((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2) / 2
                    - k / 2 * (xm ** 2 + ym ** 2))

    def torque(g):
        (x0, y0), (x1, y1) = g.source, g.target
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        half = [-h / 2 * tau * ym, h / 2 * tau * xm]
        return half, half

    system = sg.DiscreteSystem(G, L, parameters=[h, k], forces=torque, inputs=[tau],
                               time_step=h, name="turned")
    sim = system.euler_lagrange().compile()
    J = system.noether(lambda q: [-q[1], q[0]])
    U = 0.5 * np.cos(np.arange(200) / 20)[:, None]
    traj = sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.01), "tau": 0.5}, 200,
                        {"h": 0.01, "k": 1.0}, inputs=U)
    fig = sg.plot_conservation(traj, momenta={"L_z": J}, path=tmp_path / "c.png")
    ax = fig.axes[0]
    lines = {line.get_label(): line.get_ydata() for line in ax.get_lines()}
    balance = np.nan_to_num(lines[next(k for k in lines if "Σ impulse" in k)])
    change = np.nan_to_num(lines[next(k for k in lines if "changed by" in k)])
    assert balance.max() < 1e-13 < 1e-3 < change.max()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert not any("energy" in s.lower() for s in labels)
    with pytest.raises(DomainError, match="every=1"):
        sg.plot_conservation(sim.simulate({"x": (1.0, 1.0), "y": (0.0, 0.01), "tau": 0.5},
                                          200, {"h": 0.01, "k": 1.0}, inputs=U, every=10),
                             momenta=[J])


def test_stream_takes_the_inputs_and_its_pieces_join_to_the_run(oscillator, monkeypatch):
    """In pieces of 7 steps (CHUNK_STEPS patched; the warm start carried): the joined pieces
    are bitwise ``simulate``'s run, every state and every third."""
    monkeypatch.setattr("symgroupoid.runtime._simulator.CHUNK_STEPS", 7)
    U, start = _table(1)[0], _starts(2)[1]
    for every in (1, 3):
        run = oscillator.simulate(start, STEPS, PARAMS, inputs=U, every=every)
        pieces = list(oscillator.stream(start, STEPS, PARAMS, inputs=U, every=every))
        assert len(pieces) > 2
        joined = np.concatenate([pieces[0].states] + [q.states[1:] for q in pieces[1:]])
        assert np.array_equal(joined, run.states)
    with pytest.raises(ShapeError, match="inputs"):
        oscillator.stream(start, STEPS, PARAMS, inputs=U[:3])


@needs_cc
def test_a_restored_simulator_gives_the_input_jacobian(oscillator):
    """(It said "the system has no inputs": it read them from the symbolic step, which an
    unpickled simulator does not have.)  The same bits as the simulator it was pickled from."""
    import pickle

    restored = pickle.loads(pickle.dumps(oscillator))
    start = _starts(2)[1]
    J = oscillator.input_jacobian(start, PARAMS, inputs=[0.2])
    assert J.shape == (1, 2) and np.any(J != 0)
    np.testing.assert_array_equal(restored.input_jacobian(start, PARAMS, inputs=[0.2]), J)


def _driven_satellite():
    """The satellite with a reaction wheel driven by τ = 0.5 sin(0.1 k) over 300 steps
    (NumPy backend): (system, trajectory)."""
    import sympy as sp

    from symgroupoid import systems

    system = systems.satellite_with_wheel()
    sim = system.euler_lagrange().compile(backend="numpy")
    W0 = sp.matrix2numpy(sp.rot_axis1(0.01) * sp.rot_axis3(0.02), dtype=float).T
    V0 = np.array([[np.cos(0.05), -np.sin(0.05)], [np.sin(0.05), np.cos(0.05)]])
    p = {"h": 0.02, "I": 2.0, "I3": 3.0, "Iw": 0.1}
    U = 0.5 * np.sin(0.1 * np.arange(300))
    return system, sim.simulate({"W": W0, "V": V0, "tau": 0.0}, 300, p, inputs=U)


def test_the_conservation_summary_of_a_forced_system_reports_the_impulse_balance():
    """(The summary printed a forced Noether quantity's raw drift, 0.2 against a rounding
    floor of 5e-15 — a failure by 13 orders to the eye — while plot_conservation showed its
    impulse balance at rounding; it also included the energy the forces change.)"""
    system, traj = _driven_satellite()
    summary = traj.conservation_summary(noether={"wheel": system.noether(3)})
    (balance,) = summary.quantities
    assert balance.name == "wheel − Σ impulse"
    assert balance.max_drift <= 10 * balance.floor.max() + 1e-14
    text = "\n".join(summary.lines())
    assert "wheel: changed by the forces' impulse" in text
    assert "energy: not included (the forces change it" in text


def test_a_forced_noether_quantity_without_net_impulse_is_reported_conserved(tmp_path):
    """(The satellite's total angular momentum about the wheel axis, which the wheel's
    internal torque leaves unchanged, was labelled "changed by the forces" in the figure,
    its balance with a zero impulse plotted beside it.)  A forced Noether quantity whose
    summed impulse stays within its rounding floor is J itself, "no net impulse"; the
    wheel's own momentum, which the torque changes, keeps its balance."""
    pytest.importorskip("matplotlib")
    system, traj = _driven_satellite()
    total = system.noether(2)  # body and wheel about e3 together
    wheel = system.noether(3)
    summary = traj.conservation_summary(noether={"total": total, "wheel": wheel})
    names = [q.name for q in summary.quantities]
    assert names == ["total (no net impulse)", "wheel − Σ impulse"]
    for q in summary.quantities:
        assert q.max_drift <= 10 * q.floor.max() + 1e-14
    text = "\n".join(summary.lines())
    assert "total: changed" not in text and "wheel: changed by the forces' impulse" in text
    fig = sg.plot_conservation(traj, momenta={"total": total, "wheel": wheel})
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels[0].startswith("wheel (changed by the forces)")
    assert not any(label.startswith("total (changed") for label in labels)
