/* cli.c: the command-line vocabulary shared by every wrt tool (see cli.h). */
#include "cli.h"

#include <errno.h>
#include <pthread.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "../common/limits.h"
#include "../common/text.h"
#include "../formats/gto.h"

void wrt_cli_exit_table(FILE *f) {
    fprintf(f,
            "exit codes (the same in every wrt tool):\n"
            "  0 ok                        4 interrupted (SIGINT/SIGTERM), after cleaning up\n"
            "  1 bad command line          5 accuracy not met\n"
            "  2 bad input (scene, .gto)   6 no display / OpenGL unavailable\n"
            "  3 output cannot be written  7 out of memory or internal error\n");
}

void wrt_cli_version(const char *tool) {
    printf("%s %s (.gto version %d)\n", tool, WRT_VERSION_STRING, WRT_GTO_VERSION);
}

static int bad(const char *tool, const char *opt, const char *val, const char *want) {
    if (!val) fprintf(stderr, "%s: error: %s needs a value (%s)\n", tool, opt, want);
    else fprintf(stderr, "%s: error: bad value for %s: '%s' (%s)\n", tool, opt, val, want);
    return 0;
}

int wrt_cli_int(const char *tool, const char *opt, const char *val, long lo, long hi, long *out) {
    char want[96];
    snprintf(want, sizeof want, "an integer in [%ld, %ld]", lo, hi);
    if (!val) return bad(tool, opt, val, want);
    char *end;
    errno = 0;
    long v = strtol(val, &end, 10);
    if (end == val || *end || errno || v < lo || v > hi) return bad(tool, opt, val, want);
    *out = v;
    return 1;
}

int wrt_cli_num(const char *tool, const char *opt, const char *val, double lo, double hi, double *out) {
    char want[96];
    snprintf(want, sizeof want, "a number in [%g, %g]", lo, hi);
    if (!val) return bad(tool, opt, val, want);
    char *end;
    errno = 0;
    double v = strtod(val, &end);
    if (end == val || *end || errno || !isfinite(v) || !(v >= lo && v <= hi)) return bad(tool, opt, val, want);
    *out = v;
    return 1;
}

int wrt_cli_vec3(const char *tool, const char *opt, const char *val, double out[3]) {
    /* positions, directions and colours alike: within what the computation can carry */
    if (!val || !wrt_parse_vec3(val, out) || !wrt_coord3_ok(out[0], out[1], out[2]))
        return bad(tool, opt, val, "three numbers X,Y,Z, each within +-1e9 (common/limits.h)");
    return 1;
}

/* ---------------------------------------------------------------- lights */

void wrt_cli_lights_init(wrt_cli_lights *L) {
    memset(L, 0, sizeof *L);
    for (int i = 0; i < WRT_CLI_MAX_LIGHTS; i++) L->scale[i] = 1;
}

int wrt_cli_lights_any(const wrt_cli_lights *L) {
    return L->which || L->has_pos || L->has_dir || L->has_cone || L->has_intensity || L->has_color || L->max_named;
}

static void name_light(wrt_cli_lights *L, long n) {
    if (n > L->max_named) L->max_named = (int)n;
}

