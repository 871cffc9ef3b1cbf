/* budget.h: the bake's memory budget (budget.c): resident memory, the default budget
 * and the check before an allocation. Depends on wrt_common only. */
#ifndef WRT_BUDGET_H
#define WRT_BUDGET_H

#include <stdint.h>

#include "../common/wrt_common.h"

/* The default memory budget in MB: half the physical memory. */
double wrt_bake_memory_default(void);
/* The process's resident memory now and at its peak (getrusage), in bytes (0 if unknown). */
uint64_t wrt_bake_rss_bytes(void);
uint64_t wrt_bake_peak_rss_bytes(void);
/* the kernel's high-water mark of resident memory since the last call (VmHWM, reset
 * through /proc/self/clear_refs, Linux 4.0 on), for WRT_DTO_TIMES' stages; 0 where not
 * readable. wrt_bake_peak_rss_bytes still states the whole run's peak */
uint64_t wrt_bake_stage_peak_bytes(void);
/* Hands the pages of freed memory back to the system (glibc's malloc_trim; nothing
 * elsewhere), so that resident memory counts only what is in use. */
void wrt_bake_memory_trim(void);
/* Refuses (WRT_ERR_NOMEM, a message naming the figures) when `need` bytes more than
 * what is resident now (after wrt_bake_memory_trim) would pass `budget_mb`; records the largest total (MB) in
 * *largest_mb. `what` names the stage in the message. */
wrt_status wrt_bake_memory_check(double budget_mb, double *largest_mb, uint64_t need, const char *what);

#endif
