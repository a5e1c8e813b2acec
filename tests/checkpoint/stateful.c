/*
 * stateful: the C component of the checkpoint tests. It keeps a state (x, and its step count
 * n) that it hands over and takes back through RTSetStateCallbacks, and each step answers
 *     x = 0.5 x + 0.4 u + 0.001 (n mod 97),   y = x
 * from the PUBLISH item u. With `nostate` as its third argument it keeps its state to itself
 * (no callbacks): a checkpoint then names it.
 *
 *   stateful DDF DOMAIN [nostate]
 */
#include <stdio.h>
#include <string.h>

#include "RTAPI.h"

#define CHECK(call)                                                                                            \
    do {                                                                                                       \
        RTAPIReturn_t rc_ = (call);                                                                            \
        if (rc_ != RTAPI_SUCCESS) {                                                                            \
            fprintf(stderr, "stateful: %s failed: %s (%d): %s\n", #call, RTGetErrorMessage(rc_), (int)rc_,    \
                    RTGetLastErrorDetail());                                                                   \
            RTDisconnect();                                                                                    \
            return rc_ == RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED ? 0 : 1;                             \
        }                                                                                                      \
    } while (0)

struct state {
    double x;
    long n;
};

static struct state now;
static struct state saved;
static int saves, restores;

static int save(void *context, const void **buffer, unsigned int *size)
{
    (void)context;
    saved = now;
    *buffer = &saved;
    *size = sizeof saved;
    saves++;
    return 0;
}

static int restore(void *context, const void *buffer, unsigned int size)
{
    (void)context;
    if (size != sizeof now) {
        fprintf(stderr, "stateful: a state of %u bytes, expected %zu\n", size, sizeof now);
        return 1;
    }
    memcpy(&now, buffer, sizeof now);
    restores++;
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s DDF DOMAIN [nostate]\n", argv[0]);
        return 2;
    }
    int keeps_state = !(argc > 3 && strcmp(argv[3], "nostate") == 0);
    if (keeps_state)
        CHECK(RTSetStateCallbacks(save, restore, NULL));
    CHECK(RTSetSkipWaitToGoAtConnection(1));
    CHECK(RTConnectWithFile(argv[1], argv[2], 60));
    /* A first answer before the first step: a writer from the first step on. */
    CHECK(RTPublishLock());
    CHECK(RTPublish("y", &now.x, sizeof now.x));
    CHECK(RTPublishUnlock());
    CHECK(RTWaitReadyToGo());
    for (;;) {
        double u;
        RTAPIReturn_t rc = RTSubscribeLock();
        if (rc == RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED)
            break; /* the framework has stopped: the run is over */
        CHECK(rc);
        CHECK(RTSubscribe("u", &u, sizeof u));
        CHECK(RTSubscribeUnlock());
        now.n++;
        now.x = 0.5 * now.x + 0.4 * u + 0.001 * (double)(now.n % 97);
        CHECK(RTPublishLock());
        CHECK(RTPublish("y", &now.x, sizeof now.x));
        CHECK(RTPublishUnlock());
    }
    printf("stateful: %ld steps, %d saves, %d restores\n", now.n, saves, restores);
    return 0;
}
