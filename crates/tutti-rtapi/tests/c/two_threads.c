/*
 * two_threads: a client of a synchronous domain that reads in one thread and writes in
 * another, as VILLASnode's Orchestra node does. The reader takes each step's PUBLISH item
 * and hands it to the writer, which answers 2 x the value. With "own-mutex", every RTAPI call
 * (with its RTSetConnectionKey) runs under one process-wide mutex of the client's own, held
 * for the whole call, as VILLASnode's RTConnectionLockGuard does; with "no-mutex", the
 * threads call the library concurrently.
 *
 * With "paced", the writer does not answer the reader: it writes on its own, once every
 * PACE steps the reader has read (counting the steps from the end of its last write), the
 * values 1, 2, 3, ..., with no mutex of its own. It counts the steps the reader read while
 * each RTPublishLock ran: a writer held up by the reader's wait for the next step sees
 * steps pass there.
 *
 *   two_threads DOMAIN PUB_ITEM SUB_ITEM STEPS own-mutex|no-mutex|paced
 *
 * Prints "read V" for every value read (in order), then "writes N"; "paced" also prints
 * "lock_steps S" (the steps read during all RTPublishLock calls) and "max_lock_steps M".
 */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdatomic.h>
#include <time.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "RTAPI.h"

static unsigned int key;
static unsigned short in_key, out_key;
static void *in_buf, *out_buf;
static long steps;
static int own_mutex;

static pthread_mutex_t client_lock = PTHREAD_MUTEX_INITIALIZER; /* the client's own, around calls */
static pthread_mutex_t queue_lock = PTHREAD_MUTEX_INITIALIZER;  /* reader -> writer hand-over */
static pthread_cond_t queue_cond = PTHREAD_COND_INITIALIZER;
static double latest;
static int fresh, done, failed;
static double *values;
static long writes;
static int paced;
static atomic_long reader_steps;
static atomic_int reader_done;
static long lock_steps, max_lock_steps;
#define PACE 20

static void call_lock(void)
{
    if (own_mutex) {
        pthread_mutex_lock(&client_lock);
    }
}

static void call_unlock(void)
{
    if (own_mutex) {
        pthread_mutex_unlock(&client_lock);
    }
}

static int check(RTAPIReturn_t rc, const char *what)
{
    if (rc != RTAPI_SUCCESS) {
        fprintf(stderr, "two_threads: %s failed: %s (%d): %s\n", what, RTGetErrorMessage(rc), (int)rc,
                RTGetLastErrorDetail());
        return 0;
    }
    return 1;
}

static void *reader(void *arg)
{
    (void)arg;
    for (long i = 0; i < steps; i++) {
        call_lock();
        int ok = check(RTSetConnectionKey(key), "RTSetConnectionKey") && check(RTSubscribeLock(), "RTSubscribeLock");
        double v = ok ? *(const double *)in_buf : 0.0;
        ok = ok && check(RTSubscribeUnlock(), "RTSubscribeUnlock");
        call_unlock();
        if (!ok) {
            failed = 1;
            break;
        }
        values[i] = v;
        atomic_store(&reader_steps, i + 1);
        pthread_mutex_lock(&queue_lock);
        latest = v;
        fresh = 1;
        pthread_cond_signal(&queue_cond);
        pthread_mutex_unlock(&queue_lock);
    }
    atomic_store(&reader_done, 1);
    pthread_mutex_lock(&queue_lock);
    done = 1;
    pthread_cond_signal(&queue_cond);
    pthread_mutex_unlock(&queue_lock);
    return NULL;
}

static void *paced_writer(void *arg)
{
    (void)arg;
    long next = PACE;
    const struct timespec nap = {0, 100000};
    for (;;) {
        while (atomic_load(&reader_steps) < next && !atomic_load(&reader_done)) {
            nanosleep(&nap, NULL);
        }
        if (atomic_load(&reader_done)) {
            return NULL;
        }
        long before = atomic_load(&reader_steps);
        int ok = check(RTPublishLock(), "RTPublishLock");
        long after = atomic_load(&reader_steps);
        if (ok) {
            *(double *)out_buf = (double)(writes + 1);
        }
        ok = ok && check(RTPublishUnlock(), "RTPublishUnlock");
        if (!ok) {
            failed = 1;
            return NULL;
        }
        writes++;
        lock_steps += after - before;
        if (after - before > max_lock_steps) {
            max_lock_steps = after - before;
        }
        next = atomic_load(&reader_steps) + PACE;
    }
}

static void *writer(void *arg)
{
    (void)arg;
    for (;;) {
        pthread_mutex_lock(&queue_lock);
        while (!fresh && !done) {
            pthread_cond_wait(&queue_cond, &queue_lock);
        }
        if (!fresh) {
            pthread_mutex_unlock(&queue_lock);
            return NULL;
        }
        double v = latest;
        fresh = 0;
        pthread_mutex_unlock(&queue_lock);

        call_lock();
        int ok = check(RTSetConnectionKey(key), "RTSetConnectionKey") && check(RTPublishLock(), "RTPublishLock");
        if (ok) {
            *(double *)out_buf = 2.0 * v;
        }
        ok = ok && check(RTPublishUnlock(), "RTPublishUnlock");
        call_unlock();
        if (!ok) {
            failed = 1;
            return NULL;
        }
        writes++;
    }
}

int main(int argc, char **argv)
{
    if (argc < 6) {
        fprintf(stderr, "usage: %s DOMAIN PUB_ITEM SUB_ITEM STEPS own-mutex|no-mutex\n", argv[0]);
        return 2;
    }
    steps = atol(argv[4]);
    own_mutex = strcmp(argv[5], "own-mutex") == 0;
    paced = strcmp(argv[5], "paced") == 0;
    values = calloc((size_t)steps, sizeof *values);
    if (!values) {
        return 1;
    }
    if (!check(RTNewConnectionKey(&key), "RTNewConnectionKey") || !check(RTSetConnectionKey(key), "RTSetConnectionKey")
        || !check(RTConnect(argv[1], 30), "RTConnect") || !check(RTGetKeyForItem(argv[2], &in_key), "RTGetKeyForItem")
        || !check(RTGetKeyForItem(argv[3], &out_key), "RTGetKeyForItem")
        || !check(RTGetBuffer(key, in_key, &in_buf), "RTGetBuffer")
        || !check(RTGetBuffer(key, out_key, &out_buf), "RTGetBuffer")) {
        return 1;
    }
    pthread_t r, w;
    pthread_create(&w, NULL, paced ? paced_writer : writer, NULL);
    pthread_create(&r, NULL, reader, NULL);
    pthread_join(r, NULL);
    pthread_join(w, NULL);
    for (long i = 0; i < steps; i++) {
        printf("read %.17g\n", values[i]);
    }
    printf("writes %ld\n", writes);
    if (paced) {
        printf("lock_steps %ld\nmax_lock_steps %ld\n", lock_steps, max_lock_steps);
    }
    free(values);
    check(RTDisconnect(), "RTDisconnect");
    return failed;
}
