/*
 * two_domains: one process, two connections to two domains, selected with connection keys
 * as in the product. Each step, for each domain in turn, reads PUB_ITEM (RTSubscribe inside a
 * lock pair) and echoes it to SUB_ITEM (RTPublish inside a lock pair). The layout comes from
 * the live segments (RTConnect, no DDF).
 *
 *   two_domains DOMAIN_A DOMAIN_B PUB_ITEM SUB_ITEM [STEPS]
 *   two_domains multiuav_uav1 multiuav_uav2 X Latitude 50
 */
#include <stdio.h>
#include <stdlib.h>

#include "RTAPI.h"

static int ok(RTAPIReturn_t rc, const char *call)
{
    if (rc != RTAPI_SUCCESS)
        fprintf(stderr, "two_domains: %s failed: %s (%d): %s\n", call, RTGetErrorMessage(rc), (int)rc,
                RTGetLastErrorDetail());
    return rc == RTAPI_SUCCESS;
}

#define CHECK(call)                                                                                            \
    do {                                                                                                       \
        if (!ok((call), #call))                                                                                \
            goto fail;                                                                                         \
    } while (0)

int main(int argc, char **argv)
{
    if (argc < 5) {
        fprintf(stderr, "usage: %s DOMAIN_A DOMAIN_B PUB_ITEM SUB_ITEM [STEPS]\n", argv[0]);
        return 2;
    }
    const char *domains[2] = {argv[1], argv[2]};
    const char *pub_item = argv[3], *sub_item = argv[4];
    long steps = argc > 5 ? atol(argv[5]) : 50;
    unsigned int keys[2];

    for (int d = 0; d < 2; d++) {
        CHECK(RTNewConnectionKey(&keys[d]));
        CHECK(RTSetConnectionKey(keys[d]));
        CHECK(RTConnect(domains[d], 5));
    }
    for (int d = 0; d < 2; d++) {
        unsigned int count = 0;
        CHECK(RTGetConnectionCount(domains[d], &count));
        printf("%s connections=%u\n", domains[d], count);
    }
    for (long i = 0; i < steps; i++) {
        double in[2];
        /* In synchronous domains, answer each domain's step before waiting for the next
         * domain: the framework waits for this connection's commit before it moves on. */
        for (int d = 0; d < 2; d++) {
            CHECK(RTSetConnectionKey(keys[d]));
            CHECK(RTSubscribeLock());
            CHECK(RTSubscribe(pub_item, &in[d], sizeof in[d]));
            CHECK(RTSubscribeUnlock());
            CHECK(RTPublishLock());
            CHECK(RTPublish(sub_item, &in[d], sizeof in[d]));
            CHECK(RTPublishUnlock());
        }
        printf("step %ld a=%.17g b=%.17g\n", i, in[0], in[1]);
    }
    for (int d = 0; d < 2; d++) {
        CHECK(RTSetConnectionKey(keys[d]));
        CHECK(RTDisconnect());
    }
    fflush(stdout);
    return 0;
fail:
    for (int d = 0; d < 2; d++) {
        if (RTSetConnectionKey(keys[d]) == RTAPI_SUCCESS)
            RTDisconnect();
    }
    return 1;
}
