/* main.c: wrt-play, the run-time of Wavelet Radiance Transport (paper section 5). Opens
 * a .gto file through libwrt's API (include/wrt.h: one read, one validation), relights it
 * through the same API each time a light moves (direct light
 * projected on the wavelet basis, the baked indirect operator applied, outgoing
 * radiance synthesized into per-quad textures) and shows it with player/render.c
 * (direct light with shadow maps + the indirect textures), in a GLFW window or headless
 * (EGL) into image files, a scripted sequence of frames, per-quad statistics or a
 * benchmark. Command line and exit codes: see usage() in options.c, which parses them;
 * the scripted frames and the benchmark are run by headless.c. The only file that exits
 * (with options.c, for --help and --version).
 * Depends on formats/image.h, include/wrt.h (the runtime), player/render.h,
 * player/platform.h, and player/wrt_runtime.h (the runtime's validated file, which the
 * renderer draws). */
#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../cli/cli.h"
#include "../common/limits.h"
#include "../common/outfile.h"
#include "../common/text.h"
#include "../formats/image.h"
#include "overlay.h"
#include "platform.h"
#include "../include/wrt.h"
#include "render.h"
#include "options.h"
#include "play.h"
#include "view.h"
#include "wrt_runtime.h"

static const char *T = "wrt-play";

/* ---------------------------------------------------------------- the application */

/* Opens the .gto through the library alone (include/wrt.h): read into private memory
 * (WRT_OPEN_PRIVATE), so that a file replaced or truncated while the player runs (a new
 * bake copied over it, a truncate) cannot pull pages from under the runtime, and
 * validated once, there. *sb receives the file's stat from before the read: a change
 * made during the read is then noticed later, never missed. A FIFO or device is
 * refused by the library without blocking. */
static wrt_status open_file(const options *o, int progress_line, wrt_runtime **rt, struct stat *sb, wrt_error *err);

static void quad_centroid(const double p[4][3], double c[3]) {
    for (int k = 0; k < 3; k++) c[k] = 0.25 * (p[0][k] + p[1][k] + p[2][k] + p[3][k]);
}

/* The player keeps its lights in the API's struct (wrt_runtime_get_light), which goes
 * to wrt_runtime_set_lights as it is. The renderer and the command line's light options
 * (shared with wrt-ref and wrt-compare) take the scene's wrt_light: these copy between
 * the two, field for field (nothing normalised: the axis is made unit once, at setup). */
static void scene_light(const wrt_runtime_light *in, wrt_light *out) {
    memset(out, 0, sizeof *out);
    out->type = in->kind == WRT_LIGHT_KIND_SPOT ? WRT_LIGHT_SPOT
                : in->kind == WRT_LIGHT_KIND_DIRECTIONAL ? WRT_LIGHT_DIRECTIONAL : WRT_LIGHT_POINT;
    snprintf(out->name, sizeof out->name, "%s", in->name);
    out->pos = light_pos(in);
    out->dir = light_dir(in);
    for (int k = 0; k < 3; k++) out->color[k] = in->color[k];
    out->intensity = in->intensity;
    out->range = in->range;
    out->inner_cone = in->inner_cone;
    out->outer_cone = in->outer_cone;
}

static void runtime_light(const wrt_light *in, wrt_runtime_light *out) {
    memset(out, 0, sizeof *out);
    out->kind = in->type == WRT_LIGHT_SPOT ? WRT_LIGHT_KIND_SPOT
                : in->type == WRT_LIGHT_DIRECTIONAL ? WRT_LIGHT_KIND_DIRECTIONAL : WRT_LIGHT_KIND_POINT;
    snprintf(out->name, sizeof out->name, "%s", in->name);
    light_set_pos(out, in->pos);
    light_set_dir(out, in->dir);
    for (int k = 0; k < 3; k++) out->color[k] = in->color[k];
    out->intensity = in->intensity;
    out->range = in->range;
    out->inner_cone = in->inner_cone;
    out->outer_cone = in->outer_cone;
}

/* One frame: relight what changed, upload the textures that changed, draw. */
int run_frame(app *a, stage_ms *t) {
    memset(t, 0, sizeof *t);
    double t0 = wrt_now();
    int n = a->nlights < WRT_RENDER_MAX_LIGHTS ? a->nlights : WRT_RENDER_MAX_LIGHTS;
    wrt_light drawn[WRT_RENDER_MAX_LIGHTS]; /* the renderer's form of the same lights */
    for (int i = 0; i < n; i++) scene_light(&a->lights[i], &drawn[i]);
    wrt_render_set_lights(a->rd, drawn, a->scales, n);
    /* direct-only pictures need no relighting; everything else does */
    if (a->mode != WRT_MODE_DIRECT || a->o->stats) {
        double ms[4];
        wrt_runtime_light rls[WRT_RENDER_MAX_LIGHTS];
        for (int i = 0; i < n; i++) { /* the same struct; a scale folds into the intensity */
            rls[i] = a->lights[i];
            if (a->scales[i] != 1) rls[i].intensity = a->lights[i].intensity * a->scales[i];
            rls[i].off = a->scales[i] == 0;
        }
        int changed = 0;
        wrt_error err = {0};
        wrt_status st = wrt_runtime_set_lights(a->rl, rls, n, &err);
        if (!st) st = wrt_runtime_set_eye(a->rl, a->view.eye, &err);
        if (!st) st = wrt_runtime_update(a->rl, &changed, &err);
        if (st) { /* never ignored: a light the runtime refuses would leave the indirect light at 0 */
            fprintf(stderr, "wrt-play: error: %s\n", err.message);
            return st == WRT_ERR_NOMEM ? EXIT_RUNTIME : EXIT_INPUT;
        }
        t->relit = changed > 0 || !a->relit_once;
        wrt_runtime_timings(a->rl, ms, NULL);
        t->projection = ms[0];
        t->multiply = ms[1];
        t->brdf = ms[2];
        t->synthesis = ms[3];
        double t1 = wrt_now();
        if (changed > 0 || !a->relit_once) {
            for (int q = 0; q < a->nquads; q++) {
                int res;
                const float *tex = wrt_runtime_quad_texture(a->rl, q, &res);
                if (tex && res > 0) wrt_render_set_quad_tex(a->rd, q, res, tex);
            }
            if (wrt_render_upload(a->rd) < 0) return EXIT_GL;
            wrt_render_finish();
        }
        a->relit_once = 1;
        t->upload = (wrt_now() - t1) * 1e3;
    }
    double t2 = wrt_now();
    wrt_render_draw(a->rd, &a->view, a->mode);
    wrt_render_finish();
    t->draw = (wrt_now() - t2) * 1e3;
    t->frame = (wrt_now() - t0) * 1e3;
    return 0;
}

