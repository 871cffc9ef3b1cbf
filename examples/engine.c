/* engine.c: what an engine does with libwrt, from the installed header and library
 * alone (tests/install.sh builds it outside the tree with pkg-config). It opens a bake,
 * lays out one lightmap atlas for all quads (wrt_runtime_atlas_layout), relights with
 * the file's first light, writes the atlas as a PFM (little-endian RGB floats), prints
 * the quad-to-source map an engine needs to put each quad's block on its own meshes
 * (glTF node, mesh, primitive, triangles, twin, the corners' TEXCOORD_0 and the block's
 * place in the atlas), and checks that the atlases of two lights add up to the atlas of
 * the pair: within 1e-5 of the peak for the cell-average textures (haar_blocks), and as
 * measured for the smooth display, whose limiter depends on the data (it is printed,
 * not required).
 *
 * Usage: engine FILE.gto ATLAS.pfm
 * Output, one line per quad, then two "superposition" lines:
 *   quad Q node N mesh M prim P kind pair|triangle part K tris T0 T1 twin W of F
 *        rect X Y RES uv u0 v0 u1 v1 u2 v2 u3 v3 (or uv none) corners x0 y0 z0 ... z3
 * Exit status 0 when everything worked and the cell averages superpose. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <wrt.h>

typedef struct atlas {
    int w, h;
    float *rgb;
    wrt_atlas_rect *rects;
} atlas;

/* Relights `rt` with lights[0..n) and fills the atlas. */
static int relight_into(wrt_runtime *rt, const wrt_runtime_light *lights, int n, atlas *a, float *out) {
    wrt_error err;
    if (wrt_runtime_set_lights(rt, lights, n, &err) || wrt_runtime_update(rt, NULL, &err) ||
        wrt_runtime_atlas_fill(rt, a->rects, a->w, a->h, out, (size_t)a->w * a->h * 3, &err)) {
        fprintf(stderr, "engine: %s\n", err.message);
        return -1;
    }
    return 0;
}

/* Largest |ab - (a + b)| and largest |ab| over the atlas. */
static void deviation(const float *a, const float *b, const float *ab, size_t n, double *dev, double *peak) {
    *dev = *peak = 0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)ab[i] - ((double)a[i] + (double)b[i]));
        if (d > *dev) *dev = d;
        if (fabs(ab[i]) > *peak) *peak = fabs(ab[i]);
    }
}

/* PFM: "PF", width height, -1 (little-endian), then rows bottom to top. */
static int write_pfm(const char *path, const atlas *a, const float *rgb) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    fprintf(f, "PF\n%d %d\n-1.0\n", a->w, a->h);
    for (int y = a->h - 1; y >= 0; y--) fwrite(rgb + (size_t)y * a->w * 3, sizeof(float), (size_t)a->w * 3, f);
    int bad = ferror(f);
    return fclose(f) == 0 && !bad ? 0 : -1;
}

/* Two lights and their pair on one runtime, each in an atlas of that runtime's layout
 * (the smooth and the cell textures may differ in size): the largest deviation, the
 * peak and their ratio. */
