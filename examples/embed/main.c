/*
 * Embedding a generated symgroupoid kernel: step the plate-ball system from C.
 *
 * Build (from the repository root):
 *     cc -std=c99 -O2 -Igenerated examples/embed/main.c generated/plate_ball.c -lm \
 *        -o examples/embed/embed_demo
 * Run:
 *     examples/embed/embed_demo STEPS < examples/embed/initial.txt
 *
 * Input (whitespace separated): the PLATE_BALL_N_PARAMETERS parameters (h, r, Omega, c),
 * then the PLATE_BALL_N_KNOWNS entries of the initial state (g_k, lambda_k) in the order
 * listed in plate_ball.h.
 * Output: one line per state k = 0..STEPS: "k newton_iterations residual_norm state..."
 * (iterations and residual norm are those of the step that produced the state; 0 for k = 0).
 *
 * The run is computed in chunks of CHUNK steps through one fixed buffer: each call of
 * plate_ball_simulate starts from the last state of the previous one and carries the Newton
 * warm start, so the states are exactly those of one call, and any STEPS up to LONG_MAX
 * runs in constant memory.
 */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plate_ball.h"

#define CHUNK 1024

static double states[(CHUNK + 1) * PLATE_BALL_N_KNOWNS];
static double norms[CHUNK];
static int iterations[CHUNK];

static int read_values(double *out, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        if (scanf("%lf", &out[i]) != 1) {
            return 0;
        }
    }
    return 1;
}

/* STEPS as a long in 0..LONG_MAX; -1 when the text is not such a number */
static long parse_steps(const char *text)
{
    char *end;
    long value;
    errno = 0;
    value = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || value < 0) {
        return -1;
    }
    return value;
}

static void print_state(long k, int newton_iterations, double residual_norm, const double *state)
{
    int i;
    printf("%ld %d %.17g", k, newton_iterations, residual_norm);
    for (i = 0; i < PLATE_BALL_N_KNOWNS; ++i) {
        printf(" %.17g", state[i]);
    }
    printf("\n");
}

int main(int argc, char **argv)
{
    double params[PLATE_BALL_N_PARAMETERS];
    double last[PLATE_BALL_N_UNKNOWNS];
    long steps, done, failed, n, k;
    int status;
    plate_ball_options options;
    plate_ball_warm_start warm;

    if (argc != 2 || (steps = parse_steps(argv[1])) < 0) {
        fprintf(stderr, "usage: %s STEPS < input   (STEPS an integer in 0..%ld)\n", argv[0],
                (long)LONG_MAX);
        return 2;
    }
    if (!read_values(params, PLATE_BALL_N_PARAMETERS) || !read_values(states, PLATE_BALL_N_KNOWNS)) {
        fprintf(stderr, "expected %d parameters and %d state values on stdin\n",
                PLATE_BALL_N_PARAMETERS, PLATE_BALL_N_KNOWNS);
        return 2;
    }
    plate_ball_default_options(&options);
    memset(&warm, 0, sizeof warm);
    /* zero steps: still validate the input (and echo the state) */
    status = plate_ball_simulate(states, params, NULL, 0, &options, &warm, states, CHUNK + 1,
                                 iterations, norms, &failed, last);
    if (status != PLATE_BALL_OK) {
        fprintf(stderr, "plate_ball_simulate: %s\n", plate_ball_status_message(status));
        return 1;
    }
    print_state(0, 0, 0.0, states);
    for (done = 0; done < steps; done += n) {
        n = steps - done < CHUNK ? steps - done : CHUNK;
        status = plate_ball_simulate(states, params, NULL, n, &options, &warm, states, CHUNK + 1,
                                     iterations, norms, &failed, last);
        if (status != PLATE_BALL_OK) {
            fprintf(stderr, "step %ld failed: %s\n", done + failed,
                    plate_ball_status_message(status));
            return 1;
        }
        for (k = 1; k <= n; ++k) {
            print_state(done + k, iterations[k - 1], norms[k - 1],
                        states + k * PLATE_BALL_N_KNOWNS);
        }
        memmove(states, states + n * PLATE_BALL_N_KNOWNS, sizeof(double) * PLATE_BALL_N_KNOWNS);
    }
    return 0;
}
