/* test_gto.c: the .gto file (formats/gto_*.c). Writes a small synthetic scene and operator,
 * reads it back field by field, and feeds the reader every kind of broken file: foreign,
 * empty, each truncation, each flipped byte, a newer version, a section pointing past
 * the end and bad indices behind fixed-up checksums. The layout constants below are
 * taken from GTO_FORMAT.md, not from gto.c, so the tests also hold the document to the
 * code. Also: atomic writing (a failed write leaves the target alone, no temporary
 * survives a signal) and the speed of the checksum and of opening a large file.
 * `test_gto --regen` rewrites tests/data/gto/v1_small.gto (after a format change). */
#ifndef _GNU_SOURCE
#define _GNU_SOURCE
#endif
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "tests/test.h"
#include "formats/gto.h"
#include "formats/scene.h"
#include "common/basis.h"

/* From GTO_FORMAT.md. */
#define F_HEADER 64
#define F_ENTRY 48
#define F_VERSION_MAJOR 12
#define F_FILE_SIZE 16
#define F_BOM 8
#define F_HEADER_SUM 40
#define F_E_OFFSET 8
#define F_E_SIZE 16
#define F_E_COUNT 24
#define F_E_SUM 32
#define F_NSEC 11
static const char *const sec_names[F_NSEC] = {"quads", "materials", "lights", "camera", "names",
                                              "fkeys", "col_start", "rows", "vals", "stats",
                                              "provenance"};
enum { S_QUADS, S_MATERIALS, S_LIGHTS, S_CAMERA, S_NAMES, S_FKEYS, S_COL_START, S_ROWS, S_VALS,
       S_STATS, S_PROVENANCE };
/* Version 1.1: the first-bounce operator K, ids 12-15 after the 11 above. */
#define F_NSEC_K 15
static const char *const k_sec_names[4] = {"kkeys", "kcol_start", "krows", "kvals"};
enum { S_KKEYS = 11, S_KCOL_START, S_KROWS, S_KVALS };

static const char *golden_path = "tests/data/gto/v1_small.gto";
static const char *golden_k_path = "tests/data/gto/v1.1_k_small.gto";
static const char *golden_s_path = "tests/data/gto/v1.2_srcmap_small.gto";
/* Version 2.0: the compact operator (section 17 for 8 and 9); tests/test_gto_compact.c
 * tests it, this file keeps its golden file. */
static const char *golden_c_path = "tests/data/gto/v2.0_compact_small.gto";
static const char *golden_c3_path = "tests/data/gto/v3.0_compact_small.gto";
/* Version 1.2: the quad-to-source map, id 16, after the 11 (no K here). */
#define S_SRCMAP 11
#define F_NSEC_S 12
#define F_SRC_REC 72
static char tmpdir[256];

/* ---- the synthetic scene and operator ---- */

static wrt_quad quads[3];
static wrt_material mats[2];
static wrt_light lights[2];
static char names[2][64] = {"floor", "wall"};
static wrt_scene scene;
static uint64_t fkeys[8];
static uint32_t nfuncs;
static uint64_t col_start[9];
static uint32_t rows[32];
static float vals[32 * 3];
static uint8_t mat_alevel[2] = {0, 2};
static wrt_gto_contents contents;
/* The first-bounce operator of the synthetic scene: 5 columns on the glossy quads 1 and
 * 2 (material 1), 9 entries; contents_k = contents + K. */
static uint64_t kkeys[5];
static uint64_t kcol_start[6];
static uint32_t krows[16];
static float kvals[16];
static wrt_gto_contents contents_k;
static wrt_gto_contents contents_s; /* contents with the quad-to-source map (1.2) */
static const char *provenance = "{\"scene\": \"synthetic\", \"hash\": \"0123\", \"n\": [1, 2.5e3, -0.5], \"ok\": true}";

static void set_quad(wrt_quad *q, wrt_v3 p0, wrt_v3 p1, wrt_v3 p2, wrt_v3 p3, int mat, int name) {
    memset(q, 0, sizeof *q);
    q->p[0] = p0; q->p[1] = p1; q->p[2] = p2; q->p[3] = p3;
    q->t = v3_norm(v3_sub(p1, p0));
    q->n = v3_norm(v3_cross(v3_sub(p1, p0), v3_sub(p3, p0)));
    q->b = v3_cross(q->n, q->t);
    q->area = v3_len(v3_cross(v3_sub(p1, p0), v3_sub(p3, p0)));
    q->parallelogram = v3_len(v3_sub(v3_add(p1, p3), v3_add(p0, p2))) < 1e-12;
    q->material = mat;
    q->name = name;
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static void build(void) {
    memset(&scene, 0, sizeof scene);
    set_quad(&quads[0], v3(0, 0, 0), v3(1, 0, 0), v3(1, 0, 1), v3(0, 0, 1), 0, 0);
    set_quad(&quads[1], v3(0, 0, 0), v3(0, 1, 0), v3(1, 1, 0), v3(1, 0, 0), 1, 1);
    set_quad(&quads[2], v3(1e6, 2, 3), v3(1e6 + 1, 2, 3), v3(1e6 + 1.5, 3, 3), v3(1e6, 3, 3), 1, -1);
    memset(mats, 0, sizeof mats);
    snprintf(mats[0].name, 64, "white");
    mats[0].base_color[0] = 0.8f; mats[0].base_color[1] = 0.7f; mats[0].base_color[2] = 0.6f;
    mats[0].metallic = 0; mats[0].roughness = 1; mats[0].lambertian = 1;
    snprintf(mats[1].name, 64, "a name of exactly sixty-three characters, long enough to fill!!");
    mats[1].base_color[0] = 0.1f; mats[1].metallic = 0.5f; mats[1].roughness = 0.25f;
    mats[1].emissive[2] = 3.0f;
    memset(lights, 0, sizeof lights);
    lights[0].type = WRT_LIGHT_POINT; snprintf(lights[0].name, 64, "bulb");
    lights[0].pos = v3(0.5, 0.9, 0.5); lights[0].dir = v3(0, -1, 0);
    lights[0].color[0] = 1; lights[0].color[1] = 0.9f; lights[0].color[2] = 0.8f;
    lights[0].intensity = 12.5f; lights[0].range = 0; lights[0].outer_cone = 0.785f;
    lights[1].type = WRT_LIGHT_SPOT; snprintf(lights[1].name, 64, "spot");
    lights[1].pos = v3(-1, 2, 3); lights[1].dir = v3(0, 0, -1);
    lights[1].intensity = 100; lights[1].range = 20; lights[1].inner_cone = 0.2f; lights[1].outer_cone = 0.4f;
    scene.quads = quads; scene.nquads = 3;
    scene.materials = mats; scene.nmaterials = 2;
    scene.lights = lights; scene.nlights = 2;
    scene.names = names; scene.nnames = 2;
    scene.camera.pos = v3(0.5, 0.5, 3); scene.camera.dir = v3(0, 0, -1); scene.camera.up = v3(0, 1, 0);
    scene.camera.yfov = 0.7; scene.camera.aspect = 1.5; scene.camera.znear = 0.01; scene.camera.zfar = 100;

    wrt_node r = wrt_node_root(), c11 = wrt_node_child(r, 1, 1), c01 = wrt_node_child(r, 0, 1);
    wrt_node c2 = wrt_node_child(wrt_node_child(r, 1, 0), 0, 1);
    nfuncs = 0;
    fkeys[nfuncs++] = wrt_fkey_make(0, r, 0, r, 0);
    fkeys[nfuncs++] = wrt_fkey_make(0, r, 1, r, 0);
    fkeys[nfuncs++] = wrt_fkey_make(0, c11, 3, r, 0);
    fkeys[nfuncs++] = wrt_fkey_make(0, c2, 2, r, 0);
    fkeys[nfuncs++] = wrt_fkey_make(1, r, 0, r, 0);
    fkeys[nfuncs++] = wrt_fkey_make(2, r, 0, r, 0);
    fkeys[nfuncs++] = wrt_fkey_make(2, r, 0, c01, 2);
    qsort(fkeys, nfuncs, sizeof *fkeys, cmp_u64);
    /* Columns with 3, 0, 2, 1, 4, 0, 2 entries. */
    static const int per_col[7] = {3, 0, 2, 1, 4, 0, 2};
    uint64_t e = 0;
    for (uint32_t s = 0; s < nfuncs; s++) {
        col_start[s] = e;
        for (int i = 0; i < per_col[s]; i++, e++) {
            rows[e] = (uint32_t)(i * 2 + (s % 2));
            for (int ch = 0; ch < 3; ch++) vals[3 * e + ch] = 0.01f * (float)(e + 1) * (float)(ch + 1) - 0.05f;
        }
    }
    col_start[nfuncs] = e;

    memset(&contents, 0, sizeof contents);
    contents.scene = &scene;
    contents.fkeys = fkeys; contents.nfuncs = nfuncs;
    contents.col_start = col_start; contents.rows = rows; contents.vals = vals;
    contents.op_kind = WRT_GTO_OP_GATHERED;
    contents.material_alevel = mat_alevel;
    wrt_gto_stats *st = &contents.stats;
    st->t_dto = 1.5; st->t_gto = 2.25; st->t_write = 0.125; st->t_total = 4;
    st->links_dto = 11; st->links_gto = 12; st->links_gathered = 13;
    st->entries_dto = 14; st->entries_op = e; st->rays_traced = 1000000007ull; st->rays_skipped = 16;
    st->bounces = 5; st->energy_left = 1e-3;
    contents.provenance = provenance;
    contents.no_srcmap = 1; /* the 1.0 and 1.1 files, byte for byte */

    /* K: functions of quad 1 are fkeys index 4, of quad 2 indices 5 and 6; a column's
     * rows avoid its own quad's. Keys written in ascending order (quad, spatial level,
     * position, type, angular level, position, type). */
    wrt_node a10 = wrt_node_child(r, 1, 0);
    kkeys[0] = wrt_fkey_make(1, r, 0, r, 0);
    kkeys[1] = wrt_fkey_make(1, r, 0, r, 1);
    kkeys[2] = wrt_fkey_make(1, r, 0, a10, 3);
    kkeys[3] = wrt_fkey_make(2, r, 0, r, 0);
    kkeys[4] = wrt_fkey_make(2, c11, 2, r, 2);
    static const uint32_t kr[9] = {0, 2, 5, /* col 1 empty */ 1, 6, 0, 3, 4, 4};
    static const uint64_t ks[6] = {0, 3, 3, 5, 8, 9};
    memcpy(krows, kr, sizeof kr);
    memcpy(kcol_start, ks, sizeof ks);
    for (int i = 0; i < 9; i++) kvals[i] = 0.125f * (float)(i + 1) - 0.5f; /* signed, as Haar entries are */
    contents_k = contents;
    contents_k.nkcols = 5;
    contents_k.kkeys = kkeys; contents_k.kcol_start = kcol_start;
    contents_k.krows = krows; contents_k.kvals = kvals;

    /* The source map: quad 0 paired from triangles 4 and 1 of node 3's mesh 0 primitive
     * 2, with TEXCOORD_0; quad 1 the third part of triangle 5 of node 0's mesh 1, without;
     * quad 2 (whatever its corners) the back twin of quad 1. */
    quads[0].node = 3; quads[0].mesh = 0; quads[0].prim = 2; quads[0].tri[0] = 4; quads[0].tri[1] = 1;
    quads[0].kind = WRT_ELEM_QUAD; quads[0].has_uv = 1;
    static const float uv0[4][2] = {{0, 0}, {0.5f, 0}, {0.5f, 0.25f}, {-1.5f, 1e3f}};
    memcpy(quads[0].uv, uv0, sizeof uv0);
    for (int q = 1; q < 3; q++) {
        quads[q].node = 0; quads[q].mesh = 1; quads[q].prim = 0; quads[q].tri[0] = 5; quads[q].tri[1] = -1;
        quads[q].kind = WRT_ELEM_TRIANGLE; quads[q].part = 2;
    }
    quads[2].twin = 1; quads[2].twin_of = 1;
    contents_s = contents;
    contents_s.no_srcmap = 0;
}

/* ---- file helpers ---- */

static char *tpath(const char *name) {
    static char buf[8][512];
    static int k;
    char *p = buf[k++ & 7];
    snprintf(p, 512, "%s/%s", tmpdir, name);
    return p;
}

static uint8_t *read_all(const char *path, size_t *len) {
    FILE *f = fopen(path, "rb");
    if (!f) { *len = 0; return NULL; }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc(n ? (size_t)n : 1);
    *len = fread(b, 1, (size_t)n, f);
    fclose(f);
    return b;
}

static void write_raw(const char *path, const void *data, size_t n) {
    FILE *f = fopen(path, "wb");
    if (n) fwrite(data, 1, n, f);
    fclose(f);
}

static uint64_t rd64(const uint8_t *b, size_t o) { uint64_t x; memcpy(&x, b + o, 8); return x; }
static void wr64(uint8_t *b, size_t o, uint64_t x) { memcpy(b + o, &x, 8); }
static size_t entry(int s) { return F_HEADER + (size_t)s * F_ENTRY; }
static size_t sec_off(const uint8_t *b, int s) { return (size_t)rd64(b, entry(s) + F_E_OFFSET); }
static size_t sec_size(const uint8_t *b, int s) { return (size_t)rd64(b, entry(s) + F_E_SIZE); }

/* Recomputes a section's checksum and the header checksum, as a forger would. */
static void fix_section_sum(uint8_t *b, int s) {
    wr64(b, entry(s) + F_E_SUM, wrt_gto_checksum(b + sec_off(b, s), sec_size(b, s)));
}
static void fix_header_sum(uint8_t *b) {
    uint32_t ns;
    memcpy(&ns, b + 28, 4); /* nsections */
    size_t hn = F_HEADER + (size_t)ns * F_ENTRY;
    uint8_t h[F_HEADER + 64 * F_ENTRY];
    if (ns > 64) return;
    memcpy(h, b, hn);
    wr64(h, F_HEADER_SUM, 0);
    wr64(b, F_HEADER_SUM, wrt_gto_checksum(h, hn));
}

/* Opens an image from an exactly sized heap copy (so AddressSanitizer sees overreads). */
static wrt_status open_copy(const uint8_t *b, size_t n, wrt_gto *g) {
    uint8_t *c = malloc(n ? n : 1);
    if (n) memcpy(c, b, n);
    wrt_status st = wrt_gto_open_memory(c, n, g);
    free(c);
    return st;
}

static int count_tmp_files(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) if (strstr(e->d_name, ".tmp.")) n++;
    closedir(d);
    return n;
}

