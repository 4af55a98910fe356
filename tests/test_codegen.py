"""Layer 4: the emitted C — content, determinism, strict compilation, agreement with SymPy."""

from __future__ import annotations

import copy
import re
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    REPO,
    SESSION_CACHE,
    compiled,
    isolated_cache,
    needs_cc,
    seed_step,
)

import symgroupoid as sg
from symgroupoid.codegen import MAX_PREFIX, KernelCPrinter, c_identifier, emit_c, generate_c
from symgroupoid.ir import UnmappedSymbolError

SEEDS = ("plate_ball", "heavy_top", "rigid_body")
#: the kernels shipped in generated/: the seed systems' and the forced satellite's of
#: examples/embed/closed_loop.c
GOLDEN = (*SEEDS, "satellite_wheel")
IDENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


# --- identifiers and printing --------------------------------------------------------------

@pytest.mark.parametrize("name, expected", [
    ("plate_ball", "plate_ball"), ("Plate-Ball 2", "plate_ball_2"), ("2body", "sg_2body"),
    ("for", "sg_for"), ("", "sg_system"), ("héavy top!", "h_avy_top"), ("__x__", "x"),
])
def test_c_identifier_is_sanitised(name, expected):
    assert c_identifier(name) == expected
    assert IDENT.match(c_identifier(name))


def test_a_long_name_gives_a_prefix_that_names_files():
    """A system named by 300 characters compiled into files whose names were too long for
    the file system, and the build said the cache could not be written (moving the cache
    would not help): the prefix is at most MAX_PREFIX characters, its end a digest of the
    whole name."""
    long, other = "x" * 300, "x" * 299 + "y"
    assert len(c_identifier(long)) == MAX_PREFIX and IDENT.match(c_identifier(long))
    assert c_identifier(long) != c_identifier(other)
    assert c_identifier(long)[:55] == "x" * 55 and c_identifier("x" * MAX_PREFIX) == "x" * 64


def test_printer_maps_symbols_by_table_and_dispatches_on_type():
    x, y, p = sp.symbols("x y p", real=True)
    printer = KernelCPrinter({x: "u[0]", y: "known[1]", p: "p[0]"})
    assert printer.doprint(x ** 3) == "(u[0]*u[0]*u[0])"
    assert printer.doprint(x ** -2) == "(1.0/(u[0]*u[0]))"
    assert printer.doprint(sp.Rational(3, 7) * y) == "(3.0/7.0)*known[1]"
    assert printer.doprint(sp.sqrt(p)) == "sqrt(p[0])"
    assert printer.doprint(sp.Float("0.1") * x) == "0.1*u[0]"
    with pytest.raises(UnmappedSymbolError, match="'z'"):
        printer.doprint(x + sp.Symbol("z"))


# --- emitted files --------------------------------------------------------------------------

def test_emit_c_writes_short_comments_by_default_and_latex_on_request(tmp_path):
    """``emit_c`` numbers the equations in the source's comment and builds no SymPy
    residuals; ``latex=True`` lists them in LaTeX (the matrix form, as printed)."""
    from symgroupoid.systems import SEED_SYSTEMS

    fresh = SEED_SYSTEMS["plate_ball"]().euler_lagrange()
    c_path, _ = emit_c(fresh, tmp_path / "short")
    assert fresh._d.residuals is None, "emit_c built the SymPy residuals"
    short = c_path.read_text()
    assert " *   F[0]: 0 = equation 0 of the step (print the equations with " in short
    assert "\\operatorname" not in short and "\\frac" not in short
    with pytest.raises(sg.InputTypeError, match="latex must be True or False"):
        emit_c(fresh, tmp_path / "bad", latex="yes")
    step = seed_step("plate_ball")
    c_path, h_path = emit_c(step, tmp_path / "pb", latex=True)
    assert (c_path.name, h_path.name) == ("pb.c", "pb.h")
    header, source = h_path.read_text(), c_path.read_text()
    assert '"plate_ball"' in header and '"plate_ball"' in source
    assert "#define PLATE_BALL_N_EQUATIONS 8" in header
    assert "(8 equations)" in source and '#include "pb.h"' in source
    assert step.structured is not None  # the comments show the matrix form, as printed
    for i, r in enumerate(step.structured):
        assert f" *   F[{i}]: 0 = {sg.latex(r)}\n" in source
    assert "\\operatorname{tr}(g_{k} E_{1} E_{2})" in source
    assert source.isascii() and header.isascii()


def test_emit_is_deterministic(tmp_path):
    step = seed_step("heavy_top")
    a = emit_c(step, tmp_path / "a" / "k")
    b = emit_c(step, tmp_path / "b" / "k")
    for p, q in zip(a, b):
        assert p.read_bytes() == q.read_bytes()


