"""The kernel cache under real-world faults: read-only and unwritable roots, killed builders,
files where directories belong, unloadable modules, a broken compiler, locks, the umask."""

from __future__ import annotations

import contextlib
import ctypes
import fcntl
import functools
import json
import os
import signal
import stat
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    OSCILLATOR,
    isolated_cache,
    needs_cc,
    oscillator,
    subprocess_env,
)

import symgroupoid as sg
from symgroupoid.codegen import emit_c, generate_program_c
from symgroupoid.ir import Graph, Program, from_sympy

# a window program's evaluator has no public constructor: its cache path is reached here
from symgroupoid.runtime import CacheError, CompilationError, compile_program, toolchain
from symgroupoid.runtime.toolchain import optimisation_flags

pytestmark = needs_cc

SCRIPT = OSCILLATOR + '''
import json, sys, warnings
from symgroupoid.runtime import toolchain

with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    sim = sg.compile_step(oscillator(), backend="c")
    final = sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]
print(json.dumps({"warnings": [str(w.message) for w in caught], "entry": str(sim.cache_entry),
                  "backend": sim.backend, "final": final.tolist(), **toolchain.STATS}))
'''

CC_WRAPPER = """#!/bin/sh
echo $$ > "$SG_COMPILER_STARTED"
sleep 60
exec cc "$@"
"""


@pytest.fixture
def cache_dir() -> Path:
    """This test's (empty, not yet created) cache root, set up by ``isolated_cache``."""
    return toolchain.cache_root()


def reference_final() -> np.ndarray:
    sim = oscillator().compile(backend="numpy")
    return sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]


def _drop_file_permission_override() -> None:
    """In a child running as root: remove CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH from the
    bounding set, so that after exec file permissions apply to it as to any owner."""
    libc = ctypes.CDLL(None, use_errno=True)
    for capability in (1, 2):
        if libc.prctl(24, capability, 0, 0, 0) != 0:  # PR_CAPBSET_DROP
            raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP) failed")


#: the environment of a child process (its cache locks given up after 60 s)
script_env = functools.partial(subprocess_env, 60)


def run_script(env: dict[str, str], unprivileged: bool = False) -> dict:
    """Run SCRIPT in a new process; ``unprivileged``: with file permissions enforced even
    when the tests run as root."""
    preexec = _drop_file_permission_override if unprivileged and os.geteuid() == 0 else None
    try:
        result = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True,
                                text=True, env=env, preexec_fn=preexec, timeout=300)
    except subprocess.SubprocessError as exc:
        pytest.skip(f"cannot enforce file permissions for a root process: {exc}")
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def tree(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")) if root.exists() else []


@contextlib.contextmanager
def read_only(*paths: Path):
    modes = [p.stat().st_mode for p in paths]
    try:
        for p in paths:
            p.chmod(0o555)
        yield
    finally:
        for p, mode in zip(paths, modes):
            p.chmod(stat.S_IMODE(mode))


@contextlib.contextmanager
def umask(mask: int):
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


# -- concurrency, stale build directories, locks ------------------------------------------------

def slow_compiler(tmp_path: Path, cache_dir: Path) -> tuple[Path, dict]:
    """(the file where the compiler writes its pid when it starts, the environment of a
    script whose compiler sleeps a minute first)."""
    wrapper = tmp_path / "slow-cc"
    wrapper.write_text(CC_WRAPPER)
    wrapper.chmod(0o755)
    started = tmp_path / "compiler-started"
    return started, script_env(SYMGROUPOID_CACHE=str(cache_dir), CC=str(wrapper),
                               SG_COMPILER_STARTED=str(started), SYMGROUPOID_OPENMP="0")


def test_killed_builder_leaves_no_build_directory_and_blocks_nobody(tmp_path, cache_dir):
    """kill -9 of a process while its compiler runs: its build directory stays behind; the
    next use removes it (the lock died with the process, not with the orphaned compiler)
    and builds exactly once."""
    started, env = slow_compiler(tmp_path, cache_dir)
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT], env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not started.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert started.exists(), "the build never reached the compiler"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        _assert_ends_soon(int(started.read_text()))  # (on Linux: the parent's death kills it)
        left = sorted(p.name for p in (cache_dir / "tmp").iterdir())
        assert len(left) == 1 and left[0].startswith("build-"), left
        t0 = time.monotonic()
        again = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir),
                                      SYMGROUPOID_LOCK_TIMEOUT="30", SYMGROUPOID_OPENMP="0"))
        assert time.monotonic() - t0 < 30
    finally:  # the orphaned compiler wrapper, in a process group of its own
        with contextlib.suppress(ProcessLookupError, ValueError, OSError):
            os.killpg(int(started.read_text()), signal.SIGKILL)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert (again["builds"], again["loads"]) == (1, 1)
    assert np.abs(np.array(again["final"]) - reference_final()).max() <= 1e-12
    assert list((cache_dir / "tmp").iterdir()) == []


