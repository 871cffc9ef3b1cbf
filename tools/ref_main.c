/* ref_main.c: wrt-ref, the command-line front end of the reference path tracer
 * (tools/reference.h). Loads a quad-based glTF scene (formats/scene.h), optionally
 * replaces its lights by one given on the command line, and renders direct, indirect
 * and combined images of the radiance toward the camera plus the standard error of the
 * indirect part (OpenEXR through formats/image.h when the tree has it, plus a PNG of
 * the combined image; otherwise, or with --pfm, PFM files), and/or irradiance at surface points listed in a file, or
 * cell averages over a quad. Prints the figures (time, samples, rays, mean standard
 * error) as text or one JSON object. The reference for the comparisons of the paper's
 * section 6 (Kontkanen et al. 2006). */
#include "tools/reference.h"

/* The OpenImageIO shim is optional at build time so that this tool stands alone. */
#if defined(__has_include)
#if __has_include("formats/image.h")
#include "formats/image.h"
#define WRT_REF_HAVE_IMAGE 1
#endif
#endif

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: wrt-ref SCENE.gltf [options]\n"
            "  --light-pos X,Y,Z       use one light there (a copy of the scene's first light,\n"
            "                          or a white point light) instead of the scene's lights\n"
            "  --light-dir X,Y,Z       make it a spot light along this axis\n"
            "  --light-cone IN,OUT     spot cone angles in radians (default 0,0.7854)\n"
            "  --light-intensity I     candela (default: the scene light's, else 1)\n"
            "  --light-color R,G,B     linear RGB (default 1,1,1)\n"
            "  --spp N                 samples per pixel (default 64)\n"
            "  --width W --height H    image size (default 256 x 256)\n"
            "  --no-image              do not render an image\n"
            "  --out PREFIX            image files PREFIX_{direct,indirect,both,stderr}.exr\n"
            "                          and PREFIX_both.png (default ref)\n"
            "  --pfm                   write .pfm files instead (always, without OpenImageIO)\n"
            "  --exposure E            scale before the PNG's sRGB encoding (default 1)\n"
            "  --points FILE           irradiance at points, one 'QUAD U V' per line\n"
            "  --cells QUAD,N          mean irradiance over an N x N (u,v) grid on a quad\n"
            "  --samples N             paths per point / per cell (default 1024)\n"
            "  --max-bounces N         reflections of indirect light, 0 = unbiased (default 0)\n"
            "  --threads N             worker threads, 0 = all cores (default 0)\n"
            "  --seed S                random seed (default 1)\n"
            "  --json                  print the figures as one JSON object\n");
}

static int parse_int(const char *s, long lo, long hi, int *out) {
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (end == s || *end || errno || v < lo || v > hi) return 0;
    *out = (int)v;
    return 1;
}

/* Writes a little-endian PFM (bottom row first) through a temporary file. */
static wrt_status write_pfm(const char *path, const float *rgb, int w, int h) {
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp)
        return wrt_fail(WRT_ERR_INVALID_ARG, "%s: path too long", path);
    FILE *f = fopen(tmp, "wb");
    if (!f) return wrt_fail(WRT_ERR_IO, "%s: %s", tmp, strerror(errno));
    int ok = fprintf(f, "PF\n%d %d\n-1.0\n", w, h) > 0;
    for (int y = h - 1; y >= 0 && ok; y--)
        ok = fwrite(rgb + (size_t)3 * w * y, sizeof(float), (size_t)3 * w, f) == (size_t)3 * w;
    ok = (fflush(f) == 0) && ok;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, path) != 0) {
        remove(tmp);
        return wrt_fail(WRT_ERR_IO, "%s: write failed", path);
    }
    return WRT_OK;
}

typedef struct point_list { wrt_v3 *p; int *quad; double *uv; int n; } point_list;

