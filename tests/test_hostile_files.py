"""Hostile input where the library meets the file system: ``emit_c``, the kernel cache
(``compile_step(cache_dir=...)``, the cache's files and directories, its environment
variables) and the cache maintenance functions.

``emit_c``: steps that are not steps, paths of the wrong type, empty, ``/``, with NUL
characters, under a file, relative (the working directory is a scratch directory, see
``scratch_cwd``); prefixes of the wrong type, C keywords, leading digits, non-ASCII.  A
valid call writes a header and a source that are exactly ``generate_c``'s, with the mode an
ordinary file gets, whose identifiers are valid C, and which the C compiler accepts
(``-fsyntax-only -std=c99``).

The cache: after a kernel is built, one of its files or directories is damaged (garbage or
a list as manifest, a truncated or missing module, a directory or file in the way of any
part, an index pointing outside the cache, a symlink loop, a stale build directory, a
truncated module with a matching manifest, Python planted in the manifest, a directory or
lock file that is a link to someone else's files, a cache others can write) and the kernel
is asked for again: the answer must be a kernel that steps exactly as the NumPy backend
does, or a CacheError naming the cache; planted code never runs and the files a link
points to are never changed.  Environment variables get junk values.
Every build here uses ``-O0`` and its own flag, so each example builds a new kernel.
"""

from __future__ import annotations

import contextlib
import hashlib
import itertools
import json
import os
import re
import shutil
import stat
import subprocess
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from _hostile import (
    PROFILES,
    judge,
    junk,
    oscillator,
    profile,
    scalars,
    scratch_cwd,  # noqa: F401  (autouse fixture)
)
from hypothesis import given
from hypothesis import strategies as st
from kernel_support import HAVE_CC, isolated_cache, needs_cc  # noqa: F401  (autouse fixture)

import symgroupoid as sg
from symgroupoid.codegen import generate_c
from symgroupoid.runtime import toolchain, wait_for_kernels
from symgroupoid.runtime.toolchain import KernelCache, cache_info, cache_root, clear_cache

STEP = oscillator().euler_lagrange()
PARAMS = {"h": 0.1, "k": 1.0}
START = {"q": (0.1, 0.2)}
REFERENCE = STEP.compile(backend="numpy").simulate(START, 3, PARAMS).states
_BUILD = itertools.count()


def fresh_flags() -> list[str]:
    """Flags of a kernel no other example has built (a new cache key each time)."""
    return ["-O0", f"-DSG_HOSTILE_BUILD_{os.getpid()}_{next(_BUILD)}"]


# --- emit_c ---------------------------------------------------------------------------------------

IDENTIFIER = re.compile(r"^[a-z_][a-z0-9_]*$")
#: the keywords of C99 (ISO/IEC 9899:1999 §6.4.1), which no prefix may be
C99_KEYWORDS = frozenset((
    "auto", "break", "case", "char", "const", "continue", "default", "do", "double", "else",
    "enum", "extern", "float", "for", "goto", "if", "inline", "int", "long", "register",
    "restrict", "return", "short", "signed", "sizeof", "static", "struct", "switch", "typedef",
    "union", "unsigned", "void", "volatile", "while", "_Bool", "_Complex", "_Imaginary"))


def check_emitted(prefix):
    def verify(paths):
        c_path, h_path = (Path(p) for p in paths)
        kernel = generate_c(STEP, prefix, header_name=h_path.name)
        assert c_path.read_text() == kernel.source and h_path.read_text() == kernel.header
        assert IDENTIFIER.match(kernel.prefix) and kernel.prefix not in C99_KEYWORDS
        umask = os.umask(0)
        os.umask(umask)
        for p in paths:
            assert stat.S_IMODE(Path(p).stat().st_mode) == 0o666 & ~umask
        if HAVE_CC:
            result = subprocess.run(["cc", "-std=c99", "-fsyntax-only", "-Wall", "-Werror",
                                     "-I", str(c_path.parent), str(c_path.absolute())],
                                    capture_output=True, text=True, timeout=120)
            assert result.returncode == 0, result.stderr
    return verify


