"""The kernel cache: warm loads in new processes, concurrent builds, damage, compiler trouble."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from kernel_support import REPO, isolated_cache, needs_cc  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid.runtime import CompilationError, CompilerNotFoundError, cache_root, toolchain
from symgroupoid.runtime.toolchain import translation_units

pytestmark = needs_cc

SCRIPT = """
import json, os, sys, time
from pathlib import Path
import sympy as sp
import symgroupoid as sg
from symgroupoid.runtime import toolchain

h, k = sp.symbols("h k", positive=True)
def L(g):
    (q0,), (q1,) = g.source, g.target
    return h * (((q1 - q0) / h) ** 2 / 2 - k * ((q0 + q1) / 2) ** 2 / 2)
step = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                         name="oscillator").euler_lagrange()
barrier = os.environ.get("BARRIER")
if barrier:
    Path(barrier, f"ready-{os.getpid()}").touch()
    while not Path(barrier, "go").exists():
        time.sleep(0.005)
t0 = time.process_time()  # CPU time: a busy machine does not inflate it
sim = sg.compile_step(step, backend="c")
seconds = time.process_time() - t0
traj = sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0})
print(json.dumps({"seconds": seconds, "entry": str(sim.cache_entry), **toolchain.STATS,
                  "final": traj.states[-1].tolist()}))
