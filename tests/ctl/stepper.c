/*
 * stepper: a C component of the run-control tests. It connects to a synchronous domain and,
 * every step, reads one float64 PUBLISH item and answers one float64 SUBSCRIBE item with the
 * number of steps it has made. It prints a line per step ("step N x=V"), so that a test can
 * count exactly the steps it saw, and ends when the framework does: exit 0 when the
 * framework stopped, 3 when a lock timed out (what a pause must never cause), 1 otherwise.
 *
 *   stepper DDF DOMAIN PUB_ITEM SUB_ITEM TIMEOUT_SECONDS
 */
#include <stdio.h>
#include <stdlib.h>

#include "RTAPI.h"

static int fail(const char *what, RTAPIReturn_t rc)
{
    printf("end: %s: %s (%d): %s\n", what, RTGetErrorMessage(rc), (int)rc, RTGetLastErrorDetail());
    fflush(stdout);
    RTDisconnect();
    if (rc == RTAPI_ERROR_TIMEOUT)
        return 3;
    /* The framework stopped (the vendor's "subsystem unmapped" codes) or let the connection go. */
    return (rc == RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED || rc == RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED ||
            rc == RTAPI_ERROR_CONNECTION_LOST)
               ? 0
               : 1;
}

int main(int argc, char **argv)
{
    if (argc < 6) {
        fprintf(stderr, "usage: %s DDF DOMAIN PUB_ITEM SUB_ITEM TIMEOUT_SECONDS\n", argv[0]);
        return 2;
    }
    RTAPIReturn_t rc;
    unsigned int key;
    unsigned short in_key, out_key;
    void *in_buf, *out_buf;
    if ((rc = RTNewConnectionKey(&key)) || (rc = RTSetConnectionKey(key)))
        return fail("key", rc);
    if ((rc = RTConnectWithFile(argv[1], argv[2], atoi(argv[5]))))
        return fail("RTConnectWithFile", rc);
    if ((rc = RTGetKeyForItem(argv[3], &in_key)) || (rc = RTGetKeyForItem(argv[4], &out_key)))
        return fail("RTGetKeyForItem", rc);
    if ((rc = RTGetBuffer(key, in_key, &in_buf)) || (rc = RTGetBuffer(key, out_key, &out_buf)))
        return fail("RTGetBuffer", rc);
    printf("connected\n");
    fflush(stdout);
    for (unsigned long n = 1;; n++) {
        if ((rc = RTSubscribeLock()))
            return fail("RTSubscribeLock", rc);
        double x = *(const double *)in_buf;
        if ((rc = RTSubscribeUnlock()))
            return fail("RTSubscribeUnlock", rc);
        /* Printed before the answer: once the framework has the answer, the line is out. */
        printf("step %lu x=%g\n", n, x);
        fflush(stdout);
        if ((rc = RTPublishLock()))
            return fail("RTPublishLock", rc);
        *(double *)out_buf = (double)n;
        if ((rc = RTPublishUnlock()))
            return fail("RTPublishUnlock", rc);
    }
}