@pytest.mark.parametrize("run", PROFILES)
def test_emit_c(run):
    Path("file").write_text("a file in the way")
    paths = st.one_of(st.sampled_from(["out/k", "k.c", "k.h", "deep/er/k", "", "/", ".", "..",
                                       "file/k", "a\0b", "k.", " ", "ü/k", "out/"]),
                      st.text(max_size=6), junk(max_leaves=2))
    prefixes = st.one_of(st.none(), st.sampled_from(["", "int", "1abc", "é", "a b", "_",
                                                     "main", "NULL", "x" * 80, "static",
                                                     "__", "double"]),
                         st.text(max_size=5), scalars)

    @profile(run, 5)
    @given(data=st.data())
    def prop(data):
        which = data.draw(st.sampled_from(["step", "path", "prefix"]))
        step, path, prefix = STEP, "out/kernel", None
        if which == "step":
            step = data.draw(st.one_of(junk(max_leaves=2), st.just(STEP.system)))
        elif which == "path":
            path = data.draw(paths)
        else:
            prefix = data.draw(prefixes)
        judge("emit_c", lambda: sg.emit_c(step, path, prefix=prefix),
              [which, "emit_c"], owner=STEP.name, verify=check_emitted(prefix))

    prop()


# --- the cache ------------------------------------------------------------------------------------

def _entry(root: Path) -> Path:
    return next(p for p in (root / "kernels").iterdir())


def _replace(path: Path, data: bytes) -> None:
    """Put ``data`` at ``path`` through a new file (a loaded module is never rewritten in
    place: the running process maps it)."""
    tmp = path.with_name(path.name + ".new")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _in_the_way(path: Path, kind: str) -> None:
    """Replace ``path`` (file or directory) by a file or an empty directory."""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()
    if kind == "file":
        path.write_text("in the way")
    else:
        path.mkdir()


def _victim(root: Path) -> Path:
    """Someone else's directory next to the cache: old dot-files and dot-directories."""
    victim = root.parent / f"{root.name}-victim"
    (victim / ".ssh").mkdir(parents=True)
    (victim / ".ssh" / "id").write_text("key")
    (victim / ".bashrc").write_text("rc")
    (victim / "0123456789abcdef0123456789abcdef").mkdir()
    then = time.time() - 7200
    for path in (*victim.rglob("*"), victim):
        os.utime(path, (then, then))
    return victim


def _files(folder: Path) -> dict:
    return {str(p): p.read_bytes() if p.is_file() else None for p in sorted(folder.rglob("*"))}


