/* wrt_common.c: status text, thread-local last error, logging sink, checked
 * allocation, clock and hash. See wrt_common.h. */
#define _POSIX_C_SOURCE 200809L
#include "wrt_common.h"
#include "text.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static const char *const status_text[WRT_STATUS_COUNT] = {
    "ok", "i/o error", "not a wrt file", "corrupt file", "unsupported version or feature",
    "malformed input", "bad geometry", "invalid argument", "out of memory", "cancelled",
    "accuracy not met", "graphics error",
};

const char *wrt_status_str(wrt_status s) {
    return (s >= 0 && s < WRT_STATUS_COUNT) ? status_text[s] : "unknown status";
}

static _Thread_local char last_error[1024];

/* Every error and log message is made safe for a terminal where it is formed: names and
 * paths from files can hold escape codes, newlines or invalid UTF-8 (common/text.h). */
wrt_status wrt_fail(wrt_status s, const char *fmt, ...) {
    char raw[sizeof last_error];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(raw, sizeof raw, fmt, ap);
    va_end(ap);
    wrt_text_safe(last_error, sizeof last_error, raw);
    return s;
}

const char *wrt_last_error(void) { return last_error; }
void wrt_clear_error(void) { last_error[0] = 0; }

static wrt_log_sink log_sink;
static void *log_user;
static int log_verbosity = WRT_LOG_WARN;

void wrt_log_set_sink(wrt_log_sink sink, void *user) { log_sink = sink; log_user = user; }
void wrt_log_set_verbosity(int level) { log_verbosity = level; }

void wrt_log(int level, const char *fmt, ...) {
    char raw[1024], buf[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(raw, sizeof raw, fmt, ap);
    va_end(ap);
    wrt_text_safe(buf, sizeof buf, raw);
    if (log_sink) {
        log_sink(log_user, level, buf);
        return;
    }
    if (level > log_verbosity) return;
    static const char *const names[] = {"error", "warning", "info", "debug"};
    fprintf(stderr, "wrt: %s: %s\n", names[level < 0 ? 0 : level > 3 ? 3 : level], buf);
}

static wrt_oom_handler oom_handler;

void wrt_set_oom_handler(wrt_oom_handler h) { oom_handler = h; }

static void oom(size_t n) {
    if (oom_handler) oom_handler(n); /* does not return */
    fprintf(stderr, "wrt: error: out of memory allocating %zu bytes\n", n);
    abort();
}

void *wrt_xmalloc(size_t n) {
    void *p = malloc(n ? n : 1);
    if (!p) oom(n);
    return p;
}

void *wrt_xcalloc(size_t count, size_t size) {
    void *p = calloc(count ? count : 1, size ? size : 1);
    if (!p) oom(count * size);
    return p;
}

void *wrt_xcalloc_aligned64(size_t n) {
    size_t bytes = (n + 63) / 64 * 64; /* aligned_alloc wants a multiple of the alignment */
    if (!bytes) bytes = 64;
    void *p = aligned_alloc(64, bytes);
    if (!p) oom(bytes);
    memset(p, 0, bytes);
    return p;
}

void *wrt_xrealloc(void *p, size_t n) {
    void *q = realloc(p, n ? n : 1);
    if (!q) oom(n);
    return q;
}

double wrt_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

uint64_t wrt_hash64(const void *data, size_t n, uint64_t seed) {
    const unsigned char *p = data;
    uint64_t h = seed;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

int wrt_parse_vec3(const char *s, double v[3]) {
    char *end;
    for (int i = 0; i < 3; i++) {
        errno = 0;
        v[i] = strtod(s, &end);
        if (end == s || errno || !isfinite(v[i])) return 0;
        s = end;
        if (i < 2) {
            if (*s != ',') return 0;
            s++;
        }
    }
    return *s == 0;
}
