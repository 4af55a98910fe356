"""Regression tests of the defects the hostile-input suite found, one mechanism each.

Each test states the defect it pins (the behaviour before the fix in parentheses); the
property tests that found them are in tests/test_hostile_*.py.  Further regression tests
live next to their subject: the relative and foreign cache roots in test_hostile_files.py,
the OpenMP team size in test_hostile_isolated.py, the command line's last resort in
test_hostile_cli.py.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import sympy as sp
from _hostile import H, diagonal, oscillator, scratch_cwd  # noqa: F401  (autouse fixture)
from _hostile_cases import case_of
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid import systems
from symgroupoid.equations import LatexOptionError
from symgroupoid.runtime import system_argument

# --- one rule for arguments -----------------------------------------------------------------------


def test_progress_must_be_a_switch():
    """(A string such as "no" turned progress bars on.)"""
    sim = case_of("oscillator").sim
    with pytest.raises(sg.ShapeError, match="oscillator: simulating: progress must be True or "
                                            "False, got str 'no'"):
        sim.simulate({"q": (0.1, 0.2)}, 2, {"h": 0.1, "k": 1.0}, progress="no")
    with pytest.raises(sg.ShapeError, match="progress must be True or False"):
        oscillator().euler_lagrange(progress="no")


# --- batches and sweeps ---------------------------------------------------------------------------

def _rows(name: str = "diagonal") -> tuple[np.ndarray, dict]:
    case = case_of(name)
    return case.sim.simulate(case.flat, 2, case.params).states[:2], case.params


@pytest.mark.parametrize("dtype", [str, bool, complex, "M8[D]"])
def test_a_batch_reads_its_states_by_the_one_rule_for_real_arrays(dtype):
    """(Strings were parsed, booleans read as 0/1, dates as day numbers and complex parts
    dropped: a batch ran states that simulate refuses.)"""
    S, params = _rows()
    table = S.astype(np.int64).astype(dtype) if dtype == "M8[D]" else S.astype(dtype)
    with pytest.raises(sg.ShapeError, match="initial state 0: diagonal: a flat state must "
                                            "hold real numbers"):
        case_of("diagonal").sim.simulate_batch(table, 2, params)


def test_a_ragged_table_of_states_names_the_row():
    S, params = _rows()
    with pytest.raises(sg.ShapeError, match="initial state 1: .*shape"):
        case_of("diagonal").sim.simulate_batch([S[0].tolist(), S[1][:-1].tolist()], 2,
                                               params)


def test_batches_and_sweeps_check_their_options():
    """(``options="x"`` reached the kernel: AttributeError 'str' has no 'extrapolate'.)"""
    S, params = _rows()
    sim = case_of("diagonal").sim
    with pytest.raises(sg.InputTypeError, match="diagonal: options must be a NewtonOptions"):
        sim.simulate_batch(S, 2, params, options="x")
    with pytest.raises(sg.InputTypeError, match="diagonal: options must be a NewtonOptions"):
        sg.sweep(sim, S, params, 2, options=3, workers=1)


def test_a_batch_too_large_for_memory_names_steps_and_every():
    S, params = _rows()
    with pytest.raises(sg.TrajectoryTooLargeError, match=r"steps=35184372088832, every=1"):
        case_of("diagonal").sim.simulate_batch(S, 2**45, params)
    with pytest.raises(sg.TrajectoryTooLargeError, match=r"steps=35184372088832"):
        sg.sweep(case_of("diagonal").sim, S, params, 2**45, workers=1)


@pytest.mark.parametrize("change, error, message", [
    ({"combine": "Zip"}, sg.ShapeError, "combine must be one of 'product', 'zip'"),
    ({"steps": None}, sg.InputTypeError, "sweep needs steps="),
    ({"reduce": 3}, sg.InputTypeError, "reduce must be a function"),
    ({"reduce_failures": "yes"}, sg.ShapeError, "reduce_failures must be True or False"),
    ({"client": "localhost"}, sg.InputTypeError, "client must be a dask.distributed.Client"),
    ({"progress": "x"}, sg.ShapeError,
     r"progress must be True, False, None or a function progress\(done, total\), got str"),
])
def test_sweep_checks_every_argument_before_any_run(change, error, message):
    """(A misspelt combine was a ValueError, steps=None a TypeError, a reduce that is not a
    function failed inside the first run, junk client or progress were accepted or failed
    late.)"""
    S, params = _rows()
    kwargs = {"steps": 2, "workers": 1, **change}
    with pytest.raises(error, match=message):
        sg.sweep(case_of("diagonal").sim, S, params, **kwargs)
    with pytest.raises(sg.InputTypeError, match="sweep: sim must be a Simulator"):
        sg.sweep("diagonal", S, params, 2)


def test_sweep_boundary_value_checks_the_system_and_the_solver_options():
    """(A string as the system was an AttributeError; an unknown option a TypeError inside
    the first run.)"""
    step = oscillator().euler_lagrange()
    with pytest.raises(sg.InputTypeError, match="sweep_boundary_value: step must be a "
                                                "discrete system"):
        sg.sweep_boundary_value("x", [0.0], [1.0], 6, {"h": 0.1, "k": 1.0})
    with pytest.raises(sg.InputTypeError, match="unknown option.*tolerance; the solver's "
                                                "options are tol, tol_step, max_iterations"):
        sg.sweep_boundary_value(step, [0.0], [1.0], 6, {"h": 0.1, "k": 1.0}, workers=1,
                                tolerance=1e-9)


def test_the_openmp_team_is_bounded_in_python_too():
    S, params = _rows()
    with pytest.raises(sg.ShapeError, match="threads must be at most 1024"):
        case_of("diagonal").sim.simulate_batch(S, 2, params, threads=10**5)


# --- states, diagnostics, figures -------------------------------------------------------------

def test_project_initial_checks_its_iteration_cap():
    """(A string cap was a TypeError from range(); 0 reported a "non-finite" residual.)"""
    sim = case_of("diagonal").sim
    state = {"x": (0.0, 0.1), "y": (0.0, 0.3)}
    for cap in ("x", 0, -1, 2.5, True):
        with pytest.raises(sg.ShapeError, match="diagonal: max_iterations must be"):
            sim.project_initial(state, {"h": 0.1, "k": 1.0}, max_iterations=cap)


@pytest.mark.parametrize("section, error, message", [
    ([sp.nan, 0], sg.InvalidExpressionError, r"section \(coefficient 0\) is nan"),
    ([sp.I, 0], sg.InvalidExpressionError, r"section \(coefficient 0\) is I"),
    ([sp.Symbol("zeta"), 0], sg.UndeclaredSymbolError, "the section uses symbol.*zeta"),
    (["x", 0], sg.ShapeError, "strings are not coefficients"),
    ("!", sg.ShapeError, "strings are not coefficients"),
    ([True, 0], sg.ShapeError, r"section \(entry 0\)"),
    ([[1, 0]], sg.ShapeError, r"section \(entry 0\)"),
    (None, sg.ShapeError, "a section is a basis index.*got NoneType None"),
    (True, sg.ShapeError, "a section is a basis index.*got bool True"),
    (0.0, sg.ShapeError, "a section is a basis index.*got float 0.0"),
    (1 + 2j, sg.ShapeError, "a section is a basis index.*got complex"),
    (lambda q: 1 / 0, sg.CallableError, "evaluating the section"),
])
def test_noether_sections_are_checked_as_expressions(section, error, message):
    """(Sections were sympified unchecked: SympifyError and TypeError from SymPy, or a
    quantity with nan, I or an undeclared symbol that failed only when evaluated.)"""
    with pytest.raises(error, match=message):
        diagonal().noether(section)


def test_noether_sections_may_use_parameters_and_the_base_point():
    system = diagonal()
    quantity = system.noether(lambda q: [H, q[0] * 0])
    assert quantity.expr.has(H)


def test_diagnostics_name_what_is_wrong():
    """(Junk noether lists, step parameters and part names were TypeError or KeyError;
    ``energy="x"`` was taken as True.)"""
    traj = case_of("diagonal").sim.simulate(case_of("diagonal").flat, 3, {"h": 0.1, "k": 1.0})
    with pytest.raises(sg.SymgroupoidError, match="noether must be a list"):
        traj.conservation_summary(noether=3)
    with pytest.raises(sg.ShapeError, match="energy must be True or False"):
        traj.conservation_summary(energy="x")
    with pytest.raises(sg.SymgroupoidError, match="step_parameter must be the name of a "
                                                  "parameter"):
        traj.energy([1])
    with pytest.raises(sg.ShapeError, match="diagonal: no part named 'nope'") as info:
        traj["nope"]
    assert isinstance(info.value, KeyError)
    with pytest.raises(sg.ShapeError, match="no part named"):
        traj[[1]]
    with pytest.raises(sg.InputTypeError, match="NoetherQuantity.along: trajectory must be"):
        diagonal().noether(0).along("x")


def test_figures_check_parts_and_paths_before_drawing(tmp_path):
    traj = case_of("diagonal").sim.simulate(case_of("diagonal").flat, 3, {"h": 0.1, "k": 1.0})
    with pytest.raises(sg.InputTypeError, match="parts must be a list of strings"):
        sg.plot_trajectory(traj, 3)
    with pytest.raises(sg.ShapeError, match=r"path 'f.xyz' must end in the suffix of a "
                                            r"figure format"):
        sg.plot_trajectory(traj, ["x"], path="f.xyz")
    import matplotlib.pyplot as plt

    figures = plt.get_fignums()
    with pytest.raises(sg.OutputError, match="cannot be written to path .*does not exist"):
        sg.plot_trajectory(traj, ["x"], path=str(tmp_path / "missing" / "f.png"))
    assert plt.get_fignums() == figures  # refused before drawing
    with pytest.raises(sg.ShapeError, match="constraints must be True or False"):
        sg.plot_conservation(traj, constraints="yes")


def test_a_figure_format_whose_writer_needs_a_missing_tool_is_an_output_error(
        tmp_path, monkeypatch):
    """.pgf needs a TeX engine (xelatex): without it matplotlib raised a raw RuntimeError;
    a file already at the path is left as it was."""
    monkeypatch.setenv("PATH", str(tmp_path))  # no TeX engine to be found
    traj = case_of("diagonal").sim.simulate(case_of("diagonal").flat, 3, {"h": 0.1, "k": 1.0})
    target = tmp_path / "fig.pgf"
    target.write_text("an older figure")
    for plot in (lambda: sg.plot_trajectory(traj, ["x"], path=str(target)),
                 lambda: sg.plot_conservation(traj, path=str(target))):
        with pytest.raises(sg.OutputError, match="cannot write the figure"):
            plot()
    assert target.read_text() == "an older figure"


@pytest.mark.parametrize("suffix", ["png", "pdf"])
@pytest.mark.parametrize("failure", ["full disk", "error while closing"])
def test_a_figure_that_cannot_be_written_keeps_the_older_one(tmp_path, monkeypatch, suffix,
                                                             failure):
    """On a full disk savefig wrote the target in place: the older figure was lost and a
    truncated one left (.png), or matplotlib's PDF writer raised a raw AttributeError while
    closing.  Now the figure goes through a temporary file: OutputError, the older file kept,
    nothing else left in the directory."""
    from matplotlib.figure import Figure

    traj = case_of("diagonal").sim.simulate(case_of("diagonal").flat, 3, {"h": 0.1, "k": 1.0})
    real = Figure.savefig

    def full_disk(self, f, **options):
        real(self, f, **options)  # written, then the disk fills
        if failure == "full disk":
            raise OSError(28, "No space left on device")
        try:
            raise OSError(28, "No space left on device")
        except OSError:
            raise AttributeError("'Stream' object has no attribute 'pos'") from None

    monkeypatch.setattr(Figure, "savefig", full_disk)
    target = tmp_path / f"fig.{suffix}"
    target.write_text("an older figure")
    for plot in (lambda: sg.plot_trajectory(traj, ["x"], path=target),
                 lambda: sg.plot_conservation(traj, path=str(target))):
        with pytest.raises(sg.OutputError, match="No space left on device"):
            plot()
    assert target.read_text() == "an older figure"
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary


# --- verification and C output ------------------------------------------------------------------

def test_verify_stationary_checks_system_eps_and_arrows():
    """(A string system was an AttributeError, eps=0 a ZeroDivisionError, arrows given as
    strings were parsed and complex ones lost their imaginary part.)"""
    case = case_of("oscillator")
    traj = case.sim.simulate(case.flat, 4, case.params)
    arrows = traj._layout.arrows(traj.states)
    system = case.step.system
    with pytest.raises(sg.InputTypeError, match="verify_stationary: system must be a discrete "
                                                "system"):
        sg.verify_stationary(traj, "oscillator")
    assert system_argument(case.step, "system") is system
    for eps in (0, -1e-3, float("nan"), 2.0):
        with pytest.raises(sg.ShapeError, match="eps"):
            sg.verify_stationary(traj, system, eps=eps)
    for bad in (arrows.astype(str), arrows.astype(complex) + 1j):
        with pytest.raises(sg.ShapeError, match="the arrows must hold real numbers"):
            sg.verify_stationary(bad, system, case.params)


def test_emit_c_checks_step_path_and_prefix(tmp_path):
    """(A system instead of its step was a TypeError from len(), "" or "/" a ValueError from
    pathlib, a prefix that is not a string an AttributeError, an unwritable target a raw
    OSError; a file name with a quote or a non-ASCII character was written into the
    source's #include: a UnicodeEncodeError, or C that does not compile.)"""
    step = oscillator().euler_lagrange()
    with pytest.raises(sg.InputTypeError, match="emit_c: step must be the StepEquations"):
        sg.emit_c(step.system, tmp_path / "k")
    for path, message in (("", "path must not be empty"), ("/", "path must name the files"),
                          (3, "path must be a path"), (tmp_path / "\x80", "portable|ASCII"),
                          (tmp_path / 'a"b', "ASCII letters")):
        with pytest.raises(sg.ShapeError, match=message):
            sg.emit_c(step, path)
    with pytest.raises(sg.InputTypeError, match="prefix must be a string"):
        sg.emit_c(step, tmp_path / "k", prefix=3)
    (tmp_path / "file").write_text("in the way")
    with pytest.raises(sg.OutputError,
                       match=r"oscillator: path '.*file/k': .*file is not a directory"):
        sg.emit_c(step, tmp_path / "file" / "k")


def test_emit_c_names_the_file_it_could_not_write(tmp_path, monkeypatch):
    """(On a full disk the message named the stem 'k', neither file; in a read-only
    directory the hidden temporary file.)  It names the file, and nothing is left."""
    step = oscillator().euler_lagrange()
    step.emit_c(tmp_path / "warm")  # (templates loaded before the disk fills)

    def full_disk(fd, *args, **kwargs):
        os.close(fd)
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fdopen", full_disk)
    with pytest.raises(sg.OutputError, match=r"cannot write .*/k\.h: No space left on device"):
        sg.emit_c(step, tmp_path / "k")
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith((".", "k"))] == []


