/*
 * A closed loop in C: a PD controller turns a satellite with a reaction wheel to a target
 * attitude, one step of the generated kernel generated/satellite_wheel.c at a time.
 *
 * The system is symgroupoid.systems.satellite_with_wheel(): an axisymmetric body (inertia
 * I, I, I3) and a wheel (inertia Iw) spinning about the body's third axis, on SO(3) x SO(2).
 * Its known state (satellite_wheel.h) is the last arrow, the body's attitude increment W_k
 * (R_{k+1} = R_k W_k) and the wheel's turn relative to the body V_k, then the motor torques
 * tau_k of that arrow and tau_{k+1} of the arrow the next step computes (docs/conventions.md
 * section 20).  The motor torque turns the wheel and, in reaction, the body (-tau about the
 * axis); one wheel controls the rotation about its own axis only, so the body turns about
 * that axis: it starts spinning at OMEGA0 about it, and the target is a rotation by TARGET
 * about it.
 *
 * Each step the controller reads the body's and the wheel's rates off the known arrow
 * (the rotation angles of W_k and V_k over h), keeps the attitude R by multiplying the
 * increments, and sets the torque of the next arrow
 *     tau_{k+1} = KP e + KD omega,
 * e the body's rotation from the target about the axis and omega its rate (the closed loop
 * I3 e'' = -KP e - KD e': critically damped at 1.5 rad/s), then calls
 * satellite_wheel_step(known, p, &tau, options, next).
 *
 * Build and run (from the repository root):
 *     make -C examples/embed run-closed-loop [STEPS=750]
 * Usage: closed_loop STEPS [TRAJECTORY]
 * stdout: every 50th step and the last "k t error body_rate wheel_rate torque" (error: the
 * angle of the rotation from the target attitude to the attitude, in radians), then the
 * final error against TOLERANCE; the exit status is 1 when it is not below it (or a step
 * fails), 2 on a usage error.
 * TRAJECTORY (optional): one line per state k = 0..STEPS, "k" and the
 * SATELLITE_WHEEL_N_KNOWNS entries of the state (%.17g; state k holds tau_k in its last two
 * entries), the torques and arrows a Simulator reproduces bit for bit.
 */
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "satellite_wheel.h"

#if SATELLITE_WHEEL_N_KNOWNS != 15 || SATELLITE_WHEEL_N_INPUTS != 1 || SATELLITE_WHEEL_N_PARAMETERS != 4
#error "closed_loop.c expects the kernel of symgroupoid.systems.satellite_with_wheel()"
#endif

/* the known state: W_k row by row, V_k row by row, tau_k, tau_{k+1} */
#define W_AT 0
#define V_AT 9
#define TAU_AT 13

#define H 0.02        /* the time step (s) */
#define INERTIA 2.0   /* the body's inertia about its first two axes */
#define INERTIA3 3.0  /* the body's inertia about the wheel's axis */
#define INERTIA_W 0.1 /* the wheel's inertia about its axis */
#define OMEGA0 0.3    /* the body's initial rate about the axis (rad/s) */
#define TARGET 1.0    /* the target attitude: this rotation about the axis (rad) */
#define KP 6.75       /* I3 w^2, w = 1.5 rad/s */
#define KD 9.0        /* 2 I3 w: critical damping */
#define TOLERANCE 1e-6
#define EVERY 50

/* STEPS as a long in 1..LONG_MAX; -1 when the text is not such a number */
static long parse_steps(const char *text)
{
    char *end;
    long value;
    errno = 0;
    value = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || value < 1) {
        return -1;
    }
    return value;
}

