/* test_gto_kcode.c: the compact first-bounce operator K of .gto version 2.0 (critical
 * section kcode, 260; formats/gto_kcode.c, GTO_FORMAT.md "The compact first-bounce
 * operator"). A synthetic K over a glossy quad's 24 outgoing functions and 257 receiver
 * functions of two other quads (columns of 0 to 120 entries, row steps above 255, values
 * from 1e-7 to 1 of both signs) is written compact and read back: the rows exactly, every
 * value within the documented half step (under 1/8191 of the larger of itself and an
 * eighth of its block's largest; the blocks cut by the documented rule counted here), an
 * exactly representable value exactly, the section of the documented size; the same contents give the same bytes; with k_float the file
 * keeps sections krows and kvals. Damaged and forged files (each check of the section
 * behind made-right checksums) are refused naming what is wrong. The layout is read
 * from GTO_FORMAT.md's description, independently of gto_layout.h.
 * `test_gto_kcode --seed FILE` writes the fuzz seed tests/data/gto/v2.0_kcode_small.gto. */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <stdlib.h>
#include <unistd.h>

#include "tests/test.h"
#include "tests/gto_bytes.h"
#include "formats/gto.h"
#include "formats/scene.h"
#include "common/basis.h"

#define NF_MAX 400
#define NK 24
#define KNNZ_MAX 4000
static wrt_quad quads[3];
static wrt_material mats[2];
static wrt_scene scene;
static uint64_t fkeys[NF_MAX], col_start[NF_MAX + 1], kkeys[NK], kcol_start[NK + 1];
static uint32_t nfuncs, krows[KNNZ_MAX];
static float kvals[KNNZ_MAX];
static wrt_gto_contents contents;
static char tmpdir[256];