static int write_good(const char *path) {
    wrt_status st = wrt_gto_write(path, &contents);
    CHECK(st == WRT_OK, "write %s: %s", path, wrt_last_error());
    return st == WRT_OK;
}

/* ---- the checksum, from its description in GTO_FORMAT.md ---- */

static uint64_t ref_step(uint64_t v, uint64_t w) {
    v ^= w;
    v *= 0x9E3779B97F4A7C15ull;
    return v ^ (v >> 32);
}

static uint64_t ref_checksum(const uint8_t *p, size_t n) {
    uint64_t lane[4];
    for (int i = 0; i < 4; i++) lane[i] = 0xC2B2AE3D27D4EB4Full * (uint64_t)(i + 1);
    size_t padded = (n + 31) / 32 * 32;
    for (size_t o = 0; o < padded; o += 8) {
        uint64_t w = 0;
        for (int k = 0; k < 8; k++)
            if (o + k < n) w |= (uint64_t)p[o + k] << (8 * k);
        lane[(o / 8) % 4] = ref_step(lane[(o / 8) % 4], w);
    }
    uint64_t h = (uint64_t)n ^ 0x165667B19E3779F9ull;
    for (int i = 0; i < 4; i++) h = ref_step(h, lane[i]);
    h ^= h >> 33; h *= 0xC2B2AE3D27D4EB4Full;
    h ^= h >> 29; h *= 0x165667B19E3779F9ull;
    h ^= h >> 32;
    return h;
}

static void test_checksum(void) {
    uint8_t buf[1024];
    uint64_t x = 88172645463325252ull;
    for (size_t i = 0; i < sizeof buf; i++) { x ^= x << 13; x ^= x >> 7; x ^= x << 17; buf[i] = (uint8_t)x; }
    int same = 1;
    for (size_t n = 0; n <= 200; n++) same &= wrt_gto_checksum(buf + 3, n) == ref_checksum(buf + 3, n);
    CHECK(same, "checksum differs from its specification");
    CHECK(wrt_gto_checksum(buf, 1000) == ref_checksum(buf, 1000), "long input");
    /* Every single-bit change of a 1000-byte buffer changes it (guaranteed by the design). */
    uint64_t h0 = wrt_gto_checksum(buf, 1000);
    int missed = 0;
    for (size_t bit = 0; bit < 8000; bit++) {
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
        missed += wrt_gto_checksum(buf, 1000) == h0;
        buf[bit / 8] ^= (uint8_t)(1u << (bit % 8));
    }
    CHECK(missed == 0, "%d single-bit changes not detected", missed);
    /* Zero runs of different lengths differ (the length is hashed). */
    static const uint8_t zeros[64];
    int collide = 0;
    for (int a = 0; a <= 64; a++)
        for (int b = a + 1; b <= 64; b++) collide += wrt_gto_checksum(zeros, a) == wrt_gto_checksum(zeros, b);
    CHECK(collide == 0, "%d zero-length collisions", collide);

    size_t big = 64u << 20;
    uint8_t *m = malloc(big);
    for (size_t i = 0; i < big; i++) m[i] = (uint8_t)(i * 131 + (i >> 12));
    volatile uint64_t sink = wrt_gto_checksum(m, big); /* warm */
    double best = 1e9, best_fnv = 1e9;
    for (int r = 0; r < 3; r++) {
        double t0 = wrt_now();
        sink ^= wrt_gto_checksum(m, big);
        double t = wrt_now() - t0;
        if (t < best) best = t;
    }
    {
        double t0 = wrt_now();
        sink ^= wrt_hash64(m, big / 8, WRT_HASH_SEED);
        best_fnv = (wrt_now() - t0) * 8;
    }
    (void)sink;
    printf("checksum: %.0f MB/s (byte-wise FNV-1a: %.0f MB/s)\n", big / best / 1e6, big / best_fnv / 1e6);
    free(m);
}

/* ---- round trip ---- */

static void test_roundtrip(void) {
    build();
    const char *path = tpath("small.gto");
    if (!write_good(path)) return;
    wrt_gto g;
    wrt_status st = wrt_gto_open(path, &g);
    CHECK(st == WRT_OK, "open: %s", wrt_last_error());
    if (st != WRT_OK) return;
    /* No first-bounce operator: still version 1.0 (1.1 only for files with K). */
    CHECK(g.version == WRT_GTO_VERSION_FLOAT && g.version_minor == 0, "version %u.%u", g.version, g.version_minor);
    CHECK(g.nkcols == 0 && g.knnz == 0 && !g.kkeys && !g.kcol_start && !g.krows && !g.kvals, "no K");
    CHECK(g.op_kind == WRT_GTO_OP_GATHERED, "op kind %u", g.op_kind);
    CHECK(g.nquads == 3 && g.nmaterials == 2 && g.nlights == 2 && g.nnames == 2, "counts");
    CHECK(g.nfuncs == 7 && g.nnz == 12, "nfuncs %u nnz %llu", g.nfuncs, (unsigned long long)g.nnz);
    CHECK(g.owns_map == 1 && g.map && g.size > 0, "mapping");
    /* Quads. */
    for (int q = 0; q < 3; q++) {
        const wrt_gto_quad *r = &g.quads[q];
        const wrt_quad *s = &quads[q];
        int pe = 1;
        for (int k = 0; k < 4; k++)
            pe &= r->p[k][0] == s->p[k].x && r->p[k][1] == s->p[k].y && r->p[k][2] == s->p[k].z;
        CHECK(pe, "quad %d corners exact (double)", q);
        CHECK(r->n[0] == (float)s->n.x && r->n[1] == (float)s->n.y && r->n[2] == (float)s->n.z, "quad %d n", q);
        CHECK(r->t[0] == (float)s->t.x && r->t[1] == (float)s->t.y && r->t[2] == (float)s->t.z, "quad %d t", q);
        CHECK(r->b[0] == (float)s->b.x && r->b[1] == (float)s->b.y && r->b[2] == (float)s->b.z, "quad %d b", q);
        CHECK(r->area == (float)s->area, "quad %d area", q);
        CHECK(r->material == (uint32_t)s->material, "quad %d material", q);
        CHECK(r->flags == (s->parallelogram ? 1u : 0u), "quad %d flags %u", q, r->flags);
        CHECK(r->reserved == 0, "reserved");
    }
    CHECK(g.quads[0].name == 0 && g.quads[1].name == 1 && g.quads[2].name == WRT_GTO_NO_NAME, "names");
    CHECK(g.quads[2].flags == 0 && g.quads[0].flags == 1, "parallelogram flags");
    /* Function ranges and levels, counted by hand from build(): quad 0 has 4 functions
     * (deepest spatial level 2), quad 1 one, quad 2 two (angular level 1). */
    CHECK(g.quads[0].func_first == 0 && g.quads[0].func_count == 4, "q0 range %u+%u",
          g.quads[0].func_first, g.quads[0].func_count);
    CHECK(g.quads[1].func_first == 4 && g.quads[1].func_count == 1, "q1 range");
    CHECK(g.quads[2].func_first == 5 && g.quads[2].func_count == 2, "q2 range");
    CHECK(g.quads[0].slevel == 2 && g.quads[0].alevel == 0, "q0 levels %u %u", g.quads[0].slevel, g.quads[0].alevel);
    CHECK(g.quads[1].slevel == 0 && g.quads[1].alevel == 0, "q1 levels");
    CHECK(g.quads[2].slevel == 0 && g.quads[2].alevel == 1, "q2 levels %u %u", g.quads[2].slevel, g.quads[2].alevel);
    /* Materials. */
    for (int m = 0; m < 2; m++) {
        const wrt_gto_material *r = &g.materials[m];
        CHECK(strcmp(r->name, mats[m].name) == 0, "material %d name '%s'", m, r->name);
        CHECK(memcmp(r->base_color, mats[m].base_color, 12) == 0 && memcmp(r->emissive, mats[m].emissive, 12) == 0,
              "material %d colors", m);
        CHECK(r->metallic == mats[m].metallic && r->roughness == mats[m].roughness, "material %d mr", m);
        CHECK(r->lambertian == (uint32_t)mats[m].lambertian && r->alevel == mat_alevel[m], "material %d flags", m);
    }
    CHECK(strlen(g.materials[1].name) == 63, "63-character name kept whole");
    /* Lights. */
    for (int l = 0; l < 2; l++) {
        const wrt_gto_light *r = &g.lights[l];
        const wrt_light *s = &lights[l];
        CHECK(strcmp(r->name, s->name) == 0 && r->type == (uint32_t)s->type, "light %d", l);
        CHECK(r->pos[0] == s->pos.x && r->pos[1] == s->pos.y && r->pos[2] == s->pos.z, "light %d pos", l);
        CHECK(r->dir[0] == s->dir.x && r->dir[1] == s->dir.y && r->dir[2] == s->dir.z, "light %d dir", l);
        CHECK(memcmp(r->color, s->color, 12) == 0 && r->intensity == s->intensity && r->range == s->range &&
              r->inner_cone == s->inner_cone && r->outer_cone == s->outer_cone, "light %d params", l);
    }
    /* Camera. */
    const wrt_gto_camera *c = g.camera;
    const wrt_camera *sc = &scene.camera;
    CHECK(c->pos[0] == sc->pos.x && c->pos[1] == sc->pos.y && c->pos[2] == sc->pos.z, "camera pos");
    CHECK(c->dir[2] == sc->dir.z && c->up[1] == sc->up.y, "camera frame");
    CHECK(c->yfov == sc->yfov && c->aspect == sc->aspect && c->znear == sc->znear && c->zfar == sc->zfar, "camera lens");
    /* Names, operator, stats, provenance. */
    CHECK(strcmp(g.names[0], "floor") == 0 && strcmp(g.names[1], "wall") == 0, "names table");
    CHECK(memcmp(g.fkeys, fkeys, nfuncs * 8) == 0, "fkeys");
    CHECK(memcmp(g.col_start, col_start, (nfuncs + 1) * 8) == 0, "col_start");
    CHECK(memcmp(g.rows, rows, g.nnz * 4) == 0, "rows");
    CHECK(memcmp(g.vals, vals, g.nnz * 12) == 0, "vals");
    CHECK(memcmp(g.stats, &contents.stats, sizeof *g.stats) == 0, "stats");
    CHECK(g.provenance_len == strlen(provenance) && memcmp(g.provenance, provenance, g.provenance_len) == 0,
          "provenance");
    /* Alignment promised to the player. */
    int al = 1;
    const void *ptrs[] = {g.quads, g.materials, g.lights, g.camera, g.names, g.fkeys, g.col_start, g.rows, g.vals, g.stats};
    for (size_t i = 0; i < sizeof ptrs / sizeof *ptrs; i++) al &= ((uintptr_t)ptrs[i] % 64) == 0;
    CHECK(al, "sections 64-byte aligned in the mapping");
    wrt_gto_close(&g);
    CHECK(g.map == NULL, "close zeroes");
    wrt_gto_close(&g);
    wrt_gto_close(NULL);

    /* A file with no operator at all (nothing refined yet) is valid too. */
    wrt_gto_contents e = contents;
    e.nfuncs = 0; e.fkeys = NULL; e.col_start = NULL; e.rows = NULL; e.vals = NULL; e.provenance = NULL;
    st = wrt_gto_write(tpath("empty_op.gto"), &e);
    CHECK(st == WRT_OK, "write empty operator: %s", wrt_last_error());
    st = wrt_gto_open(tpath("empty_op.gto"), &g);
    CHECK(st == WRT_OK && g.nfuncs == 0 && g.nnz == 0 && g.col_start[0] == 0 && g.provenance_len == 0,
          "open empty operator: %s", wrt_last_error());
    CHECK(g.nquads == 3 && g.quads[2].func_count == 0, "quads without functions");
    wrt_gto_close(&g);
}

static void test_deterministic(void) {
    build();
    const char *a = tpath("det_a.gto"), *b = tpath("det_b.gto");
    if (!write_good(a) || !write_good(b)) return;
    size_t na, nb;
    uint8_t *x = read_all(a, &na), *y = read_all(b, &nb);
    CHECK(na == nb && na > 0 && memcmp(x, y, na) == 0, "two writes differ (%zu, %zu bytes)", na, nb);
    /* The documented layout: magic, version, sizes, 64-byte aligned sections. */
    CHECK(memcmp(x, "\x89WRT\r\n\x1a\n", 8) == 0, "magic");
    CHECK(x[F_BOM] == 4 && x[F_BOM + 1] == 3 && x[F_BOM + 2] == 2 && x[F_BOM + 3] == 1, "byte-order mark");
    CHECK(x[F_VERSION_MAJOR] == 1 && x[F_VERSION_MAJOR + 1] == 0, "version bytes");
    CHECK(rd64(x, F_FILE_SIZE) == na, "recorded size");
    int ok = 1;
    for (int s = 0; s < F_NSEC; s++) ok &= sec_off(x, s) % 64 == 0 && (uint32_t)x[entry(s)] == (uint32_t)(s + 1);
    CHECK(ok, "section table ids and alignment");
    CHECK(rd64(x, entry(S_VALS) + F_E_COUNT) == 12, "vals count");
    free(x); free(y);
}

/* A fresh copy of a good file for a test to damage: build(), `write` into the test
 * folder as `name`, its bytes read back (NULL, the failure checked, if either fails). */
static uint8_t *written(const char *name, int (*write)(const char *), size_t *n) {
    build();
    const char *p = tpath(name);
    if (!write(p)) return NULL;
    uint8_t *b = read_all(p, n);
    if (!b) CHECK(0, "read back %s", p);
    return b;
}

/* Today's writer (`write`, into the test folder as `now`) produces the committed file
 * `golden` byte for byte (the golden tests of each version). */
static void writer_reproduces(const char *golden, const char *now, int (*write)(const char *)) {
    const char *p = tpath(now);
    if (!write(p)) return;
    size_t na, nb;
    uint8_t *x = read_all(golden, &na), *y = read_all(p, &nb);
    CHECK(x && na == nb && memcmp(x, y, na) == 0,
          "the writer no longer produces %s byte for byte: a format change needs a version decision", golden);
    free(x); free(y);
}

/* A committed file of version 1.0: it must stay readable, and today's writer must
 * still produce exactly it (a change here is a format change: see the checklist). */
static void test_golden(void) {
    build();
    wrt_gto g;
    wrt_status st = wrt_gto_open(golden_path, &g);
    CHECK(st == WRT_OK, "golden file: %s", wrt_last_error());
    if (st == WRT_OK) {
        CHECK(g.nquads == 3 && g.nfuncs == 7 && g.nnz == 12 && g.version == 1, "golden counts");
        wrt_gto_close(&g);
    }
    writer_reproduces(golden_path, "golden_now.gto", write_good);
}

