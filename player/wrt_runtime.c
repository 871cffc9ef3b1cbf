/* wrt_runtime.c: the public runtime API (include/wrt.h) over the relighting core
 * (relight.h) and the .gto reader (formats/gto.h): options read by their size, handles
 * checked by their magic, every value that enters checked against the header's bounds,
 * and the scene's lights, materials, camera, bounds and quad-to-source map read from
 * the file. Keeps no global state. */
#include "../include/wrt.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../common/basis.h"
#include "relight.h"
#include "wrt_runtime.h"

/* A live handle's magic ("WRTRTIME"); cleared at close, so that a use after close or
 * a double close is caught (include/wrt.h, "Handles"). */
#define RT_MAGIC 0x454d495454525457ull

struct wrt_runtime {
    uint64_t magic;
    wrt_allocator al;
    wrt_gto g;
    wrt_relight *rl;
    double lo[3], hi[3];   /* the box of every quad's corners */
    wrt_relight_timings tm;
    void *copy;            /* WRT_OPEN_PRIVATE: the file's bytes (the allocator's), freed at close */
};

/* The options' layout of API version 2, the first with `size`: what size 0 means (the
 * fields of API 3 on need a size that covers them). */
#define OPTIONS_V2_SIZE offsetof(wrt_runtime_options, linear_display)

int wrt_version(void) { return WRT_VERSION; }
const char *wrt_version_string(void) { return WRT_VERSION_STRING; }
int wrt_api_version(void) { return WRT_API_VERSION; }

static void *sys_alloc(void *u, size_t n) { (void)u; return malloc(n); }
static void sys_free(void *u, void *p) { (void)u; free(p); }

/* The relighting core's allocator hooks (player/relight.h) take the user pointer last;
 * these forward to the caller's, whose user pointer comes first. */

static wrt_status fail(wrt_error *err, wrt_status s) {
    if (err) {
        err->status = s;
        snprintf(err->message, sizeof err->message, "%s", s ? wrt_last_error() : "");
    }
    return s;
}

static int live(const wrt_runtime *rt) { return rt && rt->magic == RT_MAGIC; }

/* WRT_ERR_INVALID_ARG for a NULL or dead handle, naming the call. */
static wrt_status dead(wrt_error *err, const char *fn, const wrt_runtime *rt) {
    return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: %s", fn,
                              rt ? "not a live runtime (closed, or not from wrt_runtime_open_*)" : "runtime is NULL"));
}

/* Copies the caller's options into *o by their `size` (0: the version-2 layout); the
 * fields beyond it stay zero. */
static wrt_status read_options(const wrt_runtime_options *opt, wrt_runtime_options *o, const char *fn) {
    memset(o, 0, sizeof *o);
    if (!opt) return WRT_OK;
    size_t sz = opt->size ? opt->size : OPTIONS_V2_SIZE;
    if (sz < OPTIONS_V2_SIZE || sz > sizeof *o)
        return wrt_fail(WRT_ERR_INVALID_ARG, "%s: options.size %zu is not one this library knows (0, or %zu "
                        "as in its header: API version %d)", fn, opt->size, sizeof *o, WRT_API_VERSION);
    memcpy(o, opt, sz);
    return WRT_OK;
}

wrt_status wrt_runtime_defaults(wrt_runtime_options *o) {
    if (!o) return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_defaults: options are NULL");
    wrt_runtime_options d;
    wrt_status s = read_options(o, &d, "wrt_runtime_defaults");
    if (s) return s;
    if (!d.allocator.alloc != !d.allocator.free)
        return wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_defaults: allocator has alloc or free but not both");
    if (d.threads < 0) d.threads = 0;
    if (d.max_tex_res <= 0) d.max_tex_res = 64;
    if (!d.allocator.alloc) d.allocator = (wrt_allocator){sys_alloc, sys_free, NULL};
    memcpy(o, &d, o->size ? o->size : OPTIONS_V2_SIZE);
    return WRT_OK;
}

/* Reads `path` whole into memory from the allocator (WRT_OPEN_PRIVATE): a regular file
 * only, checked by fstat before any read (O_NONBLOCK: a FIFO or device is refused, not
 * waited on). A file that shrinks while it is read is validated as the bytes read. */
