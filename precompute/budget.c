/* budget.c: the bake's memory budget: the process's resident memory (now and at its
 * peak), the default budget (half the physical memory) and the check each stage makes
 * before it allocates (refuse with the figures rather than be killed by the system).
 * Used by the driver (bake.c) and the series (series.c), which pass in the budget and
 * where to record the largest estimate. Depends on wrt_common and POSIX (sysconf,
 * getrusage, /proc/self/statm). */
#include "budget.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <unistd.h>

double wrt_bake_memory_default(void) {
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || size <= 0) return 4096;
    return 0.5 * (double)pages * (double)size / (1024.0 * 1024.0);
}

uint64_t wrt_bake_rss_bytes(void) {
    FILE *f = fopen("/proc/self/statm", "r");
    unsigned long long total = 0, res = 0;
    int n = f ? fscanf(f, "%llu %llu", &total, &res) : 0;
    if (f) fclose(f);
    long size = sysconf(_SC_PAGESIZE);
    return n == 2 && size > 0 ? (uint64_t)res * (uint64_t)size : 0;
}

/* the largest high-water mark before a reset by wrt_bake_stage_peak_bytes */
static uint64_t peak_before_reset;

uint64_t wrt_bake_peak_rss_bytes(void) {
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0;
    uint64_t p = (uint64_t)ru.ru_maxrss * 1024u; /* kilobytes on Linux */
    return p > peak_before_reset ? p : peak_before_reset;
}

uint64_t wrt_bake_stage_peak_bytes(void) {
    uint64_t kb = 0;
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "VmHWM:", 6)) kb = strtoull(line + 6, NULL, 10);
    if (f) fclose(f);
    if (kb * 1024u > peak_before_reset) peak_before_reset = kb * 1024u;
    if ((f = fopen("/proc/self/clear_refs", "w"))) { /* the mark back to what is resident now */
        fputs("5", f);
        fclose(f);
    }
    return kb * 1024u;
}

void wrt_bake_memory_trim(void) {
#ifdef __GLIBC__
    malloc_trim(0); /* the pages of freed blocks back to the system (glibc keeps them otherwise) */
#endif
}

wrt_status wrt_bake_memory_check(double budget_mb, double *largest_mb, uint64_t need, const char *what) {
    double mb = 1.0 / (1024.0 * 1024.0);
    /* what is resident now, without the freed memory the allocator holds on to: the
     * stage's allocations reuse that first, so counting it too made the estimate count
     * the same memory twice (the maze: 2.2 GB estimated against a 0.75 GB peak) */
    wrt_bake_memory_trim();
    double total = ((double)wrt_bake_rss_bytes() + (double)need) * mb;
    if (total > *largest_mb) *largest_mb = total;
    if (total <= budget_mb) return WRT_OK;
    return wrt_fail(WRT_ERR_NOMEM,
                    "the bake would need about %.0f MB (%s: %.0f MB more than the %.0f MB in use), over the "
                    "memory budget of %.0f MB (--max-memory; default half the physical memory): lower --quality, "
                    "--max-angular-level or --first-bounce-level, or raise --max-memory",
                    total, what, (double)need * mb, (double)wrt_bake_rss_bytes() * mb, budget_mb);
}
