/* The HELICS side of `tutti-bench scale` (benchmarks/src/scale.rs): the same shapes as
 * HELICS federates written in C against the C library of the `helics` wheel from PyPI,
 * one thread per federate, all on one in-process core (`inproc`: HELICS's fastest
 * transport, no sockets), time-stepped with helicsFederateRequestTime.
 *
 *   barrier  a hub federate and N federates connected as in `hub` (each depends on the
 *            other's time), publishing nothing: the cost of HELICS's time coordination
 *            alone (N federates with no connection would not wait for each other at all)
 *   hub      a hub federate publishes x at every step; N federates read it and publish
 *            their own y = x + 1, which the hub subscribes to (tutti: the framework and N
 *            participants each writing its own item)
 *   ring     N federates in a ring, each publishing y = (its predecessor's y) + 1
 *
 * Usage: helics_scale SHAPE N STEPS
 * Prints one JSON object: wall and CPU time, the wall time of each of federate 0's steps
 * (its p50 / p99), and each federate's granted steps (each must be STEPS).
 */
#include <helics/helics.h>

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

enum shape { BARRIER, HUB, RING };

static enum shape g_shape;
static int g_n;        /* federates besides the hub */
static int g_steps;
static char g_core[64];
static long *g_granted; /* per federate */
static double *g_step_ns; /* federate 0's step times */
static pthread_barrier_t g_start;

static double now_ns(clockid_t c) {
    struct timespec t;
    clock_gettime(c, &t);
    return (double)t.tv_sec * 1e9 + (double)t.tv_nsec;
}

static void check(HelicsError *err, const char *what) {
    if (err->error_code != HELICS_OK) {
        fprintf(stderr, "helics_scale: %s: %s\n", what, err->message);
        exit(1);
    }
}

