/* FMI 2.0 co-simulation interface around a model (model.h).
 *
 * Every FMI 2.0 function is exported; model exchange, asynchronous steps, derivatives and
 * Boolean/String variables return fmi2Error with a logged reason. Real variables map to
 * the model's Float64 variables, Integer to its Int32 variables.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "model.h"

enum { MODE_INSTANTIATED, MODE_INIT, MODE_STEP, MODE_TERMINATED, MODE_ERROR };

typedef struct {
    Model m;
    char name[128];
    int mode;
    int logging;
    fmi2CallbackLogger log;
    fmi2ComponentEnvironment env;
} Instance;

static void logf2(Instance *s, fmi2Status status, const char *category, const char *fmt, ...) {
    if (!s || !s->log) return;
    if (status == fmi2OK && !s->logging) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    s->log(s->env, s->name, status, category, "%s", buf);
}

static fmi2Status unsupported(fmi2Component c, const char *what) {
    logf2((Instance *)c, fmi2Error, "logStatusError", "%s is not supported by this co-simulation FMU", what);
    return fmi2Error;
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories, (void)categories;
    if (!c) return fmi2Error;
    ((Instance *)c)->logging = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)fmuResourceLocation, (void)visible;
    fmi2CallbackLogger log = functions ? functions->logger : NULL;
    fmi2ComponentEnvironment env = functions ? functions->componentEnvironment : NULL;
    const char *name = instanceName ? instanceName : MODEL_IDENTIFIER;
    if (fmuType != fmi2CoSimulation) {
        if (log) log(env, name, fmi2Error, "logStatusError", "only co-simulation is supported");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, INSTANTIATION_TOKEN) != 0) {
        if (log) log(env, name, fmi2Error, "logStatusError", "GUID does not match this binary (expected %s)",
                     INSTANTIATION_TOKEN);
        return NULL;
    }
    Instance *s = (Instance *)calloc(1, sizeof(Instance));
    if (!s) return NULL;
    snprintf(s->name, sizeof(s->name), "%s", name);
    s->log = log;
    s->env = env;
    s->logging = loggingOn ? 1 : 0;
    model_reset(&s->m);
    s->mode = MODE_INSTANTIATED;
    return s;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    Instance *s = (Instance *)c;
    if (!s || s->mode != MODE_INSTANTIATED) return fmi2Error;
    s->m.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!s || s->mode != MODE_INSTANTIATED) return fmi2Error;
    s->mode = MODE_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!s || s->mode != MODE_INIT) return fmi2Error;
    const char *problem = model_check(&s->m);
    if (problem) {
        logf2(s, fmi2Error, "logStatusError", "%s", problem);
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    model_start(&s->m);
    model_outputs(&s->m);
    s->mode = MODE_STEP;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!s) return fmi2Error;
    s->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *s = (Instance *)c;
    if (!s) return fmi2Error;
    model_reset(&s->m);
    s->mode = MODE_INSTANTIATED;
    return fmi2OK;
}

/* -- variable access -------------------------------------------------------------- */

static fmi2Status check_vrs(Instance *s, const fmi2ValueReference vr[], size_t nvr, int type, const char *tname) {
    if (!s) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARS || VAR_TYPE[vr[i]] != type) {
            logf2(s, fmi2Error, "logStatusError", "value reference %u is not a %s variable", vr[i], tname);
            return fmi2Error;
        }
    }
    return fmi2OK;
}

static fmi2Status check_set(Instance *s, fmi2ValueReference vr) {
    int c = VAR_CAUSALITY[vr];
    int before_step = s->mode == MODE_INSTANTIATED || s->mode == MODE_INIT;
    if ((c == CAUS_INPUT || c == CAUS_TUNABLE) && s->mode != MODE_TERMINATED && s->mode != MODE_ERROR) return fmi2OK;
    if (c == CAUS_FIXED && before_step) return fmi2OK;
    logf2(s, fmi2Error, "logStatusError", "variable %s cannot be set now (causality/variability forbid it)",
          VAR_NAMES[vr]);
    return fmi2Error;
}