def damage(root: Path, how: str) -> Path | None:
    """Damage the cache ``root`` as ``how`` says; the directory or file a planted link
    points to (which must stay unchanged), if any."""
    entry = _entry(root)
    module = next(entry.glob("*.so"))
    manifest = json.loads((entry / "manifest.json").read_text())
    if how == "module truncated, hash matching":
        _replace(module, module.read_bytes()[: module.stat().st_size // 2])
        data = {**manifest, "sha256": hashlib.sha256(module.read_bytes()).hexdigest()}
        _replace(entry / "manifest.json", json.dumps(data).encode())
    elif how == "manifest python":
        code = f"open({str(root.parent / 'planted-marker')!r}, 'w')\n"
        table = {**manifest["types"], "_types": code}
        data = {**manifest, "ffi": code, "types": table, "types_sha256": toolchain.table_sha256(
            table), "ffi_sha256": toolchain.sha256_of([code])}
        _replace(entry / "manifest.json", json.dumps(data).encode())
    elif how.endswith(" link"):
        victim = _victim(root)
        name = how.split()[0]
        if name == "lock":
            shutil.rmtree(entry)  # a build is needed: it takes the lock
            for lock in (root / "locks").iterdir():
                lock.unlink()
                lock.symlink_to(victim / ".bashrc")
        else:
            shutil.rmtree(root / name)
            (root / name).symlink_to(victim)
        return victim
    elif how == "root writable":
        root.chmod(0o777)
    elif how == "entry writable":
        module.chmod(0o777)
    elif how == "manifest garbage":
        _replace(entry / "manifest.json", b"{not json")
    elif how == "manifest list":
        _replace(entry / "manifest.json", b"[1, 2, 3]")
    elif how == "manifest wrong hash":
        data = json.loads((entry / "manifest.json").read_text())
        data["sha256"] = "0" * 64
        _replace(entry / "manifest.json", json.dumps(data).encode())
    elif how == "module truncated":
        _replace(module, module.read_bytes()[:64])
    elif how == "module missing":
        module.unlink()
    elif how == "module directory":
        _in_the_way(module, "dir")
    elif how in ("kernels", "index", "tmp", "locks"):
        _in_the_way(root / how, "file")
    elif how == "entry file":
        _in_the_way(entry, "file")
    elif how == "entry symlink loop":
        shutil.rmtree(entry)
        entry.symlink_to(entry)
    elif how == "index garbage":
        for f in (root / "index").iterdir():
            _replace(f, b"\0\0")
    elif how == "index outside":
        for f in (root / "index").iterdir():
            _replace(f, json.dumps({"source_key": "../../x", "prefix": 3}).encode())
    elif how == "stale build":
        (root / "tmp" / f"build-{entry.name}-stale").mkdir(parents=True)
    elif how == "root file":
        shutil.rmtree(root)
        root.write_text("in the way")
    return None


DAMAGE = ["manifest garbage", "manifest list", "manifest wrong hash", "module truncated",
          "module missing", "module directory", "kernels", "index", "tmp", "locks",
          "entry file", "entry symlink loop", "index garbage", "index outside", "stale build",
          "root file", "module truncated, hash matching", "manifest python", "kernels link",
          "tmp link", "index link", "locks link", "lock link", "root writable",
          "entry writable"]


def check_kernel(sim) -> None:
    assert sim.backend == "c"
    states = sim.simulate(START, 3, PARAMS).states
    assert np.allclose(states, REFERENCE, rtol=1e-13, atol=1e-15), (states, REFERENCE)


@needs_cc
@pytest.mark.parametrize("run", PROFILES)
def test_damaged_cache(tmp_path, run):
    @profile(run, 1, 30)
    @given(how=st.sampled_from(DAMAGE), relative=st.booleans())
    def prop(how, relative):
        root = tmp_path / f"cache-{next(_BUILD)}"
        flags = fresh_flags()
        cache_dir = os.path.relpath(root) if relative else root
        check_kernel(STEP.compile(backend="c", cache_dir=cache_dir, flags=flags))
        victim = damage(root, how)
        before = _files(victim) if victim is not None else None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # an unwritable root falls back
            judge("compile_step (damaged cache)",
                  lambda: STEP.compile(backend="c", cache_dir=cache_dir, flags=flags),
                  ["cache", "kernel cache", str(root)], owner=STEP.name, verify=check_kernel)
            with contextlib.suppress(sg.SymgroupoidError):
                cache_info(root)
                clear_cache(root)
        assert not (root.parent / "planted-marker").exists()
        if victim is not None:
            assert _files(victim) == before

    prop()


# --- environment variables and maintenance --------------------------------------------------------

ENVIRONMENT = {
    "SYMGROUPOID_CACHE": ["", "relative", "~", "~nobody-here/x", "file", " ", "a\nb"],
    "SYMGROUPOID_BACKEND": ["", "numpy", "NumPy", "c ", "fortran", "auto"],
    "SYMGROUPOID_LOCK_TIMEOUT": ["", "0", "-1", "nan", "inf", "ten", "1e999", "5"],
    "SYMGROUPOID_OPENMP": ["", "0", "1", "no", "yes"],
    "SYMGROUPOID_SHARED_CACHE": ["", "relative", "~", "file", " ", "/"],
    "XDG_CACHE_HOME": ["", "relative", "file"],
}


@pytest.mark.parametrize("run", PROFILES)
def test_environment_and_maintenance(tmp_path, monkeypatch, run):
    """Junk in the environment, then a NumPy-backend compile (whatever the backend
    variable says, an explicit backend wins), ``cache_info`` and ``clear_cache``.  The home
    directory is a scratch one: an empty variable falls back to ``~/.cache``, which must
    never be the user's."""
    Path("file").write_text("a file in the way")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))

    @profile(run, 6)
    @given(data=st.data())
    def prop(data):
        key = data.draw(st.sampled_from(sorted(ENVIRONMENT)))
        value = data.draw(st.one_of(st.sampled_from(ENVIRONMENT[key]),
                                    st.text(alphabet="abc/~. 0", max_size=6)))
        with monkeypatch.context() as m:
            if key == "XDG_CACHE_HOME":
                m.delenv("SYMGROUPOID_CACHE", raising=False)
            m.setenv(key, value)
            action = data.draw(st.sampled_from(["compile", "info", "clear", "clear bad",
                                                "root"]))

            def call():
                if action == "compile":
                    return STEP.compile(backend="numpy")
                if action == "info":
                    return cache_info()
                if action.startswith("clear"):
                    return clear_cache(bad_only=action == "clear bad")
                return KernelCache().root

            def verify(result):
                if action == "compile":
                    assert np.allclose(result.simulate(START, 3, PARAMS).states, REFERENCE)
                elif action == "root":
                    assert result.is_absolute() and result == cache_root()
                else:
                    assert Path(result.root).is_absolute()

            judge(f"environment ({action})", call, [key, "cache"], verify=verify)

    prop()


