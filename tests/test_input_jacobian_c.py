"""∂F/∂(u_k, u_{k+1}) in the emitted C (docs/conventions.md §20): ``<prefix>_input_jacobian``
of a forced kernel equals ``StepEquations.input_jacobian`` bit for bit (one program, two
evaluators, §17) and the finite differences of the C residual in the inputs' entries of the
known state; kernels without inputs have no such function."""

from __future__ import annotations

import ctypes
import subprocess

import numpy as np
import pytest
import sympy as sp
from kernel_support import isolated_cache, needs_cc, seed_step  # noqa: F401  (autouse)

import symgroupoid as sg
from symgroupoid.codegen import generate_c

pytestmark = needs_cc

h, m, k, c = sp.symbols("h m k c", positive=True)
u, w = sp.symbols("u w", real=True)
FLAGS = ["-std=c99", "-pedantic", "-O2", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off",
         "-fPIC", "-shared"]


def _two_inputs_step():
    """A point in the plane driven by a torque u about the origin and a push w along x that
    grows with the torque (u·w: the inputs enter nonlinearly), with damping c."""
    G = sg.PairGroupoid(sg.EuclideanSpace(["x", "y"]))

    def L(g):
        (x0, y0), (x1, y1) = g.source, g.target
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        return h * (m / 2 * (((x1 - x0) / h) ** 2 + ((y1 - y0) / h) ** 2)
                    - k / 2 * (xm ** 2 + ym ** 2))

    def forces(g):
        (x0, y0), (x1, y1) = g.source, g.target
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        r2 = xm ** 2 + ym ** 2 + 1
        F = [-c * (x1 - x0) / h - u * ym / r2 + w * sp.cos(u * ym),
             -c * (y1 - y0) / h + u * xm / r2 + u * w * xm]
        return [h / 4 * f for f in F], [3 * h / 4 * f for f in F]

    return sg.DiscreteSystem(G, L, parameters=[h, m, k, c], forces=forces, inputs=[u, w],
                             name="pushed", time_step=h).euler_lagrange()


@pytest.fixture(scope="module")
def pushed():
    return _two_inputs_step()


