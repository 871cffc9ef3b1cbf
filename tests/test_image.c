/* test_image.c: tests of formats/image.h (EXR keeps float32 radiance exactly, PNG keeps
 * 8-bit values, failures are statuses with messages, never crashes), and the small
 * image checker the shell tests use (tests/play.sh), which reads back what wrt-play
 * wrote through the same module:
 *   test_image --stats IMG                     prints "mean R G B min MAX lit FRACTION"
 *   test_image --nonblank IMG                  exit 0 if more than 1% of the pixels are lit
 *                                              and the picture is not one flat colour
 *   test_image --sum BOTH DIRECT INDIRECT TOL  exit 0 if mean |both - (direct + indirect)|
 *                                              is below TOL x mean(both) (linear EXR)
 *   test_image --error IMG REF                 prints the relative RMSE of IMG against REF
 *                                              (linear EXR; sqrt(mean (a-b)^2) / mean b) and
 *                                              the median and 99th percentile of |a-b| / mean b
 * Without arguments it runs its own cases. */
#include "tests/test.h"
#include "formats/image.h"

#include <stdlib.h>
#include <unistd.h>

static void test_roundtrip(void) {
    char dir[] = "/tmp/wrt_test_image_XXXXXX";
    CHECK(mkdtemp(dir) != NULL, "mkdtemp");
    char exr[256], png[256], bad[256];
    snprintf(exr, sizeof exr, "%s/a.exr", dir);
    snprintf(png, sizeof png, "%s/a.png", dir);
    snprintf(bad, sizeof bad, "%s/nodir/a.exr", dir);
    float pix[6 * 4 * 3];
    uint8_t pix8[6 * 4 * 3];
    for (int i = 0; i < 6 * 4 * 3; i++) { pix[i] = (float)i * 0.37f + 1e-3f; pix8[i] = (uint8_t)(i * 3); }
    CHECK(wrt_image_write_exr(exr, pix, 6, 4) == WRT_OK, "%s", wrt_last_error());
    CHECK(wrt_image_write_rgb8(png, pix8, 6, 4) == WRT_OK, "%s", wrt_last_error());
    float *back = NULL;
    int w = 0, h = 0;
    CHECK(wrt_image_read(exr, &back, &w, &h) == WRT_OK && w == 6 && h == 4, "%s", wrt_last_error());
    int same = back != NULL;
    for (int i = 0; back && i < 6 * 4 * 3; i++) same &= back[i] == pix[i];
    CHECK(same, "EXR keeps float32 exactly, top row first");
    free(back);
    CHECK(wrt_image_read(png, &back, &w, &h) == WRT_OK && w == 6 && h == 4, "%s", wrt_last_error());
    same = back != NULL;
    for (int i = 0; back && i < 6 * 4 * 3; i++) same &= fabsf(back[i] * 255 - pix8[i]) < 1e-3f;
    CHECK(same, "PNG keeps 8-bit values");
    free(back);
    CHECK(wrt_image_write_exr(bad, pix, 6, 4) == WRT_ERR_IO, "unwritable path fails cleanly");
    CHECK(wrt_image_read(bad, &back, &w, &h) != WRT_OK && back == NULL, "missing file fails cleanly");
    CHECK(wrt_image_is_exr("x/a.EXR") && !wrt_image_is_exr("a.exr.png") && !wrt_image_is_exr("a"), "is_exr");
    unlink(exr);
    unlink(png);
    rmdir(dir);
}

static int load(const char *path, float **px, int *w, int *h) {
    if (wrt_image_read(path, px, w, h) != WRT_OK) {
        fprintf(stderr, "test_image: %s\n", wrt_last_error());
        return 0;
    }
    return 1;
}