int wrt_cli_lights_option(const char *tool, wrt_cli_lights *L, int argc, char **argv, int *i) {
    const char *a = argv[*i], *v = *i + 1 < argc ? argv[*i + 1] : NULL;
    int ok;
    long n;
    if (!strcmp(a, "--light")) {
        ok = wrt_cli_int(tool, a, v, 1, WRT_CLI_MAX_LIGHTS, &n);
        if (ok) { L->which = (int)n; name_light(L, n); }
    } else if (!strcmp(a, "--light-pos")) {
        ok = L->has_pos = wrt_cli_vec3(tool, a, v, L->pos);
    } else if (!strcmp(a, "--light-dir")) {
        ok = wrt_cli_vec3(tool, a, v, L->dir);
        if (ok && v3_len(v3(L->dir[0], L->dir[1], L->dir[2])) == 0) ok = bad(tool, a, v, "a non-zero direction");
        L->has_dir = ok;
    } else if (!strcmp(a, "--light-cone")) {
        char *end = NULL;
        double c[2] = {0, 0};
        ok = v != NULL;
        if (ok) {
            errno = 0;
            c[0] = strtod(v, &end);
            ok = end != v && *end == ',' && !errno;
            if (ok) {
                const char *s = end + 1;
                c[1] = strtod(s, &end);
                ok = end != s && *end == 0 && !errno;
            }
        }
        /* The lights carry cones as floats (the .gto, the library): 0.5,0.50000001 passed
         * here and was refused later by the library as "light 0" with exit 2. */
        if (!ok || !(c[0] >= 0 && (float)c[1] > (float)c[0] && c[1] <= WRT_PI / 2))
            ok = bad(tool, a, v, "IN,OUT radians with 0 <= IN < OUT <= pi/2, distinct as 32-bit floats");
        else { L->cone[0] = c[0]; L->cone[1] = c[1]; L->has_cone = 1; }
    } else if (!strcmp(a, "--light-intensity")) {
        ok = L->has_intensity = wrt_cli_num(tool, a, v, 0, WRT_MAX_LIGHT_INTENSITY, &L->intensity);
    } else if (!strcmp(a, "--light-color")) {
        ok = wrt_cli_vec3(tool, a, v, L->color);
        if (ok && !(L->color[0] >= 0 && L->color[1] >= 0 && L->color[2] >= 0 && L->color[0] <= WRT_MAX_COLOR &&
                    L->color[1] <= WRT_MAX_COLOR && L->color[2] <= WRT_MAX_COLOR))
            ok = bad(tool, a, v, "R,G,B each in [0, 1000] (common/limits.h)");
        L->has_color = ok;
    } else if (!strcmp(a, "--light-scale")) {
        ok = v != NULL;
        char *end = NULL;
        if (ok) { errno = 0; n = strtol(v, &end, 10); }
        double s = 0;
        if (!ok || end == v || *end != '=' || errno || n < 1 || n > WRT_CLI_MAX_LIGHTS) {
            ok = bad(tool, a, v, "N=S, light N (1-based) times S");
        } else {
            char full[64];
            snprintf(full, sizeof full, "%s (the factor)", a);
            ok = wrt_cli_num(tool, full, end + 1, 0, WRT_MAX_LIGHT_SCALE, &s);
        }
        if (ok) { L->scale[n - 1] = (float)s; L->scaled[n - 1] = 1; name_light(L, n); }
    } else if (!strcmp(a, "--lights-off")) {
        ok = v != NULL;
        const char *s = v;
        while (ok) {
            char *end;
            errno = 0;
            n = strtol(s, &end, 10);
            if (end == s || errno || n < 1 || n > WRT_CLI_MAX_LIGHTS || (*end && *end != ',')) { ok = 0; break; }
            L->scale[n - 1] = 0;
            L->scaled[n - 1] = 1;
            name_light(L, n);
            if (!*end) break;
            s = end + 1;
        }
        if (!ok) bad(tool, a, v, "light numbers N[,M..], 1-based");
    } else {
        return 0;
    }
    if (v) (*i)++;
    return ok ? 1 : -1;
}

