"""Diagnostics along trajectories (symgroupoid.diagnostics), figures, trajectory views and
summaries, and the projection of initial states onto the constraints."""

from __future__ import annotations

import functools
import sys

import numpy as np
import pytest
import sympy as sp
from kernel_support import compiled, constraint_function, initial_state, seed_system

import symgroupoid as sg
from symgroupoid.diagnostics import ConservationSummary, DiagnosticsError, rounding_floor
from symgroupoid.runtime import ProjectionError

h = sp.Symbol("h", positive=True)
EPS = float(np.finfo(float).eps)


@functools.cache
def plate_ball_run(steps: int = 400):
    sim = compiled("plate_ball")
    params = {"h": 0.01, "r": 1.0, "Omega": 0.1, "c": 0.02}
    return sim.simulate(initial_state(sim, "plate_ball"), steps, params)


@functools.cache
def spherical_pendulum():
    """The tutorial's system: R³ pair groupoid, φ = ½(|q₀|² + |q₁|²) − 1, gravity along z."""
    grav = sp.Symbol("g", positive=True)

    def L(a):
        q0, q1 = sp.Matrix(a.source), sp.Matrix(a.target)
        v, mid = (q1 - q0) / h, (q0 + q1) / 2
        return h * (v.dot(v) / 2 - grav * mid[2])

    def phi(a):
        q0, q1 = sp.Matrix(a.source), sp.Matrix(a.target)
        return [(q0.dot(q0) + q1.dot(q1)) / 2 - 1]

    system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y z")), L,
                               constraints=phi, parameters=[h, grav], name="sph")
    return system, system.euler_lagrange().compile(backend="numpy")


PENDULUM = {"h": 0.05, "g": 9.81}


@functools.cache
def pendulum_run(steps: int = 400):
    system, sim = spherical_pendulum()
    q0 = np.array([np.sin(1.0), 0.0, -np.cos(1.0)])
    q1 = q0 + PENDULUM["h"] * np.array([0.0, 1.5, 0.0])
    start = {"x": (q0[0], q1[0]), "y": (q0[1], q1[1]), "z": (q0[2], q1[2])}
    return sim.simulate(sim.project_initial(start, PENDULUM), steps, PENDULUM)


# --- momenta, energy, constraints, Noether -----------------------------------------------------

def test_momenta_equal_the_legendre_transforms_and_match_along_the_solution():
    """F±L from the graph equal system.legendre() (SymPy) at every state, and the DEL
    F⁺L(g_k, λ_k) = F⁻L(g_{k+1}, λ_{k+1}) holds along the compiled run."""
    traj = plate_ball_run()
    m = traj.momenta()
    assert m.minus.shape == m.plus.shape == (len(traj), 5)
    legendre = seed_system("plate_ball").legendre()
    p = list(traj.parameters.values())
    for k in (0, 1, 137, len(traj) - 1):
        minus, plus = legendre.evaluate(traj.states[k, :13], traj.states[k, 13:], p)
        np.testing.assert_allclose(m.minus[k], minus, rtol=0, atol=1e-13)
        np.testing.assert_allclose(m.plus[k], plus, rtol=0, atol=1e-13)
    scale = np.abs(m.plus).max()
    assert np.abs(m.matching()).max() < 1e-12 * scale
    assert np.abs(m.plus[:-1] - m.plus[1:]).max() > 1e-6 * scale  # not trivially constant


