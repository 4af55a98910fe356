"""Walking a program's graph with NumPy (``symgroupoid.ir.interpret``, used for a
derivation's regularity samples) computes what the compiled NumPy form computes, to
rounding, batched or not."""

from __future__ import annotations

import numpy as np
import pytest

from symgroupoid import systems
from symgroupoid.ir import interpret


@pytest.mark.parametrize("make", [lambda: systems.spherical_chain(2), systems.plate_ball,
                                  lambda: systems.planar_chain(3), systems.heavy_top],
                         ids=["spherical_chain_2", "plate_ball", "planar_chain_3", "heavy_top"])
def test_interpret_is_the_compiled_numpy_form(make):
    step = make().euler_lagrange()
    program = step.program
    rng = np.random.default_rng(17)
    batch = {"u": rng.uniform(-0.4, 0.4, (len(step.unknowns), 5)),
             "known": rng.normal(size=(len(step.knowns), 5)),
             "p": rng.uniform(0.5, 2.0, (len(step.parameters), 5))}
    for outputs, inputs in ((["F", "J"], ["u", "known", "p"]),
                            (["next_knowns"], ["u", "known", "p"]),
                            (["predict"], ["known", "p"])):
        if not all(program.outputs.get(o) for o in outputs):
            continue
        compiled = program.numpy_function(outputs, inputs)
        for x in (batch, {k: v[:, 0] for k, v in batch.items()}):
            want = compiled(*[x[i] for i in inputs])
            got = interpret(program, outputs, inputs, *[x[i] for i in inputs])
            assert len(got) == len(want)
            for a, b in zip(got, want):
                assert a.shape == b.shape
                scale = np.maximum(np.abs(b), 1.0)
                assert np.all(np.abs(a - b) <= 1e-13 * scale), (outputs, np.abs(a - b).max())


def test_interpret_names_a_missing_input():
    step = systems.planar_chain(2).euler_lagrange()
    with pytest.raises(ValueError, match="not in the inputs"):
        interpret(step.program, ["F"], ["u", "p"], np.zeros(2), np.ones(2))