def test_generate_c_checks_its_template_cache():
    """(A template cache that is not a path was a TypeError from os.fspath.)"""
    step = oscillator().euler_lagrange()
    for value, error, message in ((3, sg.InputTypeError, "template_cache must be a path"),
                                  (b"dir", sg.InputTypeError, "template_cache must be a path"),
                                  ("", sg.ShapeError, "template_cache must not be empty"),
                                  ("a\0b", sg.ShapeError, "NUL")):
        with pytest.raises(error, match=message):
            sg.codegen.generate_c(step, template_cache=value)


def test_numeric_cayley_refuses_a_singular_point():
    """A group whose basis lets I − ξ/2 be singular (here ξ = x·I) has no cay(x) at x = 2:
    a DomainError naming x (the solve raised LinAlgError)."""

    class Stretch(sg.SO2):
        @classmethod
        def _basis(cls):
            return [sp.eye(2)]

    G = Stretch("s")
    np.testing.assert_allclose(G.numeric_tau([0.5]), np.eye(2) * 1.25 / 0.75)
    with pytest.raises(sg.DomainError, match=r"cay\(x\) is undefined at x = 2\.0"):
        G.numeric_tau([2.0])


def test_a_batch_is_indexed_by_run_number():
    """(A string or an out-of-range run in ``batch.error(b)`` was a raw NumPy error.)"""
    S, params = _rows()
    batch = case_of("diagonal").sim.simulate_batch(S, 2, params)
    assert np.array_equal(batch[-1].states, batch[1].states)
    for bad in ("0", 1.0, None, True):
        with pytest.raises(sg.InputTypeError, match="indexed by run number"):
            batch[bad]
    with pytest.raises(sg.ShapeError, match="run 2 out of range for a batch of 2") as info:
        batch.error(2)
    assert isinstance(info.value, IndexError)
    with pytest.raises(sg.ShapeError, match="out of range"):
        batch.step_indices(-3)


