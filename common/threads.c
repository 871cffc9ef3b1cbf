/* threads.c: parallel-for with a shared atomic counter. See threads.h. */
#include "threads.h"

#include <pthread.h>
#include <stdatomic.h>
#include <unistd.h>

int wrt_threads_resolve(int threads) {
    if (threads <= 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (int)n : 1;
    }
    return threads > 64 ? 64 : threads;
}

typedef struct job {
    size_t n;
    atomic_size_t next;
    wrt_parallel_fn fn;
    void *user;
} job;

typedef struct worker { job *j; int index; } worker;

static void *run_worker(void *arg) {
    worker *w = arg;
    for (;;) {
        size_t i = atomic_fetch_add(&w->j->next, 1);
        if (i >= w->j->n) break;
        w->j->fn(i, w->index, w->j->user);
    }
    return NULL;
}

void wrt_parallel_for(size_t n, int threads, wrt_parallel_fn fn, void *user) {
    int t = wrt_threads_resolve(threads);
    if ((size_t)t > n) t = n ? (int)n : 1;
    job j = {.n = n, .fn = fn, .user = user};
    atomic_init(&j.next, 0);
    pthread_t tid[64];
    worker w[64];
    for (int i = 0; i < t; i++) w[i] = (worker){&j, i};
    int started = 0;
    for (int i = 1; i < t; i++) {
        if (pthread_create(&tid[i], NULL, run_worker, &w[i]) != 0) break;
        started = i;
    }
    run_worker(&w[0]);
    for (int i = 1; i <= started; i++) pthread_join(tid[i], NULL);
}