int save_picture(app *a, const char *path) {
    int w = a->o->width, h = a->o->height, ss = a->o->headless ? a->o->supersample : 1;
    float *lin = wrt_xmalloc((size_t)w * h * 3 * sizeof(float));
    if (ss > 1) {
        /* rendered at ss x the size: the mean of each ss x ss block (a box filter of the
         * linear radiance, which smooths shadow edges too, unlike MSAA) */
        size_t W = (size_t)w * ss;
        float *big = wrt_xmalloc(W * (size_t)h * ss * 3 * sizeof(float));
        wrt_render_read_linear(a->rd, big);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                for (int c = 0; c < 3; c++) {
                    double sum = 0;
                    for (int j = 0; j < ss; j++)
                        for (int i = 0; i < ss; i++) sum += big[((size_t)(y * ss + j) * W + (size_t)x * ss + i) * 3 + c];
                    lin[((size_t)y * w + x) * 3 + c] = (float)(sum / (ss * ss));
                }
        free(big);
    } else {
        wrt_render_read_linear(a->rd, lin);
    }
    wrt_status s;
    if (wrt_image_is_exr(path)) {
        s = wrt_image_write_exr(path, lin, w, h);
    } else {
        uint8_t *b = wrt_xmalloc((size_t)w * h * 3);
        wrt_render_tonemap(lin, (size_t)w * h, a->o->exposure, b);
        s = wrt_image_write_rgb8(path, b, w, h);
        free(b);
    }
    free(lin);
    if (s) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        return EXIT_OUTPUT;
    }
    return 0;
}

/* Strings and numbers through the one JSON writer (common/text.h): valid JSON whatever
 * the names hold, null for a number that is not finite. */
static void json_str(FILE *f, const char *s, size_t max) { wrt_json_strn(f, s, max); }

/* ", "KEY": [a, b, c]" (n > 1) or ", "KEY": a" (n == 1). */
static void json_key_nums(FILE *f, const char *key, const double *v, int n, int digits) {
    fprintf(f, ", \"%s\": ", key);
    if (n > 1) fputc('[', f);
    for (int i = 0; i < n; i++) {
        if (i) fputs(", ", f);
        wrt_json_num(f, v[i], digits);
    }
    if (n > 1) fputc(']', f);
}

static int write_stats(app *a, const char *path) {
    wrt_output out; /* a regular file only, through a temporary (common/outfile.h) */
    if (wrt_output_begin(path, "w", &out) != WRT_OK) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        return EXIT_OUTPUT;
    }
    FILE *f = out.f;
    fprintf(f, "{\n  \"file\": ");
    json_str(f, a->o->file, 4096);
    fprintf(f, ",\n  \"nquads\": %d,\n  \"lights\": [", a->nquads);
    for (int i = 0; i < a->nlights; i++) {
        const wrt_runtime_light *l = &a->lights[i];
        wrt_light sl;
        scene_light(l, &sl);
        fprintf(f, "%s\n    {\"name\": ", i ? "," : "");
        json_str(f, l->name, sizeof l->name);
        fprintf(f, ", \"type\": \"%s\"", wrt_light_type_name(sl.type));
        double pos[3] = {l->position[0], l->position[1], l->position[2]};
        double dir[3] = {l->direction[0], l->direction[1], l->direction[2]};
        double in = l->intensity, sc = i < WRT_RENDER_MAX_LIGHTS ? a->scales[i] : 0.0f;
        json_key_nums(f, "pos", pos, 3, 17);
        json_key_nums(f, "dir", dir, 3, 9);
        json_key_nums(f, "intensity", &in, 1, 9);
        json_key_nums(f, "scale", &sc, 1, 9);
        fputc('}', f);
    }
    fprintf(f, "\n  ],\n  \"quads\": [");
    for (int q = 0; q < a->nquads; q++) {
        wrt_runtime_quad Q;
        double c[3], dir[3], ind[3];
        wrt_runtime_get_quad(a->rl, q, &Q, NULL);
        quad_centroid(Q.corners, c);
        wrt_runtime_quad_irradiance(a->rl, q, dir, ind, NULL);
        fprintf(f, "%s\n    {\"quad\": %d, \"mesh\": ", q ? "," : "", q);
        json_str(f, Q.mesh_name, sizeof Q.mesh_name);
        double area = Q.area;
        fprintf(f, ", \"material\": %d", Q.material);
        json_key_nums(f, "area", &area, 1, 9);
        json_key_nums(f, "centroid", c, 3, 17);
        json_key_nums(f, "normal", Q.normal, 3, 9); /* the library's, in double: the file's float
                                                     * differs from it in the 8th digit at most */
        json_key_nums(f, "direct", dir, 3, 9);
        json_key_nums(f, "indirect", ind, 3, 9);
        fputc('}', f);
    }
    fprintf(f, "\n  ]\n}\n");
    if (wrt_output_commit(&out) != WRT_OK) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        return EXIT_OUTPUT;
    }
    return 0;
}

/* ---------------------------------------------------------------- lights and view */

void scene_up(const app *a, wrt_v3 *up) {
    *up = v3_norm(v3(a->view.up[0], a->view.up[1], a->view.up[2]));
    if (!(v3_len(*up) > 0.5)) *up = v3(0, 1, 0);
}

/* The light the command line's --light names (0-based), which scripts and --bench move. */
int chosen_light(const app *a) { return a->o->lights.which ? a->o->lights.which - 1 : 0; }

void scene_bounds(const app *a, double lo[3], double hi[3]) {
    if (a->nquads <= 0 || wrt_runtime_get_bounds(a->rl, lo, hi, NULL) != WRT_OK)
        for (int k = 0; k < 3; k++) { lo[k] = -1; hi[k] = 1; }
}

/* --emitter-scale: each named emissive material's scale, in the library and the
 * renderer (docs/emitters.md); a material that is not in the file or does not emit is
 * refused (exit 1). */
static int apply_emitters(app *a) {
    const options *o = a->o;
    if (!o->nemit) return 0;
    int nm = wrt_runtime_material_count(a->rl);
    if (nm < 0) nm = 0;
    float *sc = wrt_xmalloc((size_t)(nm ? nm : 1) * sizeof *sc);
    for (int m = 0; m < nm; m++) sc[m] = 1;
    for (int k = 0; k < o->nemit; k++) {
        int m = o->emit_mat[k];
        wrt_runtime_material mat;
        const float *e = m < nm && wrt_runtime_get_material(a->rl, m, &mat, NULL) == WRT_OK ? mat.emissive : NULL;
        if (!e || !(e[0] > 0 || e[1] > 0 || e[2] > 0)) {
            fprintf(stderr, "wrt-play: error: --emitter-scale %d: %s (wrt-bake --info lists the emitters)\n", m,
                    e ? "that material does not emit" : "the file has no such material");
            free(sc);
            return EXIT_USAGE;
        }
        sc[m] = o->emit_scale[k];
        wrt_runtime_set_emitter_scale(a->rl, m, sc[m], NULL);
    }
    wrt_render_set_emitter_scales(a->rd, sc);
    free(sc);
    return 0;
}

