/* tests/runtime_budget.c FILE.gto [FILE.gto ...]: the time budget and skip_below of the
 * public API (wrt_runtime_set_budget, wrt_runtime_get_update_stats; API 5), through the
 * header and libwrt.a alone. On each file (tests/runtime.sh: a 2 x 2 maze, a glossy floor
 * with its final gather, the eye set):
 *  - a budgeted runtime (a budget of 1e-6 ms: every update does exactly its first unit)
 *    against an unbudgeted one on the same lights: the budgeted updates report pending
 *    until, after k > 1 calls, every quad's texture equals the unbudgeted one's bit for
 *    bit; the same from a light moved after that, and from a light moved again while work
 *    was still pending (the textures of the last lights, not a mixture);
 *  - a light moved before each of 60 budgeted updates: the multiply, the synthesis and
 *    the smoothing still run (no stage starved behind the projection);
 *  - its counters: one multiply per light change, as many quads synthesized as without a
 *    budget (no quad done twice) when nothing moves in between;
 *  - skip_below 0.05: a light 1% brighter costs no multiply, no texture and no smoothing
 *    (the counters do not move, *changed is 0, skipped is 1) and the textures stay; one
 *    30% brighter is applied and equals the unbudgeted runtime's bit for bit;
 *  - bad values refused with their value named: a negative, NaN or 1e10 budget, a
 *    skip_below of 1 or -0.1; the settings are then unchanged.
 * Prints "N passed, N failed". */
#include <wrt.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int passed, failed;
#define CHECK(c, ...) do { if (c) passed++; else { failed++; fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__); \
    fprintf(stderr, __VA_ARGS__); fputc('\n', stderr); } } while (0)

static wrt_runtime *open_rt(const char *path) {
    wrt_runtime_options o;
    memset(&o, 0, sizeof o);
    o.size = sizeof o;
    wrt_runtime_defaults(&o);
    o.threads = 1;
    wrt_runtime *rt = NULL;
    wrt_error err;
    if (wrt_runtime_open_file(path, &o, &rt, &err) != WRT_OK) {
        fprintf(stderr, "FAIL: open %s: %s\n", path, err.message);
        failed++;
        return NULL;
    }
    return rt;
}

/* 1 if every quad's texture of a and b is the same bytes. */
static int same_textures(const wrt_runtime *a, const wrt_runtime *b, int *first_diff) {
    int nq = wrt_runtime_quad_count(a);
    for (int q = 0; q < nq; q++) {
        int ra = 0, rb = 0;
        const float *ta = wrt_runtime_quad_texture(a, q, &ra), *tb = wrt_runtime_quad_texture(b, q, &rb);
        if (ra != rb || (ra && memcmp(ta, tb, (size_t)ra * ra * 3 * sizeof(float)) != 0)) { *first_diff = q; return 0; }
    }
    return 1;
}

static void set_both(wrt_runtime *a, wrt_runtime *b, const wrt_runtime_light *l, int n) {
    wrt_error err;
    CHECK(wrt_runtime_set_lights(a, l, n, &err) == WRT_OK, "set_lights: %s", err.message);
    CHECK(wrt_runtime_set_lights(b, l, n, &err) == WRT_OK, "set_lights: %s", err.message);
}

/* Updates the budgeted b until nothing is pending (at most 100000 calls): the calls made. */
static int converge(wrt_runtime *b, const char *what) {
    wrt_runtime_update_stats st;
    wrt_error err;
    int k = 0;
    do {
        CHECK(wrt_runtime_update(b, NULL, &err) == WRT_OK, "%s: update: %s", what, err.message);
        wrt_runtime_get_update_stats(b, &st, NULL);
        k++;
    } while (st.pending && k < 100000);
    CHECK(!st.pending, "%s: still pending after %d updates", what, k);
    return k;
}

static void light_moved(wrt_runtime_light *l, double s) {
    if (l->kind == WRT_LIGHT_KIND_DIRECTIONAL) { l->direction[0] += 0.1 * s; return; }
    l->position[0] += s; l->position[2] += 0.5 * s;
}