def _assert_ends_soon(pid: int) -> None:
    """On Linux, the process ``pid`` ends within 10 s (it was running the compiler of a
    build whose process was killed)."""
    if not sys.platform.startswith("linux"):
        return
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            status = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
        except FileNotFoundError:
            return
        if status == "Z":  # ended, not yet reaped by its new parent
            return
        time.sleep(0.05)
    raise AssertionError(f"the compiler run {pid} outlived the process that started it")


def test_a_compiler_that_does_not_finish_is_stopped(tmp_path, cache_dir):
    """(A compiler that hangs hung the build, and with it every process waiting for its
    lock, for ever.)  A compiler run that takes longer than SYMGROUPOID_BUILD_TIMEOUT is
    killed with what it started, and the build is a CompilationError saying so."""
    started, env = slow_compiler(tmp_path, cache_dir)
    script = OSCILLATOR + """
from symgroupoid.runtime import CompilationError
try:
    sg.compile_step(oscillator(), backend="c")
except CompilationError as exc:
    print(str(exc).splitlines()[0])
"""
    t0 = time.monotonic()
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          env={**env, "SYMGROUPOID_BUILD_TIMEOUT": "1.5"}, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "did not finish within 1.5 s and was stopped" in done.stdout, done.stdout
    assert time.monotonic() - t0 < 50  # the compiler sleeps 60 s
    _assert_ends_soon(int(started.read_text()))
    assert list((cache_dir / "tmp").iterdir()) == []
    for bad in ("0", "-3", "soon", "inf"):
        bad_env = {**env, "SYMGROUPOID_BUILD_TIMEOUT": bad}
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                              env=bad_env, timeout=120)
        assert "SYMGROUPOID_BUILD_TIMEOUT must be a positive number of seconds" in done.stderr


def test_the_compiler_keeps_its_temporary_files_in_the_build(tmp_path, cache_dir,
                                                            monkeypatch):
    """(The compiler wrote its temporary files, ``cc*.s``, to the system's temporary
    directory, where a build killed mid-way left them.)  Every compiler run of a build sees
    ``TMPDIR`` in the build's own directory, inside the cache; the compiler's probes, in
    the probe's own temporary directory."""
    log = tmp_path / "tmpdirs"
    wrapper = tmp_path / "logging-cc"
    wrapper.write_text(f'#!/bin/sh\necho "$TMPDIR" >> {log}\nexec cc "$@"\n')
    wrapper.chmod(0o755)
    monkeypatch.setenv("CC", str(wrapper))
    sg.compile_step(oscillator(), backend="c")
    seen = log.read_text().split()
    builds = [d for d in seen if not Path(d).name.startswith("symgroupoid-")]
    assert builds and all(Path(d).resolve().is_relative_to(cache_dir.resolve())
                          for d in builds)
    assert all(Path(d).resolve().is_relative_to(cache_dir.resolve())
               or Path(d).name.startswith(("symgroupoid-probe-", "symgroupoid-openmp-"))
               for d in seen)