static int setup_lights(app *a) {
    const options *o = a->o;
    a->nlights = wrt_runtime_light_count(a->rl);
    if (a->nlights < 0) a->nlights = 0;
    /* emissive surfaces light the scene on their own (docs/emitters.md) */
    int need_default = a->nlights == 0 && wrt_runtime_emitter_count(a->rl) <= 0;
    a->lights = wrt_xcalloc((size_t)(a->nlights ? a->nlights : 1), sizeof *a->lights);
    for (int i = 0; i < a->nlights; i++) {
        wrt_runtime_light *l = &a->lights[i];
        wrt_runtime_get_light(a->rl, i, l, NULL); /* i < the count: cannot fail */
        light_set_dir(l, v3_norm(light_dir(l)));
    }
    if (need_default) {
        /* no light in the file: one point light above the centre of the scene */
        double lo[3], hi[3];
        scene_bounds(a, lo, hi);
        wrt_v3 up;
        scene_up(a, &up);
        wrt_v3 c = v3(0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2]));
        double r = 0.5 * v3_len(v3(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]));
        wrt_runtime_light *l = &a->lights[0];
        l->kind = WRT_LIGHT_KIND_POINT;
        snprintf(l->name, sizeof l->name, "default");
        light_set_pos(l, v3_mad(c, up, 0.4 * r));
        light_set_dir(l, v3_scale(up, -1));
        l->color[0] = l->color[1] = l->color[2] = 1;
        l->intensity = (float)(r * r);
        l->outer_cone = (float)(WRT_PI / 4);
        a->nlights = 1;
        wrt_log(WRT_LOG_WARN, "the file has no light: using a point light at (%g, %g, %g)", l->position[0],
                l->position[1], l->position[2]);
    }
    /* the command line's light options (cli/, shared with wrt-ref and wrt-compare) */
    float *sc = wrt_xmalloc((size_t)(a->nlights ? a->nlights : 1) * sizeof *sc);
    wrt_light *sl = wrt_xmalloc((size_t)(a->nlights ? a->nlights : 1) * sizeof *sl);
    for (int i = 0; i < a->nlights; i++) scene_light(&a->lights[i], &sl[i]);
    int rc = wrt_cli_lights_apply(T, &o->lights, sl, a->nlights, sc);
    for (int i = 0; i < a->nlights; i++) runtime_light(&sl[i], &a->lights[i]);
    for (int i = 0; i < WRT_RENDER_MAX_LIGHTS; i++) a->scales[i] = i < a->nlights ? sc[i] : 1;
    free(sl);
    free(sc);
    return rc;
}

/* The file's camera; else the view of view.h that sees the most directly lit surface
 * (wrt_runtime_get_camera, and the file's lights and quads through the API). */
static void default_view(const app *a, wrt_view *v) {
    memset(v, 0, sizeof *v);
    wrt_runtime_camera cam;
    if (wrt_runtime_get_camera(a->rl, &cam, NULL) == WRT_OK && cam.from_file && cam.yfov > 0) {
        for (int k = 0; k < 3; k++) {
            v->eye[k] = cam.position[k];
            v->target[k] = cam.position[k] + cam.direction[k];
            v->up[k] = cam.up[k];
        }
        v->yfov = cam.yfov;
        return;
    }
    wrt_runtime_light ls[WRT_MAX_LIGHTS];
    int nl = wrt_runtime_light_count(a->rl);
    nl = nl < 0 ? 0 : nl > WRT_MAX_LIGHTS ? WRT_MAX_LIGHTS : nl;
    for (int i = 0; i < nl; i++) wrt_runtime_get_light(a->rl, i, &ls[i], NULL);
    if (nl == 0) { /* the light setup_lights will add: above the centre, up +Y */
        double lo[3], hi[3];
        scene_bounds(a, lo, hi);
        double r = 0.5 * v3_len(v3(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]));
        memset(&ls[0], 0, sizeof ls[0]);
        for (int k = 0; k < 3; k++) ls[0].position[k] = 0.5 * (lo[k] + hi[k]) + (k == 1 ? 0.4 * r : 0);
        ls[0].intensity = (float)(r * r);
        nl = 1;
    }
    wrt_play_default_view(a->geom, ls, nl, v, NULL);
}

static int setup_view(app *a) {
    default_view(a, &a->view);
    const options *o = a->o;
    if (o->has_cam_pos) {
        double d[3];
        for (int k = 0; k < 3; k++) d[k] = a->view.target[k] - a->view.eye[k];
        for (int k = 0; k < 3; k++) {
            a->view.eye[k] = o->cam_pos[k];
            if (!o->has_cam_target) a->view.target[k] = o->cam_pos[k] + d[k];
        }
    }
    if (o->has_cam_target) memcpy(a->view.target, o->cam_target, sizeof a->view.target);
    if (o->has_fov) a->view.yfov = o->fov * WRT_PI / 180;
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (a->view.target[k] - a->view.eye[k]) * (a->view.target[k] - a->view.eye[k]);
    if (!(d2 > 0)) {
        fprintf(stderr, "wrt-play: error: the camera's position (%g, %g, %g) equals its target: no view direction\n",
                a->view.eye[0], a->view.eye[1], a->view.eye[2]);
        return 0;
    }
    return 1;
}

/* ---------------------------------------------------------------- window */

/* The colours C cycles through; the first is the light's own colour from the file, shown
 * as "own" (C skips a colour the same as it, so each press changes the light). */
static const struct { const char *name; float rgb[3]; } colours[] = {
    {"own", {1, 1, 1}}, {"white", {1, 1, 1}}, {"warm", {1.0f, 0.72f, 0.45f}}, {"cool", {0.62f, 0.78f, 1.0f}},
    {"red", {1.0f, 0.25f, 0.2f}}, {"green", {0.3f, 1.0f, 0.35f}}, {"blue", {0.3f, 0.45f, 1.0f}},
};
#define NCOLOURS ((int)(sizeof colours / sizeof colours[0]))

typedef struct win_state {
    wrt_overlay *ov;
    int sel, overlay_on, keys_on; /* keys_on: the overlay lists the keys (F1) */
    float exposure;
    float saved_scale[WRT_RENDER_MAX_LIGHTS]; /* what Space restores */
    float file_colour[WRT_RENDER_MAX_LIGHTS][3];
    int colour[WRT_RENDER_MAX_LIGHTS];
    double box_lo[3], box_hi[3];              /* where lights may go */
    const wrt_play_geom *geom;                /* and the walls they stop at */
    float panel_rect[4];                      /* x, y, w, h of the overlay's panel: no marker drawn there */
    double frame_ms, fps, last_draw;          /* smoothed; when the last frame was drawn */
    stage_ms relight;                         /* the last frame that relit */
    int relit_any;
    char status[256];
    double status_until;
    int shots;
} win_state;

static int nshown(const app *a) { return a->nlights < WRT_RENDER_MAX_LIGHTS ? a->nlights : WRT_RENDER_MAX_LIGHTS; }