static wrt_status read_private(const char *path, const wrt_allocator *al, void **buf_out, size_t *len_out) {
    *buf_out = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    if (fd < 0) return wrt_fail(WRT_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat sb;
    if (fstat(fd, &sb) != 0) {
        int e = errno;
        close(fd);
        return wrt_fail(WRT_ERR_IO, "%s: cannot stat: %s", path, strerror(e));
    }
    if (!S_ISREG(sb.st_mode)) {
        close(fd);
        return wrt_fail(WRT_ERR_NOT_OURS, "%s: not a regular file (%s)", path,
                        S_ISDIR(sb.st_mode) ? "a directory" : S_ISFIFO(sb.st_mode) ? "a FIFO"
                        : S_ISCHR(sb.st_mode) || S_ISBLK(sb.st_mode) ? "a device" : "a special file");
    }
    size_t len = (size_t)sb.st_size, got = 0;
    /* The header's magic and file size before the bulk read: a 20 GB sparse file, or a
     * bake with 20 GB of zeros appended, was read whole (20 GB resident, then the
     * kernel's out-of-memory kill, exit 137) only to be refused as "bad magic" or
     * "trailing data". A file whose header agrees is read; the reader checks the rest. */
    unsigned char head[WRT_GTO_HEAD_BYTES];
    ssize_t hr;
    do hr = pread(fd, head, sizeof head, 0); while (hr < 0 && errno == EINTR);
    wrt_status hs = hr > 0 ? wrt_gto_check_head(head, (size_t)hr, (uint64_t)len) : WRT_OK;
    if (hs) {
        char msg[200];
        snprintf(msg, sizeof msg, "%s", wrt_last_error());
        close(fd);
        return wrt_fail(hs, "%s: %s (not read)", path, msg);
    }
    unsigned char *buf = al->alloc(al->user, len + 8); /* aligned for any type: the reader needs 8 */
    if (!buf) {
        close(fd);
        return wrt_fail(WRT_ERR_NOMEM, "%s: out of memory reading %zu bytes", path, len);
    }
    memset(buf, 0, 8);
    while (got < len) {
        ssize_t r = read(fd, buf + got, len - got);
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) break;
        got += (size_t)r;
    }
    close(fd);
    *buf_out = buf;
    *len_out = got;
    return WRT_OK;
}

/* The file into rt->g: mapped (path, !private), read into rt->copy (path, private), or
 * the caller's bytes (no path). The reader's messages get the path in front once. */
static wrt_status open_gto(wrt_runtime *rt, const char *path, int private_copy, const void *data, size_t size) {
    /* the reader's arrays for the compact entries (col_start of a 3.0 file, a 2.0 file's
     * block rows and bases) come from the caller's allocator too */
    const wrt_allocator *al = &rt->al;
    if (!path) return wrt_gto_open_memory_alloc(data, size, al->alloc, al->free, al->user, &rt->g);
    if (!private_copy) return wrt_gto_open_alloc(path, al->alloc, al->free, al->user, &rt->g);
    size_t len = 0;
    wrt_status s = read_private(path, &rt->al, &rt->copy, &len);
    if (s) return s;
    if ((s = wrt_gto_open_memory_alloc(rt->copy, len, al->alloc, al->free, al->user, &rt->g))) {
        char msg[200];
        snprintf(msg, sizeof msg, "%s", wrt_last_error());
        rt->al.free(rt->al.user, rt->copy);
        rt->copy = NULL;
        return wrt_fail(s, "%s: %s", path, msg);
    }
    return WRT_OK;
}

static wrt_status open_common(const void *data, size_t size, const char *path, int private_copy,
                              const wrt_runtime_options *opt, wrt_runtime **out, wrt_error *err) {
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open: out is NULL"));
    *out = NULL;
    wrt_runtime_options o;
    wrt_status s = read_options(opt, &o, "wrt_runtime_open");
    if (s) return fail(err, s);
    if (o.max_tex_res < 0 || (o.max_tex_res & (o.max_tex_res - 1)) || o.max_tex_res > 1024 || o.threads < 0 || o.threads > 64 ||
        o.proj_level < 0 || o.proj_level > WRT_MAX_SLEVEL)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open: options out of range (max_tex_res %d, "
                                  "threads %d, proj_level %d)", o.max_tex_res, o.threads, o.proj_level));
    if ((s = wrt_runtime_defaults(&o))) return fail(err, s);
    wrt_runtime *rt = o.allocator.alloc(o.allocator.user, sizeof *rt);
    if (!rt) return fail(err, wrt_fail(WRT_ERR_NOMEM, "wrt_runtime_open: out of memory"));
    memset(rt, 0, sizeof *rt);
    rt->al = o.allocator;
    if ((s = open_gto(rt, path, private_copy, data, size))) { rt->al.free(rt->al.user, rt); return fail(err, s); }
    for (int c = 0; c < 3; c++) { rt->lo[c] = rt->g.nquads ? HUGE_VAL : 0; rt->hi[c] = rt->g.nquads ? -HUGE_VAL : 0; }
    for (uint32_t q = 0; q < rt->g.nquads; q++)
        for (int k = 0; k < 4; k++)
            for (int c = 0; c < 3; c++) {
                rt->lo[c] = fmin(rt->lo[c], rt->g.quads[q].p[k][c]);
                rt->hi[c] = fmax(rt->hi[c], rt->g.quads[q].p[k][c]);
            }
    wrt_relight_options ro = {.proj_level = o.proj_level, .max_tex_res = o.max_tex_res, .threads = o.threads,
                              .alloc = rt->al.alloc, .free = rt->al.free, .alloc_user = rt->al.user,
                              .haar_blocks = o.haar_blocks, .parallel_for = o.parallel_for,
                              .parallel_user = o.parallel_user, .log = o.log, .log_user = o.log_user,
                              .no_gather = o.no_final_gather, .no_light_splat = o.no_light_splat,
                              .gather_points = o.gather_points, .no_avx = o.no_avx,
                              .linear_display = o.linear_display, .progress = o.progress,
                              .progress_user = o.progress_user};
    if ((s = wrt_relight_create(&rt->g, &ro, &rt->rl))) {
        wrt_gto_close(&rt->g);
        if (rt->copy) rt->al.free(rt->al.user, rt->copy);
        rt->al.free(rt->al.user, rt);
        return fail(err, s);
    }
    rt->magic = RT_MAGIC;
    *out = rt;
    return WRT_OK;
}

