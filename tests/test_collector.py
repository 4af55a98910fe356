"""The garbage collector is paused during symbolic work and restored after it
(symgroupoid/_collector.py)."""

from __future__ import annotations

import gc

import pytest
import sympy as sp

import symgroupoid as sg
from symgroupoid._collector import collector_paused


def test_paused_inside_restored_after_even_on_error() -> None:
    seen = []

    @collector_paused
    def inner():
        seen.append(gc.isenabled())

    @collector_paused
    def outer(fail: bool):
        inner()
        seen.append(gc.isenabled())  # the nested call must not resume it
        if fail:
            raise ValueError("boom")

    assert gc.isenabled()
    outer(False)
    assert seen == [False, False] and gc.isenabled()
    with pytest.raises(ValueError):
        outer(True)
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
    from symgroupoid.derivation import _step

    original = _step.junction_step

    def spy(*args, **kwargs):
        states.append(gc.isenabled())
        return original(*args, **kwargs)

    monkeypatch.setattr("symgroupoid.equations._system.junction_step", spy)
    G = sg.PairGroupoid(sg.EuclideanSpace("q"))
    sg.DiscreteSystem(G, lambda g: (g.target[0] - g.source[0]) ** 2 / 2).euler_lagrange()
    assert states == [False] and gc.isenabled()
