/*
 * The code of a step kernel that runs rarely or once per call: the batched entry points
 * (OpenMP), the one-step entry point and the status messages (symgroupoid.stepper; see
 * stepper.h).  In one file with the stepper (stepper.c), or in a translation unit of its own
 * compiled at -Og beside the others (see ``symgroupoid.runtime.toolchain``):
 * nothing here is floating-point arithmetic of a step, so the optimisation level changes no
 * result.
 */
#include "stepper.h"
#include "prologue.h"
#include "options.h"

/* Steps per SG_NAME(simulate) call inside SG_NAME(simulate_batch): the chunk buffer of one
 * trajectory (SG_BATCH_CHUNK + 1 states) stays within 32 KiB of stack per thread. */
#define SG_BATCH_CHUNK (SG_N_KNOWNS >= 4096 ? 1 : (4096 / SG_N_KNOWNS < 64 ? 4096 / SG_N_KNOWNS : 64))

/* Advance one trajectory of SG_NAME(simulate_batch) / SG_NAME(simulate_batch_until) from its
 * cursor to step `until` (at most n_steps) through SG_NAME(simulate) in chunks of at most
 * SG_BATCH_CHUNK steps with the cursor's warm start (bitwise the states of one
 * SG_NAME(simulate) call, however the run is split into calls), keeping state 0, every
 * `every`-th state and the last one.  *kept counts the rows written; 0 starts the run from
 * known0 (the cursor is reset).  Row r > 0 of iterations/residual_norms summarises the steps
 * since the previous kept state: their Newton iterations summed, the largest residual norm
 * (carried in the cursor across calls).  A failure at step s keeps state s too (unless
 * already kept) and records the failed step's own iterations, residual norm and last
 * iterate.  A forced kernel reads the inputs of step k from u + k * SG_N_INPUTS (u: the run's
 * inputs, n_steps rows; NULL without inputs). */
static void SG_NAME(batch_advance)(SG_NAME(batch_cursor) *cursor, const double *known0, const double *p, const double *u, long n_steps, long every, long until, const SG_NAME(options) *options, double *states, long long *iterations, double *residual_norms, long *kept, int *status, long *failed_step, int *failed_iterations, double *failed_residual_norm, double *last_iterate)
{
    double buffer[(SG_BATCH_CHUNK + 1) * SG_N_KNOWNS];
    int its[SG_BATCH_CHUNK];
    double norms[SG_BATCH_CHUNK];
    long r = *kept;
    if (until > n_steps) {
        until = n_steps;
    }
    if (r == 0) { /* a fresh start: state 0 (checked finite by SG_NAME(simulate)) */
        int st;
        memset(cursor, 0, sizeof *cursor);
        *failed_step = -1;
        *failed_iterations = 0;
        *failed_residual_norm = 0.0;
        st = SG_NAME(simulate)(known0, p, NULL, 0, options, &cursor->warm, buffer, 1, its, norms, NULL, NULL);
        if (st != SG_OK) { /* a non-finite state or parameter row */
            *status = st;
            return;
        }
        memcpy(states, buffer, sizeof(double) * SG_N_KNOWNS);
        memcpy(cursor->known, buffer, sizeof(double) * SG_N_KNOWNS);
        r = 1;
    }
    while (cursor->done < until) {
        const long n = until - cursor->done < SG_BATCH_CHUNK ? until - cursor->done : SG_BATCH_CHUNK;
        long fail = -1, solved, j;
        const double *u_piece = u != NULL ? u + (size_t)cursor->done * SG_N_INPUTS : NULL;
        const int st = SG_NAME(simulate)(cursor->known, p, u_piece, n, options, &cursor->warm, buffer, SG_BATCH_CHUNK + 1, its, norms, &fail, last_iterate);
        if (st == SG_INVALID_ARGUMENT) { /* (a cursor that was not this run's) */
            *kept = r;
            *status = st;
            return;
        }
        solved = st == SG_OK ? n : fail;
        for (j = 1; j <= solved; ++j) {
            const long k = cursor->done + j;
            cursor->carry_iterations += its[j - 1];
            if (norms[j - 1] > cursor->carry_norm) {
                cursor->carry_norm = norms[j - 1];
            }
            if (k % every == 0 || k == n_steps) {
                memcpy(states + (size_t)r * SG_N_KNOWNS, buffer + (size_t)j * SG_N_KNOWNS, sizeof(double) * SG_N_KNOWNS);
                iterations[r - 1] = cursor->carry_iterations;
                residual_norms[r - 1] = cursor->carry_norm;
                cursor->carry_iterations = 0;
                cursor->carry_norm = 0.0;
                cursor->last_kept = k;
                ++r;
            }
        }
        if (st != SG_OK) {
            if (cursor->done + fail != cursor->last_kept) { /* the last state reached ends the trajectory */
                memcpy(states + (size_t)r * SG_N_KNOWNS, buffer + (size_t)fail * SG_N_KNOWNS, sizeof(double) * SG_N_KNOWNS);
                iterations[r - 1] = cursor->carry_iterations;
                residual_norms[r - 1] = cursor->carry_norm;
                ++r;
            }
            *failed_step = cursor->done + fail;
            *failed_iterations = its[fail];
            *failed_residual_norm = norms[fail];
            *kept = r;
            *status = st;
            return;
        }
        cursor->done += n;
        /* the next call starts from the last state of this one (row n of the buffer) */
        memcpy(cursor->known, buffer + (size_t)n * SG_N_KNOWNS, sizeof(double) * SG_N_KNOWNS);
    }
    *kept = r;
    *status = SG_OK;
}