def test_threads_building_kernels_at_once(cache_dir):
    """Threads of one process: one compiler run per kernel, and builds of different
    kernels do not mix (each build changes the working directory and captures fds 1, 2)."""
    names = ["oscillator_t1", "oscillator_t2", "oscillator_t1", "oscillator_t3"]
    results: dict[int, np.ndarray] = {}
    errors: list[BaseException] = []

    def run(i: int) -> None:
        try:
            sim = sg.compile_step(oscillator(names[i]), backend="c")
            results[i] = sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    builds = toolchain.STATS["builds"]
    threads = [threading.Thread(target=run, args=(i,)) for i in range(len(names))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=300)
    assert errors == [] and len(results) == len(names)
    assert toolchain.STATS["builds"] == builds + 3
    assert all(np.abs(r - reference_final()).max() <= 1e-12 for r in results.values())
    assert len(list((cache_dir / "kernels").iterdir())) == 3


def test_sweep_spares_live_builders_and_removes_abandoned_leftovers(cache_dir):
    step = oscillator()
    key = toolchain.source_key_of(toolchain.step_kernel(step), toolchain.step_flags(step, None))
    toolchain.writable_root(cache_dir)
    tmp = cache_dir / "tmp"
    live = tmp / f"build-{key}-live"
    dead = tmp / f"build-{'0' * 32}-dead"
    old_unkeyed, new_unkeyed = tmp / "build-abc123xy", tmp / "build-def456uv"  # mkdtemp's
    for path in (live, dead, old_unkeyed, new_unkeyed):
        path.mkdir()
        (path / "x.o").write_bytes(b"partial")
    os.utime(old_unkeyed, (time.time() - 2 * toolchain.GRACE,) * 2)
    fd = os.open(cache_dir / "locks" / f"{key}.lock", os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # as a live builder of this kernel holds it
        toolchain.sweep(cache_dir)
        assert sorted(p.name for p in tmp.iterdir()) == sorted([live.name, new_unkeyed.name])
    finally:
        os.close(fd)
    toolchain.sweep(cache_dir)
    assert [p.name for p in tmp.iterdir()] == [new_unkeyed.name]


def test_warm_use_removes_a_dead_builders_directory(cache_dir):
    """The leftover of a killed build of another kernel goes on the next warm load too."""
    env = script_env(SYMGROUPOID_CACHE=str(cache_dir))
    assert run_script(env)["builds"] == 1
    dead = cache_dir / "tmp" / f"build-{'0' * 32}-killed"
    dead.mkdir()
    (dead / "partial.o").write_bytes(b"partial")
    warm = run_script(env)
    assert (warm["builds"], warm["loads"]) == (0, 1)
    assert list((cache_dir / "tmp").iterdir()) == []


def test_waiting_for_a_hung_builder_times_out_clearly(monkeypatch, cache_dir):
    step = oscillator("oscillator_lock")
    key = toolchain.source_key_of(toolchain.step_kernel(step), toolchain.step_flags(step, None))
    lock = cache_dir / "locks" / f"{key}.lock"
    lock.parent.mkdir(parents=True, exist_ok=True)  # the OpenMP probe may have made it
    fd = os.open(lock, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        os.write(fd, b"pid 4242 on some-host\n")
        monkeypatch.setenv("SYMGROUPOID_LOCK_TIMEOUT", "0.3")
        t0 = time.monotonic()
        with pytest.raises(CacheError, match="pid 4242 on some-host") as info:
            sg.compile_step(step, backend="c")
        assert 0.3 <= time.monotonic() - t0 < 10
        assert str(lock) in str(info.value) and "SYMGROUPOID_LOCK_TIMEOUT" in str(info.value)
        monkeypatch.setenv("SYMGROUPOID_LOCK_TIMEOUT", "soon")
        with pytest.raises(CacheError, match="positive number of seconds"):
            sg.compile_step(step, backend="c")
    finally:
        os.close(fd)
    monkeypatch.setenv("SYMGROUPOID_LOCK_TIMEOUT", "5")
    assert sg.compile_step(step, backend="c").backend == "c"


# -- unwritable roots ---------------------------------------------------------------------------

def _assert_fell_back(result: dict, unwritable: Path) -> None:
    (message,) = [w for w in result["warnings"] if "kernel cache" in w]
    assert str(unwritable) in message and "not writable" in message
    assert "SYMGROUPOID_CACHE" in message
    assert result["backend"] == "c" and result["builds"] == 1
    assert not Path(result["entry"]).is_relative_to(unwritable)
    assert not Path(result["entry"]).exists(), "the private cache is removed at exit"
    assert np.abs(np.array(result["final"]) - reference_final()).max() <= 1e-12


def test_read_only_cache_root_falls_back_with_one_warning(cache_dir):
    cache_dir.mkdir()
    with read_only(cache_dir):
        result = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)),
                            unprivileged=True)
    _assert_fell_back(result, cache_dir)
    assert tree(cache_dir) == []


