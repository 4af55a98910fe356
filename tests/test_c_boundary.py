"""Memory safety at the Python → C boundary and in the generated C itself.

Every buffer handed to a kernel is checked (length, dtype, contiguity) before the call;
the C API takes the capacity of its output buffer; the generated source refuses
-ffast-math; and one kernel runs through the embedding example under AddressSanitizer and
UndefinedBehaviorSanitizer.
"""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    BACKENDS,
    REPO,
    SEED_DATA,
    SESSION_CACHE,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
    seed_step,
)

import symgroupoid as sg
from symgroupoid.codegen import emit_c
from symgroupoid.runtime import c_buffer, real_vector
from symgroupoid.stepper import STATUS_MESSAGES, Status

OK, INVALID_ARGUMENT = Status.OK, Status.INVALID_ARGUMENT

BAD_GUESSES = {
    "length 1": [0.0],
    "length 20": np.zeros(20),
    "shape (2, 4)": np.zeros((2, 4)),
    "a scalar": 0.0,
    "complex": np.zeros(8, dtype=complex),
}


# --- Python → C: every buffer checked before the call -----------------------------------------

@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("what", sorted(BAD_GUESSES))
def test_solve_rejects_a_guess_of_the_wrong_shape(backend, what):
    """The plate-ball has 8 unknowns: a shorter guess used to be read and written as 8
    doubles (heap corruption), a longer or 2-d one was accepted."""
    sim = compiled("plate_ball", backend=backend)
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    with pytest.raises(sg.ShapeError, match=r"plate_ball: guess must (have shape \(8,\)|hold)"):
        sim.solve(state, params, guess=BAD_GUESSES[what])


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_solve_rejects_a_non_finite_guess(backend, bad):
    sim = compiled("plate_ball", backend=backend)
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    guess = sim.kernel.predict(state, sim.parameters(params))
    guess[3] = bad
    with pytest.raises(sg.ShapeError, match=r"guess must be finite; entries \[3\]"):
        sim.solve(state, params, guess=guess)


@pytest.mark.parametrize("backend", BACKENDS)
def test_solve_accepts_any_real_guess_of_the_right_shape(backend):
    """Integers, float32 and non-contiguous views are converted, not rejected."""
    sim = compiled("plate_ball", backend=backend)
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    u, _, _ = sim.solve(state, params)
    guess = np.empty(16)
    guess[::2] = u
    for g in (guess[::2], u.astype(np.float32), list(u)):
        v, _, rn = sim.solve(state, params, guess=g)
        assert np.abs(v - u).max() < 1e-9 and rn <= 1e-10


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernel_methods_check_their_arrays(backend):
    """The kernel methods themselves (not only the Simulator) check every argument."""
    sim = compiled("rigid_body", backend=backend)
    kernel = sim.kernel
    params = sim.parameters(SEED_DATA["rigid_body"][0])
    state = initial_state(sim, "rigid_body")
    u = kernel.predict(state, params)
    calls = {
        "u": lambda bad: kernel.residual(bad, state, params),
        "known": lambda bad: kernel.residual_jacobian(u, bad, params),
        "p": lambda bad: kernel.next_knowns(u, state, bad),
    }
    for name, call in calls.items():
        for bad in ([1.0], np.zeros(40), np.zeros((3, 3))):
            with pytest.raises(sg.ShapeError, match=rf"{name} must have shape"):
                call(bad)
    with pytest.raises(sg.ShapeError, match=r"known0 must have shape \(9,\)"):
        kernel.simulate(np.zeros(8), params, 3, sim.options)
    with pytest.raises(sg.ShapeError, match="n_steps must be at least 0"):
        kernel.simulate(state, params, -1, sim.options)
    status, *_ = kernel.solve_step(state, params, np.full(3, np.nan), sim.options)
    assert status == INVALID_ARGUMENT
    # (u=None unpacked into a ValueError, options None or a dict an AttributeError or a
    # TypeError, and 2**40 steps a MemoryError from NumPy)
    for call in (kernel.residual, kernel.residual_jacobian, kernel.next_knowns):
        with pytest.raises(sg.ShapeError, match="u must be"):
            call(None, state, params)
    for options in (None, {"max_iterations": 3}):
        with pytest.raises(sg.InputTypeError, match="options must be NewtonOptions"):
            kernel.solve_step(state, params, u, options)
        with pytest.raises(sg.InputTypeError, match="options must be NewtonOptions"):
            kernel.simulate(state, params, 3, options)
    with pytest.raises(sg.TrajectoryTooLargeError, match="run it in pieces"):
        kernel.simulate(state, params, 2**40, sim.options)


