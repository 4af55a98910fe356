"""Errors that say what to do, and Lie-group states a user can read (regression tests).

Each test reproduces what a new user met: a product of two groups with one name, numeric
functions and non-smooth functions in a Lagrangian, a half-turn increment in a Cayley chart,
a holonomic system started from typed numbers, the increments W_k = R_kᵀR_{k+1} of a
Lie-group state without the attitudes R_k, unreadable plot legends, trajectories that could
be saved only from the command line.
"""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import CoordinateNameError, UnsupportedExpressionError

H = sp.Symbol("h", positive=True)


# --- products with duplicate part names ---------------------------------------------------------

@pytest.mark.parametrize("make", [
    lambda: sg.SO3("R") * sg.SO3("R"),
    lambda: (sg.SO3("R") * sg.PairGroupoid(sg.EuclideanSpace("x"))) * sg.SO3("R"),
    lambda: sg.PairGroupoid(sg.EuclideanSpace("x")) * sg.PairGroupoid(sg.EuclideanSpace("y x")),
    lambda: sg.EuclideanSpace("x") * sg.EuclideanSpace("x"),
    lambda: sg.PairGroupoid(sg.SO3("R") * sg.SO3("R")),
], ids=["SO3*SO3", "nested", "pair coordinates", "manifolds", "pair of a product"])
def test_products_refuse_duplicate_part_names(make):
    with pytest.raises(CoordinateNameError, match=r"'(R|x)'.*distinct names"):
        make()


def test_products_with_distinct_names_are_accepted():
    G = sg.SO3("R1") * sg.SO3("R2") * sg.PairGroupoid(sg.EuclideanSpace("x"))
    assert len(G.factors) == 3


# --- numeric and non-smooth functions in a Lagrangian -------------------------------------------

def _oscillator(potential):
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return H * (((q1 - q0) / H) ** 2 / 2 - potential(q0))

    return sg.DiscreteSystem(G, L, parameters=[H], name="pendulum")


def test_math_cos_in_the_lagrangian_says_use_sympy():
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return H * (((q1 - q0) / H) ** 2 / 2 - math.cos(q0))

    with pytest.raises(sg.CallableError, match=r"calls math\.cos.*SymPy's functions.*sp\.cos"):
        sg.DiscreteSystem(G, L, parameters=[H], name="pendulum")


def test_numpy_cos_in_the_lagrangian_says_use_sympy():
    with pytest.raises(sg.CallableError, match=r"np\.cos.*SymPy's functions.*sp\.cos") as info:
        _oscillator(np.cos)
    assert "Dummy" not in str(info.value)


@pytest.mark.parametrize("function, name", [
    (lambda q: sp.Max(q, 0), "Max"), (lambda q: sp.Min(q, 1), "Min"), (sp.Abs, "Abs"),
    (abs, "Abs"), (lambda q: q * sp.sign(q), "sign"),
    (lambda q: sp.Piecewise((q, q > 0), (0, True)), "Piecewise"), (sp.floor, "floor"),
    (sp.Heaviside, "Heaviside")])
def test_non_smooth_functions_are_refused_by_name(function, name):
    with pytest.raises(UnsupportedExpressionError, match=rf"{name} in the Lagrangian.*"
                                                         r"non-smooth functions.*not supported"
                       ) as info:
        _oscillator(function)
    assert "_x" not in str(info.value) and "Dummy" not in str(info.value)
    assert "q_{k" in str(info.value)  # the coordinate by its name


def test_non_smooth_holonomic_constraint_is_refused_with_coordinate_names():
    ell = sp.Symbol("ell", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace("x y z"))
    with pytest.raises(UnsupportedExpressionError, match=r"Max in the holonomic constraints "
                                                         r"\(Max\(x_\{k\}, y_\{k\}\)\)"):
        sg.DiscreteSystem(G, lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target)),
                          holonomic=lambda q: [sp.Max(q[0], q[1]) + q[2] ** 2 - ell ** 2],
                          parameters=[ell], name="bowl")


# --- the cut locus, h = 0 -----------------------------------------------------------------------

HALF_TURN = np.diag([1.0, -1.0, -1.0])  # a rotation by π about e₁
RIGID = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}