/* SG_NAME(batch_advance) for trajectory b of a batch's arrays: its rows of known0, p (none
 * when p is NULL, the same row for all when p_stride is 0), u (likewise with u_stride), states, iterations and
 * residual_norms, its entries of kept and status, and of the failure outputs that were
 * given (a NULL one is written to a local and dropped). */
static void SG_NAME(batch_run)(long b, SG_NAME(batch_cursor) *cursor, const double *known0, const double *p, long p_stride, const double *u, long u_stride, long n_steps, long every, long until, const SG_NAME(options) *options, double *states, long rows, long long *iterations, double *residual_norms, long *kept, int *status, long *failed_step, int *failed_iterations, double *failed_residual_norm, double *last_iterate)
{
    int unused_iterations;
    long unused_step;
    double unused_norm;
    SG_NAME(batch_advance)(cursor, known0 + (size_t)b * SG_N_KNOWNS, p != NULL ? p + (size_t)b * (size_t)p_stride : NULL,
                          SG_N_INPUTS > 0 && u != NULL ? u + (size_t)b * (size_t)u_stride : NULL, n_steps, every, until, options,
                          states + (size_t)b * (size_t)rows * SG_N_KNOWNS,
                          iterations + (size_t)b * (size_t)(rows - 1), residual_norms + (size_t)b * (size_t)(rows - 1),
                          kept + b, status + b,
                          failed_step != NULL ? failed_step + b : &unused_step,
                          failed_iterations != NULL ? failed_iterations + b : &unused_iterations,
                          failed_residual_norm != NULL ? failed_residual_norm + b : &unused_norm,
                          last_iterate != NULL ? last_iterate + (size_t)b * SG_N_UNKNOWNS : NULL);
}