def test_read_only_populated_cache_is_used_without_warning(cache_dir):
    first = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert first["builds"] == 1
    dirs = [cache_dir, *(p for p in cache_dir.rglob("*") if p.is_dir())]
    before = tree(cache_dir)
    with read_only(*dirs):
        warm = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)),
                          unprivileged=True)
    assert warm["warnings"] == [] and (warm["builds"], warm["loads"]) == (0, 1)
    assert warm["entry"] == first["entry"] and warm["final"] == first["final"]
    assert tree(cache_dir) == before


def test_unwritable_home_falls_back(tmp_path):
    home = tmp_path / "home"
    home.mkdir()
    with read_only(home):
        result = run_script(script_env(HOME=str(home), SYMGROUPOID_CACHE=None,
                                       XDG_CACHE_HOME=None), unprivileged=True)
    _assert_fell_back(result, home / ".cache" / "symgroupoid")
    assert str(home / ".cache") in result["warnings"][0]
    assert tree(home) == []


def test_cache_root_that_is_a_file_falls_back(cache_dir):
    cache_dir.parent.mkdir(parents=True, exist_ok=True)
    cache_dir.write_text("not a cache")
    result = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    _assert_fell_back(result, cache_dir)
    assert "not a directory" in result["warnings"][0]
    assert cache_dir.read_text() == "not a cache"


def test_cache_root_whose_path_is_not_utf8_falls_back(tmp_path, monkeypatch):
    """A cache path of Latin-1 bytes (b"cache_\\xff\\xfe"): the kernel was built into it and
    then could not be loaded, a raw UnicodeEncodeError in this process and in every later
    one.  Such a root is not used: one warning, the run from a private cache."""
    root = Path(os.fsdecode(os.fsencode(tmp_path) + b"/cache_\xff\xfe"))
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(root))
    with pytest.warns(RuntimeWarning, match="is not used .*not valid UTF-8"):
        sim = sg.compile_step(oscillator(), backend="c")
    assert sim.backend == "c" and not sim.cache_entry.is_relative_to(root)
    final = sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]
    assert np.abs(final - reference_final()).max() <= 1e-12
    assert not os.path.lexists(root)  # never created


# -- damage -------------------------------------------------------------------------------------

#: the directories a cache root keeps (docs/cli.md, the cache)
CACHE_LAYOUT = ("index", "kernels", "locks", "tmp")


@pytest.mark.parametrize("name", CACHE_LAYOUT)
def test_layout_directory_that_is_a_file_is_replaced(cache_dir, name):
    cache_dir.mkdir()
    (cache_dir / name).write_text("in the way")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim = sg.compile_step(oscillator(), backend="c")
    assert sim.backend == "c" and sim.cache_entry.is_relative_to(cache_dir)
    assert all((cache_dir / d).is_dir() for d in CACHE_LAYOUT)