def _rigid_body(retraction: str = "cayley") -> sg.DiscreteSystem:
    I1, I2, I3 = sp.symbols("I1 I2 I3", positive=True)
    J = sp.diag((I2 + I3 - I1) / 2, (I1 + I3 - I2) / 2, (I1 + I2 - I3) / 2)
    return sg.DiscreteSystem(sg.SO3("W", retraction=retraction),
                             lambda g: -(J * g.matrix).trace() / H, parameters=[H, I1, I2, I3],
                             name=f"rigid_{retraction}")


@pytest.mark.parametrize("backend", [pytest.param("c", marks=pytest.mark.skipif(
    __import__("shutil").which("cc") is None, reason="no C compiler")), "numpy"])
@pytest.mark.parametrize("retraction", ["cayley", "exp"])
def test_a_half_turn_increment_names_the_cut_locus_and_the_remedy(backend, retraction):
    sim = _rigid_body(retraction).euler_lagrange().compile(backend=backend)
    chart = "Cayley map" if retraction == "cayley" else "logarithm"
    for run in (lambda: sim.simulate({"W": HALF_TURN}, 5, RIGID),
                lambda: sim.simulate({"W": HALF_TURN}, 5, RIGID, every=2),
                lambda: sim.step({"W": HALF_TURN}, RIGID),
                lambda: sim.solve({"W": HALF_TURN}, RIGID)):
        with pytest.raises(sg.CutLocusStepError,
                           match=rf"step 0 failed: the increment 'W' .*initial state is a "
                                 rf"half-turn.*cut locus of the {chart}.*smaller time step"
                           ) as info:
            run()
        assert isinstance(info.value, sg.CutLocusError)
        assert isinstance(info.value, sg.NewtonDivergenceError)
        assert info.value.parts == ("W",)
        if retraction == "cayley":
            assert 'retraction="exp"' in str(info.value)
    batch = sim.simulate_batch(np.array([sim.state({"W": np.eye(3)}),
                                         sim.state({"W": HALF_TURN})]), 3, RIGID)
    assert batch.error(0) is None and isinstance(batch.error(1), sg.CutLocusStepError)
    near = np.array(sg.SO3("W").numeric_tau([0.0, 0.0, 50.0]))  # 2·atan(25): 176° per step
    assert len(sim.simulate({"W": near}, 3, RIGID)) == 4


def test_increments_of_every_groupoid_with_group_parts():
    R = np.array(sg.SO3("R").numeric_tau([0.3, -0.2, 0.1]))
    pair = sg.PairGroupoid(sg.SO3("R") * sg.SO3("S"))
    free = [R[i, j] for i in range(3) for j in range(3)]
    turned = R @ HALF_TURN
    a = free + [1, 0, 0, 0, 1, 0, 0, 0, 1] + [turned[i, j] for i in range(3)
                                             for j in range(3)] + [1, 0, 0, 0, 1, 0, 0, 0, 1]
    names = [(n, round(abs(np.linalg.det(np.eye(3) + M)), 12))
             for n, _, M in pair.increments(a)]
    assert names == [("R", 0.0), ("S", 8.0)]
    chain = sg.TrivialisedPairGroupoid(sg.SO3("R"), increment="F")
    F = chain.increments(free + list((HALF_TURN - np.eye(3)).ravel()))
    assert F[0][0] == "F" and np.allclose(F[0][2], HALF_TURN)
    product = sg.PairGroupoid(sg.EuclideanSpace("x")) * sg.SO3("W")
    assert [n for n, _, _ in product.increments([0.0, 1.0] + list(HALF_TURN.ravel()))] == ["W"]
    assert sg.PairGroupoid(sg.EuclideanSpace("x")).increments([0.0, 1.0]) == []


@pytest.mark.parametrize("backend", ["numpy", pytest.param("c", marks=pytest.mark.skipif(
    __import__("shutil").which("cc") is None, reason="no C compiler"))])
def test_a_zero_time_step_not_declared_positive_is_refused_with_the_remedy(backend):
    h = sp.Symbol("h")  # not declared positive: 0 passes the assumption checks
    system = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")),
                               lambda g: h * ((g.target[0] - g.source[0]) / h) ** 2 / 2,
                               parameters=[h], name="free")
    sim = system.euler_lagrange().compile(backend=backend)
    pattern = (r"free: the parameter h = 0 makes the Lagrangian non-finite \(it divides by "
               r"h\).*nonzero value.*positive=True")
    for run in (lambda: sim.simulate({"q": (0.0, 0.1)}, 3, {"h": 0}),
                lambda: sim.step(np.array([0.0, 0.1]), np.zeros(1)),
                lambda: sim.step(np.array([0.0, 0.1]), {"h": 0.0}),
                lambda: sim.simulate_batch(np.array([[0.0, 0.1]]), 3, {"h": [0.0]})):
        with pytest.raises(sg.ParameterError, match=pattern):
            run()
    p = np.array([0.1])
    state = sim.step(np.array([0.0, 0.1]), p)
    p[0] = 0.0  # the same vector, changed in place inside a loop
    with pytest.raises(sg.ParameterError, match=pattern):
        sim.step(state, p)
    assert np.allclose(sim.step(np.array([0.0, 0.1]), {"h": 0.1}), [0.1, 0.2])


