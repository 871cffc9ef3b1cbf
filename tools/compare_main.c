/* compare_main.c: wrt-compare, how far bakes are from the path-traced reference
 * (verify/compare.h). Loads the scene, path-traces the reference once for a few light
 * positions, compares every .gto given with it, and prints one JSON object on stdout
 * (progress on stderr). With --max-error E it is the pipeline's accuracy check: exit
 * code 5 when a bake's cell-average error (mean over the lights, reference noise
 * included, so the check errs on the safe side) exceeds E. The measurement of the
 * accuracy/time study (paper section 6). */
#include "verify/compare.h"
#include "cli/cli.h"
#include "common/outfile.h"

#include "cli/font.h"
#include "formats/image.h"

#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: wrt-compare SCENE.gltf FILE.gto [FILE.gto ...] [options]\n"
            "Compares bakes of SCENE with a path-traced reference; prints one JSON object.\n"
            "It compares one light at a time: light 1 (or the one --light names) at its own\n"
            "position and at K-1 positions moved inside the bounding box.\n"
            "  --lights K          positions of the light (default 5)\n"
            "  --light-pos X,Y,Z   a position of the light (repeatable; replaces the defaults)\n"
            "Light changes (as in wrt-play and wrt-ref):\n");
    wrt_cli_lights_help(f);
    fprintf(f,
            "Measurement:\n"
            "  --cells N           cells per quad side (default 4)\n"
            "  --cell-paths N      reference paths per light over all cells (default 2000000)\n"
            "  --pilot N           paths per cell of the pilot pass (default 32)\n"
            "  --width W           image width, the height follows the camera (default 96)\n"
            "  --spp N             reference paths per pixel (default 512)\n"
            "  --sub N             camera rays per pixel side for the bake's image (default 4;\n"
            "                      the study uses 16: at 4, pixels across a crease or an edge\n"
            "                      weigh its two sides unlike the path tracer's pixel integral)\n"
            "  --no-image          compare cell averages only\n"
            "  --bench N           timed light changes for the median (default 21)\n"
            "  --bench-only        no reference: only time the light changes of each bake\n"
            "  --threads N         0 = all cores (default)\n"
            "  --seed S            reference seed (default 1)\n"
            "  -o, --out PREFIX    write PREFIX_{wavelet,haar,reference}.exr/.png and\n"
            "                      PREFIX_panel.png (Haar | smooth | reference | error map,\n"
            "                      labelled, each at least 320 pixels wide)\n"
            "                      of the first position and the last bake (--images is the same)\n"
            "  --closeup X,Y,S     with --out: PREFIX_closeup.png, the S x S pixels at X, Y of\n"
            "                      the Haar and the smooth display, 4x enlarged\n"
            "  --exposure EV       the PNGs' exposure in stops (default 0), wrt-play's curve\n"
            "  --max-error E       exit 5 if a bake's cell rmse exceeds E (pipeline check)\n"
            "  --per-quad          add each quad's mean indirect irradiance (first light), wavelet\n"
            "                      and reference, to each bake's figures\n"
            "Display of glossy quads, for before/after figures (default: the player's):\n"
            "  --no-final-gather   the coarse angular synthesis only, no final gather\n"
            "  --no-light-splat    the light's direction truncated to its angular cell, not\n"
            "                      spread over one cell centred on it (a bake without K)\n"
            "  --gather-points N   16 or 32 gather points a side on every glossy quad\n"
            "  --linear-display    the linear smooth display (textures superpose across lights;\n"
            "                      no slope limiter, no clamp: libwrt's linear_display)\n"
            "  --version, -h, --help\n"
            "\n");
    wrt_cli_exit_table(f);
}

static int parse_long(const char *s, long lo, long hi, long *out) {
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno || v < lo || v > hi) return 0;
    *out = v;
    return 1;
}

static int parse_double(const char *s, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (end == s || *end || errno || !isfinite(v)) return 0;
    *out = v;
    return 1;
}

