/* ref_main.c: wrt-ref, the command-line front end of the reference path tracer
 * (verify/reference.h). Loads a quad-based glTF scene (formats/scene.h), optionally
 * replaces its lights by one given on the command line, and renders direct, indirect
 * and combined images of the radiance toward the camera plus the standard error of the
 * indirect part (OpenEXR through formats/image.h when the tree has it, plus a PNG of
 * the combined image; otherwise, or with --pfm, PFM files), and/or irradiance at surface points listed in a file, or
 * cell averages over a quad. Prints the figures (time, samples, rays, mean standard
 * error) as text or one JSON object. The reference for the comparisons of the paper's
 * section 6 (Kontkanen et al. 2006). */
#include "verify/reference.h"
#include "cli/cli.h"
#include "common/outfile.h"

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
            "Path-traces the scene (the independent reference): images of the radiance toward\n"
            "the camera, and/or irradiance at points or averaged over cells of a quad.\n"
            "Lights (default: the scene's; with none, --light-pos adds a white point light of 1 cd):\n");
    wrt_cli_lights_help(f);
    fprintf(f,
            "Images:\n"
            "  --spp N                 samples per pixel (default 64)\n"
            "  --width W --height H    image size (default 256 x 256)\n"
            "  --no-image              do not render an image\n"
            "  --viewport-aspect       frame the image by its own width / height, as wrt-play\n"
            "                          does, not by the camera's aspectRatio\n"
            "  -o, --out PREFIX        image files PREFIX_{direct,indirect,both,stderr}.exr\n"
            "                          and PREFIX_{both,direct}.png (default ref)\n"
            "  --pfm                   write .pfm files instead (always, without OpenImageIO)\n"
            "  --exposure EV           the PNGs' exposure in stops (default 0): x 2^EV, Reinhard\n"
            "                          x/(1+x), sRGB, the same curve as wrt-play's\n"
            "Points and cells:\n"
            "  --points FILE           irradiance at points, one 'QUAD U V' per line\n"
            "  --cells QUAD,N          mean irradiance over an N x N (u,v) grid on a quad\n"
            "  --samples N             paths per point / per cell (default 1024)\n"
            "Other:\n"
            "  --max-bounces N         reflections of indirect light, 0 = unbiased (default 0)\n"
            "  --threads N             worker threads, 0 = all cores (default 0)\n"
            "  --seed S                random seed (default 1)\n"
            "  --json                  print the figures as one JSON object\n"
            "  --version, -h, --help\n"
            "\n");
    wrt_cli_exit_table(f);
}

