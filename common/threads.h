/* threads.h: a minimal parallel-for over item indices with pthreads. Items are handed
 * out dynamically (an atomic counter), so callers that need deterministic output
 * write each item's result into its own slot and merge the slots in index order.
 * Depends on pthreads. */
#ifndef WRT_THREADS_H
#define WRT_THREADS_H

#include <stddef.h>

/* fn(item, thread_index, user) for item in [0, n), on `threads` threads (0 = all cores).
 * Returns when all items are done. thread_index < wrt_threads_resolve(threads). */
typedef void (*wrt_parallel_fn)(size_t item, int thread, void *user);
void wrt_parallel_for(size_t n, int threads, wrt_parallel_fn fn, void *user);

/* The number of threads `threads` means (0 = online cores, capped at 64). */
int wrt_threads_resolve(int threads);

#endif
