/* headless.c: wrt-play's scripted runs: --script (a keyframe file read and checked,
 * lights and camera interpolated per frame, one picture per frame named by
 * --out-pattern) and --bench (frames with a light moving, per-stage times, medians).
 * Each frame is drawn by main.c's run_frame and saved by its save_picture (play.h).
 * Depends on player/play.h (the application state), common/text.h (JSON strings) and
 * player/render.h. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/limits.h"
#include "../common/text.h"
#include "play.h"

static int parse_num(const char *s, double lo, double hi, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno || !(v >= lo && v <= hi)) return 0;
    *out = v;
    return 1;
}


/* Expands a pattern with one %d / %0Nd (and %% for a percent sign); 0 if malformed. */
static int format_frame(const char *pat, int frame, char *out, size_t n) {
    size_t o = 0;
    int used = 0;
    for (const char *p = pat; *p; p++) {
        char piece[32];
        if (*p != '%') { piece[0] = *p; piece[1] = 0; }
        else if (p[1] == '%') { strcpy(piece, "%"); p++; }
        else {
            p++;
            int zero = 0, width = 0;
            if (*p == '0') { zero = 1; p++; }
            while (isdigit((unsigned char)*p) && width < 100) width = width * 10 + (*p++ - '0');
            if (*p != 'd' || used || width > 20) return 0;
            used = 1;
            snprintf(piece, sizeof piece, zero ? "%0*d" : "%*d", width, frame);
        }
        size_t l = strlen(piece);
        if (o + l + 1 > n) return 0;
        memcpy(out + o, piece, l);
        o += l;
    }
    out[o] = 0;
    return used;
}

/* ---------------------------------------------------------------- script */

typedef struct keyframe {
    double t;
    double lpos[3], ldir[3], lint, cpos[3], ctarget[3];
} keyframe;

/* One line of a script into line (cap bytes, the newline dropped): 1 a line, 0 the end,
 * -1 a line that is too long or holds a NUL byte (not a text file: /dev/zero gave an
 * endless run of empty lines), -2 a read error. */
static int script_line(FILE *f, char *line, size_t cap) {
    size_t n = 0;
    int c;
    while ((c = getc(f)) != EOF && c != '\n') {
        if (c == 0 || n + 1 >= cap) return -1;
        line[n++] = (char)c;
    }
    line[n] = 0;
    if (c == EOF && ferror(f)) return -2;
    return c == EOF && n == 0 ? 0 : 1;
}

#define MAX_KEYFRAMES 100000 /* as many as frames a script may ask for */

static int read_script(app *a, const char *path, keyframe **out, int *count) {
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "wrt-play: error: cannot read the script %s: %s\n", path, strerror(errno));
        return EXIT_INPUT;
    }
    keyframe cur;
    memset(&cur, 0, sizeof cur);
    for (int k = 0; k < 3; k++) {
        cur.lpos[k] = a->lights[chosen_light(a)].position[k];
        cur.ldir[k] = a->lights[chosen_light(a)].direction[k];
        cur.cpos[k] = a->view.eye[k];
        cur.ctarget[k] = a->view.target[k];
    }
    cur.lint = a->lights[chosen_light(a)].intensity;
    keyframe *kf = NULL;
    int n = 0, cap = 0, lineno = 0;
    char line[4096];
    int got;
    while ((got = script_line(f, line, sizeof line)) != 0) {
        lineno++;
        if (got < 0) {
            if (got == -1)
                fprintf(stderr, "wrt-play: error: %s:%d: a line longer than %zu bytes or holding a NUL byte: "
                        "a script is text\n", path, lineno, sizeof line - 1);
            else
                fprintf(stderr, "wrt-play: error: %s: cannot read the script: %s\n", path, strerror(errno));
            goto fail;
        }
        if (n == MAX_KEYFRAMES) {
            fprintf(stderr, "wrt-play: error: %s:%d: more than %d keyframes\n", path, lineno, MAX_KEYFRAMES);
            goto fail;
        }
        char *hash = strchr(line, '#');
        if (hash) *hash = 0;
        char *save = NULL, *tok = strtok_r(line, " \t\r\n", &save);
        if (!tok) continue;
        double t;
        if (!parse_num(tok, -1e12, 1e12, &t)) goto bad_line;
        if (n > 0 && t < kf[n - 1].t) {
            fprintf(stderr, "wrt-play: error: %s:%d: times must not decrease\n", path, lineno);
            goto fail;
        }
        cur.t = t;
        while ((tok = strtok_r(NULL, " \t\r\n", &save))) {
            const char *key = tok;
            double *dst = NULL;
            int nv = 3;
            if (!strcmp(tok, "light_pos")) dst = cur.lpos;
            else if (!strcmp(tok, "light_dir")) dst = cur.ldir;
            else if (!strcmp(tok, "camera_pos")) dst = cur.cpos;
            else if (!strcmp(tok, "camera_target")) dst = cur.ctarget;
            else if (!strcmp(tok, "light_intensity")) { dst = &cur.lint; nv = 1; }
            else {
                char safe[96]; /* text from the file, shown escaped (common/text.h) */
                fprintf(stderr, "wrt-play: error: %s:%d: unknown key '%s'\n", path, lineno,
                        wrt_text_safe(safe, sizeof safe, tok));
                goto fail;
            }
            for (int k = 0; k < nv; k++) {
                tok = strtok_r(NULL, " \t\r\n", &save);
                /* within what the computation can carry (common/limits.h) */
                if (!tok || (nv == 1 ? !parse_num(tok, 0, WRT_MAX_LIGHT_INTENSITY, &dst[k])
                                     : !parse_num(tok, -WRT_MAX_COORD, WRT_MAX_COORD, &dst[k]))) {
                    fprintf(stderr, "wrt-play: error: %s:%d: %s needs %s\n", path, lineno, key,
                            nv == 1 ? "an intensity in [0, 1e12] cd" : "three numbers, each within +-1e9");
                    goto fail;
                }
            }
        }
        if (n == cap) {
            cap = cap ? 2 * cap : 16;
            kf = wrt_xrealloc(kf, (size_t)cap * sizeof *kf);
        }
        kf[n++] = cur;
        continue;
    bad_line:
        fprintf(stderr, "wrt-play: error: %s:%d: expected 't key values...' (see --help)\n", path, lineno);
        goto fail;
    }
    fclose(f);
    if (n == 0) {
        fprintf(stderr, "wrt-play: error: %s: no keyframes\n", path);
        free(kf);
        return EXIT_INPUT;
    }
    *out = kf;
    *count = n;
    return 0;
