"""The Newton stepper's C library on its own (``symgroupoid/stepper``): compiled from its
sources with a small hand-written kernel, run through its entry points, and compared bit for
bit with its NumPy twin; its statuses and default options against the one :class:`Status`
enum and ``DEFAULT_OPTIONS``.

The toy kernel: known state (a, b), parameter c, unknowns u with
F = (u_0² − a, u_1 − b), the next state (a + c, u_0) and the prediction u = (b, b): a run
from (2, 1) follows u_0 = √a_k; from b = 0 the prediction is the singular point u_0 = 0 of
J = diag(2u_0, 1); from a = −2 there is no root, and Newton wanders until its iteration cap;
from a = 10³⁰⁰ the residual overflows.
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from kernel_support import needs_cc

from symgroupoid.runtime import NewtonOptions
from symgroupoid.stepper import (
    DEFAULT_OPTIONS,
    STATUS_MESSAGES,
    NumpyStepper,
    Status,
    StepFunctions,
    c_defines,
    c_status_message,
    library_dir,
    library_source,
)

#: the toy kernel's functions, hand-written as the code generator would write them
TOY_C = r"""
#define TOY_N_EQUATIONS 2
#define TOY_N_UNKNOWNS 2
#define TOY_N_KNOWNS 2
#define TOY_N_PARAMETERS 1
#define TOY_N_INPUTS 0
#define TOY_N_HOISTED 1
#define TOY_TIME_ROW -1
#define TOY_TIME_UNKNOWN -1
#define TOY_TIME_KNOWN -1
#define TOY_TIME_BEFORE -1
#include <math.h>
#include "stepper.h"

void toy_reconstruct(const double *u, const double *known, const double *p, double *fibre)
{
    (void)known;
    (void)p;
    fibre[0] = u[0];
    fibre[1] = u[1];
}

void toy_hoist(const double *known, const double *p, double *h)
{
    (void)p;
    h[0] = -known[0];
}

void toy_residual_hoisted(const double *u, const double *known, const double *p,
                          const double *h, double *F)
{
    (void)p;
    F[0] = u[0] * u[0] + h[0];
    F[1] = u[1] - known[1];
}

void toy_residual(const double *u, const double *known, const double *p, double *F)
{
    double h[1];
    toy_hoist(known, p, h);
    toy_residual_hoisted(u, known, p, h, F);
}

void toy_residual_jacobian_hoisted(const double *u, const double *known, const double *p,
                                   const double *h, double *F, double *J)
{
    toy_residual_hoisted(u, known, p, h, F);
    J[0] = 2.0 * u[0];
    J[1] = 0.0;
    J[2] = 0.0;
    J[3] = 1.0;
}

void toy_residual_jacobian(const double *u, const double *known, const double *p, double *F,
                           double *J)
{
    double h[1];
    toy_hoist(known, p, h);
    toy_residual_jacobian_hoisted(u, known, p, h, F, J);
}

void toy_residual_scale(const double *u, const double *known, const double *p, double *S)
{
    (void)p;
    S[0] = u[0] * u[0] + fabs(known[0]);
    S[1] = fabs(u[1]) + fabs(known[1]);
}

void toy_predict(const double *known, const double *p, double *u)
{
    (void)p;
    u[0] = known[1];
    u[1] = known[1];
}

void toy_next_knowns(const double *u, const double *known, const double *p,
                     double *known_next)
{
    known_next[0] = known[0] + p[0];
    known_next[1] = u[0];
}
"""

#: what the library is compiled with: the embedded kernels' warning flags, as errors
FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-fPIC",
         "-DSG_PREFIX=toy", "-DSG_PREFIX_UPPER=TOY"]


def _toy_functions() -> StepFunctions:
    """The toy kernel's functions in NumPy (the same operations as :data:`TOY_C`)."""

    def residual(u, known, p):
        return np.array([u[0] * u[0] - known[0], u[1] - known[1]])

    def residual_jacobian(u, known, p):
        return residual(u, known, p), np.array([[2.0 * u[0], 0.0], [0.0, 1.0]])

    return StepFunctions(
        residual=residual, residual_jacobian=residual_jacobian,
        residual_scale=lambda u, known, p: np.array([u[0] * u[0] + abs(known[0]),
                                                     abs(u[1]) + abs(known[1])]),
        predict=lambda known, p: np.array([known[1], known[1]]),
        next_knowns=lambda u, known, p: np.array([known[0] + p[0], u[0]]))