/* Writes a little-endian PFM (bottom row first) through a temporary file. */
static wrt_status write_pfm(const char *path, const float *rgb, int w, int h) {
    wrt_output o; /* a regular file only, through a temporary (common/outfile.h) */
    wrt_status st = wrt_output_begin(path, "wb", &o);
    if (st != WRT_OK) return st;
    fprintf(o.f, "PF\n%d %d\n-1.0\n", w, h);
    for (int y = h - 1; y >= 0; y--) fwrite(rgb + (size_t)3 * w * y, sizeof(float), (size_t)3 * w, o.f);
    return wrt_output_commit(&o);
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
        /* A line cut by the buffer, or holding a NUL byte (fgets stops only at a newline
         * or a full buffer): refused, so that /dev/zero is not read forever. */
        size_t len = strlen(line);
        if ((len == 0 || line[len - 1] != '\n') && (len == sizeof line - 1 || !feof(f))) {
            fclose(f);
            return wrt_fail(WRT_ERR_PARSE, "%s:%d: a line longer than %d bytes or holding a NUL byte", path,
                            lineno, (int)sizeof line - 2);
        }
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

/* PREFIX_NAME.png through the tone curve every tool's PNG shares (cli/cli.h). */
static wrt_status write_png(const char *prefix, const char *name, const float *rgb, int w, int h, double exposure,
                            char *path, size_t pathsize) {
#ifdef WRT_REF_HAVE_IMAGE
    uint8_t *px = wrt_xmalloc((size_t)w * h * 3);
    wrt_tonemap_rgb8(rgb, (size_t)w * h, (float)exposure, px);
    snprintf(path, pathsize, "%s_%s.png", prefix, name);
    wrt_status st = wrt_image_write_rgb8(path, px, w, h);
    free(px);
    return st;
#else
    (void)prefix; (void)name; (void)rgb; (void)w; (void)h; (void)exposure;
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

static const char *T = "wrt-ref";

/* The command line's settings */
typedef struct {
    const char *scene_path, *out_prefix, *points_path;
    double exposure;
    int pfm;
    int spp, width, height, image, viewport_aspect;
    int samples, max_bounces, threads, json, cell_quad, cell_n;
    long long seed;
    wrt_cli_lights L;
} ref_opts;

/* What the renders measured and wrote, for the report */
typedef struct {
    double t_image, t_points, t_cells;
    double img_se, img_ind, img_dir;
    double pt_se, pt_ind, cell_se, cell_ind;
    int npoints;
    char written[6][4200];
    int nwritten;
} ref_figures;

/* Stage 1: the command line; -1 to go on, else the exit code */
static int ref_parse(int argc, char **argv, ref_opts *o) {
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        long n;
        int lr = wrt_cli_lights_option(T, &o->L, argc, argv, &i);
        if (lr < 0) return WRT_EXIT_USAGE;
        if (lr > 0) continue;
#define INT(lo, hi, dst) do { if (!wrt_cli_int(T, a, v, lo, hi, &n)) return WRT_EXIT_USAGE; dst = (int)n; i++; } while (0)
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { usage(stdout); return 0; }
        else if (!strcmp(a, "--version")) { wrt_cli_version(T); return 0; }
        else if (!strcmp(a, "--json")) o->json = 1;
        else if (!strcmp(a, "--no-image")) o->image = 0;
        else if (!strcmp(a, "--viewport-aspect")) o->viewport_aspect = 1;
        else if (!strcmp(a, "--pfm")) o->pfm = 1;
        else if (!strcmp(a, "--exposure")) { if (!wrt_cli_num(T, a, v, -64, 64, &o->exposure)) return WRT_EXIT_USAGE; i++; }
        else if (!strcmp(a, "--spp")) INT(1, 1 << 24, o->spp);
        else if (!strcmp(a, "--width")) INT(1, 16384, o->width);
        else if (!strcmp(a, "--height")) INT(1, 16384, o->height);
        else if (!strcmp(a, "--samples")) INT(1, 1 << 30, o->samples);
        else if (!strcmp(a, "--max-bounces")) INT(0, 100000, o->max_bounces);
        else if (!strcmp(a, "--threads")) INT(0, 256, o->threads);
        else if (!strcmp(a, "--seed")) { if (!wrt_cli_int(T, a, v, 0, 1L << 62, &n)) return WRT_EXIT_USAGE; o->seed = n; i++; }
        else if (!strcmp(a, "-o") || !strcmp(a, "--out") || !strcmp(a, "--points")) {
            if (!v) { fprintf(stderr, "wrt-ref: error: %s needs a value\n", a); return WRT_EXIT_USAGE; }
            if (!strcmp(a, "--points")) o->points_path = v; else o->out_prefix = v;
            i++;
        } else if (!strcmp(a, "--cells")) {
            if (!v || sscanf(v, "%d,%d", &o->cell_quad, &o->cell_n) != 2 || o->cell_quad < 0 || o->cell_n < 1 || o->cell_n > 4096) {
                fprintf(stderr, "wrt-ref: error: bad value for --cells: '%s' (QUAD,N with N in [1, 4096])\n", v ? v : "");
                return WRT_EXIT_USAGE;
            }
            i++;
        }
        else if (a[0] == '-' && a[1]) { fprintf(stderr, "wrt-ref: error: unknown option %s (see --help)\n", a); return WRT_EXIT_USAGE; }
        else if (!o->scene_path) o->scene_path = a;
        else { fprintf(stderr, "wrt-ref: error: more than one scene ('%s', '%s')\n", o->scene_path, a); return WRT_EXIT_USAGE; }
#undef INT
    }
    if (!o->scene_path) { fprintf(stderr, "wrt-ref: error: no scene (see --help)\n"); return WRT_EXIT_USAGE; }
    wrt_output_protect(o->scene_path); /* no output replaces an input (common/outfile.h) */
    wrt_output_protect(o->points_path);
    return -1;
}

/* Stage 2: the scene and its lights with the command line's changes; -1 to go on, else
 * the exit code (nothing left allocated) */
static int ref_load(const ref_opts *o, wrt_scene *scene, wrt_light **lights_out, int *nlights_out) {
    wrt_status st = wrt_scene_load(o->scene_path, NULL, scene);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-ref: error: %s: %s\n", wrt_status_str(st), wrt_last_error());
        return st == WRT_ERR_NOMEM ? WRT_EXIT_INTERNAL : WRT_EXIT_INPUT;
    }
    if (o->cell_quad >= scene->nquads) {
        fprintf(stderr, "wrt-ref: error: --cells quad %d, the scene has %d (numbered from 0)\n", o->cell_quad, scene->nquads);
        wrt_scene_free(scene);
        return WRT_EXIT_USAGE;
    }
    /* the scene's lights with the command line's changes; a scene without lights gets a
     * white point light of 1 cd where --light-pos puts it */
    int nlights = scene->nlights;
    wrt_light *lights = wrt_xcalloc((size_t)(nlights ? nlights : 1), sizeof *lights);
    if (nlights) memcpy(lights, scene->lights, (size_t)nlights * sizeof *lights);
    else if (o->L.has_pos) {
        lights[0].type = WRT_LIGHT_POINT;
        lights[0].intensity = 1;
        lights[0].outer_cone = (float)(WRT_PI / 4);
        for (int c = 0; c < 3; c++) lights[0].color[c] = 1;
        snprintf(lights[0].name, sizeof lights[0].name, "command line");
        nlights = 1;
    }
    int arc = wrt_cli_lights_apply(T, &o->L, lights, nlights, NULL);
    if (arc) {
        free(lights);
        wrt_scene_free(scene);
        return arc;
    }
    if (nlights == 0) wrt_log(WRT_LOG_WARN, "%s has no lights: everything is black", o->scene_path);
    *lights_out = lights;
    *nlights_out = nlights;
    return -1;
}

