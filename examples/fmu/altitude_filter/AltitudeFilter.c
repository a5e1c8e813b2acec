/*
 * AltitudeFilter: the FMI 3.0 co-simulation FMU of the UAV demo (docs/uav-demo.md), built from
 * this source by `tutti-demo uav` and run as a participant with `tutti fmu run`.
 *
 * Input `elevation` (m, UAV 1's elevation as the framework read it); parameter `tau` (s).
 * Outputs: `altitude`, the elevation through a first-order filter with time constant tau,
 * started at the elevation of the first step; `climb_rate` (m/s), the filtered altitude's
 * rate; `steps`, the steps made.
 *
 * Self-contained: the few FMI 3.0 types it uses are declared here with the ABI of the
 * standard's fmi3PlatformTypes.h, so that building it needs only a C compiler.
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef void *fmi3Instance;
typedef void *fmi3InstanceEnvironment;
typedef uint32_t fmi3ValueReference;
typedef double fmi3Float64;
typedef int32_t fmi3Int32;
typedef bool fmi3Boolean;
typedef const char *fmi3String;
typedef enum { fmi3OK, fmi3Warning, fmi3Discard, fmi3Error, fmi3Fatal } fmi3Status;
typedef void (*fmi3LogMessageCallback)(fmi3InstanceEnvironment, fmi3Status, fmi3String, fmi3String);

#define EXPORT __attribute__((visibility("default")))
#define TOKEN "{tutti-uav-altitude-filter-1}"

enum { VR_ELEVATION = 1, VR_TAU = 2, VR_ALTITUDE = 3, VR_CLIMB = 4, VR_STEPS = 5 };

typedef struct {
    double time, elevation, tau, altitude, climb;
    int32_t steps;
    bool started;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Filter;

static fmi3Status fail(Filter *f, const char *message)
{
    if (f->log)
        f->log(f->env, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

EXPORT const char *fmi3GetVersion(void) { return "3.0"; }

EXPORT fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
                                                fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                                fmi3Boolean earlyReturnAllowed, const fmi3ValueReference *required,
                                                size_t nRequired, fmi3InstanceEnvironment env,
                                                fmi3LogMessageCallback log, void *intermediateUpdate)
{
    (void)name, (void)resources, (void)visible, (void)loggingOn, (void)earlyReturnAllowed, (void)required;
    (void)nRequired, (void)intermediateUpdate;
    if (!token || strcmp(token, TOKEN) != 0 || eventModeUsed)
        return NULL;
    Filter *f = calloc(1, sizeof *f);
    if (f) {
        f->tau = 2.0;
        f->env = env;
        f->log = log;
    }
    return f;
}

EXPORT void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

EXPORT fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                              fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    ((Filter *)instance)->time = startTime;
    return fmi3OK;
}

EXPORT fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Filter *f = instance;
    if (f->tau <= 0)
        return fail(f, "tau must be positive");
    return fmi3OK;
}

EXPORT fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

EXPORT fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 v[],
                                 size_t nv)
{
    Filter *f = instance;
    for (size_t i = 0; i < nvr && i < nv; i++) {
        switch (vr[i]) {
        case VR_ELEVATION: v[i] = f->elevation; break;
        case VR_TAU: v[i] = f->tau; break;
        case VR_ALTITUDE: v[i] = f->altitude; break;
        case VR_CLIMB: v[i] = f->climb; break;
        default: return fail(f, "fmi3GetFloat64: unknown value reference");
        }
    }
    return fmi3OK;
}

EXPORT fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                 const fmi3Float64 v[], size_t nv)
{
    Filter *f = instance;
    for (size_t i = 0; i < nvr && i < nv; i++) {
        switch (vr[i]) {
        case VR_ELEVATION:
            f->elevation = v[i];
            if (!f->started) {
                /* The filter starts where the UAV is. */
                f->altitude = v[i];
                f->started = true;
            }
            break;
        case VR_TAU: f->tau = v[i]; break;
        default: return fail(f, "fmi3SetFloat64: not an input or parameter");
        }
    }
    return fmi3OK;
}

EXPORT fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 v[],
                               size_t nv)
{
    Filter *f = instance;
    for (size_t i = 0; i < nvr && i < nv; i++) {
        if (vr[i] != VR_STEPS)
            return fail(f, "fmi3GetInt32: unknown value reference");
        v[i] = f->steps;
    }
    return fmi3OK;
}

EXPORT fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 v[],
                               size_t nv)
{
    (void)vr, (void)nvr, (void)v, (void)nv;
    return fail(instance, "fmi3SetInt32: steps is an output");
}

EXPORT fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior,
                             fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminate, fmi3Boolean *earlyReturn,
                             fmi3Float64 *lastSuccessfulTime)
{
    Filter *f = instance;
    (void)noSetPrior;
    if (h <= 0)
        return fail(f, "fmi3DoStep: the step size must be positive");
    double a = h / f->tau;
    if (a > 1.0)
        a = 1.0; /* a step longer than tau: follow the input at once */
    double before = f->altitude;
    f->altitude += a * (f->elevation - f->altitude);
    f->climb = (f->altitude - before) / h;
    f->steps += 1;
    f->time = t + h;
    *eventHandlingNeeded = false;
    *terminate = false;
    *earlyReturn = false;
    *lastSuccessfulTime = f->time;
    return fmi3OK;
}