/* ---- broken files ---- */

static void expect(wrt_status got, wrt_status want, const char *substr, const char *what) {
    CHECK(got == want, "%s: status %s, expected %s (%s)", what, wrt_status_str(got), wrt_status_str(want),
          wrt_last_error());
    CHECK(strstr(wrt_last_error(), substr) != NULL, "%s: message '%s' lacks '%s'", what, wrt_last_error(), substr);
}

static void test_foreign(void) {
    wrt_gto g;
    static const uint8_t png[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                                  0, 0, 0, 1, 0, 0, 0, 1, 8, 2, 0, 0, 0, 0x90, 0x77, 0x53, 0xde};
    write_raw(tpath("foreign.png"), png, sizeof png);
    expect(wrt_gto_open(tpath("foreign.png"), &g), WRT_ERR_NOT_OURS, "not a .gto file", "PNG");
    CHECK(strstr(wrt_last_error(), "foreign.png") != NULL, "message names the file: %s", wrt_last_error());
    const char *text = "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": []}\n";
    write_raw(tpath("scene.gltf"), text, strlen(text));
    expect(wrt_gto_open(tpath("scene.gltf"), &g), WRT_ERR_NOT_OURS, "not a .gto file", "text");
    /* The magic with its line ending converted, as a text-mode copy would. */
    size_t n;
    build();
    if (!write_good(tpath("good.gto"))) return;
    uint8_t *b = read_all(tpath("good.gto"), &n);
    uint8_t *d = malloc(n + 1);
    memcpy(d, b, 4); d[4] = '\n'; memcpy(d + 5, b + 6, n - 6);
    expect(open_copy(d, n - 1, &g), WRT_ERR_NOT_OURS, "not a .gto file", "CRLF -> LF");
    memcpy(d, b, n); d[0] = 0x09;
    expect(open_copy(d, n, &g), WRT_ERR_NOT_OURS, "not a .gto file", "high bit stripped");
    free(b); free(d);
    expect(wrt_gto_open(tpath("does_not_exist.gto"), &g), WRT_ERR_IO, "cannot open", "missing file");
    expect(wrt_gto_open(tmpdir, &g), WRT_ERR_NOT_OURS, "not a regular file (a directory)", "directory");
    /* A FIFO is refused at once (opened without blocking, then fstat), not waited on. */
    const char *fifo = tpath("pipe.gto");
    unlink(fifo);
    CHECK(mkfifo(fifo, 0600) == 0, "mkfifo: %s", strerror(errno));
    double t0 = wrt_now();
    expect(wrt_gto_open(fifo, &g), WRT_ERR_NOT_OURS, "not a regular file (a FIFO)", "FIFO");
    char *info = NULL;
    size_t tn = 0;
    FILE *f = open_memstream(&info, &tn);
    wrt_status st = wrt_gto_print_info(fifo, 0, f);
    fclose(f);
    CHECK(st == WRT_ERR_NOT_OURS && strstr(wrt_last_error(), "a FIFO"), "--info on a FIFO: %s", wrt_last_error());
    CHECK(wrt_now() - t0 < 5, "FIFO answered in %.1f s", wrt_now() - t0);
    free(info);
    unlink(fifo);
}

static void test_empty(void) {
    wrt_gto g;
    write_raw(tpath("empty.gto"), "", 0);
    expect(wrt_gto_open(tpath("empty.gto"), &g), WRT_ERR_CORRUPT, "empty file", "empty");
    CHECK(g.map == NULL && g.nquads == 0, "out zeroed on failure");
}

static void test_truncated(void) {
    size_t n;
    uint8_t *b = written("trunc_src.gto", write_good, &n);
    if (!b) return;
    wrt_gto g;
    int bad_status = 0, bad_msg = 0;
    for (size_t len = 1; len < n; len++) {
        wrt_status st = open_copy(b, len, &g);
        bad_status += st != WRT_ERR_CORRUPT;
        bad_msg += strstr(wrt_last_error(), "truncated") == NULL;
    }
    CHECK(bad_status == 0, "%d prefixes not reported corrupt", bad_status);
    CHECK(bad_msg == 0, "%d prefixes without 'truncated' in the message", bad_msg);
    /* Through files too (a sample), with the exact figures. */
    write_raw(tpath("trunc.gto"), b, n - 1);
    char want[128];
    snprintf(want, sizeof want, "truncated: expected %zu bytes, found %zu", n, n - 1);
    expect(wrt_gto_open(tpath("trunc.gto"), &g), WRT_ERR_CORRUPT, want, "file cut by one byte");
    write_raw(tpath("trunc.gto"), b, 20);
    expect(wrt_gto_open(tpath("trunc.gto"), &g), WRT_ERR_CORRUPT, "expected at least 64 bytes", "file cut in header");
    write_raw(tpath("trunc.gto"), b, 5);
    expect(wrt_gto_open(tpath("trunc.gto"), &g), WRT_ERR_CORRUPT, "truncated", "file cut in magic");
    /* Trailing bytes are as wrong as missing ones. */
    uint8_t *l = malloc(n + 64);
    memcpy(l, b, n); memset(l + n, 0, 64);
    expect(open_copy(l, n + 64, &g), WRT_ERR_CORRUPT, "trailing data", "appended bytes");
    free(l); free(b);
}

static void test_flipped_bytes(void) {
    size_t n;
    uint8_t *b = written("flip_src.gto", write_good, &n);
    if (!b) return;
    wrt_gto g;
    /* One byte in the middle of each section: its checksum, named. */
    for (int s = 0; s < F_NSEC; s++) {
        size_t o = sec_off(b, s) + sec_size(b, s) / 2;
        b[o] ^= 0x10;
        char want[64], what[64];
        snprintf(want, sizeof want, "section %s: checksum mismatch", sec_names[s]);
        snprintf(what, sizeof what, "flip in %s", sec_names[s]);
        expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, want, what);
        b[o] ^= 0x10;
    }
    /* In the header and the section table. */
    b[33] ^= 1; /* op kind */
    expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, "header checksum mismatch", "flip in header");
    b[33] ^= 1;
    b[entry(S_ROWS) + F_E_SUM] ^= 0x80;
    expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, "header checksum mismatch", "flip in table");
    b[entry(S_ROWS) + F_E_SUM] ^= 0x80;
    /* In the zero padding before a section. */
    size_t pad = sec_off(b, S_LIGHTS) - 1;
    CHECK(pad >= sec_off(b, S_MATERIALS) + sec_size(b, S_MATERIALS), "there is padding before lights");
    b[pad] = 7;
    expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, "non-zero padding", "flip in padding");
    b[pad] = 0;
    /* Every byte of the file is covered: any flip fails cleanly. */
    int undetected = 0;
    for (size_t o = 0; o < n; o++) {
        b[o] ^= 0x01;
        undetected += open_copy(b, n, &g) == WRT_OK;
        b[o] ^= 0x01;
    }
    CHECK(undetected == 0, "%d flipped bytes went unnoticed", undetected);
    CHECK(open_copy(b, n, &g) == WRT_OK, "restored image opens: %s", wrt_last_error());
    wrt_gto_close(&g);
    free(b);
}

static void test_versions(void) {
    size_t n;
    uint8_t *b = written("ver_src.gto", write_good, &n);
    if (!b) return;
    wrt_gto g;
    b[F_VERSION_MAJOR] = 4;
    fix_header_sum(b);
    write_raw(tpath("v4.gto"), b, n);
    expect(wrt_gto_open(tpath("v4.gto"), &g), WRT_ERR_UNSUPPORTED, "file version 4.0 is newer than this reader's version 3.0",
           "newer major");
    /* Version 3.0 with float entries: it opens (3.0 only adds the compact stream). */
    b[F_VERSION_MAJOR] = 3;
    fix_header_sum(b);
    wrt_status st3 = open_copy(b, n, &g);
    CHECK(st3 == WRT_OK && g.version == 3 && g.rows && !g.op_codes, "3.0 with float entries opens: %s", wrt_last_error());
    /* Version 2.0 with float entries (a 2.0 writer that needs a critical section but
     * writes floats): it opens. */
    b[F_VERSION_MAJOR] = 2;
    fix_header_sum(b);
    wrt_status st2 = open_copy(b, n, &g);
    CHECK(st2 == WRT_OK && g.version == 2 && g.rows && !g.op_codes, "2.0 with float entries opens: %s", wrt_last_error());
    b[F_VERSION_MAJOR] = 0;
    fix_header_sum(b);
    expect(open_copy(b, n, &g), WRT_ERR_UNSUPPORTED, "older", "older major");
    /* A newer minor of the same major opens. */
    b[F_VERSION_MAJOR] = 1; b[F_VERSION_MAJOR + 2] = 7;
    fix_header_sum(b);
    wrt_status st = open_copy(b, n, &g);
    CHECK(st == WRT_OK, "minor 1.7 opens: %s", wrt_last_error());
    b[F_VERSION_MAJOR + 2] = 0;
    fix_header_sum(b);
    /* Byte order. */
    uint32_t swapped = 0x04030201u;
    memcpy(b + F_BOM, &swapped, 4);
    fix_header_sum(b);
    expect(open_copy(b, n, &g), WRT_ERR_UNSUPPORTED, "big-endian", "swapped byte-order mark");
    uint32_t junk = 0xdeadbeefu;
    memcpy(b + F_BOM, &junk, 4);
    fix_header_sum(b);
    expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, "byte-order mark", "bad byte-order mark");
    free(b);
}

static void test_bad_offsets(void) {
    size_t n;
    uint8_t *b = written("off_src.gto", write_good, &n);
    if (!b) return;
    uint8_t *c = malloc(n);
    wrt_gto g;
    /* A section pointing past the end, the header checksum made right. */
    memcpy(c, b, n);
    wr64(c, entry(S_VALS) + F_E_OFFSET, n + 64);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "section vals: offset", "offset past the end");
    CHECK(strstr(wrt_last_error(), "beyond end of file") != NULL, "%s", wrt_last_error());
    /* Offset + size overflowing 64 bits must not wrap into range. */
    memcpy(c, b, n);
    wr64(c, entry(S_ROWS) + F_E_OFFSET, 64);
    wr64(c, entry(S_ROWS) + F_E_SIZE, UINT64_MAX - 32);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "beyond end of file", "wrapping size");
    memcpy(c, b, n);
    wr64(c, entry(S_FKEYS) + F_E_OFFSET, UINT64_MAX - 7);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "beyond end of file", "huge offset");
    /* Misaligned, overlapping, inconsistent count. */
    memcpy(c, b, n);
    wr64(c, entry(S_NAMES) + F_E_OFFSET, sec_off(b, S_NAMES) + 8);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "not 64-byte aligned", "misaligned");
    memcpy(c, b, n);
    wr64(c, entry(S_NAMES) + F_E_OFFSET, sec_off(b, S_NAMES) - 64);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "sections follow each other", "overlapping");
    memcpy(c, b, n);
    wr64(c, entry(S_ROWS) + F_E_COUNT, 13);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "section rows: size 48 is not 13 elements", "count vs size");
    memcpy(c, b, n);
    c[entry(S_QUADS) + 4] = 160; /* element size */
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "section quads: element size 160, expected 168", "element size");
    memcpy(c, b, n);
    c[entry(S_STATS)] = 1; /* id repeated, out of order */
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "out of order or repeated", "table order");
    free(b); free(c);
}

/* Breaks one value inside a section, fixes that section's and the header's checksums,
 * and expects the index check to catch it. */
static void corrupt_index(uint8_t *b, size_t n, int s, size_t at, const void *val, size_t vn,
                          const char *want, const char *what) {
    uint8_t *c = malloc(n);
    memcpy(c, b, n);
    memcpy(c + sec_off(c, s) + at, val, vn);
    fix_section_sum(c, s);
    fix_header_sum(c);
    wrt_gto g;
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, want, what);
    free(c);
}

static void test_bad_indices(void) {
    size_t n;
    uint8_t *b = written("idx_src.gto", write_good, &n);
    if (!b) return;
    uint32_t r7 = 7, r0 = 0;
    corrupt_index(b, n, S_ROWS, 4 * 5, &r7, 4, "rows[5] = 7 out of range (7 functions) in column 3", "row out of range");
    /* Column 0 holds rows 0, 2, 4: make the second 0. */
    corrupt_index(b, n, S_ROWS, 4 * 1, &r0, 4, "rows not strictly ascending in column 0", "rows unsorted");
    uint64_t big = 7, five = 5, zero = 0;
    corrupt_index(b, n, S_COL_START, 8 * 2, &big, 8, "col_start not monotone at column 3", "col_start decreasing");
    uint64_t last = 11;
    corrupt_index(b, n, S_COL_START, 8 * 7, &last, 8, "col_start[7] is 11, but there are 12 entries", "col_start end");
    corrupt_index(b, n, S_COL_START, 0, &five, 8, "col_start[0] is 5", "col_start start");
    corrupt_index(b, n, S_FKEYS, 8 * 3, &zero, 8, "fkeys not strictly ascending at index 3", "fkeys unsorted");
    uint64_t far = wrt_fkey_make(3, wrt_node_root(), 0, wrt_node_root(), 0);
    corrupt_index(b, n, S_FKEYS, 8 * 6, &far, 8, "fkeys[6] names quad 3, but there are 3 quads", "fkey quad");
    float nan = NAN, inf = INFINITY;
    corrupt_index(b, n, S_VALS, 12 * 4 + 4, &nan, 4, "vals[4] channel 1 is NaN", "NaN value");
    corrupt_index(b, n, S_VALS, 12 * 11 + 8, &inf, 4, "vals[11] channel 2 is infinite", "infinite value");
    /* finite but absurd, checksums made consistent: what the computation cannot carry */
    float huge = 3e38f, just = 2.7e14f, over = 2.9e14f;
    corrupt_index(b, n, S_VALS, 12 * 3, &huge, 4, "vals[3] channel 0 is beyond 2^48", "value 3e38");
    corrupt_index(b, n, S_VALS, 12 * 3 + 4, &over, 4, "vals[3] channel 1 is beyond 2^48", "value 2.9e14");
    {   /* the bound is not too tight: a value just under it is read */
        uint8_t *c = malloc(n);
        memcpy(c, b, n);
        memcpy(c + sec_off(c, S_VALS) + 12 * 3 + 4, &just, 4);
        fix_section_sum(c, S_VALS);
        fix_header_sum(c);
        wrt_gto g;
        wrt_status st = wrt_gto_open_memory(c, n, &g);
        CHECK(st == WRT_OK, "a value of 2.7e14, under 2^48, is read: %s", st ? wrt_last_error() : "");
        if (st == WRT_OK) wrt_gto_close(&g);
        free(c);
    }
    double dfar = 1e30;
    corrupt_index(b, n, S_QUADS, 8, &dfar, 8, "quad 0: corner 0 is not finite or beyond 1e+09", "corner 1e30");
    corrupt_index(b, n, S_LIGHTS, 80, &dfar, 8, "light 0: position beyond 1e+09", "light position 1e30");
    uint32_t m9 = 9, ff = 5, fc = 9;
    corrupt_index(b, n, S_QUADS, 168 + 136, &m9, 4, "quad 1: material 9 out of range (2 materials)", "material index");
    corrupt_index(b, n, S_QUADS, 168 + 140, &m9, 4, "quad 1: name 9 out of range", "name index");
    corrupt_index(b, n, S_QUADS, 168 * 2 + 148, &fc, 4, "quad 2: functions [5, +9) beyond the 7 functions", "func range");
    corrupt_index(b, n, S_QUADS, 168 + 144, &ff, 4, "quad 1: functions start at 5, expected 4", "func gap");
    double dnan = NAN;
    corrupt_index(b, n, S_QUADS, 8, &dnan, 8, "quad 0: corner 0 is not finite", "corner NaN");
    uint32_t t5 = 5;
    corrupt_index(b, n, S_LIGHTS, 144 + 64, &t5, 4, "light 1: unknown type 5", "light type");
    char full[64];
    memset(full, 'x', 64);
    corrupt_index(b, n, S_NAMES, 64, full, 64, "name 1: not terminated", "unterminated name");
    free(b);
}

