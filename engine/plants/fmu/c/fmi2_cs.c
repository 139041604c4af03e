/*
 * The project's FMI 2.0 co-simulation framework: every function of fmi2Functions.h around one
 * model of the contract in model.h (model_n_reals, model_start_values, model_initialize,
 * model_do_step), and the model-exchange interface around a model that also defines
 * model_n_states and model_derivatives (model.h), with event indicators where it also defines
 * model_n_event_indicators and model_event_indicators. Reals only; no integers, booleans or strings;
 * no FMU state, no directional derivatives (those calls return fmi2Error with a message); no discrete
 * states (an event changes nothing: the indicators only make the host's solver stop at a kink).
 *
 * States of an instance: instantiated -> (fmi2SetupExperiment) -> initialization mode
 * (fmi2EnterInitializationMode; parameters and inputs may be set) -> stepping
 * (fmi2ExitInitializationMode calls model_initialize) -> fmi2Reset goes back to instantiated.
 * A failed step (model_do_step non-zero) leaves the instance in error: every later step fails
 * until fmi2Reset.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>

#include "model.h"

typedef struct {
    Instance m;
    int in_init;  /* between fmi2EnterInitializationMode and fmi2ExitInitializationMode */
    int failed;   /* a step failed: only fmi2Reset and fmi2FreeInstance are allowed */
    int exchange; /* instantiated as fmi2ModelExchange */
    double start_time;
    char name[128]; /* the instance's name, copied: the host's string need not outlive fmi2Instantiate */
} Component;

static void fail(Component *c, const char *message) {
    if (message && message != c->m.message) {
        strncpy(c->m.message, message, MESSAGE_SIZE - 1);
        c->m.message[MESSAGE_SIZE - 1] = '\0';
    }
    if (c->m.callbacks && c->m.callbacks->logger) {
        c->m.callbacks->logger(c->m.callbacks->componentEnvironment, c->m.instance_name, fmi2Error, "logError",
                               "%s", c->m.message);
    }
    /* "%s" with the message as its argument: a logger that formats (printf-style, or FMPy's proxy) prints
     * the message; one that does not sees "%s" only, which is why FmuModel puts FMPy's proxy in front. */
}

static fmi2Status unsupported(fmi2Component comp, const char *what) {
    Component *c = (Component *)comp;
    if (c) {
        snprintf(c->m.message, MESSAGE_SIZE, "%s is not supported by this FMU", what);
        fail(c, NULL);
    }
    return fmi2Error;
}