static wrt_status read_points(const char *path, const wrt_scene *s, point_list *out) {
    FILE *f = fopen(path, "r");
    if (!f) return wrt_fail(WRT_ERR_IO, "%s: %s", path, strerror(errno));
    char line[512];
    int cap = 0, lineno = 0;
    memset(out, 0, sizeof *out);
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *c = line;
        while (*c == ' ' || *c == '\t') c++;
        if (*c == '#' || *c == '\n' || *c == 0) continue;
        int q;
        double u, v;
        if (sscanf(c, "%d %lf %lf", &q, &u, &v) != 3 || q < 0 || q >= s->nquads || !(u >= 0) ||
            !(u <= 1) || !(v >= 0) || !(v <= 1)) {
            fclose(f);
            return wrt_fail(WRT_ERR_PARSE, "%s:%d: want 'QUAD U V' with QUAD < %d, U,V in [0,1]",
                            path, lineno, s->nquads);
        }
        if (out->n == cap) {
            cap = cap ? 2 * cap : 64;
            out->p = wrt_xrealloc(out->p, sizeof *out->p * cap);
            out->quad = wrt_xrealloc(out->quad, sizeof *out->quad * cap);
            out->uv = wrt_xrealloc(out->uv, sizeof *out->uv * 2 * cap);
        }
        out->p[out->n] = wrt_quad_point(&s->quads[q], u, v);
        out->quad[out->n] = q;
        out->uv[2 * out->n] = u;
        out->uv[2 * out->n + 1] = v;
        out->n++;
    }
    fclose(f);
    return WRT_OK;
}

/* A JSON string literal (quotes, backslashes and control characters escaped). */
static void print_json_str(const char *s) {
    putchar('"');
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') printf("\\%c", c);
        else if (c < 0x20) printf("\\u%04x", c);
        else putchar(c);
    }
    putchar('"');
}

/* sRGB encoding of a linear value in [0, 1]. */
static double srgb_encode(double v) {
    v = v < 0 ? 0 : v > 1 ? 1 : v;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
}

/* Writes one image: EXR when the OpenImageIO shim is built in and pfm is 0, else PFM. */
static wrt_status write_image(const char *prefix, const char *name, int pfm, const float *rgb,
                              int w, int h, char *path, size_t pathsize) {
#ifdef WRT_REF_HAVE_IMAGE
    if (!pfm) {
        snprintf(path, pathsize, "%s_%s.exr", prefix, name);
        return wrt_image_write_exr(path, rgb, w, h);
    }
#endif
    (void)pfm;
    snprintf(path, pathsize, "%s_%s.pfm", prefix, name);
    return write_pfm(path, rgb, w, h);
}

static wrt_status write_png(const char *prefix, const float *rgb, int w, int h, double exposure,
                            char *path, size_t pathsize) {
#ifdef WRT_REF_HAVE_IMAGE
    size_t n = (size_t)w * h * 3;
    uint8_t *px = wrt_xmalloc(n);
    for (size_t i = 0; i < n; i++) px[i] = (uint8_t)(255 * srgb_encode(rgb[i] * exposure) + 0.5);
    snprintf(path, pathsize, "%s_both.png", prefix);
    wrt_status st = wrt_image_write_rgb8(path, px, w, h);
    free(px);
    return st;
#else
    (void)prefix; (void)rgb; (void)w; (void)h; (void)exposure; (void)srgb_encode;
    path[0] = 0;
    return WRT_OK;
#endif
}

static double mean_of(const double *v, size_t n) {
    double s = 0;
    for (size_t i = 0; i < n; i++) s += v[i];
    return n ? s / n : 0;
}
static double mean_of_f(const float *v, size_t n) {
    double s = 0;
    for (size_t i = 0; i < n; i++) s += v[i];
    return n ? s / n : 0;
}

