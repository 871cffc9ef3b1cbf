/* test_gto_compact.c: the compact operator of .gto versions 2.0 (section opcode) and 3.0
 * (section opstream; formats/gto_opcode.c, GTO_FORMAT.md "The compact operator") and the
 * version rules that came with them. A
 * synthetic operator over 1,025 functions (columns of up to 150 entries, row steps above
 * 255, values from 1e-6 to 1 of both signs) is written compact and read back: the rows
 * exactly, every value within its documented step, values that the encoding holds
 * exactly exactly, the blocks where the documented rule cuts them (counted here from
 * the rule, not from the encoder); the same contents give the same bytes. Damaged files
 * (truncated, flipped bytes) and forged ones (every check of the section behind made-right
 * checksums, each naming what is wrong) are refused; a critical section id (>= 256) is
 * refused naming it, an unknown id below 256 skipped. The 3.0 file of the same contents
 * decodes to the 2.0 file's operator to the bit, and its own damage and forgeries (a
 * block start lost or made up, a row past the last function, a block over 64 entries,
 * bcol, header, padding, version) are refused by name. `--seed FILE` writes the 3.0
 * fuzz seed. The layout is read from
 * GTO_FORMAT.md's description, independently of gto_layout.h. */
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

#define NF_MAX 1100
#define NNZ_MAX 60000
static wrt_quad quads[2];
static wrt_material mats[1];
static wrt_scene scene;
static uint64_t fkeys[NF_MAX], col_start[NF_MAX + 1];
static uint32_t rows[NNZ_MAX], nfuncs;
static float vals[NNZ_MAX * 3];
static wrt_gto_contents contents;
static char tmpdir[256];