@pytest.mark.parametrize("run", PROFILES)
def test_environment_of_a_boundary_value_solve(tmp_path, monkeypatch, run):
    """Junk in the backend and cache variables, then a boundary-value solve (its window
    kernel is built in the background where a compiler and a cache are usable): the same
    solution as the NumPy backend's, bit for bit, or a clear error naming the variable."""
    Path("file").write_text("a file in the way")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    system = oscillator()

    def solve():
        sol = sg.solve_boundary_value(oscillator(), (0.1,), (0.3,), 6, params=PARAMS)
        wait_for_kernels(120)
        return sol

    with monkeypatch.context() as m:
        m.setenv("SYMGROUPOID_BACKEND", "numpy")
        reference = sg.solve_boundary_value(system, (0.1,), (0.3,), 6, params=PARAMS).arrows

    @profile(run, 4)
    @given(data=st.data())
    def prop(data):
        key = data.draw(st.sampled_from(["SYMGROUPOID_BACKEND", "SYMGROUPOID_CACHE"]))
        value = data.draw(st.one_of(st.sampled_from(ENVIRONMENT[key]),
                                    st.text(alphabet="abc/~. 0", max_size=6)))
        with monkeypatch.context() as m, warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a cache it cannot use
            m.setenv(key, value)

            def verify(sol):
                assert np.array_equal(sol.arrows, reference)

            judge("environment (boundary value)", solve, [key, "cache"], verify=verify)

    prop()


# --- regression tests -------------------------------------------------------------------------

@needs_cc
def test_relative_cache_dir_is_resolved_once_against_the_working_directory(tmp_path,
                                                                           monkeypatch):
    """A relative ``cache_dir`` is the directory of that name in the working directory of
    the call, made absolute then: entries never land beside later working directories."""
    work, elsewhere = tmp_path / "work", tmp_path / "elsewhere"
    work.mkdir()
    elsewhere.mkdir()
    monkeypatch.chdir(work)
    flags = fresh_flags()
    sim = STEP.compile(backend="c", cache_dir="relative", flags=flags)
    assert sim.cache_entry.is_absolute()
    assert sim.cache_entry.parent.parent == work / "relative"
    monkeypatch.chdir(elsewhere)
    assert KernelCache(Path("x")).root == elsewhere / "x"
    assert sim.simulate(START, 3, PARAMS).states.tolist() == REFERENCE.tolist()
    assert not any(elsewhere.iterdir())