static void json_errors(FILE *f, const wrt_compare_light_result *r) {
    printf("\"cell_rmse\":%.6g,\"cell_floor\":%.6g,\"cell_rmse_debiased\":%.6g,", r->cell_rmse, r->cell_floor,
           r->cell_debiased);
    printf("\"image_rmse\":%.6g,\"image_floor\":%.6g,\"image_rmse_debiased\":%.6g,\"cell_ratio\":%.6g,",
           r->image_rmse, r->image_floor, r->image_debiased, r->cell_ratio);
    printf("\"cell_rmse_smooth\":%.6g,\"cell_rmse_smooth_debiased\":%.6g,\"image_rmse_haar\":%.6g,"
           "\"image_rmse_haar_debiased\":%.6g,",
           r->cell_rmse_smooth, r->cell_debiased_smooth, r->image_rmse_haar, r->image_debiased_haar);
    printf("\"seam_across\":%.6g,\"seam_inside\":%.6g,\"seam_across_haar\":%.6g,\"seam_inside_haar\":%.6g",
           r->seam_across, r->seam_inside, r->seam_across_haar, r->seam_inside_haar);
    (void)f;
}

/* Error heat map colour of t in [0, 1]: black, blue, red, yellow, white. */
static void heat(double t, uint8_t *px) {
    static const double k[5][3] = {{0, 0, 0}, {0.1, 0.2, 0.9}, {0.9, 0.1, 0.1}, {1, 0.9, 0.1}, {1, 1, 1}};
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double f = t * 4;
    int i = f >= 4 ? 3 : (int)f;
    double a = f - i;
    for (int c = 0; c < 3; c++) px[c] = (uint8_t)lround(255 * (k[i][c] * (1 - a) + k[i + 1][c] * a));
}

static int write_png(const char *prefix, const char *name, const uint8_t *px, int w, int h) {
    char path[4096];
    snprintf(path, sizeof path, "%s_%s.png", prefix, name);
    if (wrt_image_write_rgb8(path, px, w, h) == WRT_OK) return 0;
    fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
    return WRT_EXIT_OUTPUT;
}

/* PREFIX_panel.png from the four w x h pictures side by side in `panel`: each enlarged
 * by a whole factor (nearest pixel) to at least PANEL_MIN_W pixels wide, 4 pixels apart
 * on dark grey, under a bar naming it. */
#define PANEL_MIN_W 320
static int write_labelled_panel(const char *prefix, const uint8_t *panel, int w, int h) {
    static const char *const label[4] = {"Haar cells", "smooth display", "path tracer", "error, 0 to 50% of mean"};
    int k = w >= PANEL_MIN_W ? 1 : (PANEL_MIN_W + w - 1) / w, gap = 4, fs = 2, bar = WRT_FONT_CELL_H * fs + 6;
    int pw = w * k, W = 4 * pw + 3 * gap, H = bar + h * k;
    uint8_t *out = wrt_xmalloc((size_t)W * H * 3);
    memset(out, 40, (size_t)W * H * 3);
    static const uint8_t white[3] = {235, 235, 235};
    for (int s = 0; s < 4; s++) {
        int x0 = s * (pw + gap), tw, th;
        /* the label, shortened to the picture's width */
        char text[64];
        snprintf(text, sizeof text, "%s", label[s]);
        wrt_font_measure(text, fs, &tw, &th);
        while (tw > pw && strlen(text) > 1) {
            text[strlen(text) - 1] = 0;
            wrt_font_measure(text, fs, &tw, &th);
        }
        wrt_font_draw_rgb8(out, W, H, x0 + (pw - tw) / 2, 3, fs, white, text);
        for (int y = 0; y < h * k; y++)
            for (int x = 0; x < pw; x++)
                memcpy(out + ((size_t)(bar + y) * W + x0 + x) * 3, panel + ((size_t)(y / k) * 4 * w + (size_t)s * w + x / k) * 3, 3);
    }
    int rc = write_png(prefix, "panel", out, W, H);
    free(out);
    return rc;
}

/* The first light's images as EXR (linear) and PNG (the tone curve of every tool's PNG,
 * cli/cli.h, so that they can be put beside wrt-play's and wrt-ref's): the bake's display
 * (wavelet: smooth; haar: the Haar cells as blocks), the reference, and
 * PREFIX_panel.png: haar | wavelet | reference | error heat map of the smooth display
 * (|wavelet - reference| over RGB relative to the reference's mean: black 0, white 50%
 * and above), labelled and enlarged (write_labelled_panel); with `closeup` (X, Y, S) PREFIX_closeup.png, the Haar and smooth panels'
 * S x S pixels at X, Y enlarged 4 times. Returns 0 or WRT_EXIT_OUTPUT. */
