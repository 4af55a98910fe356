"""The kernel cache as a safety boundary: it follows no link it did not make and removes
nothing that is not its own; it runs no code from cache files and refuses a cache others
can write; it never installs or maps a damaged library; its key covers the build
environment; it builds correctly where ``flock`` is missing; a full disk is a CacheError.
"""

from __future__ import annotations

import base64
import contextlib
import errno
import functools
import json
import os
import shutil
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    OSCILLATOR,
    REPO,
    isolated_cache,
    needs_cc,
    oscillator,
    subprocess_env,
)

import symgroupoid as sg
from symgroupoid.cli import main
from symgroupoid.runtime import CacheError, CompilationError, toolchain

# white-box: a new process is imitated by clearing the cache's in-process state (the kernels
# loaded and their recipes, toolchain/_kernels.py; the roots swept, _sweep.py), and the flock
# test (_locks.py), the build directories' host tag (_processes.py) and the removal of a link
# (_atomic.py) are checked directly; no public name resets or shows them
from symgroupoid.runtime.toolchain import (
    _atomic,
    _kernels,
    _locks,
    _processes,
    _sweep,
    cache_info,
    clear_cache,
)

pytestmark = needs_cc

#: a process compiling the oscillator (``NO_FLOCK=1``: with ``flock`` failing as on NFS
#: mounted nolock, ENOLCK; ``BARRIER``: after waiting for a start signal)
SCRIPT = OSCILLATOR + '''
import errno, fcntl, json, os, time
from pathlib import Path

if os.environ.get("NO_FLOCK"):
    def flock(fd, operation):
        raise OSError(errno.ENOLCK, "No locks available")
    fcntl.flock = flock
from symgroupoid.runtime import toolchain

barrier = os.environ.get("BARRIER")
if barrier:
    Path(barrier, f"ready-{os.getpid()}").touch()
    while not Path(barrier, "go").exists():
        time.sleep(0.005)
sim = sg.compile_step(oscillator(), backend="c")
final = sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]
print(json.dumps({"entry": str(sim.cache_entry), "final": final.tolist(), **toolchain.STATS}))
'''


#: the environment of a child process (its cache locks given up after 120 s)
script_env = functools.partial(subprocess_env, 120)


def run_script(env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True,
                          env=env, timeout=600)


def reference_final() -> np.ndarray:
    sim = oscillator().compile(backend="numpy")
    return sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]


@pytest.fixture
def cache_dir() -> Path:
    """This test's (empty, not yet created) cache root, set up by ``isolated_cache``."""
    return toolchain.cache_root()


def built(cache_dir: Path, name: str = "oscillator") -> tuple[sg.Simulator, Path, dict]:
    """A kernel compiled into ``cache_dir``: the simulator, its entry and manifest."""
    sim = sg.compile_step(oscillator(name), backend="c")
    manifest = json.loads((sim.cache_entry / toolchain.MANIFEST).read_text())
    return sim, sim.cache_entry, manifest


def compile_anew(name: str = "oscillator", **options) -> tuple[sg.Simulator, int]:
    """``compile_step`` as a new process would run it (nothing loaded or built here
    before): the simulator and how many kernels it built."""
    _kernels._LOADED.clear()
    _kernels._RECIPES.clear()
    builds = toolchain.STATS["builds"]
    sim = sg.compile_step(oscillator(name), backend="c", **options)
    return sim, toolchain.STATS["builds"] - builds


def step_key(name: str = "oscillator") -> str:
    step = oscillator(name)
    return toolchain.source_key_of(toolchain.step_kernel(step), toolchain.step_flags(step, None))