def test_a_scalar_array_is_not_a_list():
    """(A 0-d NumPy array passed the sequence check and failed in ``list()`` with a raw
    TypeError: 'iteration over a 0-d array'.)"""
    plane = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    with pytest.raises(sg.InputTypeError, match="hostile: parameters must be a list or tuple, "
                                                "got ndarray"):
        sg.DiscreteSystem(plane, lambda g: (g.target[0] - g.source[0]) ** 2 / H,
                          parameters=np.array(0.0), name="hostile")
    with pytest.raises(sg.InputTypeError, match="must be a list of strings"):
        sg.PairGroupoid(sg.EuclideanSpace(np.array("x")))


def test_counts_that_size_an_allocation_are_bounded():
    """(``EuclideanSpace.vector("x", 10**12)`` built 10¹² coordinate names — the process
    grew past 8 GB; ``planar_chain(10**9)`` likewise; a sweep with ``workers=10**6``
    started one process per task.)"""
    from symgroupoid import systems

    with pytest.raises(sg.ShapeError, match="dim must be at most 100000, got 1000000000000"):
        sg.EuclideanSpace.vector("x", 10**12)
    with pytest.raises(sg.ShapeError, match="planar_chain: n must be at most 100000"):
        systems.planar_chain(10**9)
    S, params = _rows()
    with pytest.raises(sg.ShapeError, match="workers must be at most"):
        sg.sweep(case_of("diagonal").sim, S, params, 2, workers=10**6)


@pytest.mark.parametrize("metric", [[[], None], [[1, 0], [0]], "ab", [[1, "a"], [0, 1]],
                                    [[[1]]], []])
def test_a_metric_that_is_not_a_matrix_is_named(metric):
    """(``metric=[[], None]`` reached SymPy's matrix parser: a raw ZeroDivisionError.)"""
    plane = sg.PairGroupoid(sg.EuclideanSpace("x y"))
    with pytest.raises(sg.ShapeError, match="nh: the metric must be a matrix"):
        sg.NonholonomicSystem(plane, lambda g: (g.target[0] - g.source[0]) ** 2 / H,
                              distribution=[[1, 1]], parameters=[H], method="energy_momentum",
                              metric=metric, name="nh")


def test_stationarity_is_checked_at_the_scale_of_the_coordinates():
    """(Variations of absolute size ε vanished in the rounding of coordinates of size
    1e150: every path, solution or not, was reported stationary; an action that overflows
    was reported "not stationary" with NaN derivatives.)"""
    system = oscillator()
    params = {"h": 0.1, "k": 1.0}
    q = 1e150 + 1e148 * np.arange(8)  # a straight path: not a solution
    report = sg.verify_stationary(np.stack([q[:-1], q[1:]], axis=1), system, params)
    assert not report and report.scale > 1e290
    with pytest.raises(sg.ShapeError, match="the discrete action is not finite on this "
                                            "trajectory"):
        q = 1e300 * np.arange(1, 9)
        sg.verify_stationary(np.stack([q[:-1], q[1:]], axis=1), system, params)