# --- starting a holonomic system, and rotations, from typed numbers ----------------------------

def test_project_initial_moves_typed_configurations_onto_the_holonomic_constraints():
    from symgroupoid import systems

    sim = systems.spherical_pendulum().euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "ell": 1.0, "g": 9.81}
    typed = {"x": (0.707, 0.71), "y": (0.0, 0.01), "z": (-0.707, -0.70)}
    with pytest.raises(sg.DomainError, match=r"ψ_1\(α\(g_k\)\).*project_initial"):
        sim.state(typed, params)
    state = sim.project_initial(typed, params)
    x, y = state[:3], state[3:6]
    assert abs(x @ x - 1.0) < 1e-14 and abs(y @ y - 1.0) < 1e-14
    assert np.abs(state[:3] - [0.707, 0.0, -0.707]).max() < 2e-3  # the nearest point of M
    assert len(sim.simulate(state, 3, params)) == 4

    chain = systems.link_chain(2).euler_lagrange().compile(backend="numpy")
    lengths = {"h": 0.01, "g": 9.81, "l1": 1.0, "l2": 1.0}
    state = chain.project_initial({"x1": (0.5, 0.51), "y1": (-0.866, -0.86),
                                   "x2": (1.5, 1.51), "y2": (-0.866, -0.86)}, lengths)
    p1, p2 = state[0:2], state[2:4]
    assert abs(p1 @ p1 - 1) < 1e-14 and abs((p2 - p1) @ (p2 - p1) - 1) < 1e-14
    with pytest.raises(sg.DomainError, match=r"onto the holonomic constraint set M"):
        chain.project_initial({"x1": (0.0, 0.0), "y1": (0.0, 0.0), "x2": (0.0, 0.0),
                               "y2": (0.0, 0.0)}, {**lengths, "l2": 5.0})


def test_project_initial_moves_the_base_point_of_an_action_groupoid_along_its_orbit():
    from symgroupoid import systems

    sim = systems.tilted_top().euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "mgl": 1.0, "I1": 1.0, "I2": 1.0, "I3": 0.5, "c": 0.8}
    state = sim.project_initial({"Gamma": (0.0, 0.6, 0.8001), "W": np.eye(3)}, params)
    gamma = state[:3]
    assert abs(gamma[2] - 0.8) < 1e-14
    assert abs(gamma @ gamma - (0.36 + 0.8001 ** 2)) < 1e-14  # moved by a rotation


def test_a_rotation_given_to_eight_digits_is_orthonormalised_with_a_warning():
    from symgroupoid import systems

    R = np.array(sg.SO3("W").numeric_tau([0.3, -0.2, 0.5]))
    rounded = np.round(R, 8)
    sim = systems.rigid_body().euler_lagrange().compile(backend="numpy")
    with pytest.warns(sg.GroupRoundingWarning, match=r"'W' is off SO3\(W\) by .*nearest "
                                                     r"element"):
        state = sim.state({"W": rounded})
    W = sim.layout.view(state[None], "W")[0]
    assert np.abs(W.T @ W - np.eye(3)).max() < 1e-15 and np.abs(W - R).max() < 1e-8
    flat = sim.state({"W": R})
    flat[:9] = np.round(flat[:9], 8)
    with pytest.warns(sg.GroupRoundingWarning):
        assert np.abs(sim.state(flat)[:9] - state[:9]).max() < 1e-15
    with pytest.raises(sg.DomainError, match=r"off orthonormal by 1\.\d+e-04.*nearest_element"):
        sim.state({"W": np.round(R, 4)})
    with pytest.raises(sg.DomainError, match="reflection"):
        sim.state({"W": -R})
    assert np.allclose(sg.SO3("W").nearest_element(rounded), W, atol=1e-15)