def test_energy_of_the_adaptive_time_step_is_conserved_to_rounding():
    """On R×R×(Q×Q) without a step constraint (seed 000 Example 6.1), E = −∂L/∂t₁ equals
    ½v² − κ cos q_mid (docs/conventions.md §7) and stays at the rounding floor while the
    step varies."""
    kappa = sp.Symbol("kappa", positive=True)

    def L(g):
        dt, q0, q1 = g.t1 - g.t0, g.source[0], g.target[0]
        return dt * (((q1 - q0) / dt) ** 2 / 2 + kappa * sp.cos((q0 + q1) / 2))

    system = sg.DiscreteSystem(sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q"))), L,
                               parameters=[kappa], name="adaptive")
    sim = system.euler_lagrange().compile(backend="numpy")
    traj = sim.simulate(np.array([0.0, 0.05, 1.0, 1.02]), 300, {"kappa": 4.0})
    E = traj.energy()
    t, q = traj["t"], traj["q"]
    v, mid = np.diff(q) / np.diff(t), (q[:-1] + q[1:]) / 2
    np.testing.assert_allclose(E, v**2 / 2 - 4.0 * np.cos(mid), rtol=1e-13)
    h = np.diff(t)
    assert h.min() > 0 and t[-1] > 0.9 * 300 * 0.05  # forward in time, never reversed
    assert np.ptp(h) > 0.01 * h.mean()  # the step does vary
    # each E_k is computed from its step h_k = t_k − t_{k−1}, rounded relative to |t_k|
    # (absolute times), hence off by up to v²·ε|t_k|/h_k besides ε|E|: a random walk of both
    eps = np.finfo(float).eps
    per_step = (v**2 * eps * np.abs(t[1:]) / h) ** 2 + rounding_floor(E, [0, 1])[-1] ** 2
    assert np.all(np.abs(E - E[0]) <= 8 * np.sqrt(np.cumsum(per_step)))
    assert sg.diagnostics.energy_label(traj) == "E = −∂L/∂t₁"


def test_energy_of_the_discrete_rigid_body_is_conserved_to_rounding():
    """Moser–Veselov: E_d = −∂L_d/∂h = −tr(J_d W)/h² is an exact invariant of the step."""
    sim = compiled("rigid_body")
    traj = sim.simulate(initial_state(sim, "rigid_body"), 2000,
                        {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0})
    E = traj.energy()
    Jd = np.diag([2.0, 1.0, 0.0])  # tr(I)/2 − I
    np.testing.assert_allclose(E, -np.einsum("ij,kji->k", Jd, traj["W"]) / 0.01**2,
                               rtol=1e-14)
    assert np.abs(E - E[0]).max() < 50 * rounding_floor(E, traj.step_indices)[-1]


def test_fixed_step_energy_is_the_h_derivative_and_stays_bounded():
    """E_d = −∂L_d/∂h = ½|v|² + g·z_mid for the midpoint pendulum: its oscillation over the
    second half of a run is no larger than over the first (no drift)."""
    traj = pendulum_run()
    E = traj.energy()
    q = np.stack([traj["x"], traj["y"], traj["z"]], axis=1)  # q_0 … q_{N+1}
    v = np.diff(q, axis=0) / PENDULUM["h"]
    mid = (q[:-1] + q[1:]) / 2
    np.testing.assert_allclose(E, 0.5 * (v * v).sum(1) + PENDULUM["g"] * mid[:, 2],
                               rtol=1e-12, atol=1e-12)
    half = len(E) // 2
    assert np.ptp(E[half:]) < 1.5 * np.ptp(E[:half])
    assert np.ptp(E) < 0.05 * np.abs(E).max()


def _terms(expr: sp.Expr, at: dict) -> float:
    """The expression with every sum and product taken over absolute values, at ``at``: the
    scale of its rounding errors."""
    if expr.is_Add or expr.is_Mul:
        parts = [_terms(a, at) for a in expr.args]
        return float(sum(parts)) if expr.is_Add else float(np.prod(parts))
    return abs(float(expr.xreplace(at)))


def test_noether_quantity_along_a_trajectory_is_constant():
    """The rotation about z is a symmetry of the spherical pendulum (seed 000 Thm 4.9):
    nq.along(traj) equals nq.evaluate state by state and is constant to rounding."""
    system, _ = spherical_pendulum()
    traj = pendulum_run()
    nq = system.noether(lambda q: [-q[1], q[0], 0])
    assert nq.is_symmetry
    F = nq.along(traj)
    assert F.shape == (len(traj),)
    p = [traj.parameters[str(s)] for s in nq.parameters]
    for k in (0, 57, len(traj) - 1):
        # the same expression, evaluated in another order: equal to a few roundings of its
        # terms (which cancel: their magnitudes sum to 4-14 against F ≈ 1.26)
        at = dict(zip([*nq.arrow, *nq.multipliers, *nq.parameters],
                      [*traj.states[k], *p]))
        assert F[k] == pytest.approx(nq.evaluate(traj.states[k, :6], traj.states[k, 6:], p),
                                     rel=0, abs=4 * np.finfo(float).eps * _terms(nq.expr, at))
    assert abs(F[0]) > 0.1
    assert np.ptp(F) < 1e-13
    # a quantity that is not conserved is reported as such, not silently constant
    other = system.noether(0)
    assert not other.is_symmetry and np.ptp(other.along(traj)) > 1e-3


