"""The time step of a system and the continuous limit of its discrete Lagrangian
(docs/conventions.md §19).

The discrete energy E_d = −∂L_d/∂h differentiates by the time step: the one declared with
``time_step=``, or the one parameter h for which L_d(g_h(q, v))/h tends to a Lagrangian with a
kinetic term — never a parameter chosen by its name (a projectile with step ``dt`` and a height
``h`` reported −g·dt as its energy).  When no parameter or several qualify, the energy is a
:class:`~symgroupoid.TimeStepError`; systems without an energy still build.  The same limit's
velocity Hessian, restricted to the constraint directions, must be regular: a degenerate
kinetic energy that only the potential makes formally regular is a
:class:`~symgroupoid.DegenerateSystemError` naming the direction, one that velocity-linear terms
regularise is a :class:`~symgroupoid.DegenerateLagrangianWarning`.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid import systems
from symgroupoid.derivation import identified_time_steps

EPS = float(np.finfo(float).eps)
dt, grav, h, c = sp.symbols("dt g h c", positive=True)
height = h  # the projectile's height is named like the usual step
PLANE = sg.PairGroupoid(sg.EuclideanSpace("x y"))


def projectile(**kwargs) -> sg.DiscreteSystem:
    """A body thrown up: step dt, gravity g, potential measured from a height h (midpoint)."""
    def L(a):
        (y0,), (y1,) = a.source, a.target
        return dt * (((y1 - y0) / dt) ** 2 / 2 - grav * ((y0 + y1) / 2 - height))

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("y")), L,
                             parameters=[dt, grav, height], name="projectile", **kwargs)


PROJECTILE = {"dt": 0.01, "g": 9.81, "h": 2.0}


def thrown(system: sg.DiscreteSystem, steps: int = 400):
    sim = system.euler_lagrange().compile(backend="numpy")
    return sim.simulate({"y": (0.0, 0.01 * 12.0)}, steps, PROJECTILE)


def true_energy(traj) -> np.ndarray:
    """½((y₁ − y₀)/dt)² + g((y₀ + y₁)/2 − h) on every kept arrow."""
    y = traj["y"]
    p = PROJECTILE
    return 0.5 * (np.diff(y) / p["dt"]) ** 2 + p["g"] * ((y[:-1] + y[1:]) / 2 - p["h"])


@pytest.mark.parametrize("declared", [False, True])
def test_projectile_energy_differentiates_by_the_step_not_by_h(declared: bool) -> None:
    """E_d = −∂L_d/∂dt (not −∂L_d/∂h = −g·dt, a constant that looked perfectly conserved):
    equal to the mechanical energy of the arrows, conserved to rounding (the midpoint rule is
    exact for a uniform field), the same whether dt is declared or identified."""
    system = projectile(time_step=dt) if declared else projectile()
    assert system.time_step == (dt if declared else None)
    assert identified_time_steps(system) == [dt]
    traj = thrown(system)
    E = traj.energy()
    np.testing.assert_allclose(E, true_energy(traj), rtol=1e-12)
    assert abs(E[0] - 0.5 * 12.0**2 - 9.81 * (0.06 - 2.0)) < 1e-9  # not −g·dt = −0.0981
    summary = traj.conservation_summary()
    (drift,) = summary.quantities
    assert drift.name == "E_d = −∂L_d/∂dt"
    assert drift.max_drift < 1e-10 * drift.scale  # measured: 2e-12 over the 400 steps
    np.testing.assert_allclose(traj.energy(step_parameter="h"), -9.81 * 0.01)  # by name


def test_conservation_figure_plots_the_energy_of_the_step() -> None:
    """plot_conservation(energy=True) draws E_d = −∂L_d/∂dt of the projectile."""
    pytest.importorskip("matplotlib")
    traj = thrown(projectile())
    fig = sg.plot_conservation(traj, energy=True)
    labels = [t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()]
    assert any("E_d = −∂L_d/∂dt" in label for label in labels), labels
    # time on the axis: the step dt, named (the system here declares none), not the height h
    fig = sg.plot_conservation(traj, energy=True, step_parameter="dt")
    dt_value = traj.parameters["dt"]
    assert fig.axes[-1].get_xlabel() == f"time t = k·dt (dt = {dt_value:g})"
    x = fig.axes[0].get_lines()[0].get_xdata()
    assert np.isclose(x[-1], traj.step_indices[-1] * dt_value)
    declared = thrown(projectile(time_step=dt))
    fig = sg.plot_conservation(declared, energy=True)
    assert fig.axes[-1].get_xlabel().startswith("time t = k·dt")
    fig = sg.plot_conservation(declared, energy=True, time_step=False)
    assert fig.axes[-1].get_xlabel() == "step k"
    # undeclared, but identified by the continuous limit (as the energy finds it)
    fig = sg.plot_conservation(traj, energy=True)
    assert fig.axes[-1].get_xlabel() == f"time t = k·dt (dt = {dt_value:g})"
    assert sg.plot_trajectory(traj).axes[-1].get_xlabel().startswith("time t = k·dt")


def test_the_time_axis_falls_back_to_the_step_index_when_the_step_cannot_be_told() -> None:
    """Two parameters behave as the step: the figures plot against k, and say so."""
    pytest.importorskip("matplotlib")
    system = ambiguous()
    traj = system.euler_lagrange().compile(backend="numpy").simulate(
        {"q": (1.0, 0.99)}, 20, {"dt": 0.01, "c": 1.0})
    assert sg.plot_trajectory(traj).axes[-1].get_xlabel() == "step k"


def ambiguous() -> sg.DiscreteSystem:
    """L_d depends on dt and c only through dt·c: both behave as the step."""
    return sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a: (a.target[0] - a.source[0]) ** 2 / (2 * dt * c)
        - dt * c * ((a.source[0] + a.target[0]) / 2) ** 2 / 2,
        parameters=[dt, c], name="ambiguous")


def test_ambiguous_step_is_refused_when_an_energy_is_asked_for() -> None:
    """Two parameters qualify: the system derives and runs, the energy is a TimeStepError
    naming both and saying to pass time_step=; the summary leaves the energy out with that
    reason; declaring the step resolves it."""
    system = ambiguous()
    assert identified_time_steps(system) == [dt, c]
    sim = system.euler_lagrange().compile(backend="numpy")
    traj = sim.simulate({"q": (1.0, 1.0)}, 20, {"dt": 0.1, "c": 1.0})
    with pytest.raises(sg.TimeStepError, match=r"several parameters .*\(dt, c: .*time_step=") \
            as info:
        traj.energy()
    assert isinstance(info.value, sg.diagnostics.DiagnosticsError)
    summary = traj.conservation_summary()
    assert summary.quantities == [] and "energy: not included" in str(summary)
    assert "time_step=" in str(summary)
    with pytest.raises(sg.TimeStepError):
        traj.conservation_summary(energy=True)
    declared = sg.DiscreteSystem(ambiguous().groupoid, ambiguous().lagrangian,
                                 parameters=[dt, c], name="declared", time_step="dt")
    run = declared.euler_lagrange().compile(backend="numpy").simulate(
        {"q": (1.0, 1.0)}, 20, {"dt": 0.1, "c": 1.0})
    assert run.conservation_summary().quantities[0].name == "E_d = −∂L_d/∂dt"


def test_no_step_parameter_is_refused_with_the_remedy() -> None:
    """A Lagrangian written for a fixed step has no parameter that is the step: TimeStepError
    saying so; systems without an energy still build and run."""
    k = sp.Symbol("k", positive=True)
    system = sg.DiscreteSystem(
        sg.PairGroupoid(sg.EuclideanSpace("q")),
        lambda a: (a.target[0] - a.source[0]) ** 2 / 2 - k * a.target[0] ** 2 / 2,
        parameters=[k], name="fixed")
    traj = system.euler_lagrange().compile(backend="numpy").simulate({"q": (1.0, 1.0)}, 10,
                                                                     {"k": 0.5})
    with pytest.raises(sg.TimeStepError, match=r"no parameter behaves as the step .*"
                                                r"time_step=<the step parameter>"):
        traj.energy()
    assert traj.energy(step_parameter="k").shape == (len(traj),)


def test_time_step_argument() -> None:
    """A symbol or the name of a parameter; anything else is named."""
    assert projectile(time_step="dt").time_step == dt
    with pytest.raises(sg.InputNameError, match=r"time_step='tau' is not one of the "
                                                r"parameters \(dt, g, h\)"):
        projectile(time_step=sp.Symbol("tau"))
    with pytest.raises(sg.InputTypeError, match="time_step must be the step parameter"):
        projectile(time_step=0.01)
    n = sp.Symbol("n", integer=True)
    with pytest.raises(sg.DomainError, match="a time step is a positive real number"):
        sg.DiscreteSystem(PLANE, lambda a: sum(a.target) ** 2 * n, parameters=[n],
                          time_step=n)
    with pytest.raises(sg.UnsupportedFeatureError, match=r"t₁ − t₀ \(g.step\)"):
        sg.DiscreteSystem(sg.TimeGroupoid(PLANE), lambda a: a.step * sum(a.target),
                          parameters=[h], time_step=h)
    assert sg.NonholonomicSystem(PLANE, lambda a: sum(a.target) ** 2 / h,
                                 lambda a: [a.target[1] - a.source[1]], [[1, 0]],
                                 parameters=[h], time_step=h).time_step == h


SEEDS = {
    "plate_ball": systems.plate_ball, "heavy_top": systems.heavy_top,
    "rigid_body": systems.rigid_body, "planar_chain_2": lambda: systems.planar_chain(2),
    "spherical_chain_2": lambda: systems.spherical_chain(2),
    "spherical_chain_increments_2": lambda: systems.spherical_chain_increments(2),
    "spherical_pendulum": systems.spherical_pendulum, "link_chain_2": lambda: systems.link_chain(2),
    "tilted_top": systems.tilted_top,
}


@pytest.mark.parametrize("name", sorted(SEEDS))
def test_seed_systems_declare_their_step_and_the_limit_agrees(name: str) -> None:
    """Every system of symgroupoid.systems declares h, the continuous limit identifies the same
    parameter (Lie groups, action groupoids, increments, holonomic constraints), and each
    derives without an error or a warning (degenerate in the ambient space, as the
    plate-ball's rotation without inertia, but regular on the constraints)."""
    system = SEEDS[name]()
    step = system.time_step
    assert str(step) == "h"
    assert identified_time_steps(system) == [step]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        system.euler_lagrange()


# --- a degenerate kinetic energy ---------------------------------------------------------------

def degenerate(**kwargs) -> sg.DiscreteSystem:
    """T = (v_x + v_y)²/2 with a harmonic potential, midpoint rule."""
    def L(a):
        (x0, y0), (x1, y1) = a.source, a.target
        vx, vy, mx, my = (x1 - x0) / h, (y1 - y0) / h, (x0 + x1) / 2, (y0 + y1) / 2
        return h * ((vx + vy) ** 2 / 2 - (mx**2 + my**2) / 2)

    return sg.DiscreteSystem(PLANE, L, parameters=[h], name="degenerate", **kwargs)


@pytest.mark.parametrize("declared", [False, True])
def test_degenerate_kinetic_energy_is_refused(declared: bool) -> None:
    """The step is formally regular (the potential adds h/4 to the singular D₁D₂L_d), so the
    Jacobian check passes it, but along w = x − y the DEL read w_{k−1} + 2w_k + w_{k+1} = 0: a
    period-2 mode growing linearly, approximating no motion.  Refused at derivation, naming
    the direction of the null velocity Hessian."""
    with pytest.raises(sg.DegenerateSystemError) as info:
        degenerate(**({"time_step": h} if declared else {})).euler_lagrange()
    err = info.value
    assert err.causes == ("degenerate kinetic energy",)
    assert err.findings[0].unknowns == ("x_{k+1}", "y_{k+1}")
    text = str(err)
    assert text.startswith("degenerate: the discrete Lagrangian has no regular continuous limit")
    assert "singular along v_x − v_y (rank 1 of 2" in text
    assert "only through the potential" in text and "docs/conventions.md §19" in text


def test_degenerate_with_an_ambiguous_step_is_refused() -> None:
    """The step dt·c is ambiguous (either parameter passes): the kinetic energy is checked
    with each, and degenerate with both it is refused all the same."""
    def L(a):
        (x0, y0), (x1, y1) = a.source, a.target
        s = dt * c
        vx, vy, mx, my = (x1 - x0) / s, (y1 - y0) / s, (x0 + x1) / 2, (y0 + y1) / 2
        return s * ((vx + vy) ** 2 / 2 - (mx**2 + my**2) / 2)

    system = sg.DiscreteSystem(PLANE, L, parameters=[dt, c], name="both")
    with pytest.raises(sg.DegenerateSystemError, match="singular along v_x − v_y"):
        system.euler_lagrange()
    assert identified_time_steps(system) == [dt, c]


def test_the_refused_flow_is_the_parasitic_mode() -> None:
    """What the error prevents: the same L_d stepped (its step Jacobian is regular) has
    x − y alternating in sign and growing linearly while the energy looks conserved."""
    from symgroupoid.derivation import evaluate_system, junction_step
    from symgroupoid.equations import StepEquations

    fs = evaluate_system("degenerate", PLANE, degenerate().lagrangian, None, [h])
    step = StepEquations(junction_step("degenerate", PLANE, fs, [h]))
    sim = step.compile(backend="numpy")
    traj = sim.simulate({"x": (0.0, 0.01), "y": (0.0, 0.0)}, 400, {"h": 0.01})
    w = traj["x"] - traj["y"]
    assert np.all(np.sign(w[200:-1]) == -np.sign(w[201:]))  # period 2
    assert abs(w[-1]) > 30 * abs(w[1])  # growing like k


def test_degenerate_on_the_constraints_is_refused_and_regular_on_them_is_not() -> None:
    """Constrained: the Hessian counts on the constraint directions only.  T = (v_x − v_y)²/2
    + v_z²/2 with the constraint Δx = Δy is singular along v_x + v_y on it; T = v_x²/2 +
    v_z²/2 (no kinetic energy in y) with the same constraint is regular on it."""
    space = sg.PairGroupoid(sg.EuclideanSpace("x y z"))

    def make(kinetic):
        def L(a):
            v = [(b - u) / h for u, b in zip(a.source, a.target)]
            mid = [(u + b) / 2 for u, b in zip(a.source, a.target)]
            return h * (kinetic(v) - sum(m**2 for m in mid) / 2)

        return sg.DiscreteSystem(
            space, L, constraints=lambda a: [(a.target[0] - a.source[0])
                                             - (a.target[1] - a.source[1])],
            parameters=[h], name="on_plane")

    with pytest.raises(sg.DegenerateSystemError, match=r"restricted to the constraint "
                                                       r"directions is singular along "
                                                       r"v_x \+ v_y \(rank 1 of 2"):
        make(lambda v: (v[0] - v[1]) ** 2 / 2 + v[2] ** 2 / 2).euler_lagrange()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make(lambda v: v[0] ** 2 / 2 + v[2] ** 2 / 2).euler_lagrange()


def test_velocity_linear_lagrangian_is_a_warning() -> None:
    """L = (x ẏ − y ẋ)/2 − H (point vortex, midpoint): no kinetic energy at all, but the
    velocity-linear term makes the step regular at order h⁰ — a first-order system, warned
    about (parasitic modes), not refused."""
    def L(a):
        (x0, y0), (x1, y1) = a.source, a.target
        mx, my = (x0 + x1) / 2, (y0 + y1) / 2
        return (mx * (y1 - y0) - my * (x1 - x0)) / 2 - h * (mx**2 + my**2) / 2

    with pytest.warns(sg.DegenerateLagrangianWarning,
                      match=r"vortex: .* singular along every direction \(v_x, v_y\) \(rank 0 "
                            r"of 2.*velocity-linear terms"):
        step = sg.DiscreteSystem(PLANE, L, parameters=[h], name="vortex",
                                 time_step=h).euler_lagrange()
    assert len(step.unknowns) == 2


@pytest.mark.parametrize("scheme", ["midpoint", sg.GaussLegendre(2), sg.LobattoIIIAB(3)],
                         ids=["midpoint", "gauss2", "lobatto3"])
@pytest.mark.parametrize("L", [
    lambda q, v: (v[0] + v[1]) ** 2 / 2 - (q[0] ** 2 + q[1] ** 2) / 2,  # the §19 example
    lambda q, v: grav * (sp.cos(q[0]) + sp.cos(q[1])),  # no kinetic energy at all
    lambda q, v: v[0] ** 2 / 2 - (q[0] ** 2 + q[1] ** 2) / 2,  # none along y: v_y unread
], ids=["along-vx-minus-vy", "no-kinetic-energy", "no-velocity-y"])
def test_a_degenerate_continuous_lagrangian_is_refused_by_every_scheme(L, scheme) -> None:
    """(The schemes with internal stages were not probed: the §19 example ran with x − y
    held where the continuous system has x = y; and L = g cos θ, with no kinetic energy,
    passed the midpoint rule too, the rounding left of its zero leading term being counted
    as a rank.)"""
    system = sg.ContinuousSystem(sg.EuclideanSpace("x y"), L, parameters=[h, grav],
                                 name="flat")
    with pytest.raises(sg.DegenerateSystemError) as info:
        system.discretize(h, scheme).euler_lagrange()
    assert str(info.value).startswith("flat_")  # the scheme's own system is named
    # (LobattoIIIAB(3)'s step is already singular along x − y: refused by the check of §4)
    assert info.value.findings[0].cause in ("degenerate kinetic energy", "not regular")


def test_a_velocity_linear_continuous_lagrangian_warns_with_stages() -> None:
    """The point vortex from its continuous L with GaussLegendre(2): the warning of the
    midpoint rule, naming the scheme's system and pointing at the caller's line."""
    vortex = sg.ContinuousSystem(
        sg.EuclideanSpace("x y"),
        lambda q, v: (q[0] * v[1] - q[1] * v[0]) / 2 - (q[0] ** 2 + q[1] ** 2) / 2,
        parameters=[h], name="vortex")
    with pytest.warns(sg.DegenerateLagrangianWarning, match="^vortex_gauss2: ") as caught:
        vortex.discretize(h, sg.GaussLegendre(2)).euler_lagrange()
    assert caught[0].filename == __file__


def test_degenerate_time_dependent_system_is_refused() -> None:
    """On a time groupoid the step is the arrow's t₁ − t₀ (no parameter): the same degenerate
    kinetic energy is refused, the time direction left out."""
    def L(a):
        (x0, y0), (x1, y1) = a.source, a.target
        s = a.step
        vx, vy, mx, my = (x1 - x0) / s, (y1 - y0) / s, (x0 + x1) / 2, (y0 + y1) / 2
        return s * ((vx + vy) ** 2 / 2 - (mx**2 + my**2) / 2)

    with pytest.raises(sg.DegenerateSystemError, match=r"singular along v_x − v_y .* the step "
                                                       r"h is t₁ − t₀"):
        sg.DiscreteSystem(sg.TimeGroupoid(PLANE), L, name="timed").euler_lagrange()


def test_second_order_and_stepless_systems_are_not_probed() -> None:
    """No step, no limit: a Lagrangian without a step parameter derives as before."""
    step = sg.DiscreteSystem(PLANE, lambda a: (sum(a.target) - sum(a.source)) ** 2
                             + (a.target[0] - a.source[0]) ** 2 + a.source[0] ** 2,
                             name="stepless").euler_lagrange()
    assert len(step.unknowns) == 2


def _example(name: str):
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "examples" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"example_{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SLOW_EXAMPLE_SYSTEMS = {
    "elroys_beanie": lambda m: [s for s in m.systems() if hasattr(s, "euler_lagrange")],
    "optimal_control_lie_groups": lambda m: [m.so3_problem(), m.se2_problem()],
    "heavy_top_rotors": lambda m: [m.heavy_top_system()],
}