int wrt_cli_lights_apply(const char *tool, const wrt_cli_lights *L, wrt_light *lights, int n, float *scales) {
    int which = L->which ? L->which : 1;
    for (int k = 0; k < WRT_CLI_MAX_LIGHTS; k++) {
        if (!L->scaled[k] || k < n) continue;
        fprintf(stderr, "%s: error: %s %d: the scene has %d light%s (lights are numbered from 1)\n", tool,
                L->scale[k] == 0 ? "--lights-off" : "--light-scale", k + 1, n, n == 1 ? "" : "s");
        return WRT_EXIT_USAGE;
    }
    int per_light = L->has_pos || L->has_dir || L->has_cone || L->has_intensity || L->has_color;
    if ((L->which || per_light) && which > n) {
        fprintf(stderr, "%s: error: --light %d: the scene has %d light%s (lights are numbered from 1)\n", tool, which, n,
                n == 1 ? "" : "s");
        return WRT_EXIT_USAGE;
    }
    if (per_light) {
        wrt_light *l = &lights[which - 1];
        if (l->type == WRT_LIGHT_DIRECTIONAL && (L->has_pos || L->has_cone)) {
            fprintf(stderr, "%s: %s: light %d ('%s') is a directional light (a sun), which has no %s; "
                    "--light-dir turns it\n", tool, L->has_pos ? "--light-pos" : "--light-cone", which, l->name,
                    L->has_pos ? "position" : "cone");
            return WRT_EXIT_USAGE;
        }
        if (L->has_dir && l->type == WRT_LIGHT_DIRECTIONAL && !(v3_len(v3(L->dir[0], L->dir[1], L->dir[2])) > 0)) {
            fprintf(stderr, "%s: --light-dir: a zero direction for the directional light %d\n", tool, which);
            return WRT_EXIT_USAGE;
        }
        if (L->has_dir && l->type == WRT_LIGHT_POINT && !L->has_cone) {
            fprintf(stderr,
                    "%s: error: --light-dir: light %d ('%s') is a point light, which shines every way; add "
                    "--light-cone IN,OUT to make it a spot light\n",
                    tool, which, l->name);
            return WRT_EXIT_USAGE;
        }
        if (L->has_pos) l->pos = v3(L->pos[0], L->pos[1], L->pos[2]);
        if (L->has_cone) {
            l->type = WRT_LIGHT_SPOT;
            l->inner_cone = (float)L->cone[0];
            l->outer_cone = (float)L->cone[1];
            if (!L->has_dir && !(v3_len(l->dir) > 0.5)) l->dir = v3(0, -1, 0);
        }
        if (L->has_dir) l->dir = v3_norm(v3(L->dir[0], L->dir[1], L->dir[2]));
        if (L->has_intensity) l->intensity = (float)L->intensity;
        if (L->has_color)
            for (int c = 0; c < 3; c++) l->color[c] = (float)L->color[c];
    }
    for (int k = 0; k < n; k++) {
        float s = k < WRT_CLI_MAX_LIGHTS ? L->scale[k] : 1;
        if (scales) scales[k] = s;
        else lights[k].intensity *= s;
    }
    return 0;
}

void wrt_cli_lights_help(FILE *f) {
    fprintf(f,
            "  --light N               the light the options below change (default 1; lights are\n"
            "                          numbered from 1, as --scan lists them)\n"
            "  --light-pos X,Y,Z       move it\n"
            "  --light-dir X,Y,Z       aim a spot light (a point light needs --light-cone too),\n"
            "                          or turn a sun: the way its light travels\n"
            "  --light-cone IN,OUT     make it a spot light with these cone angles (radians)\n"
            "  --light-intensity I     its intensity in candela (lux for a sun)\n"
            "  --light-color R,G,B     its colour, linear RGB\n"
            "  --light-scale N=S       multiply light N by S (repeatable)\n"
            "  --lights-off N[,M..]    switch lights off\n"
            "  A light number the scene does not have is refused (exit 1).\n");
}

/* ---------------------------------------------------------------- tone mapping, JSON */

static float srgb_encode(float x) {
    return x <= 0.0031308f ? 12.92f * x : 1.055f * powf(x, 1.0f / 2.4f) - 0.055f;
}

void wrt_tonemap_rgb8(const float *rgb, size_t npixels, float exposure_ev, uint8_t *out) {
    float s = exp2f(exposure_ev);
    for (size_t i = 0; i < npixels * 3; i++) {
        float x = rgb[i] * s;
        if (!(x > 0)) x = 0; /* also NaN */
        x = x / (1 + x);
        float e = srgb_encode(x) * 255.0f + 0.5f;
        out[i] = (uint8_t)(e > 255 ? 255 : e);
    }
}

void wrt_cli_json_str(FILE *f, const char *s) { wrt_json_str(f, s); } /* common/text.h */

void wrt_cli_print_safe(FILE *f, const char *s, size_t max) {
    const unsigned char *p = (const unsigned char *)(s ? s : "");
    size_t len = strnlen((const char *)p, max);
    char unit[WRT_SAFE_UNIT_MAX];
    for (size_t i = 0, ulen; i < len;) {
        i += wrt_text_safe_unit(p + i, len - i, 1, unit, &ulen); /* common/text.h */
        fwrite(unit, 1, ulen, f);
    }
}

int wrt_cli_print_safely(FILE *out, int (*print)(void *user, FILE *f), void *user) {
    char *buf = NULL;
    size_t len = 0;
    FILE *m = open_memstream(&buf, &len);
    if (!m) return print(user, out); /* no memory for the copy: as it is */
    int r = print(user, m);
    fclose(m);
    wrt_cli_print_safe(out, buf, len);
    free(buf);
    return r;
}

