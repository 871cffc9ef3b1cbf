/* threads.h: wrt's one thread pool. A pool keeps its worker threads parked between
 * loops (no thread is started per loop); a loop hands out item indices dynamically (an
 * atomic counter), so callers that need deterministic output write each item's result
 * into its own slot and merge the slots in index order. wrt_parallel_for is a one-shot
 * pool for callers that run a loop now and then. Depends on pthreads. */
#ifndef WRT_THREADS_H
#define WRT_THREADS_H

#include <pthread.h>
#include <stddef.h>

#include "../include/wrt.h"

/* fn(item, thread_index, user) for item in [0, n); thread_index < the threads used. */
typedef void (*wrt_parallel_fn)(size_t item, int thread, void *user);

typedef struct wrt_pool wrt_pool;

/* A pool of `threads` threads counting the caller's (0 = all cores, capped at 64); a
 * pool of 1 runs everything on the caller's thread. If the system refuses a thread the
 * pool is smaller (wrt_pool_size says how big). Errors: WRT_ERR_NOMEM. */
wrt_status wrt_pool_create(int threads, wrt_pool **out);
void wrt_pool_destroy(wrt_pool *p); /* NULL is a no-op */
int wrt_pool_size(const wrt_pool *p);

/* Runs fn over [0, n) on at most `max_threads` of the pool's threads (0 = all), the
 * calling thread included; returns when all items are done, with the number of threads
 * used. One loop at a time per pool (the pool's owner calls it). */
int wrt_pool_run(wrt_pool *p, size_t n, int max_threads, wrt_parallel_fn fn, void *user);

/* One loop on `threads` threads (0 = all cores) of a pool made for it. */
void wrt_parallel_for(size_t n, int threads, wrt_parallel_fn fn, void *user);

/* One call fn(user) on a thread of its own beside the caller's, for work that overlaps
 * the caller's own loops (wrt_task_start; the caller's pools are not touched). Where no
 * thread can be started, fn runs on the caller's thread at wrt_task_join. */
typedef struct wrt_task {
    pthread_t tid;
    int started;
    void (*fn)(void *user);
    void *user;
} wrt_task;
void wrt_task_start(wrt_task *t, void (*fn)(void *user), void *user);
void wrt_task_join(wrt_task *t); /* returns when fn has returned */

/* The number of threads `threads` means (0 = online cores, capped at 64). */
int wrt_threads_resolve(int threads);

#endif