static void test_budget(const char *path) {
    wrt_runtime *a = open_rt(path), *b = open_rt(path);
    if (!a || !b) { wrt_runtime_close(a); wrt_runtime_close(b); return; }
    wrt_error err;
    double lo[3], hi[3], eye[3];
    wrt_runtime_get_bounds(a, lo, hi, NULL);
    for (int c = 0; c < 3; c++) eye[c] = 0.5 * (lo[c] + hi[c]) + 0.3 * (hi[c] - lo[c]);
    wrt_runtime_set_eye(a, eye, NULL);
    wrt_runtime_set_eye(b, eye, NULL);
    int nl = wrt_runtime_light_count(a);
    wrt_runtime_light l[8];
    for (int i = 0; i < nl && i < 8; i++) wrt_runtime_get_light(a, i, &l[i], NULL);
    if (nl > 8) nl = 8;
    double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[2] - lo[2]) * (hi[2] - lo[2]));
    CHECK(wrt_runtime_set_budget(b, 1e-6, 0, &err) == WRT_OK, "set_budget: %s", err.message);
    wrt_runtime_update_stats sa, sb0, sb;
    for (int step = 0; step < 3; step++) {
        if (step == 2) { /* moved while work is pending: b must end on the last lights */
            light_moved(&l[0], 0.02 * diag);
            CHECK(wrt_runtime_set_lights(b, l, nl, &err) == WRT_OK, "%s", err.message);
            for (int k = 0; k < 3; k++) wrt_runtime_update(b, NULL, NULL);
            wrt_runtime_get_update_stats(b, &sb, NULL);
            CHECK(sb.pending, "%s: pending after 3 budgeted updates of a moved light", path);
        }
        if (step) light_moved(&l[0], 0.05 * diag);
        set_both(a, b, l, nl);
        wrt_runtime_get_update_stats(b, &sb0, NULL);
        wrt_runtime_update(a, NULL, NULL);
        wrt_runtime_get_update_stats(a, &sa, NULL);
        CHECK(!sa.pending, "%s: an unbudgeted update leaves nothing pending", path);
        long long a_synth0 = sa.quads_synthesized;
        int k = converge(b, path), q = -1;
        wrt_runtime_get_update_stats(b, &sb, NULL);
        CHECK(k > 1, "%s step %d: a budget of 1e-6 ms took %d updates (more than one expected)", path, step, k);
        CHECK(same_textures(a, b, &q), "%s step %d: quad %d's texture differs after %d budgeted updates", path, step,
              q, k);
        CHECK(sb.multiplies - sb0.multiplies == 1, "%s step %d: %lld multiplies for one light change", path, step,
              sb.multiplies - sb0.multiplies);
        if (step < 2) { /* nothing moved in between: no quad synthesized twice */
            static long long a_prev;
            long long da = step ? a_synth0 - a_prev : a_synth0, db = sb.quads_synthesized - sb0.quads_synthesized;
            CHECK(da == db, "%s step %d: %lld quads synthesized budgeted, %lld without", path, step, db, da);
            a_prev = a_synth0;
        }
        printf("%s step %d: converged bit for bit in %d budgeted updates (%lld quads, %lld groups)\n", path, step, k,
               sb.quads_synthesized - sb0.quads_synthesized, sb.groups_smoothed - sb0.groups_smoothed);
    }
    /* a light moved before every budgeted update: the later stages still run (the
     * multiply from the lights' last whole projections), none is starved */
    wrt_runtime_get_update_stats(b, &sb0, NULL);
    for (int k = 0; k < 60; k++) {
        light_moved(&l[0], (k % 2 ? -0.01 : 0.01) * diag);
        wrt_runtime_set_lights(b, l, nl, NULL);
        wrt_runtime_update(b, NULL, NULL);
    }
    wrt_runtime_get_update_stats(b, &sb, NULL);
    CHECK(sb.multiplies - sb0.multiplies >= 3 && sb.quads_synthesized > sb0.quads_synthesized &&
          sb.groups_smoothed > sb0.groups_smoothed,
          "%s: a light moving every update starved the budgeted stages: %lld multiplies, %lld quads, %lld groups in "
          "60 updates", path, sb.multiplies - sb0.multiplies, sb.quads_synthesized - sb0.quads_synthesized,
          sb.groups_smoothed - sb0.groups_smoothed);
    printf("%s: light moving every update, budget 1e-6 ms: %lld multiplies, %lld quads, %lld groups in 60 updates\n",
           path, sb.multiplies - sb0.multiplies, sb.quads_synthesized - sb0.quads_synthesized,
           sb.groups_smoothed - sb0.groups_smoothed);
    wrt_runtime_close(a);
    wrt_runtime_close(b);
}