/* ---------------------------------------------------------------- stdout */

static const char *stdout_tool = "wrt";

static void check_stdout(void) {
    errno = 0;
    int bad = fflush(stdout) != 0;
    int e = errno;
    bad |= ferror(stdout) != 0;
    if (!bad) return;
    fprintf(stderr, "%s: error: cannot write the results to standard output: %s\n", stdout_tool,
            e ? strerror(e) : "an earlier write failed");
    _exit(WRT_EXIT_OUTPUT);
}

static void oom_exit(size_t bytes) {
    char msg[160]; /* no allocation on this path */
    int n = snprintf(msg, sizeof msg, "%s: error: out of memory allocating %zu bytes\n", stdout_tool, bytes);
    ssize_t w = write(2, msg, n > 0 ? (size_t)n : 0);
    (void)w;
    wrt_gto_remove_temporaries();
    _exit(WRT_EXIT_INTERNAL);
}

/* A crash while the shared libraries initialize, before main. Under an address-space
 * limit (ulimit -v, ~470 MB for the programs that link OpenImageIO) a constructor in one
 * of its dependencies dereferences a failed allocation: SIGSEGV, exit 139, no message.
 * The executable's .preinit_array runs before every library's initializer and installs
 * this handler; wrt_cli_init, first thing in main, restores the default. Only where an
 * address-space limit is set is the crash reported as out of memory (exit 7); without
 * one it is re-raised as it was. */
static struct sigaction before_segv, before_bus, before_abrt; /* as they were (a sanitizer's, say) */

static volatile sig_atomic_t in_main; /* wrt_cli_init has run */

#define WRT_MIN_STACK_KB 512 /* the least stack limit the programs start with */

static void early_crash(int sig) {
    struct rlimit rl;
    if (getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY) {
        char msg[240];
        int n = snprintf(msg, sizeof msg, "%s: error: out of memory: signal %d %s, under an address-space limit "
                         "of %llu MB\n", program_invocation_short_name, sig,
                         in_main ? "from a library (std::terminate: a thread or an allocation refused)"
                                 : "while the shared libraries initialized, before main",
                         (unsigned long long)(rl.rlim_cur >> 20));
        ssize_t w = write(2, msg, n > 0 ? (size_t)n : 0);
        (void)w;
        _exit(WRT_EXIT_INTERNAL); /* 7: out of memory */
    }
    sigaction(SIGSEGV, &before_segv, NULL);
    sigaction(SIGBUS, &before_bus, NULL);
    sigaction(SIGABRT, &before_abrt, NULL);
    raise(sig);
}

static void install_early_crash(int argc, char **argv, char **envp) {
    (void)argc; (void)argv; (void)envp;
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = early_crash;
    sigaction(SIGSEGV, &sa, &before_segv);
    sigaction(SIGBUS, &sa, &before_bus);
    /* libstdc++'s start-up under a tight limit ends in std::terminate, "terminate called
     * without an active exception", then abort (wrt-bake --version at 50 MB): the same case */
    sigaction(SIGABRT, &sa, &before_abrt);
}
__attribute__((section(".preinit_array"), used)) static void (*const wrt_cli_preinit)(int, char **, char **) =
    install_early_crash;