/* Every number handed out is checked, with consistent checksums (a forged file), and
 * --info's integrity line reports it. */
static void test_bad_numbers(void) {
    size_t n;
    uint8_t *b = written("num_src.gto", write_good, &n);
    if (!b) return;
    float fnan = NAN, finf = INFINITY, two = 2, neg = -1;
    double dnan = NAN, dzero = 0;
    corrupt_index(b, n, S_MATERIALS, 104 + 64 + 4, &fnan, 4, "material 1: base_color[1] nan is not in [0, 1]", "material NaN");
    corrupt_index(b, n, S_MATERIALS, 76, &two, 4, "material 0: metallic 2 or roughness", "metallic 2");
    corrupt_index(b, n, S_MATERIALS, 84, &finf, 4, "material 0: emissive[0] inf is not in [0, 1e+12]", "emissive inf");
    /* finite, but the emitter's power pi L_e A is inf in float (issue 25, session 4) */
    float fhuge = 3e38f;
    corrupt_index(b, n, S_MATERIALS, 84, &fhuge, 4, "material 0: emissive[0] 3e+38 is not in [0, 1e+12]", "emissive 3e38");
    corrupt_index(b, n, S_LIGHTS, 68, &fnan, 4, "light 0: color[0] nan is not finite", "light colour NaN");
    corrupt_index(b, n, S_LIGHTS, 144 + 128, &fnan, 4, "light 1: intensity nan", "light intensity NaN");
    corrupt_index(b, n, S_LIGHTS, 128, &finf, 4, "light 0: intensity inf", "light intensity inf");
    corrupt_index(b, n, S_LIGHTS, 144 + 132, &neg, 4, "light 1: intensity 100 or range -1", "negative range");
    corrupt_index(b, n, S_LIGHTS, 80, &dnan, 8, "light 0: position or direction not finite", "light position NaN");
    corrupt_index(b, n, S_LIGHTS, 144 + 104 + 16, &dzero, 8, "light 1: position or direction not finite (or not unit)", "spot axis zero");
    corrupt_index(b, n, S_LIGHTS, 144 + 136, &two, 4, "light 1: cone angles 2 / 0.4", "cone");
    corrupt_index(b, n, S_CAMERA, 72, &dnan, 8, "camera: yfov nan", "yfov NaN");
    corrupt_index(b, n, S_CAMERA, 88, &dzero, 8, "camera: yfov 0.7, aspect 1.5, znear 0 ", "znear 0");
    corrupt_index(b, n, S_CAMERA, 24 + 16, &dzero, 8, "camera: direction or up not of unit length", "camera dir zero");
    corrupt_index(b, n, S_CAMERA, 48 + 8, &dnan, 8, "camera: position, direction or up not finite", "camera up NaN");
    /* finite but beyond what the player carries (common/limits.h): refused when read, not
     * by wrt_runtime_set_eye (unnamed file) or as a black picture with exit 0 */
    double far = 3e38, tiny_fov = 1e-300;
    corrupt_index(b, n, S_CAMERA, 0, &far, 8, "camera: position (3e+38, ", "camera at 3e38");
    corrupt_index(b, n, S_CAMERA, 72, &tiny_fov, 8, "camera: yfov 1e-300", "yfov 1e-300");
    corrupt_index(b, n, S_STATS, 96, &dnan, 8, "stats: energy_left nan", "energy NaN");
    corrupt_index(b, n, S_QUADS, 96, &fnan, 4, "quad 0: normal is not a unit vector", "normal NaN");
    corrupt_index(b, n, S_QUADS, 168 + 132, &neg, 4, "quad 1: area -1 is not finite and > 0", "negative area");
    /* --info: a forged file with NaN in a light is not "integrity: ok". */
    uint8_t *c = malloc(n);
    memcpy(c, b, n);
    memcpy(c + sec_off(c, S_LIGHTS) + 128, &fnan, 4);
    fix_section_sum(c, S_LIGHTS);
    fix_header_sum(c);
    write_raw(tpath("nan_light.gto"), c, n);
    char *text = NULL;
    size_t tn = 0;
    FILE *f = open_memstream(&text, &tn);
    wrt_status st = wrt_gto_print_info(tpath("nan_light.gto"), 0, f);
    fclose(f);
    CHECK(st == WRT_ERR_CORRUPT, "info status %s", wrt_status_str(st));
    CHECK(strstr(text, "integrity:  FAILED (corrupt") && strstr(text, "light 0: intensity nan"), "%s", text);
    free(text);
    free(c);
    /* The writer refuses the same numbers. */
    wrt_light saved = lights[0];
    lights[0].intensity = NAN;
    expect(wrt_gto_write(tpath("w.gto"), &contents), WRT_ERR_INVALID_ARG, "light 0: intensity nan", "writer NaN");
    lights[0] = saved;
    free(b);
}

/* The checks run 8192 elements at a time: a fault right at a chunk boundary, inside
 * a column that spans it, must still be found. */
static void test_chunk_boundaries(void) {
    build();
    uint32_t nf = 20000;
    uint64_t nnz = 10000;
    uint64_t *k = malloc(nf * 8), *cs = malloc((nf + 1) * 8);
    uint32_t *r = malloc(nnz * 4);
    float *v = malloc(nnz * 12);
    for (uint32_t i = 0; i < nf; i++) k[i] = wrt_fkey_make(0, wrt_node_root(), 0, wrt_node_root(), 0) + ((uint64_t)i << 6);
    cs[0] = 0;
    for (uint32_t s = 1; s <= nf; s++) cs[s] = nnz; /* column 0 holds everything */
    for (uint64_t e = 0; e < nnz; e++) r[e] = (uint32_t)(2 * e);
    for (uint64_t e = 0; e < 3 * nnz; e++) v[e] = 0.5f;
    wrt_gto_contents c = contents;
    c.fkeys = k; c.nfuncs = nf; c.col_start = cs; c.rows = r; c.vals = v;
    const char *p = tpath("chunks.gto");
    if (wrt_gto_write(p, &c) != WRT_OK) { CHECK(0, "write: %s", wrt_last_error()); return; }
    size_t n;
    uint8_t *b = read_all(p, &n);
    wrt_gto g;
    CHECK(open_copy(b, n, &g) == WRT_OK, "open: %s", wrt_last_error());
    uint32_t same = 2 * 8191, big = 2 * 20000;
    corrupt_index(b, n, S_ROWS, 4 * 8192, &same, 4, "rows not strictly ascending in column 0 at entry 8192", "rows at boundary");
    corrupt_index(b, n, S_ROWS, 4 * 8191, &big, 4, "rows[8191] = 40000 out of range", "rows before boundary");
    corrupt_index(b, n, S_FKEYS, 8 * 8192, &k[8191], 8, "fkeys not strictly ascending at index 8192", "fkeys at boundary");
    uint64_t less = nnz - 1;
    corrupt_index(b, n, S_COL_START, 8 * 8192, &less, 8, "col_start not monotone at column 8192 (9999 after 10000)", "col_start at boundary");
    float nan = NAN;
    corrupt_index(b, n, S_VALS, 12 * 8192, &nan, 4, "vals[8192] channel 0 is NaN", "vals at boundary");
    free(b); free(k); free(cs); free(r); free(v);
}

/* ---- writing ---- */

static void test_write_errors(void) {
    build();
    char dir[512];
    snprintf(dir, sizeof dir, "%s/no_such_dir", tmpdir);
    const char *p = tpath("no_such_dir/x.gto");
    expect(wrt_gto_write(p, &contents), WRT_ERR_IO, "cannot create a temporary file", "missing directory");
    struct stat sb;
    CHECK(stat(dir, &sb) != 0 && errno == ENOENT, "nothing created");

    /* The writer refuses what the reader would refuse; no file appears. */
    const char *q = tpath("refused.gto");
    uint64_t k2[8];
    memcpy(k2, fkeys, sizeof k2);
    uint64_t t = k2[1]; k2[1] = k2[2]; k2[2] = t;
    wrt_gto_contents c = contents;
    c.fkeys = k2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "fkeys not strictly ascending", "unsorted keys");
    uint32_t r2[32];
    memcpy(r2, rows, sizeof r2);
    r2[0] = 99;
    c = contents; c.rows = r2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "out of range", "row index");
    float v2[96];
    memcpy(v2, vals, sizeof v2);
    v2[7] = NAN;
    c = contents; c.vals = v2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "NaN", "NaN value");
    quads[1].material = 5;
    expect(wrt_gto_write(q, &contents), WRT_ERR_INVALID_ARG, "material 5 out of range", "material");
    quads[1].material = 1;
    uint64_t k3[8];
    memcpy(k3, fkeys, sizeof k3);
    k3[6] = wrt_fkey_make(7, wrt_node_root(), 0, wrt_node_root(), 0);
    c = contents; c.fkeys = k3;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "names quad 7", "quad of key");
    CHECK(stat(q, &sb) != 0, "refused write left a file");
    CHECK(count_tmp_files(tmpdir) == 0, "temporaries left behind");
}

/* A write that fails half way (file size limit) leaves the old file as it was. */
static void test_failed_write_keeps_target(void) {
    build();
    const char *p = tpath("keep.gto");
    const char *old = "the previous contents";
    write_raw(p, old, strlen(old));
    struct rlimit saved, lim;
    getrlimit(RLIMIT_FSIZE, &saved);
    lim = saved;
    lim.rlim_cur = 1000; /* the file is ~3 kB */
    void (*prev)(int) = signal(SIGXFSZ, SIG_IGN);
    setrlimit(RLIMIT_FSIZE, &lim);
    wrt_status st = wrt_gto_write(p, &contents);
    setrlimit(RLIMIT_FSIZE, &saved);
    signal(SIGXFSZ, prev);
    const char *msg = wrt_last_error();
    CHECK(st == WRT_ERR_IO, "status %s: %s", wrt_status_str(st), msg);
    CHECK(strstr(msg, "cannot write") && strstr(msg, "keep.gto"), "message: %s", msg);
    size_t n;
    uint8_t *b = read_all(p, &n);
    CHECK(b && n == strlen(old) && memcmp(b, old, n) == 0, "target changed (%zu bytes)", n);
    free(b);
    CHECK(count_tmp_files(tmpdir) == 0, "temporary left behind");
    /* And the next write replaces it, with the usual permissions. */
    if (write_good(p)) {
        wrt_gto g;
        CHECK(wrt_gto_open(p, &g) == WRT_OK, "rewritten: %s", wrt_last_error());
        wrt_gto_close(&g);
        struct stat sb;
        stat(p, &sb);
        mode_t um = umask(0);
        umask(um);
        CHECK((sb.st_mode & 0777) == (0666 & ~um), "mode %o", (unsigned)(sb.st_mode & 0777));
    }
}

static void raise_term(const char *tmp) {
    struct stat sb;
    if (stat(tmp, &sb) != 0) _exit(3); /* the temporary should exist now */
    raise(SIGTERM);
    _exit(4); /* not reached */
}

/* Forks a writer that is killed by `sig` once its temporary exists; returns the status. */
static int killed_write(const char *path, int handler, int named) {
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        if (handler) wrt_gto_install_signal_cleanup();
        wrt_gto_force_named_temporaries(named);
        wrt_gto_set_write_hook(raise_term);
        wrt_gto_write(path, &contents);
        _exit(5);
    }
    int ws = 0;
    waitpid(pid, &ws, 0);
    return ws;
}

/* A write interrupted while writing leaves neither a temporary nor a target: an
 * unnamed temporary (O_TMPFILE) vanishes with the process, a named one is removed by
 * the handler; without the handler the named one stays, and the next write to the
 * same path removes it (its process is gone). */
static void test_signal_cleanup(void) {
    build();
    char dir[512];
    snprintf(dir, sizeof dir, "%s/sig", tmpdir);
    mkdir(dir, 0777);
    char path[600];
    snprintf(path, sizeof path, "%s/out.gto", dir);
    struct stat sb;
    int ws = killed_write(path, 0, 0);
    CHECK(WIFSIGNALED(ws) && WTERMSIG(ws) == SIGTERM, "unnamed: child ended with status 0x%x, expected SIGTERM", ws);
    CHECK(count_tmp_files(dir) == 0, "unnamed temporary left without any handler");
    CHECK(stat(path, &sb) != 0, "target appeared");
    ws = killed_write(path, 1, 1);
    CHECK(WIFSIGNALED(ws) && WTERMSIG(ws) == SIGTERM, "named: child ended with status 0x%x, expected SIGTERM", ws);
    CHECK(count_tmp_files(dir) == 0, "named temporary survived the handler");
    CHECK(stat(path, &sb) != 0, "target appeared");
    ws = killed_write(path, 0, 1);
    CHECK(WIFSIGNALED(ws) && count_tmp_files(dir) == 1, "control: named temporary expected without handler");
    test_capture_begin();
    int ok = write_good(path);
    test_capture_end();
    CHECK(ok && count_tmp_files(dir) == 0, "the next write removes the stale temporary (%d left)", count_tmp_files(dir));
    CHECK(strstr(test_log, "which is gone") != NULL, "log: %s", test_log);
    unlink(path);
}