/* Lights stay inside the scene's bounding box (grown to hold where the file puts them),
 * so that no key drives a light out of reach. */
static void light_bounds(app *a, win_state *w) {
    scene_bounds(a, w->box_lo, w->box_hi);
    double size = v3_len(v3(w->box_hi[0] - w->box_lo[0], w->box_hi[1] - w->box_lo[1], w->box_hi[2] - w->box_lo[2]));
    for (int k = 0; k < 3; k++) {
        w->box_lo[k] += 1e-3 * size;
        w->box_hi[k] -= 1e-3 * size;
    }
    for (int i = 0; i < a->nlights; i++)
        for (int k = 0; k < 3 && a->lights[i].kind != WRT_LIGHT_KIND_DIRECTIONAL; k++) { /* a sun has no position */
            double p = a->lights[i].position[k];
            if (p < w->box_lo[k]) w->box_lo[k] = p;
            if (p > w->box_hi[k]) w->box_hi[k] = p;
        }
}

static void win_reset_lights(app *a, win_state *w) {
    for (int i = 0; i < WRT_RENDER_MAX_LIGHTS; i++) {
        w->saved_scale[i] = a->scales[i] != 0 ? a->scales[i] : 1;
        w->colour[i] = 0;
        if (i < a->nlights) memcpy(w->file_colour[i], a->lights[i].color, sizeof w->file_colour[i]);
    }
    if (w->sel >= nshown(a)) w->sel = 0;
    light_bounds(a, w);
}

static void say(win_state *w, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void say(win_state *w, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(w->status, sizeof w->status, fmt, ap);
    va_end(ap);
    w->status_until = wrt_now() + 3;
    fprintf(stderr, "wrt-play: %s\n", w->status);
}

static int save_window(app *a, const char *path) {
    uint8_t *b = wrt_xmalloc((size_t)a->o->width * a->o->height * 3);
    wrt_render_read_window(a->o->width, a->o->height, b);
    wrt_status s = wrt_image_write_rgb8(path, b, a->o->width, a->o->height);
    free(b);
    if (s) fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
    return s ? EXIT_OUTPUT : 0;
}

/* The open's progress (wrt_runtime_options.progress): a line on stderr, redrawn when the
 * percentage changes, only when stderr is a terminal (a glossy file takes seconds: the
 * final gather's rays). Never cancels. */
typedef struct open_progress { int shown; } open_progress;
static int show_progress(void *user, double fraction) {
    open_progress *p = user;
    int pct = (int)(fraction * 100);
    if (pct == p->shown) return 1;
    if (p->shown < 0 && (fraction < 0.05 || fraction >= 1)) return 1; /* quick stages: no line */
    p->shown = pct;
    fprintf(stderr, "\rwrt-play: opening: %3d%%%s", pct, fraction >= 1 ? "\n" : "");
    fflush(stderr);
    return 1;
}

static wrt_status open_file(const options *o, int progress_line, wrt_runtime **rt, struct stat *sb, wrt_error *err) {
    memset(sb, 0, sizeof *sb);
    (void)stat(o->file, sb); /* before the read; a failure is the open's to report */
    open_progress op = {-1};
    wrt_runtime_options ro = {.size = sizeof ro, .max_tex_res = o->max_tex_res, .threads = o->threads,
                              .linear_display = o->linear_display, .progress_user = &op};
    if (progress_line) ro.progress = show_progress;
    wrt_status s = wrt_runtime_open_path(o->file, WRT_OPEN_PRIVATE, &ro, rt, err);
    if (s == WRT_OK && (o->budget_ms > 0 || o->skip_below > 0) &&
        (s = wrt_runtime_set_budget(*rt, o->budget_ms, o->skip_below, err)) != WRT_OK) {
        wrt_runtime_close(*rt);
        *rt = NULL;
    }
    return s;
}

/* F5: reads the file again (after a new bake) and rebuilds the relighting and the
 * renderer; the camera stays, the lights too if the file has as many. */
static int win_reload(app *a, win_state *w) {
    wrt_runtime *rl2;
    struct stat st2;
    wrt_error err;
    if (open_file(a->o, isatty(2), &rl2, &st2, &err)) {
        say(w, "reload failed, keeping the old file: %s", err.message);
        return 0;
    }
    wrt_play_geom *geom2;
    if (wrt_play_geom_create(rl2, &geom2)) {
        say(w, "reload failed, keeping the old file: %s", wrt_last_error());
        wrt_runtime_close(rl2);
        return 0;
    }
    wrt_play_geom_destroy(a->geom);
    a->geom = geom2;
    w->geom = geom2;
    int same_lights = wrt_runtime_light_count(rl2) == wrt_runtime_light_count(a->rl);
    wrt_render_destroy(a->rd); /* it draws from the old runtime's file */
    wrt_runtime_close(a->rl);
    a->rd = NULL;
    a->rl = rl2;
    a->gto_st = st2;
    a->nquads = wrt_runtime_quad_count(rl2);
    wrt_runtime_get_file_info(rl2, &a->info, NULL);
    wrt_status s;
    wrt_render_options rdo = {a->o->width, a->o->height, a->o->shadow_res, a->o->msaa};
    if ((s = wrt_render_create(wrt_runtime_gto_of(a->rl), &rdo, &a->rd))) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        return s == WRT_ERR_GL ? EXIT_GL : EXIT_RUNTIME;
    }
    int erc = apply_emitters(a);
    if (erc) return erc;
    a->relit_once = 0;
    if (!same_lights) {
        free(a->lights);
        int rc = setup_lights(a);
        if (rc) return rc;
        win_reset_lights(a, w);
    } else {
        light_bounds(a, w);
    }
    say(w, "reloaded %s: %d quads, %llu functions", a->o->file, a->nquads, a->info.functions);
    return 0;
}

static const float white[4] = {1, 1, 1, 1}, dim[4] = {0.7f, 0.7f, 0.7f, 1}, yellow[4] = {1, 0.85f, 0.2f, 1},
                   panel[4] = {0, 0, 0, 0.6f}, black[4] = {0, 0, 0, 0.8f};

/* Whether the square of half-side `pad` around (x, y) touches the overlay's panel. */
static int under_panel(const win_state *w, float x, float y, float pad) {
    const float *r = w->panel_rect;
    return x + pad >= r[0] && x - pad <= r[0] + r[2] && y + pad >= r[1] && y - pad <= r[1] + r[3];
}