static int write_images(const char *prefix, const wrt_compare_ref *c, int w, int h, double exposure,
                        const double *closeup) {
    const float *img[3] = {wrt_compare_image(c, 0, 1), wrt_compare_image(c, 0, 0), wrt_compare_image(c, 0, 2)};
    const char *name[3] = {"wavelet", "reference", "haar"};
    static const int slot[3] = {1, 2, 0}; /* panel order: haar, wavelet, reference, error */
    if (!img[0] || !img[1] || !img[2]) return 0;
    size_t n = (size_t)w * h;
    uint8_t *px = wrt_xmalloc(n * 3), *panel = wrt_xmalloc(n * 3 * 4);
    int rc = 0;
    double mean = 0;
    for (size_t i = 0; i < n * 3; i++) mean += img[1][i] / (double)(n * 3);
    for (int k = 0; k < 3; k++) {
        char path[4096];
        snprintf(path, sizeof path, "%s_%s.exr", prefix, name[k]);
        if (wrt_image_write_exr(path, img[k], w, h) != WRT_OK) {
            fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
            rc = WRT_EXIT_OUTPUT;
        }
        wrt_tonemap_rgb8(img[k], n, (float)exposure, px);
        for (int y = 0; y < h; y++)
            memcpy(panel + ((size_t)y * 4 * w + (size_t)slot[k] * w) * 3, px + (size_t)y * w * 3, (size_t)w * 3);
        if (write_png(prefix, name[k], px, w, h)) rc = WRT_EXIT_OUTPUT;
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t p = ((size_t)y * w + x) * 3;
            double d = 0;
            for (int ch = 0; ch < 3; ch++) d += fabs(img[0][p + ch] - img[1][p + ch]) / 3;
            heat(mean > 0 ? d / mean / 0.5 : 0, panel + ((size_t)y * 4 * w + 3 * (size_t)w + x) * 3);
        }
    if (write_labelled_panel(prefix, panel, w, h)) rc = WRT_EXIT_OUTPUT;
    if (closeup) {
        int x0 = (int)closeup[0], y0 = (int)closeup[1], sz = (int)closeup[2], k = 4, cw = 2 * sz * k + k;
        uint8_t *cu = wrt_xcalloc((size_t)cw * sz * k * 3, 1);
        for (int y = 0; y < sz * k; y++)
            for (int x = 0; x < cw; x++) {
                int side = x / (sz * k + k), xx = (x - side * (sz * k + k)) / k, yy = y / k;
                if (xx >= sz || x0 + xx >= w || y0 + yy >= h) continue; /* the gap, or outside */
                memcpy(cu + ((size_t)y * cw + x) * 3, panel + ((size_t)(y0 + yy) * 4 * w + (size_t)side * w + x0 + xx) * 3, 3);
            }
        if (write_png(prefix, "closeup", cu, cw, sz * k)) rc = WRT_EXIT_OUTPUT;
        free(cu);
    }
    free(px);
    free(panel);
    return rc;
}

static const char *T = "wrt-compare";

/* The value of a string KEY in a bake's provenance JSON (flat: "KEY":"VALUE"), or "". */
static void provenance_str(const wrt_gto *g, const char *key, char *out, size_t n) {
    char pat[64];
    int pl = snprintf(pat, sizeof pat, "\"%s\":\"", key);
    out[0] = 0;
    if (!g->provenance || pl <= 0 || (size_t)pl >= sizeof pat) return;
    for (size_t i = 0; i + (size_t)pl <= g->provenance_len; i++) {
        if (memcmp(g->provenance + i, pat, (size_t)pl)) continue;
        size_t k = 0;
        for (i += (size_t)pl; i < g->provenance_len && g->provenance[i] != '"' && k + 1 < n; i++) out[k++] = g->provenance[i];
        out[k] = 0;
        return;
    }
}

/* What can be checked before the reference is path-traced (which takes seconds to
 * minutes): each .gto opens and passes the reader's checks, holds the scene's quads
 * (count, then every corner to 1e-6 of the scene's size), and the images' folder takes
 * a new file. A bake whose source file's hash differs from the scene's but whose quads
 * match gets a note (the scene was edited or rewritten after the bake: its materials may
 * differ). Returns 0 or the exit code, having said why. */