wrt_status wrt_runtime_open_file(const char *path, const wrt_runtime_options *opt, wrt_runtime **out, wrt_error *err) {
    if (out) *out = NULL;
    if (!path) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open_file: path is NULL"));
    return open_common(NULL, 0, path, 0, opt, out, err);
}

wrt_status wrt_runtime_open_path(const char *path, int how, const wrt_runtime_options *opt, wrt_runtime **out,
                                 wrt_error *err) {
    if (out) *out = NULL;
    if (!path) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open_path: path is NULL"));
    if (how != WRT_OPEN_MAP && how != WRT_OPEN_PRIVATE)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open_path: how is %d, neither WRT_OPEN_MAP (0) "
                                  "nor WRT_OPEN_PRIVATE (1)", how));
    return open_common(NULL, 0, path, how == WRT_OPEN_PRIVATE, opt, out, err);
}

wrt_status wrt_runtime_get_file_info(const wrt_runtime *rt, wrt_runtime_file_info *out, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_get_file_info", rt);
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_file_info: out is NULL"));
    memset(out, 0, sizeof *out);
    out->version_major = rt->g.version;
    out->version_minor = rt->g.version_minor;
    out->bytes = rt->g.size;
    out->functions = rt->g.nfuncs;
    out->entries = rt->g.nnz;
    out->private_copy = rt->copy != NULL;
    return WRT_OK;
}

const wrt_gto *wrt_runtime_gto_of(const wrt_runtime *rt) { return live(rt) ? &rt->g : NULL; }

wrt_status wrt_runtime_open_memory(const void *data, size_t size, const wrt_runtime_options *opt, wrt_runtime **out,
                                   wrt_error *err) {
    if (out) *out = NULL;
    if (!data || ((uintptr_t)data & 7))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_open_memory: data is NULL or not 8-byte aligned"));
    return open_common(data, size, NULL, 0, opt, out, err);
}

wrt_status wrt_runtime_close(wrt_runtime *rt) {
    if (!rt) return WRT_OK;
    if (!live(rt)) return dead(NULL, "wrt_runtime_close", rt);
    rt->magic = 0;
    wrt_relight_destroy(rt->rl);
    wrt_gto_close(&rt->g);
    wrt_allocator al = rt->al;
    if (rt->copy) al.free(al.user, rt->copy);
    al.free(al.user, rt);
    return WRT_OK;
}

int wrt_runtime_light_count(const wrt_runtime *rt) { return live(rt) ? (int)rt->g.nlights : -1; }

/* A 64-byte name from the file (terminated within 64 bytes: the reader checked). */
static void copy_name(char dst[64], const char *src) {
    memset(dst, 0, 64);
    if (src) memcpy(dst, src, strnlen(src, 63));
}

wrt_status wrt_runtime_get_light(const wrt_runtime *rt, int i, wrt_runtime_light *out, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_get_light", rt);
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_light: out is NULL"));
    if (i < 0 || i >= (int)rt->g.nlights)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_light: no light %d (the file has %u)", i,
                                  rt->g.nlights));
    const wrt_gto_light *l = &rt->g.lights[i];
    memset(out, 0, sizeof *out);
    out->kind = l->type == WRT_LIGHT_SPOT ? WRT_LIGHT_KIND_SPOT
                : l->type == WRT_LIGHT_DIRECTIONAL ? WRT_LIGHT_KIND_DIRECTIONAL : WRT_LIGHT_KIND_POINT;
    for (int c = 0; c < 3; c++) {
        out->position[c] = l->pos[c];
        out->direction[c] = l->dir[c];
        out->color[c] = l->color[c];
    }
    out->intensity = l->intensity;
    out->inner_cone = l->inner_cone;
    out->outer_cone = l->outer_cone;
    out->range = l->range;
    copy_name(out->name, l->name);
    return WRT_OK;
}

