/* FMI 3.0 co-simulation interface around a model (model.h).
 *
 * Every function of the FMI 3.0 API is exported (importers such as fmpy load them all);
 * what a co-simulation FMU of this kind does not support (model exchange, scheduled
 * execution, clocks, derivatives, non-Float64/Int32 variables) returns fmi3Error with a
 * logged reason.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "model.h"

enum { MODE_INSTANTIATED, MODE_INIT, MODE_STEP, MODE_TERMINATED, MODE_ERROR };

typedef struct {
    Model m;
    char name[128];
    int mode;
    int logging;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

static void logf3(Instance *s, fmi3Status status, const char *category, const char *fmt, ...) {
    if (!s || !s->log) return;
    if (status == fmi3OK && !s->logging) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof(buf), fmt, ap);
    va_end(ap);
    s->log(s->env, status, category, buf);
}

static fmi3Status unsupported(fmi3Instance instance, const char *what) {
    logf3((Instance *)instance, fmi3Error, "logStatusError", "%s is not supported by this co-simulation FMU", what);
    return fmi3Error;
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    (void)nCategories;
    (void)categories;
    if (!instance) return fmi3Error;
    ((Instance *)instance)->logging = loggingOn ? 1 : 0;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "model exchange is not supported");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)resourcePath, (void)visible, (void)earlyReturnAllowed, (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    if (!instantiationToken || strcmp(instantiationToken, INSTANTIATION_TOKEN) != 0) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "instantiation token does not match this binary (expected " INSTANTIATION_TOKEN ")");
        return NULL;
    }
    if (eventModeUsed) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "logStatusError", "event mode is not supported");
        return NULL;
    }
    Instance *s = (Instance *)calloc(1, sizeof(Instance));
    if (!s) return NULL;
    snprintf(s->name, sizeof(s->name), "%s", instanceName ? instanceName : MODEL_IDENTIFIER);
    s->env = instanceEnvironment;
    s->log = logMessage;
    s->logging = loggingOn ? 1 : 0;
    model_reset(&s->m);
    s->mode = MODE_INSTANTIATED;
    return s;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError", "scheduled execution is not supported");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    Instance *s = (Instance *)instance;
    if (!s || s->mode != MODE_INSTANTIATED) return fmi3Error;
    s->m.time = startTime;
    s->mode = MODE_INIT;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *s = (Instance *)instance;
    if (!s || s->mode != MODE_INIT) return fmi3Error;
    const char *problem = model_check(&s->m);
    if (problem) {
        logf3(s, fmi3Error, "logStatusError", "%s", problem);
        s->mode = MODE_ERROR;
        return fmi3Error;
    }
    model_start(&s->m);
    model_outputs(&s->m);
    s->mode = MODE_STEP;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return unsupported(instance, "event mode"); }

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *s = (Instance *)instance;
    if (!s) return fmi3Error;
    s->mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *s = (Instance *)instance;
    if (!s) return fmi3Error;
    model_reset(&s->m);
    s->mode = MODE_INSTANTIATED;
    return fmi3OK;
}

/* -- variable access -------------------------------------------------------------- */

static fmi3Status check_vrs(Instance *s, const fmi3ValueReference vr[], size_t nvr, size_t nValues, int type,
                            const char *tname) {
    if (!s) return fmi3Error;
    if (nValues != nvr) {
        logf3(s, fmi3Error, "logStatusError", "%s access: %zu values for %zu scalar variables", tname, nValues, nvr);
        return fmi3Error;
    }
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= N_VARS || VAR_TYPE[vr[i]] != type) {
            logf3(s, fmi3Error, "logStatusError", "value reference %u is not a %s variable", vr[i], tname);
            return fmi3Error;
        }
    }
    return fmi3OK;
}

static fmi3Status check_set(Instance *s, fmi3ValueReference vr) {
    int c = VAR_CAUSALITY[vr];
    int before_step = s->mode == MODE_INSTANTIATED || s->mode == MODE_INIT;
    if (c == CAUS_INPUT && s->mode != MODE_TERMINATED && s->mode != MODE_ERROR) return fmi3OK;
    if (c == CAUS_TUNABLE && s->mode != MODE_TERMINATED && s->mode != MODE_ERROR) return fmi3OK;
    if (c == CAUS_FIXED && before_step) return fmi3OK;
    logf3(s, fmi3Error, "logStatusError", "variable %s cannot be set now (causality/variability forbid it)",
          VAR_NAMES[vr]);
    return fmi3Error;
}