/* Stage 3: the images and their files; returns the exit code so far */
static int ref_image(const ref_opts *o, wrt_ref *ref, const wrt_scene *scene, const wrt_light *lights, int nlights,
                     ref_figures *f) {
    int rc = 0;
    size_t n = (size_t)o->width * o->height * 3;
    float *d = wrt_xmalloc(n * sizeof(float)), *ind = wrt_xmalloc(n * sizeof(float));
    float *both = wrt_xmalloc(n * sizeof(float)), *se = wrt_xmalloc(n * sizeof(float));
    double t0 = wrt_now();
    wrt_camera cam = scene->camera;
    if (o->viewport_aspect) cam.aspect = 0; /* wrt_ref_render: 0 = width / height */
    wrt_status st = wrt_ref_render(ref, lights, nlights, &cam, o->width, o->height, o->spp, o->max_bounces,
                                   o->threads, (uint64_t)o->seed, d, ind, both, se);
    f->t_image = wrt_now() - t0;
    if (st == WRT_OK) {
        f->img_se = mean_of_f(se, n); f->img_ind = mean_of_f(ind, n); f->img_dir = mean_of_f(d, n);
        const char *names[4] = {"direct", "indirect", "both", "stderr"};
        const float *imgs[4] = {d, ind, both, se};
        for (int k = 0; k < 4 && st == WRT_OK; k++) {
            st = write_image(o->out_prefix, names[k], o->pfm, imgs[k], o->width, o->height, f->written[k],
                             sizeof f->written[k]);
            if (st == WRT_OK) f->nwritten++;
        }
        for (int k = 0; k < 2 && st == WRT_OK && !o->pfm; k++) {
            st = write_png(o->out_prefix, k ? "direct" : "both", k ? d : both, o->width, o->height, o->exposure,
                           f->written[f->nwritten], sizeof f->written[f->nwritten]);
            if (st == WRT_OK && f->written[f->nwritten][0]) f->nwritten++;
        }
    } else {
        fprintf(stderr, "wrt-ref: error: %s\n", wrt_last_error());
        rc = st == WRT_ERR_INVALID_ARG ? WRT_EXIT_USAGE : WRT_EXIT_INTERNAL;
        st = WRT_OK;
    }
    free(d); free(ind); free(both); free(se);
    if (st != WRT_OK) { fprintf(stderr, "wrt-ref: error: %s\n", wrt_last_error()); rc = WRT_EXIT_OUTPUT; }
    return rc;
}