static uint64_t lcg_state = 7;
static double lcg(void) {
    lcg_state = lcg_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(lcg_state >> 11) / 9007199254740992.0;
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static void set_quad(wrt_quad *q, double z, int mat) {
    memset(q, 0, sizeof *q);
    q->p[0] = v3(0, 0, z); q->p[1] = v3(1, 0, z); q->p[2] = v3(1, 1, z); q->p[3] = v3(0, 1, z);
    q->t = v3(1, 0, 0); q->n = v3(0, 0, z > 0 ? -1 : 1); q->b = v3_cross(q->n, q->t);
    q->area = 1; q->parallelogram = 1; q->name = -1; q->material = mat;
}

/* Quad 0 glossy (its scaling function and 3 wavelets, each with the angular root and its
 * 3 wavelets: 16 functions; K's 24 columns are outgoing functions at angular level 1);
 * quads 1 and 2 Lambertian: quad 1 every spatial Haar function to level 3 (256), quad 2 its
 * root. The operator: no entries. K's column j: 0 to 120 entries on quads 1 and 2. */
static void build(void) {
    memset(&scene, 0, sizeof scene);
    set_quad(&quads[0], 0, 1); set_quad(&quads[1], 1, 0); set_quad(&quads[2], 2, 0);
    memset(mats, 0, sizeof mats);
    snprintf(mats[0].name, 64, "white");
    mats[0].base_color[0] = mats[0].base_color[1] = mats[0].base_color[2] = 0.5f;
    mats[0].roughness = 1; mats[0].lambertian = 1;
    snprintf(mats[1].name, 64, "gloss");
    mats[1].base_color[0] = mats[1].base_color[1] = mats[1].base_color[2] = 0.9f;
    mats[1].roughness = 0.2f; mats[1].metallic = 1;
    scene.quads = quads; scene.nquads = 3;
    scene.materials = mats; scene.nmaterials = 2;
    wrt_node r = wrt_node_root();
    uint32_t nk = 0;
    nfuncs = 0;
    for (int st = 0; st <= 3; st++) { /* quad 0: spatial root (type 0) and its 3 wavelets */
        for (int at = 0; at <= 3; at++) /* angular root and its 3 wavelets */
            fkeys[nfuncs++] = wrt_fkey_make(0, r, st, r, at);
        for (int a = 0; a < 2 && nk < NK; a++) /* K's columns: outgoing, 6 per spatial function */
            for (int at = 0; at <= 2; at++) kkeys[nk++] = wrt_fkey_make(0, r, st, wrt_node_child(r, a, 0), at + 1);
    }
    fkeys[nfuncs++] = wrt_fkey_make(1, r, 0, r, 0);
    for (int l = 0; l <= 3; l++)
        for (int y = 0; y < (1 << l); y++)
            for (int x = 0; x < (1 << l); x++)
                for (int t = 1; t <= 3; t++) {
                    wrt_node n = {(uint8_t)l, (uint16_t)x, (uint16_t)y};
                    fkeys[nfuncs++] = wrt_fkey_make(1, n, t, r, 0);
                }
    fkeys[nfuncs++] = wrt_fkey_make(2, r, 0, r, 0);
    qsort(fkeys, nfuncs, sizeof *fkeys, cmp_u64);
    qsort(kkeys, nk, sizeof *kkeys, cmp_u64);
    uint32_t first = 16; /* quad 0 holds fkeys 0..15 */
    uint64_t e = 0;
    kcol_start[0] = 0;
    krows[0] = first + 3; kvals[0] = -0.375f; /* -6144 x 2^-14: exact */
    kcol_start[1] = e = 1;
    for (uint32_t j = 1; j < NK; j++) {
        int n = j == 5 ? 0 : (int)(lcg() * 121);
        uint32_t row = first + (uint32_t)(lcg() * 20);
        for (int k = 0; k < n && row < nfuncs && e < KNNZ_MAX; k++) {
            krows[e] = row;
            kvals[e] = (float)(pow(10, -7 * lcg()) * (lcg() - 0.4));
            e++;
            row += 1 + (uint32_t)(lcg() < 0.03 ? 256 : lcg() * 3);
        }
        kcol_start[j + 1] = e;
    }
    for (uint32_t s = 0; s <= nfuncs; s++) col_start[s] = 0;
    memset(&contents, 0, sizeof contents);
    contents.scene = &scene;
    contents.fkeys = fkeys; contents.nfuncs = nfuncs;
    contents.col_start = col_start;
    contents.provenance = "{}";
    contents.no_srcmap = 1;
    contents.compact = 1;
    contents.nkcols = NK;
    contents.kkeys = kkeys; contents.kcol_start = kcol_start; contents.krows = krows; contents.kvals = kvals;
}

/* ---- files ---- */

static char *tpath(const char *name) {
    static char buf[4][512];
    static int k;
    char *p = buf[k++ & 3];
    snprintf(p, 512, "%s/%s", tmpdir, name);
    return p;
}


static uint8_t *written(const char *name, size_t *n) {
    wrt_status st = wrt_gto_write(tpath(name), &contents);
    CHECK(st == WRT_OK, "write: %s", wrt_last_error());
    return st == WRT_OK ? read_all(tpath(name), n) : NULL;
}




static wrt_status open_copy(const uint8_t *b, size_t n, wrt_gto *g) {
    uint8_t *c = malloc(n ? n : 1);
    if (n) memcpy(c, b, n);
    wrt_status st = wrt_gto_open_memory(c, n, g);
    if (st == WRT_OK) wrt_gto_close(g);
    free(c);
    return st;
}

static void expect(wrt_status got, wrt_status want, const char *substr, const char *what) {
    CHECK(got == want, "%s: status %s, expected %s (%s)", what, wrt_status_str(got), wrt_status_str(want),
          wrt_last_error());
    CHECK(strstr(wrt_last_error(), substr) != NULL, "%s: message '%s' lacks '%s'", what, wrt_last_error(), substr);
}

/* Where section kcode's arrays are (GTO_FORMAT.md): header 64 bytes (codec u32, block_max
 * u32, nblocks u64, nnz u64), then bcol (u32, nkcols + 1), blocks (8 bytes), codes (u16),
 * deltas (u8), each from a multiple of 64 of the payload. */
typedef struct kpos { size_t sec, size, bcol, blocks, codes, deltas; uint64_t nblocks, nnz; } kpos;
static size_t al64(size_t x) { return (x + 63) / 64 * 64; }
static kpos locate(const uint8_t *b) {
    kpos o;
    o.sec = (size_t)rd64(b, entry_of(b, 260) + 8);
    o.size = (size_t)rd64(b, entry_of(b, 260) + 16);
    o.nblocks = rd64(b, o.sec + 8);
    o.nnz = rd64(b, o.sec + 16);
    o.bcol = o.sec + 64;
    o.blocks = o.sec + al64(64 + 4 * (size_t)(NK + 1));
    o.codes = o.sec + al64(o.blocks - o.sec + 8 * o.nblocks);
    o.deltas = o.sec + al64(o.codes - o.sec + 2 * o.nnz);
    return o;
}

/* The blocks by the documented rule: from a column's first entry, ending after 64
 * entries or before a row 256 or more past the previous one. */
static uint64_t blocks_by_rule(void) {
    uint64_t nb = 0;
    for (uint32_t j = 0; j < NK; j++)
        for (uint64_t i = kcol_start[j], k = 0; i < kcol_start[j + 1]; i++, k++) {
            if (k == 64 || (i > kcol_start[j] && krows[i] - krows[i - 1] >= 256)) k = 0;
            nb += k == 0;
        }
    return nb;
}

/* ---- round trip ---- */

static void test_roundtrip(void) {
    build();
    size_t n;
    uint8_t *b = written("k.gto", &n);
    if (!b) return;
    wrt_gto g;
    wrt_status st = wrt_gto_open(tpath("k.gto"), &g);
    CHECK(st == WRT_OK, "open: %s", wrt_last_error());
    if (st != WRT_OK) { free(b); return; }
    uint64_t knnz = kcol_start[NK];
    CHECK(g.version == 3 && g.version_minor == 0, "version %u.%u", g.version, g.version_minor);
    CHECK(!g.krows && !g.kvals && g.k_codes && g.knnz == knnz && g.nkcols == NK, "compact K: %llu entries",
          (unsigned long long)g.knnz);
    CHECK(!entry_of(b, 14) && !entry_of(b, 15) && entry_of(b, 12) && entry_of(b, 13) && entry_of(b, 260),
          "sections krows and kvals replaced by kcode (260)");
    uint64_t nb = blocks_by_rule();
    CHECK(g.knblocks == nb, "%llu blocks, the rule cuts %llu", (unsigned long long)g.knblocks, (unsigned long long)nb);
    kpos o = locate(b);
    CHECK(o.size == o.deltas - o.sec + knnz, "section of %zu bytes, the layout says %zu", o.size,
          (size_t)(o.deltas - o.sec + knnz));
    uint32_t *dr = malloc(sizeof *dr * knnz);
    float *dv = malloc(sizeof *dv * knnz);
    wrt_gto_k_entries(&g, dr, dv);
    int rows_ok = 1;
    double worst = 0;
    uint64_t i = 0;
    for (uint32_t j = 0; j < NK; j++)
        for (uint32_t k = g.k_bcol[j]; k < g.k_bcol[j + 1]; k++) {
            const wrt_gto_block *bk = &g.k_blocks[k];
            double bm = 0;
            for (uint64_t m = i; m < i + bk->n; m++) bm = fmax(bm, fabs(kvals[m]));
            for (uint32_t m = 0; m < bk->n; m++, i++) {
                rows_ok &= dr[i] == krows[i];
                worst = fmax(worst, fabs(dv[i] - kvals[i]) / fmax(fabs(kvals[i]), bm / 8));
            }
        }
    CHECK(i == knnz && rows_ok, "every row decoded exactly (%llu entries)", (unsigned long long)i);
    CHECK(worst <= 1.0 / 8191 && worst > 1e-6, "values within half a step, under 1/8191 of max(entry, block / 8): "
          "worst %.3g", worst);
    CHECK(dv[0] == -0.375f, "an exact value decodes exactly: %g", dv[0]);
    printf("compact K: %d columns, %llu entries, %llu blocks, section %zu bytes (%.2f an entry; floats 8)\n", NK,
           (unsigned long long)knnz, (unsigned long long)g.knblocks, o.size, (double)o.size / (double)knnz);
    free(dr); free(dv);
    wrt_gto_close(&g);
    size_t n2;
    uint8_t *b2 = written("k2.gto", &n2);
    CHECK(b2 && n2 == n && memcmp(b, b2, n) == 0, "the same contents give the same bytes");
    free(b2);
    contents.k_float = 1; /* K's floats in a compact file */
    uint8_t *f = written("kf.gto", &n2);
    CHECK(f && entry_of(f, 14) && entry_of(f, 15) && !entry_of(f, 260), "k_float: sections krows and kvals");
    st = wrt_gto_open(tpath("kf.gto"), &g);
    CHECK(st == WRT_OK && g.krows && !g.k_codes, "k_float file reads: %s", wrt_last_error());
    if (st == WRT_OK) wrt_gto_close(&g);
    contents.k_float = 0;
    contents.compact = 0; /* float entries: K's floats, version 1.1 */
    uint8_t *f1 = written("k1.gto", &n2);
    CHECK(f1 && f1[12] == 1 && f1[14] == 1 && entry_of(f1, 14) && !entry_of(f1, 260), "float entries: a 1.1 file");
    contents.compact = 1;
    free(f); free(f1); free(b);
}

/* ---- damage ---- */

static void test_damaged(void) {
    build();
    size_t n;
    uint8_t *b = written("d.gto", &n);
    if (!b) return;
    wrt_gto g;
    kpos o = locate(b);
    uint8_t *c = malloc(n);
    for (size_t cut = 1; cut < n; cut += n / 17 + 1) /* truncated */
        CHECK(open_copy(b, cut, &g) == WRT_ERR_CORRUPT, "truncated at %zu", cut);
    size_t at[4] = {o.sec + 3, o.blocks + 5, o.codes + 7, o.deltas + 1};
    for (int k = 0; k < 4; k++) { /* flipped, checksums as written */
        memcpy(c, b, n);
        c[at[k]] ^= 0x10;
        expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "section kcode: checksum mismatch", "flipped byte");
    }
    free(c);
    free(b);
}