static int coord_ok(double x) { return isfinite(x) && fabs(x) <= WRT_MAX_COORD; }

/* What is wrong with light l ("" if nothing), for the message. */
static const char *light_problem(const wrt_runtime_light *l) {
    int spot = l->kind == WRT_LIGHT_KIND_SPOT, sun = l->kind == WRT_LIGHT_KIND_DIRECTIONAL;
    if (l->kind != WRT_LIGHT_KIND_POINT && !spot && !sun) return "kind is neither point, spot nor directional";
    if (!sun && (!coord_ok(l->position[0]) || !coord_ok(l->position[1]) || !coord_ok(l->position[2])))
        return "position not finite or beyond WRT_MAX_COORD (1e9 m)";
    if (sun) { /* no position: the way its light travels */
        double m = fmax(fabs(l->direction[0]), fmax(fabs(l->direction[1]), fabs(l->direction[2])));
        if (!isfinite(m) || !(m > 0)) return "directional light's direction not finite or zero";
    }
    float cmax = 0;
    for (int c = 0; c < 3; c++) {
        if (!isfinite(l->color[c]) || l->color[c] < 0 || l->color[c] > (float)WRT_MAX_INTENSITY)
            return "colour channel not finite, negative or beyond WRT_MAX_INTENSITY";
        cmax = fmaxf(cmax, l->color[c]);
    }
    if (cmax == 0) cmax = 1; /* black: white */
    if (!isfinite(l->intensity) || l->intensity < 0 || l->intensity > (float)WRT_MAX_INTENSITY ||
        l->intensity * cmax > (float)WRT_MAX_INTENSITY)
        return "intensity not finite, negative, or (times its largest colour channel) beyond WRT_MAX_INTENSITY "
               "(1e20 cd)";
    if (!isfinite(l->range) || l->range < 0) return "range not finite or negative";
    if (spot) {
        float outer = l->outer_cone > 0 ? l->outer_cone : (float)(WRT_PI / 4);
        double m = fmax(fabs(l->direction[0]), fmax(fabs(l->direction[1]), fabs(l->direction[2])));
        if (!isfinite(m) || !(m > 0)) return "spot axis not finite or zero";
        if (!(outer <= WRT_PI / 2) || !(l->inner_cone >= 0) || !(l->inner_cone < outer))
            return "spot cones not 0 <= inner < outer <= pi/2";
    }
    return "";
}

wrt_status wrt_runtime_set_lights(wrt_runtime *rt, const wrt_runtime_light *in, int n, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_set_lights", rt);
    if (n < 0 || n > WRT_MAX_LIGHTS || (n && !in))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_lights: %d lights%s (0..%d)", n,
                                  n && !in ? " from NULL" : "", WRT_MAX_LIGHTS));
    wrt_light ls[WRT_MAX_LIGHTS];
    float sc[WRT_MAX_LIGHTS];
    for (int i = 0; i < n; i++) {
        const wrt_runtime_light *l = &in[i];
        const char *why = light_problem(l);
        if (why[0])
            return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_lights: light %d: %s", i, why));
        int spot = l->kind == WRT_LIGHT_KIND_SPOT, sun = l->kind == WRT_LIGHT_KIND_DIRECTIONAL;
        memset(&ls[i], 0, sizeof ls[i]);
        ls[i].type = spot ? WRT_LIGHT_SPOT : sun ? WRT_LIGHT_DIRECTIONAL : WRT_LIGHT_POINT;
        ls[i].pos = sun ? v3(0, 0, 0) : v3(l->position[0], l->position[1], l->position[2]); /* a sun has none */
        if (spot || sun) { /* scaled first, so that no length overflows or underflows */
            double m = fmax(fabs(l->direction[0]), fmax(fabs(l->direction[1]), fabs(l->direction[2])));
            ls[i].dir = v3_norm(v3(l->direction[0] / m, l->direction[1] / m, l->direction[2] / m));
        } else
            ls[i].dir = v3(0, 0, -1);
        int black = l->color[0] == 0 && l->color[1] == 0 && l->color[2] == 0;
        for (int c = 0; c < 3; c++) ls[i].color[c] = black ? 1.0f : l->color[c];
        ls[i].intensity = l->intensity;
        ls[i].range = l->range;
        ls[i].inner_cone = spot ? l->inner_cone : 0;
        ls[i].outer_cone = spot ? (l->outer_cone > 0 ? l->outer_cone : (float)(WRT_PI / 4)) : (float)(WRT_PI / 4);
        sc[i] = l->off ? 0.0f : 1.0f;
    }
    wrt_status s = wrt_relight_set_lights(rt->rl, ls, sc, n);
    return s ? fail(err, s) : WRT_OK;
}

