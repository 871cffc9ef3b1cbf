/* fuzz_gto.c: libFuzzer target for the .gto reader (formats/gto_read.c, gto_check.c). Each input is
 * validated twice from an exactly sized, 8-byte aligned heap copy (so AddressSanitizer
 * sees any read past the end): once as given, and once with every section checksum and
 * the header checksum made consistent, as a forger would (GTO_FORMAT.md, "Checksums"),
 * so that mutations reach the index and number checks behind the checksums instead of
 * stopping at them. A file that passes is then read in full, every array the reader
 * hands out, the way the player uses it, the first-bounce operator K included. Built
 * by `make fuzz`; the seeds are tests/data/fuzz_gto and tests/data/gto (which holds a
 * file with K, v1.1_k_small.gto, so that mutations reach K's checks, and a compact 2.0
 * file, v2.0_compact_small.gto, for the opcode section's, one with the compact K,
 * v2.0_kcode_small.gto, for section kcode's, and 3.0 files, v3.0_compact_small.gto and
 * v3.0_opstream_seed.gto (80 columns, blocks cut by both rules), for section opstream's:
 * its block starts, rows, bases and the col_start rebuilt from them). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/wrt_common.h"
#include "common/text.h"
#include "formats/gto.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Every message is safe for a terminal whatever the input's names (common/text.h): no
 * control byte, no C1 control, only valid UTF-8. A crash for the fuzzer if not. */
static void check_safe(const char *what, const char *msg) {
    const unsigned char *p = (const unsigned char *)msg;
    size_t len = strlen(msg);
    char unit[WRT_SAFE_UNIT_MAX];
    for (size_t i = 0, ulen; i < len;) {
        size_t n = wrt_text_safe_unit(p + i, len - i, 0, unit, &ulen);
        if (ulen != n || memcmp(unit, p + i, n) != 0) {
            fprintf(stderr, "fuzz: %s holds an unescaped byte 0x%02x at %zu: %s\n", what, p[i], i, msg);
            abort();
        }
        i += n;
    }
}

static void quiet(void *user, int level, const char *msg) {
    (void)level; (void)user;
    check_safe("a log message", msg);
}

static uint64_t rd64(const uint8_t *b, size_t o) { uint64_t x; memcpy(&x, b + o, 8); return x; }
static uint32_t rd32(const uint8_t *b, size_t o) { uint32_t x; memcpy(&x, b + o, 4); return x; }
static void wr64(uint8_t *b, size_t o, uint64_t x) { memcpy(b + o, &x, 8); }

/* Header 64 bytes; nsections (u32) at 28; table entries of 48 bytes from 64: offset at
 * +8, size at +16, checksum at +32; header checksum at 40 over [0, 64 + 48 n). */
static void forge_checksums(uint8_t *b, size_t n) {
    if (n < 64) return;
    uint32_t ns = rd32(b, 28);
    if (ns == 0 || ns > 64 || 64 + 48 * (size_t)ns > n) return;
    for (uint32_t i = 0; i < ns; i++) {
        size_t e = 64 + 48 * (size_t)i;
        uint64_t off = rd64(b, e + 8), sz = rd64(b, e + 16);
        if (off <= n && sz <= n - off) wr64(b, e + 32, wrt_gto_checksum(b + off, (size_t)sz));
    }
    wr64(b, 40, 0);
    wr64(b, 40, wrt_gto_checksum(b, 64 + 48 * (size_t)ns));
}

/* Reads every value handed out, so that a wrong pointer or count shows. */
static double touch(const wrt_gto *g) {
    double s = 0;
    for (uint32_t q = 0; q < g->nquads; q++) s += g->quads[q].p[3][2] + g->quads[q].area + g->quads[q].func_count;
    for (uint32_t m = 0; m < g->nmaterials; m++) s += g->materials[m].base_color[2] + strlen(g->materials[m].name);
    for (uint32_t l = 0; l < g->nlights; l++) s += g->lights[l].intensity + strlen(g->lights[l].name);
    for (uint32_t k = 0; k < g->nnames; k++) s += strlen(g->names[k]);
    s += g->camera->yfov + g->stats->energy_left;
    for (uint32_t f = 0; f < g->nfuncs; f++) {
        s += (double)g->fkeys[f];
        if (g->rows)
            for (uint64_t e = g->col_start[f]; e < g->col_start[f + 1]; e++)
                s += g->rows[e] + g->vals[3 * e] + g->vals[3 * e + 2];
    }
    /* The compact operator (2.0, 3.0): each column's entries decoded as the multiply
     * does, the rows looked up in fkeys (so a row out of range shows). */
    if (g->op_codes)
        for (uint32_t f = 0; f < g->nfuncs; f++) {
            wrt_gto_walk wk = wrt_gto_walk_at(g, f);
            for (uint64_t e = g->col_start[f]; e < g->col_start[f + 1]; e++) {
                float v[3];
                uint32_t row = wrt_gto_entry(g, &wk, e, v);
                s += (double)g->fkeys[row] + v[0] + v[2];
            }
        }
    for (size_t i = 0; i < g->provenance_len; i++) s += g->provenance[i];
    /* K: each column's key, its entries' rows looked up in fkeys, as the player does (the
     * compact section kcode decoded first, as the player does). */
    uint32_t *kr = g->knnz ? malloc(sizeof *kr * g->knnz) : NULL;
    float *kv = g->knnz ? malloc(sizeof *kv * g->knnz) : NULL;
    if (g->knnz && (!kr || !kv)) { free(kr); free(kv); return s; }
    wrt_gto_k_entries(g, kr, kv);
    for (uint32_t j = 0; j < g->nkcols; j++) {
        s += (double)g->kkeys[j];
        for (uint64_t e = g->kcol_start[j]; e < g->kcol_start[j + 1]; e++)
            s += (double)g->fkeys[kr[e]] + kv[e];
    }
    free(kr); free(kv);
    return s;
}

static volatile double sink;

static void check(const uint8_t *data, size_t size, int forge) {
    uint8_t *c = malloc(size ? size : 1);
    if (!c) return;
    if (size) memcpy(c, data, size);
    if (forge) forge_checksums(c, size);
    wrt_gto g;
    if (wrt_gto_open_memory(c, size, &g) == WRT_OK) {
        sink = touch(&g);
        wrt_gto_close(&g);
    } else {
        check_safe("the error", wrt_last_error());
    }
    free(c);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    wrt_log_set_sink(quiet, NULL);
    check(data, size, 0);
    check(data, size, 1);
    return 0;
}
