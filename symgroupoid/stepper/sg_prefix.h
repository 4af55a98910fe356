/*
 * The name prefix of the Newton stepper library (symgroupoid.stepper): every function and
 * type of a kernel is named SG_NAME(x), i.e. <prefix>_x, and every macro SG_X stands for the
 * kernel's <PREFIX>_X.  The library compiled on its own (a kernel "toy"):
 *
 *     cc -std=c99 -DSG_PREFIX=toy -DSG_PREFIX_UPPER=TOY -include toy_sizes.h -c stepper.c
 *
 * with TOY_N_EQUATIONS, TOY_N_UNKNOWNS, TOY_N_KNOWNS, TOY_N_PARAMETERS, TOY_N_INPUTS and
 * the time indices TOY_TIME_ROW, TOY_TIME_UNKNOWN, TOY_TIME_KNOWN, TOY_TIME_BEFORE (-1
 * without a time groupoid) defined in toy_sizes.h (or before stepper.h is included),
 * beside the kernel's own functions (see stepper.h); a kernel whose Jacobian is banded in a
 * reordering of its unknowns also defines TOY_BANDED 1, TOY_BAND_KL, TOY_BAND_KU and
 * TOY_BAND_ORDER (see stepper.c; without TOY_BANDED the factors are dense).  The code
 * generator writes the library into a kernel with these names spelt out
 * (plate_ball_simulate, PLATE_BALL_OK, ...); this file is never part of a kernel.
 */
#ifndef SG_PREFIX_H
#define SG_PREFIX_H

#if !defined(SG_PREFIX) || !defined(SG_PREFIX_UPPER)
#error "define SG_PREFIX and SG_PREFIX_UPPER (the kernel's name prefix, e.g. toy and TOY)"
#endif

#define SG_CAT_(a, b) a##_##b
#define SG_CAT(a, b) SG_CAT_(a, b)
/* <prefix>_x: the kernel's functions and types */
#define SG_NAME(x) SG_CAT(SG_PREFIX, x)
/* the kernel's sizes, defined by the kernel */
#define SG_N_EQUATIONS SG_CAT(SG_PREFIX_UPPER, N_EQUATIONS)
#define SG_N_UNKNOWNS SG_CAT(SG_PREFIX_UPPER, N_UNKNOWNS)
#define SG_N_KNOWNS SG_CAT(SG_PREFIX_UPPER, N_KNOWNS)
#define SG_N_PARAMETERS SG_CAT(SG_PREFIX_UPPER, N_PARAMETERS)
#define SG_N_INPUTS SG_CAT(SG_PREFIX_UPPER, N_INPUTS)
/* the values of the known arrow the residual reads (SG_NAME(hoist)) */
#define SG_N_HOISTED SG_CAT(SG_PREFIX_UPPER, N_HOISTED)
/* the values of the window's terms defined on part of the real line only (SG_NAME(domain);
 * undefined: none) */
#define SG_N_DOMAIN SG_CAT(SG_PREFIX_UPPER, N_DOMAIN)
/* the time of a step on a time groupoid (-1: none; symgroupoid.stepper._time) */
#define SG_TIME_ROW SG_CAT(SG_PREFIX_UPPER, TIME_ROW)
#define SG_TIME_UNKNOWN SG_CAT(SG_PREFIX_UPPER, TIME_UNKNOWN)
#define SG_TIME_KNOWN SG_CAT(SG_PREFIX_UPPER, TIME_KNOWN)
#define SG_TIME_BEFORE SG_CAT(SG_PREFIX_UPPER, TIME_BEFORE)
/* a Jacobian banded in the order SG_BAND_ORDER (SG_BANDED undefined or 0: dense factors) */
#define SG_BANDED SG_CAT(SG_PREFIX_UPPER, BANDED)
#define SG_BAND_KL SG_CAT(SG_PREFIX_UPPER, BAND_KL)
#define SG_BAND_KU SG_CAT(SG_PREFIX_UPPER, BAND_KU)
#define SG_BAND_ORDER SG_CAT(SG_PREFIX_UPPER, BAND_ORDER)

#endif /* SG_PREFIX_H */
