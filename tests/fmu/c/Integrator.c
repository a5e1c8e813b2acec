/*
 * Integrator: an FMI 3.0 co-simulation FMU written in C against the FMI 3.0 headers that the
 * `fmi-sys` crate ships (fmi-standard3/headers), built into a test's temp dir by `build_integrator`
 * (crates/tutti-test-support/src/fmu.rs).
 *
 *   y     += h * k * u      (Float64 output; u Float64 input, k Float64 tunable parameter)
 *   steps += 1              (Int32 output)
 *   rising = k * u > 0      (Boolean output)
 *
 * Only what a co-simulation importer calls is implemented, and the FMU state (get, set, free,
 * serialize, deserialize: a copy of the model's State); the other functions of the standard
 * are stubs (stubs.c).
 */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define TOKEN "{tutti-integrator-3}"

enum { VR_TIME = 0, VR_U = 1, VR_K = 2, VR_Y = 3, VR_STEPS = 4, VR_RISING = 5 };

/* Everything the model computes with: what an FMU state copies. */
typedef struct {
    fmi3Float64 time, u, k, y;
    fmi3Int32 steps;
    fmi3Boolean rising;
} State;

typedef struct {
    State s;
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
    m->s.k = 1.0;
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
    ((Model *)instance)->s.time = startTime;
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
        case VR_TIME: values[i] = m->s.time; break;
        case VR_U: values[i] = m->s.u; break;
        case VR_K: values[i] = m->s.k; break;
        case VR_Y: values[i] = m->s.y; break;
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
        case VR_U: m->s.u = values[i]; break;
        case VR_K: m->s.k = values[i]; break;
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
        values[i] = m->s.steps;
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
        values[i] = m->s.rising;
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
    m->s.y += communicationStepSize * m->s.k * m->s.u;
    m->s.steps += 1;
    m->s.rising = m->s.k * m->s.u > 0;
    m->s.time = currentCommunicationPoint + communicationStepSize;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = m->s.time;
    return fmi3OK;
}

/* The FMU state: a heap copy of State, serialized as a tag and its bytes (read back by this
 * same library only, as the standard allows). */
#define STATE_TAG 0x494e5431u /* "INT1" */

typedef struct {
    unsigned int tag;
    State s;
} Serialized;

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Model *m = instance;
    State *copy = *FMUState ? *FMUState : malloc(sizeof *copy);
    if (!copy) {
        say(m, fmi3Error, "fmi3GetFMUState: out of memory");
        return fmi3Error;
    }
    *copy = m->s;
    *FMUState = copy;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    Model *m = instance;
    if (!FMUState) {
        say(m, fmi3Error, "fmi3SetFMUState: no state");
        return fmi3Error;
    }
    m->s = *(const State *)FMUState;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)instance;
    if (FMUState) {
        free(*FMUState);
        *FMUState = NULL;
    }
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    (void)instance, (void)FMUState;
    *size = sizeof(Serialized);
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size)
{
    Model *m = instance;
    if (!FMUState || size != sizeof(Serialized)) {
        say(m, fmi3Error, "fmi3SerializeFMUState: no state, or not the size fmi3SerializedFMUStateSize gave");
        return fmi3Error;
    }
    Serialized out;
    memset(&out, 0, sizeof out); /* the padding too: the same state, the same bytes */
    out.tag = STATE_TAG;
    out.s = *(const State *)FMUState;
    memcpy(serializedState, &out, sizeof out);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState)
{
    Model *m = instance;
    Serialized in;
    if (size != sizeof in) {
        say(m, fmi3Error, "fmi3DeserializeFMUState: not an Integrator state (wrong size)");
        return fmi3Error;
    }
    memcpy(&in, serializedState, sizeof in);
    if (in.tag != STATE_TAG) {
        say(m, fmi3Error, "fmi3DeserializeFMUState: not an Integrator state (wrong tag)");
        return fmi3Error;
    }
    State *copy = malloc(sizeof *copy);
    if (!copy) {
        say(m, fmi3Error, "fmi3DeserializeFMUState: out of memory");
        return fmi3Error;
    }
    *copy = in.s;
    *FMUState = copy;
    return fmi3OK;
}