/* 1 when every entry of v is finite */
static int SG_NAME(all_finite)(const double *v, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

/* 1 when a cursor can continue: 0 <= last_kept <= done <= n_steps, last_kept a multiple of
 * every (or n_steps), kept[b] the rows kept up to it (state 0, every `every`-th, the last),
 * a finite state and carried norm */
static int SG_NAME(cursor_valid)(const SG_NAME(batch_cursor) *cursor, long n_steps, long every, long kept)
{
    return cursor->done >= 0 && cursor->done <= n_steps && cursor->last_kept >= 0
           && cursor->last_kept <= cursor->done
           && (cursor->last_kept % every == 0 || cursor->last_kept == n_steps)
           && kept == 1 + cursor->last_kept / every + (cursor->last_kept % every != 0)
           && cursor->carry_iterations >= 0
           /* at most two tries of at most INT_MAX updates per step since the last kept row
            * (a larger count would overflow when the next steps are added to it) */
           && cursor->carry_iterations / (2LL * INT_MAX) <= cursor->done - cursor->last_kept
           && cursor->carry_norm >= 0.0
           && SG_NAME(all_finite)(&cursor->carry_norm, 1)
           && SG_NAME(all_finite)(cursor->known, SG_N_KNOWNS);
}

/* The checks of SG_NAME(simulate_batch) and SG_NAME(simulate_batch_until): 1 when the
 * arguments are usable */
static int SG_NAME(batch_valid)(long n_batch, const double *known0, const double *p, long p_stride, const double *u, long u_stride, long n_steps, long every, const SG_NAME(options) *options, const double *states, long rows, const long long *iterations, const double *residual_norms, const long *kept, const int *status)
{
    (void)p;
    (void)u;
    (void)u_stride;
    return !(known0 == NULL || states == NULL || iterations == NULL || residual_norms == NULL
        || kept == NULL || status == NULL
        || (SG_N_PARAMETERS > 0 && p == NULL)
        || n_batch < 0 || n_steps < 0 || every < 1 || rows < 1
        || (p_stride != 0 && p_stride != SG_N_PARAMETERS)
        || (SG_N_INPUTS > 0 && n_steps > 0 && u == NULL)
        || (SG_N_INPUTS > 0 && n_steps > LONG_MAX / (SG_N_INPUTS > 0 ? SG_N_INPUTS : 1))
        || (SG_N_INPUTS > 0 && u_stride != 0 && u_stride != n_steps * SG_N_INPUTS)
        || n_steps / every + (n_steps % every != 0) > rows - 1
        || (size_t)rows > ((size_t)-1 / sizeof(double)) / SG_N_KNOWNS / (n_batch > 0 ? (size_t)n_batch : 1)
        || !SG_NAME(options_valid)(options));
}

/* The OpenMP team of a batch: no more threads than trajectories, nor than
 * SG_MAX_THREADS (a team is created whole, and a huge n_threads would exhaust memory
 * before any work is done) */
static int SG_NAME(batch_team)(long n_batch, int n_threads)
{
#ifdef _OPENMP
    long team = n_threads > 0 ? n_threads : omp_get_max_threads();
    if (team > n_batch) {
        team = n_batch;
    }
    if (team > SG_MAX_THREADS) {
        team = SG_MAX_THREADS;
    }
    return team < 1 ? 1 : (int)team;
#else
    (void)n_batch;
    (void)n_threads;
    return 1;
#endif
}

/* Advance n_batch independent trajectories n_steps steps each (see the header).  Trajectory b
 * starts from known0 + b * SG_N_KNOWNS with the parameters p + b * p_stride (p_stride 0:
 * one parameter vector for all, or SG_N_PARAMETERS) and, for a forced kernel
 * (SG_N_INPUTS > 0), the inputs u + b * u_stride (u_stride 0: one input sequence for all, or
 * n_steps * SG_N_INPUTS; row k of a run's sequence, u[k * SG_N_INPUTS + j], is read by its step
 * k as SG_NAME(simulate) reads it; u may be NULL without inputs), and is computed exactly as
 * SG_NAME(simulate) computes it (bitwise: the same function, called in chunks with one warm
 * start).  Its kept states go to states + b * rows * SG_N_KNOWNS (rows >= 1 +
 * ceil(n_steps / every)), the Newton summaries of the intervals between them to iterations and
 * residual_norms + b * (rows - 1), their number to kept[b], its status to status[b].  A
 * trajectory that fails stops alone: failed_step[b] = s (else -1), failed_iterations[b] and
 * failed_residual_norm[b] describe step s, last_iterate + b * SG_N_UNKNOWNS receives its last
 * Newton iterate (these four may be NULL), and the others go on.  Trajectories are independent,
 * so with OpenMP (compiled with -fopenmp) they are shared among n_threads threads (<= 0: the
 * OpenMP default; at most n_batch and SG_MAX_THREADS) without changing any result;
 * without OpenMP they run one after the other.
 * Returns SG_INVALID_ARGUMENT, writing nothing, for a null buffer, n_batch < 0,
 * n_steps < 0, every < 1, too few rows, a p_stride other than 0 or SG_N_PARAMETERS, a forced
 * kernel's NULL u or u_stride other than 0 or n_steps * SG_N_INPUTS, or invalid options; otherwise SG_OK (a non-finite row of known0 or p is reported as
 * status[b] = SG_INVALID_ARGUMENT, kept[b] = 0; a non-finite input of a piece of steps stops
 * that run with status[b] = SG_INVALID_ARGUMENT at the state before the piece). */
int SG_NAME(simulate_batch)(long n_batch, const double *known0, const double *p, long p_stride, const double *u, long u_stride, long n_steps, long every, const SG_NAME(options) *options, double *states, long rows, long long *iterations, double *residual_norms, long *kept, int *status, long *failed_step, int *failed_iterations, double *failed_residual_norm, double *last_iterate, int n_threads)
{
    SG_NAME(options) defaults;
    long b;
    int team;
    if (options == NULL) {
        SG_NAME(default_options)(&defaults);
        options = &defaults;
    }
    if (!SG_NAME(batch_valid)(n_batch, known0, p, p_stride, u, u_stride, n_steps, every, options, states, rows, iterations, residual_norms, kept, status)) {
        return SG_INVALID_ARGUMENT;
    }
    team = SG_NAME(batch_team)(n_batch, n_threads);
    (void)team;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(team) if (team > 1)
#endif
    for (b = 0; b < n_batch; ++b) {
        SG_NAME(batch_cursor) cursor;
        kept[b] = 0;
        SG_NAME(batch_run)(b, &cursor, known0, p, p_stride, u, u_stride, n_steps, every, n_steps, options, states, rows, iterations, residual_norms, kept, status, failed_step, failed_iterations, failed_residual_norm, last_iterate);
    }
    return SG_OK;
}

/* SG_NAME(simulate_batch) in installments: advance the trajectories to step `until` (at most
 * n_steps), to be called again with a larger `until` and the same arrays to continue (see
 * the header).  cursors[b] carries trajectory b from one call to the next; kept[b] = 0 (and
 * status[b] = SG_OK) starts it from row b of known0, a trajectory whose status is not
 * SG_OK has stopped and is left alone.  A call with until = n_steps after any sequence of
 * smaller ones gives bitwise the arrays of one SG_NAME(simulate_batch) call; between calls,
 * trajectory b has reached step min(until, n_steps) (unless it failed), with cursors[b].known
 * that state.  Returns SG_INVALID_ARGUMENT, writing nothing, for the arguments
 * SG_NAME(simulate_batch) refuses, a null cursors or until < 0; a cursor that does not
 * describe its trajectory's progress gives status[b] = SG_INVALID_ARGUMENT. */
int SG_NAME(simulate_batch_until)(long n_batch, SG_NAME(batch_cursor) *cursors, const double *known0, const double *p, long p_stride, const double *u, long u_stride, long n_steps, long every, long until, const SG_NAME(options) *options, double *states, long rows, long long *iterations, double *residual_norms, long *kept, int *status, long *failed_step, int *failed_iterations, double *failed_residual_norm, double *last_iterate, int n_threads)
{
    SG_NAME(options) defaults;
    long b;
    int team;
    if (options == NULL) {
        SG_NAME(default_options)(&defaults);
        options = &defaults;
    }
    if (cursors == NULL || until < 0
        || !SG_NAME(batch_valid)(n_batch, known0, p, p_stride, u, u_stride, n_steps, every, options, states, rows, iterations, residual_norms, kept, status)) {
        return SG_INVALID_ARGUMENT;
    }
    team = SG_NAME(batch_team)(n_batch, n_threads);
    (void)team;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 1) num_threads(team) if (team > 1)
#endif
    for (b = 0; b < n_batch; ++b) {
        if (status[b] != SG_OK) {
            continue;
        }
        if (kept[b] != 0 && !SG_NAME(cursor_valid)(cursors + b, n_steps, every, kept[b])) {
            status[b] = SG_INVALID_ARGUMENT;
            continue;
        }
        SG_NAME(batch_run)(b, cursors + b, known0, p, p_stride, u, u_stride, n_steps, every, until, options, states, rows, iterations, residual_norms, kept, status, failed_step, failed_iterations, failed_residual_norm, last_iterate);
    }
    return SG_OK;
}