void wrt_cli_init(const char *tool) {
    stdout_tool = tool ? tool : "wrt";
    sigaction(SIGSEGV, &before_segv, NULL); /* main has started: a crash is no longer the libraries' start */
    sigaction(SIGBUS, &before_bus, NULL);
    /* Under an address-space limit a C++ library (Embree's threads) can still end in
     * std::terminate after main has started: that abort is the same out of memory (exit 7);
     * without a limit an abort is what it was. */
    struct rlimit rl;
    in_main = 1;
    if (!(getrlimit(RLIMIT_AS, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY)) sigaction(SIGABRT, &before_abrt, NULL);
    /* A stack limit (ulimit -s) far below the default 8 MB: at 64 KB a Cornell box bake
     * ended in SIGSEGV (exit 139, no message); glibc also sizes the worker threads'
     * stacks by it. Refused at the start, naming the limit (128 KB was measured enough
     * for the Cornell box; the bound leaves a margin for deeper scenes). */
    if (getrlimit(RLIMIT_STACK, &rl) == 0 && rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur < WRT_MIN_STACK_KB * 1024) {
        fprintf(stderr, "%s: error: the stack limit (ulimit -s) is %llu KB, below the %d KB wrt's programs need\n",
                stdout_tool, (unsigned long long)(rl.rlim_cur / 1024), WRT_MIN_STACK_KB);
        _exit(WRT_EXIT_INTERNAL);
    }
    atexit(check_stdout);
    wrt_set_oom_handler(oom_exit);
    /* A file size limit (ulimit -f) must fail the write (EFBIG), which every output path
     * reports and cleans up (exit 3), instead of killing the program mid-write with its
     * temporary left behind and no message. */
    signal(SIGXFSZ, SIG_IGN);
}

/* ---------------------------------------------------------------- progress */

/* The state of the line, and a thread that redraws it every half second, so that its
 * elapsed time moves while a phase gives no news (the balance). */
static struct {
    int on, active;
    char phase[32];
    double start, last, done;
    pthread_mutex_t mu;
    pthread_t ticker;
    int ticking;
} prog = {.mu = PTHREAD_MUTEX_INITIALIZER};

static void draw(int final);

static void *tick(void *arg) {
    (void)arg;
    for (;;) {
        struct timespec ts = {0, 500000000L};
        nanosleep(&ts, NULL);
        pthread_mutex_lock(&prog.mu);
        if (prog.on && prog.active && wrt_now() - prog.last >= 0.45) {
            prog.last = wrt_now();
            draw(0);
        }
        pthread_mutex_unlock(&prog.mu);
    }
    return NULL;
}

void wrt_cli_progress_enable(int on) {
    pthread_mutex_lock(&prog.mu);
    prog.on = on;
    if (on && !prog.ticking && pthread_create(&prog.ticker, NULL, tick, NULL) == 0) {
        pthread_detach(prog.ticker);
        prog.ticking = 1;
    }
    pthread_mutex_unlock(&prog.mu);
}
int wrt_cli_progress_enabled(void) { return prog.on; }
static void fmt_secs(char *b, size_t n, double s) {
    if (s < 60) snprintf(b, n, "%.1f s", s);
    else snprintf(b, n, "%d:%02d min", (int)(s / 60), (int)fmod(s, 60));
}

static void draw(int final) {
    double now = wrt_now(), el = now - prog.start;
    char e[32], left[48] = "";
    fmt_secs(e, sizeof e, el);
    fprintf(stderr, "\r  %-8s ", prog.phase);
    if (prog.done >= 0 || final) {
        double d = final ? 1 : prog.done;
        int w = 30, k = (int)(d * w + 0.5);
        fputc('[', stderr);
        for (int i = 0; i < w; i++) fputc(i < k ? '#' : '.', stderr);
        fprintf(stderr, "] %3.0f%%", 100 * d);
        if (!final && d > 0.02 && d < 1 && el > 0.5) {
            char r[32];
            fmt_secs(r, sizeof r, el * (1 - d) / d);
            snprintf(left, sizeof left, "  ~%s left", r);
        }
    } else {
        fprintf(stderr, "%-37s", "...");
    }
    fprintf(stderr, "  %9s%-18s", e, final ? "  done" : left);
    if (final) fputc('\n', stderr);
    fflush(stderr);
}

static void end_locked(void) {
    if (prog.on && prog.active) draw(1);
    prog.active = 0;
}

void wrt_cli_progress_end(void) {
    pthread_mutex_lock(&prog.mu);
    end_locked();
    pthread_mutex_unlock(&prog.mu);
}

void wrt_cli_progress(const char *phase, double done) {
    if (!prog.on) return;
    pthread_mutex_lock(&prog.mu);
    double now = wrt_now();
    if (!prog.active || strncmp(prog.phase, phase, sizeof prog.phase - 1)) {
        end_locked();
        snprintf(prog.phase, sizeof prog.phase, "%s", phase);
        prog.start = now;
        prog.last = 0;
        prog.active = 1;
    }
    prog.done = done > 1 ? 1 : done;
    if (now - prog.last >= 0.1) {
        prog.last = now;
        draw(0);
    }
    pthread_mutex_unlock(&prog.mu);
}