/* A pending write: checked through its descriptor, then committed or discarded; the
 * target is the old file until the commit. */
static void test_pending(void) {
    build();
    const char *p = tpath("pend.gto");
    write_raw(p, "old", 3);
    wrt_gto_pending w;
    CHECK(wrt_gto_write_pending(p, &contents, &w) == WRT_OK, "%s", wrt_last_error());
    char dir[512];
    snprintf(dir, sizeof dir, "%s", tmpdir);
    CHECK(count_tmp_files(dir) == 0, "an unnamed temporary has no name");
    wrt_gto g;
    CHECK(wrt_gto_open_pending(&w, &g) == WRT_OK && g.nquads == 3, "open pending: %s", wrt_last_error());
    wrt_gto_close(&g);
    size_t n;
    uint8_t *b = read_all(p, &n);
    CHECK(n == 3 && memcmp(b, "old", 3) == 0, "target untouched while pending");
    free(b);
    wrt_gto_discard(&w);
    b = read_all(p, &n);
    CHECK(n == 3 && memcmp(b, "old", 3) == 0, "target untouched after discard");
    free(b);
    CHECK(count_tmp_files(dir) == 0, "nothing left after discard");
    CHECK(wrt_gto_write_pending(p, &contents, &w) == WRT_OK, "%s", wrt_last_error());
    CHECK(wrt_gto_commit(&w) == WRT_OK, "commit: %s", wrt_last_error());
    CHECK(wrt_gto_open(p, &g) == WRT_OK, "committed file opens: %s", wrt_last_error());
    wrt_gto_close(&g);
    CHECK(count_tmp_files(dir) == 0, "nothing left after commit");
    /* the same with a named temporary */
    wrt_gto_force_named_temporaries(1);
    CHECK(wrt_gto_write_pending(p, &contents, &w) == WRT_OK, "%s", wrt_last_error());
    CHECK(count_tmp_files(dir) == 1, "named temporary while pending");
    wrt_gto_discard(&w);
    CHECK(count_tmp_files(dir) == 0, "named temporary removed by discard");
    wrt_gto_force_named_temporaries(0);
}

/* The output is checked before any work: not an input (same inode, also through a
 * hard or symbolic link), not a directory, in a folder where a file can be made. */
static void test_check_output(void) {
    const char *in = tpath("in.gltf");
    write_raw(in, "{}", 2);
    const char *inputs[1] = {in};
    expect(wrt_gto_check_output(in, inputs, 1), WRT_ERR_INVALID_ARG, "the output is the input", "same path");
    const char *hard = tpath("hard.gto"), *sym = tpath("sym.gto");
    unlink(hard); unlink(sym);
    CHECK(link(in, hard) == 0 && symlink(in, sym) == 0, "links: %s", strerror(errno));
    expect(wrt_gto_check_output(hard, inputs, 1), WRT_ERR_INVALID_ARG, "the output is the input", "hard link");
    expect(wrt_gto_check_output(sym, inputs, 1), WRT_ERR_INVALID_ARG, "the output is the input", "symbolic link");
    expect(wrt_gto_check_output(tmpdir, inputs, 1), WRT_ERR_IO, "the output is a directory", "directory");
    expect(wrt_gto_check_output("/proc/wrt_no.gto", inputs, 1), WRT_ERR_IO, "cannot create a temporary file", "unwritable");
    expect(wrt_gto_check_output(tpath("no/such/dir.gto"), inputs, 1), WRT_ERR_IO, "cannot create a temporary file", "missing folder");
    CHECK(wrt_gto_check_output(tpath("fresh.gto"), inputs, 1) == WRT_OK, "a new file: %s", wrt_last_error());
    char dir[512];
    snprintf(dir, sizeof dir, "%s", tmpdir);
    CHECK(count_tmp_files(dir) == 0, "the probe leaves nothing");
    unlink(hard); unlink(sym);
}

/* ---- inspection ---- */

static void test_print_info(void) {
    build();
    const char *p = tpath("info.gto");
    if (!write_good(p)) return;
    char *text = NULL;
    size_t tn = 0;
    FILE *f = open_memstream(&text, &tn);
    wrt_status st = wrt_gto_print_info(p, 0, f);
    fclose(f);
    CHECK(st == WRT_OK, "info: %s", wrt_last_error());
    CHECK(strstr(text, "version 1.0") && strstr(text, "gathered"), "header: %s", text);
    CHECK(strstr(text, "3 quads, 2 materials, 2 lights, 2 names"), "counts: %s", text);
    CHECK(strstr(text, "7 functions (1 with angular detail), 12 entries"), "operator: %s", text);
    CHECK(strstr(text, "rays: 1000000007 traced"), "stats: %s", text);
    CHECK(strstr(text, "\"scene\": \"synthetic\""), "provenance: %s", text);
    CHECK(strstr(text, "integrity:  ok"), "integrity: %s", text);
    CHECK(strstr(text, "vals") && strstr(text, "        144 "), "section bytes: %s", text);
    free(text);
    f = open_memstream(&text, &tn);
    st = wrt_gto_print_info(p, 1, f);
    fclose(f);
    CHECK(st == WRT_OK && text[0] == '{' && text[tn - 2] == '}', "json object: %s", text);
    CHECK(strstr(text, "\"ok\": true") && strstr(text, "\"functions\": 7") && strstr(text, "\"entries\": 12"),
          "json counts: %s", text);
    CHECK(strstr(text, "\"provenance\": {\"scene\": \"synthetic\""), "provenance embedded as JSON: %s", text);
    CHECK(strstr(text, "\"rays_traced\": 1000000007"), "json stats");
    free(text);

    /* Provenance that is not a JSON object is embedded as a string. */
    wrt_gto_contents c = contents;
    c.provenance = "built by hand\n\"v2\"";
    if (wrt_gto_write(tpath("info_text.gto"), &c) == WRT_OK) {
        f = open_memstream(&text, &tn);
        wrt_gto_print_info(tpath("info_text.gto"), 1, f);
        fclose(f);
        CHECK(strstr(text, "\"provenance\": \"built by hand\\u000a\\\"v2\\\"\""), "escaped provenance: %s", text);
        free(text);
    }
    c.provenance = "{\"a\": [1, 2,]}";
    if (wrt_gto_write(tpath("info_text.gto"), &c) == WRT_OK) {
        f = open_memstream(&text, &tn);
        wrt_gto_print_info(tpath("info_text.gto"), 1, f);
        fclose(f);
        CHECK(strstr(text, "\"provenance\": \"{\\\"a\\\": [1, 2,]}\""), "malformed JSON quoted: %s", text);
        free(text);
    }

    /* A damaged file: the header and table still print, and the failure. */
    size_t n;
    uint8_t *b = read_all(p, &n);
    b[sec_off(b, S_VALS) + 5] ^= 0x40;
    write_raw(tpath("info_bad.gto"), b, n);
    free(b);
    f = open_memstream(&text, &tn);
    st = wrt_gto_print_info(tpath("info_bad.gto"), 0, f);
    fclose(f);
    CHECK(st == WRT_ERR_CORRUPT, "status %s", wrt_status_str(st));
    CHECK(strstr(text, "version 1.0") && strstr(text, "col_start"), "header of a damaged file: %s", text);
    CHECK(strstr(text, "integrity:  FAILED") && strstr(text, "section vals: checksum mismatch"), "failure: %s", text);
    free(text);
    f = open_memstream(&text, &tn);
    st = wrt_gto_print_info(tpath("info_bad.gto"), 1, f);
    fclose(f);
    CHECK(strstr(text, "\"ok\": false") && strstr(text, "\"status\": \"corrupt file\""), "json failure: %s", text);
    free(text);
}


/* ---- the first-bounce operator K (version 1.1) ---- */

static int write_good_k(const char *path) {
    wrt_status st = wrt_gto_write(path, &contents_k);
    CHECK(st == WRT_OK, "write K %s: %s", path, wrt_last_error());
    return st == WRT_OK;
}

static uint32_t rd32(const uint8_t *b, size_t o) { uint32_t x; memcpy(&x, b + o, 4); return x; }

/* Written with K: version 1.1, 15 sections, K read back exactly and 64-byte aligned;
 * the 11 sections of before are the same bytes as in the file without K. */
static void test_k_roundtrip(void) {
    build();
    int asc = 1;
    for (int j = 1; j < 5; j++) asc &= kkeys[j] > kkeys[j - 1];
    CHECK(asc, "test data: kkeys ascending");
    const char *p = tpath("k.gto"), *p0 = tpath("k0.gto");
    if (!write_good_k(p) || !write_good(p0)) return;
    wrt_gto g;
    wrt_status st = wrt_gto_open(p, &g);
    CHECK(st == WRT_OK, "open K: %s", wrt_last_error());
    if (st != WRT_OK) return;
    CHECK(g.version == 1 && g.version_minor == 1, "version %u.%u, expected 1.1", g.version, g.version_minor);
    CHECK(g.nkcols == 5 && g.knnz == 9, "nkcols %u knnz %llu", g.nkcols, (unsigned long long)g.knnz);
    CHECK(g.kkeys && memcmp(g.kkeys, kkeys, 5 * 8) == 0, "kkeys");
    CHECK(g.kcol_start && memcmp(g.kcol_start, kcol_start, 6 * 8) == 0, "kcol_start");
    CHECK(g.krows && memcmp(g.krows, krows, 9 * 4) == 0, "krows");
    CHECK(g.kvals && memcmp(g.kvals, kvals, 9 * 4) == 0, "kvals");
    const void *kp[] = {g.kkeys, g.kcol_start, g.krows, g.kvals};
    int al = 1;
    for (int i = 0; i < 4; i++) al &= ((uintptr_t)kp[i] % 64) == 0;
    CHECK(al, "K sections 64-byte aligned in the mapping");
    CHECK(g.nfuncs == 7 && g.nnz == 12 && memcmp(g.vals, vals, 12 * 12) == 0 && g.nquads == 3, "the rest as before");
    wrt_gto_close(&g);
    /* Bytes: the table has 15 entries with ids 12..15 last; each old section's payload
     * is the same as in the file without K. */
    size_t n, n0;
    uint8_t *b = read_all(p, &n), *b0 = read_all(p0, &n0);
    CHECK(rd32(b, 28) == F_NSEC_K && rd32(b0, 28) == F_NSEC, "nsections %u and %u", rd32(b, 28), rd32(b0, 28));
    CHECK(b[14] == 1 && b[15] == 0 && b0[14] == 0 && b0[15] == 0, "minor version bytes 1 (K) and 0 (none)");
    int ids = 1;
    for (int s = 0; s < F_NSEC_K; s++) ids &= rd32(b, entry(s)) == (uint32_t)(s + 1);
    CHECK(ids, "ids 1..15 in order");
    CHECK(rd64(b, entry(S_KKEYS) + F_E_COUNT) == 5 && rd64(b, entry(S_KCOL_START) + F_E_COUNT) == 6 &&
          rd64(b, entry(S_KROWS) + F_E_COUNT) == 9 && rd64(b, entry(S_KVALS) + F_E_COUNT) == 9, "K counts in the table");
    CHECK(rd32(b, entry(S_KKEYS) + 4) == 8 && rd32(b, entry(S_KCOL_START) + 4) == 8 &&
          rd32(b, entry(S_KROWS) + 4) == 4 && rd32(b, entry(S_KVALS) + 4) == 4, "K element sizes 8, 8, 4, 4");
    int same = 1;
    for (int s = 0; s < F_NSEC; s++)
        same &= sec_size(b, s) == sec_size(b0, s) && memcmp(b + sec_off(b, s), b0 + sec_off(b0, s), sec_size(b, s)) == 0;
    CHECK(same, "old sections' payloads unchanged by K");
    CHECK(rd64(b, F_FILE_SIZE) == n && sec_off(b, S_KVALS) + sec_size(b, S_KVALS) == n, "K ends the file");
    free(b); free(b0);

    /* A column set with no entries at all (knnz 0) is valid. */
    wrt_gto_contents c = contents_k;
    static const uint64_t zeros6[6];
    c.kcol_start = zeros6; c.krows = NULL; c.kvals = NULL;
    st = wrt_gto_write(tpath("k_empty.gto"), &c);
    CHECK(st == WRT_OK, "K without entries: %s", wrt_last_error());
    st = wrt_gto_open(tpath("k_empty.gto"), &g);
    CHECK(st == WRT_OK && g.nkcols == 5 && g.knnz == 0, "open K without entries: %s", wrt_last_error());
    wrt_gto_close(&g);

    /* The four sections renumbered to ids this reader does not know (a later minor's):
     * placed, checksummed and ignored; the file reads as one without K. */
    b = read_all(p, &n);
    for (int s = S_KKEYS; s <= S_KVALS; s++) { uint32_t id = (uint32_t)(s + 1 + 10); memcpy(b + entry(s), &id, 4); }
    fix_header_sum(b);
    st = open_copy(b, n, &g);
    CHECK(st == WRT_OK && g.nkcols == 0 && g.kkeys == NULL, "unknown ids ignored: %s", wrt_last_error());
    free(b);
}

/* A committed file with K: it opens and today's writer produces it byte for byte. */
static void test_k_golden(void) {
    build();
    wrt_gto g;
    wrt_status st = wrt_gto_open(golden_k_path, &g);
    CHECK(st == WRT_OK, "golden K file: %s", wrt_last_error());
    if (st == WRT_OK) {
        CHECK(g.version_minor == 1 && g.nkcols == 5 && g.knnz == 9 && g.nfuncs == 7, "golden K counts");
        wrt_gto_close(&g);
    }
    writer_reproduces(golden_k_path, "golden_k_now.gto", write_good_k);
}

/* Each K section: a flipped byte is its checksum error, every flip anywhere is caught,
 * every prefix is "truncated". */
