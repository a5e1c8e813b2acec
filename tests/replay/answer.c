/*
 * answer: the C component of the replay test, in the product's call pattern. It connects to
 * a synchronous domain, declares itself a writer with a first answer (0) before the framework's
 * first step, which answers that step; then each following step it reads one float64 PUBLISH
 * item and answers
 *     SUB_ITEM = factor * PUB_ITEM + n        (n = 1, 2, ... its steps)
 * plus 1 from its step DEVIATE on (0: never), so that a changed answer can be told apart.
 *
 *   answer DDF DOMAIN PUB_ITEM SUB_ITEM STEPS FACTOR DEVIATE
 */
#include <stdio.h>
#include <stdlib.h>

#include "RTAPI.h"

#define CHECK(call)                                                                                            \
    do {                                                                                                       \
        RTAPIReturn_t rc_ = (call);                                                                            \
        if (rc_ != RTAPI_SUCCESS) {                                                                            \
            fprintf(stderr, "answer: %s failed: %s (%d): %s\n", #call, RTGetErrorMessage(rc_), (int)rc_,      \
                    RTGetLastErrorDetail());                                                                   \
            RTDisconnect();                                                                                    \
            return 1;                                                                                          \
        }                                                                                                      \
    } while (0)

int main(int argc, char **argv)
{
    if (argc < 8) {
        fprintf(stderr, "usage: %s DDF DOMAIN PUB_ITEM SUB_ITEM STEPS FACTOR DEVIATE\n", argv[0]);
        return 2;
    }
    const char *ddf = argv[1], *domain = argv[2], *pub_item = argv[3], *sub_item = argv[4];
    long steps = atol(argv[5]), deviate = atol(argv[7]);
    double factor = atof(argv[6]);

    unsigned int key;
    CHECK(RTNewConnectionKey(&key));
    CHECK(RTSetConnectionKey(key));
    /* Connect without waiting for the framework's go, to answer once first (below). */
    CHECK(RTSetSkipWaitToGoAtConnection(1));
    CHECK(RTConnectWithFile(ddf, domain, 60));
    unsigned short in_key, out_key;
    CHECK(RTGetKeyForItem(pub_item, &in_key));
    CHECK(RTGetKeyForItem(sub_item, &out_key));
    void *in_buf, *out_buf;
    CHECK(RTGetBuffer(key, in_key, &in_buf));
    CHECK(RTGetBuffer(key, out_key, &out_buf));

    /* A first answer before the first step: the framework counts this connection as a writer
     * from now on (what `tutti host --wait-for DOMAIN=1` waits for). */
    CHECK(RTPublishLock());
    *(double *)out_buf = 0.0;
    CHECK(RTPublishUnlock());

    CHECK(RTWaitReadyToGo());
    for (long n = 1; n <= steps; n++) {
        CHECK(RTSubscribeLock());
        double value = *(const double *)in_buf;
        CHECK(RTSubscribeUnlock());

        CHECK(RTPublishLock());
        *(double *)out_buf = factor * value + (double)n + (deviate > 0 && n >= deviate ? 1.0 : 0.0);
        CHECK(RTPublishUnlock());
    }
    CHECK(RTDisconnect());
    printf("answered %ld steps\n", steps);
    return 0;
}