wrt_status wrt_runtime_set_eye(wrt_runtime *rt, const double eye[3], wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_set_eye", rt);
    if (!eye || !coord_ok(eye[0]) || !coord_ok(eye[1]) || !coord_ok(eye[2]))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_eye: %s", eye ? "position not finite or "
                                  "beyond WRT_MAX_COORD (1e9 m)" : "eye is NULL"));
    wrt_relight_set_eye(rt->rl, eye);
    return WRT_OK;
}

int wrt_runtime_emitter_count(const wrt_runtime *rt) { return live(rt) ? wrt_relight_emitter_count(rt->rl) : -1; }

wrt_status wrt_runtime_set_emitter_scale(wrt_runtime *rt, int material, float scale, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_set_emitter_scale", rt);
    /* The lights' bound (include/wrt.h, "Bounds"): radiance x scale at most WRT_MAX_INTENSITY;
     * FLT_MAX on an emitter of radiance 10 gave inf in the textures. */
    if (material >= 0 && material < (int)rt->g.nmaterials && isfinite(scale))
        for (int c = 0; c < 3; c++)
            if ((double)rt->g.materials[material].emissive[c] * scale > WRT_MAX_INTENSITY)
                return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_set_emitter_scale: material %d: scale %g "
                                          "times its radiance %g is beyond WRT_MAX_INTENSITY (%g)", material,
                                          (double)scale, (double)rt->g.materials[material].emissive[c],
                                          WRT_MAX_INTENSITY));
    wrt_status s = wrt_relight_set_emitter_scale(rt->rl, material, scale);
    return s == WRT_OK ? WRT_OK : fail(err, s);
}

wrt_status wrt_runtime_update(wrt_runtime *rt, int *changed, wrt_error *err) {
    if (changed) *changed = 0;
    if (!live(rt)) return dead(err, "wrt_runtime_update", rt);
    int n = wrt_relight_update(rt->rl, &rt->tm);
    if (changed) *changed = n > 0 ? n : 0;
    return n < 0 ? fail(err, WRT_ERR_NOMEM) : WRT_OK;
}

wrt_status wrt_runtime_set_budget(wrt_runtime *rt, double budget_ms, double skip_below, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_set_budget", rt);
    wrt_status s = wrt_relight_set_budget(rt->rl, budget_ms, skip_below);
    return s == WRT_OK ? WRT_OK : fail(err, s);
}

wrt_status wrt_runtime_get_update_stats(const wrt_runtime *rt, wrt_runtime_update_stats *out, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_get_update_stats", rt);
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_update_stats: out is NULL"));
    wrt_relight_counters c;
    wrt_relight_get_counters(rt->rl, &c);
    memset(out, 0, sizeof *out);
    out->pending = rt->tm.pending;
    out->skipped = rt->tm.skipped;
    out->ms[0] = rt->tm.projection; out->ms[1] = rt->tm.multiply; out->ms[2] = rt->tm.brdf;
    out->ms[3] = rt->tm.synthesis - rt->tm.reconstruction; out->ms[4] = rt->tm.reconstruction;
    out->updates = c.updates; out->projections = c.projections; out->multiplies = c.multiplies;
    out->skips = c.skips; out->quads_synthesized = c.quads_synthesized; out->groups_smoothed = c.groups_smoothed;
    out->gathers = c.gathers;
    out->entries_streamed = c.entries_streamed;
    return WRT_OK;
}

int wrt_runtime_material_count(const wrt_runtime *rt) { return live(rt) ? (int)rt->g.nmaterials : -1; }

wrt_status wrt_runtime_get_material(const wrt_runtime *rt, int i, wrt_runtime_material *out, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_get_material", rt);
    if (!out || i < 0 || i >= (int)rt->g.nmaterials)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_material: %s %d (the file has %u)",
                                  out ? "no material" : "out is NULL; material", i, rt->g.nmaterials));
    const wrt_gto_material *m = &rt->g.materials[i];
    memset(out, 0, sizeof *out);
    copy_name(out->name, m->name);
    for (int c = 0; c < 3; c++) { out->base_color[c] = m->base_color[c]; out->emissive[c] = m->emissive[c]; }
    out->metallic = m->metallic;
    out->roughness = m->roughness;
    out->lambertian = m->lambertian != 0;
    return WRT_OK;
}