static int check_inputs(const wrt_scene *s, const char *scene_path, const char **gtos, int ngto, const char *images) {
    double size = v3_len(v3_sub(s->bbox_max, s->bbox_min));
    char scene_hash[32];
    snprintf(scene_hash, sizeof scene_hash, "%016llx", (unsigned long long)s->source_hash);
    for (int b = 0; b < ngto; b++) {
        wrt_gto g;
        if (wrt_gto_open(gtos[b], &g) != WRT_OK) {
            fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
            return WRT_EXIT_INPUT;
        }
        int bad = -1;
        if ((int)g.nquads != s->nquads) {
            fprintf(stderr, "wrt-compare: error: %s has %u quads, the scene %s has %d: it was not baked from this scene\n",
                    gtos[b], g.nquads, scene_path, s->nquads);
            wrt_gto_close(&g);
            return WRT_EXIT_INPUT;
        }
        for (int q = 0; q < s->nquads && bad < 0; q++)
            for (int k = 0; k < 4; k++) {
                const double *p = g.quads[q].p[k];
                wrt_v3 d = v3_sub(v3(p[0], p[1], p[2]), s->quads[q].p[k]);
                if (!(v3_len(d) <= 1e-6 * (size > 0 ? size : 1))) { bad = q; break; }
            }
        if (bad >= 0) {
            fprintf(stderr, "wrt-compare: error: %s: quad %d (numbered from 0) is not where the scene %s has it: "
                    "it was not baked from this scene\n", gtos[b], bad, scene_path);
            wrt_gto_close(&g);
            return WRT_EXIT_INPUT;
        }
        char hash[32];
        provenance_str(&g, "source_hash", hash, sizeof hash);
        if (hash[0] && strcmp(hash, scene_hash))
            fprintf(stderr, "wrt-compare: note: %s was baked from another version of %s (source hash %s, now %s); "
                    "its quads match\n", gtos[b], scene_path, hash, scene_hash);
        wrt_gto_close(&g);
    }
    if (images) {
        char dir[PATH_MAX];
        snprintf(dir, sizeof dir, "%s", images);
        char *slash = strrchr(dir, '/');
        if (!slash) snprintf(dir, sizeof dir, ".");
        else if (slash == dir) dir[1] = 0;
        else *slash = 0;
        if (access(dir, W_OK | X_OK) != 0) {
            fprintf(stderr, "wrt-compare: error: -o %s: cannot write in the folder %s: %s\n", images, dir, strerror(errno));
            return WRT_EXIT_OUTPUT;
        }
    }
    return 0;
}

static int takes_value(const char *a) {
    static const char *const names[] = {"--lights", "--light-pos", "--cells", "--cell-paths", "--pilot", "--width",
                                        "--spp", "--sub", "--bench", "--threads", "--seed", "--images", "-o",
                                        "--out", "--exposure", "--max-error", "--closeup", "--gather-points"};
    for (size_t k = 0; k < sizeof names / sizeof *names; k++)
        if (!strcmp(a, names[k])) return 1;
    return 0;
}

/* The command line's settings */
typedef struct {
    const char *scene_path, *images;
    double closeup[3];
    int has_closeup;
    int per_quad, bench_only;
    int ngto, nlights_req, nexplicit;
    double explicit_pos[WRT_COMPARE_MAX_LIGHTS][3];
    double max_error, exposure;
    wrt_compare_options o;
    wrt_cli_lights L;
} cmp_args;