static void test_k_damaged(void) {
    size_t n;
    uint8_t *b = written("k_flip.gto", write_good_k, &n);
    if (!b) return;
    wrt_gto g;
    for (int s = S_KKEYS; s <= S_KVALS; s++) {
        size_t o = sec_off(b, s) + sec_size(b, s) / 2;
        b[o] ^= 0x10;
        char want[64], what[64];
        snprintf(want, sizeof want, "section %s: checksum mismatch", k_sec_names[s - S_KKEYS]);
        snprintf(what, sizeof what, "flip in %s", k_sec_names[s - S_KKEYS]);
        expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, want, what);
        b[o] ^= 0x10;
    }
    int undetected = 0, not_trunc = 0;
    for (size_t o = 0; o < n; o++) {
        b[o] ^= 0x01;
        undetected += open_copy(b, n, &g) == WRT_OK;
        b[o] ^= 0x01;
    }
    for (size_t len = 1; len < n; len++)
        not_trunc += open_copy(b, len, &g) != WRT_ERR_CORRUPT || !strstr(wrt_last_error(), "truncated");
    CHECK(undetected == 0, "%d flipped bytes of a K file went unnoticed", undetected);
    CHECK(not_trunc == 0, "%d prefixes of a K file not reported truncated", not_trunc);
    CHECK(open_copy(b, n, &g) == WRT_OK, "restored: %s", wrt_last_error());
    free(b);
}

/* Builds a version-1.1 file from a file without K by the layout of GTO_FORMAT.md alone:
 * the table grows by four entries (192 bytes, so every old payload moves by 192 and
 * stays 64-byte aligned) and the K payloads follow, each at the next multiple of 64. */
static uint8_t *append_k(const uint8_t *b, size_t n, const void *const data[4], const uint64_t count[4], size_t *outn) {
    static const uint32_t es[4] = {8, 8, 4, 4};
    const size_t shift = 4 * F_ENTRY, head = F_HEADER + F_NSEC_K * F_ENTRY;
    uint64_t off[4], end = n + shift;
    for (int i = 0; i < 4; i++) {
        off[i] = (end + 63) / 64 * 64;
        end = off[i] + count[i] * es[i];
    }
    uint8_t *c = calloc(end, 1);
    memcpy(c, b, F_HEADER + F_NSEC * F_ENTRY);
    memcpy(c + sec_off(b, 0) + shift, b + sec_off(b, 0), n - sec_off(b, 0));
    uint32_t ns = F_NSEC_K, hs = (uint32_t)head;
    memcpy(c + 28, &ns, 4);
    memcpy(c + 24, &hs, 4);
    c[14] = 1; c[15] = 0; /* minor 1 */
    wr64(c, F_FILE_SIZE, end);
    for (int s = 0; s < F_NSEC; s++) wr64(c, entry(s) + F_E_OFFSET, sec_off(b, s) + shift);
    for (int i = 0; i < 4; i++) {
        size_t e = entry(S_KKEYS + i);
        uint32_t id = (uint32_t)(S_KKEYS + i + 1);
        memcpy(c + e, &id, 4);
        memcpy(c + e + 4, &es[i], 4);
        wr64(c, e + F_E_OFFSET, off[i]);
        wr64(c, e + F_E_SIZE, count[i] * es[i]);
        wr64(c, e + F_E_COUNT, count[i]);
        if (count[i]) memcpy(c + off[i], data[i], count[i] * es[i]);
        fix_section_sum(c, S_KKEYS + i);
    }
    fix_header_sum(c);
    *outn = end;
    return c;
}

/* Shrinks section s of a copy by `by` elements (its count and size, the bytes freed
 * zeroed as padding), fixes the checksums and expects `want`. */
static void shrink_section(const uint8_t *b, size_t n, int s, uint64_t by, const char *want, const char *what) {
    uint8_t *c = malloc(n);
    memcpy(c, b, n);
    uint64_t cnt = rd64(c, entry(s) + F_E_COUNT), es = rd32(c, entry(s) + 4), sz = sec_size(c, s);
    memset(c + sec_off(c, s) + sz - by * es, 0, by * es);
    wr64(c, entry(s) + F_E_COUNT, cnt - by);
    wr64(c, entry(s) + F_E_SIZE, sz - by * es);
    fix_section_sum(c, s);
    fix_header_sum(c);
    wrt_gto g;
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, want, what);
    free(c);
}

/* Every reader check of K, each on a forged copy (checksums made right), with the
 * section and the index in the message. */
static void test_k_bad(void) {
    size_t n;
    uint8_t *b = written("k_bad.gto", write_good_k, &n);
    if (!b) return;
    uint8_t *c = malloc(n);
    wrt_gto g;
    /* All four or none: kvals renumbered to an unknown id (100: below 256, skipped). */
    memcpy(c, b, n);
    uint32_t id17 = 100;
    memcpy(c + entry(S_KVALS), &id17, 4);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "missing section kvals (the first-bounce sections", "kvals missing");
    memcpy(c, b, n);
    uint32_t ids[3] = {100, 101, 102}; /* unknown ids (18 is the corner normals) */
    for (int i = 0; i < 3; i++) memcpy(c + entry(S_KCOL_START + i), &ids[i], 4);
    fix_header_sum(c);
    expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "missing section kcol_start", "only kkeys");
    /* Counts across the K sections. */
    shrink_section(b, n, S_KKEYS, 1, "section kcol_start: 6 entries, expected 5 (K's columns + 1)", "kcol_start count");
    shrink_section(b, n, S_KROWS, 1, "section kvals: 9 entries, krows has 8", "kvals count");
    /* K built by hand from the file without K: the writer's bytes exactly; then with no
     * columns at all (kcol_start = {0}), which the writer never makes. */
    {
        size_t n0, nk;
        if (!write_good(tpath("k_base.gto"))) return;
        uint8_t *b0 = read_all(tpath("k_base.gto"), &n0);
        const void *data[4] = {kkeys, kcol_start, krows, kvals};
        uint64_t cnt[4] = {5, 6, 9, 9};
        uint8_t *m = append_k(b0, n0, data, cnt, &nk);
        CHECK(nk == n && memcmp(m, b, n) == 0, "K appended by the documented layout differs from the writer's file");
        free(m);
        uint64_t none[4] = {0, 1, 0, 0};
        m = append_k(b0, n0, data, none, &nk);
        expect(open_copy(m, nk, &g), WRT_ERR_CORRUPT, "section kkeys: 0 columns", "no columns");
        free(m); free(b0);
    }
    /* kkeys. */
    wrt_node r = wrt_node_root(), bad_grid = {1, 2, 0}, l11 = {11, 0, 0};
    uint64_t k;
    corrupt_index(b, n, S_KKEYS, 8 * 1, &kkeys[0], 8, "section kkeys: kkeys not strictly ascending at index 1", "kkeys repeated");
    k = wrt_fkey_make(3, r, 0, r, 0);
    corrupt_index(b, n, S_KKEYS, 8 * 4, &k, 8, "section kkeys: kkeys[4] names quad 3, but there are 3 quads", "kkeys quad");
    k = wrt_fkey_make(0, r, 0, r, 0);
    corrupt_index(b, n, S_KKEYS, 0, &k, 8, "section kkeys: kkeys[0] names quad 0, whose material 0 is Lambertian", "kkeys Lambertian");
    k = wrt_fkey_make(2, l11, 1, r, 0);
    corrupt_index(b, n, S_KKEYS, 8 * 4, &k, 8, "section kkeys: kkeys[4]: spatial level 11, at most 10", "kkeys spatial level");
    k = wrt_fkey_make(2, wrt_node_child(r, 1, 1), 0, r, 0);
    corrupt_index(b, n, S_KKEYS, 8 * 4, &k, 8, "kkeys[4]: malformed key", "kkeys type 0 off the root");
    CHECK(strstr(wrt_last_error(), "spatial scaling function (type 0) on a non-root node"), "%s", wrt_last_error());
    k = wrt_fkey_make(2, bad_grid, 1, r, 0);
    corrupt_index(b, n, S_KKEYS, 8 * 4, &k, 8, "kkeys[4]: malformed key", "kkeys node off the grid");
    CHECK(strstr(wrt_last_error(), "spatial node outside its level's grid"), "%s", wrt_last_error());
    k = wrt_fkey_make(1, r, 0, r, 1) + 32 + 1;
    corrupt_index(b, n, S_KKEYS, 8 * 1, &k, 8, "kkeys[1]: malformed key", "kkeys spare bits");
    CHECK(strstr(wrt_last_error(), "spare bits not zero"), "%s", wrt_last_error());
    k = wrt_fkey_make(1, r, 0, wrt_node_child(r, 0, 1), 0);
    corrupt_index(b, n, S_KKEYS, 8 * 2, &k, 8, "kkeys[2]: malformed key", "kkeys angular type 0 off the root");
    CHECK(strstr(wrt_last_error(), "angular scaling function"), "%s", wrt_last_error());
    /* kcol_start (0, 3, 3, 5, 8, 9). */
    uint64_t five = 5, one = 1, eight = 8;
    corrupt_index(b, n, S_KCOL_START, 0, &five, 8, "section kcol_start: kcol_start[0] is 5, not 0", "kcol_start start");
    corrupt_index(b, n, S_KCOL_START, 8 * 2, &one, 8, "section kcol_start: kcol_start not monotone at column 2 (1 after 3)", "kcol_start decreasing");
    corrupt_index(b, n, S_KCOL_START, 8 * 5, &eight, 8, "section kcol_start: kcol_start[5] is 8, but there are 9 entries", "kcol_start end");
    /* krows: column 0 (quad 1) holds 0, 2, 5; column 2 (quad 1) entries 3, 4 hold 1, 6. */
    uint32_t r7 = 7, r0 = 0, r4 = 4;
    corrupt_index(b, n, S_KROWS, 0, &r7, 4, "section krows: krows[0] = 7 out of range (7 functions) in column 0", "krows range");
    corrupt_index(b, n, S_KROWS, 4 * 1, &r0, 4, "section krows: krows not strictly ascending in column 0 at entry 1", "krows unsorted");
    corrupt_index(b, n, S_KROWS, 4 * 1, &r4, 4, "section krows: krows[1] = 4 in column 0 is a function of quad 1, the column's own quad", "krows own quad");
    uint32_t r5 = 5;
    corrupt_index(b, n, S_KROWS, 4 * 7, &r5, 4, "section krows: krows[7] = 5 in column 3 is a function of quad 2, the column's own quad", "krows own quad 2");
    /* kvals. */
    float fnan = NAN, finf = -INFINITY;
    corrupt_index(b, n, S_KVALS, 4 * 3, &fnan, 4, "section kvals: kvals[3] is NaN", "kvals NaN");
    corrupt_index(b, n, S_KVALS, 4 * 8, &finf, 4, "section kvals: kvals[8] is infinite", "kvals infinite");
    free(b); free(c);
}

/* The writer refuses K contents the reader would refuse; no file appears. */
static void test_k_write_errors(void) {
    build();
    const char *q = tpath("k_refused.gto");
    wrt_gto_contents c = contents_k;
    uint64_t k2[5];
    memcpy(k2, kkeys, sizeof k2);
    uint64_t t = k2[0]; k2[0] = k2[1]; k2[1] = t;
    c.kkeys = k2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "kkeys: kkeys not strictly ascending at index 1", "unsorted kkeys");
    memcpy(k2, kkeys, sizeof k2);
    k2[0] = wrt_fkey_make(0, wrt_node_root(), 1, wrt_node_root(), 0);
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "whose material 0 is Lambertian", "K on a Lambertian quad");
    c = contents_k;
    uint32_t r2[9];
    memcpy(r2, krows, sizeof r2);
    r2[2] = 4;
    c.krows = r2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "the column's own quad", "own-quad row");
    c = contents_k;
    float v2[9];
    memcpy(v2, kvals, sizeof v2);
    v2[6] = NAN;
    c.kvals = v2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "kvals[6] is NaN", "NaN kval");
    c = contents_k;
    uint64_t cs2[6];
    memcpy(cs2, kcol_start, sizeof cs2);
    cs2[0] = 1;
    c.kcol_start = cs2;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "kcol_start[0] is 1, not 0", "kcol_start start");
    c = contents_k;
    c.kkeys = NULL;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "K has 5 columns but no kkeys", "no kkeys");
    c = contents_k;
    c.kvals = NULL;
    expect(wrt_gto_write(q, &c), WRT_ERR_INVALID_ARG, "K has 9 entries but no krows or kvals", "no kvals");
    /* K's key check needs the quads' materials: a material out of range is found first. */
    quads[1].material = 5;
    expect(wrt_gto_write(q, &contents_k), WRT_ERR_INVALID_ARG, "material 5 out of range", "material");
    quads[1].material = 1;
    struct stat sb;
    CHECK(stat(q, &sb) != 0, "refused write left a file");
    CHECK(count_tmp_files(tmpdir) == 0, "temporaries left behind");
}

/* K's checks at the 8192-element chunk boundaries: a column of 10000 entries and 10000
 * keys, each fault just after (or at) the boundary. */
static void test_k_chunk_boundaries(void) {
    build();
    uint32_t nf = 20001, nk = 10000;
    uint64_t knz = 10000;
    uint64_t *f = malloc(nf * 8), *cs = calloc(nf + 1, 8), *kk = malloc(nk * 8), *kc = malloc((nk + 1) * 8);
    uint32_t *kr = malloc(knz * 4);
    float *kv = malloc(knz * 4);
    /* 20000 functions of quad 0 (Lambertian), then quad 1's root. */
    for (uint32_t i = 0; i < nf - 1; i++) f[i] = wrt_fkey_make(0, wrt_node_root(), 0, wrt_node_root(), 0) + ((uint64_t)i << 6);
    f[nf - 1] = wrt_fkey_make(1, wrt_node_root(), 0, wrt_node_root(), 0);
    /* K's columns: type-1 wavelets of level-7 nodes of quad 1, row by row. */
    for (uint32_t j = 0; j < nk; j++) {
        wrt_node s = {7, (uint16_t)(j % 128), (uint16_t)(j / 128)};
        kk[j] = wrt_fkey_make(1, s, 1, wrt_node_root(), 0);
    }
    kc[0] = 0;
    for (uint32_t j = 1; j <= nk; j++) kc[j] = knz; /* column 0 holds everything */
    for (uint64_t e = 0; e < knz; e++) { kr[e] = (uint32_t)(2 * e); kv[e] = 0.25f; }
    wrt_gto_contents c = contents;
    c.fkeys = f; c.nfuncs = nf; c.col_start = cs; c.rows = NULL; c.vals = NULL;
    c.nkcols = nk; c.kkeys = kk; c.kcol_start = kc; c.krows = kr; c.kvals = kv;
    const char *p = tpath("k_chunks.gto");
    if (wrt_gto_write(p, &c) != WRT_OK) { CHECK(0, "write: %s", wrt_last_error()); goto out; }
    size_t n;
    uint8_t *b = read_all(p, &n);
    wrt_gto g;
    CHECK(open_copy(b, n, &g) == WRT_OK && g.nkcols == nk && g.knnz == knz, "open: %s", wrt_last_error());
    uint32_t same = 2 * 8191, big = 2 * 20001, own = nf - 1;
    corrupt_index(b, n, S_KROWS, 4 * 8192, &same, 4, "krows not strictly ascending in column 0 at entry 8192", "krows at boundary");
    corrupt_index(b, n, S_KROWS, 4 * 8191, &big, 4, "krows[8191] = 40002 out of range", "krows before boundary");
    corrupt_index(b, n, S_KROWS, 4 * 9999, &own, 4, "krows[9999] = 20000 in column 0 is a function of quad 1", "krows own quad after boundary");
    corrupt_index(b, n, S_KKEYS, 8 * 8192, &kk[8191], 8, "kkeys not strictly ascending at index 8192", "kkeys at boundary");
    uint64_t less = knz - 1;
    corrupt_index(b, n, S_KCOL_START, 8 * 8192, &less, 8, "kcol_start not monotone at column 8192 (9999 after 10000)", "kcol_start at boundary");
    float nan = NAN;
    corrupt_index(b, n, S_KVALS, 4 * 8192, &nan, 4, "kvals[8192] is NaN", "kvals at boundary");
    free(b);
out:
    free(f); free(cs); free(kk); free(kc); free(kr); free(kv);
}