def _build_without_loading(step, cache_root: Path) -> tuple[Path, dict]:
    cache = toolchain.KernelCache(cache_root)
    flags = toolchain.step_flags(step, None)  # what compile_step builds by default
    toolchain.build_step(step, flags, cache, toolchain.input_key(step, flags))
    (entry,) = (cache_root / "kernels").iterdir()
    return entry, json.loads((entry / "manifest.json").read_text())


def _replace_library_consistently(entry: Path, manifest: dict, data: bytes) -> None:
    """Replace the module and its manifest so that the hash matches the new bytes (by a
    rename: writing into a module some process has loaded would crash that process)."""
    library = entry / manifest["library"]
    replacement = entry / "replacement"
    replacement.write_bytes(data)
    os.replace(replacement, library)
    manifest = {**manifest, "sha256": toolchain.file_sha256(library)}
    (entry / "manifest.json").write_text(json.dumps(manifest))


def test_a_type_table_edited_with_an_unknown_opcode_is_rebuilt(cache_dir):
    """(Four bytes of the manifest's type table set to 0xff, its hash recomputed: the load
    escaped as a raw NotImplementedError, "op=255", on every use.)  The entry is rebuilt.
    A table edited at random can still crash cffi itself: the cache is trusted for what it
    runs (docs/how-to/kernel-cache.md), which is why only its owner may write it."""
    import base64

    entry, manifest = _build_without_loading(oscillator(), cache_dir)
    raw = bytearray(base64.b64decode(manifest["types"]["_types"]["b64"]))
    raw[8:12] = b"\xff\xff\xff\xff"
    manifest["types"]["_types"] = {"b64": base64.b64encode(bytes(raw)).decode()}
    manifest["types_sha256"] = toolchain.table_sha256(manifest["types"])
    (entry / "manifest.json").write_text(json.dumps(manifest))
    again = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert (again["builds"], again["loads"]) == (1, 1)
    assert np.abs(np.array(again["final"]) - reference_final()).max() <= 1e-12


@pytest.mark.slow
def test_garbage_module_with_matching_manifest_is_rebuilt(cache_dir):
    entry, manifest = _build_without_loading(oscillator(), cache_dir)
    _replace_library_consistently(entry, manifest, b"\x7fELF but not really" * 100)
    again = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert again["warnings"] == [] and (again["builds"], again["loads"]) == (1, 1)
    assert np.abs(np.array(again["final"]) - reference_final()).max() <= 1e-12
    manifest = json.loads((entry / "manifest.json").read_text())
    assert (entry / manifest["library"]).read_bytes()[:4] == b"\x7fELF"
    assert list((cache_dir / "tmp").iterdir()) == []


def test_a_library_without_the_kernels_entry_points_is_rebuilt(cache_dir, tmp_path):
    """A valid shared library (with a manifest that hashes it) that is not the kernel: cffi's
    lookup of the first entry point raised a raw ``ffi.error`` (an internal error on the
    command line) on every use.  It does not load now (every declared symbol is resolved at
    load, and the library closed again, so that the rebuilt one at the same path is the one
    loaded): the entry is rebuilt in the same process."""
    entry, manifest = _build_without_loading(oscillator(), cache_dir)
    (tmp_path / "other.c").write_text("int other_symbol(void) { return 1; }\n")
    subprocess.run(["cc", "-shared", "-fPIC", "-o", str(tmp_path / "other.so"),
                    str(tmp_path / "other.c")], check=True, timeout=120)
    _replace_library_consistently(entry, manifest, (tmp_path / "other.so").read_bytes())
    again = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert (again["builds"], again["loads"]) == (1, 1)
    assert np.abs(np.array(again["final"]) - reference_final()).max() <= 1e-12