def aged(*paths: Path, seconds: float = 2 * toolchain.GRACE) -> None:
    """Make ``paths`` look ``seconds`` old (without following links)."""
    then = time.time() - seconds
    for path in paths:
        os.utime(path, (then, then), follow_symlinks=False)


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every path under ``folder`` (not following links) with its bytes (None: a dir)."""
    out = {}
    for path in sorted(folder.rglob("*")):
        out[str(path.relative_to(folder))] = None if path.is_dir() else path.read_bytes()
    return out


def victim_directory(tmp_path: Path) -> Path:
    """A directory someone cares about: old dot-files and dot-directories (as $HOME or the
    system's temporary directory hold), names like the cache's, all aged."""
    victim = tmp_path / "victim"
    (victim / ".ssh").mkdir(parents=True)
    (victim / ".ssh" / "id_ed25519").write_text("private key")
    (victim / ".bashrc").write_text("export PATH")
    (victim / ".X11-unix").mkdir()
    (victim / "build-notes").mkdir()
    (victim / "0123456789abcdef0123456789abcdef").mkdir()
    (victim / ".0123456789abcdef0123456789abcdef.json.abcdefgh").write_text("{}")
    (victim / "probe-abcdefgh").write_text("mine")
    aged(*victim.rglob("*"), victim)
    return victim


def cli(*argv: str, capsys) -> tuple[int, str, str]:
    status = main(list(argv))
    out = capsys.readouterr()
    return status, out.out, out.err


# -- 1. links: never followed, nothing deleted that is not the cache's ---------------------------

def test_a_lock_file_that_is_a_link_is_refused_and_its_target_untouched(tmp_path, cache_dir):
    """The build key is deterministic: whoever plants ``locks/<key>.lock`` as a link chose
    which file a build would truncate and overwrite.  The lock is opened without following
    links: a CacheError naming it, the target unchanged."""
    target = tmp_path / "precious.txt"
    target.write_text("precious data\n")
    key = step_key()
    (cache_dir / "locks").mkdir(parents=True, exist_ok=True)
    (cache_dir / "locks" / f"{key}.lock").symlink_to(target)
    with pytest.raises(CacheError) as info:
        sg.compile_step(oscillator(), backend="c")
    text = str(info.value)
    assert f"{key}.lock" in text and "symbolic link" in text and "rm " in text
    assert target.read_text() == "precious data\n"
    toolchain.sweep(cache_dir)  # the sweep's lock probe never follows it either
    # (cache info did not list it, and cache clear left it, saying the kernel was "being
    # built by another process")
    assert toolchain.cache_info(cache_dir).bad_locks == [f"{key}.lock"]
    assert clear_cache(cache_dir).bad_locks == 1
    assert target.read_text() == "precious data\n"
    assert not os.path.lexists(cache_dir / "locks" / f"{key}.lock")
    assert toolchain.cache_info(cache_dir).bad_locks == []
    sg.compile_step(oscillator(), backend="c")  # built, the lock now the cache's own


@pytest.mark.parametrize("layout", ["tmp", "index"])
def test_names_alone_never_make_a_users_directory_a_cache(cache_dir, layout, capsys):
    """(A directory holding only tmp/build-20240101/results.csv and tmp/probe-abcdefgh, or
    only index/<32 hex>.json files, was adopted and marked: the sweep deleted the first
    once an hour old, ``cache clear`` the second.)  An unmarked directory is adopted only
    when empty or holding a kernel with its manifest; names a cache could have written are
    not evidence."""
    import warnings

    if layout == "tmp":
        (cache_dir / "tmp" / "build-20240101").mkdir(parents=True)
        (cache_dir / "tmp" / "build-20240101" / "results.csv").write_text("1,2,3")
        (cache_dir / "tmp" / "probe-abcdefgh").write_text("probe")
        aged(cache_dir / "tmp" / "build-20240101", cache_dir / "tmp" / "probe-abcdefgh")
    else:
        (cache_dir / "index").mkdir(parents=True)
        (cache_dir / "index" / ("2c" * 16 + ".json")).write_text('{"mine": 1}')
    before = snapshot(cache_dir)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim = sg.compile_step(oscillator(), backend="c")
    assert not str(sim.cache_entry).startswith(str(cache_dir))
    assert any("not a kernel cache" in str(w.message) for w in caught)
    toolchain.sweep(cache_dir)
    status, _, err = cli("cache", "clear", capsys=capsys)
    assert status == 1 and "nothing was removed" in err
    assert snapshot(cache_dir) == before
    assert not (cache_dir / "CACHEDIR.TAG").exists()


def test_clear_empties_an_unmarked_cache_layout_that_info_lists(cache_dir, capsys):
    """(Without its CACHEDIR.TAG — an older layout — ``cache info`` listed 2 kernels and
    compile loaded them, but ``cache clear`` removed nothing and said so with status 0.)
    Such a cache is marked as the cache it is, and cleared."""
    built(cache_dir)
    (cache_dir / "CACHEDIR.TAG").unlink()
    status, out, _ = cli("cache", "info", capsys=capsys)
    assert status == 0 and "1 kernels" in out
    status, out, _ = cli("cache", "clear", capsys=capsys)
    assert status == 0 and "removed 1 kernels" in out
    assert not list((cache_dir / "kernels").iterdir())
    assert (cache_dir / "CACHEDIR.TAG").exists()


def test_clear_with_locks_a_file_says_so_instead_of_builds_in_progress(cache_dir, capsys):
    """(It reported the kernels "being built by another process", status 0.)"""
    built(cache_dir)
    toolchain.remove_tree(cache_dir / "locks")
    (cache_dir / "locks").write_text("")
    status, _, err = cli("cache", "clear", capsys=capsys)
    assert status == 1 and "locks is not a directory" in err
    assert len(list((cache_dir / "kernels").iterdir())) == 1


def test_cache_info_does_not_walk_a_linked_kernel_entry(tmp_path, cache_dir, capsys):
    """(A kernel entry linked to /usr/share was walked by ``cache info``: 986.8 MiB in 4.6 s,
    5.9 GiB in 17.8 s for /usr.)  Its size is the link's, and clear removes the link only."""
    built(cache_dir)
    other = tmp_path / "other"
    other.mkdir()
    (other / "big.bin").write_bytes(b"x" * 3_000_000)
    (cache_dir / "kernels" / ("f" * 32)).symlink_to(other)
    status, out, _ = cli("cache", "info", capsys=capsys)
    assert status == 0 and "MiB" not in out
    clear_cache()
    assert (other / "big.bin").stat().st_size == 3_000_000


def test_cache_clear_with_kernels_a_link_leaves_the_other_directory_alone(
        tmp_path, cache_dir, capsys):
    built(cache_dir)
    other = tmp_path / "other"
    other.mkdir()
    (other / "thesis.tex").write_text("chapter 1")
    (other / ("ab" * 16)).mkdir()  # even a name like a kernel's
    (other / ("ab" * 16) / "data").write_text("results")
    before = snapshot(other)
    toolchain.remove_tree(cache_dir / "kernels")
    (cache_dir / "kernels").symlink_to(other)
    with pytest.raises(CacheError, match="kernels is a symbolic link|kernels cannot be trusted"):
        clear_cache()
    status, out, err = cli("cache", "clear", capsys=capsys)
    assert status == 1 and len(err.strip().splitlines()) == 1
    assert str(cache_dir / "kernels") in err and "symbolic link" in err
    status, out, err = cli("cache", "info", capsys=capsys)
    assert status == 1 and "NOT USED" in out and "symbolic link" in out
    with pytest.raises(CacheError, match="symbolic link"):
        sg.compile_step(oscillator(), backend="c")
    assert snapshot(other) == before


@pytest.mark.parametrize("name", ["tmp", "index"])
def test_first_use_sweep_never_follows_a_linked_directory(tmp_path, cache_dir, name):
    """A user moving scratch space (``ln -s /tmp ~/.cache/symgroupoid/tmp``): the sweep on
    a process's first use deleted the target's dot-files and dot-directories older than an
    hour.  The cache is refused (saying which link and what to do) and nothing is
    deleted, in this process or a new one."""
    built(cache_dir)
    victim = victim_directory(tmp_path)
    before = snapshot(victim)
    shutil.rmtree(cache_dir / name)
    (cache_dir / name).symlink_to(victim)
    _sweep._SWEPT.discard(cache_dir)
    with pytest.raises(CacheError) as info:
        sg.compile_step(oscillator("other"), backend="c")
    text = str(info.value)
    assert str(cache_dir / name) in text and "symbolic link" in text
    assert f"rm {cache_dir / name}" in text and "SYMGROUPOID_CACHE" in text
    toolchain.sweep(cache_dir)
    if name == "tmp":  # a new process
        result = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
        assert result.returncode != 0 and "CacheError" in result.stderr
    assert snapshot(victim) == before


@pytest.mark.parametrize("name", toolchain.INTERNAL)
def test_a_cache_whose_directory_is_a_link_is_refused(tmp_path, cache_dir, name):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    cache_dir.mkdir()
    (cache_dir / name).symlink_to(elsewhere)
    with pytest.raises(CacheError) as info:
        sg.compile_step(oscillator(), backend="c")
    assert f"{cache_dir / name} cannot be trusted" in str(info.value)
    assert list(elsewhere.iterdir()) == []


def test_a_dangling_link_in_the_cache_is_refused_not_followed(tmp_path, cache_dir):
    cache_dir.mkdir()
    (cache_dir / "kernels").symlink_to(tmp_path / "would-be-created")
    with pytest.raises(CacheError, match="symbolic link"):
        sg.compile_step(oscillator(), backend="c")
    assert not (tmp_path / "would-be-created").exists()


def test_clear_and_sweep_remove_only_the_names_the_cache_makes(cache_dir):
    built(cache_dir)
    strays = {"kernels": ["notes.txt", "ABCDEF0123456789ABCDEF0123456789", "my-results"],
              "index": ["keep.json", ".hidden"], "tmp": [".bashrc", "my-build", ".ssh"],
              "locks": ["do-not-remove"]}
    for folder, names in strays.items():
        for n in names:
            (cache_dir / folder / n).write_text("not the cache's")
    aged(*(cache_dir / f / n for f, names in strays.items() for n in names))
    result = clear_cache()
    assert result.removed == 1 and result.index_entries == 1
    for folder, names in strays.items():
        for n in names:
            assert (cache_dir / folder / n).read_text() == "not the cache's"


def test_a_directory_of_user_files_named_build_is_never_adopted_nor_swept(cache_dir):
    """A directory holding only tmp/ with the user's build-2024-01-05.log and build-artifacts/
    was taken over as an unmarked cache of an older layout ("build-" then anything), and the
    first build's sweep deleted them once an hour old.  Only tempfile's exact shape
    (build- and eight random characters) is an old build directory."""
    import warnings

    tmp = cache_dir / "tmp"
    (tmp / "build-artifacts").mkdir(parents=True)
    (tmp / "build-2024-01-05.log").write_text("keep me")
    (tmp / "build-artifacts" / "result.bin").write_text("data")
    aged(tmp / "build-2024-01-05.log", tmp / "build-artifacts")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim = sg.compile_step(oscillator(), backend="c")
    assert not str(sim.cache_entry).startswith(str(cache_dir))
    assert any("not a kernel cache" in str(w.message) for w in caught)
    assert (tmp / "build-2024-01-05.log").read_text() == "keep me"
    assert (tmp / "build-artifacts" / "result.bin").read_text() == "data"
    assert not (cache_dir / "CACHEDIR.TAG").exists()


@pytest.mark.parametrize("where", ["index", "marker", "probe"])
def test_a_fifo_where_the_cache_reads_a_file_never_blocks(cache_dir, where, monkeypatch):
    """(A FIFO as an index file, the cache marker or an OpenMP probe made ``compile()``
    wait forever in ``open``: a file the cache reads is opened without waiting, and
    anything but a regular file is ignored.)  The run is bitwise the first one's."""
    first, _, _ = built(cache_dir)
    # the compiler's OpenMP answer, kept in probes/ (and read again: not known here)
    monkeypatch.setattr("symgroupoid.runtime.toolchain._openmp._OPENMP", {})
    toolchain.openmp_available(cache_dir)
    monkeypatch.setattr("symgroupoid.runtime.toolchain._openmp._OPENMP", {})
    targets = {"index": next((cache_dir / "index").iterdir(), None),
               "marker": cache_dir / "CACHEDIR.TAG",
               "probe": next((cache_dir / "probes").glob("openmp-*.json"), None)}
    path = targets[where]
    if path is None:
        pytest.skip(f"this build wrote no {where} file")
    path.unlink()
    os.mkfifo(path)
    done: list = []
    worker = threading.Thread(target=lambda: done.append(compile_anew()[0]), daemon=True)
    worker.start()
    worker.join(timeout=120)
    assert done, f"compile() blocked on a FIFO as the {where} file"
    start = {"q": (0.1, 0.11)}
    assert np.array_equal(done[0].simulate(start, 20, {"h": 0.1, "k": 2.0}).states,
                          first.simulate(start, 20, {"h": 0.1, "k": 2.0}).states)


def test_removing_a_link_never_touches_its_target(tmp_path):
    target = tmp_path / "target"
    (target / "sub").mkdir(parents=True)
    (target / "sub" / "f").write_text("x")
    link = tmp_path / "link"
    link.symlink_to(target)
    _atomic._remove(link)
    assert not os.path.lexists(link) and (target / "sub" / "f").read_text() == "x"


# -- 2. no code from cache files; a cache others can write is not trusted -----------------------

PLANTED = "import pathlib; pathlib.Path({marker!r}).write_text('ran')\nffi = None\n"


def test_a_planted_manifest_never_runs_python(tmp_path, cache_dir):
    """``manifest.json``'s old ``"ffi"`` field was Python source the loader ran, guarded
    only by a hash in the same file.  The type table is data now: a planted ``ffi`` (with
    a matching hash), or Python where the table belongs, never runs, in a new process or
    this one; the entry is rebuilt where it does not verify."""
    _, entry, manifest = built(cache_dir)
    marker = tmp_path / "marker"
    code = PLANTED.format(marker=str(marker))
    planted = {**manifest, "ffi": code, "ffi_sha256": toolchain.sha256_of([code])}
    (entry / toolchain.MANIFEST).write_text(json.dumps(planted))
    result = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout.splitlines()[-1])["builds"] == 0  # ignored, still valid
    for table in (code, {"name": manifest["module"], "_types": code},
                  {**manifest["types"], "_includes": [{"b64": ""}]},
                  {**manifest["types"], "_types": code}):
        planted = {**manifest, "types": table}
        planted["types_sha256"] = (toolchain.table_sha256(table) if isinstance(table, dict)
                                   else "0" * 64)
        (entry / toolchain.MANIFEST).write_text(json.dumps(planted))
        assert toolchain.entry_defect(entry, entry.name)[0] is None
        sim, builds = compile_anew()
        assert builds == 1 and sim.cache_entry == entry  # rebuilt
    assert not marker.exists()
    with pytest.raises(ImportError):
        toolchain.load_extension(entry / manifest["library"], manifest["module"], {"name": code})
    assert not marker.exists()


