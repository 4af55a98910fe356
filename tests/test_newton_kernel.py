"""The compiled Newton stepper and its NumPy mirror: the LU with its one-pass row scan, the
single finiteness test of a solve, the norms, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from kernel_support import (  # noqa: F401  (isolated_cache: autouse fixture)
    SEED_DATA,
    compiled,
    initial_state,
    isolated_cache,
    needs_cc,
)

from symgroupoid import NewtonOptions
from symgroupoid.stepper import (
    Status,
    explained_by_rounding,
    lu_apply,
    lu_factor,
    norm_inf,
    pivot_ratio,
)

NON_FINITE, OK, SINGULAR_JACOBIAN = Status.NON_FINITE, Status.OK, Status.SINGULAR_JACOBIAN


@needs_cc
@pytest.mark.parametrize("name", ["plate_ball", "heavy_top", "rigid_body"])
def test_c_and_numpy_steppers_agree_bit_for_bit(name):
    """Same iterations, residual norms and states: the C loops (unrolled for few unknowns) do
    the operations of the NumPy mirror in the same order."""
    c_sim, np_sim = compiled(name), compiled(name, backend="numpy")
    params = SEED_DATA[name][0]
    state = initial_state(c_sim, name)
    a, b = c_sim.simulate(state, 25, params), np_sim.simulate(state, 25, params)
    assert np.array_equal(a.states, b.states)
    assert np.array_equal(a.newton_iterations, b.newton_iterations)
    assert np.array_equal(a.residual_norms, b.residual_norms)


def test_norm_inf_returns_the_first_non_finite_entry():
    assert norm_inf(np.array([1.0, -3.0, 2.0])) == 3.0
    assert np.isnan(norm_inf(np.array([1.0, np.nan, -np.inf])))
    assert norm_inf(np.array([1.0, -np.inf, np.nan])) == np.inf


def test_lu_statuses_follow_the_first_failing_row():
    """A zero row before a non-finite one is singular, the other way round non-finite."""
    assert lu_factor(np.array([[0.0, 0.0], [np.nan, 1.0]]))[0] == SINGULAR_JACOBIAN
    assert lu_factor(np.array([[np.inf, 0.0], [0.0, 0.0]]))[0] == NON_FINITE


def test_an_overflowing_scaled_right_hand_side_is_non_finite():
    """b scaled by 2^-e can overflow; the single test of x catches it (b is not tested first)."""
    status, factors = lu_factor(np.diag([1e-300, 1.0]))
    assert status == OK
    assert lu_apply(factors, [1e300, 1.0])[0] == NON_FINITE
    assert lu_apply(factors, [np.nan, 1.0])[0] == NON_FINITE
    assert lu_apply(factors, [1e-300, 1.0])[0] == OK


@needs_cc
@pytest.mark.parametrize("name", ["rigid_body", "plate_ball"])
def test_runaway_guesses_are_never_returned_as_solutions(name: str) -> None:
    """Guesses up to 10⁸ from the solution: Newton may run away to |u| ~ 10⁹⁰, where its
    relative updates are tiny and the pivots' ratio huge.  Such an iterate was returned as
    converged with |F| = 99 (rigid body) or 0.02 (plate-ball); every OK now has a residual a
    rounding-level update explains, in C and in NumPy alike."""
    rng = np.random.default_rng(1)
    sim = compiled(name)
    mirror = compiled(name, backend="numpy")
    state = initial_state(sim, name)
    p = sim.parameters(SEED_DATA[name][0])
    solved = 0
    for trial in range(600):
        guess = rng.standard_normal(sim.kernel.n_u) * 10.0 ** rng.uniform(-1, 8)
        status, u, _, norm = sim.kernel.solve_step(state, p, guess, sim.options)
        if status == 0:
            solved += 1
            assert norm <= 1e-10, (trial, norm, np.abs(u).max())
        if trial < 150:  # the NumPy mirror agrees bit for bit
            same = mirror.kernel.solve_step(state, p, guess, mirror.options)
            assert same[0] == status and np.array_equal(same[1], u), trial
    assert solved > 50  # the nearer guesses still converge


# --- the stepper's static functions, compiled from the kernel source, against the mirror ------

HARNESS = r"""
#include <stdio.h>
#include <stdlib.h>
#include "plate_ball.c"
/* per case, from stdin (C99 hex floats): J (64), F (8), u (8), u_J (8); prints the status of
 * the factorisation, the solution of J x = F and explained_by_rounding's answer */
