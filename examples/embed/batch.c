/*
 * Many plate-ball trajectories in one call of the generated batched entry point.
 *
 * Build (from the repository root; add -fopenmp to share the runs among threads):
 *     cc -std=c99 -O2 -Igenerated examples/embed/batch.c generated/plate_ball.c -lm \
 *        -o examples/embed/batch_demo
 * Run:
 *     examples/embed/batch_demo RUNS STEPS EVERY < examples/embed/initial.txt
 *
 * Input as for main.c: the parameters, then one consistent initial state.  Run b starts from
 * state b of a first plate_ball_simulate call (consecutive states of one trajectory, so
 * every start satisfies the rolling constraints); plate_ball_simulate_batch then advances
 * all RUNS for STEPS steps each, keeping every EVERY-th state.
 * Output: one line per run: "b status failed_step kept last_state..." (the last state each
 * run reached, %.17g).
 */
#include <errno.h>
#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "plate_ball.h"

/* A whole decimal number in minimum..LONG_MAX; -1 when the text is not such a number
 * (trailing characters, overflow, below the minimum). */
static long parse_count(const char *text, long minimum)
{
    char *end;
    long value;
    errno = 0;
    value = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || value < minimum) {
        return -1;
    }
    return value;
}

/* a * b * c bytes of elements of size `size`, or 0 when that product overflows a size_t
 * (the caller reports it as out of memory instead of allocating a wrapped, small size). */
static size_t bytes_of(size_t size, size_t a, size_t b, size_t c)
{
    if (a != 0 && b > SIZE_MAX / a) {
        return 0;
    }
    if (c != 0 && a * b > SIZE_MAX / c) {
        return 0;
    }
    return a * b * c > SIZE_MAX / size ? 0 : size * a * b * c;
}

int main(int argc, char **argv)
{
    double params[PLATE_BALL_N_PARAMETERS], state0[PLATE_BALL_N_KNOWNS];
    double *starts, *states, *norms;
    long long *iterations;
    long *kept, *failed, runs, steps, every, rows, b;
    size_t per_run;
    int *status, i, code;

    if (argc != 4 || (runs = parse_count(argv[1], 1)) < 1 || (steps = parse_count(argv[2], 0)) < 0
        || (every = parse_count(argv[3], 1)) < 1 || runs > INT_MAX) {
        fprintf(stderr, "usage: %s RUNS STEPS EVERY < input   (RUNS an integer in 1..%d, "
                "STEPS in 0..%ld, EVERY in 1..%ld)\n", argv[0], INT_MAX, (long)LONG_MAX,
                (long)LONG_MAX);
        return 2;
    }
    for (i = 0; i < PLATE_BALL_N_PARAMETERS; ++i) {
        if (scanf("%lf", &params[i]) != 1) {
            return 2;
        }
    }
    for (i = 0; i < PLATE_BALL_N_KNOWNS; ++i) {
        if (scanf("%lf", &state0[i]) != 1) {
            return 2;
        }
    }
    rows = 1 + steps / every + (steps % every != 0);
    per_run = (size_t)(rows > 1 ? rows - 1 : 1);
    /* every size checked before it is allocated: a product that wraps around would allocate
     * a small block that the calls below overrun */
    {
        const size_t sizes[] = {
            bytes_of(sizeof(double), (size_t)runs, PLATE_BALL_N_KNOWNS, 1),
            bytes_of(sizeof(double), (size_t)runs, (size_t)rows, PLATE_BALL_N_KNOWNS),
            bytes_of(sizeof(long long), (size_t)runs, per_run, 1),
            bytes_of(sizeof(double), (size_t)runs, per_run, 1)};
        for (i = 0; i < 4; ++i) {
            if (sizes[i] == 0) {
                fprintf(stderr, "out of memory: %ld runs of %ld kept states do not fit in "
                        "this machine's address space\n", runs, rows);
                return 1;
            }
        }
        starts = malloc(sizes[0]);
        states = malloc(sizes[1]);
        iterations = malloc(sizes[2]);
        norms = malloc(sizes[3]);
    }
    kept = malloc(sizeof(long) * (size_t)runs);
    failed = malloc(sizeof(long) * (size_t)runs);
    status = malloc(sizeof(int) * (size_t)runs);
    if (!starts || !states || !iterations || !norms || !kept || !failed || !status) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    {   /* the starts: states 0 .. runs - 1 of one trajectory */
        int *its = malloc(sizeof(int) * (size_t)runs);
        double *res = malloc(sizeof(double) * (size_t)runs);
        code = its && res ? plate_ball_simulate(state0, params, NULL, runs - 1, NULL, NULL, starts,
                                                runs, its, res, NULL, NULL)
                          : PLATE_BALL_INVALID_ARGUMENT;
        free(its);
        free(res);
        if (code != PLATE_BALL_OK) {
            fprintf(stderr, "start states: %s\n", plate_ball_status_message(code));
            return 1;
        }
    }
    code = plate_ball_simulate_batch(runs, starts, params, 0, NULL, 0, steps, every, NULL,
                                     states, rows, iterations, norms, kept, status, failed,
                                     NULL, NULL, NULL, 0);
    if (code != PLATE_BALL_OK) {
        fprintf(stderr, "%s\n", plate_ball_status_message(code));
        return 1;
    }
    for (b = 0; b < runs; ++b) {
        const double *last = states + ((size_t)b * (size_t)rows + (size_t)(kept[b] - 1))
                                          * PLATE_BALL_N_KNOWNS;
        printf("%ld %d %ld %ld", b, status[b], failed[b], kept[b]);
        for (i = 0; i < PLATE_BALL_N_KNOWNS; ++i) {
            printf(" %.17g", last[i]);
        }
        printf("\n");
    }
    free(starts);
    free(states);
    free(iterations);
    free(norms);
    free(kept);
    free(failed);
    free(status);
    return 0;
}