def _library(tmp_path, kernel, name: str) -> ctypes.CDLL:
    """The kernel's translation units built into one shared library."""
    directory = tmp_path / name
    directory.mkdir()
    (directory / kernel.header_name).write_text(kernel.header)
    sources = [directory / f"{kernel.prefix}.c"]
    sources[0].write_text(kernel.source)
    for unit, text in kernel.units:
        (directory / unit).write_text(text)
        sources.append(directory / unit)
    lib = directory / f"lib{name}.so"
    build = subprocess.run(["cc", *FLAGS, *map(str, sources), "-lm", "-o", str(lib)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    return ctypes.CDLL(str(lib))


def _call(function, *arrays: np.ndarray) -> None:
    pointer = ctypes.POINTER(ctypes.c_double)
    function(*(a.ctypes.data_as(pointer) for a in arrays))


@pytest.mark.parametrize("units", [1, 3])
def test_the_c_input_jacobian_is_the_python_one_and_the_residual_s_derivative(pushed, tmp_path,
                                                                            units):
    kernel = generate_c(pushed, "pushed", units=units)
    assert ("pushed_cold.c" in dict(kernel.units)) == (units > 1)
    assert "void pushed_input_jacobian(const double *u, const double *known, const double *p, " \
           "double *J_inputs);" in kernel.header and "pushed_input_jacobian" in kernel.cdef
    # the batched entry points take the inputs too, and the header's prose says so
    assert "pushed_simulate_batch(n_batch, known0, p, p_stride, u, u_stride," in kernel.header
    assert "inputs u + b * u_stride" in kernel.header and "no inputs yet" not in kernel.header
    lib = _library(tmp_path, kernel, f"pushed{units}")
    n, n_k, n_p = len(pushed.unknowns), len(pushed.knowns), len(pushed.parameters)
    assert n_k == 8 and [str(s) for s in pushed.knowns[4:]] == ["u_{k}", "w_{k}", "u_{k+1}",
                                                                 "w_{k+1}"]
    rng = np.random.default_rng(28)
    eps = 1e-6
    for _ in range(5):
        x, known = rng.normal(size=n), rng.normal(size=n_k)
        p = rng.uniform(0.5, 2.0, size=n_p)
        J = np.empty((n, 4))
        _call(lib.pushed_input_jacobian, x, known, p, J)
        assert np.array_equal(J, pushed.input_jacobian(x, known, p))  # the same bits (§17)
        for j in range(4):
            F = [np.empty(n), np.empty(n)]
            for sign, out in zip((1, -1), F):
                moved = known.copy()
                moved[n_k - 4 + j] += sign * eps
                _call(lib.pushed_residual, x, moved, p, out)
            np.testing.assert_allclose(J[:, j], (F[0] - F[1]) / (2 * eps), rtol=1e-7,
                                       atol=1e-8)
        assert np.abs(J[:, :2]).min() > 0 and np.abs(J[:, 2:]).min() > 0


def test_only_a_kernel_with_inputs_has_the_input_jacobian():
    kernel = generate_c(seed_step("rigid_body"), "rigid_body", units=3)
    for text in (kernel.header, kernel.source, kernel.cdef, *dict(kernel.units).values()):
        assert "input_jacobian" not in text


def test_the_simulator_s_input_jacobian_is_the_kernel_s_on_both_backends(pushed):
    """``Simulator.input_jacobian`` evaluates the compiled ``<prefix>_input_jacobian`` (the
    NumPy backend the same program: the same bits) at the step's solution, and with the
    step's Jacobian gives the derivative of the solution in the new arrow's inputs."""
    params = {"h": 0.05, "m": 1.0, "k": 2.0, "c": 0.3}
    sims = [pushed.compile(backend=b) for b in ("c", "numpy")]
    state = np.array([1.0, 0.2, 0.98, 0.25, 0.4, -0.3, 0.0, 0.0])
    u_next = np.array([0.5, 0.1])
    x = sims[0].solve(state, params, inputs=u_next)[0]
    Ju = [sim.input_jacobian(state, params, inputs=u_next) for sim in sims]
    assert Ju[0].shape == (2, 4) and np.array_equal(Ju[0], Ju[1])
    known = np.r_[state[:6], u_next]
    p = sims[0].parameters(params)
    assert np.array_equal(Ju[0], pushed.input_jacobian(x, known, p))
    assert np.array_equal(Ju[0], sims[0].input_jacobian(state, params, inputs=u_next,
                                                        unknowns=x))
    _, J = sims[0].kernel.residual_jacobian(x, known, p)
    sensitivity = np.linalg.solve(J, -Ju[0][:, 2:])  # d(solution)/d(u_{k+1})
    eps = 1e-6
    for j in range(2):
        moved = [sims[0].solve(state, params, inputs=u_next + s * eps * np.eye(2)[j])[0]
                 for s in (1, -1)]
        np.testing.assert_allclose(sensitivity[:, j], (moved[0] - moved[1]) / (2 * eps),
                                   rtol=1e-6, atol=1e-9)
    with pytest.raises(sg.ShapeError):
        sims[0].input_jacobian(state, params, inputs=u_next, unknowns=x[:1])
    plain = seed_step("rigid_body").compile()
    with pytest.raises(sg.UnsupportedFeatureError, match="no inputs"):
        plain.input_jacobian(np.zeros(3), {})


def test_a_second_order_kernel_documents_three_input_columns(tmp_path):
    """A second-order step's ∂F/∂u has the columns of u_{k−1}, u_k, u_{k+1} (3m): the
    header says so, and the C writes what ``StepEquations.input_jacobian`` gives."""
    def L(g1, g2):
        (q0,), (q1,) = g1.source, g1.target
        return (g2.target[0] - 2 * q1 + q0) ** 2 / (2 * h ** 3) + k * q1 ** 2

    step = sg.SecondOrderSystem(sg.PairGroupoid(sg.EuclideanSpace("q")), L, parameters=[h, k],
                                forces=lambda g1, g2: ([u * g1.source[0]], [h * u], [w]),
                                inputs=[u, w], name="spline").euler_lagrange()
    kernel = generate_c(step, "spline", units=1)
    assert "1 x 6: the columns of the inputs in the last 6 entries" in kernel.header
    assert "those of the known pairs (u_{k-1}, u_k)" in kernel.header
    lib = _library(tmp_path, kernel, "spline")
    rng = np.random.default_rng(7)
    x, known = rng.normal(size=1), rng.normal(size=len(step.knowns))
    p = np.array([0.1, 0.5])
    J = np.empty((1, 6))
    _call(lib.spline_input_jacobian, x, known, p, J)
    assert np.array_equal(J, step.input_jacobian(x, known, p)) and np.abs(J).max() > 0