def test_configurations_of_a_pair_groupoid_of_rotations_are_checked_for_the_group():
    from symgroupoid import systems

    sim = systems.spherical_chain(1).euler_lagrange().compile(backend="numpy")
    R = np.array(sg.SO3("R").numeric_tau([0.1, 0.2, 0.3]))
    with pytest.raises(sg.DomainError, match=r"'R1' is not in SO3\(R1\)"):
        sim.state({"R1": (R, 1.01 * R)})
    with pytest.warns(sg.GroupRoundingWarning, match="'R1'"):
        state = sim.state({"R1": (np.round(R, 8), R)})
    R0 = state[:9].reshape(3, 3)
    assert np.abs(R0.T @ R0 - np.eye(3)).max() < 1e-15


# --- Lie-group states a user can read -----------------------------------------------------------

def _rigid_run(steps: int = 400, every: int = 1):
    from symgroupoid import systems

    sim = systems.rigid_body().euler_lagrange().compile(backend="numpy")
    W0 = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    return sim, sim.simulate({"W": W0}, steps, RIGID, every=every)


def test_configurations_multiply_the_increments_out_and_spatial_momenta_are_conserved():
    sim, traj = _rigid_run()
    R0 = np.array(sg.SO3("R").numeric_tau([0.3, 0.1, -0.2]))
    R = traj.configurations(R0)
    W = traj["W"]
    assert R.shape == (len(traj) + 1, 3, 3) and np.array_equal(R[0], R0)
    G = sim.equations.groupoid
    c = R0
    for k in range(len(W)):  # the groupoid's own multiplication, step by step
        c = G.configuration_after(c, traj.states[k, :9])
        assert np.allclose(R[k + 1], c, rtol=0, atol=1e-14)
    assert np.allclose(R[1:], np.einsum("kij,kjl->kil", R[:-1], W), rtol=0, atol=1e-14)
    assert np.abs(np.einsum("kji,kjl->kil", R, R) - np.eye(3)).max() < 1e-13
    assert np.array_equal(traj.configurations()[0], np.eye(3))
    pi = traj.spatial_momenta(R0)  # R_k μ_k: Noether's quantity of rotations of space
    assert pi.shape == (len(traj), 3)
    assert np.abs(pi - pi[0]).max() < 1e-12 * np.abs(pi[0]).max()
    body = traj.momenta().minus
    assert np.allclose(pi, np.einsum("kij,kj->ki", R[:-1], body), rtol=0, atol=1e-12)
    with pytest.raises(sg.DomainError, match=r"start.*not in SO3"):
        traj.configurations(2 * R0)
    _, sampled = _rigid_run(10, every=3)
    with pytest.raises(sg.DomainError, match="every=1"):
        sampled.configurations()


@pytest.mark.skipif(__import__("shutil").which("cc") is None, reason="no C compiler")
def test_configurations_of_pair_action_and_product_groupoids():
    from kernel_support import SEED_DATA, compiled, initial_state

    from symgroupoid import systems

    sim = compiled("plate_ball")
    traj = sim.simulate(initial_state(sim, "plate_ball"), 50, SEED_DATA["plate_ball"][0])
    points, rotations = traj.configurations((None, np.eye(3)))
    assert np.array_equal(points[:, 0], traj["x"]) and np.array_equal(points[:, 1], traj["y"])
    assert rotations.shape == (len(traj) + 1, 3, 3)
    assert np.array_equal(traj.configurations()[1], rotations)
    with pytest.raises(sg.DomainError, match="leave start out"):
        traj.configurations(((1.0, 2.0), None))
    # a pair groupoid of rotations holds its configurations; gravity along e₃ leaves the
    # spatial angular momentum about e₃ conserved
    chain = systems.spherical_chain(1).euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "g": 9.81}
    R = np.array(sg.SO3("R").numeric_tau([0.4, 0.3, 0.2]))
    state = chain.from_momentum({"R1": R}, [0.2, -0.1, 0.3], params)
    run = chain.simulate(state, 30, params)
    assert np.array_equal(run.configurations(), run["R1"])
    pi = run.spatial_momenta()
    assert np.abs(pi[:, 2] - pi[0, 2]).max() < 1e-12
    # the same body in increment coordinates: the same configurations and momenta
    inc = systems.spherical_chain_increments(1).euler_lagrange().compile(backend="numpy")
    run2 = inc.simulate(inc.from_momentum({"R1": R}, [0.2, -0.1, 0.3], params), 30, params)
    assert np.allclose(run2.configurations(), run["R1"], rtol=0, atol=1e-12)
    assert np.allclose(run2.spatial_momenta(), pi, rtol=0, atol=1e-10)