/* Stage 1: the command line (the .gto paths into gtos); -1 to go on, else the exit code */
static int cmp_parse(int argc, char **argv, const char **gtos, cmp_args *A) {
    wrt_compare_options *o = &A->o;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        long x;
        int ok = 1, takes = 1;
        if (strcmp(a, "--light-pos")) {
            int lr = wrt_cli_lights_option(T, &A->L, argc, argv, &i);
            if (lr < 0) return WRT_EXIT_USAGE;
            if (lr > 0) continue;
        }
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { usage(stdout); return 0; }
        else if (!strcmp(a, "--version")) { wrt_cli_version(T); return 0; }
        else if (!strcmp(a, "--no-image")) { o->width = -1; takes = 0; }
        else if (!strcmp(a, "--per-quad")) { A->per_quad = 1; takes = 0; }
        else if (!strcmp(a, "--bench-only")) { A->bench_only = 1; takes = 0; }
        else if (!strcmp(a, "--no-final-gather")) { o->no_final_gather = 1; takes = 0; }
        else if (!strcmp(a, "--no-light-splat")) { o->no_light_splat = 1; takes = 0; }
        else if (!strcmp(a, "--linear-display")) { o->linear_display = 1; takes = 0; }
        else if (a[0] == '-' && a[1] && !takes_value(a)) {
            fprintf(stderr, "wrt-compare: error: unknown option %s (see --help)\n", a);
            return WRT_EXIT_USAGE;
        }
        else if (a[0] == '-' && a[1] && !v) { fprintf(stderr, "wrt-compare: error: %s needs a value\n", a); return WRT_EXIT_USAGE; }
        else if (!strcmp(a, "--lights")) { ok = parse_long(v, 1, WRT_COMPARE_MAX_LIGHTS, &x); A->nlights_req = (int)x; }
        else if (!strcmp(a, "--light-pos")) {
            ok = A->nexplicit < WRT_COMPARE_MAX_LIGHTS && wrt_parse_vec3(v, A->explicit_pos[A->nexplicit]);
            A->nexplicit += ok;
        }
        else if (!strcmp(a, "--cells")) { ok = parse_long(v, 1, 64, &x); o->cells = (int)x; }
        else if (!strcmp(a, "--cell-paths")) ok = parse_long(v, 1, 1L << 40, &o->cell_paths);
        else if (!strcmp(a, "--pilot")) { ok = parse_long(v, 2, 1 << 20, &x); o->pilot = (int)x; }
        else if (!strcmp(a, "--width")) { ok = parse_long(v, 1, 4096, &x); o->width = (int)x; }
        else if (!strcmp(a, "--spp")) { ok = parse_long(v, 2, 1 << 24, &x); o->spp = (int)x; }
        else if (!strcmp(a, "--sub")) { ok = parse_long(v, 1, 16, &x); o->sub = (int)x; }
        else if (!strcmp(a, "--bench")) { ok = parse_long(v, 1, 100000, &x); o->bench_updates = (int)x; }
        else if (!strcmp(a, "--threads")) { ok = parse_long(v, 0, 256, &x); o->threads = (int)x; }
        else if (!strcmp(a, "--seed")) { ok = parse_long(v, 1, 1L << 62, &x); o->seed = (uint64_t)x; }
        else if (!strcmp(a, "--images") || !strcmp(a, "-o") || !strcmp(a, "--out")) A->images = v;
        else if (!strcmp(a, "--exposure")) ok = parse_double(v, &A->exposure) && fabs(A->exposure) <= 64;
        else if (!strcmp(a, "--closeup")) {
            double *closeup = A->closeup;
            ok = wrt_parse_vec3(v, closeup) && closeup[0] >= 0 && closeup[1] >= 0 && closeup[2] >= 1 &&
                 closeup[0] == floor(closeup[0]) && closeup[1] == floor(closeup[1]) && closeup[2] == floor(closeup[2]);
            A->has_closeup = 1;
        }
        else if (!strcmp(a, "--max-error")) ok = parse_double(v, &A->max_error) && A->max_error >= 0;
        else if (!strcmp(a, "--gather-points")) {
            ok = parse_long(v, 16, 32, &x) && (x == 16 || x == 32);
            o->gather_points = (int)x;
        }
        else if (a[0] == '-' && a[1]) { fprintf(stderr, "wrt-compare: error: unknown option %s (see --help)\n", a); return 1; }
        else {
            takes = 0;
            if (!A->scene_path) A->scene_path = a;
            else gtos[A->ngto++] = a;
        }
        if (!ok) { fprintf(stderr, "wrt-compare: error: bad value for %s: '%s' (see --help)\n", a, v ? v : ""); return 1; }
        i += takes;
    }
    if (!A->scene_path || A->ngto == 0) {
        fprintf(stderr, "wrt-compare: error: needs a scene and at least one .gto (see --help)\n");
        return 1;
    }
    wrt_output_protect(A->scene_path); /* no output replaces an input (common/outfile.h) */
    for (int b = 0; b < A->ngto; b++) wrt_output_protect(gtos[b]);
    return -1;
}

/* Stage 2: the scene, the inputs' checks and the lights compared (*nl of them); -1 to
 * go on, else the exit code (the scene freed) */