static void refresh(Instance *s) {
    if (s->mode == MODE_INIT || s->mode == MODE_INSTANTIATED) {
        model_start(&s->m);
        model_outputs(&s->m);
    }
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    Instance *s = (Instance *)instance;
    if (check_vrs(s, vr, nvr, nValues, TYPE_FLOAT64, "Float64") != fmi3OK) return fmi3Error;
    refresh(s);
    for (size_t i = 0; i < nvr; i++) values[i] = vr[i] == 0 ? s->m.time : s->m.v[vr[i]];
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    Instance *s = (Instance *)instance;
    if (check_vrs(s, vr, nvr, nValues, TYPE_FLOAT64, "Float64") != fmi3OK) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        if (check_set(s, vr[i]) != fmi3OK) return fmi3Error;
        if (!isfinite(values[i])) {
            logf3(s, fmi3Error, "logStatusError", "%s set to a non-finite value", VAR_NAMES[vr[i]]);
            return fmi3Error;
        }
        s->m.v[vr[i]] = values[i];
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues) {
    Instance *s = (Instance *)instance;
    if (check_vrs(s, vr, nvr, nValues, TYPE_INT32, "Int32") != fmi3OK) return fmi3Error;
    refresh(s);
    for (size_t i = 0; i < nvr; i++) values[i] = (fmi3Int32)s->m.v[vr[i]];
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
                        size_t nValues) {
    Instance *s = (Instance *)instance;
    if (check_vrs(s, vr, nvr, nValues, TYPE_INT32, "Int32") != fmi3OK) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        if (check_set(s, vr[i]) != fmi3OK) return fmi3Error;
        if (values[i] < VAR_MIN[vr[i]] || values[i] > VAR_MAX[vr[i]]) {
            logf3(s, fmi3Error, "logStatusError", "%s = %d is outside [%g, %g]", VAR_NAMES[vr[i]], (int)values[i],
                  VAR_MIN[vr[i]], VAR_MAX[vr[i]]);
            return fmi3Error;
        }
        s->m.v[vr[i]] = (double)values[i];
    }
    return fmi3OK;
}

#define NO_TYPE(T, CT)                                                                                            \
    fmi3Status fmi3Get##T(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, CT values[],         \
                          size_t nValues) {                                                                       \
        (void)vr, (void)nvr, (void)values, (void)nValues;                                                         \
        return unsupported(instance, "fmi3Get" #T " (the model has no " #T " variables)");                        \
    }                                                                                                             \
    fmi3Status fmi3Set##T(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const CT values[],   \
                          size_t nValues) {                                                                       \
        (void)vr, (void)nvr, (void)values, (void)nValues;                                                         \
        return unsupported(instance, "fmi3Set" #T " (the model has no " #T " variables)");                        \
    }

NO_TYPE(Float32, fmi3Float32)
NO_TYPE(Int8, fmi3Int8)
NO_TYPE(UInt8, fmi3UInt8)
NO_TYPE(Int16, fmi3Int16)
NO_TYPE(UInt16, fmi3UInt16)
NO_TYPE(UInt32, fmi3UInt32)
NO_TYPE(Int64, fmi3Int64)
NO_TYPE(UInt64, fmi3UInt64)
NO_TYPE(Boolean, fmi3Boolean)
NO_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)vr, (void)nvr, (void)valueSizes, (void)values, (void)nValues;
    return unsupported(instance, "fmi3GetBinary");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    (void)vr, (void)nvr, (void)valueSizes, (void)values, (void)nValues;
    return unsupported(instance, "fmi3SetBinary");
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    (void)vr, (void)nvr, (void)values;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    (void)vr, (void)nvr, (void)values;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    (void)vr, (void)n;
    return unsupported(instance, "variable dependencies");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents;
    (void)dependencyKinds, (void)nDependencies;
    return unsupported(instance, "variable dependencies");
}