/* out = a b (3 x 3, row-major) */
static void multiply(const double *a, const double *b, double *out)
{
    int i, j;
    for (i = 0; i < 3; ++i) {
        for (j = 0; j < 3; ++j) {
            out[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
        }
    }
}

/* the rotation angle of a rotation matrix A (0..pi), accurate near 0 */
static double rotation_angle(const double *A)
{
    double x = A[7] - A[5], y = A[2] - A[6], z = A[3] - A[1];
    return atan2(0.5 * sqrt(x * x + y * y + z * z), 0.5 * (A[0] + A[4] + A[8] - 1.0));
}

/* the rotation angle about the third axis of a rotation matrix A close to such a rotation */
static double axial_angle(const double *A)
{
    return atan2(A[3] - A[1], A[0] + A[4]);
}

/* the rotation R_target^T R from the target attitude to R */
static void from_target(const double *R, double *A)
{
    const double c = cos(TARGET), s = sin(TARGET);
    const double target_t[9] = {c, s, 0.0, -s, c, 0.0, 0.0, 0.0, 1.0};
    multiply(target_t, R, A);
}

static void write_state(FILE *out, long k, const double *state)
{
    int i;
    fprintf(out, "%ld", k);
    for (i = 0; i < SATELLITE_WHEEL_N_KNOWNS; ++i) {
        fprintf(out, " %.17g", state[i]);
    }
    fprintf(out, "\n");
}

int main(int argc, char **argv)
{
    const double p[SATELLITE_WHEEL_N_PARAMETERS] = {H, INERTIA, INERTIA3, INERTIA_W};
    double known[SATELLITE_WHEEL_N_KNOWNS] = {0.0}, next[SATELLITE_WHEEL_N_KNOWNS];
    double R[9] = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0}, Rn[9], A[9];
    double body_rate, wheel_rate, error, tau;
    long steps, k;
    int status;
    FILE *trajectory = NULL;
    satellite_wheel_options options;

    if (argc < 2 || argc > 3 || (steps = parse_steps(argv[1])) < 0) {
        fprintf(stderr, "usage: %s STEPS [TRAJECTORY]   (STEPS an integer in 1..%ld)\n",
                argv[0], (long)LONG_MAX);
        return 2;
    }
    if (argc == 3 && (trajectory = fopen(argv[2], "w")) == NULL) {
        fprintf(stderr, "%s: cannot write %s: %s\n", argv[0], argv[2], strerror(errno));
        return 2;
    }
    satellite_wheel_default_options(&options);
    /* the first arrow: the body turns by OMEGA0 h about the axis, the wheel with it (V = I),
     * no torque; R: the attitude at its target */
    known[W_AT] = known[W_AT + 4] = cos(OMEGA0 * H);
    known[W_AT + 3] = sin(OMEGA0 * H);
    known[W_AT + 1] = -known[W_AT + 3];
    known[W_AT + 8] = 1.0;
    known[V_AT] = known[V_AT + 3] = 1.0;
    multiply(R, known + W_AT, Rn);
    memcpy(R, Rn, sizeof R);
    if (trajectory != NULL) {
        write_state(trajectory, 0, known);
    }
    printf("# k t attitude_error body_rate wheel_rate torque\n");
    for (k = 0; k <= steps; ++k) {
        /* read off the known arrow: the rates over its step; the attitude at its target */
        body_rate = axial_angle(known + W_AT) / H;
        wheel_rate = body_rate + atan2(known[V_AT + 2], known[V_AT]) / H;
        from_target(R, A);
        error = rotation_angle(A);
        if (k % EVERY == 0 || k == steps) {
            printf("%ld %.2f %.3e %+.3e %+.4f %+.3e\n", k, k * H, error, body_rate, wheel_rate,
                   known[TAU_AT]);
        }
        if (k == steps) {
            break;
        }
        tau = KP * axial_angle(A) + KD * body_rate; /* the torque of the next arrow */
        status = satellite_wheel_step(known, p, &tau, &options, next);
        if (status != SATELLITE_WHEEL_OK) {
            fprintf(stderr, "step %ld failed: %s\n", k, satellite_wheel_status_message(status));
            return 1;
        }
        memcpy(known, next, sizeof known);
        multiply(R, known + W_AT, Rn);
        memcpy(R, Rn, sizeof R);
        if (trajectory != NULL) {
            write_state(trajectory, k + 1, known);
        }
    }
    if (trajectory != NULL && fclose(trajectory) != 0) {
        fprintf(stderr, "%s: cannot write %s\n", argv[0], argv[2]);
        return 2;
    }
    printf("final attitude error %.3e rad after %.2f s (tolerance %.0e): %s\n", error,
           steps * H, TOLERANCE, error < TOLERANCE ? "reached" : "NOT reached");
    return error < TOLERANCE ? 0 : 1;
}