static int cmp_load(cmp_args *A, const char **gtos, wrt_scene *scene, wrt_light *lights, int *nl) {
    const char *scene_path = A->scene_path;
    wrt_cli_lights *L = &A->L;
    wrt_status lst = wrt_scene_load(scene_path, NULL, scene);
    if (lst != WRT_OK) {
        fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
        return lst == WRT_ERR_NOMEM ? WRT_EXIT_INTERNAL : WRT_EXIT_INPUT;
    }
    int crc = check_inputs(scene, scene_path, gtos, A->ngto, A->bench_only ? NULL : A->images);
    if (crc) {
        wrt_scene_free(scene);
        return crc;
    }
    /* the light compared: --light N's (default 1), with the command line's changes, put
     * first, where wrt_compare_default_lights takes it from */
    if (wrt_cli_lights_any(L)) {
        int which = L->which ? L->which : 1;
        for (int k = 0; k < WRT_CLI_MAX_LIGHTS; k++)
            if (L->scaled[k] && k != which - 1 && k < scene->nlights) {
                fprintf(stderr, "wrt-compare: error: %s %d: the comparison uses light %d only\n",
                        L->scale[k] == 0 ? "--lights-off" : "--light-scale", k + 1, which);
                wrt_scene_free(scene);
                return WRT_EXIT_USAGE;
            }
        int arc = wrt_cli_lights_apply(T, L, scene->lights, scene->nlights, NULL);
        if (arc) {
            wrt_scene_free(scene);
            return arc;
        }
        wrt_light t = scene->lights[0];
        scene->lights[0] = scene->lights[which - 1];
        scene->lights[which - 1] = t;
    }
    int nexplicit = A->nexplicit;
    if (nexplicit > 0) {
        wrt_compare_default_lights(scene, 1, lights);
        for (int k = 1; k < nexplicit; k++) lights[k] = lights[0];
        for (int k = 0; k < nexplicit; k++) lights[k].pos = v3(A->explicit_pos[k][0], A->explicit_pos[k][1], A->explicit_pos[k][2]);
        *nl = nexplicit;
    } else *nl = wrt_compare_default_lights(scene, A->nlights_req, lights);
    return -1;
}

/* Stage 3 (--bench-only): time the light changes of each bake, no reference; the exit code */
static int cmp_bench_only(cmp_args *A, const char **gtos, const wrt_scene *scene, const wrt_light *lights) {
    wrt_compare_options *o = &A->o;
    int ngto = A->ngto;
    wrt_compare_defaults(o);
    double eye[3] = {scene->camera.pos.x, scene->camera.pos.y, scene->camera.pos.z};
    int bad = 0;
    printf("{\"scene\":");
    wrt_cli_json_str(stdout, A->scene_path);
    printf(",\"bakes\":[");
    for (int b = 0; b < ngto; b++) {
        wrt_gto g;
        wrt_compare_result res = {0};
        if (wrt_gto_open(gtos[b], &g) != WRT_OK) {
            fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
            bad = 1;
            continue;
        }
        if ((int)g.nquads != scene->nquads ||
            wrt_compare_bench(&g, &lights[0], eye, o->bench_updates, o, &res) != WRT_OK) {
            fprintf(stderr, "wrt-compare: error: %s: %s\n", gtos[b],
                    (int)g.nquads != scene->nquads ? "not baked from this scene" : wrt_last_error());
            wrt_gto_close(&g);
            bad = 1;
            continue;
        }
        printf("%s{\"file\":", b ? "," : "");
        wrt_cli_json_str(stdout, gtos[b]);
        printf(",\"bytes\":%zu,\"ms_per_light_change\":%.4f,\"ms_min\":%.4f,\"ms_max\":%.4f,"
               "\"cpu_ms_per_light_change\":%.4f,\"ms_per_camera_move\":%.4f,\"cpu_ms_per_camera_move\":%.4f,"
               "\"bench_updates\":%d}",
               g.size, res.ms_update_median, res.ms_update_min, res.ms_update_max, res.cpu_ms_update_median,
               res.ms_eye_median, res.cpu_ms_eye_median, o->bench_updates);
        fprintf(stderr, "wrt-compare: %s: %.2f ms per light change (median; fastest %.2f, CPU %.2f), "
                "%.2f ms per camera move (CPU %.2f)\n", gtos[b], res.ms_update_median, res.ms_update_min,
                res.cpu_ms_update_median, res.ms_eye_median, res.cpu_ms_eye_median);
        wrt_gto_close(&g);
    }
    printf("],\"ok\":%s}\n", bad ? "false" : "true");
    return bad ? 2 : 0;
}

