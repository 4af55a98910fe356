"""The garbage collector is paused during symbolic work and restored after it
(symgroupoid/_collector.py), seen through the public API."""

from __future__ import annotations

import gc

import pytest
import sympy as sp

import symgroupoid as sg


def test_paused_inside_restored_after_even_on_error() -> None:
    """DiscreteSystem(...) calls the Lagrangian with the collector paused; a nested derivation
    inside it does not resume it, and it is restored also when the Lagrangian raises."""
    seen = []
    line = sg.PairGroupoid(sg.EuclideanSpace("x"))

    def kinetic(g):
        return (g.target[0] - g.source[0]) ** 2

    def lagrangian(fail: bool):
        def L(g):
            sg.DiscreteSystem(line, kinetic)  # the nested call must not resume it
            seen.append(gc.isenabled())
            if fail:
                raise ValueError("boom")
            return kinetic(g)
        return L

    assert gc.isenabled()
    sg.DiscreteSystem(line, lagrangian(False))
    assert seen and not any(seen) and gc.isenabled()
    with pytest.raises((ValueError, sg.CallableError), match="boom"):
        sg.DiscreteSystem(line, lagrangian(True))
    assert gc.isenabled()


def test_a_collector_disabled_by_the_user_stays_disabled() -> None:
    gc.disable()
    try:
        x = sp.Symbol("x")
        sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x")),
                          lambda g: (g.target[0] - g.source[0]) ** 2 + x * 0).euler_lagrange()
        assert not gc.isenabled()
    finally:
        gc.enable()


def test_derivation_runs_with_the_collector_paused(monkeypatch) -> None:
    """DiscreteSystem(...), euler_lagrange() and compile() pause it; it runs after."""
    states = []
    from symgroupoid.derivation import junction_step as original

    def spy(*args, **kwargs):
        states.append(gc.isenabled())
        return original(*args, **kwargs)

    monkeypatch.setattr("symgroupoid.equations._system.junction_step", spy)
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    sg.DiscreteSystem(G, lambda g: (g.target[0] - g.source[0]) ** 2 / 2).euler_lagrange()
    assert states == [False] and gc.isenabled()