@pytest.mark.parametrize("name", [
    pytest.param("elroys_beanie", marks=pytest.mark.slow),  # its reduction checks take 10 s
    "heavy_top_rotors", "optimal_control_lie_groups"])
def test_the_systems_of_the_long_examples_derive(name: str) -> None:
    """The examples that run with the slow tests only (boundary-value solves) build systems
    on Atiyah, SO(3), SE(2) and second-order groupoids with cost Lagrangians: each derives
    without an error or a warning (the fast examples run whole in tests/test_examples.py)."""
    systems_ = SLOW_EXAMPLE_SYSTEMS[name](_example(name))
    assert systems_
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for system in systems_:
            system.euler_lagrange()


def test_a_zero_initial_time_step_is_a_domain_error():
    """(t_k = t_{k−1}, or t_{k−1} = 1e17 and t_k = t_{k−1} + 0.1, equal as doubles, ran into
    Newton's NaN: 'non-finite value'.)  The initial state is refused, naming the step."""
    kappa = sp.Symbol("kappa", positive=True)

    def L(a):
        dt, q0, q1 = a.t1 - a.t0, a.source[0], a.target[0]
        return dt * (((q1 - q0) / dt) ** 2 / 2 + kappa * sp.cos((q0 + q1) / 2))

    G = sg.TimeGroupoid(sg.PairGroupoid(sg.EuclideanSpace("q")))
    sim = sg.DiscreteSystem(G, L, parameters=[kappa], name="adaptive").euler_lagrange() \
        .compile(backend="numpy")
    for t0, t1 in ((0.0, 0.0), (1e17, 1e17 + 0.1)):
        with pytest.raises(sg.DomainError, match=r"time step t_k - t_\(k-1\) is 0"):
            sim.simulate([t0, t1, 1.0, 1.05], 3, [1.0])
    assert sim.simulate([0.0, 0.1, 1.0, 1.05], 3, [1.0]).states.shape == (4, 4)
    # a time step at the rounding of its times: at t = 1e300 a step of 1e285 (7 spacings)
    # returned states off the step equations by 70 % of their terms (their rounding floor);
    # at 1e15 a step of one spacing, and at 1e12 one of 164, hold fewer than three digits
    for t0, step, spacings in ((1e300, 1e285, "7"), (1e15, 0.125, "1"), (1e12, 0.02, "164")):
        with pytest.raises(sg.DomainError, match=f"is {spacings} times the spacing"):
            sim.simulate([t0, t0 + step, 1.0, 1.05], 3, [1.0])
    assert sim.simulate([1e6, 1e6 + 0.02, 1.0, 1.05], 3, [1.0]).states.shape == (4, 4)
