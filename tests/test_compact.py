"""Compaction of step programs and the code size of large kernels.

:func:`symgroupoid.ir.compact` rewrites a finished program with the associativity and
commutativity of + and ·: one node for a sum and its negation, shared prefixes of products and
sums.  The values are the same expressions (rounding aside); the kernels get smaller, and the
C compiler's time with them.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    isolated_cache,
    needs_cc,
    step_inputs,
)

from symgroupoid import systems
from symgroupoid.equations import step_program
from symgroupoid.ir import ADD, MUL, Graph, compact, to_sympy
from symgroupoid.runtime import toolchain


@pytest.mark.parametrize("make", [lambda: systems.spherical_chain(2), systems.plate_ball,
                                  lambda: systems.link_chain(2), systems.heavy_top],
                         ids=["spherical_chain_2", "plate_ball", "link_chain_2", "heavy_top"])
def test_the_compacted_program_computes_what_the_program_computes(make):
    step = make().euler_lagrange()
    plain, compacted = step_program(step, compacted=False), step.program
    rng = np.random.default_rng(3)
    x = step_inputs(step, rng)
    for outputs, inputs in ((["F", "J"], ["u", "known", "p"]),
                            (["fibre", "next_knowns"], ["u", "known", "p"]),
                            (["predict"], ["known", "p"])):
        if not all(plain.outputs[o] for o in outputs):
            continue
        want = plain.numpy_function(outputs, inputs)(*[x[i] for i in inputs])
        got = compacted.numpy_function(outputs, inputs)(*[x[i] for i in inputs])
        for a, b in zip(got, want):
            scale = np.maximum(np.abs(b), 1.0)
            assert np.all(np.abs(a - b) <= 1e-12 * scale), (outputs, np.abs(a - b).max())
    assert compacted.fingerprint() != plain.fingerprint()


def test_a_sum_and_its_negation_are_one_node():
    a, b, c = sp.symbols("a b c", real=True)
    g = Graph()
    x, y, z = (g.input(s) for s in (a, b, c))
    s1 = g.add(x, g.neg(y))  # a − b
    s2 = g.add(y, g.neg(x))  # b − a
    total = g.add(g.mul(z, s1), g.mul(z, s2), z)  # c(a − b) + c(b − a) + c = c
    h, (out, o1, o2) = compact(g, [total, s1, s2])
    assert to_sympy(h, [out])[0] == c
    assert h.op[o2] == MUL and h.args[o2] == (h.minus_one, o1)
    assert sp.expand(to_sympy(h, [o1])[0] - (a - b)) == 0


def test_products_sharing_all_but_one_factor_share_their_prefix():
    syms = sp.symbols("t1 t5 k10 k13 k16", real=True)
    g = Graph()
    t1, t5, *ks = (g.input(s) for s in syms)
    two = g.const(2)
    products = [g.mul(two, t1, t5, k) for k in ks]
    h, outs = compact(g, products)
    prefixes = {h.args[o][0] for o in outs}
    assert len(prefixes) == 1, "2·t1·t5 is computed once"
    (prefix,) = prefixes
    assert sp.expand(to_sympy(h, [prefix])[0] - 2 * syms[0] * syms[1]) == 0
    assert all(len(h.args[o]) == 2 for o in outs)
    assert [sp.expand(e) for e in to_sympy(h, outs)] == [
        2 * syms[0] * syms[1] * k for k in syms[2:]]
    assert all(h.op[o] == MUL for o in outs) and h.op[prefix] != ADD


_OPERATOR = re.compile(r"[-+*/]")


def kernel_operations(source: str) -> int:
    """Arithmetic operators (+ − · /) in the straight-line statements of a kernel's C."""
    count = 0
    for line in source.splitlines():
        text = line.strip()
        if text.startswith(("const double ", "w[", "F[", "J[", "fibre[", "u[", "known_next[")):
            rhs = re.sub(r"\[[^\]]*\]", "", text.split("=", 1)[1])
            count += len(_OPERATOR.findall(re.sub(r"\d[eE][-+]\d", "", rhs)))
    return count


def test_the_kernel_of_three_linked_rigid_bodies_stays_small():
    """spherical_chain(3): 6728 operations before compaction and the shared residual parts,
    3503 with them (the C compiler's time is about proportional to both the operations and
    the statements); the bound leaves 15 % for legitimate changes and fails on a return to
    the old size.  The cold unit is not counted: it holds the residual's scale (evaluated
    only when a rounding floor is tested, compiled at a low level beside the others)."""
    kernel = toolchain.step_kernel(systems.spherical_chain(3).euler_lagrange())
    text = kernel.source + "".join(unit for name, unit in kernel.units
                                   if name not in kernel.cold)
    assert kernel_operations(text) <= 4000


_DIGEST = """
import hashlib
from unittest import mock
from symgroupoid.runtime.toolchain import step_kernel
from symgroupoid.systems import spherical_chain
mock.patch("symgroupoid.codegen._kernel.PART_SIZE", 60).start()
k = step_kernel(spherical_chain(2).euler_lagrange())
print(hashlib.sha256((k.source + "".join(u for _, u in k.units)).encode()).hexdigest())
"""


@pytest.mark.slow
def test_compacted_kernels_do_not_depend_on_the_hash_seed():
    digests = set()
    for seed in ("1", "2"):
        out = subprocess.run([sys.executable, "-c", _DIGEST], capture_output=True, text=True,
                             cwd=REPO, check=True,
                             env={**os.environ, "PYTHONHASHSEED": seed})
        digests.add(out.stdout.strip())
    assert len(digests) == 1