/* Stage 4: irradiance at the points of --points; returns the exit code so far */
static int ref_points(const ref_opts *o, wrt_ref *ref, const wrt_scene *scene, const wrt_light *lights, int nlights,
                      ref_figures *f) {
    int rc = 0;
    point_list pl;
    wrt_status st = read_points(o->points_path, scene, &pl);
    if (st == WRT_OK && pl.n > 0) {
        double *d = wrt_xmalloc(sizeof(double) * 3 * pl.n), *ind = wrt_xmalloc(sizeof(double) * 3 * pl.n);
        double *se = wrt_xmalloc(sizeof(double) * 3 * pl.n);
        double t0 = wrt_now();
        st = wrt_ref_irradiance(ref, lights, nlights, pl.p, pl.quad, pl.n, o->samples, o->max_bounces,
                                o->threads, (uint64_t)o->seed, d, ind, se);
        f->t_points = wrt_now() - t0;
        if (st == WRT_OK) {
            f->npoints = pl.n;
            f->pt_se = mean_of(se, 3 * (size_t)pl.n); f->pt_ind = mean_of(ind, 3 * (size_t)pl.n);
            if (!o->json) printf("# quad u v  direct_rgb  indirect_rgb  indirect_stderr_rgb\n");
            for (int i = 0; i < pl.n && !o->json; i++)
                printf("%d %.6f %.6f  %.9g %.9g %.9g  %.9g %.9g %.9g  %.3g %.3g %.3g\n",
                       pl.quad[i], pl.uv[2 * i], pl.uv[2 * i + 1], d[3 * i], d[3 * i + 1],
                       d[3 * i + 2], ind[3 * i], ind[3 * i + 1], ind[3 * i + 2], se[3 * i],
                       se[3 * i + 1], se[3 * i + 2]);
        }
        free(d); free(ind); free(se);
    }
    free(pl.p); free(pl.quad); free(pl.uv);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-ref: error: %s\n", wrt_last_error());
        rc = st == WRT_ERR_IO || st == WRT_ERR_PARSE ? WRT_EXIT_INPUT : WRT_EXIT_INTERNAL;
    }
    return rc;
}

/* Stage 5: cell averages over the quad of --cells; returns the exit code so far */
static int ref_cells(const ref_opts *o, wrt_ref *ref, const wrt_light *lights, int nlights, ref_figures *f) {
    int rc = 0;
    int cell_n = o->cell_n;
    size_t n = (size_t)cell_n * cell_n * 3;
    double *d = wrt_xmalloc(sizeof(double) * n), *ind = wrt_xmalloc(sizeof(double) * n);
    double *se = wrt_xmalloc(sizeof(double) * n);
    double t0 = wrt_now();
    wrt_status st = wrt_ref_cell_irradiance(ref, lights, nlights, o->cell_quad, cell_n, o->samples, o->max_bounces,
                                            o->threads, (uint64_t)o->seed, d, ind, se);
    f->t_cells = wrt_now() - t0;
    if (st == WRT_OK) {
        f->cell_se = mean_of(se, n); f->cell_ind = mean_of(ind, n);
        if (!o->json) printf("# cell i j  direct_rgb  indirect_rgb  indirect_stderr_rgb (quad %d)\n", o->cell_quad);
        for (int c = 0; c < cell_n * cell_n && !o->json; c++)
            printf("%d %d  %.9g %.9g %.9g  %.9g %.9g %.9g  %.3g %.3g %.3g\n", c % cell_n,
                   c / cell_n, d[3 * c], d[3 * c + 1], d[3 * c + 2], ind[3 * c],
                   ind[3 * c + 1], ind[3 * c + 2], se[3 * c], se[3 * c + 1], se[3 * c + 2]);
    } else {
        fprintf(stderr, "wrt-ref: error: %s\n", wrt_last_error());
        rc = WRT_EXIT_INTERNAL;
    }
    free(d); free(ind); free(se);
    return rc;
}

