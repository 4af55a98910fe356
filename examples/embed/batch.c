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
#include <stdio.h>
#include <stdlib.h>

#include "plate_ball.h"

int main(int argc, char **argv)
{
    double params[PLATE_BALL_N_PARAMETERS], state0[PLATE_BALL_N_KNOWNS];
    double *starts, *states, *norms;
    long long *iterations;
    long *kept, *failed, runs, steps, every, rows, b;
    int *status, i, code;

    if (argc != 4 || (runs = atol(argv[1])) < 1 || (steps = atol(argv[2])) < 0
        || (every = atol(argv[3])) < 1) {
        fprintf(stderr, "usage: %s RUNS STEPS EVERY < input\n", argv[0]);
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
    starts = malloc(sizeof(double) * (size_t)runs * PLATE_BALL_N_KNOWNS);
    states = malloc(sizeof(double) * (size_t)runs * (size_t)rows * PLATE_BALL_N_KNOWNS);
    iterations = malloc(sizeof(long long) * (size_t)runs * (size_t)(rows > 1 ? rows - 1 : 1));
    norms = malloc(sizeof(double) * (size_t)runs * (size_t)(rows > 1 ? rows - 1 : 1));
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