"""


def run_script(cache: Path, **env) -> dict:
    result = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                            env={**os.environ, "SYMGROUPOID_CACHE": str(cache),
                                 "PYTHONPATH": str(REPO), **env})
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def oscillator():
    h, k = sp.symbols("h k", positive=True)

    def L(g):
        (q0,), (q1,) = g.source, g.target
        return h * (((q1 - q0) / h) ** 2 / 2 - k * ((q0 + q1) / 2) ** 2 / 2)

    return sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                             name="oscillator").euler_lagrange()


def cache_contents(cache: Path) -> dict:
    return {d: sorted(p.name for p in (cache / d).iterdir()) if (cache / d).exists() else []
            for d in ("index", "kernels", "locks", "tmp")}


def test_cache_root_resolution(monkeypatch, tmp_path):
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path / "a"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache_root() == tmp_path / "a"
    monkeypatch.delenv("SYMGROUPOID_CACHE")
    assert cache_root() == tmp_path / "xdg" / "symgroupoid"
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert cache_root() == Path.home() / ".cache" / "symgroupoid"


def test_second_process_hits_the_cache_and_loads_fast():
    cold = run_script(cache_root())
    assert (cold["codegen"], cold["builds"], cold["loads"]) == (1, 1, 1)
    warm = run_script(cache_root())
    assert (warm["codegen"], warm["builds"], warm["loads"]) == (0, 0, 1)
    assert warm["entry"] == cold["entry"] and warm["final"] == cold["final"]
    assert warm["seconds"] < 0.050, f"warm load took {warm['seconds'] * 1e3:.1f} ms of CPU"
    contents = cache_contents(cache_root())
    assert len(contents["index"]) == 1 and len(contents["kernels"]) == 1
    assert contents["tmp"] == []


def test_concurrent_builds_of_one_kernel_compile_once(tmp_path):
    """Four processes missing one new kernel at the same moment: one runs the compiler
    (holding the kernel's lock), the others wait and load its result."""
    barrier = tmp_path / "barrier"
    barrier.mkdir()
    env = {**os.environ, "SYMGROUPOID_CACHE": str(cache_root()), "PYTHONPATH": str(REPO),
           "BARRIER": str(barrier)}
    procs = [subprocess.Popen([sys.executable, "-c", SCRIPT], stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True, env=env) for _ in range(4)]
    deadline = time.monotonic() + 120
    while len(list(barrier.glob("ready-*"))) < len(procs) and time.monotonic() < deadline:
        time.sleep(0.01)
    (barrier / "go").touch()
    results = []
    for proc in procs:
        out, err = proc.communicate(timeout=180)
        assert proc.returncode == 0, err
        results.append(json.loads(out.strip().splitlines()[-1]))
    assert sum(r["builds"] for r in results) == 1, [r["builds"] for r in results]
    assert [r["loads"] for r in results] == [1, 1, 1, 1]
    assert len({r["entry"] for r in results}) == 1
    assert all(r["final"] == results[0]["final"] for r in results)
    contents = cache_contents(cache_root())
    assert len(contents["kernels"]) == 1 and contents["tmp"] == []
    assert contents["locks"] == [f"{Path(results[0]['entry']).name}.lock"]
    entry = Path(results[0]["entry"])
    units = ["oscillator_cold.c", "oscillator_unit1.c"] if translation_units() > 1 else []
    assert sorted(p.name for p in entry.iterdir() if p.suffix != ".so") == sorted([
        "manifest.json", "oscillator.c", "oscillator.h", *units])


def _entry_and_manifest(cache: Path) -> tuple[Path, dict]:
    (entry,) = (cache / "kernels").iterdir()
    return entry, json.loads((entry / "manifest.json").read_text())


@pytest.mark.parametrize("damage", ["truncate", "manifest", "remove"])
def test_damaged_cache_entry_is_detected_and_rebuilt(damage):
    """Built here without loading (a library loaded by this process is never damaged)."""
    step = oscillator()
    flags = toolchain.step_flags(step, None)  # what compile_step builds by default
    cache = sg.runtime.toolchain.KernelCache(cache_root())
    toolchain.build_step(step, flags, cache, toolchain.input_key(step, flags))
    reference = step.compile(backend="numpy").simulate({"q": (1.0, 0.999)}, 100,
                                                      {"h": 0.01, "k": 1.0}).states[-1]
    entry, manifest = _entry_and_manifest(cache_root())
    library = entry / manifest["library"]
    if damage == "truncate":
        data = library.read_bytes()
        library.write_bytes(data[: len(data) // 2])
    elif damage == "manifest":
        (entry / "manifest.json").write_text("{not json")
    else:
        library.unlink()
    again = run_script(cache_root())
    assert (again["codegen"], again["builds"]) == (1, 1)
    assert np.abs(np.array(again["final"]) - reference).max() <= 1e-12
    entry, manifest = _entry_and_manifest(cache_root())
    assert sg.runtime.toolchain.file_sha256(entry / manifest["library"]) == manifest["sha256"]
    assert cache_contents(cache_root())["tmp"] == []


def test_compiler_error_shows_the_message_and_leaves_the_cache_clean():
    with pytest.raises(CompilationError) as info:
        sg.compile_step(oscillator(), backend="c", flags=["-fno-such-option-for-symgroupoid"])
    assert "-fno-such-option-for-symgroupoid" in info.value.output
    assert "Compiler output:" in str(info.value) and info.value.output in str(info.value)
    contents = cache_contents(cache_root())
    assert contents["kernels"] == [] and contents["index"] == [] and contents["tmp"] == []


def test_missing_compiler_falls_back_to_numpy(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", "/nonexistent/bin/cc-symgroupoid")
    step = oscillator()
    with pytest.warns(RuntimeWarning, match="not found.*NumPy backend") as caught:
        sim = sg.compile_step(step)
    assert sim.backend == "numpy"
    assert caught[0].filename == __file__  # the user's line, not the library's wrapper
    with pytest.raises(CompilerNotFoundError, match="cc-symgroupoid"):
        sg.compile_step(step, backend="c")
    assert cache_contents(cache_root())["kernels"] == []
    # a kernel already in the cache needs no compiler (the compiler command, CC, is part of
    # the build environment in its key: here the default one, absent from PATH)
    monkeypatch.delenv("CC")
    sg.compile_step(step, backend="c")
    (tmp_path / "no-compiler").mkdir()
    monkeypatch.setenv("PATH", str(tmp_path / "no-compiler"))
    with pytest.raises(CompilerNotFoundError):
        toolchain.find_compiler()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sg.compile_step(step).backend == "c"


def test_backend_selection(monkeypatch):
    step = oscillator()
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "numpy")
    assert sg.compile_step(step).backend == "numpy"
    assert step.compile(backend="numpy").backend == "numpy"
    with pytest.raises(ValueError, match="backend must be one of"):
        sg.compile_step(step, backend="fortran")
    monkeypatch.setenv("SYMGROUPOID_BACKEND", "gpu")
    with pytest.raises(ValueError, match="SYMGROUPOID_BACKEND"):
        sg.compile_step(step)


def test_fingerprint_distinguishes_and_is_stable():
    x, y = sp.symbols("x y", real=True)
    fp = toolchain.fingerprint
    assert fp([x + 2 * y]) == fp([2 * y + x])
    assert fp([x + 2 * y]) != fp([x + 3 * y])
    assert fp([x * y, x]) != fp([x, x * y])
    assert fp([sp.Float("0.1") * x]) != fp([sp.Rational(1, 10) * x])
    assert fp([sp.Symbol("x", real=True)]) != fp([sp.Symbol("x", positive=True)])
    step = oscillator()
    assert toolchain.input_key(step, ["-O2"]) == toolchain.input_key(oscillator(), ["-O2"])
    assert toolchain.input_key(step, ["-O2"]) != toolchain.input_key(step, ["-O3"])


def test_codegen_digest_covers_the_build_rules(monkeypatch, tmp_path):
    """The kernel cache's code digest hashes the code generator, the expression graph and
    the toolchain's build rules (step_kernel, the per-unit flags a cache key's flags do not
    all name, the compiler's command lines and the build of the units), by content."""
    package = Path(toolchain.__file__).resolve().parents[2]
    sources = toolchain.codegen_sources()
    for name in ("_step_kernel.py", "_flags.py", "_compiler.py", "_cffi_build.py"):
        assert package / "runtime" / "toolchain" / name in sources
    for folder in ("codegen", "ir"):
        assert set((package / folder).glob("*.py")) <= set(sources)
    rules = tmp_path / "_flags.py"
    rules.write_text("COLD_LEVEL = '-O1'\n", encoding="ascii")
    monkeypatch.setattr("symgroupoid.runtime.toolchain._step_kernel.codegen_sources",
                        lambda: [rules])
    before = toolchain.codegen_digest.__wrapped__()
    rules.write_text("COLD_LEVEL = '-O0'\n", encoding="ascii")
    assert toolchain.codegen_digest.__wrapped__() != before
