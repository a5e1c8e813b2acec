/*
 * uav_altitude_log: the C external component of the UAV demo (Figure 6 of the RT-LAB
 * Orchestra paper). It connects to a UAV domain, reads each step the altitude the framework
 * republishes (PUBLISH item Altitude) with the step's simulated time (PUBLISH item Time), and
 * logs both to a CSV file, until the framework stops or it is told to stop (SIGTERM, SIGINT).
 * It only reads: it never writes the SUBSCRIBE set, so it does not compete with the UAV model.
 *
 *   uav_altitude_log DOMAIN OUT.csv [NAME]
 *   uav_altitude_log multiuav_uav2 out/uav/c_reader1.csv
 *
 * CSV: time,altitude,connections (simulated s, m, connections of the domain seen at that step).
 * Build (see Makefile):
 *   gcc -std=c99 -Wall -I../../include uav_altitude_log.c -L../../target/release -lrtapi \
 *       -Wl,-rpath,$PWD/../../target/release -o uav_altitude_log
 */
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "RTAPI.h"

static volatile sig_atomic_t stop_requested = 0;

static void on_stop(int sig)
{
    (void)sig;
    stop_requested = 1;
}

static int check(RTAPIReturn_t rc, const char *call)
{
    if (rc != RTAPI_SUCCESS) {
        fprintf(stderr, "uav_altitude_log: %s failed: %s (%d): %s\n", call, RTGetErrorMessage(rc), (int)rc,
                RTGetLastErrorDetail());
        return 0;
    }
    return 1;
}

/* The framework has stopped: the normal end of a run. */
static int framework_gone(RTAPIReturn_t rc)
{
    return rc == RTAPI_SUBSCRIBE_FAILED_RTLAB_SUBSYSTEM_UNMAPPED || rc == RTAPI_PUBLISH_FAILED_RTLAB_SUBSYSTEM_UNMAPPED;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s DOMAIN OUT.csv\n", argv[0]);
        return 2;
    }
    const char *domain = argv[1], *path = argv[2];

    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);

    FILE *out = fopen(path, "w");
    if (!out) {
        perror(path);
        return 1;
    }
    fprintf(out, "time,altitude,connections\n");
    fflush(out);

    unsigned int key;
    if (!check(RTNewConnectionKey(&key), "RTNewConnectionKey") || !check(RTSetConnectionKey(key), "RTSetConnectionKey")
        || !check(RTConnect(domain, 10), "RTConnect")) {
        fclose(out);
        return 1;
    }
    unsigned short alt_key, time_key;
    void *alt_buf, *time_buf;
    if (!check(RTGetKeyForItem("Altitude", &alt_key), "RTGetKeyForItem(Altitude)")
        || !check(RTGetKeyForItem("Time", &time_key), "RTGetKeyForItem(Time)")
        || !check(RTGetBuffer(key, alt_key, &alt_buf), "RTGetBuffer(Altitude)")
        || !check(RTGetBuffer(key, time_key, &time_buf), "RTGetBuffer(Time)")) {
        RTDisconnect();
        fclose(out);
        return 1;
    }
    fprintf(stderr, "uav_altitude_log: connected to %s\n", domain);

    int status = 0;
    long rows = 0;
    while (!stop_requested) {
        RTAPIReturn_t rc = RTSubscribeLock();
        if (rc == RTAPI_ERROR_TIMEOUT) {
            continue; /* the framework has not stepped yet: ask again */
        }
        if (framework_gone(rc)) {
            break;
        }
        if (!check(rc, "RTSubscribeLock")) {
            status = 1;
            break;
        }
        double altitude = *(const double *)alt_buf, time = *(const double *)time_buf;
        RTSubscribeUnlock();
        unsigned int count = 0;
        RTGetConnectionCount(domain, &count);
        fprintf(out, "%.6f,%.17g,%u\n", time, altitude, count);
        fflush(out);
        rows++;
    }
    fclose(out);
    RTDisconnect();
    fprintf(stderr, "uav_altitude_log: %s: %ld steps logged to %s\n", domain, rows, path);
    return status;
}