def test_stationarity_does_not_depend_on_an_angle_offset_of_2_pi_k():
    """(Sized by the coordinates themselves, the variations of a double pendulum's run with
    2π·200 added to its angles were 1.3 rad: "not stationary" for a solution to 5e-12, and
    ``bvp --check`` exited 1.)"""
    from symgroupoid import systems

    system = systems.planar_chain(2)
    sim = system.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.05, "g": 9.81}
    for k in (0, 200, 1000):
        off = 2 * np.pi * k
        run = sim.simulate({"theta1": (0.3 + off, 0.32 + off),
                            "theta2": (0.1 + off, 0.09 + off)}, 40, params)
        report = sg.verify_stationary(run, system)
        assert report, (k, report)
        moved = run.states[:, :4].copy()
        moved[20, 2] += 1e-4  # θ₁ at one step moved: no longer a solution there
        moved[21, 0] += 1e-4
        assert not sg.verify_stationary(moved, system, params), k


def test_a_noether_quantity_that_overflows_is_an_error_not_a_nan():
    """(A section with coefficients near 1e308 returned inf and NaN along the run.)"""
    traj = case_of("diagonal").sim.simulate(case_of("diagonal").flat, 3, {"h": 0.1, "k": 1.0})
    quantity = diagonal().noether([1e308, 1e308])
    with pytest.raises(sg.ShapeError, match="NoetherQuantity.along: the quantity .* is not "
                                            "finite at state 0"):
        quantity.along(traj)



def test_verify_stationary_refuses_a_subnormal_eps():
    """ε/4 of a subnormal ε is 0: refused up front, not a ZeroDivisionError."""
    arrows = np.array([[0.0, 0.1], [0.1, 0.2], [0.2, 0.3]])
    for eps in (5e-324, 1e-310):
        with pytest.raises(sg.DomainError, match="eps must be in"):
            sg.verify_stationary(arrows, oscillator(), params={"h": 0.1, "k": 1.0}, eps=eps)


def test_conservation_summary_refuses_a_0d_array_of_noether_quantities():
    """noether=np.array(0.0) was iterated over (a raw TypeError)."""
    sim = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")),
                            lambda g: (g.target[0] - g.source[0]) ** 2 / 2,
                            name="free").euler_lagrange().compile(backend="numpy")
    traj = sim.simulate({"q": (0.0, 0.1)}, 3, {})
    with pytest.raises(sg.SymgroupoidError, match="noether must be a list"):
        traj.conservation_summary(noether=np.array(0.0))


def test_a_progress_callback_that_raises_gives_a_callable_error() -> None:
    """``sweep(..., progress=type)``: ``type`` is callable but ``type(done, total)`` raises;
    the sweep reports it as a CallableError naming the progress callback (found by the
    thorough hostile sweep profile)."""
    from symgroupoid import systems

    sim = systems.rigid_body().euler_lagrange().compile(backend="numpy")
    W = sg.SO3("W").numeric_tau([0.01, 0.02, -0.01])
    state = sim.state({"W": W})
    params = {str(p): 0.1 for p in sim.equations.parameters}
    with pytest.raises(sg.CallableError, match="progress"):
        sg.sweep(sim, np.vstack([state, state]), params, steps=2, progress=type)


def test_a_section_returning_an_unprintable_array_is_a_shape_error():
    """A Noether section whose entry is an empty 0-dimensional SymPy array (whose repr
    raises IndexError): a ShapeError naming the section, not the IndexError (found by the
    thorough hostile profile, NoetherQuantity on the accel system)."""
    from symgroupoid.derivation import as_scalar

    class Unprintable:
        def __repr__(self):
            raise IndexError("list index out of range")

    with pytest.raises(sg.ShapeError, match="section .*Unprintable that cannot be printed"):
        as_scalar("sys", "section (entry 0)", Unprintable())


# --- boundary values ------------------------------------------------------------------------------

@pytest.mark.parametrize("steps", [4, 6])
def test_constraints_made_dependent_by_the_ends(monkeypatch, steps):
    """(The fast path's Newton raised SingularJacobianError on the diagonal particle between
    (0, 0) and (1, 1): Σ φ_k = Δx − Δy over all arrows is fixed by the ends, so the KKT
    matrix is singular and the multipliers are unique only up to a constant.  The fast path
    now hands over to the inertia-corrected iteration, which regularises them.)"""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    system = diagonal()
    params = {"h": 0.1, "k": 1.0}
    solution = sg.solve_boundary_value(system.euler_lagrange(), (0.0, 0.0), (1.0, 1.0), steps,
                                       params=params)
    nodes = np.asarray(solution.configurations, float)
    assert np.allclose(nodes[[0, -1]], [[0.0, 0.0], [1.0, 1.0]], atol=1e-12, rtol=0)
    assert np.max(np.abs(nodes[:, 0] - nodes[:, 1])) <= 1e-12
    assert solution.residual_norm <= 1e-12
    assert np.isfinite(solution.multipliers).all()
    assert sg.verify_stationary(solution, system, params)


@pytest.mark.filterwarnings("error")
def test_a_time_step_at_the_smallest_double_is_a_named_boundary_value_failure(monkeypatch):
    """(The free rigid body's boundary-value problem at h = 2.2e-308: its Jacobian's entries
    near the largest doubles made LAPACK's eigenvalue routine fail with a raw LinAlgError in
    the inertia test, after RuntimeWarnings of overflow.)  Now the inertia is undetermined,
    the convexification gives up with a named error, and no NumPy warning escapes."""
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    inertia = sp.diag(1, 2, 3)
    Jd = inertia.trace() / 2 * sp.eye(3) - inertia
    body = sg.DiscreteSystem(sg.SO3("W"), lambda a: -(Jd * a.matrix).trace() / H,
                             parameters=[H], name="free_body")
    end = np.array([[0.71837052, -0.53183683, 0.44843438],
                    [0.61849205, 0.78336194, -0.06173864],
                    [-0.31845154, 0.32170432, 0.89168097]])
    end = np.linalg.qr(end)[0] * np.sign(np.diag(np.linalg.qr(end)[1]))  # on SO(3)
    with pytest.raises(sg.SymgroupoidError, match="free_body"):
        sg.solve_boundary_value(body.euler_lagrange(), np.eye(3), end, 6,
                                params={"h": 2.2250738585072014e-308}, tol=1e-10,
                                tol_step=1e-9, max_iterations=30)


