/* The seam between a vehicle model and the FMI glue (fmi2_glue.c, fmi3_glue.c).
 *
 * A model is a set of variables addressed by value reference (all stored as double,
 * Int32 variables hold whole numbers) and a vector of continuous states integrated by
 * the fixed-step Runge-Kutta solver of solver.c. The generated header "vars.h" (from the
 * model's model.toml by fmu/build.py) defines N_VARS, the VR_<name> value references,
 * the X_<name> state indices, N_STATES, the variable table and the instantiation token.
 */
#ifndef BENCH_MODEL_H
#define BENCH_MODEL_H

#include <stddef.h>

#include "vars.h"

typedef struct Model {
    double v[N_VARS];     /* variables by value reference */
    double x[N_STATES];   /* continuous states */
    double time;          /* s */
    char msg[256];        /* why the last step failed */
} Model;

/* Implemented by each model ------------------------------------------------------- */

/* Parameter problems as a message, or NULL when the parameters are usable. */
const char *model_check(const Model *m);

/* Initial states from parameters and start values (called when initialization ends). */
void model_start(Model *m);

/* Time derivatives dx of the states x (inputs and parameters from m->v). */
void model_derivatives(const Model *m, const double *x, double *dx);

/* Output variables from the states and inputs. */
void model_outputs(Model *m);

/* Provided by solver.c --------------------------------------------------------------- */

/* Start values into m->v, states zero, time zero. */
void model_reset(Model *m);

/* Advance by h seconds with RK4 substeps no longer than the solver_step parameter;
 * returns 0, or -1 with m->msg saying what went wrong. */
int model_advance(Model *m, double h);

#endif