def test_constraint_residuals_along_a_trajectory():
    traj = plate_ball_run()
    phi = traj.constraint_residuals()
    assert phi.shape == (len(traj), 3)
    reference = constraint_function("plate_ball")
    p = list(traj.parameters.values())
    for k in (0, 200, len(traj) - 1):
        np.testing.assert_allclose(phi[k], np.ravel(reference(traj.states[k], p)), atol=1e-16)
    assert np.abs(phi).max() < 1e-13


@functools.cache
def second_order():
    def L(a, b):
        q0, q1, q2 = sp.Matrix(a.source), sp.Matrix(a.target), sp.Matrix(b.target)
        acc = (q2 - 2 * q1 + q0) / h**2
        return h * (acc.dot(acc) / 2 + q1.dot(q1) / 2 + sp.cos(q1[0]) * q2[1] / 5)

    system = sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), L,
                                  parameters=[h], name="so2")
    return system, system.euler_lagrange().compile(backend="numpy")


def test_diagnostics_of_a_second_order_system_match_with_lag_two():
    """Second order: F⁺L(state k) = F⁻L(state k+2) along a run (seed 001 §4), and the graph
    momenta equal system.legendre()."""
    system, sim = second_order()
    traj = sim.simulate({"x": (0.0, 0.01, 0.03, 0.06), "y": (1.0, 1.0, 0.99, 0.97)}, 60,
                        {"h": 0.1})
    m = traj.momenta()
    legendre = system.legendre()
    scale = np.abs(m.plus).max()
    terms = 1 / 0.1**3  # |q|·h/h⁴: the size of the terms that cancel in each momentum
    for k in (0, 30):
        minus, plus = legendre.evaluate(traj.states[k], [], [0.1])
        np.testing.assert_allclose(m.minus[k], minus, rtol=0, atol=1e3 * EPS * terms)
        np.testing.assert_allclose(m.plus[k], plus, rtol=0, atol=1e3 * EPS * terms)
    assert np.abs(m.matching(2)).max() < 1e-13 * scale
    assert np.abs(m.matching(1)).max() > 1e-3 * scale  # lag 2, not 1
    summary = traj.conservation_summary()
    assert summary.momentum_matching < 1e-13 * summary.momentum_scale
    with pytest.raises(DiagnosticsError, match="first-order"):
        traj.energy()


def test_energy_differentiates_by_the_identified_step():
    """A step named τ, not h: the continuous limit identifies τ as the step, so the energy is
    −∂L/∂τ without being told (docs/conventions.md §19); step_parameter= still names the
    parameter to differentiate by, and an unknown name is an error."""
    tau, k = sp.symbols("tau k", positive=True)
    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a: tau * (((a.target[0] - a.source[0]) / tau) ** 2 / 2 - k * a.target[0] ** 2 / 2),
        parameters=[tau, k], name="osc")
    sim = system.euler_lagrange().compile(backend="numpy")
    traj = sim.simulate({"q": (1.0, 1.0)}, 50, {"tau": 0.1, "k": 1.0})
    with pytest.raises(DiagnosticsError, match="'dt' is not a parameter"):
        traj.energy(step_parameter="dt")
    E = traj.energy(step_parameter="tau")  # −∂L/∂τ = ½((q₁ − q₀)/τ)² + ½k q₁²
    q = traj["q"]
    np.testing.assert_allclose(E, 0.5 * (np.diff(q) / 0.1) ** 2 + 0.5 * q[1:] ** 2, rtol=1e-13)
    np.testing.assert_array_equal(traj.energy(), E)
    summary = traj.conservation_summary()
    assert [d.name for d in summary.quantities] == ["E_d = −∂L_d/∂tau"]
    assert summary.constraint_residual is None
    np.testing.assert_allclose(traj.energy(step_parameter="k"), 0.1 * q[1:] ** 2 / 2)  # by name