static double next_value(void)
{
    char word[64];
    if (scanf("%63s", word) != 1) {
        exit(2);
    }
    return strtod(word, NULL);
}
int main(void)
{
    int cases, c, i;
    if (scanf("%d", &cases) != 1) {
        return 2;
    }
    for (c = 0; c < cases; ++c) {
        double J[64], F[8], u[8], uJ[8], x[8];
        plate_ball_lu lu;
        int status;
        for (i = 0; i < 64; ++i) J[i] = next_value();
        for (i = 0; i < 8; ++i) F[i] = next_value();
        for (i = 0; i < 8; ++i) u[i] = next_value();
        for (i = 0; i < 8; ++i) uJ[i] = next_value();
        status = plate_ball_lu_factor(J, &lu);
        printf("%d", status);
        if (status == PLATE_BALL_OK) {
            memcpy(x, F, sizeof x);
            printf(" %d", plate_ball_lu_apply(&lu, x));
            for (i = 0; i < 8; ++i) printf(" %a", x[i]);
            printf(" %d", plate_ball_explained_by_rounding(F, J, u, uJ, &lu));
        }
        printf("\n");
    }
    return 0;
}
"""


@pytest.fixture(scope="module")
def stepper_harness(tmp_path_factory):
    """The golden plate-ball kernel's static LU and acceptance test, compiled as the kernel
    is (-O3, no contraction of a*b+c), behind a text interface."""
    import subprocess

    from kernel_support import REPO

    where = tmp_path_factory.mktemp("harness")
    (where / "harness.c").write_text(HARNESS)
    exe = where / "harness"
    subprocess.run(["cc", "-O3", "-ffp-contract=off", "-I", str(REPO / "generated"),
                    str(where / "harness.c"), "-o", str(exe), "-lm"], check=True,
                   capture_output=True)

    def run(cases: list[tuple[np.ndarray, ...]]) -> list[list[str]]:
        words = [str(len(cases))]
        for J, F, u, uJ in cases:
            words += [float(v).hex() for v in (*J.ravel(), *F, *u, *uJ)]
        out = subprocess.run([str(exe)], input=" ".join(words), capture_output=True,
                             text=True, check=True).stdout
        return [line.split() for line in out.splitlines()]
    return run


def full_sums(J: np.ndarray, u: np.ndarray, uJ: np.ndarray) -> np.ndarray:
    """S_i = Σ_j |J_ij|(1 + min(|u_j|, |u_J,j|)), summed from j = 0 up (as the kernel)."""
    m = 1.0 + np.minimum(np.abs(u), np.abs(uJ))
    S = np.zeros(len(J))
    for j in range(J.shape[1]):
        S = S + np.abs(J[:, j]) * m[j]
    return S


def acceptance_cases(rng) -> list[tuple[np.ndarray, ...]]:
    """Jacobians with zeros and rows of very different sizes; residuals on both sides of the
    acceptance bound, between the row-maximum shortcut and the full sums, exactly at the
    bound and one ulp above; weights that are infinite (u_j = u_J,j = ∞ over a zero of J)."""
    cases = []
    for trial in range(400):
        J = rng.standard_normal((8, 8)) * 10.0 ** rng.integers(-3, 4, size=(8, 1))
        J[rng.random((8, 8)) < 0.3] = 0.0
        J += np.diag(np.where(np.diag(J) == 0.0, 1.0, 0.0))
        u = rng.standard_normal(8) * 10.0 ** rng.uniform(-3, 3)
        uJ = u + rng.standard_normal(8) * 10.0 ** rng.uniform(-8, 0)
        status, factors = lu_factor(J)
        if status != OK:
            continue
        bound = 64.0 * np.finfo(float).eps * pivot_ratio(factors, uJ)
        S = full_sums(J, u, uJ)
        M = np.abs(J).max(axis=1)
        kind = trial % 6
        if kind == 5:  # one entry per row dominates: S_i is barely above max_j |J_ij|
            J = np.diag(np.diag(J)) + 1e-9 * (J - np.diag(np.diag(J)))
            u, uJ = u * 1e-12, uJ * 1e-12
            status, factors = lu_factor(J)
            bound = 64.0 * np.finfo(float).eps * pivot_ratio(factors, uJ)
            S, M = full_sums(J, u, uJ), np.abs(J).max(axis=1)
        if kind == 0:  # below the row maxima: the shortcut decides
            F = bound * M * rng.uniform(0, 1, 8)
        elif kind == 1:  # between max_j |J_ij| and S_i: the full sums decide
            F = bound * (M + (S - M) * rng.uniform(0, 1, 8))
        elif kind in (2, 5):  # exactly at the bound, one row one ulp above
            F = bound * S
            F[trial % 8] = np.nextafter(F[trial % 8], np.inf)
        elif kind == 3:  # at the bound
            F = bound * S
        else:  # infinite weights over a zero of J: S_i = NaN, never accepted
            j = trial % 8
            J[(j + 1) % 8, j] = 0.0
            u[j] = uJ[j] = np.inf
            F = bound * M * 0.5
        F = F * np.where(rng.random(8) < 0.5, -1.0, 1.0)
        cases.append((J, F, u, uJ))
    return cases


@needs_cc
def test_factor_solve_and_acceptance_match_the_mirror_bit_for_bit(stepper_harness):
    """The LU into its struct (scaled copy, row order, branch-free scaling of b) and the
    acceptance test, which decides first by the row maxima of J, give exactly the mirror's
    factors, solutions and answers — on both sides of the bound, at it, one ulp above it
    (also where the sums barely exceed the row maxima) and with infinite weights (where the
    row maxima alone would accept)."""
    rng = np.random.default_rng(7)
    cases = acceptance_cases(rng)
    answers = {True: 0, False: 0}
    for (J, F, u, uJ), words in zip(cases, stepper_harness(cases), strict=True):
        status, factors = lu_factor(J)
        assert int(words[0]) == status == OK
        solved, x = lu_apply(factors, F)
        assert int(words[1]) == solved
        assert [float.fromhex(w) for w in words[2:10]] == x.tolist()
        with np.errstate(invalid="ignore"):  # ∞·0 in the sums of infinite weights
            expected = explained_by_rounding(F, J, u, uJ, pivot_ratio(factors, uJ))
        assert bool(int(words[10])) == expected, (J, F, u, uJ)
        answers[expected] += 1
    assert answers[True] > 100 and answers[False] > 100


@needs_cc
def test_factor_statuses_and_tiny_rows_match_the_mirror(stepper_harness):
    """Rows whose scale 2^-e is not a normal double (|J_ij| ~ 1e-310 or 1e305) take the
    ldexp path in both the factorisation and the solve; zero and non-finite rows fail as
    in the mirror."""
    rng = np.random.default_rng(3)
    cases = []
    for scale in (1e-310, 1e-305, 1e305, 0.0, np.inf, np.nan):
        J = rng.standard_normal((8, 8))
        J[2] *= scale if np.isfinite(scale) and scale != 0.0 else 1.0
        if not np.isfinite(scale) or scale == 0.0:
            J[5] = scale
        F = rng.standard_normal(8)
        F[2] *= scale if np.isfinite(scale) and scale != 0.0 else 1.0
        cases.append((J, F, np.ones(8), np.ones(8)))
    for (J, F, *_), words in zip(cases, stepper_harness(cases), strict=True):
        status, factors = lu_factor(J)
        assert int(words[0]) == status
        if status == OK:
            solved, x = lu_apply(factors, F)
            assert int(words[1]) == solved
            assert [float.fromhex(w) for w in words[2:10]] == x.tolist()


def _cayley(x) -> np.ndarray:
    X = np.array([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]], float)
    return np.eye(3) + 4 / (4 + x @ x) * (X + X @ X / 2)


@needs_cc
def test_the_polishing_update_is_made_alike_by_both_steppers():
    """The 3D pendulum's Cayley coordinates (~4e-2 at h = 0.02) stop on the estimated error
    above their rounding, so most steps end with a polishing update from the accepted
    residual (a third update without a third evaluation): the same in C and NumPy, bit for
    bit.  (At h = 0.01 the quadratic guess is so close that two updates reach the rounding.)"""
    from symgroupoid.systems import spherical_chain

    step = spherical_chain(1).euler_lagrange()
    c_sim, np_sim = step.compile(backend="c"), step.compile(backend="numpy")
    R = _cayley(np.array([0.5, 0.4, 0.3]))
    params = {"h": 0.02, "g": 9.81}
    state = c_sim.state({"R1": (R, R @ _cayley(0.04 * np.array([0.8, -0.6, 1.5])))}, params)
    a, b = c_sim.simulate(state, 40, params), np_sim.simulate(state, 40, params)
    assert np.array_equal(a.states, b.states)
    assert np.array_equal(a.newton_iterations, b.newton_iterations)
    assert np.array_equal(a.residual_norms, b.residual_norms)
    assert np.count_nonzero(np.asarray(a.newton_iterations) == 3) >= 20
    # from a guess 3e-6 off the root: two updates, then the polishing one -- unless the
    # iteration cap is two
    known, p = a.states[10], np.array([params["h"], params["g"]])
    root = c_sim.kernel.solve_step(known, p, np.zeros(3), NewtonOptions())[1]
    for cap, updates in ((50, 3), (2, 2)):
        runs = [sim.kernel.solve_step(known, p, root + 3e-6, NewtonOptions(max_iterations=cap))
                for sim in (c_sim, np_sim)]
        assert [r[0] for r in runs] == [0, 0] and [r[2] for r in runs] == [updates] * 2
        assert np.array_equal(runs[0][1], runs[1][1])