/* --info shows K's sections and counts; a file without K says so. */
static void test_k_print_info(void) {
    build();
    const char *p = tpath("k_info.gto"), *p0 = tpath("k0_info.gto");
    if (!write_good_k(p) || !write_good(p0)) return;
    char *text = NULL;
    size_t tn = 0;
    FILE *f = open_memstream(&text, &tn);
    wrt_status st = wrt_gto_print_info(p, 0, f);
    fclose(f);
    CHECK(st == WRT_OK, "info: %s", wrt_last_error());
    CHECK(strstr(text, "version 1.1 (older, read in full: later versions add 1.2 the optional source map, 1.3 the optional corner normals and textures, 2.0 the compact operator and critical sections)"),
          "version: %s", text);
    CHECK(strstr(text, "first bounce: K, 5 columns on 2 glossy quads, 9 entries"), "K line: %s", text);
    CHECK(strstr(text, "max 3; deepest level: spatial 1, angular node 1"), "K figures: %s", text);
    CHECK(strstr(text, "kkeys ") && strstr(text, "kcol_start ") && strstr(text, "krows ") && strstr(text, "kvals "),
          "K sections listed: %s", text);
    CHECK(strstr(text, "integrity:  ok"), "integrity: %s", text);
    free(text);
    f = open_memstream(&text, &tn);
    st = wrt_gto_print_info(p, 1, f);
    fclose(f);
    CHECK(st == WRT_OK && text[0] == '{' && text[tn - 2] == '}', "json object: %s", text);
    CHECK(strstr(text, "\"k_columns\": 5, \"k_entries\": 9"), "json K counts: %s", text);
    CHECK(strstr(text, "\"first_bounce\": {\"columns\": 5, \"entries\": 9"), "json first_bounce: %s", text);
    CHECK(strstr(text, "\"glossy_quads\": 2"), "json glossy quads: %s", text);
    CHECK(strstr(text, "\"name\": \"kkeys\"") && strstr(text, "\"name\": \"kvals\", \"offset\""), "json K sections: %s", text);
    CHECK(strstr(text, "\"version\": \"1.1\""), "json version: %s", text);
    free(text);
    f = open_memstream(&text, &tn);
    wrt_gto_print_info(p0, 0, f);
    fclose(f);
    CHECK(strstr(text, "version 1.0 (older, read in full: later versions add 1.1 the optional first-bounce "
                       "operator, 1.2 the optional source map, 1.3 the optional corner normals and textures, 2.0 the compact operator and critical sections)") && strstr(text, "first bounce: none") && !strstr(text, "kkeys"),
          "no K: %s", text);
    free(text);
    f = open_memstream(&text, &tn);
    wrt_gto_print_info(p0, 1, f);
    fclose(f);
    CHECK(strstr(text, "\"k_columns\": 0, \"k_entries\": 0") && strstr(text, "\"first_bounce\": null"), "json no K: %s", text);
    free(text);
    /* A K file damaged in krows: the failure names the section. */
    size_t n;
    uint8_t *b = read_all(p, &n);
    b[sec_off(b, S_KROWS) + 5] ^= 0x40;
    write_raw(tpath("k_info_bad.gto"), b, n);
    free(b);
    f = open_memstream(&text, &tn);
    st = wrt_gto_print_info(tpath("k_info_bad.gto"), 0, f);
    fclose(f);
    CHECK(st == WRT_ERR_CORRUPT && strstr(text, "integrity:  FAILED") && strstr(text, "section krows: checksum mismatch"),
          "K failure: %s", text);
    free(text);
}

/* ---- speed ---- */

static void test_open_speed(void) {
    build();
    /* ~48 MB operator: 4M entries on 65536 functions of one quad. */
    uint32_t nf = 65536;
    uint64_t nnz = 4u << 20;
    uint64_t *k = malloc(nf * 8), *cs = malloc((nf + 1) * 8);
    uint32_t *r = malloc(nnz * 4);
    float *v = malloc(nnz * 12);
    for (uint32_t i = 0; i < nf; i++) k[i] = wrt_fkey_make(1, wrt_node_root(), 0, wrt_node_root(), 0) + ((uint64_t)i << 6);
    uint64_t per = nnz / nf;
    for (uint32_t s = 0; s <= nf; s++) cs[s] = s * per;
    for (uint64_t e = 0; e < nnz; e++) r[e] = (uint32_t)((e % per) * (nf / per) + (e / per) % (nf / per));
    for (uint64_t e = 0; e < 3 * nnz; e++) v[e] = (float)(e % 1000) * 1e-4f;
    /* Keys of quad 1 must leave quads 0 and 2 empty. */
    wrt_gto_contents c = contents;
    c.fkeys = k; c.nfuncs = nf; c.col_start = cs; c.rows = r; c.vals = v;
    const char *p = tpath("big.gto");
    double t0 = wrt_now();
    wrt_status st = wrt_gto_write(p, &c);
    double tw = wrt_now() - t0;
    CHECK(st == WRT_OK, "big write: %s", wrt_last_error());
    if (st == WRT_OK) {
        wrt_gto g;
        double best = 1e9;
        for (int i = 0; i < 3; i++) {
            t0 = wrt_now();
            st = wrt_gto_open(p, &g);
            double t = wrt_now() - t0;
            if (t < best) best = t;
            CHECK(st == WRT_OK, "big open: %s", wrt_last_error());
            if (st == WRT_OK) {
                CHECK(g.nnz == nnz && g.quads[1].func_count == nf, "big counts");
                if (i < 2) wrt_gto_close(&g);
            }
        }
        size_t sz = g.size;
        wrt_gto_close(&g);
        uint8_t *mem = malloc(sz);
        FILE *f = fopen(p, "rb");
        CHECK(fread(mem, 1, sz, f) == sz, "read");
        fclose(f);
        double tm = 1e9;
        for (int i = 0; i < 3; i++) {
            t0 = wrt_now();
            st = wrt_gto_open_memory(mem, sz, &g);
            double t = wrt_now() - t0;
            if (t < tm) tm = t;
            CHECK(st == WRT_OK, "memory open");
        }
        printf("open of a %.1f MB file: %.1f ms (%.0f MB/s, mapping included); validation in memory %.1f ms "
               "(%.0f MB/s); write %.0f ms\n", sz / 1e6, best * 1e3, sz / best / 1e6, tm * 1e3, sz / tm / 1e6,
               tw * 1e3);
        free(mem);
    }
    unlink(p);
    free(k); free(cs); free(r); free(v);
}

/* ---- the quad-to-source map (version 1.2) ---- */

static int write_good_s(const char *path) {
    wrt_status st = wrt_gto_write(path, &contents_s);
    CHECK(st == WRT_OK, "write %s: %s", path, wrt_last_error());
    return st == WRT_OK;
}

/* Written from the scene's quads, read back field by field; version 1.2 with 12
 * sections; a file without the map (1.0, 1.1, or no_srcmap) has none. */
static void test_srcmap_roundtrip(void) {
    build();
    const char *p = tpath("s.gto");
    if (!write_good_s(p)) return;
    wrt_gto g;
    wrt_status st = wrt_gto_open(p, &g);
    CHECK(st == WRT_OK, "open: %s", wrt_last_error());
    if (st != WRT_OK) return;
    CHECK(g.version == 1 && g.version_minor == 2 && g.srcmap, "version %u.%u, map %p", g.version, g.version_minor,
          (const void *)g.srcmap);
    if (g.srcmap) {
        const wrt_gto_srcmap *m = g.srcmap;
        CHECK(m[0].node == 3 && m[0].mesh == 0 && m[0].prim == 2 && m[0].tri[0] == 4 && m[0].tri[1] == 1 &&
              m[0].kind == 0 && m[0].part == 0 && m[0].flags == WRT_GTO_SRC_UV && m[0].twin_of == -1 &&
              m[0].uv[2][1] == 0.25f && m[0].uv[3][0] == -1.5f && m[0].uv[3][1] == 1e3f,
              "quad 0: node %d mesh %d prim %d tri %d %d flags %u uv3 %g %g", m[0].node, m[0].mesh, m[0].prim,
              m[0].tri[0], m[0].tri[1], m[0].flags, m[0].uv[3][0], m[0].uv[3][1]);
        CHECK(m[1].node == 0 && m[1].mesh == 1 && m[1].tri[0] == 5 && m[1].tri[1] == -1 && m[1].kind == 1 &&
              m[1].part == 2 && m[1].flags == 0 && m[1].twin_of == -1 && m[1].uv[0][0] == 0,
              "quad 1: kind %u part %u flags %u twin_of %d", m[1].kind, m[1].part, m[1].flags, m[1].twin_of);
        CHECK(m[2].flags == WRT_GTO_SRC_TWIN && m[2].twin_of == 1 && m[2].part == 2,
              "quad 2: flags %u twin_of %d", m[2].flags, m[2].twin_of);
    }
    wrt_gto_close(&g);
    size_t n;
    uint8_t *b = read_all(p, &n);
    if (b) {
        CHECK(rd32(b, 28) == F_NSEC_S && b[14] == 2 && rd32(b, entry(S_SRCMAP)) == 16 &&
              rd32(b, entry(S_SRCMAP) + 4) == F_SRC_REC && rd64(b, entry(S_SRCMAP) + F_E_COUNT) == 3 &&
              sec_off(b, S_SRCMAP) + sec_size(b, S_SRCMAP) == n,
              "layout: %u sections, minor %u, srcmap id %u, %u-byte records", rd32(b, 28), b[14],
              rd32(b, entry(S_SRCMAP)), rd32(b, entry(S_SRCMAP) + 4));
        free(b);
    }
    const char *olds[2] = {golden_path, golden_k_path};
    for (int i = 0; i < 2; i++) {
        st = wrt_gto_open(olds[i], &g);
        CHECK(st == WRT_OK && g.srcmap == NULL && g.version_minor == (uint32_t)i, "%s opens without a map: %s",
              olds[i], st == WRT_OK ? "ok" : wrt_last_error());
        if (st == WRT_OK) wrt_gto_close(&g);
    }
}

static void test_srcmap_golden(void) {
    build();
    wrt_gto g;
    wrt_status st = wrt_gto_open(golden_s_path, &g);
    CHECK(st == WRT_OK && g.srcmap && g.srcmap[2].twin_of == 1, "golden 1.2 file: %s",
          st == WRT_OK ? "ok" : wrt_last_error());
    if (st == WRT_OK) wrt_gto_close(&g);
    writer_reproduces(golden_s_path, "s_golden_now.gto", write_good_s);
}

/* Corner normals (version 1.3): a quad whose normals leave its plane makes the writer add
 * section 18, one record per quad (a quad without normals: its flat normal at all four
 * corners), read back as written; normals within half a degree of the plane (or none)
 * leave the file as before (1.2); a normal that is not unit is refused with its quad and
 * corner, and a flipped byte by the checksum. */
static int write_good_n(const char *path) {
    build();
    static wrt_quad nq[3];
    static wrt_scene ns;
    memcpy(nq, quads, sizeof nq);
    ns = scene;
    ns.quads = nq;
    nq[1].has_nrm = 1; /* quad 1 faces -z: tilt its corners' normals by 30 degrees outward */
    for (int k = 0; k < 4; k++) {
        wrt_v3 out = v3_norm(v3(nq[1].p[k].x - 0.5, nq[1].p[k].y - 0.5, 0));
        wrt_v3 n = v3_norm(v3_add(v3_scale(nq[1].n, cos(WRT_PI / 6)), v3_scale(out, sin(WRT_PI / 6))));
        nq[1].vn[k][0] = (float)n.x; nq[1].vn[k][1] = (float)n.y; nq[1].vn[k][2] = (float)n.z;
    }
    wrt_gto_contents c = contents_s;
    c.scene = &ns;
    wrt_status st = wrt_gto_write(path, &c);
    CHECK(st == WRT_OK, "write %s: %s", path, wrt_last_error());
    return st == WRT_OK;
}