@pytest.mark.parametrize("backend", BACKENDS)
def test_kernel_methods_check_the_widths_of_inputs_and_parameter_tables(backend):
    """Found with AddressSanitizer: the kernel's ``input_jacobian`` with fewer columns than
    it writes, ``simulate_inputs`` with rows narrower than the inputs it reads and
    ``batch_until`` with one parameter row for several runs wrote or read past the end of
    their arrays (the Simulator passes the right sizes; ``sim.kernel`` is reachable)."""
    import _systems

    sim = _systems.driven_oscillator().euler_lagrange().compile(backend=backend)
    kernel = sim.kernel
    params = sim.parameters({"h": 0.1, "k": 1.0, "c": 0.1})
    state = sim.state({"x": (1.0, 0.99), "u": [0.0]}, params)
    u = kernel.predict(state, params)
    assert kernel.input_jacobian(u, state, params, 2).shape == (1, 2)
    with pytest.raises(sg.ShapeError, match="input Jacobian has 2 columns"):
        kernel.input_jacobian(u, state, params, 1)
    n, upcoming = 4, sim.layout.upcoming_index
    states, its, norms = np.zeros((n + 1, len(state))), np.zeros(n, np.intc), np.zeros(n)
    states[0] = state
    for wide in (np.zeros((n, 2)), np.zeros(n)):
        with pytest.raises(sg.ShapeError, match=r"not \(steps, 1\)"):
            kernel.simulate_inputs(states, its, norms, params, wide, upcoming, sim.options,
                                   kernel.warm_start())
    with pytest.raises(sg.ShapeError, match=r"inputs must have shape"):
        kernel.simulate_batch(np.tile(state, (3, 1)), params, n, 1, sim.options,
                              inputs=np.zeros((3, n, 2)))
    known0 = np.tile(state, (4, 1))
    out = kernel.simulate_batch(known0, params, n, 1, sim.options, inputs=np.zeros((n, 1)))
    for table in (params[None, :], params[:-1]):
        with pytest.raises(sg.ShapeError, match="parameters of shape|p must have shape"):
            kernel.batch_until(kernel.batch_cursors(4), known0, table, n, 1, n, sim.options,
                               out, inputs=np.zeros((n, 1)))


def test_c_buffer_accepts_only_the_exact_buffer():
    import cffi

    ffi = cffi.FFI()
    good = np.zeros(8)
    assert ffi.typeof(c_buffer(ffi, good, 8, "u")) == ffi.typeof("double[]")
    for bad, text in [(np.zeros(8, np.float32), "dtype float64"),
                      (np.zeros(16)[::2], "C-contiguous"),
                      (np.zeros(7), "hold 8 elements"),
                      (np.zeros(9), "hold 8 elements"),
                      ([0.0] * 8, "NumPy array")]:
        with pytest.raises(sg.ShapeError, match=text):
            c_buffer(ffi, bad, 8, "u")
    with pytest.raises(sg.ShapeError, match=r"dtype int32"):
        c_buffer(ffi, np.zeros(8, np.int64), 8, "iterations", "int")
    assert real_vector(np.arange(3), 3, "x").dtype == np.float64
    with pytest.raises(sg.ShapeError, match="x must hold real numbers"):
        real_vector(np.array(["a", "b"]), 2, "x")


@needs_cc
def test_window_programs_check_their_input_array():
    """The compiled boundary-value window programs (the other cffi call site)."""
    import sympy as sp

    from symgroupoid.ir import Graph, Program, from_sympy
    from symgroupoid.runtime import compile_program

    a, b = sp.symbols("a b")
    g = Graph()
    nodes = {a: g.input(a), b: g.input(b)}
    program = Program(g, {"a": [a, b]}, {"out": [from_sympy(g, e, nodes)
                                                  for e in (a * b + 1, a * b - a)]})
    fn = compile_program("boundary check", program, "a", "out")
    assert fn is not None
    out = fn(np.array([[2.0, 3.0], [1.0, -1.0]]))
    assert np.array_equal(out, [[7.0, 4.0], [0.0, -2.0]])
    assert np.array_equal(fn(np.zeros((0, 2))), np.zeros((0, 2)))
    for bad in (np.zeros(2), np.zeros((2, 3)), np.zeros((2, 1)), np.zeros((2, 2), complex)):
        with pytest.raises(sg.ShapeError, match=r"takes a real \(W, 2\) array"):
            fn(bad)


# --- the C API: explicit capacity, status texts -----------------------------------------------