/* Stage 6: the figures, as one JSON object or a line of text and the files written */
static void ref_report(const ref_opts *o, const wrt_scene *scene, int nlights, const ref_figures *f, uint64_t rays,
                       int rc) {
    double t_all = f->t_image + f->t_points + f->t_cells;
    if (o->json) {
        printf("{\"scene\":");
        wrt_cli_json_str(stdout, o->scene_path);
        printf(",\"quads\":%d,\"lights\":%d,\"threads\":%d,\"seed\":%lld,"
               "\"max_bounces\":%d,\"time_s\":%.4f,\"rays\":%llu,\"mrays_per_s\":%.3f",
               scene->nquads, nlights, o->threads, o->seed, o->max_bounces, t_all,
               (unsigned long long)rays, t_all > 0 ? rays / t_all / 1e6 : 0.0);
        if (o->image)
            printf(",\"image\":{\"width\":%d,\"height\":%d,\"spp\":%d,\"time_s\":%.4f,"
                   "\"mean_direct\":%.6g,\"mean_indirect\":%.6g,\"mean_indirect_stderr\":%.6g,"
                   "\"files\":[",
                   o->width, o->height, o->spp, f->t_image, f->img_dir, f->img_ind, f->img_se);
        for (int k = 0; o->image && k < f->nwritten; k++) {
            if (k) putchar(',');
            wrt_cli_json_str(stdout, f->written[k]);
        }
        if (o->image) printf("]}");
        if (o->points_path)
            printf(",\"points\":{\"count\":%d,\"samples\":%d,\"time_s\":%.4f,\"mean_indirect\":%.6g,"
                   "\"mean_indirect_stderr\":%.6g}",
                   f->npoints, o->samples, f->t_points, f->pt_ind, f->pt_se);
        if (o->cell_n > 0)
            printf(",\"cells\":{\"quad\":%d,\"n\":%d,\"samples\":%d,\"time_s\":%.4f,"
                   "\"mean_indirect\":%.6g,\"mean_indirect_stderr\":%.6g}",
                   o->cell_quad, o->cell_n, o->samples, f->t_cells, f->cell_ind, f->cell_se);
        printf(",\"ok\":%s}\n", rc == 0 ? "true" : "false");
    } else {
        fprintf(stderr, "wrt-ref: %.3f s, %llu rays (%.2f Mrays/s)", t_all,
                (unsigned long long)rays, t_all > 0 ? rays / t_all / 1e6 : 0.0);
        if (o->image) fprintf(stderr, "; image %dx%d, %d spp, mean indirect %.4g +- %.2g (mean se)",
                              o->width, o->height, o->spp, f->img_ind, f->img_se);
        fprintf(stderr, "\n");
        for (int k = 0; k < f->nwritten; k++) fprintf(stderr, "wrote %s\n", f->written[k]);
    }
}

int main(int argc, char **argv) {
    wrt_cli_init("wrt-ref"); /* stdout checked at exit (3), out of memory: exit 7 */
    ref_opts o = {.out_prefix = "ref", .spp = 64, .width = 256, .height = 256, .image = 1, .samples = 1024,
                  .cell_quad = -1, .seed = 1};
    wrt_cli_lights_init(&o.L);
    int prc = ref_parse(argc, argv, &o);
    if (prc >= 0) return prc;

    wrt_scene scene;
    wrt_light *lights = NULL;
    int nlights = 0;
    int lrc = ref_load(&o, &scene, &lights, &nlights);
    if (lrc >= 0) return lrc;

    wrt_ref *ref = wrt_ref_create(&scene);
    if (!ref) {
        fprintf(stderr, "wrt-ref: error: %s\n", wrt_last_error());
        free(lights);
        wrt_scene_free(&scene);
        return WRT_EXIT_INTERNAL;
    }
    int rc = 0;
    ref_figures f = {0};
    if (o.image) rc = ref_image(&o, ref, &scene, lights, nlights, &f);
    if (o.points_path && rc == 0) rc = ref_points(&o, ref, &scene, lights, nlights, &f);
    if (o.cell_n > 0 && rc == 0) rc = ref_cells(&o, ref, lights, nlights, &f);
    ref_report(&o, &scene, nlights, &f, wrt_ref_rays(ref), rc);
    wrt_ref_destroy(ref);
    free(lights);
    wrt_scene_free(&scene);
    return rc;
}