def test_an_index_entry_naming_a_kernel_of_other_sizes_is_rebuilt(cache_dir):
    """The index maps a step's inputs to the kernel built for them; one that named another
    step's kernel (of other sizes) raised ShapeError naming that step, on every use."""
    cache = toolchain.KernelCache(cache_dir)
    h = sp.Symbol("h", positive=True)

    def plane(g):
        (x0, y0), (x1, y1) = g.source, g.target
        return ((x1 - x0) ** 2 + (y1 - y0) ** 2) / (2 * h) - h * (x0 ** 2 + y0 ** 2) / 2

    other = sg.DiscreteSystem(sg.PairGroupoid(sg.EuclideanSpace("x y")), plane,
                              parameters=[h], name="oscillator").euler_lagrange()
    for step in (oscillator(), other):
        flags = toolchain.step_flags(step, None)
        toolchain.build_step(step, flags, cache, toolchain.input_key(step, flags))
    step = oscillator()
    own_key = toolchain.input_key(step, toolchain.step_flags(step, None))
    index = cache_dir / "index" / f"{own_key}.json"
    other_key = toolchain.input_key(other, toolchain.step_flags(other, None))
    other_source = json.loads((cache_dir / "index" / f"{other_key}.json").read_text())
    index.write_text(json.dumps(other_source))
    again = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert again["codegen"] == 1 and again["warnings"] == []
    assert np.abs(np.array(again["final"]) - reference_final()).max() <= 1e-12
    assert json.loads(index.read_text())["source_key"] != other_source["source_key"]


def test_kernel_directory_replaced_by_a_file_is_rebuilt(cache_dir):
    entry, _ = _build_without_loading(oscillator(), cache_dir)
    toolchain.remove_tree(entry)
    entry.write_text("in the way")
    again = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert (again["builds"], again["loads"]) == (1, 1) and entry.is_dir()
    assert list((cache_dir / "tmp").iterdir()) == []


def test_window_program_with_garbage_module_is_rebuilt(cache_dir):
    """The boundary-value window programs load through the same cache (no step to
    regenerate from: the source this process asked to build is kept)."""
    x, y = sp.symbols("x y")
    g = Graph()
    nodes = {x: g.input(x), y: g.input(y)}
    program = Program(g, {"a": [x, y]}, {"out": [from_sympy(g, e, nodes)
                                                  for e in (x * y + sp.sin(x), x - y)]})
    kernel = generate_program_c("garbage window", program, "a", "out")
    toolchain.build_cached(kernel, optimisation_flags(program.size()), toolchain.KernelCache(),
                          "garbage window")
    (entry,) = (cache_dir / "kernels").iterdir()
    manifest = json.loads((entry / "manifest.json").read_text())
    _replace_library_consistently(entry, manifest, b"garbage" * 64)
    builds = toolchain.STATS["builds"]
    evaluate = compile_program("garbage window", program, "a", "out")
    assert toolchain.STATS["builds"] == builds + 1
    values = np.array([[0.5, 2.0], [1.0, -1.0]])
    expected = np.stack([values[:, 0] * values[:, 1] + np.sin(values[:, 0]),
                         values[:, 0] - values[:, 1]], axis=1)
    assert np.array_equal(evaluate(values), expected)


def test_module_that_never_loads_gives_cache_error(monkeypatch, cache_dir):
    def refuse(path, name, *types):
        raise ImportError(f"{path}: failed to map segment from shared object")

    monkeypatch.setattr("symgroupoid.runtime.toolchain._kernels.load_extension", refuse)
    builds = toolchain.STATS["builds"]
    with pytest.raises(CacheError) as info:
        sg.compile_step(oscillator("oscillator_noexec"), backend="c")
    assert toolchain.STATS["builds"] == builds + 2, "built, then rebuilt once"
    text = str(info.value)
    assert str(cache_dir / "kernels") in text and "SYMGROUPOID_CACHE" in text
    assert 'backend="numpy"' in text