def test_conservation_summary():
    system, _ = spherical_pendulum()
    traj = pendulum_run()
    Lz = system.noether(lambda q: [-q[1], q[0], 0])
    summary = sg.diagnostics.conservation_summary(traj, noether={"L_z": Lz})
    assert isinstance(summary, ConservationSummary)
    names = [q.name for q in summary.quantities]
    assert names == ["E_d = −∂L_d/∂h", "L_z"]
    energy, lz = summary.quantities
    assert lz.max_drift < 1e-13 and energy.max_drift > 1e-6
    size = Lz.term_magnitude(traj).max()
    assert lz.final_floor == pytest.approx(np.finfo(float).eps * (lz.scale * np.sqrt(400)
                                                                   + size))
    assert summary.constraint_residual < 1e-14
    assert summary.momentum_matching < 1e-12
    lines = summary.lines()
    assert all(isinstance(s, str) for s in lines) and len(lines) == 5
    assert lines[0] == "sph: 400 steps" and lines[2].startswith("L_z: max |Q_k − Q_0| = ")
    assert str(summary) == "\n".join(lines)
    # sections are turned into Noether quantities by the system; unverified ones are marked
    marked = traj.conservation_summary(noether=[0])
    assert marked.quantities[-1].name.endswith("(not a verified symmetry)")


def test_a_second_order_summary_says_why_it_has_no_energy():
    """The energy of a second-order system is not defined here: traj.energy() says so, and
    the summary left it out without a word, though its time step was declared."""
    h = sp.Symbol("h", positive=True)

    def L(g1, g2):
        (q0,), (q1,), (q2,) = g1.source, g1.target, g2.target
        return h * (((q2 - 2 * q1 + q0) / h ** 2) ** 2 / 2 + q1 ** 2 / 2)

    system = sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h],
                                  time_step=h, name="spline")
    traj = system.euler_lagrange().compile(backend="numpy").simulate(
        {"q": (0.0, 0.1, 0.2, 0.3)}, 5, {"h": 0.1})
    with pytest.raises(DiagnosticsError, match="first-order systems"):
        traj.energy()
    lines = traj.conservation_summary().lines()
    assert lines[-1] == ("energy: not included (the discrete energy is defined for "
                         "first-order systems, L: G → R, only)")


def test_rounding_floor_is_eps_scale_sqrt_k():
    values = np.array([2.0, -3.0, 2.5])
    floor = rounding_floor(values, np.array([10, 14, 19]))
    eps = np.finfo(float).eps
    np.testing.assert_allclose(floor, [0.0, eps * 3 * 2, eps * 3 * 3])


def test_rounding_floor_takes_the_size_of_the_terms():
    values = np.array([2.0, -3.0, 2.5])
    floor = rounding_floor(values, np.array([10, 14, 19]), np.array([1e3, 2e3, 5.0]))
    np.testing.assert_allclose(floor, [0.0, EPS * (3 * 2 + 2e3), EPS * (3 * 3 + 2e3)])


def test_a_momentum_far_from_the_origin_rounds_at_the_size_of_its_terms():
    """p = (x₁ − x₀)/h at x ≈ 1000 is a difference of terms 10⁵ times |p|: it drifts by
    rounding far above ε·|p|·√N, and within ε·(|p|·√N + S), S the size of its terms; so
    does the energy."""
    def L(a):
        (x0,), (x1,) = a.source, a.target
        return h * ((x1 - x0) / h) ** 2 / 2

    system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x")), L, parameters=[h],
                               name="drifting")
    sim = system.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01}
    traj = sim.simulate({"x": (1000.0, 1000.0 + 0.01 * 0.731)}, 300, params)
    p = system.noether(0)
    drift = traj.conservation_summary(noether=[p]).quantities[-1]
    size = p.term_magnitude(traj)
    assert size.min() > 1e5 * np.abs(p.along(traj)).max()
    assert drift.max_drift > 10 * EPS * drift.scale * np.sqrt(300)  # far above ε·|p|·√N
    assert drift.max_drift <= drift.final_floor
    assert drift.final_floor == pytest.approx(EPS * (drift.scale * np.sqrt(300) + size.max()))
    energy = traj.conservation_summary().quantities[0]
    sizes = sg.diagnostics.energy_magnitude(traj)
    assert sizes.min() > 1e5 * energy.scale
    assert energy.final_floor == pytest.approx(EPS * (energy.scale * np.sqrt(300)
                                                      + sizes.max()))
    assert energy.max_drift <= energy.final_floor