/* One forged change (bytes at `off`), checksums made right: refused with `want`. */
static void forged(const uint8_t *b, size_t n, size_t off, const void *bytes, size_t len, wrt_status want,
                   const char *substr, const char *what) {
    uint8_t *c = malloc(n);
    memcpy(c, b, n);
    memcpy(c + off, bytes, len);
    forge(c);
    wrt_gto g;
    expect(open_copy(c, n, &g), want, substr, what);
    free(c);
}

static void test_forged(void) {
    build();
    size_t n;
    uint8_t *b = written("f.gto", &n);
    if (!b) return;
    wrt_gto g;
    { /* the unchanged file with its checksums remade reads */
        uint8_t *c = malloc(n);
        memcpy(c, b, n);
        forge(c);
        CHECK(open_copy(c, n, &g) == WRT_OK, "forged unchanged: %s", wrt_last_error());
        free(c);
    }
    kpos o = locate(b);
    uint32_t u32 = 1;
    forged(b, n, o.sec, &u32, 4, WRT_ERR_CORRUPT, "unknown encoding 1", "codec 1 (the operator's)");
    u32 = 1;
    forged(b, n, o.sec + 40, &u32, 1, WRT_ERR_CORRUPT, "reserved bytes not zero", "header reserved");
    uint16_t m = 0x2000; /* mantissa -8192 */
    forged(b, n, o.codes + 2 * 3, &m, 2, WRT_ERR_CORRUPT, "mantissa -8192", "mantissa -8192");
    uint8_t z = 0; /* a block's second entry with delta 0 */
    forged(b, n, o.deltas + 2, &z, 1, WRT_ERR_CORRUPT, "row delta 0", "row delta 0");
    z = 5; /* a block's first entry with a delta */
    forged(b, n, o.deltas + 0, &z, 1, WRT_ERR_CORRUPT, "row delta 5 on a block's first entry", "first delta");
    int16_t base = 37;
    forged(b, n, o.blocks + 6, &base, 2, WRT_ERR_CORRUPT, "base exponent 37 outside [-126, 36]", "base");
    z = 0; /* block 0 with no entries */
    forged(b, n, o.blocks + 4, &z, 1, WRT_ERR_CORRUPT, "block 0 (K column 0): 0 entries", "empty block");
    u32 = 3; /* the first block's row on the column's own quad (functions 0..15) */
    forged(b, n, o.blocks + 0, &u32, 4, WRT_ERR_CORRUPT, "the column's own quad", "own quad");
    u32 = nfuncs + 5;
    forged(b, n, o.blocks + 0, &u32, 4, WRT_ERR_CORRUPT, "out of range", "row out of range");
    u32 = 1; /* bcol not from 0 */
    forged(b, n, o.bcol, &u32, 4, WRT_ERR_CORRUPT, "bcol runs from 1", "bcol");
    z = 1;
    forged(b, n, o.codes - 1, &z, 1, WRT_ERR_CORRUPT, "non-zero padding", "padding");
    uint64_t u64 = o.nnz + 1;
    forged(b, n, o.sec + 16, &u64, 8, WRT_ERR_CORRUPT, "do not hold", "entries in the header");
    uint16_t v1 = 1; /* a 1.x file may not hold it */
    forged(b, n, 12, &v1, 2, WRT_ERR_CORRUPT, "section kcode in a version 1.0 file", "kcode in 1.0");
    u32 = 259; /* an unknown critical id (between ctree and opstream): refused naming it */
    forged(b, n, entry_of(b, 260), &u32, 4, WRT_ERR_UNSUPPORTED, "section id 259 is critical", "id 259");
    u32 = 22; /* an id below 256 is skipped: K then lacks its entries */
    forged(b, n, entry_of(b, 260), &u32, 4, WRT_ERR_CORRUPT, "missing section krows", "kcode as id 22");
    /* the writer refuses K it cannot store (checked as the float sections would be) */
    build();
    kvals[4] = NAN;
    expect(wrt_gto_write(tpath("nan.gto"), &contents), WRT_ERR_INVALID_ARG, "kvals[4] is NaN", "NaN in K");
    build();
    krows[1] = 2; /* quad 0's own function */
    expect(wrt_gto_write(tpath("own.gto"), &contents), WRT_ERR_INVALID_ARG, "the column's own quad", "own quad");
    free(b);
}

static void write_seed(const char *path) {
    build();
    wrt_status st = wrt_gto_write(path, &contents);
    printf("%s: %s\n", path, st == WRT_OK ? "written" : wrt_last_error());
}

int main(int argc, char **argv) {
    if (argc > 2 && strcmp(argv[1], "--seed") == 0) { write_seed(argv[2]); return 0; }
    snprintf(tmpdir, sizeof tmpdir, "%s/wrt_test_kcode.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    TEST_RUN(test_roundtrip);
    TEST_RUN(test_damaged);
    TEST_RUN(test_forged);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_END();
}