static void draw_markers(app *a, win_state *w, wrt_overlay *ov, int sc, float ch) {
    /* a marker at each light: a cross in its colour (grey when off), a frame around the
     * selected one, its number beside it, a dotted axis for a spot; none of it over the
     * overlay's panel, whose text it would cover (the light's line in the panel says it) */
    for (int i = 0; i < nshown(a); i++) {
        double p[3] = {a->lights[i].position[0], a->lights[i].position[1], a->lights[i].position[2]}, px[2];
        if (a->lights[i].kind == WRT_LIGHT_KIND_DIRECTIONAL) /* a sun: where it comes from, at the box's edge */
            for (int k = 0; k < 3; k++)
                p[k] = 0.5 * (w->box_lo[k] + w->box_hi[k]) - a->lights[i].direction[k] * 0.5 *
                       v3_len(v3(w->box_hi[0] - w->box_lo[0], w->box_hi[1] - w->box_lo[1], w->box_hi[2] - w->box_lo[2]));
        if (!wrt_render_project(a->rd, &a->view, p, px)) continue;
        float x = (float)px[0], y = (float)px[1], r = 6.0f * sc;
        int on = a->scales[i] != 0;
        float c[4] = {a->lights[i].color[0], a->lights[i].color[1], a->lights[i].color[2], 1};
        float m = fmaxf(c[0], fmaxf(c[1], c[2]));
        for (int k = 0; k < 3; k++) c[k] = on ? (m > 0 ? 0.35f + 0.65f * c[k] / m : 1) : 0.45f;
        if (a->lights[i].kind == WRT_LIGHT_KIND_SPOT) {
            /* a spot's axis: dots from the light along its direction, a tenth of the box */
            double len = 0.1 * v3_len(v3(w->box_hi[0] - w->box_lo[0], w->box_hi[1] - w->box_lo[1],
                                          w->box_hi[2] - w->box_lo[2]));
            for (int k = 1; k <= 8; k++) {
                double q[3], qx[2];
                for (int d = 0; d < 3; d++) q[d] = p[d] + a->lights[i].direction[d] * len * k / 8;
                if (wrt_render_visible(a->rd, &a->view, q, qx) && /* depth-tested: not through walls */
                    !under_panel(w, (float)qx[0], (float)qx[1], 2.0f * sc))
                    wrt_overlay_rect(ov, (float)qx[0] - sc, (float)qx[1] - sc, 2.0f * sc, 2.0f * sc, c);
            }
        }
        if (under_panel(w, x + 3.0f * sc, y - 3.0f * sc, r + 4.0f * sc + 12.0f * sc)) continue;
        if (i == w->sel) {
            float t = 2.0f * sc, R = r + 4.0f * sc;
            wrt_overlay_rect(ov, x - R, y - R, 2 * R, t, yellow);
            wrt_overlay_rect(ov, x - R, y + R - t, 2 * R, t, yellow);
            wrt_overlay_rect(ov, x - R, y - R, t, 2 * R, yellow);
            wrt_overlay_rect(ov, x + R - t, y - R, t, 2 * R, yellow);
        }
        wrt_overlay_rect(ov, x - r - 1, y - 2.0f * sc, 2 * r + 2, 4.0f * sc, black);
        wrt_overlay_rect(ov, x - 2.0f * sc, y - r - 1, 4.0f * sc, 2 * r + 2, black);
        wrt_overlay_rect(ov, x - r, y - 1.0f * sc, 2 * r, 2.0f * sc, c);
        wrt_overlay_rect(ov, x - 1.0f * sc, y - r, 2.0f * sc, 2 * r, c);
        char num[16];
        snprintf(num, sizeof num, "%d", i + 1);
        wrt_overlay_rect(ov, x + r + 2, y - r - ch, 6.0f * sc * (float)strlen(num) + 2, ch, black);
        wrt_overlay_text(ov, x + r + 3, y - r - ch, sc, i == w->sel ? yellow : white, num);
    }
}

static void draw_overlay(app *a, win_state *w) {
    wrt_overlay *ov = w->ov;
    int W = a->o->width, H = a->o->height, sc = W >= 1000 ? 2 : 1;
    float ch = 9.0f * sc;
    wrt_overlay_begin(ov, W, H);
    double now = wrt_now();
    if (!w->overlay_on) {
        const char *hint = w->status_until > now ? w->status : "H: help and lights";
        float tw, th;
        wrt_overlay_measure(hint, sc, &tw, &th);
        w->panel_rect[0] = 4; w->panel_rect[1] = (float)H - th - 8; w->panel_rect[2] = tw + 8; w->panel_rect[3] = th + 4;
        draw_markers(a, w, ov, sc, ch);
        wrt_overlay_rect(ov, 4, (float)H - th - 8, tw + 8, th + 4, panel);
        wrt_overlay_text(ov, 8, (float)H - th - 6, sc, dim, hint);
        wrt_overlay_draw(ov);
        return;
    }
    char buf[8192];
    size_t n = 0;
#define ADD(...) n += (size_t)snprintf(buf + n, n < sizeof buf ? sizeof buf - n : 0, __VA_ARGS__)
    const char *base = strrchr(a->o->file, '/');
    ADD("WRT-PLAY  %s  %d quads  [%s]  exposure %+.1f EV  MSAA %dx\n", base ? base + 1 : a->o->file, a->nquads,
        wrt_render_mode_name(a->mode), w->exposure, wrt_render_samples(a->rd));
    ADD("%.1f fps  frame %.1f ms  draw %.1f", w->fps, w->frame_ms, w->relight.draw);
    if (w->relit_any)
        ADD("  relight: proj %.1f mul %.1f brdf %.1f syn %.1f up %.1f\n", w->relight.projection,
            w->relight.multiply, w->relight.brdf, w->relight.synthesis, w->relight.upload);
    else
        ADD("\n");
    ADD("LIGHTS  (Tab/1-9 select, Space on/off, +/- intensity, C colour)\n");
    for (int i = 0; i < nshown(a); i++) {
        const wrt_runtime_light *l = &a->lights[i];
        int sun = l->kind == WRT_LIGHT_KIND_DIRECTIONAL; /* a sun: its direction, in lux */
        wrt_v3 shown = sun ? light_dir(l) : light_pos(l);
        ADD("%c %d %-5s %-16.16s %-3s %9.4g %s x%-5.3g %s(%.2f, %.2f, %.2f) %s\n", i == w->sel ? '>' : ' ', i + 1,
            sun ? "sun" : l->kind == WRT_LIGHT_KIND_SPOT ? "spot" : "point", l->name, a->scales[i] != 0 ? "on" : "OFF",
            l->intensity, sun ? "lx" : "cd", a->scales[i] != 0 ? a->scales[i] : w->saved_scale[i], sun ? "dir " : "",
            shown.x, shown.y, shown.z, colours[w->colour[i]].name);
    }
    if (a->nlights > WRT_RENDER_MAX_LIGHTS) ADD("  (%d more not shown)\n", a->nlights - WRT_RENDER_MAX_LIGHTS);
    if (w->keys_on)
        ADD("\nKEYS  mouse (left button) look   W A S D  Q E  move   Shift faster\n"
            "      arrows / I J K L  U O  %s   [ ] exposure   T both/direct/indirect\n"
            "      R reset   F5 reload   F12 screenshot   P print options   H hide   Esc quit\n",
            w->sel < a->nlights && a->lights[w->sel].kind == WRT_LIGHT_KIND_DIRECTIONAL ? "turn the sun  " : "move the light");
    else
        ADD("F1 keys   H hide\n");
    if (w->status_until > now) ADD("\n%s\n", w->status);
#undef ADD
    float tw, th;
    wrt_overlay_measure(buf, sc, &tw, &th);
    w->panel_rect[0] = 4; w->panel_rect[1] = 4; w->panel_rect[2] = tw + 12; w->panel_rect[3] = th + 8;
    draw_markers(a, w, ov, sc, ch); /* first, and not under the panel */
    wrt_overlay_rect(ov, 4, 4, tw + 12, th + 8, panel);
    /* the text, the selected light's line in yellow */
    float y = 8;
    char *line = buf;
    int lineno = 0, first_light_line = 3;
    while (line && *line) {
        char *nl = strchr(line, '\n');
        if (nl) *nl = 0;
        int li = lineno - first_light_line;
        int is_light = li >= 0 && li < nshown(a);
        const float *col = is_light && li == w->sel ? yellow : lineno == 0 || is_light ? white : dim;
        wrt_overlay_text(ov, 10, y, sc, col, line);
        y += ch;
        lineno++;
        line = nl ? nl + 1 : NULL;
    }
    wrt_overlay_draw(ov);
}