static int stats(const char *path, int verbose) {
    float *px;
    int w, h;
    if (!load(path, &px, &w, &h)) return 2;
    size_t n = (size_t)w * h;
    double mean[3] = {0, 0, 0}, lo = INFINITY, hi = -INFINITY;
    size_t lit = 0;
    for (size_t i = 0; i < n; i++) {
        double m = 0;
        for (int k = 0; k < 3; k++) {
            double v = px[i * 3 + k];
            mean[k] += v;
            if (v < lo) lo = v;
            if (v > hi) hi = v;
            if (v > m) m = v;
        }
        lit += m > 1.0 / 255;
    }
    for (int k = 0; k < 3; k++) mean[k] /= (double)n;
    double frac = (double)lit / (double)n;
    if (verbose) printf("%s: %dx%d mean %.6g %.6g %.6g min %.6g max %.6g lit %.4f\n", path, w, h,
                        mean[0], mean[1], mean[2], lo, hi, frac);
    free(px);
    return frac > 0.01 && hi > lo ? 0 : 1;
}

static int sum_check(const char *both, const char *dir, const char *ind, double tol) {
    float *b, *d, *i;
    int w[3], h[3];
    if (!load(both, &b, &w[0], &h[0])) return 2;
    if (!load(dir, &d, &w[1], &h[1])) return 2;
    if (!load(ind, &i, &w[2], &h[2])) return 2;
    if (w[0] != w[1] || w[0] != w[2] || h[0] != h[1] || h[0] != h[2]) {
        fprintf(stderr, "test_image: sizes differ\n");
        return 1;
    }
    size_t n = (size_t)w[0] * h[0] * 3;
    double diff = 0, mb = 0, md = 0, mi = 0;
    for (size_t k = 0; k < n; k++) {
        diff += fabs((double)b[k] - ((double)d[k] + (double)i[k]));
        mb += b[k];
        md += d[k];
        mi += i[k];
    }
    double rel = mb > 0 ? diff / mb : INFINITY;
    printf("mean both %.6g direct %.6g indirect %.6g; mean |both - (direct + indirect)| / mean both = %.3g\n",
           mb / n, md / n, mi / n, rel);
    free(b);
    free(d);
    free(i);
    return rel <= tol && md > 0 && mi > 0 ? 0 : 1;
}

static int cmp_d(const void *x, const void *y) {
    double a = *(const double *)x, b = *(const double *)y;
    return a < b ? -1 : a > b;
}

static int error_of(const char *img, const char *ref) {
    float *a, *b;
    int w[2], h[2];
    if (!load(img, &a, &w[0], &h[0])) return 2;
    if (!load(ref, &b, &w[1], &h[1])) return 2;
    if (w[0] != w[1] || h[0] != h[1]) {
        fprintf(stderr, "test_image: sizes differ\n");
        return 1;
    }
    size_t n = (size_t)w[0] * h[0];
    double *e = malloc(n * sizeof *e), se = 0, mb = 0;
    for (size_t i = 0; i < n * 3; i++) mb += b[i];
    mb /= (double)(n * 3);
    for (size_t p = 0; p < n; p++) {
        double d = 0;
        for (int k = 0; k < 3; k++) {
            double x = (double)a[p * 3 + k] - (double)b[p * 3 + k];
            se += x * x;
            d += fabs(x) / 3;
        }
        e[p] = d / mb;
    }
    qsort(e, n, sizeof *e, cmp_d);
    printf("rmse %.5f median %.5f p99 %.5f (relative to the reference's mean %.5g)\n", sqrt(se / (double)(n * 3)) / mb,
           e[n / 2], e[(size_t)(0.99 * (double)(n - 1))], mb);
    free(e);
    free(a);
    free(b);
    return 0;
}

int main(int argc, char **argv) {
    if (argc == 4 && !strcmp(argv[1], "--error")) return error_of(argv[2], argv[3]);
    if (argc == 3 && !strcmp(argv[1], "--stats")) return stats(argv[2], 1) == 2 ? 2 : 0;
    if (argc == 3 && !strcmp(argv[1], "--nonblank")) return stats(argv[2], 1);
    if (argc == 6 && !strcmp(argv[1], "--sum")) return sum_check(argv[2], argv[3], argv[4], atof(argv[5]));
    TEST_RUN(test_roundtrip);
    TEST_END();
}