@needs_cc
def test_c_simulate_refuses_a_buffer_below_n_steps_plus_one_rows():
    """``capacity`` rows of output: one row short is INVALID_ARGUMENT and nothing is
    written (the buffer here is larger than the capacity claimed, so a write would show)."""
    sim = compiled("rigid_body")
    kernel, ffi, lib = sim.kernel, sim.kernel.ffi, sim.kernel.lib
    state = initial_state(sim, "rigid_body")
    p = sim.parameters(SEED_DATA["rigid_body"][0])
    n_k = len(state)

    def run(n_steps, capacity):
        states = np.full((20, n_k), 7.0)
        iterations = np.full(20, -3, dtype=np.intc)
        norms = np.full(20, 7.0)
        failed = ffi.new("long *")
        status = lib.rigid_body_simulate(
            ffi.from_buffer("double[]", state), ffi.from_buffer("double[]", p), ffi.NULL,
            n_steps, ffi.NULL, ffi.NULL, ffi.from_buffer("double[]", states), capacity,
            ffi.from_buffer("int[]", iterations), ffi.from_buffer("double[]", norms), failed,
            ffi.NULL)
        return status, states, iterations, norms

    for n_steps, capacity in [(10, 10), (10, 0), (0, 0), (3, -1)]:
        status, states, iterations, norms = run(n_steps, capacity)
        assert status == INVALID_ARGUMENT, (n_steps, capacity)
        assert (states == 7.0).all() and (iterations == -3).all() and (norms == 7.0).all()
    status, states, iterations, _ = run(10, 11)
    assert status == OK and (states[11:] == 7.0).all() and (iterations[10:] == -3).all()
    assert np.array_equal(states[:11], kernel.simulate(state, p, 10, sim.options).states)
    status, states, *_ = run(0, 1)
    assert status == OK and np.array_equal(states[0], state)


@needs_cc
def test_c_status_messages_are_the_python_ones():
    lib, ffi = compiled("rigid_body").kernel.lib, compiled("rigid_body").kernel.ffi
    for code, text in STATUS_MESSAGES.items():
        assert ffi.string(lib.rigid_body_status_message(code)).decode() == text
    assert ffi.string(lib.rigid_body_status_message(99)).decode() == "unknown status"


@needs_cc
def test_c_batch_cursors_with_impossible_carries_are_refused():
    """Found with UndefinedBehaviorSanitizer: a cursor whose count of Newton updates since
    the last kept row was LLONG_MAX was accepted and overflowed when the next steps were
    added (signed overflow); a carried residual norm of +inf was accepted too.  Such a
    cursor describes no run's progress: the run is INVALID_ARGUMENT."""
    sim = compiled("rigid_body")
    kernel = sim.kernel
    state = initial_state(sim, "rigid_body")
    p = sim.parameters(SEED_DATA["rigid_body"][0])
    known0 = np.tile(state, (1, 1))
    for field, value in (("carry_iterations", 2**63 - 1), ("carry_norm", float("inf"))):
        out, cursors = kernel._batch_buffers(1, 8, 4), kernel.batch_cursors(1)
        kernel.batch_until(cursors, known0, p, 8, 4, 2, sim.options, out)
        assert out.status[0] == OK and cursors[0].done == 2
        setattr(cursors[0], field, value)
        kernel.batch_until(cursors, known0, p, 8, 4, 8, sim.options, out)
        assert out.status[0] == INVALID_ARGUMENT, field


@needs_cc
def test_c_solve_step_refuses_non_finite_input_and_null_pointers():
    """In C itself (the Python checks come first otherwise): a NaN known state, parameter
    or guess is INVALID_ARGUMENT and the guess is left untouched."""
    sim = compiled("rigid_body")
    ffi, lib = sim.kernel.ffi, sim.kernel.lib
    state = initial_state(sim, "rigid_body")
    p = sim.parameters(SEED_DATA["rigid_body"][0])
    u0 = sim.kernel.predict(state, p)
    it, rn = ffi.new("int *", -7), ffi.new("double *", -7.0)

    def solve(known, params, u):
        return lib.rigid_body_solve_step(ffi.from_buffer("double[]", known),
                                         ffi.from_buffer("double[]", params), ffi.NULL,
                                         ffi.from_buffer("double[]", u), it, rn)

    for where in ("known", "p", "u"):
        args = {"known": state.copy(), "p": p.copy(), "u": u0.copy()}
        args[where][0] = np.nan
        before = args["u"].copy()
        assert solve(args["known"], args["p"], args["u"]) == INVALID_ARGUMENT, where
        assert np.array_equal(args["u"], before, equal_nan=True)
        assert it[0] == -7 and rn[0] == -7.0
    assert lib.rigid_body_solve_step(ffi.NULL, ffi.from_buffer("double[]", p), ffi.NULL,
                                     ffi.from_buffer("double[]", u0.copy()), it,
                                     rn) == INVALID_ARGUMENT
    u = u0.copy()
    assert solve(state, p, u) == OK and rn[0] <= 1e-10


