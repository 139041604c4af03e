/*
 * The contract between the project's FMI 2.0 co-simulation framework (fmi2_cs.c) and one model.
 *
 * A model is one C file (sources/model.c of a source FMU) that includes this header and defines
 * the four functions below. The framework implements every function of fmi2Functions.h around
 * them: instantiation, start values, get/set of reals by value reference, reset, the step.
 *
 * Every real variable of the model (parameters, inputs, outputs, locals) has one value reference:
 * its index into Instance.r, 0 to N_REALS - 1, in the order of modelDescription.xml's
 * <ModelVariables> (the first <ScalarVariable> has value reference 0). Units follow the
 * variable's unit attribute in modelDescription.xml.
 */
#ifndef BACKLASH_FMU_MODEL_H
#define BACKLASH_FMU_MODEL_H

#include "fmi2Functions.h"

#define MAX_REALS 256
#define MAX_STATES 64
#define MESSAGE_SIZE 512

typedef struct {
    double r[MAX_REALS];      /* every real variable, by value reference */
    double x[MAX_STATES];     /* the model's own state (continuous and discrete), as it likes */
    double time;              /* current time [s] */
    int initialized;          /* set by the framework after model_initialize succeeded */
    char message[MESSAGE_SIZE]; /* why the last call failed (the framework logs it) */
    /* framework's own fields */
    const fmi2CallbackFunctions *callbacks;
    fmi2String instance_name;
} Instance;

/* Number of real variables (value references 0 .. model_n_reals() - 1); at most MAX_REALS. */
int model_n_reals(void);

/* Write every real's start value (as modelDescription.xml states it) into m->r. */
void model_start_values(Instance *m);

/* Set the initial state m->x from the parameters in m->r at time m->time (the experiment's start)
 * and compute the outputs at that instant. Return 0, or non-zero with m->message set
 * (e.g. an impossible parameter value). */
int model_initialize(Instance *m);

/* Advance the model from m->time to m->time + h [s] with the inputs in m->r held over the step,
 * integrating with the model's own internal step (a step of h is cut into sub-steps), then
 * write the outputs at the new time into m->r. The framework sets m->time after a success.
 * Return 0, or non-zero with m->message set (solver failure: non-finite state, no convergence). */
int model_do_step(Instance *m, double h);

/* Model exchange (optional). A model that also offers the FMI 2.0 model-exchange interface defines
 * both functions below; its continuous states are m->x[0 .. model_n_states() - 1], in the order of
 * modelDescription.xml's <Derivatives>. The framework declares them weak: a model that defines
 * neither is a co-simulation FMU only (fmi2Instantiate refuses fmi2ModelExchange). */

/* Number of continuous states (at most MAX_STATES). */
int model_n_states(void) __attribute__((weak));

/* The states' derivatives dx at m->x, m->time and the inputs in m->r, and the outputs at that point
 * written into m->r. Return 0, or non-zero with m->message set (an impossible parameter). */
int model_derivatives(Instance *m, double dx[]) __attribute__((weak));

/* Event indicators of a model-exchange model (optional; none if it defines neither): functions of
 * the states, time and inputs whose zero crossings are where its right-hand side has a kink or a
 * switch (a contact that opens, a stop that engages), so that the host's solver stops there rather
 * than stepping across it. Their number must equal modelDescription.xml's numberOfEventIndicators. */
int model_n_event_indicators(void) __attribute__((weak));

/* The event indicators z at m->x, m->time and the inputs in m->r. Return 0, or non-zero with
 * m->message set. */
int model_event_indicators(Instance *m, double z[]) __attribute__((weak));

#endif