static void test_skip(const char *path) {
    wrt_runtime *a = open_rt(path), *b = open_rt(path);
    if (!a || !b) { wrt_runtime_close(a); wrt_runtime_close(b); return; }
    wrt_error err;
    int nl = wrt_runtime_light_count(a);
    wrt_runtime_light l[8];
    if (nl > 8) nl = 8;
    for (int i = 0; i < nl; i++) wrt_runtime_get_light(a, i, &l[i], NULL);
    CHECK(wrt_runtime_set_budget(b, 0, 0.05, &err) == WRT_OK, "set_budget: %s", err.message);
    set_both(a, b, l, nl);
    wrt_runtime_update(a, NULL, NULL);
    wrt_runtime_update(b, NULL, NULL);
    int q = -1, changed = -1;
    CHECK(same_textures(a, b, &q), "%s: first update differs at quad %d", path, q);
    int nq = wrt_runtime_quad_count(b);
    float *keep = NULL;
    size_t total = 0;
    for (int i = 0; i < nq; i++) { int res; wrt_runtime_quad_texture(b, i, &res); total += (size_t)res * res * 3; }
    keep = malloc((total + 1) * sizeof *keep);
    size_t off = 0;
    for (int i = 0; i < nq; i++) {
        int res;
        const float *t = wrt_runtime_quad_texture(b, i, &res);
        memcpy(keep + off, t, (size_t)res * res * 3 * sizeof *keep);
        off += (size_t)res * res * 3;
    }
    wrt_runtime_update_stats s0, s1;
    wrt_runtime_get_update_stats(b, &s0, NULL);
    l[0].intensity *= 1.01f; /* every E value 1% larger: a relative change of 0.01 */
    set_both(a, b, l, nl);
    CHECK(wrt_runtime_update(b, &changed, &err) == WRT_OK, "update: %s", err.message);
    wrt_runtime_get_update_stats(b, &s1, NULL);
    CHECK(s1.skipped == 1 && s1.skips == s0.skips + 1, "%s: a 1%% change not skipped (%d)", path, s1.skipped);
    CHECK(changed == 0, "%s: a skipped change reported %d quads changed", path, changed);
    CHECK(s1.multiplies == s0.multiplies && s1.quads_synthesized == s0.quads_synthesized &&
          s1.groups_smoothed == s0.groups_smoothed && s1.gathers == s0.gathers,
          "%s: a skipped change did work: multiplies %lld -> %lld, quads %lld -> %lld, groups %lld -> %lld", path,
          s0.multiplies, s1.multiplies, s0.quads_synthesized, s1.quads_synthesized, s0.groups_smoothed,
          s1.groups_smoothed);
    off = 0;
    int kept = 1;
    for (int i = 0; i < nq; i++) {
        int res;
        const float *t = wrt_runtime_quad_texture(b, i, &res);
        kept &= memcmp(keep + off, t, (size_t)res * res * 3 * sizeof *keep) == 0;
        off += (size_t)res * res * 3;
    }
    CHECK(kept, "%s: a skipped change moved a texture", path);
    l[0].intensity *= 1.3f;
    set_both(a, b, l, nl);
    wrt_runtime_update(a, NULL, NULL);
    wrt_runtime_update(b, &changed, NULL);
    wrt_runtime_get_update_stats(b, &s1, NULL);
    CHECK(s1.skipped == 0 && s1.multiplies == s0.multiplies + 1 && changed > 0,
          "%s: a 31%% change not applied (skipped %d, %lld multiplies, %d changed)", path, s1.skipped,
          s1.multiplies - s0.multiplies, changed);
    CHECK(same_textures(a, b, &q), "%s: the applied change differs from the unskipped runtime at quad %d", path, q);
    printf("%s: 1%% change skipped (no multiply, no texture), 31%% applied bit for bit\n", path);
    free(keep);
    wrt_runtime_close(a);
    wrt_runtime_close(b);
}

static void test_refused(const char *path) {
    wrt_runtime *b = open_rt(path);
    if (!b) return;
    wrt_error err;
    static const struct { double budget, skip; const char *named; } bad[] = {
        {-1, 0, "budget_ms -1"}, {NAN, 0, "budget_ms nan"}, {1e10, 0, "budget_ms 1e+10"},
        {0, 1, "skip_below 1"}, {0, -0.1, "skip_below -0.1"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        wrt_status s = wrt_runtime_set_budget(b, bad[i].budget, bad[i].skip, &err);
        CHECK(s == WRT_ERR_INVALID_ARG && strstr(err.message, bad[i].named), "set_budget(%g, %g): %d '%s' (wanted '%s')",
              bad[i].budget, bad[i].skip, (int)s, err.message, bad[i].named);
    }
    CHECK(wrt_runtime_set_budget(NULL, 1, 0, &err) == WRT_ERR_INVALID_ARG, "NULL handle");
    CHECK(wrt_runtime_get_update_stats(b, NULL, &err) == WRT_ERR_INVALID_ARG, "NULL out");
    wrt_runtime_update_stats st;
    wrt_runtime_update(b, NULL, NULL);
    wrt_runtime_get_update_stats(b, &st, NULL);
    CHECK(!st.pending && st.updates == 1, "refused settings left a budget: pending %d, updates %lld", st.pending,
          st.updates);
    wrt_runtime_close(b);
}

int main(int argc, char **argv) {
    if (argc < 2) { fprintf(stderr, "usage: runtime_budget FILE.gto [FILE.gto ...]\n"); return 2; }
    CHECK(wrt_api_version() >= 5 && WRT_API_VERSION >= 5, "API version %d (header %d)", wrt_api_version(),
          WRT_API_VERSION);
    for (int i = 1; i < argc; i++) {
        test_budget(argv[i]);
        test_skip(argv[i]);
    }
    test_refused(argv[1]);
    printf("runtime_budget: %d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
