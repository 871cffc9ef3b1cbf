/* image_err.c: the image error of a picture against the path tracer's (docs/triangles.md,
 * "The sphere and Suzanne"): relative RMS over the pixels of a box, debiased by the
 * reference's own standard error, as wrt-compare measures its images:
 *   rmse     = sqrt(sum |a - r|^2 / sum |r|^2)
 *   floor    = sqrt(sum se^2 / sum |r|^2)            (the reference's noise alone)
 *   debiased = sqrt(max(0, sum |a - r|^2 - sum se^2) / sum |r|^2)
 * over the three channels of every pixel in the box. Reads any image formats/image.h reads
 * (EXR: linear radiance, as wrt-play -o X.exr and wrt-ref -o write them).
 * Usage: image_err PLAYER.exr REF.exr [--se REF_stderr.exr] [--box X,Y,W,H]...
 *                  [--png PREFIX [--exposure EV]]
 * one line per box (the whole image without one). --png writes PREFIX_a.png and
 * PREFIX_r.png (the two images, x 2^EV, Reinhard x/(1+x), sRGB: wrt-play's curve) and
 * PREFIX_map.png, the error map |a - r| / the reference's mean over the image (luminance;
 * black 0, red 25%, yellow 50% and more). Not installed. */
#include "../formats/image.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct { int x, y, w, h; } box;

static int read_img(const char *path, float **px, int *w, int *h) {
    if (wrt_image_read(path, px, w, h) != WRT_OK) {
        fprintf(stderr, "image_err: error: cannot read %s: %s\n", path, wrt_last_error());
        return 0;
    }
    return 1;
}

static uint8_t enc(double x) { /* Reinhard, then sRGB */
    x = x > 0 ? x / (1 + x) : 0;
    x = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1 / 2.4) - 0.055;
    return (uint8_t)lrint(fmin(fmax(x, 0), 1) * 255);
}

static double lum(const float *p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

/* PREFIX_a.png, PREFIX_r.png and PREFIX_map.png; 0 on a write error. */
static int write_pngs(const char *prefix, const float *a, const float *r, int w, int h, double ev) {
    size_t n = (size_t)w * h;
    uint8_t *px = malloc(n * 3);
    char path[4096];
    double mean = 0;
    for (size_t i = 0; i < n; i++) mean += lum(r + 3 * i) / (double)n;
    int ok = px != NULL;
    for (int k = 0; k < 3 && ok; k++) {
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) {
                if (k < 2) { px[3 * i + c] = enc((k ? r : a)[3 * i + c] * pow(2, ev)); continue; }
                double e = mean > 0 ? fabs(lum(a + 3 * i) - lum(r + 3 * i)) / mean : 0; /* 0.25 red, 0.5 yellow */
                double rr = fmin(e / 0.25, 1), gg = fmin(fmax((e - 0.25) / 0.25, 0), 1);
                px[3 * i + c] = (uint8_t)lrint(255 * (c == 0 ? rr : c == 1 ? gg : 0));
            }
        snprintf(path, sizeof path, "%s_%s.png", prefix, k == 0 ? "a" : k == 1 ? "r" : "map");
        ok = wrt_image_write_rgb8(path, px, w, h) == WRT_OK;
    }
    free(px);
    return ok;
}

int main(int argc, char **argv) {
    const char *pa = NULL, *pr = NULL, *ps = NULL, *png = NULL;
    double ev = 0;
    box boxes[16];
    int nb = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--se") && i + 1 < argc) ps = argv[++i];
        else if (!strcmp(argv[i], "--png") && i + 1 < argc) png = argv[++i];
        else if (!strcmp(argv[i], "--exposure") && i + 1 < argc) ev = atof(argv[++i]);
        else if (!strcmp(argv[i], "--box") && i + 1 < argc && nb < 16) {
            box b;
            if (sscanf(argv[++i], "%d,%d,%d,%d", &b.x, &b.y, &b.w, &b.h) != 4 || b.w < 1 || b.h < 1) {
                fprintf(stderr, "image_err: error: bad --box '%s' (X,Y,W,H)\n", argv[i]);
                return 1;
            }
            boxes[nb++] = b;
        } else if (argv[i][0] == '-') {
            fprintf(stderr, "usage: image_err PLAYER.exr REF.exr [--se REF_stderr.exr] [--box X,Y,W,H]...\n");
            return 1;
        } else if (!pa) pa = argv[i];
        else if (!pr) pr = argv[i];
        else { fprintf(stderr, "image_err: error: more than two images\n"); return 1; }
    }
    if (!pa || !pr) { fprintf(stderr, "usage: image_err PLAYER.exr REF.exr [--se REF_stderr.exr] [--box X,Y,W,H]...\n"); return 1; }
    float *a = NULL, *r = NULL, *se = NULL;
    int w, h, wr, hr, ws, hs;
    if (!read_img(pa, &a, &w, &h) || !read_img(pr, &r, &wr, &hr) || (ps && !read_img(ps, &se, &ws, &hs))) return 2;
    if (w != wr || h != hr || (se && (ws != w || hs != h))) {
        fprintf(stderr, "image_err: error: sizes differ (%d x %d, %d x %d)\n", w, h, wr, hr);
        return 2;
    }
    if (nb == 0) { box b = {0, 0, w, h}; boxes[nb++] = b; }
    for (int k = 0; k < nb; k++) {
        box b = boxes[k];
        if (b.x < 0 || b.y < 0 || b.x + b.w > w || b.y + b.h > h) {
            fprintf(stderr, "image_err: error: box %d,%d,%d,%d outside the %d x %d image\n", b.x, b.y, b.w, b.h, w, h);
            return 1;
        }
        double d2 = 0, r2 = 0, s2 = 0;
        for (int y = b.y; y < b.y + b.h; y++)
            for (int x = b.x; x < b.x + b.w; x++)
                for (int c = 0; c < 3; c++) {
                    size_t i = ((size_t)y * w + x) * 3 + c;
                    double d = (double)a[i] - r[i];
                    d2 += d * d;
                    r2 += (double)r[i] * r[i];
                    if (se) s2 += (double)se[i] * se[i];
                }
        double rm = r2 > 0 ? sqrt(d2 / r2) : 0, fl = r2 > 0 ? sqrt(s2 / r2) : 0;
        double deb = r2 > 0 ? sqrt(fmax(0, d2 - s2) / r2) : 0;
        printf("box %d,%d,%d,%d: rmse %.2f%% floor %.2f%% debiased %.2f%%\n", b.x, b.y, b.w, b.h, 100 * rm, 100 * fl,
               100 * deb);
    }
    if (png && !write_pngs(png, a, r, w, h, ev)) {
        fprintf(stderr, "image_err: error: cannot write %s_*.png: %s\n", png, wrt_last_error());
        return 3;
    }
    free(a); free(r); free(se);
    return 0;
}
