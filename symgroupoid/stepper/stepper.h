/*
 * The interface of the Newton stepper library (symgroupoid.stepper): its statuses, the
 * options, warm start and batch cursor types, its entry points, and the functions a kernel
 * provides for it (the straight-line functions the code generator writes: reconstruct,
 * hoist, residual, residual_jacobian, residual_scale, predict, next_knowns, domain).  Every name goes
 * through the prefix macros of sg_prefix.h; a kernel's header holds this text with its
 * prefix spelt out, after its sizes <PREFIX>_N_EQUATIONS, _N_UNKNOWNS, _N_KNOWNS,
 * _N_PARAMETERS, _N_INPUTS, _N_HOISTED, _N_DOMAIN.  The library's sources: stepper.c (the stepper: LU, rounding floors,
 * Newton, warm start, simulate), batch.c (the batched and one-step entry points and the
 * status messages), options.h and prologue.h (shared by both).
 */
#ifndef SG_STEPPER_H
#define SG_STEPPER_H

#include "sg_prefix.h"

/* the most OpenMP threads SG_NAME(simulate_batch) starts (a team is created whole) */
#define SG_MAX_THREADS 1024

/* the statuses of the stepper (symgroupoid.stepper.Status, kernel=True) */
#define SG_OK 0
#define SG_SINGULAR_JACOBIAN 1
#define SG_NOT_CONVERGED 2
#define SG_NON_FINITE 3
#define SG_INVALID_ARGUMENT 4
#define SG_STALLED 5
#define SG_BRANCH_JUMP 6
#define SG_OUTSIDE_DOMAIN 8

typedef struct {
    double tol_residual;
    double floor_factor;
    double tol_step;
    int max_iterations;
    int extrapolate;
    double trust_factor;
} SG_NAME(options);

typedef struct {
    int count;
    int quadratic;
    double u_last[SG_N_UNKNOWNS];
    double u_before[SG_N_UNKNOWNS];
    double u_earlier[SG_N_UNKNOWNS];
} SG_NAME(warm_start);

typedef struct {
    SG_NAME(warm_start) warm;
    long done;
    long last_kept;
    long long carry_iterations;
    double carry_norm;
    double known[SG_N_KNOWNS];
} SG_NAME(batch_cursor);

/* the library's entry points, and the functions a kernel generates for it */
void SG_NAME(default_options)(SG_NAME(options) *options);
void SG_NAME(reconstruct)(const double *u, const double *known, const double *p, double *fibre);
void SG_NAME(residual)(const double *u, const double *known, const double *p, double *F);
void SG_NAME(residual_jacobian)(const double *u, const double *known, const double *p, double *F, double *J);
void SG_NAME(hoist)(const double *known, const double *p, double *h);
void SG_NAME(residual_hoisted)(const double *u, const double *known, const double *p, const double *h, double *F);
void SG_NAME(residual_scale)(const double *u, const double *known, const double *p, double *S);
void SG_NAME(predict)(const double *known, const double *p, double *u);
void SG_NAME(next_knowns)(const double *u, const double *known, const double *p, double *known_next);
void SG_NAME(domain)(const double *u, const double *known, const double *p, double *D);
int SG_NAME(solve_step)(const double *known, const double *p, const SG_NAME(options) *options, double *u, int *iterations, double *residual_norm);
int SG_NAME(simulate)(const double *known0, const double *p, const double *u, long n_steps, const SG_NAME(options) *options, SG_NAME(warm_start) *warm, double *states, long capacity, int *iterations, double *residual_norms, long *failed_step, double *last_iterate);
int SG_NAME(simulate_batch)(long n_batch, const double *known0, const double *p, long p_stride, const double *u, long u_stride, long n_steps, long every, const SG_NAME(options) *options, double *states, long rows, long long *iterations, double *residual_norms, long *kept, int *status, long *failed_step, int *failed_iterations, double *failed_residual_norm, double *last_iterate, int n_threads);
int SG_NAME(step)(const double *known, const double *p, const double *u, const SG_NAME(options) *options, double *next);
int SG_NAME(simulate_batch_until)(long n_batch, SG_NAME(batch_cursor) *cursors, const double *known0, const double *p, long p_stride, const double *u, long u_stride, long n_steps, long every, long until, const SG_NAME(options) *options, double *states, long rows, long long *iterations, double *residual_norms, long *kept, int *status, long *failed_step, int *failed_iterations, double *failed_residual_norm, double *last_iterate, int n_threads);
const char *SG_NAME(status_message)(int status);

#endif /* SG_STEPPER_H */
