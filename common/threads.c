/* threads.c: the thread pool (see threads.h). Workers sleep on a condition variable
 * until the owner posts a loop (a new generation), take items from a shared atomic
 * counter, and report when they are done. */
#include "threads.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

int wrt_threads_resolve(int threads) {
    if (threads <= 0) {
        long n = sysconf(_SC_NPROCESSORS_ONLN);
        threads = n > 0 ? (int)n : 1;
    }
    return threads > 64 ? 64 : threads;
}

typedef struct wrt_worker { struct wrt_pool *p; int index; pthread_t tid; } wrt_worker;

struct wrt_pool {
    int size;                 /* threads, the caller's included */
    pthread_mutex_t mu;
    pthread_cond_t go, done;
    unsigned long generation; /* bumped for each loop */
    int quit;
    int active;               /* workers still in the current loop */
    int want;                 /* workers that take part in the current loop (index < want) */
    /* the current loop */
    size_t n;
    atomic_size_t next;
    wrt_parallel_fn fn;
    void *user;
    wrt_worker w[64];
};

/* Items are taken a run at a time: a share of what is left, at most 64, down to one as
 * the loop ends (the last items, the likeliest to leave a thread waiting, one by one).
 * One atomic add per item cost more than the item where items are cheap: the series by
 * blocks of columns (precompute/series_cols.c) runs loops over every column with all but
 * a block's empty, 5.4M a loop at 53,122 atrium elements, and the two threads' adds on
 * one cache line took a quarter of its time (perf, 5,048 elements in 160 blocks). Which
 * thread takes an item never changes what the item computes. */
static void take_items(wrt_pool *p, int index) {
    const size_t n = p->n, parts = 32 * (size_t)(p->want > 1 ? p->want : 1);
    for (;;) {
        size_t seen = atomic_load_explicit(&p->next, memory_order_relaxed);
        if (seen >= n) break;
        size_t k = (n - seen) / parts;
        k = k < 1 ? 1 : k > 64 ? 64 : k;
        size_t i = atomic_fetch_add(&p->next, k);
        if (i >= n) break;
        size_t e = n - i > k ? i + k : n;
        for (; i < e; i++) p->fn(i, index, p->user);
    }
}

static void *worker_main(void *arg) {
    wrt_worker *w = arg;
    wrt_pool *p = w->p;
    unsigned long seen = 0;
    pthread_mutex_lock(&p->mu);
    for (;;) {
        while (!p->quit && p->generation == seen) pthread_cond_wait(&p->go, &p->mu);
        if (p->quit) break;
        seen = p->generation;
        if (w->index >= p->want) continue;
        pthread_mutex_unlock(&p->mu);
        take_items(p, w->index);
        pthread_mutex_lock(&p->mu);
        if (--p->active == 0) pthread_cond_signal(&p->done);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

wrt_status wrt_pool_create(int threads, wrt_pool **out) {
    *out = NULL;
    wrt_pool *p = calloc(1, sizeof *p);
    if (!p) return WRT_ERR_NOMEM;
    int t = wrt_threads_resolve(threads);
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->go, NULL);
    pthread_cond_init(&p->done, NULL);
    atomic_init(&p->next, 0);
    p->size = 1;
    for (int i = 1; i < t; i++) {
        p->w[i].p = p;
        p->w[i].index = i;
        if (pthread_create(&p->w[i].tid, NULL, worker_main, &p->w[i]) != 0) break;
        p->size = i + 1;
    }
    *out = p;
    return WRT_OK;
}

void wrt_pool_destroy(wrt_pool *p) {
    if (!p) return;
    pthread_mutex_lock(&p->mu);
    p->quit = 1;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->mu);
    for (int i = 1; i < p->size; i++) pthread_join(p->w[i].tid, NULL);
    pthread_cond_destroy(&p->go);
    pthread_cond_destroy(&p->done);
    pthread_mutex_destroy(&p->mu);
    free(p);
}

int wrt_pool_size(const wrt_pool *p) { return p->size; }

int wrt_pool_run(wrt_pool *p, size_t n, int max_threads, wrt_parallel_fn fn, void *user) {
    if (n == 0) return 0;
    int t = max_threads > 0 && max_threads < p->size ? max_threads : p->size;
    if ((size_t)t > n) t = (int)n;
    p->n = n;
    p->fn = fn;
    p->user = user;
    atomic_store(&p->next, 0);
    if (t > 1) {
        pthread_mutex_lock(&p->mu);
        p->want = t;
        p->active = t - 1;
        p->generation++;
        pthread_cond_broadcast(&p->go);
        pthread_mutex_unlock(&p->mu);
    }
    take_items(p, 0);
    if (t > 1) {
        pthread_mutex_lock(&p->mu);
        while (p->active > 0) pthread_cond_wait(&p->done, &p->mu);
        pthread_mutex_unlock(&p->mu);
    }
    return t;
}

void wrt_parallel_for(size_t n, int threads, wrt_parallel_fn fn, void *user) {
    int t = wrt_threads_resolve(threads);
    if ((size_t)t > n) t = n ? (int)n : 1;
    wrt_pool *p = NULL;
    if (t > 1 && wrt_pool_create(t, &p) == WRT_OK) {
        wrt_pool_run(p, n, 0, fn, user);
        wrt_pool_destroy(p);
        return;
    }
    for (size_t i = 0; i < n; i++) fn(i, 0, user); /* one thread, or no memory for a pool */
}

static void *task_main(void *arg) {
    wrt_task *t = arg;
    t->fn(t->user);
    return NULL;
}

void wrt_task_start(wrt_task *t, void (*fn)(void *user), void *user) {
    t->fn = fn;
    t->user = user;
    t->started = pthread_create(&t->tid, NULL, task_main, t) == 0;
}

void wrt_task_join(wrt_task *t) {
    if (t->started) pthread_join(t->tid, NULL);
    else t->fn(t->user);
    t->started = 0;
}
