/* wrt_common.h: status codes, error reporting, logging, small vector math and
 * allocation helpers shared by every part of wrt (bake, player, tools, tests).
 * Depends on the C standard library only. Thread-safety: the last-error buffer
 * is thread-local; the log sink is global and must be set before threads start. */
#ifndef WRT_COMMON_H
#define WRT_COMMON_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "../include/wrt.h"

/* WRT_VERSION_STRING and the other version macros: include/wrt.h. */
#define WRT_PI 3.14159265358979323846

/* 2^e, the same double as ldexp(1.0, e), made from its exponent bits where it is a
 * normal number: the bake takes cell sizes and areas 2^-l millions of times, and the
 * library call was 3% of a maze bake (perf) */
static inline double wrt_pow2(int e) {
    if (e < -1022 || e > 1023) return ldexp(1.0, e);
    union { uint64_t u; double d; } b = {.u = (uint64_t)(e + 1023) << 52};
    return b.d;
}

/* Every fallible function returns a wrt_status (include/wrt.h, the public header, defines
 * it and wrt_status_str); details go to wrt_last_error(). */

/* Sets the calling thread's last error message (printf-style) and returns `s`,
 * so that `return wrt_fail(WRT_ERR_PARSE, "x: %d", n);` reads naturally. */
wrt_status wrt_fail(wrt_status s, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* The calling thread's last error message ("" if none). Valid until the next wrt_fail. */
const char *wrt_last_error(void);
void wrt_clear_error(void);

/* Logging. Levels: 0 error, 1 warning, 2 info, 3 debug. Default sink writes
 * "wrt: warning: ..." to stderr for levels <= the verbosity (default 1). A sink takes
 * the user pointer first, as every callback in wrt (include/wrt.h). */
typedef void (*wrt_log_sink)(void *user, int level, const char *msg);
void wrt_log_set_sink(wrt_log_sink sink, void *user); /* NULL restores the default */
void wrt_log_set_verbosity(int level);
void wrt_log(int level, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
#define WRT_LOG_ERROR 0
#define WRT_LOG_WARN 1
#define WRT_LOG_INFO 2
#define WRT_LOG_DEBUG 3

/* Allocation that never returns NULL for n > 0: on exhaustion it calls the out-of-memory
 * handler, which must not return (default: a message and abort(); the programs install
 * one that exits with their documented code 7, cli/cli.h). */
typedef void (*wrt_oom_handler)(size_t bytes);
void wrt_set_oom_handler(wrt_oom_handler h); /* NULL restores the default; set before threads start */
void *wrt_xmalloc(size_t n);
void *wrt_xcalloc(size_t count, size_t size);
void *wrt_xrealloc(void *p, size_t n);
/* n zeroed bytes on a 64-byte boundary (a cache line), released with free() */
void *wrt_xcalloc_aligned64(size_t n);

/* Monotonic wall-clock seconds. */
double wrt_now(void);

/* ---- 3-vectors in double precision (geometry is computed in double) ---- */
typedef struct wrt_v3 { double x, y, z; } wrt_v3;

static inline wrt_v3 v3(double x, double y, double z) { wrt_v3 r = {x, y, z}; return r; }
static inline wrt_v3 v3_add(wrt_v3 a, wrt_v3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline wrt_v3 v3_sub(wrt_v3 a, wrt_v3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline wrt_v3 v3_scale(wrt_v3 a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline wrt_v3 v3_mad(wrt_v3 a, wrt_v3 b, double s) { return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline double v3_dot(wrt_v3 a, wrt_v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline wrt_v3 v3_cross(wrt_v3 a, wrt_v3 b) {
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double v3_len(wrt_v3 a) { return sqrt(v3_dot(a, a)); }
static inline wrt_v3 v3_norm(wrt_v3 a) {
    double l = v3_len(a);
    return l > 0 ? v3_scale(a, 1.0 / l) : a;
}
static inline int v3_finite(wrt_v3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

/* Parses "X,Y,Z" (three finite numbers, nothing else) into v; returns 1 on success. */
int wrt_parse_vec3(const char *s, double v[3]);

/* FNV-1a 64-bit over bytes, for provenance hashes and checksums. */
uint64_t wrt_hash64(const void *data, size_t n, uint64_t seed);
#define WRT_HASH_SEED 0xcbf29ce484222325ULL

#endif
