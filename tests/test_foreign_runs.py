"""The run of another system is refused by what reads a run: a Noether quantity's ``along``
and ``impulse``, and ``Trajectory.load`` (docs/conventions.md §20, §22).

The same forced continuous system discretised by two schemes has runs of the same width,
columns and parameters; the quantity of one, evaluated on the other's run, gave numbers
(its forced balance off by 1e-8, reported as a drift), a Lobatto run's file loaded into
the Gauss–Legendre simulator, and a forced run fed the unforced system's quantity (the
unforced stages).  ``impulse`` of a run without inputs raised an IndexError, and of a bare
array an AttributeError.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp
from kernel_support import isolated_cache  # noqa: F401  (autouse fixture)

import symgroupoid as sg

h = sp.Symbol("h", positive=True)
c = sp.Symbol("c", nonnegative=True)
u = sp.Symbol("u", real=True)
PARAMS = {"h": 0.05, "c": 0.2}
STEPS = 12


def _lagrangian(q, v):
    return (v[0] ** 2 + v[1] ** 2) / 2 - (q[0] ** 2 + q[1] ** 2) / 2


def _plane(scheme, forced: bool = True, name: str = "plane"):
    forces = (lambda q, v: [u * q[0] - c * v[0], u * q[1] - c * v[1]]) if forced else None
    return sg.ContinuousSystem(sg.EuclideanSpace("x y"), _lagrangian, parameters=[h, c],
                               forces=forces, inputs=[u] if forced else [],
                               name=name).discretize(h, scheme)


@functools.cache
def _runs():
    """(Lobatto system, its run, GaussLegendre system, its simulator)."""
    lobatto, gauss = _plane(sg.LobattoIIIAB(3)), _plane(sg.GaussLegendre(2))
    sim = lobatto.euler_lagrange().compile(backend="numpy")
    start = sim.from_velocity({"x": 1.0, "y": 0.2}, [0.1, 0.9], PARAMS, inputs=[0.3])
    run = sim.simulate(start, STEPS, PARAMS, inputs=0.3 * np.cos(np.arange(STEPS)))
    return lobatto, run, gauss, gauss.euler_lagrange().compile(backend="numpy")


def _rotation(q):
    return [-q[1], q[0]]


def test_the_quantity_of_its_own_system_balances():
    lobatto, run, _, _ = _runs()
    nq = lobatto.noether(_rotation)
    assert np.abs(np.diff(nq.along(run)) - nq.impulse(run)).max() < 1e-13


@pytest.mark.parametrize("entry", ["along", "impulse"])
def test_the_quantity_of_another_scheme_refuses_the_run(entry):
    _, run, gauss, _ = _runs()
    with pytest.raises(sg.ShapeError, match=rf"{entry}: the trajectory is a run of "
                                            r"'plane_lobatto3', the quantity is of "
                                            r"'plane_gauss2'"):
        getattr(gauss.noether(_rotation), entry)(run)


def test_the_unforced_quantity_refuses_a_forced_run_of_the_same_name():
    _, run, _, _ = _runs()
    free = _plane(sg.LobattoIIIAB(3), forced=False)
    with pytest.raises(sg.ShapeError, match="1 input.* per arrow, this quantity's system none"):
        free.noether(_rotation).along(run)


def _unnamed(stiffness: float):
    """A spring in the plane, no name: every such system is called 'continuous_midpoint'."""
    def L(q, v):
        return (v[0] ** 2 + v[1] ** 2) / 2 - stiffness * (q[0] ** 2 + q[1] ** 2) / 2

    return sg.ContinuousSystem(sg.EuclideanSpace("x y"), L, parameters=[h]).discretize(
        h, "midpoint")


def test_a_run_of_another_system_of_the_same_name_is_refused():
    """Two unnamed continuous systems discretised alike share their name, state layout and
    parameters: the quantity of one read the other's run (another Lagrangian) and reported
    its values.  Their fingerprints differ; the same system built twice has one."""
    soft, stiff = _unnamed(1.0), _unnamed(4.0)
    assert soft.name == stiff.name and soft.fingerprint != stiff.fingerprint
    assert _unnamed(1.0).fingerprint == soft.fingerprint
    sim = stiff.euler_lagrange().compile(backend="numpy")
    params = {"h": 0.05}
    run = sim.simulate(sim.from_velocity({"x": 1.0, "y": 0.2}, [0.1, 0.9], params), STEPS,
                       params)
    assert run.is_run_of(stiff) and run.is_run_of(_unnamed(4.0)) and not run.is_run_of(soft)
    for entry in ("along", "term_magnitude"):
        with pytest.raises(sg.ShapeError, match=f"{entry}: the trajectory is a run of another "
                                                "system named 'continuous_midpoint'"):
            getattr(soft.noether(_rotation), entry)(run)
    again = _unnamed(4.0).noether(_rotation).along(run)
    assert np.ptp(again) < 1e-13 * np.abs(again).max()


def test_the_impulse_refuses_what_is_not_a_run_of_its_system():
    lobatto, run, _, _ = _runs()
    nq = lobatto.noether(_rotation)
    with pytest.raises(sg.InputTypeError, match="impulse: trajectory must be a Trajectory"):
        nq.impulse(run.states)
    free = _plane(sg.LobattoIIIAB(3), forced=False, name="free")
    sim = free.euler_lagrange().compile(backend="numpy")
    unforced = sim.simulate(sim.from_velocity({"x": 1.0, "y": 0.2}, [0.1, 0.9], PARAMS),
                            STEPS, PARAMS)
    with pytest.raises(sg.ShapeError, match="impulse: the trajectory is a run of"):
        nq.impulse(unforced)


def test_a_file_loads_only_into_the_system_that_wrote_it(tmp_path):
    lobatto, run, _, gauss_sim = _runs()
    path = tmp_path / "run.npz"
    run.save(path)
    with pytest.raises(sg.TrajectoryFileError, match=r"a run of the system 'plane_lobatto3', "
                                                     r"not of 'plane_gauss2'"):
        sg.Trajectory.load(path, gauss_sim)
    back = sg.Trajectory.load(path, lobatto.euler_lagrange().compile(backend="numpy"))
    assert np.array_equal(back.states, run.states)


def test_a_file_without_the_system_name_is_matched_by_its_columns(tmp_path):
    """Files written before the name was recorded load as before."""
    lobatto, run, _, _ = _runs()
    path = tmp_path / "run.npz"
    run.save(path)
    with np.load(path) as archive:
        arrays = {k: archive[k] for k in archive.files if k != "system"}
    old = tmp_path / "old.npz"
    np.savez(old, **arrays)
    back = sg.Trajectory.load(old, lobatto.euler_lagrange().compile(backend="numpy"))
    assert np.array_equal(back.states, run.states)
    # an earlier file of a system whose state part is named "system" held that part there
    np.savez(old, **arrays, system=np.zeros(len(run.states)))
    back = sg.Trajectory.load(old, lobatto.euler_lagrange().compile(backend="numpy"))
    assert np.array_equal(back.states, run.states)