class _Options(ctypes.Structure):
    _fields_ = [("tol_residual", ctypes.c_double), ("floor_factor", ctypes.c_double),
                ("tol_step", ctypes.c_double), ("max_iterations", ctypes.c_int),
                ("extrapolate", ctypes.c_int), ("trust_factor", ctypes.c_double)]


class _WarmStart(ctypes.Structure):
    _fields_ = [("count", ctypes.c_int), ("quadratic", ctypes.c_int),
                ("u_last", ctypes.c_double * 2), ("u_before", ctypes.c_double * 2),
                ("u_earlier", ctypes.c_double * 2)]


def _double_p(array: np.ndarray):
    return array.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    """The library's two sources compiled each on its own beside the toy kernel, linked."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH")
    where = tmp_path_factory.mktemp("stepper")
    (where / "toy.c").write_text(TOY_C)
    sizes = where / "toy_sizes.h"
    sizes.write_text("#define TOY_N_EQUATIONS 2\n#define TOY_N_UNKNOWNS 2\n"
                     "#define TOY_N_KNOWNS 2\n#define TOY_N_PARAMETERS 1\n"
                     "#define TOY_N_INPUTS 0\n#define TOY_N_HOISTED 1\n"
                     "#define TOY_TIME_ROW -1\n"
                     "#define TOY_TIME_UNKNOWN -1\n#define TOY_TIME_KNOWN -1\n"
                     "#define TOY_TIME_BEFORE -1\n")
    objects = []
    for source in (library_dir() / "stepper.c", library_dir() / "batch.c", where / "toy.c"):
        obj = where / (source.stem + ".o")
        extra = [] if source.name == "toy.c" else ["-include", str(sizes)]
        subprocess.run([cc, *FLAGS, f"-I{library_dir()}", *extra, "-c", str(source),
                        "-o", str(obj)], check=True, capture_output=True, text=True)
        objects.append(str(obj))
    library = where / "libtoy.so"
    subprocess.run([cc, "-shared", *objects, "-lm", "-o", str(library)], check=True)
    lib = ctypes.CDLL(str(library))
    lib.toy_status_message.restype = ctypes.c_char_p
    return lib


def _c_options(lib, options: NewtonOptions) -> _Options:
    c = _Options()
    lib.toy_default_options(ctypes.byref(c))
    for name, _ in _Options._fields_:
        setattr(c, name, getattr(options, name))
    return c


def _c_simulate(lib, known0, p, n_steps: int, options: NewtonOptions):
    states = np.zeros((n_steps + 1, 2))
    iterations = np.zeros(n_steps, dtype=np.intc)
    norms = np.zeros(n_steps)
    failed = ctypes.c_long(-2)
    last = np.zeros(2)
    warm = _WarmStart()
    status = lib.toy_simulate(
        _double_p(np.array(known0, dtype=float)), _double_p(np.array(p, dtype=float)),
        None, ctypes.c_long(n_steps), ctypes.byref(_c_options(lib, options)), ctypes.byref(warm),
        _double_p(states), ctypes.c_long(n_steps + 1),
        iterations.ctypes.data_as(ctypes.POINTER(ctypes.c_int)), _double_p(norms),
        ctypes.byref(failed), _double_p(last))
    return status, failed.value, states, iterations, norms, last


@needs_cc
def test_the_library_compiles_on_its_own_and_its_defaults_are_the_twins(toy):
    c = _Options()
    toy.toy_default_options(ctypes.byref(c))
    for name, value in DEFAULT_OPTIONS.items():
        assert getattr(c, name) == value, name
    for status in Status:
        expected = status.message if status.kernel else "unknown status"
        assert toy.toy_status_message(int(status)).decode() == expected


@needs_cc
@pytest.mark.parametrize(("known0", "expected"), [
    ((2.0, 1.0), Status.OK),
    ((2.0, 0.0), Status.SINGULAR_JACOBIAN),  # the prediction u_0 = 0 is singular
    ((-2.0, 1.0), Status.NOT_CONVERGED),  # no root: Newton wanders to its iteration cap
    ((1e300, 1.0), Status.NON_FINITE),  # the residual overflows
])
@pytest.mark.parametrize("extrapolate", [True, False])
def test_c_library_and_numpy_twin_agree_bit_for_bit(toy, known0, expected, extrapolate):
    options = NewtonOptions(extrapolate=extrapolate)
    p, n_steps = (0.5,), 40
    status, failed, states, iterations, norms, last = _c_simulate(toy, known0, p, n_steps,
                                                                  options)
    twin = NumpyStepper(_toy_functions(), 2)
    t_states, t_iterations, t_norms, t_status, t_failed, t_last = twin.simulate(
        np.array(known0), np.array(p), n_steps, options, twin.warm_start())
    assert (status, failed) == (t_status, t_failed)
    rows = n_steps + 1 if failed < 0 else failed + 1
    steps = n_steps if failed < 0 else failed + 1
    assert states[:rows].tobytes() == t_states[:rows].tobytes()
    assert iterations[:steps].tolist() == t_iterations[:steps].tolist()
    assert norms[:steps].tobytes() == t_norms[:steps].tobytes()
    assert last.tobytes() == np.asarray(t_last, dtype=float).tobytes()
    assert status == expected
    if expected == Status.OK:
        np.testing.assert_allclose(states[1:, 1], np.sqrt(states[:-1, 0]), rtol=1e-15)
    else:
        assert failed == 0
    if expected == Status.NOT_CONVERGED:
        assert iterations[0] == options.max_iterations


@needs_cc
def test_one_step_entry_point_and_invalid_arguments(toy):
    options = _c_options(toy, NewtonOptions())
    nxt = np.zeros(2)
    status = toy.toy_step(_double_p(np.array([4.0, 1.5])), _double_p(np.array([0.5])), None,
                          ctypes.byref(options), _double_p(nxt))
    assert status == Status.OK and nxt.tolist() == [4.5, 2.0]
    options.max_iterations = -1
    assert toy.toy_step(_double_p(np.array([4.0, 1.5])), _double_p(np.array([0.5])), None,
                        ctypes.byref(options), _double_p(nxt)) == Status.INVALID_ARGUMENT


def test_the_c_statuses_are_generated_from_the_enum():
    """``stepper.h``'s status ``#define``s and ``batch.c``'s ``status_message`` are the text
    that :func:`c_defines` and :func:`c_status_message` write from :class:`Status`."""
    assert c_defines() in library_source("stepper.h")
    assert c_status_message() in library_source("batch.c")
    assert STATUS_MESSAGES == {int(s): s.message for s in Status if s.kernel}
    assert [int(s) for s in Status if s.kernel] == [*range(7), 8]  # 7: CUT_LOCUS, runtime
    defined = re.findall(r"#define SG_(\w+) (\d+)\n", library_source("stepper.h"))
    kernel = {name: int(code) for name, code in defined if name in Status.__members__}
    assert kernel == {s.name: int(s) for s in Status if s.kernel}


def test_status_of_boundary_value_errors_and_stopped_runs():
    import symgroupoid as sg

    assert Status.of_boundary_value_error(sg.SingularJacobianError("x")) == \
        Status.SINGULAR_JACOBIAN
    assert Status.of_boundary_value_error(RuntimeError("x")) == Status.NOT_CONVERGED
    assert Status.of_boundary_value_error(sg.LagrangianDomainError("x")) == \
        Status.OUTSIDE_DOMAIN
    assert [s.name for s in Status if s.stopped] == ["INTERRUPTED", "TIMED_OUT",
                                                     "WORKER_DIED"]
    assert all(s.message and not s.message.endswith(".") for s in Status)


@pytest.mark.parametrize("code", [99, -1, 9, "OK", None])
def test_a_code_that_is_no_status_is_refused_by_name(code):
    import symgroupoid as sg

    with pytest.raises(sg.StatusCodeError, match="not the code of a run's status.*6 BRANCH_JUMP"):
        Status(code)
    assert Status(6) is Status.BRANCH_JUMP and Status(Status.OK) is Status.OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-q"]))