/* -- FMU state ---------------------------------------------------------------------- */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *state) {
    Instance *s = (Instance *)instance;
    if (!s || !state) return fmi3Error;
    if (!*state) *state = malloc(sizeof(Instance));
    if (!*state) return fmi3Error;
    memcpy(*state, s, sizeof(Instance));
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState state) {
    Instance *s = (Instance *)instance;
    if (!s || !state) return fmi3Error;
    Instance *saved = (Instance *)state;
    s->m = saved->m;
    s->mode = saved->mode;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *state) {
    (void)instance;
    if (state) {
        free(*state);
        *state = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState state, size_t *size) {
    (void)instance, (void)state;
    *size = sizeof(Model) + sizeof(int);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState state, fmi3Byte serializedState[],
                                 size_t size) {
    (void)instance;
    Instance *saved = (Instance *)state;
    if (!saved || size != sizeof(Model) + sizeof(int)) return fmi3Error;
    memcpy(serializedState, &saved->m, sizeof(Model));
    memcpy(serializedState + sizeof(Model), &saved->mode, sizeof(int));
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *state) {
    Instance *s = (Instance *)instance;
    if (!s || size != sizeof(Model) + sizeof(int)) return fmi3Error;
    if (!*state) *state = malloc(sizeof(Instance));
    if (!*state) return fmi3Error;
    memcpy(*state, s, sizeof(Instance));
    memcpy(&((Instance *)*state)->m, serializedState, sizeof(Model));
    memcpy(&((Instance *)*state)->mode, serializedState + sizeof(Model), sizeof(int));
    return fmi3OK;
}

/* -- derivatives, configuration, clocks: not supported ------------------------------ */

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "directional derivatives");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed, (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "adjoint derivatives");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { return unsupported(instance, "configuration mode"); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { return unsupported(instance, "configuration mode"); }

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)nvr, (void)intervals, (void)qualifiers;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions, (void)qualifiers;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr, (void)nvr, (void)shifts;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr, (void)nvr, (void)intervals;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr, (void)nvr, (void)shifts;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr, (void)nvr, (void)counters, (void)resolutions;
    return unsupported(instance, "clocks");
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { return unsupported(instance, "event mode"); }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime) {
    (void)discreteStatesNeedUpdate, (void)terminateSimulation, (void)nominalsOfContinuousStatesChanged;
    (void)valuesOfContinuousStatesChanged, (void)nextEventTimeDefined, (void)nextEventTime;
    return unsupported(instance, "event mode");
}

/* -- model exchange: not supported --------------------------------------------------- */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { return unsupported(instance, "model exchange"); }

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    (void)time;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    (void)derivatives, (void)nContinuousStates;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    (void)eventIndicators, (void)nEventIndicators;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    (void)continuousStates, (void)nContinuousStates;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates) {
    (void)nominals, (void)nContinuousStates;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    (void)nEventIndicators;
    return unsupported(instance, "model exchange");
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    (void)nContinuousStates;
    return unsupported(instance, "model exchange");
}

/* -- co-simulation -------------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    Instance *s = (Instance *)instance;
    return s && s->mode == MODE_STEP ? fmi3OK : fmi3Error;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr, (void)nvr, (void)orders, (void)values, (void)nValues;
    return unsupported(instance, "output derivatives");
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    Instance *s = (Instance *)instance;
    if (!s) return fmi3Error;
    if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation) *terminateSimulation = fmi3False;
    if (earlyReturn) *earlyReturn = fmi3False;
    if (s->mode != MODE_STEP) {
        logf3(s, fmi3Error, "logStatusError", "fmi3DoStep called outside step mode");
        return fmi3Error;
    }
    if (!(communicationStepSize > 0.0) || !isfinite(currentCommunicationPoint)) {
        logf3(s, fmi3Error, "logStatusError", "communication step size must be positive, found %g",
              communicationStepSize);
        return fmi3Error;
    }
    s->m.time = currentCommunicationPoint;
    if (model_advance(&s->m, communicationStepSize) != 0) {
        logf3(s, fmi3Error, "logStatusError", "%s", s->m.msg);
        s->mode = MODE_ERROR;
        if (terminateSimulation) *terminateSimulation = fmi3True;
        if (lastSuccessfulTime) *lastSuccessfulTime = currentCommunicationPoint;
        return fmi3Error;
    }
    if (lastSuccessfulTime) *lastSuccessfulTime = s->m.time;
    return fmi3OK;
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference, (void)activationTime;
    return unsupported(instance, "scheduled execution");
}
