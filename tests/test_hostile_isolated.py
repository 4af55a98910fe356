"""Hostile calls of a compiled kernel's C entry points in a child process, where a crash
shows as a signal instead of ending the test run.

The child loads the extension module of the rigid-body kernel from the test cache (plain
cffi: no SymPy, no Python-side checks) and calls ``<prefix>_simulate_batch`` with what an
embedding C program might pass: thread counts far beyond the runs and the machine
(found by the hostile-input suite: a team of 10⁵ OpenMP threads crashed the process, and
2³¹ − 1 aborted it in libgomp), null buffers and a capacity that is too small.
"""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
from _hostile import scratch_cwd  # noqa: F401  (autouse fixture)
from kernel_support import SEED_DATA, compiled, initial_state, needs_cc

CHILD = r"""
import json, sys
import numpy as np
from symgroupoid.runtime.toolchain import load_extension

path, name, prefix, known_file = sys.argv[1:5]
module = load_extension(path, name)
lib, ffi = module.lib, module.ffi
fn = getattr(lib, prefix + "_simulate_batch")
data = np.load(known_file)
known, p = data["known"], data["p"]
B, n_k = known.shape
results = {}
for label, threads, rows in (("huge", 100000, 3), ("int max", 2**31 - 1, 3),
                             ("negative", -5, 3), ("zero", 0, 3), ("too few rows", 4, 2)):
    states = np.full(B * rows * n_k, -7.0)
    its = np.zeros(B * (rows - 1), np.longlong)
    norms = np.zeros(B * (rows - 1))
    kept = np.zeros(B, np.dtype("l"))
    status = np.zeros(B, np.intc)
    rc = fn(B, ffi.from_buffer("double[]", known), ffi.from_buffer("double[]", p), 0,
            ffi.NULL, 0, 4, 2,
            ffi.NULL, ffi.from_buffer("double[]", states), rows,
            ffi.from_buffer("long long[]", its), ffi.from_buffer("double[]", norms),
            ffi.from_buffer("long[]", kept), ffi.from_buffer("int[]", status),
            ffi.NULL, ffi.NULL, ffi.NULL, ffi.NULL, threads)
    results[label] = {"rc": int(rc), "kept": kept.tolist(), "status": status.tolist(),
                      "last": states.reshape(B, rows, n_k)[:, -1].tolist()}
print(json.dumps(results))
"""


@needs_cc
def test_batch_entry_point_survives_any_thread_count(tmp_path):
    sim = compiled("rigid_body")
    manifest = json.loads((sim.cache_entry / "manifest.json").read_text())
    flat = initial_state(sim, "rigid_body")
    known = np.stack([flat] * 3)
    p = sim.parameters(SEED_DATA["rigid_body"][0])
    np.savez(tmp_path / "known.npz", known=known, p=p)
    child = subprocess.run(
        [sys.executable, "-c", CHILD, str(sim.cache_entry / manifest["library"]),
         manifest["module"], sim.kernel.prefix, str(tmp_path / "known.npz")],
        capture_output=True, text=True, timeout=300)
    assert child.returncode == 0, (f"the child process died (status {child.returncode}): "
                                   f"{child.stderr[-2000:]}")
    results = json.loads(child.stdout)
    expected = sim.simulate(flat, 4, SEED_DATA["rigid_body"][0], every=2).states[-1]
    for label in ("huge", "int max", "negative", "zero"):
        got = results[label]
        assert got["rc"] == 0 and got["kept"] == [3, 3, 3] and got["status"] == [0, 0, 0]
        assert np.array_equal(np.array(got["last"]), np.stack([expected] * 3)), label
    assert results["too few rows"]["rc"] == 4  # INVALID_ARGUMENT, nothing written
    assert np.all(np.array(results["too few rows"]["last"]) == -7.0)