static void win_title(app *a, win_state *w, int idle) {
    char title[512];
    const char *base = strrchr(a->o->file, '/');
    if (idle)
        snprintf(title, sizeof title, "wrt-play: %s [%s]", base ? base + 1 : a->o->file, wrt_render_mode_name(a->mode));
    else
        snprintf(title, sizeof title, "wrt-play: %s [%s] %.0f fps, %.1f ms/frame", base ? base + 1 : a->o->file,
                 wrt_render_mode_name(a->mode), w->fps, w->frame_ms);
    a->plat->set_title(a->plat, title);
}

/* Key presses, in order: selection, light scale/colour, exposure, mode, reset, reload, shots. */
static int win_keys(app *a, win_state *w, const wrt_input *in, int *quit, int *shot) {
    int rc = 0;
    wrt_runtime_light *sl = &a->lights[w->sel];
    for (int e = 0; e < in->nevents; e++) {
        int k = in->events[e].key;
        if (k == WRT_KEY_ESCAPE) *quit = 1;
        else if (k == WRT_KEY_TAB && !in->events[e].repeat)
            w->sel = (w->sel + (in->events[e].shift ? nshown(a) - 1 : 1)) % nshown(a);
        else if (k >= WRT_KEY_1 && k <= WRT_KEY_9) {
            int i = k - WRT_KEY_1;
            if (i < nshown(a)) w->sel = i;
            else say(w, "there is no light %d (the file has %d)", i + 1, a->nlights);
        } else if (k == WRT_KEY_SPACE && !in->events[e].repeat) {
            if (a->scales[w->sel] != 0) { w->saved_scale[w->sel] = a->scales[w->sel]; a->scales[w->sel] = 0; }
            else a->scales[w->sel] = w->saved_scale[w->sel] != 0 ? w->saved_scale[w->sel] : 1;
        } else if (k == WRT_KEY_PLUS || k == WRT_KEY_MINUS) {
            float f = k == WRT_KEY_PLUS ? 1.25f : 0.8f;
            if (a->scales[w->sel] != 0) a->scales[w->sel] = fminf(fmaxf(a->scales[w->sel] * f, 1e-4f), 1e4f);
            else w->saved_scale[w->sel] = fminf(fmaxf(w->saved_scale[w->sel] * f, 1e-4f), 1e4f);
        } else if (k == WRT_KEY_C && !in->events[e].repeat) {
            int c = (w->colour[w->sel] + 1) % NCOLOURS;
            while (c != 0 && !memcmp(colours[c].rgb, w->file_colour[w->sel], sizeof colours[c].rgb))
                c = (c + 1) % NCOLOURS; /* the same as its own: no visible change */
            w->colour[w->sel] = c;
            memcpy(sl->color, c == 0 ? w->file_colour[w->sel] : colours[c].rgb, sizeof sl->color);
        } else if (k == WRT_KEY_LBRACKET) w->exposure = fmaxf(w->exposure - 0.5f, -20);
        else if (k == WRT_KEY_RBRACKET) w->exposure = fminf(w->exposure + 0.5f, 20);
        else if (k == WRT_KEY_T && !in->events[e].repeat) a->mode = (wrt_render_mode)((a->mode + 1) % WRT_MODE_COUNT);
        else if (k == WRT_KEY_H && !in->events[e].repeat) w->overlay_on = !w->overlay_on;
        else if (k == WRT_KEY_F1 && !in->events[e].repeat) { w->keys_on = !w->keys_on; w->overlay_on = 1; }
        else if (k == WRT_KEY_R && !in->events[e].repeat) {
            (void)setup_view(a); /* checked at the start */
            free(a->lights);
            if ((rc = setup_lights(a))) break;
            win_reset_lights(a, w);
            w->exposure = a->o->exposure;
            a->mode = a->o->mode;
            say(w, "view, lights and exposure reset");
        } else if (k == WRT_KEY_F5 && !in->events[e].repeat) {
            if ((rc = win_reload(a, w))) break;
        } else if (k == WRT_KEY_F12 && !in->events[e].repeat) *shot = 1;
        else if (k == WRT_KEY_P && !in->events[e].repeat) {
            const wrt_runtime_light *l = &a->lights[w->sel];
            printf("--camera-pos %.6g,%.6g,%.6g --camera-target %.6g,%.6g,%.6g --light %d --light-pos %.6g,%.6g,%.6g\n",
                   a->view.eye[0], a->view.eye[1], a->view.eye[2], a->view.target[0], a->view.target[1],
                   a->view.target[2], w->sel + 1, l->position[0], l->position[1], l->position[2]);
            fflush(stdout);
        }
        sl = &a->lights[w->sel];
    }
    return rc;
}