def test_plot_legends_are_readable_and_time_is_on_the_axis():
    pytest.importorskip("matplotlib")
    _, traj = _rigid_run(20)
    fig = traj.plot(["W"], time_step="h")
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[:2] == ["W[0, 0]", "W[0, 1]"] and "np." not in " ".join(labels)
    assert ax.get_xlabel() == "time t = k·h (h = 0.01)"
    assert np.isclose(ax.get_lines()[0].get_xdata()[-1], 20 * 0.01)  # W_k at t = k·h
    assert traj.plot(["W"], time_step=False).axes[0].get_xlabel() == "step k"
    with pytest.raises(sg.InputNameError, match="time_step must name a parameter"):
        traj.plot(["W"], time_step="dt")


# --- saving and loading trajectories ------------------------------------------------------------

def _ring(name: str, coordinates: str = "x y") -> sg.DiscreteSystem:
    h = sp.Symbol("h", positive=True)
    G = sg.PairGroupoid(sg.EuclideanSpace(coordinates))

    def L(g):
        return sum((b - a) ** 2 for a, b in zip(g.source, g.target)) / (2 * h)

    def phi(g):
        return [sum(b ** 2 - a ** 2 for a, b in zip(g.source, g.target)) / 2]

    return sg.DiscreteSystem(G, L, constraints=phi, parameters=[h], name=name)


RING0 = {"x": (1.0, math.cos(0.01)), "y": (0.0, math.sin(0.01)), "lambda": [0.0]}


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_a_trajectory_saved_from_python_loads_back_exactly(tmp_path, suffix):
    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    traj = sim.simulate(RING0, 7, {"h": 0.01}, every=2)
    path = tmp_path / f"ring{suffix}"
    traj.save(path)
    params = {"h": 0.01} if suffix == ".csv" else None
    back = sg.Trajectory.load(path, sim, params=params)
    for name in ("states", "step_indices", "newton_iterations", "residual_norms"):
        assert np.array_equal(getattr(back, name), getattr(traj, name)), name
    assert back.every == 2 and back.parameters == {"h": 0.01}
    assert np.array_equal(back["x"], traj["x"])
    assert np.array_equal(sg.Trajectory.load(path, sim.equations, params={"h": 0.01}).states,
                          traj.states)
    if suffix == ".csv":
        with pytest.raises(sg.TrajectoryFileError, match="holds no parameter values"):
            sg.Trajectory.load(path, sim)
    with pytest.raises(sg.DomainError, match="must end in .npz or .csv"):
        traj.save(tmp_path / "ring.txt")
    with pytest.raises(sg.OutputError, match="does not exist"):
        traj.save(tmp_path / "missing" / f"ring{suffix}")


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_another_systems_trajectory_of_the_same_width_is_refused(tmp_path, suffix):
    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    other = _ring("circle", "u v").euler_lagrange().compile(backend="numpy")
    assert other.layout.n_known == sim.layout.n_known
    path = tmp_path / f"circle{suffix}"
    other.simulate({"u": RING0["x"], "v": RING0["y"], "lambda": [0.0]}, 3,
                   {"h": 0.01}).save(path)
    with pytest.raises(sg.TrajectoryFileError,
                       match=r"another system's trajectory: state column 0 is 'u \(step "
                             r"k-1\)' where this system has 'x \(step k-1\)'"):
        sg.Trajectory.load(path, sim, params={"h": 0.01})