static void test_normals(void) {
    size_t n;
    uint8_t *b = written("n.gto", write_good_n, &n);
    if (!b) return;
    wrt_gto g;
    wrt_status st = wrt_gto_open(tpath("n.gto"), &g);
    CHECK(st == WRT_OK, "open: %s", wrt_last_error());
    if (st != WRT_OK) { free(b); return; }
    CHECK(g.version == 1 && g.version_minor == 3 && g.normals && rd32(b, entry(S_SRCMAP + 1)) == 18 &&
              rd32(b, entry(S_SRCMAP + 1) + 4) == 48,
          "version %u.%u, normals %p, section id %u", g.version, g.version_minor, (const void *)g.normals,
          rd32(b, entry(S_SRCMAP + 1)));
    if (g.normals) {
        const float *a = g.normals[1].n[2], *f = g.normals[0].n[3];
        double c1 = -a[2]; /* quad 1's flat normal is -z */
        CHECK(fabs(c1 - cos(WRT_PI / 6)) < 1e-6 && f[0] == quads[0].n.x && f[1] == (float)quads[0].n.y &&
                  f[2] == (float)quads[0].n.z,
              "quad 1 corner 2 at %g degrees from its plane's normal (30), quad 0 flat (%g %g %g)",
              acos(c1) * 180 / WRT_PI, f[0], f[1], f[2]);
    }
    wrt_gto_close(&g);
    for (size_t at = 0; at < sec_size(b, S_SRCMAP + 1); at += 29) {
        uint8_t *c = malloc(n);
        memcpy(c, b, n);
        c[sec_off(c, S_SRCMAP + 1) + at] ^= 0x10;
        expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "section normals: checksum mismatch", "normals byte flipped");
        free(c);
    }
    float two = 2.0f, nan = NAN;
    corrupt_index(b, n, S_SRCMAP + 1, 48 + 12 * 2, &two, 4, "normals[1]: corner 2 (2, ", "a normal of length 2");
    corrupt_index(b, n, S_SRCMAP + 1, 4, &nan, 4, "normals[0]: corner 0 (", "a NaN normal");
    free(b);
    /* normals a quarter of a degree off the plane: no section, the file of 1.2 */
    build();
    static wrt_quad fq[3];
    static wrt_scene fs;
    memcpy(fq, quads, sizeof fq);
    fs = scene;
    fs.quads = fq;
    fq[0].has_nrm = 1;
    for (int k = 0; k < 4; k++) {
        wrt_v3 m = v3_norm(v3_add(fq[0].n, v3_scale(fq[0].t, tan(0.25 * WRT_PI / 180))));
        fq[0].vn[k][0] = (float)m.x; fq[0].vn[k][1] = (float)m.y; fq[0].vn[k][2] = (float)m.z;
    }
    wrt_gto_contents c = contents_s;
    c.scene = &fs;
    st = wrt_gto_write(tpath("n_flat.gto"), &c);
    CHECK(st == WRT_OK, "write: %s", wrt_last_error());
    st = wrt_gto_open(tpath("n_flat.gto"), &g);
    CHECK(st == WRT_OK && g.version_minor == 2 && !g.normals, "normals 0.25 degrees off: version 1.%u, normals %p",
          g.version_minor, (const void *)g.normals);
    if (st == WRT_OK) wrt_gto_close(&g);
}

/* A damaged map is refused with the section and the quad named: a flipped byte (the
 * checksum), a count that is not one per quad, and each content check behind fixed-up
 * checksums. */
static void test_srcmap_bad(void) {
    size_t n;
    uint8_t *b = written("s_bad.gto", write_good_s, &n);
    if (!b) return;
    wrt_gto g;
    for (size_t at = 0; at < sec_size(b, S_SRCMAP); at += 37) {
        uint8_t *c = malloc(n);
        memcpy(c, b, n);
        c[sec_off(c, S_SRCMAP) + at] ^= 0x10;
        char what[64];
        snprintf(what, sizeof what, "srcmap byte %zu flipped", at);
        expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "section srcmap: checksum mismatch", what);
        free(c);
    }
    { /* one record short (the map ends the file, so the file is one record shorter) */
        uint8_t *c = malloc(n);
        memcpy(c, b, n);
        wr64(c, entry(S_SRCMAP) + F_E_COUNT, 2);
        wr64(c, entry(S_SRCMAP) + F_E_SIZE, 2 * F_SRC_REC);
        wr64(c, F_FILE_SIZE, n - F_SRC_REC);
        fix_section_sum(c, S_SRCMAP);
        fix_header_sum(c);
        expect(open_copy(c, n - F_SRC_REC, &g), WRT_ERR_CORRUPT, "section srcmap: 2 records, expected 3 (one per quad)",
               "a record short");
        free(c);
    }
    size_t r0 = 0, r1 = F_SRC_REC, r2 = 2 * F_SRC_REC;
    int32_t m2 = -2, big = 7, one = 1;
    uint32_t u2 = 2, u1 = 1, u8 = 8, twin = WRT_GTO_SRC_TWIN, nan_bits = 0x7fc00000u;
    float x = 0.5f;
    corrupt_index(b, n, S_SRCMAP, r0 + 4, &m2, 4, "srcmap[0]: negative index (node 3, mesh -2", "mesh -2");
    corrupt_index(b, n, S_SRCMAP, r1 + 20, &u2, 4, "srcmap[1]: unknown element kind 2", "kind 2");
    corrupt_index(b, n, S_SRCMAP, r1 + 24, &u8, 4, "srcmap[1]: part 8 of a triangle (0..2)", "part 8");
    corrupt_index(b, n, S_SRCMAP, r0 + 24, &u1, 4, "srcmap[0]: part 1 of a paired quad (0)", "pair part 1");
    corrupt_index(b, n, S_SRCMAP, r1 + 16, &big, 4, "srcmap[1]: a triangle's quad with a second triangle 7",
                  "triangle with tri[1]");
    corrupt_index(b, n, S_SRCMAP, r0 + 28, &u8, 4, "srcmap[0]: unknown flags 0x8", "flag bit 3");
    corrupt_index(b, n, S_SRCMAP, r0 + 36, &u1, 4, "reserved 1 not zero", "reserved");
    corrupt_index(b, n, S_SRCMAP, r2 + 32, &big, 4, "srcmap[2]: twin of quad 7, not an earlier quad", "twin_of 7");
    corrupt_index(b, n, S_SRCMAP, r2 + 32, &m2, 4, "srcmap[2]: twin of quad -2, not an earlier quad", "twin_of -2");
    int32_t two = 2;
    corrupt_index(b, n, S_SRCMAP, r2 + 32, &two, 4, "srcmap[2]: twin of quad 2, not an earlier quad", "own twin");
    corrupt_index(b, n, S_SRCMAP, r1 + 28, &twin, 4, "srcmap[1]: twin of quad -1", "twin flag without front");
    corrupt_index(b, n, S_SRCMAP, r0 + 32, &one, 4, "srcmap[0]: not a twin but twin_of 1 (expected -1)", "twin_of set");
    corrupt_index(b, n, S_SRCMAP, r2 + 12, &big, 4, "srcmap[2]: twin of quad 1, which comes from other triangles",
                  "twin from another triangle");
    corrupt_index(b, n, S_SRCMAP, r0 + 40 + 4 * 5, &nan_bits, 4, "srcmap[0]: uv of corner 2 not finite", "NaN uv");
    corrupt_index(b, n, S_SRCMAP, r1 + 40 + 4 * 7, &x, 4, "srcmap[1]: uv of corner 3 not zero without the uv flag",
                  "uv without flag");
    /* a twin whose front is a twin: quad 1 made a twin of quad 0 (same source as 0) first */
    {
        uint8_t *c = malloc(n);
        memcpy(c, b, n);
        memcpy(c + sec_off(c, S_SRCMAP) + r1, c + sec_off(c, S_SRCMAP) + r0, F_SRC_REC);
        uint32_t fl = WRT_GTO_SRC_TWIN;
        int32_t zero = 0;
        memcpy(c + sec_off(c, S_SRCMAP) + r1 + 28, &fl, 4);
        memcpy(c + sec_off(c, S_SRCMAP) + r1 + 32, &zero, 4);
        memset(c + sec_off(c, S_SRCMAP) + r1 + 40, 0, 32);
        fix_section_sum(c, S_SRCMAP);
        fix_header_sum(c);
        expect(open_copy(c, n, &g), WRT_ERR_CORRUPT, "srcmap[2]: twin of quad 1, itself a twin", "twin of a twin");
        free(c);
    }
    /* the writer refuses what the reader would */
    build();
    quads[1].kind = 5;
    expect(wrt_gto_write(tpath("s_refused.gto"), &contents_s), WRT_ERR_INVALID_ARG,
           "srcmap: srcmap[1]: unknown element kind 5", "writer: bad kind");
    build();
    quads[2].twin_of = 2;
    expect(wrt_gto_write(tpath("s_refused.gto"), &contents_s), WRT_ERR_INVALID_ARG,
           "srcmap[2]: twin of quad 2, not an earlier quad", "writer: own twin");
    /* truncated at every length: never a crash, always refused */
    int refused = 1;
    for (size_t len = 0; len < n; len++)
        refused &= open_copy(b, len, &g) != WRT_OK;
    CHECK(refused, "every truncation refused");
    free(b);
}

static int write_c(const char *path, int v2) {
    wrt_gto_contents c = contents;
    c.compact = 1;
    c.opcode_v2 = v2;
    wrt_status st = wrt_gto_write(path, &c);
    CHECK(st == WRT_OK, "write %s: %s", path, wrt_last_error());
    return st == WRT_OK;
}

/* The committed 2.0 file opens with the same operator as the 1.0 golden (rows exactly,
 * values within the encoding's step) and today's writer reproduces it. */
static int write_good_c(const char *path) { return write_c(path, 1); }
static int write_good_c3(const char *path) { return write_c(path, 0); }

static void test_c_golden(void) {
    build();
    wrt_gto g;
    wrt_status st = wrt_gto_open(golden_c_path, &g);
    CHECK(st == WRT_OK, "golden compact file: %s", wrt_last_error());
    if (st == WRT_OK) {
        CHECK(g.version == 2 && g.version_minor == 0 && g.nfuncs == 7 && g.nnz == 12 && !g.rows && g.op_codes,
              "golden compact counts");
        int ok = 1;
        wrt_gto_walk wk = wrt_gto_walk_at(&g, 0);
        for (uint64_t e = 0; e < g.nnz; e++) {
            float v[3];
            uint32_t row = wrt_gto_entry(&g, &wk, e, v);
            double m = fmax(fabs(vals[3 * e]), fmax(fabs(vals[3 * e + 1]), fabs(vals[3 * e + 2])));
            ok &= row == rows[e];
            for (int c = 0; c < 3; c++) ok &= fabs(v[c] - vals[3 * e + c]) <= m / 511;
        }
        CHECK(ok, "the golden compact file holds the operator of the 1.0 golden (within 1/511)");
        wrt_gto_close(&g);
    }
    writer_reproduces(golden_c_path, "golden_c_now.gto", write_good_c);
}

/* The committed 3.0 file (section opstream, no col_start) opens with the 2.0 golden's
 * operator to the bit: the same columns, rows and value bits, entry by entry; a 2.x
 * reader would refuse it by its major version; today's writer reproduces it. */
static void test_c3_golden(void) {
    build();
    wrt_gto g2, g3;
    wrt_status st2 = wrt_gto_open(golden_c_path, &g2), st3 = wrt_gto_open(golden_c3_path, &g3);
    CHECK(st2 == WRT_OK && st3 == WRT_OK, "golden compact files: %s", wrt_last_error());
    if (st2 == WRT_OK && st3 == WRT_OK) {
        CHECK(g3.version == 3 && g3.version_minor == 0 && g3.nfuncs == 7 && g3.nnz == 12 && !g3.rows && g3.op_codes &&
              g3.nblocks == g2.nblocks, "golden 3.0 counts: version %u.%u, %llu blocks", g3.version, g3.version_minor,
              (unsigned long long)g3.nblocks);
        int same = 1;
        for (uint32_t s = 0; s <= g3.nfuncs; s++) same &= g3.col_start[s] == g2.col_start[s];
        CHECK(same, "col_start rebuilt as the 2.0 file stores it");
        wrt_gto_walk w2 = wrt_gto_walk_at(&g2, 0), w3 = wrt_gto_walk_at(&g3, 0);
        for (uint64_t e = 0; e < g3.nnz; e++) {
            float v2[3], v3[3];
            uint32_t r2 = wrt_gto_entry(&g2, &w2, e, v2), r3 = wrt_gto_entry(&g3, &w3, e, v3);
            same &= r2 == r3 && r3 == rows[e];
            same &= memcmp(v2, v3, sizeof v2) == 0;
        }
        CHECK(same, "every entry's row and value bits as the 2.0 golden's");
    }
    wrt_gto_close(&g2);
    wrt_gto_close(&g3);
    size_t n;
    uint8_t *b = read_all(golden_c3_path, &n);
    CHECK(b && n > 16 && b[12] == 3 && b[13] == 0, "the 3.0 golden's header says major 3");
    free(b);
    writer_reproduces(golden_c3_path, "golden_c3_now.gto", write_good_c3);
}

static void regen(void) {
    build();
    mkdir("tests/data", 0777);
    mkdir("tests/data/gto", 0777);
    wrt_status st = wrt_gto_write(golden_path, &contents);
    printf("%s: %s\n", golden_path, st == WRT_OK ? "written" : wrt_last_error());
    st = wrt_gto_write(golden_k_path, &contents_k);
    printf("%s: %s\n", golden_k_path, st == WRT_OK ? "written" : wrt_last_error());
    st = wrt_gto_write(golden_s_path, &contents_s);
    printf("%s: %s\n", golden_s_path, st == WRT_OK ? "written" : wrt_last_error());
    printf("%s: %s\n", golden_c_path, write_good_c(golden_c_path) ? "written" : wrt_last_error());
    printf("%s: %s\n", golden_c3_path, write_good_c3(golden_c3_path) ? "written" : wrt_last_error());
}

int main(int argc, char **argv) {
    if (argc > 1 && strcmp(argv[1], "--regen") == 0) { regen(); return 0; }
    snprintf(tmpdir, sizeof tmpdir, "%s/wrt_test_gto.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    TEST_RUN(test_checksum);
    TEST_RUN(test_roundtrip);
    TEST_RUN(test_deterministic);
    TEST_RUN(test_golden);
    TEST_RUN(test_foreign);
    TEST_RUN(test_empty);
    TEST_RUN(test_truncated);
    TEST_RUN(test_flipped_bytes);
    TEST_RUN(test_versions);
    TEST_RUN(test_bad_offsets);
    TEST_RUN(test_bad_indices);
    TEST_RUN(test_bad_numbers);
    TEST_RUN(test_chunk_boundaries);
    TEST_RUN(test_write_errors);
    TEST_RUN(test_failed_write_keeps_target);
    TEST_RUN(test_signal_cleanup);
    TEST_RUN(test_pending);
    TEST_RUN(test_check_output);
    TEST_RUN(test_print_info);
    TEST_RUN(test_k_roundtrip);
    TEST_RUN(test_k_golden);
    TEST_RUN(test_c_golden);
    TEST_RUN(test_c3_golden);
    TEST_RUN(test_k_damaged);
    TEST_RUN(test_k_bad);
    TEST_RUN(test_k_write_errors);
    TEST_RUN(test_k_chunk_boundaries);
    TEST_RUN(test_k_print_info);
    TEST_RUN(test_srcmap_roundtrip);
    TEST_RUN(test_srcmap_golden);
    TEST_RUN(test_srcmap_bad);
    TEST_RUN(test_normals);
    TEST_RUN(test_open_speed);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_END();
}