/* Stage 4b (--per-quad): each quad's mean against the reference's, as JSON */
static void cmp_per_quad(const wrt_compare_ref *ref, const wrt_scene *scene, const wrt_compare_options *o) {
    printf(",\"quads\":[");
    for (int q = 0; q < scene->nquads; q++) {
        const double *w = wrt_compare_cells(ref, 0, q, 1, NULL), *m = wrt_compare_cells(ref, 0, q, 0, NULL);
        double mw[3] = {0, 0, 0}, mr[3] = {0, 0, 0}, d2 = 0, r2 = 0;
        for (int k = 0; k < o->cells * o->cells; k++)
            for (int c = 0; c < 3; c++) {
                mw[c] += w[k * 3 + c] / (o->cells * o->cells);
                mr[c] += m[k * 3 + c] / (o->cells * o->cells);
                d2 += (w[k * 3 + c] - m[k * 3 + c]) * (w[k * 3 + c] - m[k * 3 + c]);
                r2 += m[k * 3 + c] * m[k * 3 + c];
            }
        printf("%s{\"quad\":%d,\"material\":%d,\"area\":%.5g,\"wavelet\":[%.5g,%.5g,%.5g],"
               "\"reference\":[%.5g,%.5g,%.5g],\"cell_rmse\":%.5g}",
               q ? "," : "", q, scene->quads[q].material, scene->quads[q].area, mw[0], mw[1], mw[2], mr[0],
               mr[1], mr[2], r2 > 0 ? sqrt(d2 / r2) : 0);
    }
    printf("]");
}

/* Stage 4: one bake against the reference, its JSON object and its line of text; sets
 * *failed, *exceeded and *failed_output as the bake requires */
static void cmp_one_bake(const cmp_args *A, const char *path, int b, wrt_compare_ref *ref,
                         const wrt_compare_ref_info *info, const wrt_scene *scene, int *failed, int *exceeded,
                         int *failed_output) {
    const wrt_compare_options *o = &A->o;
    double max_error = A->max_error;
    wrt_gto g;
    if (wrt_gto_open(path, &g) != WRT_OK) {
        fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
        *failed = 1;
        return;
    }
    wrt_compare_result res;
    wrt_status st = wrt_compare_gto(ref, &g, &res);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-compare: error: %s: %s\n", path, wrt_last_error());
        wrt_gto_close(&g);
        *failed = 1;
        return;
    }
    int over = max_error >= 0 && !(res.mean.cell_rmse <= max_error);
    *exceeded |= over;
    /* raw: the rmse against the path tracer, its noise included; debiased: that noise
     * (the floor) taken out, the figure the README quotes */
    fprintf(stderr, "wrt-compare: %s: cell error %.4f raw, %.4f debiased (floor %.4f)", path, res.mean.cell_rmse,
            res.mean.cell_debiased, res.mean.cell_floor);
    if (info->width > 0)
        fprintf(stderr, "; image error %.4f raw, %.4f debiased (floor %.4f)", res.mean.image_rmse,
                res.mean.image_debiased, res.mean.image_floor);
    fprintf(stderr, "; %.2f ms per light change%s\n", res.ms_update_median, over ? "; ACCURACY NOT MET" : "");
    printf("%s{\"file\":", b ? "," : "");
    wrt_cli_json_str(stdout, path);
    printf(",\"bytes\":%zu,\"functions\":%u,\"entries\":%llu,", g.size, g.nfuncs, (unsigned long long)g.nnz);
    json_errors(stdout, &res.mean);
    printf(",\"ms_per_light_change\":%.4f,\"ms_min\":%.4f,\"ms_max\":%.4f,\"cpu_ms_per_light_change\":%.4f,"
           "\"ms_per_camera_move\":%.4f,\"cpu_ms_per_camera_move\":%.4f,\"bench_updates\":%d,"
           "\"seconds\":%.3f,\"within_max_error\":%s,\"per_light\":[",
           res.ms_update_median, res.ms_update_min, res.ms_update_max, res.cpu_ms_update_median,
           res.ms_eye_median, res.cpu_ms_eye_median, o->bench_updates, res.seconds,
           over ? "false" : "true");
    for (int k = 0; k < res.nlights; k++) {
        printf("%s{", k ? "," : "");
        json_errors(stdout, &res.light[k]);
        printf("}");
    }
    printf("]");
    if (A->per_quad) cmp_per_quad(ref, scene, o);
    printf("}");
    if (A->images && write_images(A->images, ref, info->width, info->height, A->exposure,
                                  A->has_closeup ? A->closeup : NULL))
        *failed_output = 1;
    wrt_gto_close(&g);
}