def test_the_type_table_is_plain_data_checked_before_use(cache_dir):
    sim, entry, manifest = built(cache_dir)
    table = manifest["types"]

    def kinds(value):
        if isinstance(value, dict):
            assert set(value) <= {"b64"} | toolchain.TYPE_TABLE_KEYWORDS | {"name"}
            return set().union(*(kinds(v) for v in value.values()))
        if isinstance(value, list):
            return set().union(set(), *(kinds(v) for v in value))
        return {type(value).__name__}

    assert kinds(table) <= {"int", "str"}
    assert table["name"] == manifest["module"]
    ffi = toolchain.ffi_of(table, manifest["module"])
    assert ffi.sizeof(f"{sim.kernel.prefix}_options") == sim.kernel.ffi.sizeof(
        f"{sim.kernel.prefix}_options")
    for bad in ({**table, "name": "other"}, {**table, "_version": True},
                {**table, "_types": "text"}, {**table, "_globals": [[[[[[[0]]]]]]]},
                {**table, "_types": {"b64": "not base64!"}}, {**table, "extra": 1},
                {k: v for k, v in table.items() if k != "_types"}, ["a list"]):
        with pytest.raises(ImportError, match="type table"):
            toolchain.ffi_of(bad, manifest["module"])
    assert base64.b64decode(table["_types"]["b64"])  # bytes, as cffi wrote them