static void start(Component *c) {
    memset(c->m.r, 0, sizeof(c->m.r));
    memset(c->m.x, 0, sizeof(c->m.x));
    c->m.time = 0.0;
    c->m.initialized = 0;
    c->m.message[0] = '\0';
    c->in_init = 0;
    c->failed = 0;
    c->start_time = 0.0;
    model_start_values(&c->m);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)c; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuGUID; (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    int exchange = fmuType == fmi2ModelExchange;
    if (!exchange && fmuType != fmi2CoSimulation) return NULL;
    if (exchange && !(model_n_states && model_derivatives && model_n_states() <= MAX_STATES)) return NULL;
    if (model_n_reals() > MAX_REALS) return NULL;
    Component *c = (Component *)calloc(1, sizeof(Component));
    if (!c) return NULL;
    c->m.callbacks = functions;
    snprintf(c->name, sizeof c->name, "%s", instanceName ? instanceName : "");
    c->m.instance_name = c->name;
    c->exchange = exchange;
    start(c);
    return (fmi2Component)c;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    Component *c = (Component *)comp;
    if (!c) return fmi2Error;
    c->start_time = startTime;
    c->m.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp) {
    Component *c = (Component *)comp;
    if (!c) return fmi2Error;
    c->in_init = 1;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp) {
    Component *c = (Component *)comp;
    if (!c) return fmi2Error;
    c->in_init = 0;
    c->m.time = c->start_time;
    c->m.message[0] = '\0';
    if (model_initialize(&c->m) != 0) {
        c->failed = 1;
        fail(c, NULL);
        return fmi2Error;
    }
    c->m.initialized = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { return c ? fmi2OK : fmi2Error; }

fmi2Status fmi2Reset(fmi2Component comp) {
    Component *c = (Component *)comp;
    if (!c) return fmi2Error;
    start(c);
    return fmi2OK;
}

static int bad_vr(Component *c, const fmi2ValueReference vr[], size_t nvr) {
    int n = model_n_reals();
    for (size_t i = 0; i < nvr; i++) {
        if ((int)vr[i] >= n) {
            snprintf(c->m.message, MESSAGE_SIZE, "value reference %u is not a real of this FMU (0 to %d)",
                     (unsigned)vr[i], n - 1);
            fail(c, NULL);
            return 1;
        }
    }
    return 0;
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Component *c = (Component *)comp;
    if (!c || bad_vr(c, vr, nvr)) return fmi2Error;
    if (c->exchange && c->m.initialized && !c->failed) { /* the outputs at the states and time set last */
        double dx[MAX_STATES];
        if (model_derivatives(&c->m, dx) != 0) {
            c->failed = 1;
            fail(c, NULL);
            return fmi2Error;
        }
    }
    for (size_t i = 0; i < nvr; i++) value[i] = c->m.r[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Component *c = (Component *)comp;
    if (!c || bad_vr(c, vr, nvr)) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (!isfinite(value[i])) {
            snprintf(c->m.message, MESSAGE_SIZE, "value reference %u set to a non-finite value", (unsigned)vr[i]);
            fail(c, NULL);
            return fmi2Error;
        }
        c->m.r[vr[i]] = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)vr; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2GetInteger (the FMU has reals only)");
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2GetBoolean (the FMU has reals only)");
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2GetString (the FMU has reals only)");
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2SetInteger (the FMU has reals only)");
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2SetBoolean (the FMU has reals only)");
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2SetString (the FMU has reals only)");
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2GetFMUstate"); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return unsupported(c, "fmi2SetFMUstate"); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return unsupported(c, "fmi2FreeFMUstate"); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size) {
    (void)s; (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t size) {
    (void)s; (void)b; (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t size, fmi2FMUstate *s) {
    (void)b; (void)size; (void)s;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference k[], size_t nk, const fmi2Real dk[],
                                        fmi2Real du[]) {
    (void)u; (void)nu; (void)k; (void)nk; (void)dk; (void)du;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

/* model exchange: around model_n_states and model_derivatives (refused where the model has neither) */
static int me_ready(Component *c, const char *what) {
    if (!c) return 0;
    if (!c->exchange) {
        snprintf(c->m.message, MESSAGE_SIZE, "%s: the instance is not a model-exchange instance", what);
        fail(c, NULL);
        return 0;
    }
    if (c->failed) {
        fail(c, "an earlier call failed: reset the FMU (fmi2Reset) first");
        return 0;
    }
    return 1;
}
static int me_size(Component *c, size_t n, const char *what) {
    if (n != (size_t)model_n_states()) {
        snprintf(c->m.message, MESSAGE_SIZE, "%s: %u states given, the model has %d", what, (unsigned)n,
                 model_n_states());
        fail(c, NULL);
        return 0;
    }
    return 1;
}
fmi2Status fmi2EnterEventMode(fmi2Component c) { return me_ready((Component *)c, "fmi2EnterEventMode") ? fmi2OK : fmi2Error; }
fmi2Status fmi2NewDiscreteStates(fmi2Component comp, fmi2EventInfo *e) {
    if (!me_ready((Component *)comp, "fmi2NewDiscreteStates") || !e) return fmi2Error;
    e->newDiscreteStatesNeeded = fmi2False;
    e->terminateSimulation = fmi2False;
    e->nominalsOfContinuousStatesChanged = fmi2False;
    e->valuesOfContinuousStatesChanged = fmi2False;
    e->nextEventTimeDefined = fmi2False;
    e->nextEventTime = 0.0;
    return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    return me_ready((Component *)c, "fmi2EnterContinuousTimeMode") ? fmi2OK : fmi2Error;
}
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean n, fmi2Boolean *e, fmi2Boolean *t) {
    (void)n;
    if (!me_ready((Component *)c, "fmi2CompletedIntegratorStep")) return fmi2Error;
    if (e) *e = fmi2False;
    if (t) *t = fmi2False;
    return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component comp, fmi2Real t) {
    Component *c = (Component *)comp;
    if (!me_ready(c, "fmi2SetTime")) return fmi2Error;
    if (!isfinite(t)) {
        fail(c, "fmi2SetTime: the time must be finite");
        return fmi2Error;
    }
    c->m.time = t;
    return fmi2OK;
}
fmi2Status fmi2SetContinuousStates(fmi2Component comp, const fmi2Real x[], size_t nx) {
    Component *c = (Component *)comp;
    if (!me_ready(c, "fmi2SetContinuousStates") || !me_size(c, nx, "fmi2SetContinuousStates")) return fmi2Error;
    for (size_t i = 0; i < nx; i++) {
        if (!isfinite(x[i])) {
            snprintf(c->m.message, MESSAGE_SIZE, "fmi2SetContinuousStates: state %u is not finite (%g): the "
                     "solver diverged; check the parameters", (unsigned)i, x[i]);
            c->failed = 1;
            fail(c, NULL);
            return fmi2Error;
        }
        c->m.x[i] = x[i];
    }
    return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component comp, fmi2Real d[], size_t nx) {
    Component *c = (Component *)comp;
    if (!me_ready(c, "fmi2GetDerivatives") || !me_size(c, nx, "fmi2GetDerivatives")) return fmi2Error;
    if (!c->m.initialized) {
        fail(c, "fmi2GetDerivatives before fmi2ExitInitializationMode");
        return fmi2Error;
    }
    double dx[MAX_STATES];
    if (model_derivatives(&c->m, dx) != 0) {
        c->failed = 1;
        fail(c, NULL);
        return fmi2Error;
    }
    for (size_t i = 0; i < nx; i++) d[i] = dx[i];
    return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component comp, fmi2Real z[], size_t ni) {
    Component *c = (Component *)comp;
    if (!me_ready(c, "fmi2GetEventIndicators")) return fmi2Error;
    int nz = model_n_event_indicators ? model_n_event_indicators() : 0;
    if (ni != (size_t)nz) {
        snprintf(c->m.message, MESSAGE_SIZE, "fmi2GetEventIndicators: %u indicators asked, the model has %d",
                 (unsigned)ni, nz);
        fail(c, NULL);
        return fmi2Error;
    }
    if (ni == 0) return fmi2OK;
    if (!model_event_indicators || !c->m.initialized) {
        fail(c, "fmi2GetEventIndicators before fmi2ExitInitializationMode");
        return fmi2Error;
    }
    if (model_event_indicators(&c->m, z) != 0) {
        c->failed = 1;
        fail(c, NULL);
        return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2GetContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx) {
    Component *c = (Component *)comp;
    if (!me_ready(c, "fmi2GetContinuousStates") || !me_size(c, nx, "fmi2GetContinuousStates")) return fmi2Error;
    for (size_t i = 0; i < nx; i++) x[i] = c->m.x[i];
    return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component comp, fmi2Real x[], size_t nx) {
    Component *c = (Component *)comp;
    if (!me_ready(c, "fmi2GetNominalsOfContinuousStates") || !me_size(c, nx, "fmi2GetNominalsOfContinuousStates"))
        return fmi2Error;
    for (size_t i = 0; i < nx; i++) x[i] = 1.0;
    return fmi2OK;
}
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr; (void)order; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2SetRealInputDerivatives (inputs are held over a step)");
}
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr; (void)order; (void)value;
    return nvr == 0 ? fmi2OK : unsupported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    Component *c = (Component *)comp;
    if (!c) return fmi2Error;
    if (c->exchange) {
        fail(c, "fmi2DoStep on a model-exchange instance: instantiate it as fmi2CoSimulation to step it");
        return fmi2Error;
    }
    if (c->failed) {
        fail(c, "an earlier step failed: reset the FMU (fmi2Reset) before stepping again");
        return fmi2Error;
    }
    if (!c->m.initialized) {
        fail(c, "fmi2DoStep before fmi2ExitInitializationMode");
        return fmi2Error;
    }
    if (!(communicationStepSize > 0.0) || !isfinite(communicationStepSize)) {
        snprintf(c->m.message, MESSAGE_SIZE, "communication step %g s must be positive and finite",
                 communicationStepSize);
        fail(c, NULL);
        return fmi2Error;
    }
    double tol = 1e-9 * fmax(1.0, fabs(c->m.time));
    if (fabs(currentCommunicationPoint - c->m.time) > tol) {
        snprintf(c->m.message, MESSAGE_SIZE, "fmi2DoStep from t = %.12g s while the FMU is at t = %.12g s",
                 currentCommunicationPoint, c->m.time);
        fail(c, NULL);
        return fmi2Error;
    }
    c->m.message[0] = '\0';
    if (model_do_step(&c->m, communicationStepSize) != 0) {
        c->failed = 1;
        fail(c, NULL);
        return fmi2Error;
    }
    c->m.time = currentCommunicationPoint + communicationStepSize;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep (steps are synchronous)"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetStatus (steps are synchronous)");
}
fmi2Status fmi2GetRealStatus(fmi2Component comp, const fmi2StatusKind s, fmi2Real *value) {
    Component *c = (Component *)comp;
    if (c && s == fmi2LastSuccessfulTime) {
        *value = c->m.time;
        return fmi2OK;
    }
    return unsupported(comp, "fmi2GetRealStatus of this kind");
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetBooleanStatus");
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s; (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}