def test_loading_never_runs_code_and_refuses_damaged_files(tmp_path):
    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    good = tmp_path / "good.npz"
    sim.simulate(RING0, 3, {"h": 0.01}).save(good)
    with np.load(good) as archive:
        arrays = dict(archive)
    evil = tmp_path / "evil.npz"
    np.savez(evil, **{**arrays, "states": np.array([object()] * 5, dtype=object)})
    with pytest.raises(sg.TrajectoryFileError, match="cannot be read"):
        sg.Trajectory.load(evil, sim)
    for name, change in {"short": {"step_indices": arrays["step_indices"][:-1]},
                         "nan": {"states": arrays["states"] * np.nan},
                         "columns": {"columns": np.array([1, 2, 3, 4, 5])},
                         "parameters": {"parameter_names": np.array(["k"])}}.items():
        bad = tmp_path / f"{name}.npz"
        np.savez(bad, **{**arrays, **change})
        with pytest.raises(sg.TrajectoryFileError, match="bad|disagree|non-finite|strings|"
                                                        "another system"):
            sg.Trajectory.load(bad, sim)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(sg.TrajectoryFileError, match="cannot be read as .npz"):
        sg.Trajectory.load(tmp_path / "junk.npz", sim)
    with pytest.raises(sg.TrajectoryFileError, match="no such file"):
        sg.Trajectory.load(tmp_path / "absent.npz", sim)
    (tmp_path / "folder.npz").mkdir()
    os.mkfifo(tmp_path / "pipe.csv")
    for special in ("folder.npz", "pipe.csv"):  # (they were reported as "no such file")
        with pytest.raises(sg.TrajectoryFileError, match="not a regular file"):
            sg.Trajectory.load(tmp_path / special, sim)
    with pytest.raises(sg.InputTypeError, match="Simulator or the step equations"):
        sg.Trajectory.load(good, "ring")


