/*
 * Integrator: an FMI 3.0 co-simulation FMU written in C against the FMI 3.0 headers that the
 * `fmi-sys` crate ships (fmi-standard3/headers), built by tests/fmu_fmi3.rs into its temp dir.
 *
 *   y     += h * k * u      (Float64 output; u Float64 input, k Float64 tunable parameter)
 *   steps += 1              (Int32 output)
 *   rising = k * u > 0      (Boolean output)
 *
 * Only what a co-simulation importer calls is implemented; the other functions of the
 * standard are absent, which the importer must tolerate.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define TOKEN "{tutti-integrator-3}"

enum { VR_TIME = 0, VR_U = 1, VR_K = 2, VR_Y = 3, VR_STEPS = 4, VR_RISING = 5 };

typedef struct {
    fmi3Float64 time, u, k, y;
    fmi3Int32 steps;
    fmi3Boolean rising;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    char *name;
} Model;

static void say(Model *m, fmi3Status status, const char *message)
{
    if (m->log)
        m->log(m->env, status, status == fmi3OK ? "logAll" : "logStatusError", message);
}

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)resourcePath, (void)visible, (void)loggingOn, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)nRequiredIntermediateVariables, (void)intermediateUpdate;
    if (!instantiationToken || strcmp(instantiationToken, TOKEN) != 0 || eventModeUsed)
        return NULL;
    Model *m = calloc(1, sizeof *m);
    if (!m)
        return NULL;
    m->k = 1.0;
    m->env = instanceEnvironment;
    m->log = logMessage;
    m->name = strdup(instanceName ? instanceName : "");
    return m;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    Model *m = instance;
    if (m) {
        free(m->name);
        free(m);
    }
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    ((Model *)instance)->time = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance instance) { (void)instance; return fmi3Error; }

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues)
{
    Model *m = instance;
    if (nValues < nvr)
        return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        switch (vr[i]) {
        case VR_TIME: values[i] = m->time; break;
        case VR_U: values[i] = m->u; break;
        case VR_K: values[i] = m->k; break;
        case VR_Y: values[i] = m->y; break;
        default: say(m, fmi3Error, "fmi3GetFloat64: not a Float64 variable"); return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues)
{
    Model *m = instance;
    if (nValues < nvr)
        return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        switch (vr[i]) {
        case VR_U: m->u = values[i]; break;
        case VR_K: m->k = values[i]; break;
        default: say(m, fmi3Error, "fmi3SetFloat64: not a settable Float64 variable"); return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues)
{
    Model *m = instance;
    if (nValues < nvr)
        return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_STEPS)
            return fmi3Error;
        values[i] = m->steps;
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues)
{
    Model *m = instance;
    if (nValues < nvr)
        return fmi3Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] != VR_RISING)
            return fmi3Error;
        values[i] = m->rising;
    }
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Model *m = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (communicationStepSize <= 0) {
        say(m, fmi3Error, "fmi3DoStep: the step size must be positive");
        return fmi3Error;
    }
    m->y += communicationStepSize * m->k * m->u;
    m->steps += 1;
    m->rising = m->k * m->u > 0;
    m->time = currentCommunicationPoint + communicationStepSize;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = m->time;
    return fmi3OK;
}
