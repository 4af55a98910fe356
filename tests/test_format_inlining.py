"""The printed code computes the graph's operations whatever it inlines.

The formatter writes a node used once into its user instead of naming it (``ir._format``).
That must not change a single rounding: a later factor that is itself a product, a power or
a reciprocal is written in parentheses, and a reciprocal is the factor ``(1.0/c)``.  Before,
an inlined reciprocal became a division (``a*b/c``) and an inlined product a longer chain
(``t*p*k`` for t·(p·k)), so that the same value rounded differently in a residual that
inlined a node and in a Jacobian (or a hoisted block) that named it: the NumPy twin's
residual and the C kernel's, which reads the known arrow's values from its hoisted block,
differed in the last bit at states of 1e-300 (found by the hostile suite, the forced point
of ``tests/test_hostile_stages.py``).

Checked here: every output set of a step's program, evaluated by the compiled NumPy function
(which inlines) and by :func:`symgroupoid.ir.interpret` (one node at a time, nothing
inlined), bit for bit (NaN where NaN), at ordinary points and at points of extreme
magnitude.
"""

from __future__ import annotations

import numpy as np
import pytest
from kernel_support import seed_step
from test_hostile_stages import pushed

from symgroupoid.ir import interpret

#: the output sets a stepper evaluates apart, and together
OUTPUT_SETS = (["F"], ["J"], ["F", "J"], ["F_scale"], ["next_knowns"], ["J", "F"])


def _steps():
    return {"plate_ball": seed_step("plate_ball"), "heavy_top": seed_step("heavy_top"),
            "rigid_body": seed_step("rigid_body"), "pushed point": pushed("numpy").equations}


STEPS = _steps()


def _points(program, scale: float, rng) -> list:
    """Random (u, known, p) of the program's sizes, entries of magnitude ``scale``."""
    sizes = [len(program.inputs[k]) for k in ("u", "known", "p")]
    return [scale * rng.uniform(0.5, 2.0, n) * rng.choice([-1.0, 1.0], n) for n in sizes]


@pytest.mark.parametrize("name", sorted(STEPS))
@pytest.mark.parametrize("scale", [1.0, 1e-300, 1e150])
def test_inlined_code_rounds_as_the_graph(name, scale):
    program = STEPS[name].program
    rng = np.random.default_rng(7)
    for outputs in OUTPUT_SETS:
        f = program.numpy_function(outputs, ["u", "known", "p"])
        for _ in range(4):
            point = _points(program, scale, rng)
            with np.errstate(all="ignore"):
                compiled = f(*point)
                walked = interpret(program, outputs, ["u", "known", "p"], *point)
            for a, b in zip(compiled, walked):  # the same bits (a NaN's sign and payload
                assert a.shape == b.shape           # follow its operands' order: NaN only)
                same = (a.view(np.int64) == b.view(np.int64)) | (np.isnan(a) & np.isnan(b))
                assert same.all(), (outputs, point)