def test_a_misspelled_option_or_a_missing_argument_is_named():
    """``NewtonOptions(maxiter=3)`` and a DefinedGroupoid without its identity raised
    Python's TypeError; a named arrow at offset "x" a TypeError from string concatenation;
    ``nearest_element`` of a NaN matrix said "got shape (3, 3)"."""
    with pytest.raises(sg.InputNameError, match="maxiter.*its arguments are tol_residual"):
        sg.NewtonOptions(maxiter=3)
    with pytest.raises(sg.InputNameError, match="DefinedGroupoid: .*missing 7 required"):
        sg.DefinedGroupoid("line", base_names=["q"])
    line = sg.PairGroupoid(sg.EuclideanSpace("q"))
    with pytest.raises(sg.ShapeError, match="named_arrow: offset must be an integer"):
        line.named_arrow("x")
    with pytest.raises(sg.DomainError, match="non-finite entries at"):
        sg.SO3("W").nearest_element(np.full((3, 3), np.nan))


def test_an_expression_code_cannot_evaluate_is_named_in_the_users_coordinates():
    """An undefined function in L, refused when a program is asked for, was shown on the
    term's internal slot coordinates (``f(_s0_0)``) and without the system's name."""
    h = sp.Symbol("h", positive=True)
    f = sp.Function("f")
    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("x")),
        lambda a: h * (((a.target[0] - a.source[0]) / h) ** 2 / 2 - f(a.source[0])),
        parameters=[h], name="undef")
    step = system.euler_lagrange()  # fine for symbolic work
    with pytest.raises(sg.UnsupportedExpressionError,
                       match=r"^undef: the Lagrangian: the subexpression f\(x_\{k-1\}\) is an "
                             r"undefined function"):
        step.compile(backend="numpy")


@pytest.mark.parametrize("section", [np.timedelta64(1, "us"), np.timedelta64(3, "D"),
                                     np.datetime64("2020-01-01")])
def test_a_numpy_time_is_not_a_section_index(section):
    """(NumPy times are integers to ``numbers``: noether(np.timedelta64(1, "us")) raised a
    raw TypeError from int(), found by the hostile suite.)"""
    from symgroupoid import systems

    with pytest.raises(sg.ShapeError, match="a section is a basis index, a list of 3 "
                                            "coefficients or a function of q; got timedelta64"
                       if "timedelta" in type(section).__name__ else "got datetime64"):
        systems.rigid_body().noether(section)


def _spring_L(g):
    (q0,), (q1,) = g.source, g.target
    return (q1 - q0) ** 2 / (2 * H) - H * (q0 ** 2 + q1 ** 2) / 4


@pytest.mark.parametrize("build", [
    lambda: sg.EuclideanSpace(["θ", "theta"]),
    lambda: sg.PairGroupoid(sg.EuclideanSpace("theta")) * sg.PairGroupoid(
        sg.EuclideanSpace("θ")),
    lambda: sg.SO3("θ") * sg.SO3("theta"),
], ids=["one-space", "product", "groups"])
def test_names_written_alike_are_one_name(build):
    """θ, theta and \\theta are all written \\theta, and the step symbols are named by their
    LaTeX: two coordinates so named were one symbol (the Lagrangian silently degenerate)."""
    with pytest.raises(sg.CoordinateNameError, match=r"both written \\theta"):
        build()


@pytest.mark.parametrize("inputs, space, message", [
    ([sp.Symbol("θ"), sp.Symbol("theta")], "x", "declared twice"),
    ([sp.Symbol(r"\theta")], "theta", "has the name of a coordinate"),
    ([sp.Symbol("λ")], "x", r"\(or the multipliers\)"),
    ([sp.Symbol("f")], "x", r"as the discrete forces f\^\{\+\}"),
    ([sp.Symbol("x_1")], "x", r"the name of the coordinate 'x' with a subscript"),
    ([sp.Symbol("theta_a")], "θ", r"the name of the coordinate 'θ' with a subscript"),
], ids=["two-inputs", "input-coordinate", "multipliers", "force-letter", "subscripted",
        "subscripted-alias"])
def test_inputs_written_alike_are_refused(inputs, space, message):
    """Inputs θ and theta became one input: a force h(θ − theta)/2 vanished from the
    residual and runs ignored the inputs given; an input θ on a coordinate theta read the
    coordinate's slots (every run then failed as a Newton divergence)."""
    def forces(g):
        value = H * sum(inputs) / 2
        return [value], [value]

    with pytest.raises(sg.InputNameError, match=message):
        sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace(space)), _spring_L,
                          parameters=[H], forces=forces, inputs=inputs).euler_lagrange()


def test_a_parameter_written_as_the_forces_is_refused():
    """A parameter f of a forced system printed "f^{+}_{1}(g_{k}) = f" beside the forces'
    own f⁺, f⁻; inputs g_1 on SO(3)'s g printed (g_{1})_{k} beside (g_{k})_{12}.  Without
    forces a parameter f prints nothing it could be confused with."""
    f = sp.Symbol("f", positive=True)

    def forces(g):
        return [H * f / 2], [H * f / 2]

    space = sg.PairGroupoid(sg.EuclideanSpace("q"))
    with pytest.raises(sg.ParameterDeclarationError, match="as the discrete forces"):
        sg.DiscreteSystem(space, _spring_L, parameters=[H, f], forces=forces).euler_lagrange()
    free = sg.DiscreteSystem(space, lambda g: _spring_L(g) + f * g.source[0], parameters=[H, f])
    assert len(free.euler_lagrange().residuals) == 1
    u = sp.Symbol("g_1")
    with pytest.raises(sg.InputNameError, match="'g' with a subscript"):
        sg.DiscreteSystem(sg.SO3("g"), lambda g: sp.trace(g.matrix) / H, parameters=[H],
                          forces=lambda g: ([u, 0, 0], [u, 0, 0]), inputs=[u]).euler_lagrange()


