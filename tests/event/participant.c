/*
 * participant: the C component of the event-driven tests (docs/timing.md). It connects to
 * domain `ev`, says when it is due, and at each step it is woken at prints
 *     wake N X
 * (N: the step's index, its simulated time over the 1 ms step; X: the PUBLISH item x read
 * at it). In a lock-step domain the same calls change nothing, so the same program run there
 * is woken at every step: the reference the event-driven run is compared with.
 *
 *   participant MODE [DIE_AT]
 *
 * MODE: every   due at every step (calls nothing); writes src = f(N) at each step
 *       period  RTSetPeriod(0.010): every 10 ms of simulated time
 *       wake    RTSetWakeOnChange(1): when x changed (it reads x only; t changes at
 *               every step)
 *       request RTRequestTime(t + 37 ms, + 10.5 ms, + 3 ms, in turn)
 * DIE_AT: kill itself with SIGKILL at that step, while due, before answering it.
 * Ends with 0 when the framework stops.
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "RTAPI.h"

#define CHECK(call)                                                                                            \
    do {                                                                                                       \
        RTAPIReturn_t rc_ = (call);                                                                            \
        if (rc_ != RTAPI_SUCCESS) {                                                                            \
            fprintf(stderr, "participant: %s failed: %s (%d): %s\n", #call, RTGetErrorMessage(rc_), (int)rc_, \
                    RTGetLastErrorDetail());                                                                   \
            return 1;                                                                                          \
        }                                                                                                      \
    } while (0)

/* What the every-step participant writes at step n: changes at irregular steps only. */
static double src_of(long n)
{
    return (double)(n / 25) + 0.25 * (double)(n / 60);
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s every|period|wake|request [DIE_AT]\n", argv[0]);
        return 2;
    }
    const char *mode = argv[1];
    long die_at = argc > 2 ? atol(argv[2]) : -1;
    const double step = 0.001;
    const double deltas[] = {0.037, 0.0105, 0.003};
    CHECK(RTConnect("ev", 60));
    if (strcmp(mode, "period") == 0) {
        CHECK(RTSetPeriod(0.010));
    } else if (strcmp(mode, "wake") == 0) {
        CHECK(RTSetWakeOnChange(1));
    } else if (strcmp(mode, "request") == 0) {
        /* Said before the first step, as the others: due at the first step, then as asked. */
        CHECK(RTRequestTime(0.0));
    } else if (strcmp(mode, "every") != 0) {
        fprintf(stderr, "participant: unknown mode '%s'\n", mode);
        return 2;
    }
    for (long i = 0;; i++) {
        RTAPIReturn_t rc = RTSubscribeLock();
        if (rc == RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED) {
            break; /* the framework stopped: the run is over */
        }
        CHECK(rc);
        double x, t;
        CHECK(RTSubscribe("x", &x, sizeof x));
        CHECK(RTSubscribeUnlock());
        CHECK(RTGetSimulationTime(&t));
        long n = (long)(t / step + 0.5); /* t >= 0 */
        printf("wake %ld %.17g\n", n, x);
        fflush(stdout);
        if (n == die_at) {
            kill(getpid(), SIGKILL);
        }
        if (strcmp(mode, "every") == 0) {
            double src = src_of(n);
            CHECK(RTPublishLock());
            CHECK(RTPublish("src", &src, sizeof src));
            CHECK(RTPublishUnlock());
        } else if (strcmp(mode, "request") == 0) {
            CHECK(RTRequestTime(t + deltas[i % 3]));
        }
    }
    RTDisconnect();
    return 0;
}