static uint64_t lcg_state = 99;
static double lcg(void) {
    lcg_state = lcg_state * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(lcg_state >> 11) / 9007199254740992.0;
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static void set_quad(wrt_quad *q, double z) {
    memset(q, 0, sizeof *q);
    q->p[0] = v3(0, 0, z); q->p[1] = v3(1, 0, z); q->p[2] = v3(1, 1, z); q->p[3] = v3(0, 1, z);
    q->t = v3(1, 0, 0); q->n = v3(0, 0, z > 0 ? -1 : 1); q->b = v3_cross(q->n, q->t);
    q->area = 1; q->parallelogram = 1; q->name = -1;
}

/* Quad 0: every spatial Haar function to level 4 (1,024); quad 1: its scaling function.
 * Column 0: one entry that the encoding holds exactly; then columns of 0 to 150 entries,
 * rows ascending in steps of 1 to 400. */
static void build(void) {
    memset(&scene, 0, sizeof scene);
    set_quad(&quads[0], 0); set_quad(&quads[1], 1);
    memset(mats, 0, sizeof mats);
    snprintf(mats[0].name, 64, "white");
    mats[0].base_color[0] = mats[0].base_color[1] = mats[0].base_color[2] = 0.5f;
    mats[0].roughness = 1; mats[0].lambertian = 1;
    scene.quads = quads; scene.nquads = 2;
    scene.materials = mats; scene.nmaterials = 1;
    nfuncs = 0;
    wrt_node r = wrt_node_root();
    fkeys[nfuncs++] = wrt_fkey_make(0, r, 0, r, 0);
    for (int l = 0; l <= 4; l++)
        for (int y = 0; y < (1 << l); y++)
            for (int x = 0; x < (1 << l); x++)
                for (int t = 1; t <= 3; t++) {
                    wrt_node n = {(uint8_t)l, (uint16_t)x, (uint16_t)y};
                    fkeys[nfuncs++] = wrt_fkey_make(0, n, t, r, 0);
                }
    fkeys[nfuncs++] = wrt_fkey_make(1, r, 0, r, 0);
    qsort(fkeys, nfuncs, sizeof *fkeys, cmp_u64);
    uint64_t e = 0;
    col_start[0] = 0;
    rows[0] = 7; vals[0] = 0.375f; vals[1] = -0.5f; vals[2] = 0.25f; /* 192, -256, 128 times 2^-9 */
    col_start[1] = e = 1;
    for (uint32_t s = 1; s < nfuncs; s++) {
        int n = (int)(lcg() * 151);
        uint32_t row = (uint32_t)(lcg() * 50);
        for (int k = 0; k < n && row < nfuncs && e < NNZ_MAX; k++) {
            rows[e] = row;
            double mag = pow(10, -6 * lcg());
            for (int c = 0; c < 3; c++) vals[3 * e + c] = (float)(mag * (lcg() - 0.4) * (c == 2 && k % 7 == 0 ? 0 : 1));
            e++;
            row += 1 + (uint32_t)(lcg() < 0.05 ? 256 + lcg() * 150 : lcg() * 12);
        }
        col_start[s + 1] = e;
    }
    memset(&contents, 0, sizeof contents);
    contents.scene = &scene;
    contents.fkeys = fkeys; contents.nfuncs = nfuncs;
    contents.col_start = col_start; contents.rows = rows; contents.vals = vals;
    contents.provenance = "{}";
    contents.no_srcmap = 1;
    contents.compact = 1;
    contents.opcode_v2 = 1; /* the 2.0 section (opcode); the 3.0 tests below clear it */
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




/* Opens a copy of the image and closes it (the copy is gone after). */
static wrt_status open_copy(const uint8_t *b, size_t n, wrt_gto *g) {
    uint8_t *c = malloc(n ? n : 1);
    if (n) memcpy(c, b, n);
    wrt_status st = wrt_gto_open_memory(c, n, g);
    wrt_gto_close(g);
    free(c);
    return st;
}

static void expect(wrt_status got, wrt_status want, const char *substr, const char *what) {
    CHECK(got == want, "%s: status %s, expected %s (%s)", what, wrt_status_str(got), wrt_status_str(want),
          wrt_last_error());
    CHECK(strstr(wrt_last_error(), substr) != NULL, "%s: message '%s' lacks '%s'", what, wrt_last_error(), substr);
}

/* Where the opcode section's arrays are (GTO_FORMAT.md): header 64 bytes (codec u32,
 * block_max u32, nblocks u64, nnz u64), then bcol, blocks, codes, deltas, each from a
 * multiple of 64 of the payload. */
typedef struct opc { size_t sec, bcol, blocks, codes, deltas; uint64_t nblocks, nnz; } opc;
static size_t al64(size_t x) { return (x + 63) / 64 * 64; }
/* Section id's payload offset and its header's counts, then where its n arrays of
 * bytes[i] (in order after the 64-byte header, each at a multiple of 64 of the payload)
 * start: at[i]. */
static void arrays_at(const uint8_t *b, uint32_t id, size_t *sec, uint64_t *nblocks, uint64_t *nnz, int n,
                      const uint64_t *per_func_block_entry, size_t *at) {
    *sec = (size_t)rd64(b, entry_of(b, id) + 8);
    *nblocks = rd64(b, *sec + 8);
    *nnz = rd64(b, *sec + 16);
    size_t off = 64;
    for (int i = 0; i < n; i++) { /* bytes a function (+ 1), a block, an entry */
        const uint64_t *m = per_func_block_entry + 3 * i;
        at[i] = *sec + off;
        off = al64(off + m[0] * ((size_t)nfuncs + 1) + m[1] * *nblocks + m[2] * *nnz);
    }
}
static opc locate(const uint8_t *b) {
    opc o;
    static const uint64_t m[4][3] = {{4, 0, 0}, {0, 8, 0}, {0, 0, 4}, {0, 0, 1}};
    size_t at[4];
    arrays_at(b, 17, &o.sec, &o.nblocks, &o.nnz, 4, &m[0][0], at);
    o.bcol = at[0]; o.blocks = at[1]; o.codes = at[2]; o.deltas = at[3];
    return o;
}

/* Where the opstream section's arrays are (GTO_FORMAT.md): header 64 bytes, then bcol
 * (u32, nfuncs + 1), row0 (u32, nblocks), codes (u32, nnz), base (i8, nblocks), deltas
 * (u8, nnz), each from a multiple of 64 of the payload. */
typedef struct ops { size_t sec, bcol, row0, codes, base, deltas; uint64_t nblocks, nnz; } ops;
static ops locate3(const uint8_t *b) {
    ops o;
    static const uint64_t m[5][3] = {{4, 0, 0}, {0, 4, 0}, {0, 0, 4}, {0, 1, 0}, {0, 0, 1}};
    size_t at[5];
    arrays_at(b, 261, &o.sec, &o.nblocks, &o.nnz, 5, &m[0][0], at);
    o.bcol = at[0]; o.row0 = at[1]; o.codes = at[2]; o.base = at[3]; o.deltas = at[4];
    return o;
}

/* ---- round trip ---- */

/* The blocks by the documented rule: a column's entries from the first, a block ending
 * after 64 entries or before a row 256 or more past the previous one. */
static uint64_t blocks_by_rule(void) {
    uint64_t nb = 0;
    for (uint32_t s = 0; s < nfuncs; s++)
        for (uint64_t i = col_start[s], k = 0; i < col_start[s + 1]; i++, k++) {
            if (k == 64 || (i > col_start[s] && rows[i] - rows[i - 1] >= 256)) k = 0;
            nb += k == 0;
        }
    return nb;
}

static void test_roundtrip(void) {
    build();
    size_t n;
    uint8_t *b = written("c.gto", &n);
    if (!b) return;
    wrt_gto g;
    wrt_status st = wrt_gto_open(tpath("c.gto"), &g);
    CHECK(st == WRT_OK, "open: %s", wrt_last_error());
    if (st != WRT_OK) { free(b); return; }
    uint64_t nnz = col_start[nfuncs];
    CHECK(g.version == 2 && g.version_minor == 0, "version %u.%u", g.version, g.version_minor);
    CHECK(!g.rows && !g.vals && g.op_codes && g.nnz == nnz, "compact: %llu entries", (unsigned long long)g.nnz);
    CHECK(!entry_of(b, 8) && !entry_of(b, 9) && entry_of(b, 17), "sections rows and vals replaced by opcode");
    uint64_t nb = blocks_by_rule();
    CHECK(g.nblocks == nb, "%llu blocks, the rule cuts %llu", (unsigned long long)g.nblocks, (unsigned long long)nb);
    int rows_ok = 1;
    double worst = 0;
    uint64_t i = 0;
    for (uint32_t s = 0; s < nfuncs; s++) {
        CHECK(g.op_bcol[s] <= g.op_bcol[s + 1], "bcol ascends");
        for (uint32_t k = g.op_bcol[s]; k < g.op_bcol[s + 1]; k++) {
            uint32_t row = g.op_row0[k];
            uint64_t end = i + 1; /* the block: to the next delta 0 */
            while (end < col_start[s + 1] && g.op_deltas[end]) end++;
            double bm = 0;
            for (uint64_t j = i; j < end; j++)
                for (int c = 0; c < 3; c++) bm = fmax(bm, fabs(vals[3 * j + c]));
            for (; i < end; i++) {
                row += g.op_deltas[i];
                rows_ok &= row == rows[i];
                float v[3];
                wrt_gto_decode(g.op_codes[i], g.op_base[k], v);
                double m = fmax(fabs(vals[3 * i]), fmax(fabs(vals[3 * i + 1]), fabs(vals[3 * i + 2])));
                for (int c = 0; c < 3; c++) worst = fmax(worst, fabs(v[c] - vals[3 * i + c]) / fmax(m, bm / 8));
            }
        }
    }
    CHECK(i == nnz && rows_ok, "every row decoded exactly (%llu entries)", (unsigned long long)i);
    CHECK(worst <= 1.0 / 511 && worst > 1e-5, "values within half a step, 1/511 of max(entry, block / 8): worst %.3g",
          worst);
    float v0[3];
    wrt_gto_decode(g.op_codes[0], g.op_base[0], v0);
    CHECK(v0[0] == 0.375f && v0[1] == -0.5f && v0[2] == 0.25f, "exact values decode exactly: %g %g %g", v0[0], v0[1], v0[2]);
    printf("compact: %u functions, %llu entries, %llu blocks, section %llu bytes (%.2f an entry), file %zu bytes\n",
           nfuncs, (unsigned long long)nnz, (unsigned long long)g.nblocks,
           (unsigned long long)rd64(b, entry_of(b, 17) + 16), (double)rd64(b, entry_of(b, 17) + 16) / (double)nnz, n);
    wrt_gto_close(&g);
    size_t n2;
    uint8_t *b2 = written("c2.gto", &n2);
    CHECK(b2 && n2 == n && memcmp(b, b2, n) == 0, "the same contents give the same bytes");
    free(b2);
    /* float entries: version 1.0 still */
    contents.compact = 0;
    uint8_t *f = written("f.gto", &n2);
    CHECK(f && f[12] == 1 && f[14] == 0 && entry_of(f, 8) && !entry_of(f, 17), "float entries: a 1.0 file");
    contents.compact = 1;
    free(f); free(b);
}

/* ---- damage ---- */

/* Every truncation refused, and a flipped byte in each of the section's arrays (2.0's
 * opcode or 3.0's opstream) found by its checksum. */
static void damaged(int v2) {
    build();
    contents.opcode_v2 = v2;
    size_t n;
    uint8_t *b = written(v2 ? "d.gto" : "d3.gto", &n);
    if (!b) return;
    wrt_gto g;
    int refused = 0, tries = 0;
    for (size_t len = 0; len < n; len += 1 + len / 16, tries++) refused += open_copy(b, len, &g) != WRT_OK;
    CHECK(refused == tries, "every truncation refused (%d of %d)", refused, tries);
    size_t at[6];
    int na;
    if (v2) {
        opc o = locate(b);
        size_t a2[5] = {o.sec + 8, o.bcol + 40, o.blocks + 13, o.codes + 4 * 1000 + 2, o.deltas + 777};
        memcpy(at, a2, sizeof a2);
        na = 5;
    } else {
        ops o = locate3(b);
        size_t a3[6] = {o.sec + 8, o.bcol + 40, o.row0 + 13, o.codes + 4 * 1000 + 2, o.base + 7, o.deltas + 777};
        memcpy(at, a3, sizeof a3);
        na = 6;
    }
    for (int k = 0; k < na; k++) {
        b[at[k]] ^= 0x10;
        expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, v2 ? "section opcode: checksum mismatch"
                                                        : "section opstream: checksum mismatch", "flipped byte");
        b[at[k]] ^= 0x10;
    }
    CHECK(open_copy(b, n, &g) == WRT_OK, "the undamaged copy opens: %s", wrt_last_error());
    free(b);
}

static void test_truncated_and_flipped(void) { damaged(1); }

/* One forged change (then the checksums made right): refused with `msg`. */
static void forged(const uint8_t *b, size_t n, size_t at, const void *val, size_t len, wrt_status want,
                   const char *msg, const char *what) {
    uint8_t *c = malloc(n);
    memcpy(c, b, n);
    memcpy(c + at, val, len);
    forge(c);
    wrt_gto g;
    expect(open_copy(c, n, &g), want, msg, what);
    free(c);
}

/* The forgeries both compact sections (opcode, opstream) answer alike: a mantissa -512,
 * bcol out of order or not ending at nblocks, another codec, one entry more in the
 * header, a padding byte, a block's first row not above the previous block's last in
 * its column (block k's row0 at row0 + stride k). */
static void forged_shared(const uint8_t *b, size_t n, size_t sec, size_t bcol, size_t codes, size_t row0, size_t stride,
                          size_t pad, uint64_t nblocks, uint64_t nnz, uint32_t wrong_codec) {
    uint32_t u32 = 0x200u << 10;
    uint64_t u64;
    uint8_t u8;
    char msg[64];
    forged(b, n, codes + 4 * 123, &u32, 4, WRT_ERR_CORRUPT, "entry 123 channel 1: mantissa -512", "mantissa -512");
    u32 = 0xffffffu; forged(b, n, bcol + 4 * 3, &u32, 4, WRT_ERR_CORRUPT, "bcol not monotone at column 4", "bcol");
    u32 = (uint32_t)nblocks + 1;
    forged(b, n, bcol + 4 * (size_t)nfuncs, &u32, 4, WRT_ERR_CORRUPT, "bcol runs from 0 to", "bcol end");
    snprintf(msg, sizeof msg, "unknown encoding %u", wrong_codec);
    forged(b, n, sec, &wrong_codec, 4, WRT_ERR_CORRUPT, msg, "codec");
    u64 = nnz + 1; forged(b, n, sec + 16, &u64, 8, WRT_ERR_CORRUPT, "do not hold the", "header's entry count");
    u8 = 1; forged(b, n, pad, &u8, 1, WRT_ERR_CORRUPT, "non-zero padding", "padding");
    for (uint32_t s = 0; s < nfuncs; s++) {
        uint32_t k0 = rd32(b, bcol + 4 * s), k1 = rd32(b, bcol + 4 * (s + 1));
        if (k1 - k0 < 2) continue;
        u32 = rd32(b, row0 + stride * k0);
        forged(b, n, row0 + stride * (k0 + 1), &u32, 4, WRT_ERR_CORRUPT, "not above the previous block's last",
               "rows across blocks");
        break;
    }
}

static void test_forged(void) {
    build();
    size_t n;
    uint8_t *b = written("x.gto", &n);
    if (!b) return;
    opc o = locate(b);
    /* block 5: its fields; the last block; entry codes and deltas */
    size_t b5 = o.blocks + 8 * 5, blast = o.blocks + 8 * (o.nblocks - 1);
    uint8_t u8;
    int16_t i16;
    uint32_t u32;
    u8 = 0; forged(b, n, b5 + 4, &u8, 1, WRT_ERR_CORRUPT, "block 5 (column", "block of 0 entries");
    u8 = 65; forged(b, n, b5 + 4, &u8, 1, WRT_ERR_CORRUPT, "65 entries (1..64)", "block of 65 entries");
    u8 = 1; forged(b, n, b5 + 5, &u8, 1, WRT_ERR_CORRUPT, "reserved byte 1", "reserved byte");
    i16 = 37; forged(b, n, b5 + 6, &i16, 2, WRT_ERR_CORRUPT, "base exponent 37 outside [-126, 36]", "base too large");
    i16 = -127; forged(b, n, b5 + 6, &i16, 2, WRT_ERR_CORRUPT, "base exponent -127 outside", "base too small");
    u32 = nfuncs; forged(b, n, blast, &u32, 4, WRT_ERR_CORRUPT, "out of range (1025 functions)", "row0 = nfuncs");
    /* the first entry of block 5 and the one after it */
    uint64_t e5 = 0;
    for (uint64_t k = 0; k < 5; k++) e5 += b[o.blocks + 8 * k + 4];
    u8 = 3; forged(b, n, o.deltas + e5, &u8, 1, WRT_ERR_CORRUPT, "on a block's first entry (must be 0)", "first delta");
    if (b[o.blocks + 8 * 5 + 4] > 1) {
        u8 = 0; forged(b, n, o.deltas + e5 + 1, &u8, 1, WRT_ERR_CORRUPT, "row delta 0, rows must ascend", "delta 0");
    }
    forged_shared(b, n, o.sec, o.bcol, o.codes, o.blocks, 8, o.codes - 1, o.nblocks, o.nnz, 2);
    /* one entry more in a block than its column has */
    u8 = (uint8_t)(b[blast + 4] + 1);
    if (u8 <= 64) forged(b, n, blast + 4, &u8, 1, WRT_ERR_CORRUPT, "hold", "block count against col_start");
    /* opcode in a 1.x file */
    u8 = 1; forged(b, n, 12, &u8, 1, WRT_ERR_CORRUPT, "section opcode in a version 1.0 file", "opcode in 1.0");
    free(b);
}


/* ---- version 3.0: section opstream ---- */

/* The same contents written as 2.0 (opcode, col_start) and 3.0 (opstream): the 3.0 file
 * is version 3.0 without sections 7 and 17, smaller by col_start and 3 bytes a block,
 * and decodes to the 2.0 file's operator to the bit: col_start, every entry's row and
 * value bits; the blocks are those the documented rule cuts. */
static void test_v3_same_entries(void) {
    build();
    size_t n2, n3;
    uint8_t *b2 = written("a2.gto", &n2);
    contents.opcode_v2 = 0;
    uint8_t *b3 = written("a3.gto", &n3);
    if (!b2 || !b3) { free(b2); free(b3); return; }
    CHECK(b3[12] == 3 && b3[14] == 0 && entry_of(b3, 261) && !entry_of(b3, 7) && !entry_of(b3, 17) &&
          !entry_of(b3, 8) && !entry_of(b3, 9), "3.0: opstream in place of col_start and opcode");
    wrt_gto g2, g3;
    wrt_status st2 = wrt_gto_open(tpath("a2.gto"), &g2), st3 = wrt_gto_open(tpath("a3.gto"), &g3);
    CHECK(st2 == WRT_OK && st3 == WRT_OK, "open: %s", wrt_last_error());
    if (st2 == WRT_OK && st3 == WRT_OK) {
        uint64_t nb = blocks_by_rule();
        CHECK(g3.version == 3 && g3.nnz == g2.nnz && g3.nblocks == nb && g2.nblocks == nb,
              "3.0: %llu entries, %llu blocks (the rule cuts %llu)", (unsigned long long)g3.nnz,
              (unsigned long long)g3.nblocks, (unsigned long long)nb);
        int same = 1;
        for (uint32_t s = 0; s <= nfuncs; s++) same &= g3.col_start[s] == col_start[s] && g2.col_start[s] == col_start[s];
        CHECK(same, "col_start rebuilt on load as written");
        uint64_t bad = 0;
        for (uint32_t s = 0; s < nfuncs; s++) {
            wrt_gto_walk w2 = wrt_gto_walk_at(&g2, s), w3 = wrt_gto_walk_at(&g3, s);
            for (uint64_t e = col_start[s]; e < col_start[s + 1]; e++) {
                float v2[3], v3[3];
                uint32_t r2 = wrt_gto_entry(&g2, &w2, e, v2), r3 = wrt_gto_entry(&g3, &w3, e, v3);
                bad += r2 != r3 || r3 != rows[e] || memcmp(v2, v3, sizeof v2) != 0;
            }
        }
        CHECK(bad == 0, "every entry's row and value bits as 2.0's (%llu differ)", (unsigned long long)bad);
        uint64_t saved = (uint64_t)8 * (nfuncs + 1) + 3 * nb;
        CHECK(n3 < n2 && n2 - n3 + 192 >= saved && n2 - n3 <= saved + 192,
              "3.0 is %zu bytes, 2.0 %zu: col_start and 3 bytes a block (%llu) within the padding", n3, n2,
              (unsigned long long)saved);
        printf("3.0: %zu bytes against 2.0's %zu (%llu blocks, %u columns)\n", n3, n2, (unsigned long long)nb, nfuncs);
    }
    wrt_gto_close(&g2);
    wrt_gto_close(&g3);
    size_t n4;
    uint8_t *b4 = written("a4.gto", &n4);
    CHECK(b4 && n4 == n3 && memcmp(b3, b4, n3) == 0, "the same contents give the same bytes");
    free(b2); free(b3); free(b4);
}

static void test_v3_damaged(void) { damaged(0); }

/* Entry index where block k starts (the k-th delta 0). */
static uint64_t block_entry(const uint8_t *b, const ops *o, uint64_t k) {
    for (uint64_t e = 0, z = 0; e < o->nnz; e++)
        if (b[o->deltas + e] == 0 && z++ == k) return e;
    return o->nnz;
}

static void test_v3_forged(void) {
    build();
    contents.opcode_v2 = 0;
    size_t n;
    uint8_t *b = written("x3.gto", &n);
    if (!b) return;
    ops o = locate3(b);
    uint8_t u8;
    int8_t i8;
    uint32_t u32;
    uint64_t u64;
    i8 = 37; forged(b, n, o.base + 5, &i8, 1, WRT_ERR_CORRUPT, "block 5 (column", "base too large");
    i8 = 37; forged(b, n, o.base + 5, &i8, 1, WRT_ERR_CORRUPT, "base exponent 37 outside [-126, 36]", "base too large");
    i8 = -127; forged(b, n, o.base + 5, &i8, 1, WRT_ERR_CORRUPT, "base exponent -127 outside", "base too small");
    u32 = nfuncs; forged(b, n, o.row0 + 4 * (o.nblocks - 1), &u32, 4, WRT_ERR_CORRUPT, "out of range (1025 functions)",
                         "last block's row0 = nfuncs");
    /* the last entry's delta raised: a row past the last function (the column's end) */
    u8 = 255; forged(b, n, o.deltas + o.nnz - 1, &u8, 1, WRT_ERR_CORRUPT, "out of range (1025 functions)", "row past the end");
    /* a block's start lost (its delta 0 made 3): the blocks no longer cover the entries */
    uint64_t e5 = block_entry(b, &o, 5);
    u8 = 3; forged(b, n, o.deltas + e5, &u8, 1, WRT_ERR_CORRUPT, "section opstream: ", "block start lost");
    /* a block start made up (a delta 0 inside a block): one block too many for bcol */
    u8 = 0;
    for (uint64_t e = 1; e < o.nnz; e++)
        if (b[o.deltas + e] && b[o.deltas + e - 1]) {
            forged(b, n, o.deltas + e, &u8, 1, WRT_ERR_CORRUPT, "section opstream: ", "block start made up");
            break;
        }
    /* the first entry's delta not 0 */
    u8 = 1; forged(b, n, o.deltas, &u8, 1, WRT_ERR_CORRUPT, "row delta 1 where block 0 starts (must be 0)", "first delta");
    /* two blocks of one column joined past 64 entries (the second's start made a step) */
    for (uint64_t k = 0; k + 1 < o.nblocks; k++) {
        uint64_t a = block_entry(b, &o, k), c = block_entry(b, &o, k + 1);
        uint32_t r1 = rd32(b, o.row0 + 4 * (size_t)(k + 1)), r0 = rd32(b, o.row0 + 4 * (size_t)k);
        if (c - a != 64) continue;
        uint32_t last = r0;
        for (uint64_t e = a + 1; e < c; e++) last += b[o.deltas + e];
        if (r1 <= last || r1 - last > 255) continue;
        u8 = (uint8_t)(r1 - last);
        forged(b, n, o.deltas + c, &u8, 1, WRT_ERR_CORRUPT, "entries (1..64)", "block of more than 64");
        break;
    }
    forged_shared(b, n, o.sec, o.bcol, o.codes, o.row0, 4, o.base - 1, o.nblocks, o.nnz, 1);
    u64 = o.nblocks - 64; forged(b, n, o.sec + 8, &u64, 8, WRT_ERR_CORRUPT, "do not hold the", "header's block count");
    /* opstream in a 2.0 file; beside col_start (section 7 renamed to it is not possible:
     * the ids must ascend, so the opstream entry is given id 17's place instead) */
    u8 = 2; forged(b, n, 12, &u8, 1, WRT_ERR_CORRUPT, "section opstream in a version 2.0 file (it needs version 3.0)",
                   "opstream in 2.0");
    free(b);
    /* beside col_start: a 2.0 file's opcode renamed opstream (ids still ascend), major 3 */
    contents.opcode_v2 = 1;
    b = written("y2.gto", &n);
    if (!b) return;
    u32 = 261;
    memcpy(b + entry_of(b, 17), &u32, 4);
    b[12] = 3;
    forge(b);
    wrt_gto g;
    expect(open_copy(b, n, &g), WRT_ERR_CORRUPT, "section opstream beside section col_start", "opstream beside col_start");
    free(b);
}


/* The reader's own arrays come from the caller's allocator when it gives one: a 3.0
 * file's rebuilt col_start (8 bytes a function), a 2.0 file's block rows and bases (5
 * bytes a block); close gives them back. */
static long n_alloc, n_free;
static size_t last_size;
static void *count_alloc(void *user, size_t n) { (void)user; n_alloc++; last_size = n; return malloc(n); }
static void count_free(void *user, void *p) { (void)user; if (p) n_free++; free(p); }
static void test_v3_allocator(void) {
    build();
    for (int v2 = 0; v2 <= 1; v2++) {
        contents.opcode_v2 = v2;
        size_t n;
        uint8_t *b = written("al.gto", &n);
        if (!b) return;
        wrt_gto g;
        n_alloc = n_free = 0;
        wrt_status st = wrt_gto_open_memory_alloc(b, n, count_alloc, count_free, NULL, &g);
        size_t want = v2 ? 5 * (size_t)g.nblocks : 8 * ((size_t)nfuncs + 1);
        CHECK(st == WRT_OK && n_alloc == 1 && last_size == want && g.owned, "%s: %ld allocation of %zu bytes (want %zu): %s",
              v2 ? "2.0" : "3.0", n_alloc, last_size, want, wrt_last_error());
        wrt_gto_close(&g);
        CHECK(n_free == 1, "%s: close gives it back (%ld frees)", v2 ? "2.0" : "3.0", n_free);
        /* a refused image gives back what the reader took */
        b[n - 1] ^= 1;
        n_alloc = n_free = 0;
        st = wrt_gto_open_memory_alloc(b, n, count_alloc, count_free, NULL, &g);
        CHECK(st == WRT_ERR_CORRUPT && n_alloc == n_free, "%s refused: %ld allocations, %ld frees", v2 ? "2.0" : "3.0",
              n_alloc, n_free);
        free(b);
    }
    wrt_gto g;
    CHECK(wrt_gto_open_memory_alloc(NULL, 0, count_alloc, NULL, NULL, &g) == WRT_ERR_INVALID_ARG, "alloc without free refused");
}

/* ---- version rules ---- */

static void test_critical(void) {
    build();
    size_t n;
    uint8_t *b = written("k.gto", &n);
    if (!b) return;
    uint32_t id = 258;
    forged(b, n, entry_of(b, 17), &id, 4, WRT_ERR_UNSUPPORTED, "section id 258 is critical (ids from 256 on must be understood) and unknown",
           "critical section");
    free(b);
    /* an unknown id below 256 is skipped: the source map renamed 200 in a float file */
    contents.compact = 0; contents.no_srcmap = 0;
    b = written("s.gto", &n);
    contents.compact = 1; contents.no_srcmap = 1;
    if (!b) return;
    id = 200;
    memcpy(b + entry_of(b, 16), &id, 4);
    forge(b);
    wrt_gto g;
    wrt_status st = open_copy(b, n, &g);
    CHECK(st == WRT_OK, "unknown section 200 skipped: %s", wrt_last_error());
    /* a newer major: refused naming both versions */
    b[12] = 4;
    forge(b);
    expect(open_copy(b, n, &g), WRT_ERR_UNSUPPORTED, "file version 4.2 is newer than this reader's version 3.0",
           "version 4");
    free(b);
}

/* The fuzz seed tests/data/gto/v3.0_opstream_seed.gto (`--seed FILE`): the operator of
 * build() with entries in its first 80 columns only (blocks cut by both rules, a few
 * thousand entries), as 3.0, small enough for the fuzzer's 64 KB inputs. */
static void write_seed(const char *path) {
    build();
    for (uint32_t s = 81; s <= nfuncs; s++) col_start[s] = col_start[80];
    contents.opcode_v2 = 0;
    wrt_status st = wrt_gto_write(path, &contents);
    printf("%s: %s\n", path, st == WRT_OK ? "written" : wrt_last_error());
}

int main(int argc, char **argv) {
    if (argc > 2 && strcmp(argv[1], "--seed") == 0) { write_seed(argv[2]); return 0; }
    snprintf(tmpdir, sizeof tmpdir, "%s/wrt_test_gto_compact.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) { perror("mkdtemp"); return 1; }
    TEST_RUN(test_roundtrip);
    TEST_RUN(test_truncated_and_flipped);
    TEST_RUN(test_forged);
    TEST_RUN(test_critical);
    TEST_RUN(test_v3_same_entries);
    TEST_RUN(test_v3_damaged);
    TEST_RUN(test_v3_forged);
    TEST_RUN(test_v3_allocator);
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", tmpdir);
    TEST_END();
}