def test_input_values_must_satisfy_their_symbols_assumptions():
    """An input declared positive is simplified under it (√(w²) is w), so a run with w < 0
    solved a force the user did not write, silently; an integer input took 0.5.  Refused in
    every entry point, as a parameter's value is."""
    w, n = sp.Symbol("w", positive=True), sp.Symbol("n", integer=True)

    def forces(g):
        value = H / 2 * (sp.sqrt(w ** 2) + n)
        return [value], [value]

    system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), _spring_L,
                               parameters=[H], forces=forces, inputs=[w, n], name="driven")
    sim = system.euler_lagrange().compile(backend="numpy")
    p, start = {"h": 0.05}, {"q": (1.0, 1.0), "w": 1.0, "n": 1}
    good = sim.simulate(start, 3, p, inputs=[1.0, 2.0])
    assert good.states.shape == (4, 6)
    refused = [
        (lambda: sim.simulate(start, 3, p, inputs=[-1.0, 2.0]), "w is declared positive"),
        (lambda: sim.simulate(start, 2, p, inputs=[[1.0, 2.0], [1.0, 0.5]]),
         "n is declared integer, got 0.5 at step 1"),
        (lambda: sim.simulate({**start, "w": -1.0}, 3, p, inputs=[1.0, 2.0]), "in the state"),
        (lambda: sim.step(sim.state(start, p), p, inputs=np.array([0.0, 2.0])),
         "w is declared positive"),
        (lambda: sim.simulate_batch([start, start], 2, p,
                                    inputs=np.array([[[1.0, 2.0]] * 2, [[1.0, 2.0], [1.0, 2.5]]])),
         "in run 1, step 1"),
    ]
    for call, message in refused:
        with pytest.raises(sg.DomainError, match=message):
            call()
    u = np.array([1.0, 2.0])  # an array refilled in place between steps is tested again
    state = sim.step(sim.step(sim.state(start, p), p, inputs=u), p, inputs=u)
    u[0] = -2.0
    with pytest.raises(sg.DomainError, match="got -2.0"):
        sim.step(state, p, inputs=u)


def test_the_observed_order_does_not_overflow_at_large_amplitudes():
    """A linear oscillator has the same order at any amplitude; at 10¹⁶⁰ the error norm
    squared its entries and overflowed: errors inf, "rounding floor (inf)", no order."""
    k = sp.Symbol("k", positive=True)
    osc = sg.ContinuousSystem(sg.EuclideanSpace("q"),
                              lambda q, v: v[0] ** 2 / 2 - k * q[0] ** 2 / 2,
                              parameters=[H, k], name="osc")
    report = sg.convergence_order(osc, "midpoint", ({"q": 1e160}, [0.0]), {"k": 1.0}, 1.0,
                                  [20, 40, 80])
    assert np.isfinite(report.errors).all() and np.isfinite(report.reference_norm)
    assert abs(report.order - 2.0) < 0.05


def test_verify_stationary_evaluates_structure_maps_with_parameters():
    """A groupoid whose sections use a declared parameter derived, compiled and ran, but
    verify_stationary said the parameter "is a symbol with no value in this program": the
    structure maps were built without the parameters (so was Elroy's beanie's reduced
    system, whose connection holds the inertias)."""
    c = sp.Symbol("c", positive=True)
    line = sg.DefinedGroupoid(
        "line", base_names=["q"], fibre_names=["q"], source=lambda a: (a[0],),
        target=lambda a: (a[1],), multiply=lambda a, b: (a[0], b[1]),
        identity=lambda q: (q[0], q[0]), inverse=lambda a: (a[1], a[0]),
        sections=lambda q, t: [(q[0], q[0] + c * t)])

    def L(a):
        q0, q1 = a.coords
        return H * (((q1 - q0) / H) ** 2 / 2 - ((q0 + q1) / 2) ** 2 / 2)

    system = sg.DiscreteSystem(line, L, parameters=[H, c], name="line_oscillator")
    run = system.euler_lagrange().compile(backend="numpy").simulate(
        {"q": (1.0, 0.99)}, 6, {"h": 0.1, "c": 2.0})
    assert sg.verify_stationary(run, system).stationary


def test_a_time_name_is_checked_as_a_coordinate_name_is():
    """TimeGroupoid(…, time_name) checked its name against nothing: a time named as a
    coordinate (or t over a coordinate t) was the same symbol, λ read the multipliers, and
    the state part was "t" whatever the name."""
    pair = sg.PairGroupoid(sg.EuclideanSpace("q"))
    for inner, name in [(pair, "q"), (sg.PairGroupoid(sg.EuclideanSpace("t")), "t"),
                        (sg.PairGroupoid(sg.EuclideanSpace("theta")), "θ"), (pair, "λ"),
                        (pair, "%")]:
        with pytest.raises(sg.CoordinateNameError):
            sg.TimeGroupoid(inner, name)
    timed = sg.TimeGroupoid(pair, "tau")
    assert list(timed.symbols_by_name(0))[0] == "tau"


@pytest.mark.parametrize("name", ["%", "&", r"\end{align}", "a}b", "-1", "lamda", r"\lambda",
                                  "a b", "Delta", "Δ"])
def test_names_that_break_the_printed_equations_are_refused(name):
    """Coordinate names went into the LaTeX as they were: % commented out the rest of a
    row, & made a column, \\end{align} closed the display (pdflatex failed on each); -1
    printed -1_{k}; lamda and \\lambda printed as the multipliers; Delta printed its
    differences as \\Delta \\Delta."""
    with pytest.raises(sg.CoordinateNameError, match="cannot be used"):
        sg.EuclideanSpace([name])


@pytest.mark.parametrize("names", [("theta", "θ"), ("k", "k "), ("x_{k+1}",), ("Delta",),
                                   ("Δ",)])
def test_parameters_written_alike_or_as_step_values_are_refused(names):
    """Parameters theta and θ printed as one; x_{k+1} as a parameter read as the unknown;
    Delta as the differences Δq."""
    params = [sp.Symbol(n) for n in names]

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return (q1 - q0) ** 2 / 2 + sum(params) * q0

    with pytest.raises(sg.ParameterDeclarationError, match="written"):
        sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=params)


def test_a_step_symbol_of_an_unknown_name_or_step_is_a_named_error():
    """(``step.symbol("xx", "k")`` raised a raw KeyError, and ``"k+5"`` on a first-order
    step, whose symbols run from k−1 to k+1, returned a symbol of no equation.)"""
    from symgroupoid import systems

    step = systems.plate_ball().euler_lagrange()
    assert str(step.symbol("x", "k+1")) == "x_{k+1}"
    with pytest.raises(sg.InputNameError, match="no coordinate named 'xx'; known names: g, "
                                                "x, y, lambda"):
        step.symbol("xx", "k")
    with pytest.raises(sg.ShapeError, match="symbols run from k-1 to k\\+1; got k\\+5"):
        step.symbol("x", "k+5")
    with pytest.raises(sg.InputTypeError, match="got float 1.5"):
        step.symbol("x", 1.5)
    with pytest.raises(sg.ShapeError, match="step must look like 'k'"):
        step.symbol("x", "q")


def test_the_lie_poisson_form_of_a_product_of_lie_groups_says_it_is_not_supported():
    """(It said "needs a Lie group, not SO3(W) × SO2(V)", a Lie group.)"""
    from symgroupoid import systems

    with pytest.raises(sg.UnsupportedFeatureError, match="is a product of Lie groups, which "
                                                         "it does not take yet"):
        systems.satellite_with_wheel().lie_poisson()