wrt_status wrt_runtime_get_camera(const wrt_runtime *rt, wrt_runtime_camera *out, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_get_camera", rt);
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_camera: out is NULL"));
    memset(out, 0, sizeof *out);
    const wrt_gto_camera *c = rt->g.camera;
    if (!c || (c->yfov == 0 && c->aspect == 0 && c->znear == 0 && c->zfar == 0)) return WRT_OK; /* none */
    out->from_file = 1;
    for (int k = 0; k < 3; k++) { out->position[k] = c->pos[k]; out->direction[k] = c->dir[k]; out->up[k] = c->up[k]; }
    out->yfov = c->yfov;
    out->aspect = c->aspect;
    out->znear = c->znear;
    out->zfar = c->zfar;
    return WRT_OK;
}

wrt_status wrt_runtime_get_bounds(const wrt_runtime *rt, double lo[3], double hi[3], wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_get_bounds", rt);
    if (!lo || !hi) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_get_bounds: lo or hi is NULL"));
    for (int c = 0; c < 3; c++) { lo[c] = rt->lo[c]; hi[c] = rt->hi[c]; }
    return WRT_OK;
}

int wrt_runtime_quad_count(const wrt_runtime *rt) { return live(rt) ? (int)rt->g.nquads : -1; }

/* Handle, index and out-pointer of a per-quad call. */
static wrt_status quad_args(const wrt_runtime *rt, int q, const void *out, const char *fn, wrt_error *err) {
    if (!live(rt)) return dead(err, fn, rt);
    if (q < 0 || q >= (int)rt->g.nquads)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: no quad %d (the file has %u)", fn, q, rt->g.nquads));
    if (!out) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: out is NULL", fn));
    return WRT_OK;
}

wrt_status wrt_runtime_get_quad(const wrt_runtime *rt, int q, wrt_runtime_quad *out, wrt_error *err) {
    wrt_status s = quad_args(rt, q, out, "wrt_runtime_get_quad", err);
    if (s) return s;
    const wrt_gto_quad *gq = &rt->g.quads[q];
    memset(out, 0, sizeof *out);
    memcpy(out->corners, gq->p, sizeof out->corners);
    wrt_v3 p0 = v3(gq->p[0][0], gq->p[0][1], gq->p[0][2]), p1 = v3(gq->p[1][0], gq->p[1][1], gq->p[1][2]),
           p3 = v3(gq->p[3][0], gq->p[3][1], gq->p[3][2]);
    wrt_v3 n = v3_norm(v3_cross(v3_sub(p1, p0), v3_sub(p3, p0)));
    out->normal[0] = n.x; out->normal[1] = n.y; out->normal[2] = n.z;
    out->area = gq->area;
    out->material = (int)gq->material;
    out->parallelogram = (gq->flags & 1) != 0;
    /* .gto 1.x: a quad's `name` is the index of its glTF mesh in the names table (the
     * mesh names); the rest comes from the source map (1.2), else is "not stored". */
    out->mesh = gq->name == WRT_GTO_NO_NAME ? -1 : (int)gq->name;
    if (out->mesh >= 0) copy_name(out->mesh_name, rt->g.names[out->mesh]);
    out->node = out->primitive = out->triangles[0] = out->triangles[1] = -1;
    out->twin = out->kind = out->part = -1;
    out->twin_of = -1;
    const wrt_gto_srcmap *m = rt->g.srcmap ? &rt->g.srcmap[q] : NULL;
    if (m) { /* checked at open: indices >= -1, kind and part in range, twin_of earlier */
        out->node = m->node;
        out->mesh = m->mesh;
        out->primitive = m->prim;
        out->triangles[0] = m->tri[0];
        out->triangles[1] = m->tri[1];
        out->kind = (int)m->kind;
        out->part = (int)m->part;
        out->twin = (m->flags & WRT_GTO_SRC_TWIN) != 0;
        out->twin_of = m->twin_of;
        out->has_uv = (m->flags & WRT_GTO_SRC_UV) != 0;
        if (out->has_uv) memcpy(out->uv, m->uv, sizeof out->uv);
    }
    return WRT_OK;
}

wrt_status wrt_runtime_quad_corners(const wrt_runtime *rt, int q, double p[4][3], wrt_error *err) {
    wrt_status s = quad_args(rt, q, p, "wrt_runtime_quad_corners", err);
    if (s) return s;
    memcpy(p, rt->g.quads[q].p, sizeof(double) * 12);
    return WRT_OK;
}

const float *wrt_runtime_quad_texture(const wrt_runtime *rt, int q, int *res) {
    if (res) *res = 0;
    if (!live(rt) || q < 0 || q >= (int)rt->g.nquads) return NULL;
    if (res) *res = wrt_relight_tex_res(rt->rl, q);
    return wrt_relight_tex(rt->rl, q);
}

static wrt_quad quad_of(const wrt_gto_quad *gq) {
    wrt_quad wq;
    memset(&wq, 0, sizeof wq);
    for (int i = 0; i < 4; i++) wq.p[i] = v3(gq->p[i][0], gq->p[i][1], gq->p[i][2]);
    wq.area = gq->area;
    wq.parallelogram = (gq->flags & 1) != 0;
    return wq;
}

