/*
 * uav_reader: an external component in C, written in the call pattern of RT-LAB
 * Orchestra's RTAPI clients. Each step it reads one PUBLISH item (written by the framework)
 * and answers with one SUBSCRIBE item (read by the framework): answer = factor * item.
 *
 *   uav_reader DDF DOMAIN PUB_ITEM SUB_ITEM [STEPS] [FACTOR]
 *   uav_reader ../../ddf/multiuav.ddf multiuav_uav2 Z Elevation 100 1
 *
 * Both items must be float64 scalars. Build (see Makefile):
 *   gcc -std=c99 -Wall -I../../include uav_reader.c -L../../target/release -lrtapi \
 *       -Wl,-rpath,$PWD/../../target/release -o uav_reader
 */
#include <stdio.h>
#include <stdlib.h>

#include "RTAPI.h"

static int check(RTAPIReturn_t rc, const char *call)
{
    if (rc != RTAPI_SUCCESS) {
        fprintf(stderr, "uav_reader: %s failed: %s (%d): %s\n", call, RTGetErrorMessage(rc), (int)rc,
                RTGetLastErrorDetail());
        return 0;
    }
    return 1;
}

#define CHECK(call)                                                                                            \
    do {                                                                                                       \
        if (!check((call), #call)) {                                                                           \
            RTDisconnect();                                                                                    \
            return 1;                                                                                          \
        }                                                                                                      \
    } while (0)

int main(int argc, char **argv)
{
    if (argc < 5) {
        fprintf(stderr, "usage: %s DDF DOMAIN PUB_ITEM SUB_ITEM [STEPS] [FACTOR]\n", argv[0]);
        return 2;
    }
    const char *ddf = argv[1], *domain = argv[2], *pub_item = argv[3], *sub_item = argv[4];
    long steps = argc > 5 ? atol(argv[5]) : 100;
    double factor = argc > 6 ? atof(argv[6]) : 1.0;

    unsigned int key;
    CHECK(RTNewConnectionKey(&key));
    CHECK(RTSetConnectionKey(key));
    CHECK(RTConnectWithFile(ddf, domain, 5));

    unsigned int *status;
    CHECK(RTGetConnectionStatusPtr(key, &status));

    unsigned int in_size, out_size;
    unsigned short in_len, out_len, in_key, out_key;
    CHECK(RTGetInfoForItem(pub_item, &in_size, &in_len));
    CHECK(RTGetInfoForItem(sub_item, &out_size, &out_len));
    if (in_size != sizeof(double) || in_len != 1 || out_size != sizeof(double) || out_len != 1) {
        fprintf(stderr, "uav_reader: %s and %s must be float64 scalars\n", pub_item, sub_item);
        RTDisconnect();
        return 2;
    }
    CHECK(RTGetKeyForItem(pub_item, &in_key));
    CHECK(RTGetKeyForItem(sub_item, &out_key));
    void *in_buf, *out_buf;
    CHECK(RTGetBuffer(key, in_key, &in_buf));
    CHECK(RTGetBuffer(key, out_key, &out_buf));

    CHECK(RTWaitReadyToGo());
    for (long i = 0; i < steps; i++) {
        CHECK(RTSetConnectionKey(key));
        CHECK(RTSubscribeLock());
        double value = *(const double *)in_buf;
        CHECK(RTSubscribeUnlock());

        CHECK(RTPublishLock());
        *(double *)out_buf = factor * value;
        CHECK(RTPublishUnlock());

        printf("%s %s=%.17g status=%u\n", domain, pub_item, value, *(volatile unsigned int *)status);
    }
    fflush(stdout);
    CHECK(RTDisconnect());
    return 0;
}