def test_the_kernel_cache_keeps_no_compiled_templates(tmp_path, monkeypatch):
    """The templates' compiled code is Python (jinja2 bytecode).  Without the package's
    (``templates/__pycache__``), a build compiles the templates in this process and keeps
    nothing in the cache; a compiled template planted in the cache's ``templates/`` (one
    that would write a marker) is never loaded."""
    import jinja2

    from symgroupoid.codegen import template_dir

    monkeypatch.setattr("symgroupoid.codegen._emit.package_template_cache",
                        lambda write=False: None)
    names = sorted(p.name for p in Path(template_dir()).glob("*.j2"))  # every template
    root = tmp_path / "cache"
    (root / "templates").mkdir(parents=True)
    marker = tmp_path / "marker"
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(template_dir())))
    planter = jinja2.FileSystemBytecodeCache(str(root / "templates"))
    for name in names:
        source, filename, _ = env.loader.get_source(env, name)
        bucket = planter.get_bucket(env, name, filename, source)
        bucket.code = compile(PLANTED.format(marker=str(marker)), filename, "exec")
        planter.set_bucket(bucket)
    planted = sorted(p.name for p in (root / "templates").iterdir())
    assert len(planted) == len(names)
    sim = sg.compile_step(planar_step(), backend="c", cache_dir=root)
    assert sim.backend == "c" and not marker.exists()
    assert sorted(p.name for p in (root / "templates").iterdir()) == planted
    clear_cache(root)  # what older versions kept there goes with the cache
    assert list((root / "templates").iterdir()) == []


def planar_step():
    from symgroupoid.systems import planar_chain

    return planar_chain(2).euler_lagrange()


def _refused(cache_dir: Path, path: Path, why: str) -> None:
    with pytest.raises(CacheError) as info:
        sg.compile_step(oscillator(), backend="c")
    text = str(info.value)
    assert str(path) in text and why in text and "SYMGROUPOID_CACHE" in text, text
    assert cache_info(cache_dir).refused is not None