/* One step from a fresh start: next receives the state after known, the same bits as the
 * second row SG_NAME(simulate)(known, p, u, 1, options, NULL, ...) writes; returns its status
 * (next is written only on success; SG_INVALID_ARGUMENT for a null next).  The entry
 * point with the fewest arguments, for callers that advance one state at a time (a control
 * loop in Python pays for every argument of a call). */
int SG_NAME(step)(const double *known, const double *p, const double *u, const SG_NAME(options) *options, double *next)
{
    double states[2 * SG_N_KNOWNS];
    int iterations = 0;
    double residual_norm = 0.0;
    int status;
    if (next == NULL) {
        return SG_INVALID_ARGUMENT;
    }
    status = SG_NAME(simulate)(known, p, u, 1, options, NULL, states, 2, &iterations, &residual_norm, NULL, NULL);
    if (status == SG_OK) {
        memcpy(next, states + SG_N_KNOWNS, sizeof(double) * SG_N_KNOWNS);
    }
    return status;
}

const char *SG_NAME(status_message)(int status)
{
    switch (status) {
    case SG_OK:
        return "converged";
    case SG_SINGULAR_JACOBIAN:
        return "singular Jacobian: a pivot vanished relative to its equation at Newton's iterate, so the step equations do not determine the next state there (the discrete Lagrangian is not regular there, or the step is too large for a root near the guess: a rotation per step near a half-turn, a step beyond the equations' reach)";
    case SG_NOT_CONVERGED:
        return "Newton's method reached its iteration cap (the max_iterations option: that many updates) without converging";
    case SG_NON_FINITE:
        return "non-finite value (overflow to infinity, or NaN) in the residual, the Jacobian, the Newton step or the next state";
    case SG_INVALID_ARGUMENT:
        return "invalid argument (null buffer, negative step count, capacity below n_steps + 1, bad option or warm start, or non-finite input)";
    case SG_STALLED:
        return "Newton's method stalled: its update is at the rounding noise of the solve while the residual stays above its rounding floor";
    case SG_BRANCH_JUMP:
        return "branch jump: the step's solution lies far outside the region the last steps predict, or on a time groupoid its time step reverses or changes by more than a factor 2 (the nearby root of the step equations has disappeared: reduce the step; or the motion itself runs away faster than its last steps, as a solution that blows up does)";
    case SG_OUTSIDE_DOMAIN:
        return "outside the domain: Newton solved the step equations, but the discrete Lagrangian is not defined at the solution (a logarithm, square root, acos, ... of it is not finite there)";
    default:
        return "unknown status";
    }
}