static int superpose(wrt_runtime *rt, const wrt_runtime_light two[2], double *rel, double *dev, double *peak) {
    wrt_error err;
    int nq = wrt_runtime_quad_count(rt), st = -1;
    atlas a = {0, 0, NULL, calloc((size_t)nq + 1, sizeof(wrt_atlas_rect))};
    float *buf[3] = {NULL, NULL, NULL};
    if (!a.rects || wrt_runtime_atlas_layout(rt, 0, a.rects, &a.w, &a.h, &err)) goto out;
    for (int i = 0; i < 3; i++)
        if (!(buf[i] = malloc((size_t)a.w * a.h * 3 * sizeof(float)))) goto out;
    if (relight_into(rt, &two[0], 1, &a, buf[0]) || relight_into(rt, &two[1], 1, &a, buf[1]) ||
        relight_into(rt, two, 2, &a, buf[2]))
        goto out;
    deviation(buf[0], buf[1], buf[2], (size_t)a.w * a.h * 3, dev, peak);
    *rel = *peak > 0 ? *dev / *peak : 0;
    st = 0;
out:
    for (int i = 0; i < 3; i++) free(buf[i]);
    free(a.rects);
    return st;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: engine FILE.gto ATLAS.pfm\n");
        return 2;
    }
    wrt_error err;
    wrt_runtime *rt = NULL, *cells = NULL;
    wrt_runtime_options cell_opt = {.haar_blocks = 1};
    if (wrt_runtime_open_file(argv[1], NULL, &rt, &err) || wrt_runtime_open_file(argv[1], &cell_opt, &cells, &err)) {
        fprintf(stderr, "engine: %s\n", err.message);
        wrt_runtime_close(rt);
        return 1;
    }
    int nq = wrt_runtime_quad_count(rt), status = 1;
    atlas a = {0, 0, NULL, calloc((size_t)nq + 1, sizeof(wrt_atlas_rect))};
    float *rgb = NULL;
    if (!a.rects || wrt_runtime_atlas_layout(rt, 0, a.rects, &a.w, &a.h, &err)) {
        fprintf(stderr, "engine: %s\n", a.rects ? err.message : "out of memory");
        goto done;
    }
    if (!(rgb = malloc((size_t)a.w * a.h * 3 * sizeof(float)))) goto done;

    /* The file's first light (or one over the middle of the scene), and a second one
     * moved by a third of the scene's size, at half the intensity. */
    double lo[3], hi[3];
    wrt_runtime_get_bounds(rt, lo, hi, NULL);
    wrt_runtime_light two[2] = {{0}};
    if (wrt_runtime_light_count(rt) > 0) {
        wrt_runtime_get_light(rt, 0, &two[0], NULL);
    } else {
        for (int k = 0; k < 3; k++) two[0].position[k] = 0.5 * (lo[k] + hi[k]);
        two[0].intensity = 10;
    }
    two[1] = two[0];
    two[1].position[0] += (hi[0] - lo[0]) / 3;
    two[1].intensity *= 0.5f;
    if (relight_into(rt, two, 1, &a, rgb) || write_pfm(argv[2], &a, rgb)) {
        fprintf(stderr, "engine: could not relight or write %s\n", argv[2]);
        goto done;
    }

    /* The map back to the glTF scene, and each quad's block in the atlas. */
    for (int q = 0; q < nq; q++) {
        wrt_runtime_quad s;
        if (wrt_runtime_get_quad(rt, q, &s, &err)) {
            fprintf(stderr, "engine: %s\n", err.message);
            goto done;
        }
        printf("quad %d node %d mesh %d prim %d kind %s part %d tris %d %d twin %d of %d rect %d %d %d uv", q, s.node,
               s.mesh, s.primitive, s.kind == WRT_QUAD_KIND_PAIR ? "pair" : s.kind == WRT_QUAD_KIND_TRIANGLE ? "triangle" : "unknown",
               s.part, s.triangles[0], s.triangles[1], s.twin, s.twin_of, a.rects[q].x, a.rects[q].y, a.rects[q].res);
        if (s.has_uv)
            for (int k = 0; k < 4; k++) printf(" %.9g %.9g", s.uv[k][0], s.uv[k][1]);
        else
            printf(" none");
        printf(" corners");
        for (int k = 0; k < 4; k++) printf(" %.17g %.17g %.17g", s.corners[k][0], s.corners[k][1], s.corners[k][2]);
        printf("\n");
    }

    /* Superposition: the cell averages must add up; the smooth display is measured. */
    double rel_s, dev_s, peak_s, rel_c, dev_c, peak_c;
    if (superpose(rt, two, &rel_s, &dev_s, &peak_s) || superpose(cells, two, &rel_c, &dev_c, &peak_c)) {
        fprintf(stderr, "engine: superposition run failed\n");
        goto done;
    }
    printf("superposition smooth: max |pair - (a + b)| %.6g, peak %.6g, relative %.3g (measured; not linear)\n", dev_s,
           peak_s, rel_s);
    printf("superposition cells: max |pair - (a + b)| %.6g, peak %.6g, relative %.3g (%s 1e-5)\n", dev_c, peak_c, rel_c,
           rel_c <= 1e-5 ? "within" : "NOT within");
    printf("atlas: %d x %d texels, %d quads, written to %s\n", a.w, a.h, nq, argv[2]);
    status = rel_c <= 1e-5 && peak_c > 0 ? 0 : 1;
done:
    free(rgb);
    free(a.rects);
    wrt_runtime_close(cells);
    wrt_runtime_close(rt);
    return status;
}