def test_reconstruction_refuses_a_reduced_run_that_keeps_every_tenth_state():
    """(A rotor on the pair groupoid of SO(2), reduced to SO(2), run with every=10: the
    kept arrows W₀, W₁₀, W₂₀ were composed as consecutive, and the reconstructed angles
    advanced 0.05 a row where the motion advances 0.5, without a word.)"""
    h, inertia = sp.symbols("h I", positive=True)
    pair, group = sg.PairGroupoid(sg.SO2("R")), sg.SO2("W")

    def L(a):
        R0, R1 = sp.Matrix(2, 2, a.coords[:4]), sp.Matrix(2, 2, a.coords[4:])
        return inertia * (1 - (R0.T * R1)[0, 0]) / h

    phi = sg.GroupoidMorphism(pair, group, lambda a: sp.Matrix(2, 2, a.coords[:4]).T
                              * sp.Matrix(2, 2, a.coords[4:]))
    full = sg.DiscreteSystem(pair, L, parameters=[h, inertia], name="rotor")
    red = full.reduce(phi, lagrangian=lambda w: inertia * (1 - w.matrix[0, 0]) / h,
                      name="rotor_red")
    params = {"h": 0.1, "I": 1.0}

    def rot(t):
        return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])

    sim = full.euler_lagrange().compile(backend="numpy")
    run = sim.simulate(sim.state({"R": (rot(0.0), rot(0.05))}), 40, params)
    reduced = red.euler_lagrange().compile(backend="numpy")
    start = red.project(run, params)[0]
    every = reduced.simulate(start, 40, params, every=10)
    with pytest.raises(sg.DomainError, match="keeps only the states of steps 0, 10, 20, 30"):
        red.reconstruct(every, run.states[0], params)
    whole = red.reconstruct(reduced.simulate(start, 40, params), run.states[0], params)
    assert np.allclose(whole, run.states, rtol=0, atol=1e-12)


def test_a_hoelder_system_checks_the_metric_it_keeps():
    """(metric=diag(1, −5, 1) was kept without a check by the Hölder method, for
    conserved_quantities() to use later.)  It is checked as the energy–momentum method
    checks it."""
    h, m = sp.symbols("h m", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y th"))

    def L(a):
        return h * m / 2 * sum(((b - c) / h) ** 2 for b, c in zip(a.target, a.source))

    def Mc(a):
        th = (a.source[2] + a.target[2]) / 2
        return [sp.sin(th) * (a.target[0] - a.source[0])
                - sp.cos(th) * (a.target[1] - a.source[1])]

    Dc = [lambda q: [sp.cos(q[2]), sp.sin(q[2]), 0], [0, 0, 1]]
    with pytest.raises(sg.DomainError, match=r"the metric G_c is not positive definite: "
                                             r"eigenvalues \[-5.0, 1.0, 1.0\]"):
        sg.NonholonomicSystem(G, L, Mc, Dc, parameters=[h, m], metric=sp.diag(1, -5, 1))
    with pytest.raises(sg.ShapeError, match="the metric is 2×2"):
        sg.NonholonomicSystem(G, L, Mc, Dc, parameters=[h, m], metric=sp.eye(2))
    kept = sg.NonholonomicSystem(G, L, Mc, Dc, parameters=[h, m], metric=sp.eye(3) * m)
    assert kept.method == "holder"


def test_a_morphism_map_returning_strings_is_refused():
    """(("a", "b") was sympified into two new free symbols, reported as the morphism's
    parameters.)"""
    line = sg.PairGroupoid(sg.EuclideanSpace("x"))
    with pytest.raises(sg.ShapeError, match="must be numbers or SymPy expressions, got str "
                                            "'a' at coordinate 0"):
        sg.GroupoidMorphism(line, line, lambda a: ("a", "b"))


def test_an_atiyah_connection_outside_the_group_is_refused_at_construction():
    """(A shear [[1, Δr], [0, 1]] for SO(2) was accepted; only check_axioms noticed, as
    "associativity (ab)c = a(bc) fails".)"""
    factors = (sg.SO2("R"), sg.EuclideanSpace("r"))
    with pytest.raises(sg.DomainError, match="the connection must take values in SO2; .*"
                                             "rotation block is not a rotation"):
        sg.AtiyahGroupoid(factors, sg.SO2, connection=lambda s0, s1: sp.Matrix(
            [[1, s1[0] - s0[0]], [0, 1]]))

    def turn(s0, s1):
        a = s1[0] - s0[0]
        return sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])

    sg.AtiyahGroupoid(factors, sg.SO2, connection=turn)  # in the group


@pytest.mark.parametrize("scale", ["1e200", "1e-200"])
def test_a_regular_lagrangian_scaled_by_a_huge_or_tiny_constant_is_not_degenerate(scale):
    """(Its Jacobian's norms overflowed or underflowed in the regularity checks: "singular at
    every sampled point (rank 0 of 1)" at 1e200, "the Euler–Lagrange equations vanish
    identically" at 1e-200, where 1e±150 ran.)  A constant factor leaves the motion as
    it is."""
    h = sp.Symbol("h", positive=True)
    c = sp.Float(scale)

    def L(g):
        (x0,), (x1,) = g.source, g.target
        return c * ((x1 - x0) ** 2 / (2 * h) - h * (x0 + x1) ** 2 / 8)

    G = sg.PairGroupoid(sg.EuclideanSpace(["x"]))
    final = [sg.DiscreteSystem(G, lagrangian, parameters=[h], name="scaled").euler_lagrange()
             .compile(backend="numpy").simulate({"x": (0.0, 0.1)}, 3, {"h": 0.1}).states[-1]
             for lagrangian in (L, lambda g: L(g) / c)]
    np.testing.assert_allclose(final[0], final[1], rtol=1e-13)


@pytest.mark.parametrize("call, error, message", [
    (lambda: systems.link_chain(10 ** 6), sg.ShapeError, "at most 100000"),
    (lambda: systems.attitude_groupoid(2 ** 70), sg.ShapeError, "at most 100000"),
    (lambda: systems.attitude_groupoid(None), sg.ShapeError, "must be an integer"),
    (lambda: systems.chain_inertia(float("nan")), sg.ShapeError, "finite integer"),
    (lambda: systems.chain_inertia("1.5"), sg.ShapeError, "must be an integer"),
    (lambda: systems.chain_inertia(-3), sg.ShapeError, "at least 1"),
    (lambda: systems.discrete_inertia(float("inf"), 1, 1), sg.DomainError, "real and finite"),
    (lambda: systems.discrete_inertia("abc", 1, 1), sg.InputTypeError, "SymPy expression"),
    (lambda: systems.discrete_inertia(1, -1, 1), sg.DomainError, "I2 must not be negative"),
    (lambda: systems.vee(sp.eye(2)), sg.ShapeError, "3 × 3 matrix"),
    (lambda: systems.vee({"a": 1}), sg.ShapeError, "3 × 3 matrix"),
    (lambda: systems.centres_of_mass(None), sg.InputTypeError, "list or tuple"),
    (lambda: systems.summed_forces([3]), sg.InputTypeError, "must be a function"),
], ids=["link-chain", "attitudes-huge", "attitudes-none", "inertia-nan", "inertia-str",
        "inertia-negative", "moment-inf", "moment-str", "moment-negative", "vee-2x2",
        "vee-dict", "centres-none", "summed-int"])