wrt_status wrt_runtime_quad_mean(const wrt_runtime *rt, int q, float rgb[3], wrt_error *err) {
    wrt_status s = quad_args(rt, q, rgb, "wrt_runtime_quad_mean", err);
    if (s) return s;
    int res = wrt_relight_tex_res(rt->rl, q);
    const float *tex = wrt_relight_tex(rt->rl, q);
    wrt_quad wq = quad_of(&rt->g.quads[q]);
    double acc[3] = {0, 0, 0}, wsum = 0;
    for (int j = 0; j < res; j++)
        for (int i = 0; i < res; i++) {
            double w = wq.parallelogram ? 1 : wrt_quad_jacobian(&wq, (i + 0.5) / res, (j + 0.5) / res);
            for (int c = 0; c < 3; c++) acc[c] += w * tex[((size_t)j * res + i) * 3 + c];
            wsum += w;
        }
    for (int c = 0; c < 3; c++) rgb[c] = wsum > 0 ? (float)(acc[c] / wsum) : 0.0f;
    return WRT_OK;
}

/* Each Haar function's exact average over each cell it overlaps, times sqrt(pi/J) (exact
 * for a parallelogram; for a general quad its cell mean by 8 x 8 midpoints, an
 * approximation since J varies within the cell). */
wrt_status wrt_runtime_quad_cells(const wrt_runtime *rt, int q, int n, double *out, wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_quad_cells", rt);
    if (q < 0 || q >= (int)rt->g.nquads || n < 1 || n > 1024 || !out)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_quad_cells: quad %d, n %d", q, n));
    const wrt_gto *g = &rt->g;
    const float *X = wrt_relight_X(rt->rl);
    const wrt_gto_quad *gq = &g->quads[q];
    memset(out, 0, (size_t)n * n * 3 * sizeof(double));
    for (uint32_t f = gq->func_first; f < gq->func_first + gq->func_count; f++) {
        wrt_fkey k = g->fkeys[f];
        if (!wrt_fkey_angular_root(k)) continue;
        const float *x = X + (size_t)f * 3;
        if (x[0] == 0 && x[1] == 0 && x[2] == 0) continue;
        wrt_node nd = wrt_fkey_snode(k);
        int type = wrt_fkey_stype(k);
        double sz = wrt_node_size(nd), h = sz / 2, val = ldexp(1.0, nd.level);
        for (int cy = 0; cy < 2; cy++)
            for (int cx = 0; cx < 2; cx++) {
                double r0 = wrt_node_x0(nd) + cx * h, s0 = wrt_node_y0(nd) + cy * h;
                double sgn = val * wrt_haar_sign(type, cx, cy);
                int i0 = (int)floor(r0 * n), i1 = (int)ceil((r0 + h) * n), j0 = (int)floor(s0 * n),
                    j1 = (int)ceil((s0 + h) * n);
                if (i1 > n) i1 = n;
                if (j1 > n) j1 = n;
                for (int j = j0; j < j1; j++)
                    for (int i = i0; i < i1; i++) {
                        double ox = fmin(r0 + h, (i + 1.0) / n) - fmax(r0, (double)i / n);
                        double oy = fmin(s0 + h, (j + 1.0) / n) - fmax(s0, (double)j / n);
                        if (ox <= 0 || oy <= 0) continue;
                        double a = sgn * ox * oy * n * n;
                        for (int c = 0; c < 3; c++) out[((size_t)j * n + i) * 3 + c] += a * x[c];
                    }
            }
    }
    wrt_quad wq = quad_of(gq);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            double fac = 0;
            if (wq.parallelogram) fac = sqrt(WRT_PI / wq.area);
            else {
                for (int b = 0; b < 8; b++)
                    for (int a = 0; a < 8; a++)
                        fac += sqrt(WRT_PI / wrt_quad_jacobian(&wq, (i + (a + 0.5) / 8) / n, (j + (b + 0.5) / 8) / n));
                fac /= 64;
            }
            for (int c = 0; c < 3; c++) out[((size_t)j * n + i) * 3 + c] *= fac;
        }
    return WRT_OK;
}

wrt_status wrt_runtime_quad_irradiance(const wrt_runtime *rt, int q, double direct[3], double indirect[3],
                                       wrt_error *err) {
    wrt_status s = quad_args(rt, q, direct && indirect ? direct : NULL, "wrt_runtime_quad_irradiance", err);
    if (s) return s;
    wrt_relight_quad_irradiance(rt->rl, q, direct, indirect);
    return WRT_OK;
}