def test_relative_cache_variable_is_absolute(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("SYMGROUPOID_CACHE", "rel/../cache")
    assert cache_root() == tmp_path / "cache"


def _foreign_directory(path: Path) -> dict[Path, bytes]:
    """A directory a cache variable may point at by mistake ($HOME, a project): files of
    the user's under the cache's own names, and old dotfiles a sweep would take for
    leftovers.  Returns what must survive."""
    files = {path / "notes.txt": b"mine", path / "index" / "table.json": b"{}",
             path / "index" / ".hidden": b"h", path / "tmp" / ".build-x": b"t",
             path / "kernels" / "k" / "data": b"d", path / "locks" / "l.lock": b""}
    for f, data in files.items():
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(data)
        os.utime(f, (0, 0))  # older than any grace period
    return files


@needs_cc
def test_a_directory_that_is_not_a_cache_is_never_written_cleaned_or_swept(tmp_path,
                                                                           monkeypatch):
    home = tmp_path / "home"
    files = _foreign_directory(home)
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(home))
    with pytest.warns(RuntimeWarning, match=r"is not used \(it is not a kernel cache: it "
                                            r"holds other files \(index/.hidden"):
        sim = STEP.compile(backend="c", flags=fresh_flags())
    check_kernel(sim)
    assert not str(sim.cache_entry).startswith(str(home))
    with pytest.raises(sg.CacheError, match="is not a symgroupoid kernel cache .*nothing was "
                                            "removed"):
        clear_cache()
    info = cache_info()  # reading is harmless, and says it is not used (it listed a bad kernel)
    assert info.refused is not None and "not a kernel cache" in info.refused
    assert info.kernels == []
    for f, data in files.items():
        assert f.read_bytes() == data, f"{f} was changed"
    assert not (home / "CACHEDIR.TAG").exists() and not (home / "probes").exists()


@needs_cc
def test_directories_named_like_the_cache_with_other_contents_are_not_adopted(tmp_path,
                                                                             monkeypatch):
    """Only a layout a cache writes (hash-named entries) is adopted as an old cache; a
    project's own index/ or tmp/ directory is not, even with nothing else beside it."""
    project = tmp_path / "project"
    files = {project / "index" / "table.json": b"{}", project / "tmp" / ".x": b"t",
             project / "kernels" / "README": b"r"}
    for f, data in files.items():
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_bytes(data)
        os.utime(f, (0, 0))
    monkeypatch.setenv("SYMGROUPOID_CACHE", str(project))
    with pytest.warns(RuntimeWarning, match=r"holds other files \(index/table.json, "
                                            r"kernels/README, tmp/.x\)"):
        check_kernel(STEP.compile(backend="c", flags=fresh_flags()))
    with pytest.raises(sg.CacheError, match="nothing was removed"):
        clear_cache()
    assert all(f.read_bytes() == data for f, data in files.items())


