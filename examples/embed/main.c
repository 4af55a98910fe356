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
 */
#include <stdio.h>
#include <stdlib.h>

#include "plate_ball.h"

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

int main(int argc, char **argv)
{
    double params[PLATE_BALL_N_PARAMETERS];
    double known0[PLATE_BALL_N_KNOWNS];
    double last[PLATE_BALL_N_UNKNOWNS];
    double *states;
    double *norms;
    int *iterations;
    long steps, failed, k;
    int status, i;
    plate_ball_options options;

    if (argc != 2 || (steps = strtol(argv[1], NULL, 10)) < 0) {
        fprintf(stderr, "usage: %s STEPS < input\n", argv[0]);
        return 2;
    }
    if (!read_values(params, PLATE_BALL_N_PARAMETERS) || !read_values(known0, PLATE_BALL_N_KNOWNS)) {
        fprintf(stderr, "expected %d parameters and %d state values on stdin\n",
                PLATE_BALL_N_PARAMETERS, PLATE_BALL_N_KNOWNS);
        return 2;
    }
    states = malloc(sizeof(double) * (size_t)(steps + 1) * PLATE_BALL_N_KNOWNS);
    norms = malloc(sizeof(double) * (size_t)(steps > 0 ? steps : 1));
    iterations = malloc(sizeof(int) * (size_t)(steps > 0 ? steps : 1));
    if (states == NULL || norms == NULL || iterations == NULL) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    plate_ball_default_options(&options);
    status = plate_ball_simulate(known0, params, steps, &options, states, iterations, norms,
                                 &failed, last);
    if (status != PLATE_BALL_OK) {
        fprintf(stderr, "step %ld failed: %s\n", failed, plate_ball_status_message(status));
        return 1;
    }
    for (k = 0; k <= steps; ++k) {
        printf("%ld %d %.17g", k, k > 0 ? iterations[k - 1] : 0, k > 0 ? norms[k - 1] : 0.0);
        for (i = 0; i < PLATE_BALL_N_KNOWNS; ++i) {
            printf(" %.17g", states[k * PLATE_BALL_N_KNOWNS + i]);
        }
        printf("\n");
    }
    free(states);
    free(norms);
    free(iterations);
    return 0;
}