/* The whole program but the array of .gto paths, which main owns, so that every way out
 * of here (there are many) leaves nothing allocated behind. */
static int compare_main(int argc, char **argv, const char **gtos) {
    cmp_args A = {.nlights_req = 5, .max_error = -1};
    wrt_cli_lights_init(&A.L);
    int prc = cmp_parse(argc, argv, gtos, &A);
    if (prc >= 0) return prc;
    wrt_compare_options o = A.o;

    wrt_scene scene;
    wrt_light lights[WRT_COMPARE_MAX_LIGHTS];
    int nl = 0;
    int lrc = cmp_load(&A, gtos, &scene, lights, &nl);
    if (lrc >= 0) return lrc;

    if (A.bench_only) {
        int brc = cmp_bench_only(&A, gtos, &scene, lights);
        wrt_scene_free(&scene);
        return brc;
    }

    fprintf(stderr, "wrt-compare: reference for %d light(s)...\n", nl);
    wrt_compare_ref *ref;
    wrt_status st = wrt_compare_ref_create(&scene, lights, nl, &o, &ref);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-compare: error: %s\n", wrt_last_error());
        wrt_scene_free(&scene);
        return st == WRT_ERR_INVALID_ARG ? 1 : 2;
    }
    wrt_compare_ref_info info;
    wrt_compare_ref_get_info(ref, &info);
    wrt_compare_defaults(&o);
    A.o = o;
    fprintf(stderr, "wrt-compare: reference %.1f s, cell floor %.4f, image floor %.4f\n", info.seconds,
            info.cell_floor, info.image_floor);

    printf("{\"scene\":");
    wrt_cli_json_str(stdout, A.scene_path);
    printf(",\"quads\":%d,\"cells_per_side\":%d,\"lights\":[", scene.nquads, o.cells);
    for (int k = 0; k < nl; k++)
        printf("%s{\"type\":\"%s\",\"pos\":[%.6g,%.6g,%.6g],\"intensity\":%.6g}", k ? "," : "",
               wrt_light_type_name(lights[k].type), lights[k].pos.x, lights[k].pos.y,
               lights[k].pos.z, lights[k].intensity);
    printf("],\"reference\":{\"seconds\":%.3f,\"rays\":%llu,\"cell_paths_per_light\":%ld,\"pilot\":%d,"
           "\"image\":{\"width\":%d,\"height\":%d,\"spp\":%d,\"sub\":%d,\"valid_pixels\":%d},"
           "\"cell_floor\":%.6g,\"image_floor\":%.6g},\"bakes\":[",
           info.seconds, (unsigned long long)info.rays, info.cell_paths, o.pilot, info.width, info.height,
           info.spp, o.sub, info.valid_pixels, info.cell_floor, info.image_floor);
    int failed = 0, exceeded = 0, failed_output = 0;
    for (int b = 0; b < A.ngto; b++)
        cmp_one_bake(&A, gtos[b], b, ref, &info, &scene, &failed, &exceeded, &failed_output);
    printf("],\"max_error\":");
    if (A.max_error >= 0) printf("%.6g", A.max_error);
    else printf("null");
    printf(",\"ok\":%s}\n", failed || exceeded ? "false" : "true");
    wrt_compare_ref_destroy(ref);
    wrt_scene_free(&scene);
    if (failed) return WRT_EXIT_INPUT;
    if (failed_output) return WRT_EXIT_OUTPUT;
    return exceeded ? WRT_EXIT_ACCURACY : 0;
}

int main(int argc, char **argv) {
    wrt_cli_init("wrt-compare"); /* stdout checked at exit (3), out of memory: exit 7 */
    const char **gtos = wrt_xcalloc((size_t)argc, sizeof(char *));
    int rc = compare_main(argc, argv, gtos);
    free(gtos);
    return rc;
}
