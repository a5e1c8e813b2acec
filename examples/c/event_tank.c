/*
 * event_tank: the components of the event-driven example (examples/event/tank.json5,
 * docs/timing.md). One domain, `tank`, in which each component runs only when it needs to:
 *
 *   event_tank plant       due at every step (it says nothing): integrates the level from
 *                          the valve and writes it
 *   event_tank supervisor  due every 100 ms of simulated time (RTSetPeriod): opens the valve
 *                          below 0.5 m and closes it above 1.5 m
 *   event_tank alarm       due whenever an item it reads changes (RTSetWakeOnChange): it
 *                          reads the valve only, so the level changing at every step does
 *                          not wake it
 *   event_tank logger      due at the times it asks for (RTRequestTime): every 250 ms
 *
 * Each prints a line at every step it runs, with the simulated time (RTGetSimulationTime);
 * all end when the framework stops. In a lock-step domain the same program runs at every
 * step: the calls change nothing there.
 */
#include <stdio.h>
#include <string.h>

#include "RTAPI.h"

#define CHECK(call)                                                                                            \
    do {                                                                                                       \
        RTAPIReturn_t rc_ = (call);                                                                            \
        if (rc_ != RTAPI_SUCCESS) {                                                                            \
            fprintf(stderr, "event_tank: %s failed: %s (%d): %s\n", #call, RTGetErrorMessage(rc_), (int)rc_,  \
                    RTGetLastErrorDetail());                                                                   \
            return 1;                                                                                          \
        }                                                                                                      \
    } while (0)

int main(int argc, char **argv)
{
    const char *role = argc > 1 ? argv[1] : "";
    int plant = strcmp(role, "plant") == 0, supervisor = strcmp(role, "supervisor") == 0;
    int alarm = strcmp(role, "alarm") == 0, logger = strcmp(role, "logger") == 0;
    if (!(plant || supervisor || alarm || logger)) {
        fprintf(stderr, "usage: %s plant|supervisor|alarm|logger\n", argv[0]);
        return 2;
    }
    CHECK(RTConnect("tank", 60));
    /* Say when it is due before its first step; the plant says nothing: every step. */
    if (supervisor) {
        CHECK(RTSetPeriod(0.100));
    } else if (alarm) {
        CHECK(RTSetWakeOnChange(1));
    } else if (logger) {
        CHECK(RTRequestTime(0.0));
    }
    double level_out = 1.0, valve_cmd = 1.0;
    for (;;) {
        RTAPIReturn_t rc = RTSubscribeLock();
        if (rc == RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED) {
            break; /* the framework stopped */
        }
        CHECK(rc);
        double level = 0.0, valve = 0.0, t = 0.0;
        if (!alarm) {
            CHECK(RTSubscribe("level", &level, sizeof level));
        }
        CHECK(RTSubscribe("valve", &valve, sizeof valve));
        CHECK(RTSubscribeUnlock());
        CHECK(RTGetSimulationTime(&t));
        if (plant) {
            /* 1 ms steps: fills at 0.6 m/s with the valve open, drains at 0.4 m/s. */
            level_out = (t == 0.0 ? 1.0 : level) + (valve > 0.5 ? 0.6 : -0.4) * 0.001;
            CHECK(RTPublishLock());
            CHECK(RTPublish("level_out", &level_out, sizeof level_out));
            CHECK(RTPublishUnlock());
        } else if (supervisor) {
            if (level > 1.5) {
                valve_cmd = 0.0;
            } else if (level < 0.5) {
                valve_cmd = 1.0;
            }
            CHECK(RTPublishLock());
            CHECK(RTPublish("valve_cmd", &valve_cmd, sizeof valve_cmd));
            CHECK(RTPublishUnlock());
            printf("supervisor t=%.3f level=%.4f valve=%g\n", t, level, valve_cmd);
        } else if (alarm) {
            printf("alarm t=%.3f valve %s\n", t, valve > 0.5 ? "opened" : "closed");
        } else {
            printf("logger t=%.3f level=%.4f\n", t, level);
            CHECK(RTRequestTime(t + 0.250));
        }
        fflush(stdout);
    }
    RTDisconnect();
    return 0;
}