def test_diagnostics_need_the_system():
    """Equations without a system (the Lie–Poisson reconstruction) give a clear error."""
    lp = seed_system("rigid_body").lie_poisson()
    sim = lp.reconstruction.compile(backend="numpy")
    traj = sim.simulate(np.array([0.3, 0.2, 0.1]), 3, {"h": 0.01, "I1": 1.0, "I2": 2.0,
                                                       "I3": 3.0})
    with pytest.raises(DiagnosticsError, match="no system attached"):
        traj.momenta()


def test_noether_along_refuses_a_foreign_trajectory():
    system, _ = spherical_pendulum()
    nq = system.noether(lambda q: [-q[1], q[0], 0])
    with pytest.raises(sg.ShapeError, match="is a run of .*plate"):
        nq.along(plate_ball_run())


# --- figures -----------------------------------------------------------------------------------

def test_figures_are_written(tmp_path):
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    system, _ = spherical_pendulum()
    traj = pendulum_run()
    Lz = system.noether(lambda q: [-q[1], q[0], 0])
    fig = sg.plot_conservation(traj, energy=True, momenta=[Lz], path=tmp_path / "c.png")
    assert isinstance(fig, Figure) and len(fig.axes) == 2  # drifts, constraints
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("rounding floor" in s for s in labels) and any("Noether" in s for s in labels)
    fig = traj.plot(["x", "z"], path=tmp_path / "t.png")
    assert len(fig.axes) == 2 and (tmp_path / "t.png").stat().st_size > 1000
    x_line = fig.axes[0].get_lines()[0]
    assert len(x_line.get_xdata()) == len(traj["x"]) == traj.steps + 2
    fig = compiled("plate_ball") and plate_ball_run().plot()  # matrix parts entry by entry
    assert len(fig.axes) == 4 and len(fig.axes[2].get_lines()) == 9
    with pytest.raises(KeyError, match="no part named 'w'"):
        traj.plot(["w"])


def test_figure_legends_sit_beside_the_panels_and_name_exact_zeros(tmp_path):
    """(Legends at loc="best" covered the curves of the pendulum's figure; drifts that are
    exactly 0 vanished from the log axis without a word; a run of 0 steps drew an empty
    panel.)  Legends are outside the axes, on the right; a drift that is exactly 0 at some
    states says so in its entry ("gaps"), one that is 0 at every state says there is no
    curve, and a single state is drawn as a marker and named."""
    pytest.importorskip("matplotlib")
    system, _ = spherical_pendulum()
    traj = pendulum_run()
    Lz = system.noether(lambda q: [-q[1], q[0], 0])
    fig = sg.plot_conservation(traj, energy=True, momenta={"L_z": Lz})
    fig.canvas.draw()
    for ax in fig.axes:
        legend, box = ax.get_legend().get_window_extent(), ax.get_window_extent()
        assert legend.x0 >= box.x1  # beside the panel, never over its curves
    rest = compiled("rigid_body")
    state = rest.state({"W": np.eye(3)})
    params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    still = rest.simulate(state, 20, params)  # at rest: E_d is exactly E_0 at every step
    labels = [t.get_text() for t in sg.plot_conservation(still, step_parameter="h")
              .axes[0].get_legend().get_texts()]
    assert "exactly Q_0 at every step: no curve" in labels[0]
    single = sg.plot_conservation(rest.simulate(state, 0, params), step_parameter="h")
    labels = [t.get_text() for t in single.axes[0].get_legend().get_texts()]
    assert "one state: no drift to show" in labels[0]
    assert single.axes[0].get_lines()[0].get_marker() == "o"