/* Federate `index` (0 .. total-1; with a hub, index 0 is the hub). */
static void *federate(void *arg) {
    int index = (int)(long)arg;
    int publishes = g_shape != BARRIER;
    HelicsError err = helicsErrorInitialize();
    HelicsFederateInfo fi = helicsCreateFederateInfo();
    helicsFederateInfoSetCoreName(fi, g_core, &err);
    check(&err, "core name");
    helicsFederateInfoSetCoreTypeFromString(fi, "inproc", &err);
    check(&err, "core type");
    helicsFederateInfoSetTimeProperty(fi, HELICS_PROPERTY_TIME_PERIOD, 1.0, &err);
    check(&err, "period");
    char name[64];
    snprintf(name, sizeof name, "f%d", index);
    HelicsFederate fed = helicsCreateValueFederate(name, fi, &err);
    check(&err, "create federate");
    HelicsPublication pub;
    HelicsInput *inputs = NULL;
    int n_inputs = 0;
    char key[64];
    {
        snprintf(key, sizeof key, "y%d", index);
        pub = helicsFederateRegisterGlobalPublication(fed, key, HELICS_DATA_TYPE_DOUBLE, "", &err);
        check(&err, "publication");
    }
    if (g_shape != RING && index == 0) {
        n_inputs = g_n;
        inputs = calloc((size_t)g_n, sizeof *inputs);
        for (int i = 0; i < g_n; i++) {
            snprintf(key, sizeof key, "y%d", i + 1);
            inputs[i] = helicsFederateRegisterSubscription(fed, key, "", &err);
            check(&err, "subscription");
        }
    } else if (g_shape != RING) {
        n_inputs = 1;
        inputs = calloc(1, sizeof *inputs);
        inputs[0] = helicsFederateRegisterSubscription(fed, "y0", "", &err);
        check(&err, "subscription");
    } else if (g_shape == RING) {
        n_inputs = 1;
        inputs = calloc(1, sizeof *inputs);
        snprintf(key, sizeof key, "y%d", (index + g_n - 1) % g_n);
        inputs[0] = helicsFederateRegisterSubscription(fed, key, "", &err);
        check(&err, "subscription");
    }
    helicsFederateEnterExecutingMode(fed, &err);
    check(&err, "enter executing mode");
    pthread_barrier_wait(&g_start);
    double last = now_ns(CLOCK_MONOTONIC);
    double value = 0.0;
    for (int t = 1; t <= g_steps; t++) {
        if (publishes) {
            helicsPublicationPublishDouble(pub, value + 1.0, &err);
            check(&err, "publish");
        }
        HelicsTime granted = helicsFederateRequestTime(fed, (HelicsTime)t, &err);
        check(&err, "request time");
        if (granted >= (HelicsTime)t) {
            g_granted[index]++;
        }
        for (int i = 0; i < n_inputs; i++) {
            double v = helicsInputGetDouble(inputs[i], &err);
            check(&err, "read");
            if (i == 0 || v > value) {
                value = v;
            }
        }
        if (index == 0) {
            double s = now_ns(CLOCK_MONOTONIC);
            g_step_ns[t - 1] = s - last;
            last = s;
        }
    }
    helicsFederateFinalize(fed, &err);
    helicsFederateFree(fed);
    helicsFederateInfoFree(fi);
    free(inputs);
    return NULL;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    if (argc != 4) {
        fprintf(stderr, "usage: helics_scale barrier|hub|ring N STEPS\n");
        return 2;
    }
    if (strcmp(argv[1], "barrier") == 0) g_shape = BARRIER;
    else if (strcmp(argv[1], "hub") == 0) g_shape = HUB;
    else if (strcmp(argv[1], "ring") == 0) g_shape = RING;
    else { fprintf(stderr, "helics_scale: unknown shape '%s'\n", argv[1]); return 2; }
    g_n = atoi(argv[2]);
    g_steps = atoi(argv[3]);
    if (g_n < 1 || g_steps < 1) { fprintf(stderr, "helics_scale: N and STEPS must be positive\n"); return 2; }
    int total = g_n + (g_shape == RING ? 0 : 1);
    g_granted = calloc((size_t)total, sizeof *g_granted);
    g_step_ns = calloc((size_t)g_steps, sizeof *g_step_ns);
    snprintf(g_core, sizeof g_core, "scale%d", (int)getpid());
    HelicsError err = helicsErrorInitialize();
    char init[128];
    snprintf(init, sizeof init, "--autobroker --federates=%d --consoleloglevel=error", total);
    HelicsCore core = helicsCreateCore("inproc", g_core, init, &err);
    check(&err, "create core");
    pthread_barrier_init(&g_start, NULL, (unsigned)total + 1);
    pthread_t *threads = calloc((size_t)total, sizeof *threads);
    for (int i = 0; i < total; i++) {
        pthread_create(&threads[i], NULL, federate, (void *)(long)i);
    }
    pthread_barrier_wait(&g_start);
    double cpu0 = now_ns(CLOCK_PROCESS_CPUTIME_ID), wall0 = now_ns(CLOCK_MONOTONIC);
    for (int i = 0; i < total; i++) {
        pthread_join(threads[i], NULL);
    }
    double wall = now_ns(CLOCK_MONOTONIC) - wall0, cpu = now_ns(CLOCK_PROCESS_CPUTIME_ID) - cpu0;
    helicsCoreDisconnect(core, &err);
    helicsCoreFree(core);
    helicsCloseLibrary();
    qsort(g_step_ns, (size_t)g_steps, sizeof *g_step_ns, cmp);
    int p50 = (int)((g_steps - 1) * 0.5), p99 = (int)((g_steps - 1) * 0.99);
    printf("{\"shape\":\"%s\",\"n\":%d,\"federates\":%d,\"steps\":%d,\"wall_s\":%.9f,\"cpu_s\":%.9f,"
           "\"p50_us\":%.3f,\"p99_us\":%.3f,\"version\":\"%s\",\"granted\":[",
           argv[1], g_n, total, g_steps, wall / 1e9, cpu / 1e9, g_step_ns[p50] / 1e3, g_step_ns[p99] / 1e3,
           helicsGetVersion());
    for (int i = 0; i < total; i++) {
        printf("%s%ld", i ? "," : "", g_granted[i]);
    }
    printf("]}\n");
    return 0;
}