# -- compiler -----------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", ["auto", "c"])
def test_compiler_that_always_fails_says_how_to_use_numpy(monkeypatch, cache_dir, backend):
    monkeypatch.setenv("CC", "/bin/false")
    with pytest.raises(CompilationError) as info:
        sg.compile_step(oscillator(), backend=backend)
    text = str(info.value)
    assert "'/bin/false' fails even on a trivial C file" in text
    assert 'backend="numpy"' in text and "SYMGROUPOID_BACKEND=numpy" in text
    assert tree(cache_dir / "kernels") == [] and tree(cache_dir / "tmp") == []


def test_kernel_rejected_by_a_working_compiler_is_not_blamed_on_the_compiler():
    with pytest.raises(CompilationError) as info:
        sg.compile_step(oscillator(), backend="c", flags=["-fno-such-option-for-symgroupoid"])
    assert "trivial" not in str(info.value) and "SYMGROUPOID_BACKEND=numpy" in str(info.value)


def _has_debug_info(library: Path) -> bool:
    return b".debug_info" in library.read_bytes()


def test_builds_carry_debug_information_only_when_asked(cache_dir):
    plain = sg.compile_step(oscillator(), backend="c")
    flags = toolchain.step_flags(oscillator(), None)
    debug = sg.compile_step(oscillator(), backend="c", flags=[*flags, "-g"])
    manifests = [json.loads((sim.cache_entry / "manifest.json").read_text())
                 for sim in (plain, debug)]
    isa = list(toolchain.vector_flags(toolchain.compiler_command(), flags))  # the processor's
    assert manifests[0]["compile_args"] == ["-g0", *flags, *isa]
    assert manifests[1]["compile_args"] == [*flags, "-g", *isa]
    assert not _has_debug_info(plain.cache_entry / manifests[0]["library"])
    assert _has_debug_info(debug.cache_entry / manifests[1]["library"])


# -- file modes ---------------------------------------------------------------------------------

@pytest.mark.parametrize("mask, expected", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600)],
                         ids=["022", "027", "077"])
def test_emitted_files_follow_the_umask(tmp_path, mask, expected):
    with umask(mask):
        written = emit_c(oscillator(), tmp_path / "out" / "osc")
    assert [stat.S_IMODE(p.stat().st_mode) for p in written] == [expected, expected]


def test_cache_files_and_directories_follow_the_umask(cache_dir):
    with umask(0o027):
        sim = sg.compile_step(oscillator(), backend="c")
    manifest = json.loads((sim.cache_entry / "manifest.json").read_text())
    (index,) = (cache_dir / "index").iterdir()
    modes = {p.name: stat.S_IMODE(p.stat().st_mode) for p in
             (sim.cache_entry, sim.cache_entry / "manifest.json", index,
              sim.cache_entry / f"{manifest['prefix']}.c")}
    assert modes == {sim.cache_entry.name: 0o750, "manifest.json": 0o640, index.name: 0o640,
                     f"{manifest['prefix']}.c": 0o640}


@pytest.mark.slow
def test_make_generated_writes_readable_files(tmp_path):
    with umask(0o022):
        result = subprocess.run([sys.executable, "-m", "symgroupoid", "generate",
                                 str(tmp_path / "generated")], capture_output=True, text=True,
                                env=script_env(), timeout=600)
    assert result.returncode == 0, result.stderr
    files = sorted((tmp_path / "generated").iterdir())
    assert files and {stat.S_IMODE(p.stat().st_mode) for p in files} == {0o644}