def test_the_systems_helpers_check_their_arguments(call, error, message):
    """link_chain(10⁶) and attitude_groupoid(2⁷⁰) ran for minutes; chain_inertia(nan)
    returned body 0's inertia, discrete_inertia(inf, 1, 1) a matrix of nan and oo, vee and
    centres_of_mass bare TypeError/IndexError/KeyError (found by a fuzzer of the API)."""
    with pytest.raises(error, match=message):
        call()


def test_rounding_floor_checks_its_arguments():
    from symgroupoid.diagnostics import rounding_floor

    with pytest.raises(sg.DomainError, match="must be finite"):
        rounding_floor(np.array([1.0, np.nan, 1.0]), np.arange(3))  # NaN floors before
    with pytest.raises(sg.ShapeError, match="step_indices must be an array of real"):
        rounding_floor(np.ones(3), None)
    with pytest.raises(sg.ShapeError, match="values must be an array of real"):
        rounding_floor("abc", np.arange(3))
    assert rounding_floor([2.0, -3.0, 2.5], [10, 14, 19])[1] == pytest.approx(
        np.finfo(float).eps * 3 * 2)


def test_digits_grouped_by_underscores_are_not_numbers(tmp_path):
    """Python's float() reads 1_0 as 10 and 0_5 as 5: --params h=1_0 ran with h = 10 and a
    trajectory .csv with a value 0_5 loaded it as 5, where 0x10 was refused."""
    # white-box: the CLI's number reader, which every numeric option goes through
    from symgroupoid.cli._inputs import parse_number

    for text in ("1_0", "0_01", "0x10", "1j"):
        with pytest.raises(sg.SymgroupoidError, match="is not a number"):
            parse_number(text, "--params h")
    assert parse_number(" 0.01", "--params h") == 0.01
    sim = oscillator().euler_lagrange().compile(backend="numpy")
    path = tmp_path / "run.csv"
    sim.simulate({"q": (1.0, 0.99)}, 3, {"h": 0.1, "k": 1.0}).save(path)
    lines = path.read_text().splitlines()
    cells = lines[2].split(",")
    cells[1] = "0_5"
    lines[2] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(sg.TrajectoryFileError, match="'0_5': digits grouped by '_'"):
        sg.Trajectory.load(path, sim)


def test_options_and_constants_found_by_the_api_fuzzer_are_checked():
    """ActionGroupoid(check=None) skipped the action check as check=False does; a
    misspelled parameter of check_axioms was ignored; latex(width=10**400) overflowed;
    step.symbol and step.jacobian with arrays, check_on_graph(None) and NamedMatrix of a
    3-d array or NaN entries gave bare or SymPy errors, or a matrix of nan."""
    W = sg.SO3("W")
    squared = lambda p, R: list(R * R * sp.Matrix(p))  # noqa: E731 - not an action
    with pytest.raises(sg.ShapeError, match="check must be True or False"):
        sg.ActionGroupoid(sg.EuclideanSpace.vector("G", 3), W, squared, check=None)
    with pytest.raises(sg.AxiomError):
        sg.ActionGroupoid(sg.EuclideanSpace.vector("G", 3), W, squared, check=True)
    with pytest.raises(sg.ParameterError, match="zz are not symbols of its structure maps"):
        sg.check_axioms(W, parameters={"zz": 1})
    step = systems.rigid_body().euler_lagrange()
    with pytest.raises(LatexOptionError, match="width must be a number of points"):
        step.latex(width=10 ** 400)
    with pytest.raises(sg.InputTypeError, match="a symbol's name must be a string"):
        step.symbol(np.array(["x", "y"]), "k")
    with pytest.raises(sg.ShapeError, match="substitute must be True or False"):
        step.jacobian(np.array([1, 2]))
    with pytest.raises(sg.InputTypeError, match="groupoid must be a Groupoid"):
        systems.rigid_body().noether(0).check_on_graph(None)
    with pytest.raises(sg.InputTypeError, match="what sympy.Matrix takes"):
        sg.NamedMatrix(np.zeros((2, 3, 4)), name="J")
    with pytest.raises(sg.DomainError, match="real and finite"):
        sg.NamedMatrix([[sp.nan]], name="J")
    assert sg.NamedMatrix([[1, sp.Symbol("a")]], name="J").latex_name == "J"


@pytest.mark.parametrize("name", ["x_k", "theta_k", "x_j", "q_{k+1}"])
def test_a_coordinate_written_as_a_value_at_a_step_is_refused(name):
    """A coordinate x_k printed (x_{k})_{k+1} (a parameter so named was already refused)."""
    with pytest.raises(sg.CoordinateNameError, match="as a value at a step is"):
        sg.EuclideanSpace(name)
    assert sg.EuclideanSpace("x_kin").names == ("x_kin",)


def test_a_nonholonomic_system_refuses_what_it_does_not_have():
    """nh.legendre(), .noether(0), .lie_poisson() and .reduce(m) were AttributeErrors."""
    knife = sg.NonholonomicSystem(
        sg.PairGroupoid(sg.EuclideanSpace("x y")),
        lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * H),
        lambda g: [g.target[1] - g.source[1]], [[1, 0]], parameters=[H])
    for call in (knife.legendre, knife.lie_poisson, lambda: knife.noether(0),
                 lambda: knife.reduce(None)):
        with pytest.raises(sg.UnsupportedFeatureError, match="conserved_quantities"):
            call()


def test_a_type_error_raised_inside_a_checked_call_passes_as_it_is():
    """checked_call renames only the binding's TypeError: one raised inside the function,
    whose arguments bind, passes unchanged (else a defect inside would read as the caller's
    misspelled keyword)."""
    # white-box: the wrapper itself, on a function that fails inside
    from symgroupoid._arguments import checked_call

    def inside(a, *, b=1):
        return len(a) + b

    checked = checked_call(inside, "inside")
    assert checked("xy", b=2) == 4
    with pytest.raises(TypeError, match="has no len") as info:
        checked(5)
    assert not isinstance(info.value, sg.SymgroupoidError)
    with pytest.raises(sg.InputNameError, match=r"^inside: .*'c'; its arguments are a, b$"):
        checked("xy", c=3)