@pytest.mark.parametrize("mode", [0o777, 0o775, 0o757, 0o1777])
@pytest.mark.parametrize("where", ["root", "kernels"])
def test_a_cache_others_can_write_is_refused(cache_dir, mode, where):
    toolchain.writable_root(cache_dir)
    path = cache_dir if where == "root" else cache_dir / where
    path.chmod(mode)
    _refused(cache_dir, path, "writable by")
    with pytest.raises(CacheError, match=r"chmod go-w"):
        sg.compile_step(oscillator(), backend="c")
    path.chmod(0o755)
    assert toolchain.trusted(cache_dir) and cache_info(cache_dir).refused is None


as_root = pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                             reason="changing a file's owner needs root")
NOBODY = 65534


@as_root
@pytest.mark.parametrize("where", ["root", "kernels", "index", "tmp"])
def test_a_cache_of_another_user_is_refused(cache_dir, where):
    toolchain.writable_root(cache_dir)
    path = cache_dir if where == "root" else cache_dir / where
    os.chown(path, NOBODY, NOBODY)
    _refused(cache_dir, path, f"another user (uid {NOBODY})")


@as_root
@pytest.mark.parametrize("part", ["entry", "manifest", "library"])
def test_an_entry_of_another_user_or_writable_by_others_is_rebuilt_not_loaded(
        tmp_path, cache_dir, part):
    _, entry, manifest = built(cache_dir)
    path = {"entry": entry, "manifest": entry / toolchain.MANIFEST,
            "library": entry / manifest["library"]}[part]
    os.chown(path, NOBODY, NOBODY)
    assert "another user" in toolchain.entry_defect(entry, entry.name)[1]
    (bad,) = cache_info(cache_dir).bad
    assert "another user" in bad.problem
    assert compile_anew()[1] == 1
    assert os.lstat(entry).st_uid == os.geteuid()
    path = entry / manifest["library"]
    path.chmod(0o777)
    assert "writable by" in toolchain.entry_defect(entry, entry.name)[1]
    assert compile_anew()[1] == 1


@as_root
def test_an_explicitly_shared_read_only_cache_is_read_and_verified(tmp_path, monkeypatch):
    """``SYMGROUPOID_SHARED_CACHE``: a cache another account built, read after one's own;
    trusted when it all belongs to that account and nobody else can write it; never
    written.  A damaged or writable entry there is not loaded: the kernel is built into
    one's own cache."""
    shared, own = tmp_path / "shared", tmp_path / "own"
    sg.compile_step(oscillator(), backend="c", cache_dir=shared)
    for path in [shared, *shared.rglob("*")]:
        os.chown(path, NOBODY, NOBODY, follow_symlinks=False)
    before = snapshot(shared)
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(own))
    monkeypatch.setenv("SYMGROUPOID_SHARED_CACHE", str(shared))
    sim, builds = compile_anew()
    assert builds == 0 and sim.cache_entry.is_relative_to(shared)
    final = sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0}).states[-1]
    assert np.abs(final - reference_final()).max() <= 1e-12
    with monkeypatch.context() as m:  # not one's own cache
        m.setenv("SYMGROUPOID_CACHE", str(shared))
        with pytest.raises(CacheError, match="another user"):
            compile_anew()
    (entry,) = (shared / "kernels").iterdir()
    (entry / next(p.name for p in entry.glob("*.so"))).chmod(0o757)
    sim, builds = compile_anew()
    assert builds == 1 and sim.cache_entry.is_relative_to(own)
    (shared / "index").chmod(0o777)
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(tmp_path / "own2"))
    with pytest.raises(CacheError, match="shared kernel cache") as info:
        compile_anew()
    # (the advice was to set SYMGROUPOID_CACHE elsewhere, which does not help)
    assert "SYMGROUPOID_SHARED_CACHE" in str(info.value)
    assert "SYMGROUPOID_CACHE " not in str(info.value)
    (shared / "index").chmod(0o755)
    assert snapshot(shared) == before


def test_cache_files_are_never_writable_by_others_whatever_the_umask(cache_dir):
    old = os.umask(0o002)
    try:
        sim = sg.compile_step(oscillator(), backend="c")
    finally:
        os.umask(old)
    paths = [cache_dir, *cache_dir.rglob("*")]
    assert all(stat.S_IMODE(p.lstat().st_mode) & 0o022 == 0 for p in paths)
    assert cache_info(cache_dir).refused is None and sim.backend == "c"


# -- 3. damaged libraries ------------------------------------------------------------------------

TRUNCATING_CC = """#!/bin/sh
cc "$@" || exit $?
case " $* " in *" -shared "*) ;; *) exit 0 ;; esac
out=""
prev=""
for a in "$@"; do [ "$prev" = "-o" ] && out="$a"; prev="$a"; done
size=$(wc -c < "$out")
head -c $((size / 2)) "$out" > "$out.cut" && mv "$out.cut" "$out"
exit 0
"""


def test_a_compiler_that_writes_a_truncated_library_gets_nothing_installed(
        tmp_path, monkeypatch, cache_dir):
    """A compiler that exits 0 but leaves a truncated library (a full disk, a killed
    linker): before, it was installed, and loading it killed every process on that cache
    with SIGBUS."""
    wrapper = tmp_path / "truncating-cc"
    wrapper.write_text(TRUNCATING_CC)
    wrapper.chmod(0o755)
    monkeypatch.setenv("CC", str(wrapper))
    monkeypatch.setenv("SYMGROUPOID_OPENMP", "0")
    with pytest.raises(CompilationError) as info:
        sg.compile_step(oscillator(), backend="c")
    text = str(info.value)
    assert "damaged library" in text and "truncated" in text and "not installed" in text
    assert list((cache_dir / "kernels").iterdir()) == []
    assert list((cache_dir / "tmp").iterdir()) == []