def test_generated_kernels_are_up_to_date(tmp_path):
    """``generated/`` equals a fresh ``python -m symgroupoid generate`` (another process)."""
    out = tmp_path / "generated"
    subprocess.run([sys.executable, "-m", "symgroupoid", "generate", str(out)], check=True,
                   cwd=REPO, capture_output=True, env={"PYTHONHASHSEED": "12345",
                                                       "PYTHONPATH": str(REPO), "PATH": ""})
    names = sorted(p.name for p in (REPO / "generated").iterdir())
    assert names == sorted(f"{s}.{e}" for s in GOLDEN for e in "ch")
    for name in names:
        assert (out / name).read_bytes() == (REPO / "generated" / name).read_bytes(), (
            f"generated/{name} is stale: run `make generated`")


@needs_cc
@pytest.mark.parametrize("name", GOLDEN)
def test_generated_kernel_compiles_strict_c99_without_python(tmp_path, name):
    cmd = ["cc", "-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror", "-c",
           str(REPO / "generated" / f"{name}.c"), "-o", str(tmp_path / f"{name}.o")]
    result = subprocess.run(cmd, capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    source = (REPO / "generated" / f"{name}.c").read_text()
    assert "Python.h" not in source and "#include <Python" not in source


@needs_cc
def test_a_kernel_cut_into_parts_compiles_strict_c99(tmp_path):
    """Functions cut into parts (kernels of more than 200 statements a function) left
    parameters unused in some parts: -Wextra -Werror, the embedding example's flags,
    refused them."""
    from symgroupoid import systems

    c_path, _ = sg.emit_c(systems.spherical_chain(3, forced=True).euler_lagrange(),
                          tmp_path / "chain")
    assert "_part1(" in c_path.read_text()
    cmd = ["cc", "-std=c99", "-pedantic", "-O0", "-Wall", "-Wextra", "-Werror", "-c",
           str(c_path), "-o", str(tmp_path / "chain.o")]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr


def test_non_square_systems_are_rejected():
    step = seed_step("rigid_body")

    class Short(type(step)):  # the step's equations with a row short
        def __len__(self) -> int:
            return 2

    fake = copy.copy(step)
    fake.__class__ = Short
    with pytest.raises(ValueError, match="2 equations in 3 unknowns"):
        generate_c(fake)


# --- packaging ------------------------------------------------------------------------------

def test_templates_are_packaged_with_every_subpackage():
    import tomllib

    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    on_disk = {".".join(p.parent.relative_to(REPO).parts)  # subpackages at any depth
               for p in (REPO / "symgroupoid").glob("*/**/__init__.py")}
    assert on_disk | {"symgroupoid", "symgroupoid.templates"} == listed
    assert config["package-dir"]["symgroupoid.templates"] == "templates"
    assert config["package-data"]["symgroupoid.templates"] == ["*.j2"]
    assert {p.name for p in (REPO / "templates").glob("*.j2")} >= {"kernel.c.j2", "kernel.h.j2"}
    from symgroupoid.stepper import SOURCES

    assert config["package-data"]["symgroupoid.stepper"] == ["*.c", "*.h"]
    assert {p.name for p in (REPO / "symgroupoid" / "stepper").glob("*.[ch]")} == set(SOURCES)


@pytest.mark.slow
def test_built_wheel_contains_the_templates(tmp_path):
    import zipfile

    result = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w",
                             str(tmp_path), str(REPO)], capture_output=True, text=True)
    if result.returncode != 0 and "Could not find a version" in result.stderr:
        pytest.skip("no package index reachable for the isolated build")
    assert result.returncode == 0, result.stderr
    (wheel,) = tmp_path.glob("*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    for t in ("kernel.c.j2", "kernel.h.j2", "declarations.j2", "cdef.j2"):
        assert f"symgroupoid/templates/{t}" in names
    for s in ("stepper.c", "stepper.h", "batch.c"):
        assert f"symgroupoid/stepper/{s}" in names


# --- the compiled kernels agree with SymPy --------------------------------------------------

def _random_point(step, rng):
    """Unknowns near the solution scale, a state with a group element, positive parameters."""
    G = step.groupoid
    known_arrow = G.random_arrow(rng)
    n_arrow = len(known_arrow)
    known = np.concatenate([known_arrow, rng.uniform(-1, 1, len(step.knowns) - n_arrow)])
    u = rng.uniform(-0.5, 0.5, len(step.unknowns))
    p = rng.uniform(0.5, 2.0, len(step.parameters))
    return u, known, p


def _exact(exprs, step, u, known, p):
    sub = {**dict(zip(step.unknowns, map(sp.Float, u))),
           **dict(zip(step.knowns, map(sp.Float, known))),
           **dict(zip(step.parameters, map(sp.Float, p)))}
    return np.array([float(sp.sympify(e).xreplace(sub).evalf(30)) for e in exprs])


def _assert_rowwise_close(actual, exact, rtol):
    """|actual − exact| ≤ rtol · max|exact row| (relative to each row's scale)."""
    actual, exact = np.atleast_2d(actual), np.atleast_2d(exact)
    scale = np.maximum(np.abs(exact).max(axis=1, keepdims=True), 1e-300)
    assert (np.abs(actual - exact) <= rtol * scale).all(), np.abs(actual - exact) / scale


@needs_cc
@pytest.mark.parametrize("name", SEEDS)
def test_c_residual_and_jacobian_match_sympy(name):
    step, kernel = seed_step(name), compiled(name).kernel
    rng = np.random.default_rng(7)
    J_exact = step.jacobian(substitute=True)
    for _ in range(3):
        u, known, p = _random_point(step, rng)
        F, J = kernel.residual_jacobian(u, known, p)
        _assert_rowwise_close(F[None], _exact(step.residuals_in_unknowns(), step, u, known,
                                              p)[None], 1e-12)
        _assert_rowwise_close(J, _exact(list(J_exact), step, u, known, p).reshape(J.shape),
                              1e-12)
        _assert_rowwise_close(kernel.residual(u, known, p), F, 1e-14)
        _assert_rowwise_close(kernel.next_knowns(u, known, p)[None],
                              _exact(step.next_knowns, step, u, known, p)[None], 1e-12)
        _assert_rowwise_close(kernel.predict(known, p)[None],
                              _exact(step.prediction, step, u, known, p)[None], 1e-12)


@needs_cc
@pytest.mark.parametrize("name", SEEDS)
def test_c_jacobian_matches_finite_differences(name):
    step, kernel = seed_step(name), compiled(name).kernel
    rng = np.random.default_rng(11)
    u, known, p = _random_point(step, rng)
    _, J = kernel.residual_jacobian(u, known, p)
    eps = 1e-6
    fd = np.empty_like(J)
    for j in range(len(u)):
        e = np.zeros_like(u)
        e[j] = eps
        fd[:, j] = (kernel.residual(u + e, known, p) - kernel.residual(u - e, known, p)) / (2 * eps)
    assert np.abs(fd - J).max() <= 1e-7 * max(1.0, np.abs(J).max())


@needs_cc
def test_c_reconstruction_is_the_cayley_map():
    """The α-fibre chart of the rigid body's SO(3): fibre = cay(u), orthogonal, det 1."""
    kernel = compiled("rigid_body").kernel
    lib, ffi = kernel.lib, kernel.ffi
    u = np.array([0.3, -0.2, 0.5])
    fibre = np.empty(9)
    known, p = np.zeros(len(seed_step("rigid_body").knowns)), np.ones(4)
    lib.rigid_body_reconstruct(ffi.from_buffer("double[]", u), ffi.from_buffer("double[]", known),
                               ffi.from_buffer("double[]", p), ffi.from_buffer("double[]", fibre))
    W = fibre.reshape(3, 3)
    X = sg.hat3(u)
    cay = np.array(((sp.eye(3) - X / 2).inv() * (sp.eye(3) + X / 2)).evalf(), dtype=float)
    assert np.abs(W - cay).max() < 1e-15
    assert np.abs(W.T @ W - np.eye(3)).max() < 1e-15


@needs_cc
def test_exponential_retraction_kernel_compiles_strictly_and_matches_numpy(tmp_path):
    """SO(3) with the exp chart: its special functions print through their C methods."""
    from symgroupoid.systems import discrete_inertia

    h = sp.Symbol("h", positive=True)
    inertia = sp.symbols("I1 I2 I3", positive=True)
    Jd = discrete_inertia(*inertia)
    step = sg.DiscreteSystem(sg.SO3("W", retraction="exp"),
                             lambda g: -(Jd * g.matrix).trace() / h,
                             parameters=[h, *inertia], name="rigid body (exp)").euler_lagrange()
    c_path, _ = emit_c(step, tmp_path / "rb_exp")
    assert "rigid_body_exp_simulate(" in c_path.read_text()
    result = subprocess.run(["cc", "-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror",
                             "-c", str(c_path), "-o", str(tmp_path / "rb_exp.o")],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    params = {"h": 0.01, "I1": 1.0, "I2": 2.0, "I3": 3.0}
    c_sim = step.compile(backend="c")
    np_sim = step.compile(backend="numpy")
    state = c_sim.from_momentum(None, (0.3, 0.2, 0.1), params)
    a, b = c_sim.simulate(state, 100, params), np_sim.simulate(state, 100, params)
    assert np.abs(a.states - b.states).max() <= 1e-12
    at_rest = c_sim.simulate({"W": np.eye(3)}, 3, params)  # zero rotation: no 0/0
    assert np.array_equal(at_rest["W"][-1], np.eye(3))