@needs_cc
def test_a_new_or_empty_cache_root_is_marked_and_an_old_layout_is_adopted(tmp_path):
    new = tmp_path / "new"
    STEP.compile(backend="c", cache_dir=new, flags=fresh_flags())
    assert (new / "CACHEDIR.TAG").read_text().startswith(
        "Signature: 8a477f597d28d172789f06886806bc55")
    old = tmp_path / "old"
    for name in ("index", "kernels", "locks", "tmp", "probes"):
        (old / name).mkdir(parents=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        check_kernel(STEP.compile(backend="c", cache_dir=old, flags=fresh_flags()))
    assert (old / "CACHEDIR.TAG").is_file()
    assert clear_cache(old).removed == 1


def test_emit_c_writes_both_files_or_neither(tmp_path):
    """A directory in the way of NAME.c: the command failed, and the NAME.h it had just
    written stayed beside it (``generate`` left half of a seed's pair)."""
    step, out = STEP, tmp_path / "out"
    (out / "kernel.c").mkdir(parents=True)
    with pytest.raises(sg.OutputError, match="kernel.c"):
        sg.emit_c(step, out / "kernel")
    assert sorted(p.name for p in out.iterdir()) == ["kernel.c"]
    assert list((out / "kernel.c").iterdir()) == []
    c, h = sg.emit_c(step, out / "other")
    assert c.read_text().startswith("/*") and h.exists()


@pytest.mark.parametrize("prefix", ["1bad-prefix", "My_Kernel", "int", "a b"])
def test_a_prefix_that_is_not_a_c_identifier_is_refused_not_rewritten(prefix, tmp_path):
    """``emit --prefix 1bad-prefix`` wrote identifiers sg_1bad_prefix_* without a word: a
    program written against the prefix it asked for would not link."""
    with pytest.raises(sg.ShapeError, match="is not a prefix of C identifiers"):
        sg.emit_c(STEP, tmp_path / "out" / "k", prefix=prefix)
    assert not (tmp_path / "out").exists()


def _rigid_body_run(tmp_path):
    from symgroupoid import systems

    sim = systems.rigid_body().euler_lagrange().compile(backend="numpy")
    params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    W0 = np.array(sg.SO3("W").cayley([0.02, 0.05, -0.03]).tolist(), float)
    path = tmp_path / "run.npz"
    sim.simulate({"W": W0}, 4, params).save(path)
    return sim, path


def test_a_trajectory_with_a_state_off_its_group_inside_is_refused(tmp_path):
    """Only the first and last states of a loaded file were checked: an edited middle state
    (not a rotation) loaded, and the energy was computed on it silently."""
    sim, path = _rigid_body_run(tmp_path)
    arrays = dict(np.load(path))
    arrays["states"] = arrays["states"].copy()
    arrays["states"][2] = np.arange(9.0)
    np.savez(tmp_path / "edited.npz", **arrays)
    with pytest.raises(sg.TrajectoryFileError, match="its state 2 .* not in SO3"):
        sg.Trajectory.load(tmp_path / "edited.npz", sim)
    assert len(sg.Trajectory.load(path, sim).states) == 5  # the file as written loads


def test_an_array_header_claiming_more_than_its_file_is_refused_before_allocating(tmp_path):
    """A states.npy header claiming shape (10¹⁵, 9) made NumPy allocate 64 PiB first: a
    raw MemoryError.  The claim is compared with what the member holds."""
    import io
    import zipfile

    sim, path = _rigid_body_run(tmp_path)
    with zipfile.ZipFile(path) as source, zipfile.ZipFile(tmp_path / "huge.npz", "w") as out:
        for name in source.namelist():
            data = source.read(name)
            if name == "states.npy":
                header = io.BytesIO()
                np.lib.format.write_array_header_1_0(
                    header, {"descr": "<f8", "fortran_order": False, "shape": (10**15, 9)})
                data = header.getvalue() + bytes(64)
            out.writestr(name, data)
    with pytest.raises(sg.TrajectoryFileError, match="claims 72,000,000,000,000,000 bytes"):
        sg.Trajectory.load(tmp_path / "huge.npz", sim)


def test_step_indices_beyond_int64_are_refused_not_wrapped(tmp_path):
    """uint64 step indices ≥ 2⁶³ were cast to int64 and read back negative."""
    sim, path = _rigid_body_run(tmp_path)
    arrays = dict(np.load(path))
    arrays["step_indices"] = np.arange(5, dtype=np.uint64) + np.uint64(2**63)
    np.savez(tmp_path / "wrapped.npz", **arrays)
    with pytest.raises(sg.TrajectoryFileError, match="beyond the 64-bit integers"):
        sg.Trajectory.load(tmp_path / "wrapped.npz", sim)
