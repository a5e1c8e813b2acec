/*
 * ramp: a C component for the studio's browser test. It connects to DOMAIN (layout read from
 * the live segment) and, each step, writes step * 0.5 into the float64 SUBSCRIBE item ITEM,
 * until it is killed (or after a million steps).
 *
 *   ramp DOMAIN ITEM
 */
#include <stdio.h>

#include "RTAPI.h"

static int ok(RTAPIReturn_t rc, const char *call)
{
    if (rc != RTAPI_SUCCESS) {
        fprintf(stderr, "ramp: %s failed: %s (%d)\n", call, RTGetErrorMessage(rc), (int)rc);
        return 0;
    }
    return 1;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s DOMAIN ITEM\n", argv[0]);
        return 2;
    }
    unsigned int key;
    if (!ok(RTNewConnectionKey(&key), "RTNewConnectionKey") || !ok(RTSetConnectionKey(key), "RTSetConnectionKey") ||
        !ok(RTConnect(argv[1], 10), "RTConnect") || !ok(RTWaitReadyToGo(), "RTWaitReadyToGo")) {
        return 1;
    }
    for (long i = 0; i < 1000000; i++) {
        double v = 0.5 * (double)i;
        if (!ok(RTSubscribeLock(), "RTSubscribeLock") || !ok(RTSubscribeUnlock(), "RTSubscribeUnlock") ||
            !ok(RTPublishLock(), "RTPublishLock") || !ok(RTPublish(argv[2], &v, sizeof v), "RTPublish") ||
            !ok(RTPublishUnlock(), "RTPublishUnlock")) {
            RTDisconnect();
            return 1;
        }
    }
    RTDisconnect();
    return 0;
}