@needs_cc
def test_c_warm_start_is_checked():
    sim = compiled("rigid_body")
    kernel = sim.kernel
    state = initial_state(sim, "rigid_body")
    p = sim.parameters(SEED_DATA["rigid_body"][0])
    for count, quadratic, value in [(4, 0, 0.0), (-1, 0, 0.0), (3, 2, 0.0), (3, -1, 0.0),
                                    (1, 0, np.nan), (2, 0, np.inf), (3, 1, np.nan)]:
        warm = kernel.warm_start()
        warm.count, warm.quadratic = count, quadratic
        warm.u_last[0] = 0.0 if count == 3 else value
        warm.u_before[0] = 0.0 if count == 3 else value
        warm.u_earlier[0] = value
        assert kernel.simulate(state, p, 2, sim.options, warm).status == INVALID_ARGUMENT
    warm = kernel.warm_start()  # a complete, finite warm start is accepted
    warm.count, warm.quadratic = 3, 1
    assert kernel.simulate(state, p, 2, sim.options, warm).status == OK
    with pytest.raises(sg.ShapeError, match="warm start"):
        kernel.simulate(state, p, 2, sim.options, kernel.ffi.new("int *"))


# --- compiler flags ---------------------------------------------------------------------------

@needs_cc
@pytest.mark.parametrize("flag", ["-ffast-math", "-Ofast", "-ffinite-math-only"])
def test_generated_source_refuses_fast_math(tmp_path, flag):
    """Under -ffast-math the NaN checks are compiled away (a NaN input came back
    "converged"): the source stops with an #error naming the flag."""
    c_path, _ = emit_c(seed_step("rigid_body"), tmp_path / "rigid_body")
    result = subprocess.run(["cc", "-std=c99", flag, "-c", str(c_path), "-o",
                             str(tmp_path / "rb.o")], capture_output=True, text=True)
    assert result.returncode != 0
    expected = "-ffinite-math-only" if flag == "-ffinite-math-only" else "-ffast-math"
    assert f"must not be compiled with {expected}" in result.stderr
    plain = subprocess.run(["cc", "-std=c99", "-O2", "-c", str(c_path), "-o",
                            str(tmp_path / "rb.o")], capture_output=True, text=True)
    assert plain.returncode == 0, plain.stderr


@needs_cc
def test_compile_step_with_fast_math_fails_with_the_reason():
    with pytest.raises(sg.CompilationError, match="must not be compiled with -ffast-math"):
        seed_step("rigid_body").compile(backend="c", flags=["-O2", "-ffast-math"])


# --- sanitizers -------------------------------------------------------------------------------

SANITIZE = ["-fsanitize=address,undefined", "-fno-omit-frame-pointer",
            "-fno-sanitize-recover=all"]


@pytest.fixture(scope="module")
def sanitizers_unavailable(tmp_path_factory) -> str | None:
    """Why the compiler cannot build and run a sanitized program here (None if it can);
    probed once for the module's sanitizer tests."""
    tmp_path = tmp_path_factory.mktemp("sanitizer-probe")
    if shutil.which("cc") is None:
        return "no C compiler (cc) on PATH"
    src = tmp_path / "probe.c"
    src.write_text("#include <stdlib.h>\nint main(void) { int *a = malloc(4); a[0] = 0; "
                   "free(a); return 0; }\n")
    exe = tmp_path / "probe"
    build = subprocess.run(["cc", *SANITIZE, str(src), "-o", str(exe)], capture_output=True,
                           text=True)
    if build.returncode != 0:
        return f"cc cannot link ASan/UBSan: {build.stderr.strip()[:200]}"
    run = subprocess.run([str(exe)], capture_output=True, text=True, env=_sanitizer_env())
    if run.returncode != 0:
        return f"sanitized programs do not run here: {run.stderr.strip()[:200]}"
    return None


def _sanitizer_env() -> dict:
    env = dict(os.environ)
    env["ASAN_OPTIONS"] = "abort_on_error=0:exitcode=86:detect_leaks=1"
    env["UBSAN_OPTIONS"] = "print_stacktrace=1:halt_on_error=1:exitcode=87"
    return env