def _truncate_consistently(entry: Path, manifest: dict, keep: float = 0.5) -> None:
    """Cut the library and update its manifest's hash to match, as a truncated library
    installed by an earlier version would be (through a new file: a process that mapped
    the library keeps its own copy)."""
    library = entry / manifest["library"]
    data = library.read_bytes()
    cut = entry / "cut"
    cut.write_bytes(data[: int(len(data) * keep)])
    os.replace(cut, library)
    manifest = {**manifest, "sha256": toolchain.file_sha256(library)}
    (entry / toolchain.MANIFEST).write_text(json.dumps(manifest))


def test_a_truncated_library_in_the_cache_is_found_before_dlopen_and_rebuilt(
        cache_dir, capsys):
    _, entry, manifest = built(cache_dir)
    _, other, _ = built(cache_dir, "oscillator_two")
    _truncate_consistently(entry, manifest)
    (bad,) = cache_info(cache_dir).bad
    assert bad.key == entry.name and "truncated" in bad.problem
    status, out, _ = cli("cache", "info", capsys=capsys)
    assert status == 0 and "1 bad" in out and entry.name in out and "--bad" in out
    with pytest.raises(ImportError, match="damaged"):
        toolchain.load_extension(entry / manifest["library"], manifest["module"])
    result = run_script(script_env(SYMGROUPOID_CACHE=str(cache_dir)))  # SIGBUS before
    assert result.returncode == 0, (result.returncode, result.stderr)
    out = json.loads(result.stdout.splitlines()[-1])
    assert out["builds"] == 1 and cache_info(cache_dir).bad == []
    assert np.abs(np.array(out["final"]) - reference_final()).max() <= 1e-12
    assert compile_anew()[1] == 0  # and every later process loads the new one
    _truncate_consistently(entry, json.loads((entry / toolchain.MANIFEST).read_text()), 0.9)
    status, out, _ = cli("cache", "clear", "--bad", capsys=capsys)
    assert status == 0 and "removed 1 bad kernels" in out
    assert not entry.exists() and other.is_dir()


def test_a_clear_that_cannot_remove_says_so_and_fails(cache_dir, capsys, monkeypatch):
    """(``cache clear`` on a cache it could not change printed "removed 0 kernels" and
    exited 0, the kernels still there.)  Removal is made to fail here as an immutable or
    read-only cache makes it fail (this test may run as root, whom permissions do not
    stop): the command names what is left and exits 1."""
    _, entry, _ = built(cache_dir)
    monkeypatch.setattr("symgroupoid.runtime.toolchain._maintenance.remove_tree",
                        lambda path: None)
    monkeypatch.setattr("symgroupoid.runtime.toolchain._maintenance._remove", lambda path: None)
    status, out, err = cli("cache", "clear", capsys=capsys)
    assert status == 1 and "removed 0 kernels" in out
    assert f"could not remove 2 entries ({entry.name}, index/" in err
    assert entry.is_dir()


def test_a_read_only_cache_is_not_taken_for_one_being_built(cache_dir, capsys, monkeypatch):
    """On a read-only mount the locks cannot be opened, and ``cache clear`` said it left the
    kernels "being built by another process" before its error.  (The mount is stood for by
    ``os.access``: this test may run as root.)"""
    _, entry, _ = built(cache_dir)
    real_access = os.access
    monkeypatch.setattr("symgroupoid.runtime.toolchain._maintenance.os.access",
                        lambda path, mode: False if mode == os.W_OK else real_access(path, mode))
    monkeypatch.setattr("symgroupoid.runtime.toolchain._maintenance._remove", lambda path: None)
    status, out, err = cli("cache", "clear", capsys=capsys)
    assert status == 1 and "being built" not in out + err
    assert f"could not remove 2 entries ({entry.name}, index/" in err