def test_plotting_without_matplotlib_names_the_missing_package(monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.figure", None)
    with pytest.raises(sg.plotting.MissingDependencyError, match="matplotlib"):
        pendulum_run().plot()


# --- trajectories: cached views, summaries -------------------------------------------------------

def test_named_views_are_cached_and_read_only():
    traj = plate_ball_run()
    x = traj["x"]
    assert traj["x"] is x and traj.multipliers is traj["lambda"] is traj["λ"]
    np.testing.assert_array_equal(x, traj._layout.view(traj.states, "x"))
    with pytest.raises(ValueError):
        x[0] = 1.0


def test_repr_and_html_summaries():
    traj = plate_ball_run()
    text = repr(traj)
    assert text.startswith("<Trajectory 'plate_ball': 400 steps (401 states kept)")
    assert "g 3×3" in text and "h=0.01" in text and "Newton" in text
    page = traj._repr_html_()
    assert page.startswith("<table>") and "plate_ball" in page and "lambda 3" in page
    every = compiled("plate_ball").simulate(traj.states[0], 100, traj.parameters, every=10)
    assert "every 10" in repr(every)


# --- initial states: projection onto the constraints ----------------------------------------------

def test_project_initial_gives_a_consistent_state():
    """An inconsistent plate-ball start (g = identity) is moved within the α-fibre of its
    source onto φ = 0: the source (x_{k-1}, y_{k-1}) and the multipliers are kept."""
    sim = compiled("plate_ball")
    params = {"h": 0.01, "r": 1.0, "Omega": 0.5, "c": 0.3}
    start = {"x": (0.1, 0.11), "y": (0.2, 0.204), "g": np.eye(3), "lambda": [0.1, -0.2, 0.05]}
    with pytest.raises(sg.ShapeError, match="violates the constraints"):
        sim.state(start, params)
    state = sim.project_initial(start, params)
    assert np.abs(np.ravel(constraint_function("plate_ball")(state, list(params.values())))
                  ).max() < 1e-15
    assert tuple(state[:2]) == (0.1, 0.2)
    np.testing.assert_array_equal(state[13:], [0.1, -0.2, 0.05])
    W = state[4:13].reshape(3, 3)
    np.testing.assert_allclose(W @ W.T, np.eye(3), atol=1e-14)
    assert np.linalg.norm(W - np.eye(3)) < 0.1  # a nearby zero, not an arbitrary one
    sim.simulate(state, 10, params)  # accepted as an initial state
    # already consistent: unchanged up to rounding; multipliers default to zero
    again = sim.project_initial(state, params)
    np.testing.assert_allclose(again, state, atol=1e-15)
    zero = sim.project_initial({k: v for k, v in start.items() if k != "lambda"}, params)
    np.testing.assert_array_equal(zero[13:], 0.0)


def test_project_initial_reports_constraints_without_a_nearby_zero():
    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a: h * ((a.target[0] - a.source[0]) / h) ** 2 / 2,
        constraints=lambda a: [(a.source[0] ** 2 + a.target[0] ** 2) / 2 - 1],
        parameters=[h], name="circle")
    sim = system.euler_lagrange().compile(backend="numpy")
    ok = sim.project_initial({"q": (1.0, 1.1)}, {"h": 0.1})
    assert ok[1] == pytest.approx(1.0, abs=1e-15) and ok[0] == 1.0
    with pytest.raises(ProjectionError, match="could not project"):
        sim.project_initial({"q": (2.0, 2.0)}, {"h": 0.1})  # needs q₁² = −2


def test_project_initial_is_first_order_only():
    _, sim = second_order()
    with pytest.raises(ProjectionError, match="first-order"):
        sim.project_initial({"x": (0.0, 0.01, 0.03, 0.06), "y": (1.0, 1.0, 0.99, 0.97)},
                            {"h": 0.1})


