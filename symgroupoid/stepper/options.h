/*
 * The validation of a kernel's Newton options, in every translation unit that takes them
 * (symgroupoid.stepper; see stepper.h).
 */
#ifndef SG_OPTIONS_H
#define SG_OPTIONS_H

#include "stepper.h"
#include "prologue.h"

/* 1 when the options are usable: tolerances >= 0 (not NaN), max_iterations >= 0, a finite
 * trust_factor >= 0 */
static int SG_NAME(options_valid)(const SG_NAME(options) *options)
{
    return options->max_iterations >= 0 && options->tol_residual >= 0.0
           && options->floor_factor >= 0.0 && options->tol_step >= 0.0
           && options->trust_factor >= 0.0 && options->trust_factor < INFINITY;
}

#endif /* SG_OPTIONS_H */