def test_loading_refuses_values_no_run_writes(tmp_path):
    """A step h against its symbol's assumptions (its diagnostics used it), NaN residual
    norms, negative iteration counts, an ``every`` the step indices contradict (which made
    ``configurations()`` wrong), ``every = inf`` (OverflowError), an archive entry in an
    unknown compression (NotImplementedError) and a CSV step beyond int64 (OverflowError)."""
    import struct

    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    good = tmp_path / "good.npz"
    sim.simulate(RING0, 20, {"h": 0.01}, every=5).save(good)
    with np.load(good) as archive:
        arrays = dict(archive)
    n = len(arrays["residual_norms"])
    for name, change, message in [
            ("h", {"parameter_values": -arrays["parameter_values"]}, "declared positive"),
            ("nan", {"residual_norms": np.full(n, np.nan)}, "residual norms must be finite"),
            ("negative", {"newton_iterations": np.full(n, -7)}, "iteration counts must be"),
            ("every", {"every": np.array(1)}, "not those of a run keeping every 1"),
            ("inf", {"every": np.array(np.inf)}, "every must be an integer"),
            ("negative", {"step_indices": arrays["step_indices"] - 5}, "begin at step -5")]:
        bad = tmp_path / f"{name}.npz"
        np.savez(bad, **{**arrays, **change})
        with pytest.raises(sg.TrajectoryFileError, match=message):
            sg.Trajectory.load(bad, sim)
    raw = bytearray(good.read_bytes())
    at = raw.find(b"PK\x01\x02")  # the first entry of the central directory
    raw[at + 10:at + 12] = struct.pack("<H", 99)  # its compression method
    (tmp_path / "method.npz").write_bytes(raw)
    with pytest.raises(sg.TrajectoryFileError, match="cannot be read"):
        sg.Trajectory.load(tmp_path / "method.npz", sim)
    sim.simulate(RING0, 3, {"h": 0.01}).save(tmp_path / "a.csv")
    lines = (tmp_path / "a.csv").read_text().splitlines()
    lines[1] = "1" + "0" * 25 + "," + lines[1].split(",", 1)[1]
    (tmp_path / "big.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(sg.TrajectoryFileError, match="beyond the range of a 64-bit"):
        sg.Trajectory.load(tmp_path / "big.csv", sim, params={"h": 0.01})
    # cut inside its last number (4.5797e-15 loaded as 4.57) or inside any row: refused
    whole = (tmp_path / "a.csv").read_bytes()
    for cut in (whole.rfind(b",") + 3, whole.find(b",", len(whole) // 2) + 1):
        (tmp_path / "cut.csv").write_bytes(whole[:cut])
        with pytest.raises(sg.TrajectoryFileError, match="cut short"):
            sg.Trajectory.load(tmp_path / "cut.csv", sim, params={"h": 0.01})


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_a_file_whose_states_do_not_join_is_refused(tmp_path, suffix):
    """A value edited in one state (x_k of state 4 moved by 1) loaded, though states 4 and 5
    then no longer composed (x_k of state 4 ≠ x_{k-1} of state 5) and the run's diagnostics
    read another path; a run kept every 2 steps is not compared across the steps it
    skips."""
    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    traj = sim.simulate(RING0, 8, {"h": 0.01})
    path = tmp_path / f"run{suffix}"
    traj.save(path)
    assert np.array_equal(sg.Trajectory.load(path, sim, params={"h": 0.01}).states,
                          traj.states)
    column = int(sim.layout.parts["x"].index[1])  # x at step k
    if suffix == ".npz":
        with np.load(path) as archive:
            arrays = dict(archive)
        arrays["states"][4, column] += 1.0
        np.savez(path, **arrays)
    else:
        lines = path.read_text().splitlines()
        header = lines[0].split(",")
        at = next(i for i, name in enumerate(header) if name == sim.layout.describe(column))
        cells = lines[5].split(",")  # the header, then states 0, 1, …
        cells[at] = repr(float(cells[at]) + 1.0)
        lines[5] = ",".join(cells)
        path.write_text("\n".join(lines) + "\n")
    with pytest.raises(sg.TrajectoryFileError, match="states 4 and 5 .* do not join"):
        sg.Trajectory.load(path, sim, params={"h": 0.01})
    sparse = tmp_path / f"sparse{suffix}"
    sim.simulate(RING0, 8, {"h": 0.01}, every=2).save(sparse)
    assert len(sg.Trajectory.load(sparse, sim, params={"h": 0.01}).states) == 5


def test_saving_keeps_a_read_only_file_and_a_files_mode(tmp_path):
    """(A file of mode 0444 was replaced, and with mode 0644; a file of mode 0600 became
    0644.)  A symbolic link is replaced, not written through (tests/test_cli.py)."""
    import stat

    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    traj = sim.simulate(RING0, 3, {"h": 0.01})
    locked = tmp_path / "locked.npz"
    locked.write_bytes(b"old")
    locked.chmod(0o444)
    with pytest.raises(sg.OutputError, match="read-only"):
        traj.save(locked)
    assert locked.read_bytes() == b"old"
    private = tmp_path / "private.csv"
    private.write_text("old")
    private.chmod(0o600)
    traj.save(private)
    assert stat.S_IMODE(private.stat().st_mode) == 0o600
    assert np.array_equal(sg.Trajectory.load(private, sim, params={"h": 0.01}).states,
                          traj.states)


def test_saving_names_the_target_and_takes_any_legal_name(tmp_path, capsys):
    """A 250-character name failed (its temporary name needed 260) with a raw OSError; a
    target that is a directory raised IsADirectoryError, and the command line ran the whole
    simulation before failing on it, naming its temporary file."""
    from symgroupoid.cli import main

    sim = _ring("ring").euler_lagrange().compile(backend="numpy")
    traj = sim.simulate(RING0, 3, {"h": 0.01})
    long = tmp_path / ("a" * 246 + ".npz")  # 250 characters, the file system allows 255
    traj.save(long)
    assert np.array_equal(sg.Trajectory.load(long, sim).states, traj.states)
    assert [p.name for p in tmp_path.iterdir()] == [long.name]  # no temporary file left
    (tmp_path / "out.npz").mkdir()
    for target, message in [(tmp_path / "out.npz", "it is a directory"),
                            (tmp_path / ("b" * 300 + ".csv"), "File name too long")]:
        with pytest.raises(sg.OutputError, match=message):
            traj.save(target)
    ring = tmp_path / "ring.py"
    ring.write_text("import sympy as sp\nimport symgroupoid as sg\n"
                    "h = sp.Symbol('h', positive=True)\n"
                    "G = sg.PairGroupoid(sg.EuclideanSpace('x'))\n"
                    "SYSTEM = sg.DiscreteSystem(G, lambda g: (g.target[0] - g.source[0]) ** 2"
                    " / (2 * h), parameters=[h], name='free')\n"
                    "PARAMS = {'h': 0.01}\nINITIAL = {'x': [0.0, 0.01]}\n")
    capsys.readouterr()
    assert main(["simulate", str(ring), "--steps", "10", "--backend", "numpy", "-o",
                 str(tmp_path / "out.npz")]) == 1
    assert "out.npz: it is a directory" in capsys.readouterr().err


def test_simulate_initial_refuses_another_systems_trajectory(tmp_path, capsys):
    from symgroupoid.cli import main

    ring = tmp_path / "ring.py"
    ring.write_text("import math\nimport sympy as sp\nimport symgroupoid as sg\n"
                    "h = sp.Symbol('h', positive=True)\n"
                    "def system(names='x y', name='ring'):\n"
                    "    G = sg.PairGroupoid(sg.EuclideanSpace(names))\n"
                    "    L = lambda g: sum((b - a) ** 2 for a, b in zip(g.source, g.target))"
                    " / (2 * h)\n"
                    "    phi = lambda g: [sum(b ** 2 - a ** 2 for a, b in zip(g.source, "
                    "g.target)) / 2]\n"
                    "    return sg.DiscreteSystem(G, L, constraints=phi, parameters=[h], "
                    "name=name)\n"
                    "SYSTEM = system()\nPARAMS = {'h': 0.01}\n"
                    "INITIAL = {'x': [1.0, math.cos(0.01)], 'y': [0.0, math.sin(0.01)], "
                    "'lambda': [0.0]}\n")
    circle = tmp_path / "circle.py"
    circle.write_text(ring.read_text().replace("SYSTEM = system()", "SYSTEM = system('u v', "
                                                                    "'circle')")
                      .replace("'x':", "'u':").replace("'y':", "'v':"))
    out = tmp_path / "circle.npz"
    assert main(["simulate", str(circle), "--steps", "3", "--backend", "numpy", "-o",
                 str(out)]) == 0
    capsys.readouterr()
    code = main(["simulate", str(ring), "--steps", "3", "--backend", "numpy", "--initial",
                 str(out)])
    err = capsys.readouterr().err
    assert code == 1 and "another system's trajectory" in err and "--initial" in err
    mine = tmp_path / "ring.npz"
    assert main(["simulate", str(ring), "--steps", "3", "--backend", "numpy", "-o",
                 str(mine)]) == 0
    assert main(["simulate", str(ring), "--steps", "3", "--backend", "numpy", "--initial",
                 str(mine)]) == 0


def test_a_batch_checks_and_rounds_group_parts_as_simulate_does():
    from symgroupoid import systems

    sim = systems.spherical_chain(1).euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "g": 9.81}
    R = np.array(sg.SO3("R").numeric_tau([0.4, 0.3, 0.2]))
    state = sim.from_momentum({"R1": R}, [0.2, -0.1, 0.3], params)
    off = state.copy()
    off[:9] *= 1.01  # R_{k-1} off SO(3): not a matrix part of the arrow, a group part still
    with pytest.raises(sg.DomainError, match=r"initial state 1.*'R1'"):
        sim.simulate_batch(np.array([state, off]), 2, params)
    rounded = state.copy()
    rounded[:18] = np.round(rounded[:18], 8)
    with pytest.warns(sg.GroupRoundingWarning):
        batch = sim.simulate_batch(np.array([state, rounded]), 2, params)
    with pytest.warns(sg.GroupRoundingWarning):
        alone = sim.simulate(rounded, 2, params)
    assert np.array_equal(batch[1].states, alone.states)


def test_a_group_times_a_euclidean_space_is_a_manifold_in_either_order():
    """(docs/reference/groupoids.md shows ``SE2("g") * EuclideanSpace("psi")``, which raised
    "a groupoid can only be multiplied by a groupoid"; the other order worked.)"""
    left = sg.SE2("g") * sg.EuclideanSpace("psi")
    right = sg.EuclideanSpace("psi") * sg.SE2("g")
    assert sg.PairGroupoid(left).arrow_dim == sg.PairGroupoid(right).arrow_dim
    assert repr(left).startswith("SE2") and repr(right).startswith("EuclideanSpace")
    with pytest.raises(sg.InputTypeError, match="multiplied by a groupoid"):
        sg.SE2("g") * 3



@pytest.mark.parametrize("row", [1, -1])
def test_a_file_whose_first_or_last_state_is_off_the_group_names_the_file(tmp_path, row):
    """(A middle row off SO(3) was a TrajectoryFileError naming the file and the row; the
    first or last row a bare DomainError naming neither.)"""
    sim = sg.systems.rigid_body().euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    R = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    sim.simulate(sim.state({"W": R}), 5, params).save(tmp_path / "run.csv")
    lines = (tmp_path / "run.csv").read_text().splitlines()
    cells = lines[row].split(",")
    cells[1] = repr(float(cells[1]) + 1e-3)
    lines[row] = ",".join(cells)
    (tmp_path / "off.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(sg.TrajectoryFileError, match=r"off\.csv'?: its state \d+ \(of 6\)"):
        sg.Trajectory.load(tmp_path / "off.csv", sim, params=params)