wrt_status wrt_runtime_timings(const wrt_runtime *rt, double ms[4], wrt_error *err) {
    if (!live(rt)) return dead(err, "wrt_runtime_timings", rt);
    if (!ms) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "wrt_runtime_timings: ms is NULL"));
    ms[0] = rt->tm.projection; ms[1] = rt->tm.multiply; ms[2] = rt->tm.brdf; ms[3] = rt->tm.synthesis;
    return WRT_OK;
}

/* ---- the atlas ---- */

wrt_status wrt_runtime_atlas_layout(const wrt_runtime *rt, int width, wrt_atlas_rect *rects, int *width_out,
                                    int *height_out, wrt_error *err) {
    const char *fn = "wrt_runtime_atlas_layout";
    if (!live(rt)) return dead(err, fn, rt);
    if (!rects) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: rects is NULL", fn));
    int nq = (int)rt->g.nquads, widest = 0;
    double area = 0;
    for (int q = 0; q < nq; q++) {
        int t = wrt_relight_tex_res(rt->rl, q) + 2;
        if (t > widest) widest = t;
        area += (double)t * t;
    }
    if (width < 0 || (width > 0 && width < widest))
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: width %d, the widest tile needs %d (texture side + 2)",
                                  fn, width, widest));
    if (width == 0) {
        width = 1;
        while (width < widest || (double)width * width < area) width *= 2;
    }
    /* The order without a sort buffer (no allocation): the res is a power of two up to
     * 1024, so one pass per size, largest first, places the quads of that size by index. */
    long long x = 0, y = 0, row_h = 0;
    for (int lvl = 12; lvl >= 0; lvl--)
        for (int q = 0; q < nq; q++) {
            int res = wrt_relight_tex_res(rt->rl, q);
            if (res != 1 << lvl) continue;
            int t = res + 2;
            if (x + t > width) { y += row_h; x = 0; row_h = 0; }
            rects[q].x = (int)x + 1;
            rects[q].y = (int)y + 1;
            rects[q].res = res;
            x += t;
            if (t > row_h) row_h = t;
            if (y + row_h > (1LL << 31) / width)
                return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: the atlas exceeds 2^31 texels at width %d", fn,
                                          width));
        }
    if (width_out) *width_out = width;
    if (height_out) *height_out = (int)(y + row_h);
    return WRT_OK;
}

wrt_status wrt_runtime_atlas_fill(const wrt_runtime *rt, const wrt_atlas_rect *rects, int width, int height,
                                  float *rgb, size_t nfloats, wrt_error *err) {
    const char *fn = "wrt_runtime_atlas_fill";
    if (!live(rt)) return dead(err, fn, rt);
    if (!rects || !rgb) return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: rects or rgb is NULL", fn));
    if (width <= 0 || height <= 0 || (size_t)width * (size_t)height > nfloats / 3)
        return fail(err, wrt_fail(WRT_ERR_INVALID_ARG, "%s: %d x %d RGB texels need %zu floats, the buffer has %zu",
                                  fn, width, height, (size_t)(width > 0 ? width : 0) * (size_t)(height > 0 ? height : 0) * 3,
                                  nfloats));
    int nq = (int)rt->g.nquads;
    for (int q = 0; q < nq; q++) {
        const wrt_atlas_rect *r = &rects[q];
        if (r->res != wrt_relight_tex_res(rt->rl, q) || r->x < 1 || r->y < 1 || r->x > width - 1 - r->res ||
            r->y > height - 1 - r->res || !wrt_relight_tex(rt->rl, q))
            return fail(err, wrt_fail(WRT_ERR_INVALID_ARG,
                                      "%s: quad %d's rect (%d, %d) of side %d is not its texture (side %d) inside a "
                                      "%d x %d atlas with a border of 1",
                                      fn, q, r->x, r->y, r->res, wrt_relight_tex_res(rt->rl, q), width, height));
    }
    memset(rgb, 0, (size_t)width * (size_t)height * 3 * sizeof *rgb);
    for (int q = 0; q < nq; q++) {
        const wrt_atlas_rect *r = &rects[q];
        const float *tex = wrt_relight_tex(rt->rl, q);
        int res = r->res;
        /* rows -1 .. res and columns -1 .. res of the tile, clamped into the texture */
        for (int j = -1; j <= res; j++) {
            int sj = j < 0 ? 0 : j >= res ? res - 1 : j;
            float *dst = rgb + ((size_t)(r->y + j) * (size_t)width + (size_t)(r->x - 1)) * 3;
            const float *src = tex + (size_t)sj * (size_t)res * 3;
            memcpy(dst, src, 3 * sizeof *dst);
            memcpy(dst + 3, src, (size_t)res * 3 * sizeof *dst);
            memcpy(dst + 3 * (size_t)(res + 1), src + 3 * (size_t)(res - 1), 3 * sizeof *dst);
        }
    }
    return WRT_OK;
}