/* The camera: mouse look, W A S D Q E held; gives the new forward and right. */
static int win_move_camera(app *a, const wrt_input *in, wrt_v3 up, double speed, wrt_v3 *fwd_out, wrt_v3 *right_out) {
    int changed = 0;
    wrt_v3 eye = v3(a->view.eye[0], a->view.eye[1], a->view.eye[2]);
    wrt_v3 fwd = v3_norm(v3_sub(v3(a->view.target[0], a->view.target[1], a->view.target[2]), eye));
    if (in->mouse_dx != 0 || in->mouse_dy != 0) {
        double yaw = -in->mouse_dx * 0.004, pitch = -in->mouse_dy * 0.004;
        /* rotate about up (yaw), then about right (pitch), keeping away from the poles */
        wrt_v3 f1 = v3_add(v3_scale(fwd, cos(yaw)), v3_scale(v3_cross(up, fwd), sin(yaw)));
        f1 = v3_add(f1, v3_scale(up, v3_dot(up, fwd) * (1 - cos(yaw))));
        wrt_v3 right1 = v3_norm(v3_cross(f1, up));
        wrt_v3 f2 = v3_norm(v3_add(v3_scale(f1, cos(pitch)), v3_scale(v3_cross(right1, f1), sin(pitch))));
        if (fabs(v3_dot(f2, up)) < 0.98) fwd = f2; else fwd = v3_norm(f1);
    }
    wrt_v3 right = v3_norm(v3_cross(fwd, up));
    wrt_v3 move = v3(0, 0, 0);
    if (in->down[WRT_KEY_W]) move = v3_add(move, fwd);
    if (in->down[WRT_KEY_S]) move = v3_sub(move, fwd);
    if (in->down[WRT_KEY_D]) move = v3_add(move, right);
    if (in->down[WRT_KEY_A]) move = v3_sub(move, right);
    if (in->down[WRT_KEY_E]) move = v3_add(move, up);
    if (in->down[WRT_KEY_Q]) move = v3_sub(move, up);
    changed |= v3_len(move) > 0;
    eye = v3_mad(eye, move, speed);
    wrt_v3 target = v3_add(eye, fwd);
    a->view.eye[0] = eye.x; a->view.eye[1] = eye.y; a->view.eye[2] = eye.z;
    a->view.target[0] = target.x; a->view.target[1] = target.y; a->view.target[2] = target.z;
    *fwd_out = fwd;
    *right_out = right;
    return changed;
}

/* The selected light: a sun turns, any other light moves, within the scene box. */
static int win_move_light(win_state *w, const wrt_input *in, wrt_runtime_light *sl, wrt_v3 up, wrt_v3 fwd, wrt_v3 right,
                          double dt, double speed, double size) {
    int changed = 0;
    /* the selected light: arrows / I J K L horizontally (relative to the view), U O vertically */
    wrt_v3 hf = v3_norm(v3_sub(fwd, v3_scale(up, v3_dot(fwd, up))));
    wrt_v3 lm = v3(0, 0, 0);
    if (in->down[WRT_KEY_UP] || in->down[WRT_KEY_I]) lm = v3_add(lm, hf);
    if (in->down[WRT_KEY_DOWN] || in->down[WRT_KEY_K]) lm = v3_sub(lm, hf);
    if (in->down[WRT_KEY_RIGHT] || in->down[WRT_KEY_L]) lm = v3_add(lm, right);
    if (in->down[WRT_KEY_LEFT] || in->down[WRT_KEY_J]) lm = v3_sub(lm, right);
    if (in->down[WRT_KEY_O]) lm = v3_add(lm, up);
    if (in->down[WRT_KEY_U]) lm = v3_sub(lm, up);
    if (v3_len(lm) > 0 && sl->kind == WRT_LIGHT_KIND_DIRECTIONAL) {
        /* a sun turns: left/right about up (azimuth), up/down and O/U raise/lower it */
        changed = 1;
        double turn = 0.8 * dt * (in->down[WRT_KEY_SHIFT] ? 4 : 1); /* radians */
        /* up / O raise the sun: its light then travels more steeply down */
        double az = turn * v3_dot(lm, right), el = -turn * (v3_dot(lm, hf) + v3_dot(lm, up));
        wrt_v3 d = light_dir(sl), side = v3_cross(up, d);
        d = v3_add(v3_scale(d, cos(az)), v3_add(v3_scale(side, sin(az)), v3_scale(up, v3_dot(up, d) * (1 - cos(az)))));
        wrt_v3 axis = v3_cross(d, up);
        if (v3_len(axis) > 1e-6) {
            axis = v3_norm(axis);
            wrt_v3 d2 = v3_add(v3_scale(d, cos(el)), v3_scale(v3_cross(axis, d), sin(el)));
            if (fabs(v3_dot(d2, up)) < 0.999) d = d2; /* not through the poles */
        }
        light_set_dir(sl, v3_norm(d));
    } else if (v3_len(lm) > 0) {
        changed = 1;
        wrt_v3 np = v3_mad(light_pos(sl), lm, fmax(speed, size * 0.005) * 0.5);
        double c[3] = {np.x, np.y, np.z}, from[3] = {sl->position[0], sl->position[1], sl->position[2]};
        for (int k = 0; k < 3; k++) c[k] = fmin(fmax(c[k], w->box_lo[k]), w->box_hi[k]);
        /* and short of any wall on the way: a light never passes through one (view.h) */
        double f = w->geom ? wrt_play_geom_clip_move(w->geom, from, c) : 1;
        light_set_pos(sl, v3(from[0] + f * (c[0] - from[0]), from[1] + f * (c[1] - from[1]), from[2] + f * (c[2] - from[2])));
    }
    return changed;
}