fail:
    fclose(f);
    free(kf);
    return EXIT_INPUT;
}

static void apply_keyframe(app *a, const keyframe *k0, const keyframe *k1, double s) {
    wrt_runtime_light *l = &a->lights[chosen_light(a)];
    double lp[3], ld[3];
    for (int k = 0; k < 3; k++) {
        lp[k] = k0->lpos[k] + (k1->lpos[k] - k0->lpos[k]) * s;
        ld[k] = k0->ldir[k] + (k1->ldir[k] - k0->ldir[k]) * s;
        a->view.eye[k] = k0->cpos[k] + (k1->cpos[k] - k0->cpos[k]) * s;
        a->view.target[k] = k0->ctarget[k] + (k1->ctarget[k] - k0->ctarget[k]) * s;
    }
    light_set_pos(l, v3(lp[0], lp[1], lp[2]));
    wrt_v3 d = v3_norm(v3(ld[0], ld[1], ld[2]));
    if (v3_len(d) > 0.5) light_set_dir(l, d);
    l->intensity = (float)(k0->lint + (k1->lint - k0->lint) * s);
}

/* The most pictures one --script run writes. */
#define WRT_PLAY_MAX_FRAMES 100000

int run_script(app *a) {
    keyframe *kf = NULL;
    int n = 0, rc = read_script(a, a->o->script, &kf, &n);
    if (rc) return rc;
    double fps = a->o->script_fps;
    /* bounded: a keyframe at t = 1e6 with --script-fps 1000 asked for 10^9 pictures */
    double want = fps > 0 ? floor((kf[n - 1].t - kf[0].t) * fps + 1e-9) + 1 : n;
    if (!(want <= WRT_PLAY_MAX_FRAMES)) {
        fprintf(stderr, "wrt-play: error: %s: the keyframes ask for %.4g frames (t %g to %g s%s); at most %d\n",
                a->o->script, want, kf[0].t, kf[n - 1].t, fps > 0 ? " at --script-fps" : "", WRT_PLAY_MAX_FRAMES);
        free(kf);
        return EXIT_INPUT;
    }
    int frames = (int)want;
    char path[4096];
    if (!format_frame(a->o->pattern, 0, path, sizeof path)) {
        fprintf(stderr, "wrt-play: error: --out-pattern '%s' needs exactly one %%d or %%0Nd\n", a->o->pattern);
        free(kf);
        return EXIT_USAGE;
    }
    for (int i = 0; i < frames && !rc; i++) {
        if (fps > 0) {
            double t = kf[0].t + i / fps;
            int j = 0;
            while (j + 1 < n && kf[j + 1].t <= t) j++;
            if (j + 1 < n && kf[j + 1].t > kf[j].t) apply_keyframe(a, &kf[j], &kf[j + 1], (t - kf[j].t) / (kf[j + 1].t - kf[j].t));
            else apply_keyframe(a, &kf[j], &kf[j], 0);
        } else {
            apply_keyframe(a, &kf[i], &kf[i], 0);
        }
        stage_ms t;
        if ((rc = run_frame(a, &t))) break;
        format_frame(a->o->pattern, i, path, sizeof path);
        rc = save_picture(a, path);
    }
    if (!rc) fprintf(stderr, "wrt-play: wrote %d frames\n", frames);
    free(kf);
    return rc;
}