int main(int argc, char **argv) {
    const char *scene_path = NULL, *out_prefix = "ref", *points_path = NULL;
    double lpos[3], ldir[3], lcolor[3] = {1, 1, 1}, lint = -1, cone_in = 0, cone_out = WRT_PI / 4;
    double exposure = 1;
    int pfm = 0;
    int have_pos = 0, have_dir = 0, spp = 64, width = 256, height = 256, image = 1;
    int samples = 1024, max_bounces = 0, threads = 0, json = 0, cell_quad = -1, cell_n = 0;
    long long seed = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        int ok = 1, takes = 1;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { usage(stdout); return 0; }
        else if (!strcmp(a, "--json")) { json = 1; takes = 0; }
        else if (!strcmp(a, "--no-image")) { image = 0; takes = 0; }
        else if (!strcmp(a, "--pfm")) { pfm = 1; takes = 0; }
        else if (a[0] == '-' && a[1] == '-' && !v) ok = 0;
        else if (!strcmp(a, "--light-pos")) { ok = wrt_parse_vec3(v, lpos); have_pos = 1; }
        else if (!strcmp(a, "--light-dir")) { ok = wrt_parse_vec3(v, ldir); have_dir = 1; }
        else if (!strcmp(a, "--light-color")) ok = wrt_parse_vec3(v, lcolor);
        else if (!strcmp(a, "--light-intensity")) { char *e; lint = strtod(v, &e); ok = *e == 0 && lint >= 0 && isfinite(lint); }
        else if (!strcmp(a, "--light-cone")) ok = sscanf(v, "%lf,%lf", &cone_in, &cone_out) == 2 && cone_in >= 0 && cone_out > cone_in && cone_out <= WRT_PI / 2;
        else if (!strcmp(a, "--exposure")) { char *e; exposure = strtod(v, &e); ok = *e == 0 && exposure > 0 && isfinite(exposure); }
        else if (!strcmp(a, "--spp")) ok = parse_int(v, 1, 1 << 24, &spp);
        else if (!strcmp(a, "--width")) ok = parse_int(v, 1, 16384, &width);
        else if (!strcmp(a, "--height")) ok = parse_int(v, 1, 16384, &height);
        else if (!strcmp(a, "--out")) out_prefix = v;
        else if (!strcmp(a, "--points")) points_path = v;
        else if (!strcmp(a, "--cells")) ok = sscanf(v, "%d,%d", &cell_quad, &cell_n) == 2 && cell_quad >= 0 && cell_n >= 1 && cell_n <= 4096;
        else if (!strcmp(a, "--samples")) ok = parse_int(v, 1, 1 << 30, &samples);
        else if (!strcmp(a, "--max-bounces")) ok = parse_int(v, 0, 100000, &max_bounces);
        else if (!strcmp(a, "--threads")) ok = parse_int(v, 0, 256, &threads);
        else if (!strcmp(a, "--seed")) { char *e; seed = strtoll(v, &e, 10); ok = *e == 0; }
        else if (a[0] == '-') { fprintf(stderr, "wrt-ref: unknown option %s\n", a); usage(stderr); return 2; }
        else { scene_path = a; takes = 0; }
        if (!ok) { fprintf(stderr, "wrt-ref: bad value for %s\n", a); return 2; }
        i += takes;
    }
    if (!scene_path) { usage(stderr); return 2; }

    wrt_scene scene;
    wrt_status st = wrt_scene_load(scene_path, NULL, &scene);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-ref: %s: %s\n", wrt_status_str(st), wrt_last_error());
        return 1;
    }
    if (cell_quad >= scene.nquads) {
        fprintf(stderr, "wrt-ref: --cells quad %d, the scene has %d\n", cell_quad, scene.nquads);
        wrt_scene_free(&scene);
        return 2;
    }
    wrt_light one;
    const wrt_light *lights = scene.lights;
    int nlights = scene.nlights;
    if (have_pos) {
        memset(&one, 0, sizeof one);
        if (scene.nlights > 0) one = scene.lights[0];
        else {
            one.intensity = 1;
            one.outer_cone = (float)(WRT_PI / 4);
            snprintf(one.name, sizeof one.name, "command line");
        }
        one.pos = v3(lpos[0], lpos[1], lpos[2]);
        one.type = WRT_LIGHT_POINT;
        if (have_dir) {
            one.type = WRT_LIGHT_SPOT;
            one.dir = v3_norm(v3(ldir[0], ldir[1], ldir[2]));
            one.inner_cone = (float)cone_in;
            one.outer_cone = (float)cone_out;
        }
        if (lint >= 0) one.intensity = (float)lint;
        for (int c = 0; c < 3; c++) one.color[c] = (float)lcolor[c];
        lights = &one;
        nlights = 1;
    }
    if (nlights == 0) wrt_log(WRT_LOG_WARN, "%s has no lights: everything is black", scene_path);

    wrt_ref *ref = wrt_ref_create(&scene);
    if (!ref) {
        fprintf(stderr, "wrt-ref: %s\n", wrt_last_error());
        wrt_scene_free(&scene);
        return 1;
    }
    int rc = 0;
    double t_image = 0, t_points = 0, t_cells = 0;
    double img_se = 0, img_ind = 0, img_dir = 0;
    double pt_se = 0, pt_ind = 0, cell_se = 0, cell_ind = 0;
    int npoints = 0;
    char written[5][4200];
    int nwritten = 0;

    if (image) {
        size_t n = (size_t)width * height * 3;
        float *d = wrt_xmalloc(n * sizeof(float)), *ind = wrt_xmalloc(n * sizeof(float));
        float *both = wrt_xmalloc(n * sizeof(float)), *se = wrt_xmalloc(n * sizeof(float));
        double t0 = wrt_now();
        st = wrt_ref_render(ref, lights, nlights, &scene.camera, width, height, spp, max_bounces,
                            threads, (uint64_t)seed, d, ind, both, se);
        t_image = wrt_now() - t0;
        if (st == WRT_OK) {
            img_se = mean_of_f(se, n); img_ind = mean_of_f(ind, n); img_dir = mean_of_f(d, n);
            const char *names[4] = {"direct", "indirect", "both", "stderr"};
            const float *imgs[4] = {d, ind, both, se};
            for (int k = 0; k < 4 && st == WRT_OK; k++) {
                st = write_image(out_prefix, names[k], pfm, imgs[k], width, height, written[k],
                                 sizeof written[k]);
                if (st == WRT_OK) nwritten++;
            }
            if (st == WRT_OK && !pfm) {
                st = write_png(out_prefix, both, width, height, exposure, written[4],
                               sizeof written[4]);
                if (st == WRT_OK && written[4][0]) nwritten++;
            }
        }
        free(d); free(ind); free(both); free(se);
        if (st != WRT_OK) { fprintf(stderr, "wrt-ref: %s\n", wrt_last_error()); rc = 1; }
    }
    if (points_path && rc == 0) {
        point_list pl;
        st = read_points(points_path, &scene, &pl);
        if (st == WRT_OK && pl.n > 0) {
            double *d = wrt_xmalloc(sizeof(double) * 3 * pl.n), *ind = wrt_xmalloc(sizeof(double) * 3 * pl.n);
            double *se = wrt_xmalloc(sizeof(double) * 3 * pl.n);
            double t0 = wrt_now();
            st = wrt_ref_irradiance(ref, lights, nlights, pl.p, pl.quad, pl.n, samples, max_bounces,
                                    threads, (uint64_t)seed, d, ind, se);
            t_points = wrt_now() - t0;
            if (st == WRT_OK) {
                npoints = pl.n;
                pt_se = mean_of(se, 3 * (size_t)pl.n); pt_ind = mean_of(ind, 3 * (size_t)pl.n);
                if (!json) printf("# quad u v  direct_rgb  indirect_rgb  indirect_stderr_rgb\n");
                for (int i = 0; i < pl.n && !json; i++)
                    printf("%d %.6f %.6f  %.9g %.9g %.9g  %.9g %.9g %.9g  %.3g %.3g %.3g\n",
                           pl.quad[i], pl.uv[2 * i], pl.uv[2 * i + 1], d[3 * i], d[3 * i + 1],
                           d[3 * i + 2], ind[3 * i], ind[3 * i + 1], ind[3 * i + 2], se[3 * i],
                           se[3 * i + 1], se[3 * i + 2]);
            }
            free(d); free(ind); free(se);
        }
        free(pl.p); free(pl.quad); free(pl.uv);
        if (st != WRT_OK) { fprintf(stderr, "wrt-ref: %s\n", wrt_last_error()); rc = 1; }
    }
    if (cell_n > 0 && rc == 0) {
        size_t n = (size_t)cell_n * cell_n * 3;
        double *d = wrt_xmalloc(sizeof(double) * n), *ind = wrt_xmalloc(sizeof(double) * n);
        double *se = wrt_xmalloc(sizeof(double) * n);
        double t0 = wrt_now();
        st = wrt_ref_cell_irradiance(ref, lights, nlights, cell_quad, cell_n, samples, max_bounces,
                                     threads, (uint64_t)seed, d, ind, se);
        t_cells = wrt_now() - t0;
        if (st == WRT_OK) {
            cell_se = mean_of(se, n); cell_ind = mean_of(ind, n);
            if (!json) printf("# cell i j  direct_rgb  indirect_rgb  indirect_stderr_rgb (quad %d)\n", cell_quad);
            for (int c = 0; c < cell_n * cell_n && !json; c++)
                printf("%d %d  %.9g %.9g %.9g  %.9g %.9g %.9g  %.3g %.3g %.3g\n", c % cell_n,
                       c / cell_n, d[3 * c], d[3 * c + 1], d[3 * c + 2], ind[3 * c],
                       ind[3 * c + 1], ind[3 * c + 2], se[3 * c], se[3 * c + 1], se[3 * c + 2]);
        } else {
            fprintf(stderr, "wrt-ref: %s\n", wrt_last_error());
            rc = 1;
        }
        free(d); free(ind); free(se);
    }
    double t_all = t_image + t_points + t_cells;
    uint64_t rays = wrt_ref_rays(ref);
    if (json) {
        printf("{\"scene\":");
        print_json_str(scene_path);
        printf(",\"quads\":%d,\"lights\":%d,\"threads\":%d,\"seed\":%lld,"
               "\"max_bounces\":%d,\"time_s\":%.4f,\"rays\":%llu,\"mrays_per_s\":%.3f",
               scene.nquads, nlights, threads, seed, max_bounces, t_all,
               (unsigned long long)rays, t_all > 0 ? rays / t_all / 1e6 : 0.0);
        if (image)
            printf(",\"image\":{\"width\":%d,\"height\":%d,\"spp\":%d,\"time_s\":%.4f,"
                   "\"mean_direct\":%.6g,\"mean_indirect\":%.6g,\"mean_indirect_stderr\":%.6g,"
                   "\"files\":[",
                   width, height, spp, t_image, img_dir, img_ind, img_se);
        for (int k = 0; image && k < nwritten; k++) {
            if (k) putchar(',');
            print_json_str(written[k]);
        }
        if (image) printf("]}");
        if (points_path)
            printf(",\"points\":{\"count\":%d,\"samples\":%d,\"time_s\":%.4f,\"mean_indirect\":%.6g,"
                   "\"mean_indirect_stderr\":%.6g}",
                   npoints, samples, t_points, pt_ind, pt_se);
        if (cell_n > 0)
            printf(",\"cells\":{\"quad\":%d,\"n\":%d,\"samples\":%d,\"time_s\":%.4f,"
                   "\"mean_indirect\":%.6g,\"mean_indirect_stderr\":%.6g}",
                   cell_quad, cell_n, samples, t_cells, cell_ind, cell_se);
        printf(",\"ok\":%s}\n", rc == 0 ? "true" : "false");
    } else {
        fprintf(stderr, "wrt-ref: %.3f s, %llu rays (%.2f Mrays/s)", t_all,
                (unsigned long long)rays, t_all > 0 ? rays / t_all / 1e6 : 0.0);
        if (image) fprintf(stderr, "; image %dx%d, %d spp, mean indirect %.4g +- %.2g (mean se)",
                           width, height, spp, img_ind, img_se);
        fprintf(stderr, "\n");
        for (int k = 0; k < nwritten; k++) fprintf(stderr, "wrote %s\n", written[k]);
    }
    wrt_ref_destroy(ref);
    wrt_scene_free(&scene);
    return rc;
}
