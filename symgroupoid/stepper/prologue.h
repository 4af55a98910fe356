/*
 * The checks and the standard headers of every translation unit of the Newton stepper
 * library (symgroupoid.stepper; see stepper.h).
 */
#ifndef SG_PROLOGUE_H
#define SG_PROLOGUE_H

/* The Newton stepper turns an overflow or a NaN into SG_NON_FINITE through isfinite()
 * checks.  -ffast-math and -ffinite-math-only let the compiler assume that no value is ever
 * NaN or infinite and delete those checks (a NaN input then comes back "converged"), and the
 * rest of the unsafe-math family (-funsafe-math-optimizations, -fassociative-math,
 * -freciprocal-math, -fno-signed-zeros) lets it rewrite the arithmetic (other bits than the
 * NumPy backend's), so this kernel refuses to be compiled under them (by the macros the
 * compiler defines for them). */
#if defined(__FAST_MATH__)
#error "this symgroupoid kernel must not be compiled with -ffast-math (or -Ofast): it deletes the NaN and overflow checks of the Newton stepper"
#elif defined(__FINITE_MATH_ONLY__) && __FINITE_MATH_ONLY__
#error "this symgroupoid kernel must not be compiled with -ffinite-math-only: it deletes the NaN and overflow checks of the Newton stepper"
#elif defined(__ASSOCIATIVE_MATH__) || defined(__RECIPROCAL_MATH__) || defined(__NO_SIGNED_ZEROS__)
#error "this symgroupoid kernel must not be compiled with -funsafe-math-optimizations, -fassociative-math, -freciprocal-math or -fno-signed-zeros: they change its arithmetic"
#endif

#include <float.h>
#include <limits.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#if DBL_MANT_DIG != 53 || DBL_MAX_EXP != 1024 || DBL_MIN_EXP != -1021
#error "this symgroupoid kernel needs IEEE-754 binary64 doubles"
#endif
#ifdef _OPENMP
#include <omp.h>
#endif

#endif /* SG_PROLOGUE_H */