/* ---------------------------------------------------------------- bench */

static int cmp_double(const void *x, const void *y) {
    double a = *(const double *)x, b = *(const double *)y;
    return a < b ? -1 : a > b;
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

int run_bench(app *a) {
    int n = a->o->bench;
    double *col[7];
    for (int k = 0; k < 7; k++) col[k] = wrt_xmalloc((size_t)n * sizeof(double));
    wrt_runtime_light *l = &a->lights[chosen_light(a)];
    wrt_v3 c = light_pos(l), up, e1, e2;
    scene_up(a, &up);
    e1 = v3_norm(v3_cross(up, fabs(up.x) < 0.9 ? v3(1, 0, 0) : v3(0, 0, 1)));
    e2 = v3_cross(up, e1);
    double lo[3], hi[3];
    scene_bounds(a, lo, hi);
    double radius = 0.05 * v3_len(v3(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]));
    wrt_v3 d0 = light_dir(l), h0 = v3_sub(d0, v3_scale(up, v3_dot(d0, up))); /* a sun's direction, horizontal part */
    /* one warm-up frame: the first relight projects every light and uploads every quad */
    stage_ms t;
    int rc = run_frame(a, &t);
    double first = t.frame, worst = 0;
    int npending = 0;
    wrt_runtime_update_stats us0, us;
    wrt_runtime_get_update_stats(a->rl, &us0, NULL);
    double t0 = wrt_now();
    for (int i = 0; i < n && !rc; i++) {
        double ang = 2 * WRT_PI * (i + 1) / (n < 8 ? 8 : n);
        if (l->kind == WRT_LIGHT_KIND_DIRECTIONAL) /* a sun turns: its direction about up, 2 degrees a frame */
            light_set_dir(l, v3_norm(v3_add(v3_scale(up, v3_dot(d0, up)),
                                    v3_add(v3_scale(h0, cos(2 * WRT_PI / 180 * (i + 1))),
                                           v3_scale(v3_cross(up, h0), sin(2 * WRT_PI / 180 * (i + 1)))))));
        else
            light_set_pos(l, v3_add(c, v3_add(v3_scale(e1, radius * cos(ang) - radius), v3_scale(e2, radius * sin(ang)))));
        rc = run_frame(a, &t);
        col[0][i] = t.projection;
        col[1][i] = t.multiply;
        col[2][i] = t.brdf;
        col[3][i] = t.synthesis;
        col[4][i] = t.upload;
        col[5][i] = t.draw;
        col[6][i] = t.frame;
        wrt_runtime_get_update_stats(a->rl, &us, NULL);
        npending += us.pending;
        double upd = t.projection + t.multiply + t.brdf + t.synthesis;
        if (upd > worst) worst = upd;
    }
    double total = wrt_now() - t0;
    wrt_runtime_update_stats us1;
    wrt_runtime_get_update_stats(a->rl, &us1, NULL);
    if (!rc) {
        const char *names[7] = {"projection", "multiply", "brdf", "synthesis", "upload", "draw", "frame"};
        printf("{\"frames\": %d, \"width\": %d, \"height\": %d, \"mode\": \"%s\", \"quads\": %u, "
               "\"funcs\": %u, \"nnz\": %llu, \"threads\": %d, \"msaa\": %d, \"first_frame_ms\": %.3f, \"median_ms\": {",
               n, a->o->width, a->o->height, wrt_render_mode_name(a->mode), a->nquads, (unsigned)a->info.functions,
               a->info.entries, a->o->threads, wrt_render_samples(a->rd), first);
        double med_frame = 0;
        for (int k = 0; k < 7; k++) {
            double m = median(col[k], n);
            if (k == 6) med_frame = m;
            printf("%s\"%s\": %.3f", k ? ", " : "", names[k], m);
        }
        printf("}, \"fps\": %.2f, \"fps_mean\": %.2f, ", med_frame > 0 ? 1e3 / med_frame : 0.0, n / total);
        /* the time budget and skip_below (wrt_runtime_set_budget): the slowest update, the
         * frames that left work pending, and the work done over the frames */
        printf("\"budget_ms\": %g, \"skip_below\": %g, \"max_update_ms\": %.3f, \"frames_pending\": %d, "
               "\"skipped\": %lld, \"multiplies\": %lld, \"quads_synthesized\": %lld, \"renderer\": ",
               a->o->budget_ms, a->o->skip_below, worst, npending, us1.skips - us0.skips, us1.multiplies - us0.multiplies,
               us1.quads_synthesized - us0.quads_synthesized);
        wrt_json_str(stdout, wrt_render_gl_info());
        printf("}\n");
    }
    for (int k = 0; k < 7; k++) free(col[k]);
    return rc;
}