@needs_cc
@pytest.mark.parametrize("damage", ["deep manifest", "deep index", "index directory"])
def test_a_damaged_entry_is_rebuilt_not_raised(cache_dir, damage):
    """A manifest or index file nested 5 000 levels deep raised RecursionError from
    compile(), ``cache info`` and ``cache clear --bad``; an index entry that is a directory
    raised IsADirectoryError.  Each is a bad entry: reported, cleared, rebuilt."""
    from symgroupoid.cli import main

    oscillator().compile()
    deep = "[" * 5000 + "]" * 5000
    if damage == "deep manifest":
        for kernel in (cache_dir / "kernels").iterdir():
            (kernel / "manifest.json").write_text(deep)
    for index in (cache_dir / "index").iterdir():
        if damage == "deep index":
            index.write_text(deep)
        elif damage == "index directory":
            index.unlink()
            index.mkdir()
    assert main(["cache", "info"]) == 0
    sim = oscillator().compile()
    np.testing.assert_array_equal(
        sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1],
        reference_final())
    assert main(["cache", "clear", "--bad"]) == 0


TRUNCATING_CC = """#!/bin/sh
# a compiler that exits 0 and leaves its output cut off (a full disk it does not report)
out=""; prev=""
for a in "$@"; do [ "$prev" = "-o" ] && out=$a; prev=$a; done
cc "$@" || exit $?
if [ -n "$out" ] && [ -f "$out" ]; then head -c 3000 "$out" > "$out.cut" && mv "$out.cut" "$out"; fi
exit 0
"""


def test_a_truncated_openmp_probe_is_not_mapped(tmp_path, cache_dir):
    """(The OpenMP probe loaded its probe.so with ctypes without the ELF check that kernels
    get: a compiler that exits 0 and leaves a truncated file killed the process with SIGBUS
    on the first compile.)  The probe now checks it and answers "undetermined", which is not
    recorded; the kernel's own truncated library is a CompilationError."""
    wrapper = tmp_path / "truncating-cc"
    wrapper.write_text(TRUNCATING_CC)
    wrapper.chmod(0o755)
    script = OSCILLATOR + """
from symgroupoid.runtime import CompilationError
try:
    sg.compile_step(oscillator("oscillator_cut"), backend="c")
    print("compiled")
except CompilationError as exc:
    print("CompilationError")
"""
    env = subprocess_env(60, CC=str(wrapper), SYMGROUPOID_CACHE=str(cache_dir),
                         SYMGROUPOID_OPENMP=None)
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, (done.returncode, done.stderr[-2000:])
    assert done.stdout.split()[-1] == "CompilationError"
    probes = list((cache_dir / "probes").glob("openmp-*.json"))
    recorded = [json.loads(p.read_text()) for p in probes]
    assert not any(r["compiler"] == [str(wrapper)] for r in recorded), recorded


def test_an_interrupted_build_leaves_no_compiler_running(tmp_path, cache_dir):
    """(Ctrl-C reaching Python alone — a notebook's interrupt — raised KeyboardInterrupt
    while the compiler ran on, into a build directory already removed.)  Every compiler
    run is killed with the processes it started."""
    started, env = slow_compiler(tmp_path, cache_dir)
    script = ("import sys\n" + SCRIPT.replace(
        'sim = sg.compile_step(oscillator(), backend="c")',
        'try:\n        sim = sg.compile_step(oscillator(), backend="c")\n'
        '    except KeyboardInterrupt:\n        print("interrupted", flush=True)\n'
        '        sys.exit(3)'))
    proc = subprocess.Popen([sys.executable, "-c", script], env=env, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (started.exists() and started.read_text().strip()) \
                and time.monotonic() < deadline:
            time.sleep(0.01)
        wrapper_pid = int(started.read_text())
        os.kill(proc.pid, signal.SIGINT)  # Python alone, not its process group
        out, err = proc.communicate(timeout=60)
        assert proc.returncode == 3 and "interrupted" in out, (proc.returncode, err[-1500:])
        time.sleep(0.2)
        with pytest.raises(ProcessLookupError):
            os.kill(wrapper_pid, 0)
    finally:
        with contextlib.suppress(ProcessLookupError, ValueError, OSError):
            os.killpg(int(started.read_text()), signal.SIGKILL)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
