"""Input tables with named columns and masked arrays (docs/conventions.md §20).

A pandas ``DataFrame`` whose columns are labelled by the inputs' names is read by name, in
any column order, at every entry point that takes a sequence of inputs (``simulate``,
``simulate_batch``, ``sweep``); a labelled table that does not name the inputs exactly is
an ``InputNameError``; an unlabelled one (integer columns) is read by position.  A masked
array with a masked entry is refused: its hidden values are not data.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid import systems

pd = pytest.importorskip("pandas")

PARAMS = {"h": 0.01, "g": 9.81, "c": 0.1}
STATE = np.concatenate([[0.1, 0.2, 0.11, 0.21], np.zeros(4)])
STEPS = 12
EXACT = sg.NewtonOptions(extrapolate=False)


@functools.cache
def chain():
    """The forced planar chain of two links (inputs u1, u2) on the NumPy backend."""
    return systems.planar_chain(2, forced=True).euler_lagrange().compile(backend="numpy")


def _inputs() -> np.ndarray:
    return np.random.default_rng(7).normal(scale=0.5, size=(STEPS, 2))


def test_columns_are_read_by_name_in_any_order():
    sim, U = chain(), _inputs()
    assert sim.layout.input_names == ["u1", "u2"]
    plain = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    swapped = pd.DataFrame({"u2": U[:, 1], "u1": U[:, 0]})
    named = sim.simulate(STATE, STEPS, PARAMS, inputs=swapped, options=EXACT)
    assert np.array_equal(named.states, plain.states)
    # a positional reading would have driven joint 1 with u2: a different motion
    crossed = sim.simulate(STATE, STEPS, PARAMS, inputs=U[:, ::-1], options=EXACT)
    assert not np.allclose(crossed.states, plain.states, rtol=0, atol=1e-9)


def test_batches_and_sweeps_read_columns_by_name():
    sim, U = chain(), _inputs()
    plain = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    swapped = pd.DataFrame({"u2": U[:, 1], "u1": U[:, 0]})
    batch = sim.simulate_batch(np.stack([STATE, STATE]), STEPS, PARAMS, inputs=swapped,
                               options=EXACT)
    for run in batch:
        assert np.array_equal(run.states, plain.states)
    swept = sg.sweep(sim, STATE, PARAMS, STEPS, inputs=swapped, options=EXACT)
    assert np.array_equal(swept.trajectories.ravel()[0].states, plain.states)


def test_a_list_of_labelled_tables_one_per_run_is_read_by_name():
    """``simulate_batch(..., inputs=[df, df])``, a sweep's per-run tables and a
    boundary-value sweep's read each table by position (driving joint 1 with u2); tables
    labelled by anything but the inputs were accepted."""
    sim, U = chain(), _inputs()
    plain = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    swapped = pd.DataFrame({"u2": U[:, 1], "u1": U[:, 0]})
    batch = sim.simulate_batch(np.stack([STATE, STATE]), STEPS, PARAMS,
                               inputs=[swapped, swapped], options=EXACT)
    for run in batch:
        assert np.array_equal(run.states, plain.states)
    swept = sg.sweep(sim, np.stack([STATE, STATE]), PARAMS, STEPS, combine="zip",
                     inputs=(swapped, swapped), options=EXACT)
    for run in swept.trajectories.ravel():
        assert np.array_equal(run.states, plain.states)
    wrong = pd.DataFrame({"a": U[:, 1], "b": U[:, 0]})
    with pytest.raises(sg.InputNameError, match=r"inputs\[1\]: the table's columns a, b"):
        sim.simulate_batch(np.stack([STATE, STATE]), STEPS, PARAMS, inputs=[swapped, wrong])


def test_boundary_value_sweeps_read_labelled_tables_by_name():
    step = systems.planar_chain(2, forced=True).euler_lagrange()
    N = 6
    U = np.random.default_rng(3).normal(scale=0.5, size=(N, 2))
    swapped = pd.DataFrame({"u2": U[:, 1], "u1": U[:, 0]})
    one = sg.solve_boundary_value(step, [0.1, 0.0], [0.2, 0.1], N, params=PARAMS, inputs=U)
    for inputs in (swapped, [swapped, swapped]):
        runs = sg.sweep_boundary_value(step, [[0.1, 0.0]] * 2, [[0.2, 0.1]], N, PARAMS,
                                       inputs=inputs, workers=1)
        for solution in runs.solutions:
            assert np.array_equal(solution.inputs, one.inputs)
            assert np.array_equal(solution.arrows, one.arrows)


def test_unlabelled_columns_are_read_by_position():
    sim, U = chain(), _inputs()
    plain = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    table = sim.simulate(STATE, STEPS, PARAMS, inputs=pd.DataFrame(U), options=EXACT)
    assert np.array_equal(table.states, plain.states)


@pytest.mark.parametrize("columns", [["x", "y"], ["u1", "u1"], ["u1"], ["u1", "u2", "u3"]])
def test_labels_that_are_not_the_inputs_are_refused(columns):
    sim = chain()
    table = pd.DataFrame(np.zeros((STEPS, len(columns))), columns=columns)
    with pytest.raises(sg.InputNameError, match=r"inputs: the table's columns .* must be "
                                                r"the inputs u1, u2"):
        sim.simulate(STATE, STEPS, PARAMS, inputs=table)


def test_masked_entries_are_refused_everywhere():
    sim, U = chain(), _inputs()
    masked = np.ma.masked_array(U, mask=np.zeros(U.shape, bool))
    masked.mask[3, 1] = True
    with pytest.raises(sg.ShapeError, match=r"inputs has masked \(missing\) entries, the "
                                            r"first at index \(3, 1\)"):
        sim.simulate(STATE, STEPS, PARAMS, inputs=masked)
    with pytest.raises(sg.ShapeError, match="masked"):
        sim.simulate_batch(np.stack([STATE, STATE]), STEPS, PARAMS, inputs=masked)
    hidden = np.ma.masked_array(STATE, mask=np.arange(STATE.size) == 2)
    with pytest.raises(sg.ShapeError, match="masked"):
        sim.simulate(hidden, STEPS, PARAMS, inputs=U)
    # a masked array without a masked entry is its data
    clear = np.ma.masked_array(U)
    assert np.array_equal(sim.simulate(STATE, STEPS, PARAMS, inputs=clear, options=EXACT).states,
                          sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT).states)


def test_columns_labelled_by_the_input_symbols_are_read_by_name():
    """A table labelled by the SymPy symbols themselves (as a parameter table may be) was
    read by position: the inputs were swapped without a word."""
    sim, U = chain(), _inputs()
    u1, u2 = sim.equations.system.inputs
    plain = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    swapped = pd.DataFrame({u2: U[:, 1], u1: U[:, 0]})
    assert np.array_equal(sim.simulate(STATE, STEPS, PARAMS, inputs=swapped,
                                       options=EXACT).states, plain.states)


def test_a_labelled_row_is_read_by_name_in_every_one_step_entry():
    """``df.iloc[j]`` (a pandas Series labelled u2, u1) in a loop of ``step``, as inputs
    held constant, and in ``solve``: read by its labels, so the loop replays the table."""
    sim, U = chain(), _inputs()
    frame = pd.DataFrame({"u2": U[:, 1], "u1": U[:, 0]})
    whole = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    state = sim.state(STATE)
    for j in range(STEPS):
        state = sim.step(state, PARAMS, inputs=frame.iloc[j], options=EXACT)
    assert np.array_equal(state, whole.states[-1])
    held = sim.simulate(STATE, STEPS, PARAMS, inputs=frame.iloc[0], options=EXACT)
    assert np.array_equal(held.states, sim.simulate(STATE, STEPS, PARAMS, inputs=U[0],
                                                    options=EXACT).states)
    assert np.array_equal(sim.solve(STATE, PARAMS, inputs=frame.iloc[0])[0],
                          sim.solve(STATE, PARAMS, inputs=U[0])[0])
    with pytest.raises(sg.InputNameError, match="the row's labels u2, x must be the inputs"):
        sim.step(sim.state(STATE), PARAMS, inputs=pd.Series([0.0, 0.0], index=["u2", "x"]))


def test_inputs_held_constant_hold_no_table_of_the_run():
    """Inputs given as one row were copied out to a table of the run's length (and a
    finiteness mask of it) before the first step: a long sampled run held gigabytes, and
    10¹² steps ended in an internal MemoryError where the unforced run needs constant
    memory.  The row is now checked once and read a chunk at a time; the run is bitwise
    that of the full table."""
    import tracemalloc

    from kernel_support import HAVE_CC

    if not HAVE_CC:
        pytest.skip("no C compiler (cc) on PATH")
    sim = systems.planar_chain(2, forced=True).euler_lagrange().compile(backend="c")
    steps = 10**6
    tracemalloc.start()
    try:
        held = sim.simulate(STATE, steps, PARAMS, inputs=[0.1, -0.05], every=steps)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    table = sim.simulate(STATE, steps, PARAMS, inputs=np.tile([0.1, -0.05], (steps, 1)),
                         every=steps)
    assert np.array_equal(held.states, table.states)
    assert peak < 8e6, peak  # the table alone is 16 MB


def test_tables_labelled_by_anything_but_names_or_positions_are_refused():
    """(A MultiIndex's columns, ("torque", "u2"), ("torque", "u1"), were taken for
    unlabelled and read by position: joint 1 was driven by u2.)  Only integer labels are
    positions; tuples and floats name no input and the table is refused, naming them."""
    sim, U = chain(), _inputs()
    multi = pd.DataFrame(U[:, ::-1], columns=pd.MultiIndex.from_tuples(
        [("torque", "u2"), ("torque", "u1")]))
    with pytest.raises(sg.InputNameError, match=r"\('torque', 'u2'\).*must be the inputs "
                                                r"u1, u2"):
        sim.simulate(STATE, STEPS, PARAMS, inputs=multi, options=EXACT)
    floats = pd.DataFrame(U, columns=[0.0, 1.0])
    with pytest.raises(sg.InputNameError, match="0.0, 1.0 must be the inputs u1, u2"):
        sim.simulate(STATE, STEPS, PARAMS, inputs=floats, options=EXACT)
    numbered = pd.DataFrame(U, columns=np.arange(2, dtype=np.int32))  # positions
    plain = sim.simulate(STATE, STEPS, PARAMS, inputs=U, options=EXACT)
    assert np.array_equal(sim.simulate(STATE, STEPS, PARAMS, inputs=numbered,
                                       options=EXACT).states, plain.states)


def test_no_initial_states_is_an_empty_batch_whatever_their_container():
    """(A (0, n) array gave an empty batch where [] was refused as "empty".)  Both are a
    batch, or a sweep, of no runs."""
    sim = chain()
    for empty in (np.zeros((0, STATE.size)), []):
        assert len(sim.simulate_batch(empty, STEPS, PARAMS, inputs=_inputs())) == 0
        assert sg.sweep(sim, empty, PARAMS, STEPS, inputs=_inputs()).shape == (0,)