def test_embedding_runs_clean_under_address_and_undefined_sanitizers(tmp_path,
                                                                    sanitizers_unavailable):
    """A freshly emitted plate-ball kernel and examples/embed/main.c, built with
    -fsanitize=address,undefined, run 2500 steps (three calls of the chunked loop, the
    warm start carried across) and bad input with no sanitizer report."""
    if sanitizers_unavailable:
        pytest.skip(sanitizers_unavailable)
    c_path, _ = emit_c(seed_step("plate_ball"), tmp_path / "plate_ball")
    exe = tmp_path / "embed_asan"
    build = subprocess.run(["cc", "-std=c99", "-O1", "-g", *SANITIZE, f"-I{tmp_path}",
                            str(REPO / "examples" / "embed" / "main.c"), str(c_path), "-lm",
                            "-o", str(exe)], capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    sim = compiled("plate_ball")
    params = SEED_DATA["plate_ball"][0]
    state = initial_state(sim, "plate_ball")
    stdin = (" ".join(repr(float(v)) for v in sim.parameters(params)) + "\n"
             + " ".join(repr(float(v)) for v in state) + "\n")
    steps = 2500
    run = subprocess.run([str(exe), str(steps)], input=stdin, capture_output=True, text=True,
                         env=_sanitizer_env(), timeout=120)
    assert run.returncode == 0, run.stderr[-2000:]
    assert "Sanitizer" not in run.stderr and "runtime error" not in run.stderr
    table = np.array([[float(v) for v in line.split()] for line in run.stdout.splitlines()])
    assert table.shape == (steps + 1, 3 + len(state))
    traj = sim.simulate(state, steps, params)
    assert np.abs(table[:, 3:] - traj.states).max() <= 1e-12 * max(1.0, np.abs(traj.states).max())
    for argv, text, code in [(["9223372036854775808"], "usage", 2), (["-1"], "usage", 2),
                             (["12abc"], "usage", 2), (["5"], "expected 4 parameters", 2)]:
        bad = subprocess.run([str(exe), *argv], input="0.01 1", capture_output=True,
                             text=True, env=_sanitizer_env(), timeout=60)
        assert bad.returncode == code and text in bad.stderr, bad.stderr[-2000:]
        assert "Sanitizer" not in bad.stderr and "runtime error" not in bad.stderr
    nan_input = stdin.split("\n")[0] + "\n" + " ".join(["nan"] * len(state)) + "\n"
    bad = subprocess.run([str(exe), "5"], input=nan_input, capture_output=True, text=True,
                         env=_sanitizer_env(), timeout=60)
    assert bad.returncode == 1 and "invalid argument" in bad.stderr
    assert "Sanitizer" not in bad.stderr and "runtime error" not in bad.stderr


def test_the_closed_loop_runs_clean_under_address_and_undefined_sanitizers(
        tmp_path, sanitizers_unavailable):
    """examples/embed/closed_loop.c with the shipped forced kernel generated/satellite_wheel.c,
    built with -fsanitize=address,undefined: 750 controlled steps writing the trajectory, and
    a run too short to reach the target, with no sanitizer report."""
    if sanitizers_unavailable:
        pytest.skip(sanitizers_unavailable)
    exe = tmp_path / "closed_loop_asan"
    build = subprocess.run(["cc", "-std=c99", "-O1", "-g", *SANITIZE, "-ffp-contract=off",
                            f"-I{REPO / 'generated'}",
                            str(REPO / "examples" / "embed" / "closed_loop.c"),
                            str(REPO / "generated" / "satellite_wheel.c"), "-lm", "-o", str(exe)],
                           capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    for steps, code in ((750, 0), (20, 1)):
        run = subprocess.run([str(exe), str(steps), str(tmp_path / "trajectory.txt")],
                             capture_output=True, text=True, env=_sanitizer_env(), timeout=120)
        assert run.returncode == code, run.stderr[-2000:]
        assert "Sanitizer" not in run.stderr and "runtime error" not in run.stderr
        assert len((tmp_path / "trajectory.txt").read_text().splitlines()) == steps + 1


@pytest.mark.parametrize("flag", ["-D_OPENMP", "-D_OPENMP=201511", "-U_OPENMP"])
def test_flags_that_set_openmps_macro_are_refused_at_once(flag):
    """-D_OPENMP compiled the OpenMP branches without the runtime: the build's load then
    failed as a CacheError, which blamed the cache."""
    with pytest.raises(sg.ShapeError, match=r"flags: '-[DU]_OPENMP.*' sets OpenMP's own "
                                            r"macro without its runtime"):
        seed_step("rigid_body").compile(backend="c", flags=["-O2", flag])