static void refresh(Instance *s) {
    if (s->mode == MODE_INIT || s->mode == MODE_INSTANTIATED) {
        model_start(&s->m);
        model_outputs(&s->m);
    }
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *s = (Instance *)c;
    if (check_vrs(s, vr, nvr, TYPE_FLOAT64, "Real") != fmi2OK) return fmi2Error;
    refresh(s);
    for (size_t i = 0; i < nvr; i++) value[i] = vr[i] == 0 ? s->m.time : s->m.v[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Instance *s = (Instance *)c;
    if (check_vrs(s, vr, nvr, TYPE_INT32, "Integer") != fmi2OK) return fmi2Error;
    refresh(s);
    for (size_t i = 0; i < nvr; i++) value[i] = (fmi2Integer)s->m.v[vr[i]];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr, (void)nvr, (void)value;
    return unsupported(c, "Boolean variables");
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr, (void)nvr, (void)value;
    return unsupported(c, "String variables");
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *s = (Instance *)c;
    if (check_vrs(s, vr, nvr, TYPE_FLOAT64, "Real") != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (check_set(s, vr[i]) != fmi2OK) return fmi2Error;
        if (!isfinite(value[i])) {
            logf2(s, fmi2Error, "logStatusError", "%s set to a non-finite value", VAR_NAMES[vr[i]]);
            return fmi2Error;
        }
        s->m.v[vr[i]] = value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    Instance *s = (Instance *)c;
    if (check_vrs(s, vr, nvr, TYPE_INT32, "Integer") != fmi2OK) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (check_set(s, vr[i]) != fmi2OK) return fmi2Error;
        if (value[i] < VAR_MIN[vr[i]] || value[i] > VAR_MAX[vr[i]]) {
            logf2(s, fmi2Error, "logStatusError", "%s = %d is outside [%g, %g]", VAR_NAMES[vr[i]], (int)value[i],
                  VAR_MIN[vr[i]], VAR_MAX[vr[i]]);
            return fmi2Error;
        }
        s->m.v[vr[i]] = (double)value[i];
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr, (void)nvr, (void)value;
    return unsupported(c, "Boolean variables");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr, (void)nvr, (void)value;
    return unsupported(c, "String variables");
}

/* -- FMU state ---------------------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *state) {
    Instance *s = (Instance *)c;
    if (!s || !state) return fmi2Error;
    if (!*state) *state = malloc(sizeof(Instance));
    if (!*state) return fmi2Error;
    memcpy(*state, s, sizeof(Instance));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) {
    Instance *s = (Instance *)c;
    if (!s || !state) return fmi2Error;
    s->m = ((Instance *)state)->m;
    s->mode = ((Instance *)state)->mode;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *state) {
    (void)c;
    if (state) {
        free(*state);
        *state = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate state, size_t *size) {
    (void)c, (void)state;
    *size = sizeof(Model) + sizeof(int);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate state, fmi2Byte serializedState[], size_t size) {
    (void)c;
    Instance *saved = (Instance *)state;
    if (!saved || size != sizeof(Model) + sizeof(int)) return fmi2Error;
    memcpy(serializedState, &saved->m, sizeof(Model));
    memcpy(serializedState + sizeof(Model), &saved->mode, sizeof(int));
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *state) {
    Instance *s = (Instance *)c;
    if (!s || size != sizeof(Model) + sizeof(int)) return fmi2Error;
    if (!*state) *state = malloc(sizeof(Instance));
    if (!*state) return fmi2Error;
    memcpy(*state, s, sizeof(Instance));
    memcpy(&((Instance *)*state)->m, serializedState, sizeof(Model));
    memcpy(&((Instance *)*state)->mode, serializedState + sizeof(Model), sizeof(int));
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return unsupported(c, "directional derivatives");
}

/* -- model exchange: not supported --------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) { return unsupported(c, "model exchange"); }

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *fmi2eventInfo) {
    (void)fmi2eventInfo;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return unsupported(c, "model exchange"); }

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    (void)time;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    (void)x, (void)nx;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    (void)derivatives, (void)nx;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    (void)eventIndicators, (void)ni;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    (void)x, (void)nx;
    return unsupported(c, "model exchange");
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    (void)x_nominal, (void)nx;
    return unsupported(c, "model exchange");
}

/* -- co-simulation -------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "input derivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "output derivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentCommunicationPoint) {
    (void)noSetFMUStatePriorToCurrentCommunicationPoint;
    Instance *s = (Instance *)c;
    if (!s) return fmi2Error;
    if (s->mode != MODE_STEP) {
        logf2(s, fmi2Error, "logStatusError", "fmi2DoStep called outside step mode");
        return fmi2Error;
    }
    if (!(communicationStepSize > 0.0) || !isfinite(currentCommunicationPoint)) {
        logf2(s, fmi2Error, "logStatusError", "communication step size must be positive, found %g",
              communicationStepSize);
        return fmi2Error;
    }
    s->m.time = currentCommunicationPoint;
    if (model_advance(&s->m, communicationStepSize) != 0) {
        logf2(s, fmi2Error, "logStatusError", "%s", s->m.msg);
        s->mode = MODE_ERROR;
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "asynchronous steps"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    return unsupported(c, "asynchronous steps");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    Instance *inst = (Instance *)c;
    if (inst && s == fmi2LastSuccessfulTime && value) {
        *value = inst->m.time;
        return fmi2OK;
    }
    return unsupported(c, "this status kind");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    return unsupported(c, "asynchronous steps");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *inst = (Instance *)c;
    if (inst && s == fmi2Terminated && value) {
        *value = inst->mode == MODE_ERROR ? fmi2True : fmi2False;
        return fmi2OK;
    }
    return unsupported(c, "this status kind");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    return unsupported(c, "asynchronous steps");
}