def test_a_declared_step_the_continuous_limit_refutes_gives_no_energy():
    """(L_d = L(q̄, Δq/h), without the factor h, declared with time_step=h: the same motion
    as the midpoint rule, but −∂L_d/∂h = Δq²/h³ ≈ 100 was reported as its energy, drifting
    by 50 %, where the energy is 0.995 and kept to 2e-13.)  The energy checks a declared
    step with the continuous limit (docs/conventions.md §19) and refuses one it refutes;
    with the factor h the same oscillator's energy is the physical one."""
    h, k = sp.symbols("h k", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def oscillator(factor):
        def L(a):
            (q0,), (q1,) = a.source, a.target
            return factor * (((q1 - q0) / h) ** 2 / 2 - k * ((q0 + q1) / 2) ** 2 / 2)
        return sg.DiscreteSystem(G, L, parameters=[h, k], time_step=h,
                                 name=f"oscillator_{factor}").euler_lagrange() \
            .compile(backend="numpy")

    params = {"h": 0.01, "k": 1.0}
    per_time = oscillator(1).simulate({"q": (1.0, 0.99)}, 200, params)
    with pytest.raises(sg.TimeStepError, match="declared time step h does not behave as "
                                               "the step in the continuous limit"):
        per_time.energy()
    summary = per_time.conservation_summary()
    assert not [q for q in summary.quantities if q.name.startswith("E")]
    assert any("does not behave as the step" in note for note in summary.notes)
    action = oscillator(h).simulate({"q": (1.0, 0.99)}, 200, params)
    assert np.allclose(action.states, per_time.states, rtol=0, atol=1e-12)  # the same motion
    q0, q1 = action.states.T
    physical = ((q1 - q0) / 0.01) ** 2 / 2 + ((q0 + q1) / 2) ** 2 / 2
    assert np.allclose(action.energy(), physical, rtol=1e-12, atol=0)


def _time_groupoid_oscillator(depends_on_time: bool):
    kappa, eps = sp.symbols("kappa epsilon", positive=True)
    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))

    def L(a):
        dt, q0, q1 = a.step, a.source[0], a.target[0]
        stiffness = kappa * (1 + eps * sp.cos(2 * (a.t0 + a.t1) / 2)) if depends_on_time \
            else kappa
        return dt * (((q1 - q0) / dt) ** 2 / 2 - stiffness * ((q0 + q1) / 2) ** 2 / 2)

    system = sg.DiscreteSystem(G, L, parameters=[kappa, eps],
                               name=f"mathieu_{depends_on_time}")
    sim = system.euler_lagrange().compile(backend="numpy")
    return sim.simulate([0.0, 0.05, 1.0, 1.0], 150, {"kappa": 1.0, "epsilon": 0.3})


def test_the_energy_of_an_explicitly_time_dependent_l_is_not_listed_as_conserved():
    """(A Mathieu oscillator on the time groupoid: E = −∂L/∂t₁ went from 0.51 to 1.91, and
    the summary and the figure listed it beside its rounding floor as a conserved quantity,
    without a note.)  It is left out, with the reason, unless asked for; the autonomous
    oscillator's E is listed and kept to rounding."""
    changing = _time_groupoid_oscillator(True)
    summary = changing.conservation_summary()
    assert not [q for q in summary.quantities if q.name.startswith("E")]
    assert any("depends on the time explicitly" in note for note in summary.notes)
    asked = changing.conservation_summary(energy=True)
    (energy,) = [q for q in asked.quantities if q.name.startswith("E")]
    assert energy.max_drift > 0.1  # it does change
    kept = _time_groupoid_oscillator(False).conservation_summary()
    (energy,) = [q for q in kept.quantities if q.name.startswith("E")]
    assert energy.max_drift < 1e-12
    pytest.importorskip("matplotlib")
    with pytest.raises(sg.DomainError, match="the energy is not conserved .*depends on "
                                             "the time explicitly"):
        sg.plot_conservation(changing)


@pytest.mark.parametrize("name", ["zz", 3, "H"])
def test_a_step_parameter_that_names_no_parameter_is_refused(name):
    """conservation_summary and plot_conservation left the energy out, with a note, when
    step_parameter was misspelt."""
    traj = pendulum_run()
    with pytest.raises(DiagnosticsError, match="step_parameter"):
        traj.conservation_summary(step_parameter=name)
    with pytest.raises(DiagnosticsError, match="step_parameter"):
        sg.diagnostics.has_energy(traj, name)
    assert traj.conservation_summary(step_parameter="h").quantities[0].name.startswith("E")