def test_library_defects_are_found_from_the_elf_headers(cache_dir):
    _, entry, manifest = built(cache_dir)
    data = (entry / manifest["library"]).read_bytes()
    assert toolchain.library_defect(data) is None
    for size in (0, 3, 40, 63, 64, 200, len(data) // 3, len(data) // 2, len(data) - 1):
        assert toolchain.library_defect(data[:size]) is not None, size
    assert "not an ELF" in toolchain.library_defect(b"#!/bin/sh\n" * 100)
    relocatable = bytearray(data)
    relocatable[16] = 1  # ET_REL
    assert "not a shared object" in toolchain.library_defect(bytes(relocatable))
    t0 = time.perf_counter()
    for _ in range(100):
        toolchain.library_defect(data)
    assert (time.perf_counter() - t0) / 100 < 0.002  # about 20 µs


# -- 4. the key covers the build environment; the unsafe-math family is refused -------------------

@pytest.mark.parametrize("variable, value", [
    ("CFLAGS", "-fexcess-precision=standard"), ("CPPFLAGS", "-DSG_OTHER"),
    ("LDFLAGS", "-Wl,-O1"), ("CC", "cc -m64"), ("CC", "cc")])
def test_the_build_environment_is_in_both_keys(monkeypatch, variable, value):
    step = oscillator()
    flags = toolchain.step_flags(step, None)
    kernel = toolchain.step_kernel(step)
    monkeypatch.delenv(variable, raising=False)
    keys = (toolchain.input_key(step, flags), toolchain.source_key_of(kernel, flags))
    monkeypatch.setenv(variable, value)
    other = (toolchain.input_key(step, flags), toolchain.source_key_of(kernel, flags))
    assert keys[0] != other[0] and keys[1] != other[1]


def test_a_kernel_built_under_other_cflags_is_never_served(monkeypatch, cache_dir):
    """A kernel built under ``CFLAGS=-fno-math-errno`` (bits may differ) was served to a
    process that never set it."""
    monkeypatch.setenv("CFLAGS", "-fno-math-errno")
    first = sg.compile_step(oscillator(), backend="c")
    monkeypatch.delenv("CFLAGS")
    builds = toolchain.STATS["builds"]
    _kernels._LOADED.clear()
    second = sg.compile_step(oscillator(), backend="c")
    assert toolchain.STATS["builds"] == builds + 1
    assert first.cache_entry != second.cache_entry
    manifest = json.loads((second.cache_entry / toolchain.MANIFEST).read_text())
    assert manifest["source_key"] == second.cache_entry.name


@pytest.mark.parametrize("flags", ["-funsafe-math-optimizations", "-fassociative-math "
                                   "-fno-signed-zeros -fno-trapping-math", "-freciprocal-math",
                                   "-fno-signed-zeros", "-ffast-math", "-ffinite-math-only"])
def test_the_unsafe_math_family_is_refused_by_every_unit(monkeypatch, flags):
    monkeypatch.setenv("CFLAGS", flags)
    with pytest.raises(CompilationError, match="must not be compiled with") as info:
        sg.compile_step(planar_step(), backend="c")
    units = 3 if toolchain.translation_units() > 1 else 1  # the stepper, a unit, the cold one
    assert info.value.output.count("#error") >= units
    # (the vector extension the build added is not what failed: no advice about it)
    assert "SYMGROUPOID_VECTOR_ISA" not in str(info.value)


def test_window_programs_refuse_the_unsafe_math_family(monkeypatch):
    from symgroupoid.codegen import generate_program_c
    from symgroupoid.ir import Graph, Program, from_sympy

    x, y = sp.symbols("x y")
    g = Graph()
    nodes = {x: g.input(x), y: g.input(y)}
    program = Program(g, {"a": [x, y]}, {"out": [from_sympy(g, x * y + x, nodes)]})
    kernel = generate_program_c("unsafe window", program, "a", "out")
    monkeypatch.setenv("CFLAGS", "-funsafe-math-optimizations")
    with pytest.raises(CompilationError, match="program must not be compiled with"):
        toolchain.build_cached(kernel, ("-O2",), toolchain.KernelCache(), "unsafe window")


# -- 5. file systems without flock -----------------------------------------------------------------

def _no_flock(monkeypatch, code: int = errno.ENOLCK) -> None:
    """``flock`` failing as on NFS mounted nolock (ENOLCK) or Lustre noflock (ENOSYS)."""
    import fcntl

    def flock(fd, operation):
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(fcntl, "flock", flock)


@pytest.mark.parametrize("code", [errno.ENOLCK, errno.ENOSYS, errno.EOPNOTSUPP])
def test_a_flock_that_fails_is_never_taken_for_acquired(tmp_path, monkeypatch, code):
    _no_flock(monkeypatch, code)
    fd = os.open(tmp_path / "x.lock", os.O_RDWR | os.O_CREAT)
    try:
        assert _locks._try_flock(fd) is None
    finally:
        os.close(fd)


def test_without_flock_the_sweep_spares_builds_that_may_be_alive(monkeypatch, cache_dir):
    _no_flock(monkeypatch)
    toolchain.writable_root(cache_dir)
    tmp, key = cache_dir / "tmp", "1" * 32
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    try:
        live = tmp / f"build-{key}-{sleeper.pid}-{_processes.HOST_TAG}-abcdefgh"
        gone = tmp / f"build-{key}-{dead.pid}-{_processes.HOST_TAG}-abcdefgh"
        remote_young = tmp / f"build-{key}-12-{'f' * 12}-abcdefgh"
        remote_old = tmp / f"build-{key}-13-{'f' * 12}-abcdefgh"
        legacy_young = tmp / f"build-{key}-abcdefgh"
        for path in (live, gone, remote_young, remote_old, legacy_young):
            path.mkdir()
            (path / "unit.o").write_bytes(b"partial")
        aged(live, remote_old)
        toolchain.sweep(cache_dir)
        assert sorted(p.name for p in tmp.iterdir()) == sorted(
            p.name for p in (live, remote_young, legacy_young))
    finally:
        sleeper.kill()
        sleeper.wait()


def test_without_flock_threads_building_one_kernel_all_succeed(monkeypatch, cache_dir):
    """``flock`` failing with ENOLCK: before, it was taken for "acquired", every builder
    deleted the others' live build directories and most builds failed, blaming the
    compiler.  Six threads build the same kernel at once: all get it, built once."""
    _no_flock(monkeypatch)
    results: list = []
    errors: list = []
    builds = toolchain.STATS["builds"]
    _kernels._LOADED.clear()

    def run() -> None:
        try:
            sim = sg.compile_step(oscillator(), backend="c")
            results.append(sim.simulate({"q": (1.0, 0.999)}, 100, {"h": 0.01, "k": 1.0})
                           .states[-1])
        except BaseException as exc:  # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=run) for _ in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(timeout=300)
    assert errors == [] and len(results) == 6
    assert toolchain.STATS["builds"] == builds + 1
    assert all(np.abs(r - reference_final()).max() <= 1e-12 for r in results)
    assert list((cache_dir / "tmp").iterdir()) == []
    assert not list((cache_dir / "locks").glob("*.lease"))


@pytest.mark.slow
def test_without_flock_concurrent_builds_of_one_kernel_all_succeed(tmp_path, cache_dir):
    """The same with ten processes starting at once (before: 10 of 12 failed): all
    succeed with the same kernel, built once (the lease serialises them); nothing is left
    in tmp/ or locks/."""
    barrier = tmp_path / "barrier"
    barrier.mkdir()
    env = script_env(SYMGROUPOID_CACHE=str(cache_dir), NO_FLOCK="1", BARRIER=str(barrier))
    procs = [subprocess.Popen([sys.executable, "-c", SCRIPT], env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
             for _ in range(10)]
    try:
        deadline = time.monotonic() + 300
        while len(list(barrier.glob("ready-*"))) < len(procs) and time.monotonic() < deadline:
            time.sleep(0.05)
        (barrier / "go").touch()
        results = [p.communicate(timeout=600) for p in procs]
    finally:
        for p in procs:
            with contextlib.suppress(ProcessLookupError):
                p.kill()
    assert [p.returncode for p in procs] == [0] * len(procs), [err for _, err in results]
    outs = [json.loads(out.splitlines()[-1]) for out, _ in results]
    assert len({o["entry"] for o in outs}) == 1 and sum(o["builds"] for o in outs) == 1
    assert all(o["final"] == outs[0]["final"] for o in outs)
    assert list((cache_dir / "tmp").iterdir()) == []
    assert not list((cache_dir / "locks").glob("*.lease"))


def test_a_lease_of_a_dead_builder_blocks_nobody(monkeypatch, cache_dir):
    _no_flock(monkeypatch, errno.ENOSYS)
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    key = step_key()
    (cache_dir / "locks").mkdir(parents=True, exist_ok=True)
    lease = cache_dir / "locks" / f"{key}.lease"
    lease.write_text(f"pid {dead.pid} host {_processes.HOST_TAG}\n")
    monkeypatch.setenv("SYMGROUPOID_LOCK_TIMEOUT", "30")
    t0 = time.monotonic()
    assert sg.compile_step(oscillator(), backend="c").backend == "c"
    assert time.monotonic() - t0 < 25 and not lease.exists()


# -- 8. a full disk -------------------------------------------------------------------------------

def _disk_full(*args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), "/somewhere/unit.o")


@pytest.mark.parametrize("where", ["build_extension", "write_json_atomic"])
def test_a_full_disk_is_a_cache_error_naming_the_cache(monkeypatch, cache_dir, capsys, where):
    """A full disk during a build was a raw OSError (the command line said only "No space
    left on device")."""
    monkeypatch.setattr(_kernels, where, _disk_full)
    with pytest.raises(CacheError) as info:
        sg.compile_step(oscillator(), backend="c")
    text = str(info.value)
    assert str(cache_dir) in text and "no space left" in text and "SYMGROUPOID_CACHE" in text
    assert list((cache_dir / "tmp").iterdir()) == []
    monkeypatch.setattr("symgroupoid._progress.DELAY", 1e9)  # no progress line on a loaded machine
    status, _, err = cli("simulate", str(REPO / "examples" / "cli" / "spring.py"), "--steps",
                         "3", capsys=capsys)
    assert status == 1 and len(err.strip().splitlines()) == 1
    assert str(cache_dir) in err and "no space left" in err


FULL_DISK_CC = """#!/bin/sh
case " $* " in *" -c "*|*" -shared "*) ;; *) exec cc "$@" ;; esac
echo "/usr/bin/ld: final link failed: No space left on device" >&2
exit 1
"""


def test_a_compiler_stopped_by_a_full_disk_is_a_cache_error(tmp_path, monkeypatch, cache_dir):
    wrapper = tmp_path / "full-cc"
    wrapper.write_text(FULL_DISK_CC)
    wrapper.chmod(0o755)
    monkeypatch.setenv("CC", str(wrapper))
    monkeypatch.setenv("SYMGROUPOID_OPENMP", "0")
    with pytest.raises(CacheError, match="no space left") as info:
        sg.compile_step(oscillator(), backend="c")
    assert str(cache_dir) in str(info.value)


@needs_cc
def test_a_root_another_process_is_marking_is_adopted_not_taken_for_foreign(cache_dir):
    """Ten processes creating one cache at once: one saw the marker another was writing
    (its temporary file .CACHEDIR.TAG.xxxxxxxx, renamed a moment later) as a foreign file
    and fell back to a private cache of its own, building the kernel a second time.  Such a
    file is part of a root being marked: the root is adopted."""
    import warnings

    cache_dir.mkdir()
    (cache_dir / ".CACHEDIR.TAG.a1b2c3d4").write_text("")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (a fallback warns)
        sim, entry, _ = built(cache_dir)
    assert str(entry).startswith(str(cache_dir))
    assert (cache_dir / "CACHEDIR.TAG").is_file()


def test_clear_of_a_cache_path_that_is_a_file_is_an_error_as_info_says(cache_dir, capsys):
    """(``cache info`` said NOT USED, status 1; ``cache clear`` "removed 0 kernels",
    status 0.)"""
    cache_dir.parent.mkdir(parents=True, exist_ok=True)
    cache_dir.write_text("mine")
    status, out, _ = cli("cache", "info", capsys=capsys)
    assert status == 1 and "NOT USED" in out
    status, _, err = cli("cache", "clear", capsys=capsys)
    assert status == 1 and "is not a directory" in err and "nothing was removed" in err
    assert cache_dir.read_text() == "mine"


def test_cache_info_prints_no_control_characters_from_a_manifest(cache_dir, capsys):
    """(A manifest's system name holding an escape sequence was printed raw by cache info.)"""
    built(cache_dir)
    (entry,) = (cache_dir / "kernels").iterdir()
    manifest = json.loads((entry / "manifest.json").read_text())
    manifest["system"] = "osc\x1b[2J\x1b]0;owned\x07"
    (entry / "manifest.json").write_text(json.dumps(manifest))
    status, out, _ = cli("cache", "info", capsys=capsys)
    assert "\x1b" not in out and "\x07" not in out and "osc?[2J?]0;owned?" in out