static int run_window(app *a) {
    wrt_platform *p = a->plat;
    win_state w;
    memset(&w, 0, sizeof w);
    w.geom = a->geom;
    w.overlay_on = !a->o->no_overlay;
    w.exposure = a->o->exposure;
    w.sel = chosen_light(a) < nshown(a) ? chosen_light(a) : 0;
    if (wrt_overlay_create(&w.ov)) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        return EXIT_GL;
    }
    win_reset_lights(a, &w);
    double lo[3], hi[3];
    scene_bounds(a, lo, hi);
    double size = v3_len(v3(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]));
    /* yaw and the lights' up/down keys turn and move about the world's up, glTF's +Y,
     * whatever the camera's roll or tilt */
    wrt_v3 up = v3(0, 1, 0);
    double last = wrt_now(), title_at = 0, stat_at = 0;
    int frame = 0, rc = 0, was_idle = -1, dirty = 1;
    struct stat seen = a->gto_st; /* the file as last noticed */
    stage_ms t;
    memset(&t, 0, sizeof t);
    for (;;) {
        wrt_input in;
        p->poll(p, &in);
        if (in.close_requested) break;
        double now = wrt_now(), dt = fmin(now - last, 0.1);
        last = now;
        /* A new bake copied over the file: say so (once per change); the data read at the
         * start stays in use until F5 reads the new file. */
        if (now - stat_at > 1) {
            struct stat st;
            stat_at = now;
            if (stat(a->o->file, &st) == 0 &&
                (st.st_ino != seen.st_ino || st.st_size != seen.st_size || st.st_mtim.tv_sec != seen.st_mtim.tv_sec ||
                 st.st_mtim.tv_nsec != seen.st_mtim.tv_nsec)) {
                seen = st;
                say(&w, "%s changed on disk: F5 reads it (this view keeps the data read before)", a->o->file);
                dirty = 1;
            }
        }
        double speed = size * 0.3 * dt * (in.down[WRT_KEY_SHIFT] ? 4 : 1);
        int quit = 0, shot = 0, changed = in.nevents > 0 || in.mouse_dx != 0 || in.mouse_dy != 0;
        rc = win_keys(a, &w, &in, &quit, &shot);
        if (rc || quit) break;
        wrt_runtime_light *sl = &a->lights[w.sel];
        wrt_v3 fwd, right;
        changed |= win_move_camera(a, &in, up, speed, &fwd, &right);
        changed |= win_move_light(&w, &in, sl, up, fwd, right, dt, speed, size);
        if (p->fb_width > 0 && p->fb_height > 0 &&
            (p->fb_width != a->o->width || p->fb_height != a->o->height)) {
            if (wrt_render_resize(a->rd, p->fb_width, p->fb_height) == WRT_OK) {
                a->o->width = p->fb_width;
                a->o->height = p->fb_height;
                changed = 1;
            }
        }
        int idle = !changed && !dirty && w.status_until < now;
        if (idle && was_idle == 1 && !(a->o->frames > 0)) {
            /* nothing moves: sleep until an event (at most 0.1 s), no frames drawn */
            if (p->wait) p->wait(p, 0.1);
            continue;
        }
        dirty = 0;
        if ((rc = run_frame(a, &t))) break;
        if (t.relit) { w.relight = t; w.relit_any = 1; }
        w.relight.draw = t.draw;
        w.frame_ms = w.frame_ms > 0 ? 0.8 * w.frame_ms + 0.2 * t.frame : t.frame;
        /* frames per second over the frames drawn in a row (an idle pause restarts it) */
        double since = now - w.last_draw;
        if (was_idle == 0 && since > 0) w.fps = w.fps > 0 ? 0.8 * w.fps + 0.2 / since : 1 / since;
        w.last_draw = now;
        wrt_render_present(a->rd, a->o->width, a->o->height, w.exposure);
        if (shot) { /* F12: the picture, before the overlay is drawn over it */
            char path[64];
            do snprintf(path, sizeof path, "wrt-play-%04d.png", ++w.shots);
            while (access(path, F_OK) == 0 && w.shots < 9999);
            if (save_window(a, path) == 0) say(&w, "saved %s", path);
        }
        draw_overlay(a, &w);
        frame++;
        int last_frame = a->o->frames > 0 && frame >= a->o->frames;
        if (last_frame && a->o->screenshot) rc = save_window(a, a->o->screenshot);
        p->swap(p);
        if (now - title_at > 0.25 || last_frame || was_idle != idle) {
            win_title(a, &w, idle);
            title_at = now;
        }
        was_idle = idle;
        if (last_frame || rc) break;
    }
    wrt_overlay_destroy(w.ov);
    return rc;
}

/* ---------------------------------------------------------------- main */

/* Under AddressSanitizer: Mesa's driver, which EGL loads and unloads, leaves one block
 * of 128 bytes that LeakSanitizer cannot attribute to any module (the leak checks of
 * this program's own allocations were clean before this was switched off). */
const char *__asan_default_options(void);
const char *__asan_default_options(void) { return "detect_leaks=0"; }

int main(int argc, char **argv) {
    wrt_cli_init("wrt-play"); /* stdout checked at exit (3), out of memory: exit 7 */
    options o;
    if (!parse_args(argc, argv, &o)) return EXIT_USAGE;
    wrt_output_protect(o.file); /* no output replaces an input (common/outfile.h) */
    wrt_output_protect(o.script);
    app a;
    memset(&a, 0, sizeof a);
    a.o = &o;
    a.mode = o.mode;
    wrt_error err;
    wrt_status s = open_file(&o, isatty(2), &a.rl, &a.gto_st, &err);
    if (s) {
        const char *e = err.message; /* named once: the library's messages mostly name it */
        if (!strncmp(e, o.file, strlen(o.file))) fprintf(stderr, "wrt-play: error: %s\n", e);
        else fprintf(stderr, "wrt-play: error: %s: %s\n", o.file, e);
        return s == WRT_ERR_NOMEM ? EXIT_RUNTIME : s == WRT_ERR_INVALID_ARG ? EXIT_USAGE : EXIT_INPUT;
    }
    a.nquads = wrt_runtime_quad_count(a.rl);
    wrt_runtime_get_file_info(a.rl, &a.info, NULL);
    if ((s = wrt_play_geom_create(a.rl, &a.geom))) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        wrt_runtime_close(a.rl);
        return EXIT_RUNTIME;
    }
    /* the view and the lights first: a light the file does not have is refused before
     * any window opens */
    int rc = setup_view(&a) ? setup_lights(&a) : EXIT_USAGE;
    if (rc) {
        free(a.lights);
        wrt_play_geom_destroy(a.geom);
        wrt_runtime_close(a.rl);
        return rc;
    }
    if (o.headless) s = wrt_platform_egl_create(&a.plat);
    else s = wrt_platform_glfw_create(o.width, o.height, "wrt-play", &a.plat);
    if (s) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        free(a.lights);
        wrt_play_geom_destroy(a.geom);
        wrt_runtime_close(a.rl);
        return EXIT_GL;
    }
    if (a.plat->has_window && a.plat->fb_width > 0) {
        o.width = a.plat->fb_width;
        o.height = a.plat->fb_height;
    }
    int ss = o.headless ? o.supersample : 1;
    wrt_render_options rdo = {o.width * ss, o.height * ss, o.shadow_res, o.msaa};
    if ((s = wrt_render_create(wrt_runtime_gto_of(a.rl), &rdo, &a.rd))) {
        fprintf(stderr, "wrt-play: error: %s\n", wrt_last_error());
        rc = s == WRT_ERR_GL ? EXIT_GL : EXIT_USAGE;
        goto done;
    }
    if ((rc = apply_emitters(&a))) goto done;
    if (a.nlights > WRT_RENDER_MAX_LIGHTS)
        wrt_log(WRT_LOG_WARN, "%d lights: only the first %d are used", a.nlights, WRT_RENDER_MAX_LIGHTS);

    if (!o.headless) {
        rc = run_window(&a);
        goto done;
    }
    if (o.bench) {
        rc = run_bench(&a);
        if (rc) goto done;
    }
    if (o.script) {
        rc = run_script(&a);
        if (rc) goto done;
    }
    if (o.out || o.stats) {
        if (o.bench || o.script) { /* back to the command line's camera and lights */
            (void)setup_view(&a); /* checked above */
            free(a.lights);
            if ((rc = setup_lights(&a))) goto done;
        }
        stage_ms t;
        if ((rc = run_frame(&a, &t))) goto done;
        if (o.out && (rc = save_picture(&a, o.out))) goto done;
        /* on a terminal, say where the picture went (docs/walkthrough.md, 6); a pipeline
         * or a script sees nothing on success, as before */
        if (o.out && isatty(STDERR_FILENO)) fprintf(stderr, "wrt-play: wrote %s (%d x %d)\n", o.out, o.width, o.height);
        if (o.stats && (rc = write_stats(&a, o.stats))) goto done;
    }
done:
    wrt_render_destroy(a.rd);
    wrt_runtime_close(a.rl);
    free(a.lights);
    wrt_platform_destroy(a.plat);
    wrt_play_geom_destroy(a.geom);
    return rc;
}
