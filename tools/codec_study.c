/* codec_study.c: how compact can the operator's entries be (issue 23)? Reads a .gto
 * with float entries (version 1.x) and, for each candidate encoding of the values and of
 * the row indices, prints the bytes per entry and the quantization error against the
 * float operator: relative Frobenius over the whole operator and the largest relative
 * error of a column (|q - v| / |v| over the column's entries, RGB together). With
 * --write PREFIX it also writes, for each value encoding, PREFIX_NAME.gto: a copy of
 * the file whose float values are replaced by their quantized ones (checksums made
 * right), so that wrt-compare measures the encodings' cell and image error against one
 * path-traced reference (docs/bench.md, "Compact entries"). Blocks are those of the
 * file's encoding (formats/gto_encode.c): up to 64 entries of one column whose rows span
 * less than 65536. With --drop PREFIX SPEC... it studies which entries to store instead
 * (drop_study below; docs/bench.md, "Which entries are stored"); with --k PREFIX, how
 * compact K can be (k_study; docs/bench.md, "K compact"). Depends on formats/gto.h,
 * wrt_common (the checksum) and the bake's compression (precompute/sparse.h, balance.h's
 * power weights, drop_rule.h). */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/basis.h"
#include "common/wrt_common.h"
#include "formats/gto.h"
#include "precompute/balance.h"
#include "precompute/drop_rule.h"
#include "precompute/sparse.h"

#define BLOCK_MAX 64

typedef struct vcodec {
    const char *name, *what;
    int kind;              /* 0 float, 1 half, 2 per-block per-channel scale, 3 shared exponent */
    int bits;              /* kind 2: signed bits per channel; kind 3: signed mantissa bits */
    int ebits;             /* kind 3: exponent bits per entry (range 2^ebits above the block's base) */
    double bytes_entry;    /* value bytes per entry */
    double bytes_block;    /* value bytes per block */
} vcodec;

static const vcodec vcodecs[] = {
    {"f32", "float RGB (today)", 0, 0, 0, 12, 0},
    {"f16", "half-float RGB", 1, 0, 0, 6, 0},
    {"bs16", "int16 RGB, per-block per-channel scale", 2, 16, 0, 6, 12},
    {"bs10", "10-bit RGB in a u32, per-block per-channel scale", 2, 10, 0, 4, 12},
    {"bs8", "int8 RGB, per-block per-channel scale", 2, 8, 0, 3, 12},
    {"se9", "u32: 5-bit exponent + 3 x 9-bit signed mantissas, per-block base", 3, 9, 5, 4, 0},
    {"se10", "u32: 2-bit exponent + 3 x 10-bit signed mantissas, per-block base", 3, 10, 2, 4, 0},
    {"se7", "24 bits: 3-bit exponent + 3 x 7-bit signed mantissas, per-block base", 3, 7, 3, 3, 0},
};
#define NV (sizeof vcodecs / sizeof *vcodecs)

/* Round to the nearest half-float value (11 significant bits, subnormals below 2^-14,
 * saturated at 65504). */
static float to_half(float v) {
    double a = fabs(v);
    if (a == 0) return v;
    if (a > 65504) a = 65504;
    int e;
    frexp(a, &e); /* a = m 2^e, m in [0.5, 1) */
    int ulp_e = e - 11;
    if (ulp_e < -24) ulp_e = -24;
    double q = ldexp(nearbyint(ldexp(a, -ulp_e)), ulp_e);
    return (float)(v < 0 ? -q : q);
}

/* Quantizes the values of one block [a, b) of rows with codec c into out. */
static void quantize_block(const vcodec *c, const float *v, uint64_t a, uint64_t b, float *out) {
    if (c->kind == 0) { memcpy(out + a * 3, v + a * 3, (b - a) * 3 * sizeof *v); return; }
    if (c->kind == 1) { for (uint64_t i = a * 3; i < b * 3; i++) out[i] = to_half(v[i]); return; }
    double qmax = ldexp(1, c->bits - 1) - 1;
    if (c->kind == 2) {
        for (int ch = 0; ch < 3; ch++) {
            double m = 0;
            for (uint64_t i = a; i < b; i++) m = fmax(m, fabs(v[i * 3 + ch]));
            float s = (float)(m / qmax);
            for (uint64_t i = a; i < b; i++)
                out[i * 3 + ch] = s > 0 ? (float)(nearbyint(v[i * 3 + ch] / s) * s) : 0.0f;
        }
        return;
    }
    /* shared exponent: each entry's step 2^E with E the smallest that holds its largest
     * channel in qmax steps, at least the block's base (the largest E less the range) */
    int emax = -1000;
    for (uint64_t i = a; i < b; i++) {
        double m = fmax(fabs(v[i * 3]), fmax(fabs(v[i * 3 + 1]), fabs(v[i * 3 + 2])));
        if (m > 0) { int e = (int)ceil(log2(m / qmax)); if (ldexp(qmax, e) < m) e++; if (e > emax) emax = e; }
    }
    int base = emax - ((1 << c->ebits) - 1);
    for (uint64_t i = a; i < b; i++) {
        double m = fmax(fabs(v[i * 3]), fmax(fabs(v[i * 3 + 1]), fabs(v[i * 3 + 2])));
        int e = base;
        if (m > 0) { e = (int)ceil(log2(m / qmax)); if (ldexp(qmax, e) < m) e++; if (e < base) e = base; }
        for (int ch = 0; ch < 3; ch++) out[i * 3 + ch] = (float)ldexp(nearbyint(ldexp(v[i * 3 + ch], -e)), e);
    }
}

/* Calls fn on each block of the operator: column by column, up to BLOCK_MAX entries
 * whose rows span less than 65536. Returns the number of blocks. With d8, a block also
 * ends where a row is 256 or more past the previous (the u8-delta row encoding). */
static uint64_t for_blocks(const wrt_gto *g, int d8, const vcodec *c, float *out) {
    uint64_t nb = 0;
    for (uint32_t s = 0; s < g->nfuncs; s++) {
        uint64_t a = g->col_start[s], end = g->col_start[s + 1];
        while (a < end) {
            uint64_t b = a + 1;
            while (b < end && b - a < BLOCK_MAX && g->rows[b] - g->rows[a] < 65536 &&
                   (!d8 || g->rows[b] - g->rows[b - 1] < 256))
                b++;
            if (c) quantize_block(c, g->vals, a, b, out);
            nb++;
            a = b;
        }
    }
    return nb;
}

static void errors(const wrt_gto *g, const float *q, double *frob, double *colmax) {
    double num = 0, den = 0;
    *colmax = 0;
    for (uint32_t s = 0; s < g->nfuncs; s++) {
        double cn = 0, cd = 0;
        for (uint64_t i = g->col_start[s] * 3; i < g->col_start[s + 1] * 3; i++) {
            double d = (double)q[i] - g->vals[i];
            cn += d * d; cd += (double)g->vals[i] * g->vals[i];
        }
        num += cn; den += cd;
        if (cd > 0 && sqrt(cn / cd) > *colmax) *colmax = sqrt(cn / cd);
    }
    *frob = den > 0 ? sqrt(num / den) : 0;
}

static uint64_t rd64(const uint8_t *b, size_t o) { uint64_t x; memcpy(&x, b + o, 8); return x; }
static uint32_t rd32(const uint8_t *b, size_t o) { uint32_t x; memcpy(&x, b + o, 4); return x; }
static void wr64(uint8_t *b, size_t o, uint64_t x) { memcpy(b + o, &x, 8); }

/* A copy of the file with the values section (id 9, or K's values, 15) replaced by q, its
 * checksum and the header's recomputed (GTO_FORMAT.md: table entries of 48 bytes from
 * offset 64). */
static int write_copy_section(const wrt_gto *g, uint32_t id, const float *q, const char *path) {
    uint8_t *b = malloc(g->size);
    if (!b) return -1;
    memcpy(b, g->map, g->size);
    uint32_t ns = rd32(b, 28);
    for (uint32_t i = 0; i < ns; i++) {
        size_t e = 64 + 48 * (size_t)i;
        if (rd32(b, e) != id) continue;
        uint64_t off = rd64(b, e + 8), sz = rd64(b, e + 16);
        memcpy(b + off, q, sz);
        wr64(b, e + 32, wrt_gto_checksum(b + off, (size_t)sz));
    }
    wr64(b, 40, 0);
    wr64(b, 40, wrt_gto_checksum(b, 64 + 48 * (size_t)ns));
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(b, 1, g->size, f) == g->size;
    if (f && fclose(f) != 0) ok = 0;
    free(b);
    return ok ? 0 : -1;
}
static int write_copy(const wrt_gto *g, const float *q, const char *path) { return write_copy_section(g, 9, q, path); }

/* --k PREFIX: K's values (one channel; a file with float K, sections 14-15) quantized as
 * section kcode does (formats/gto_kcode.c: blocks of up to 64 entries of a column whose
 * rows step by less than 256, a base exponent per block, an entry's mantissa of B bits
 * with a 2-bit exponent above it), for B = 14 (the file's) and coarser; per B the bytes
 * an entry (mantissa and exponent, a u8 row delta, the blocks' 8 bytes and bcol's 4 a
 * column shared out), the relative Frobenius error of K and the largest relative error
 * of a column, and PREFIX_kB.gto: the file with K's values replaced, for wrt-compare. */
static int k_study(const wrt_gto *g, const char *prefix) {
    static const int bits[] = {14, 10, 8, 6, 4};
    uint64_t n = g->knnz, nb = 0;
    float *q = malloc((n + 1) * sizeof *q);
    if (!q) return 4;
    for (uint32_t j = 0; j < g->nkcols; j++)
        for (uint64_t a = g->kcol_start[j], b; a < g->kcol_start[j + 1]; a = b, nb++)
            for (b = a + 1; b < g->kcol_start[j + 1] && b - a < BLOCK_MAX && g->krows[b] - g->krows[b - 1] < 256;) b++;
    printf("%" PRIu64 " K entries, %u columns, %" PRIu64 " blocks; float K: 8 bytes an entry\n", n, g->nkcols, nb);
    printf("| mantissa bits | bytes an entry | K MB | rel. Frobenius | max column |\n|---|---|---|---|---|\n");
    for (size_t k = 0; k < sizeof bits / sizeof *bits; k++) {
        double mmax = exp2(bits[k] - 1) - 1, se = 0, sv = 0, colmax = 0;
        for (uint32_t j = 0; j < g->nkcols; j++) {
            double ce = 0, cv = 0;
            for (uint64_t a = g->kcol_start[j], b; a < g->kcol_start[j + 1]; a = b) {
                for (b = a + 1; b < g->kcol_start[j + 1] && b - a < BLOCK_MAX && g->krows[b] - g->krows[b - 1] < 256;) b++;
                int emax = -126;
                for (uint64_t i = a; i < b; i++)
                    if (g->kvals[i] != 0) emax = (int)fmax(emax, ceil(log2(fabs(g->kvals[i]) / mmax)));
                for (uint64_t i = a; i < b; i++) {
                    double v = g->kvals[i];
                    int e = v != 0 ? (int)ceil(log2(fabs(v) / mmax)) : emax - 3;
                    e = e < emax - 3 ? emax - 3 : e > emax ? emax : e;
                    q[i] = (float)ldexp(nearbyint(ldexp(v, -e)), e);
                    ce += (q[i] - v) * (q[i] - v);
                    cv += v * v;
                }
            }
            se += ce; sv += cv;
            if (cv > 0) colmax = fmax(colmax, sqrt(ce / cv));
        }
        double bpe = (bits[k] + 2) / 8.0 + 1 + (8.0 * nb + 4.0 * (g->nkcols + 1)) / (double)n;
        printf("| %d | %.2f | %.2f | %.2e | %.2e |\n", bits[k], bpe, bpe * (double)n / 1e6, sqrt(se / fmax(sv, 1e-300)),
               colmax);
        char path[4096];
        snprintf(path, sizeof path, "%s_k%d.gto", prefix, bits[k]);
        if (write_copy_section(g, 15, q, path) != 0) { fprintf(stderr, "codec_study: error: cannot write %s\n", path); free(q); return 3; }
    }
    free(q);
    return 0;
}


/* --drop: which entries to store (issues 22 and 23). Each SPEC is a drop rule of the
 * bake's final compression, "e=E,s=S,r=R,f=F" (threshold E, drop_rule.h's sender S,
 * receiver R from depth F; absent: 0, and E the products' 6.25e-5 of quality 5), applied
 * to the file's operator by wrt_csc_compress with the bake's weights (sqrt(A_s / A_r),
 * the power kept per column): PREFIX_SPEC.gto gets the kept entries (dropped ones are
 * 0), and the row says entries, the compact file's bytes (formats/gto_opcode.c's
 * blocks), and the relative Frobenius error against the file's operator. */
typedef struct drop_spec { double e; wrt_drop_rule r; } drop_spec;

static int parse_spec(const char *t, drop_spec *d) {
    *d = (drop_spec){6.25e-5, {0, 0, 0, 0}};
    while (*t) {
        char k = t[0], *end;
        if (t[1] != '=') return -1;
        double v = strtod(t + 2, &end);
        if (end == t + 2 || !isfinite(v)) return -1;
        if (k == 'e' && v > 0) d->e = v;
        else if (k == 's') d->r.sender = v;
        else if (k == 'r') d->r.receiver = v;
        else if (k == 'f') d->r.receiver_from = (int)v;
        else return -1;
        t = *end == ',' ? end + 1 : end;
        if (*end && *end != ',') return -1;
    }
    return 0;
}

/* The compact file's bytes for the entries kept (q nonzero): codes, deltas, blocks. */
static double compact_bytes(const wrt_gto *g, const float *q, uint64_t *kept) {
    uint64_t nb = 0, nk = 0;
    for (uint32_t s = 0; s < g->nfuncs; s++) {
        uint32_t prev = 0; int inb = 0;
        for (uint64_t i = g->col_start[s]; i < g->col_start[s + 1]; i++) {
            if (q[3 * i] == 0 && q[3 * i + 1] == 0 && q[3 * i + 2] == 0) continue;
            if (!inb || inb == BLOCK_MAX || g->rows[i] - prev >= 256) { nb++; inb = 0; }
            inb++; nk++; prev = g->rows[i];
        }
    }
    *kept = nk;
    return 5.0 * (double)nk + 8.0 * (double)nb;
}

static int drop_study(const wrt_gto *g, const char *prefix, int nspec, char **specs) {
    uint32_t n = g->nfuncs;
    double *rw = malloc(((size_t)n + 1) * sizeof *rw), *cw = malloc(((size_t)n + 1) * sizeof *cw);
    double *pw = malloc(((size_t)n + 1) * sizeof *pw);
    float *q = malloc(g->nnz * 3 * sizeof *q);
    wrt_csc m = {n, g->nnz, malloc(((size_t)n + 1) * sizeof(uint64_t)), malloc(g->nnz * sizeof(uint32_t)),
                 malloc(g->nnz * 3 * sizeof(float))};
    if (!rw || !cw || !pw || !q || !m.col || !m.row || !m.val) { fprintf(stderr, "codec_study: error: out of memory\n"); return 4; }
    for (uint32_t i = 0; i < n; i++) {
        const wrt_gto_quad *gq = &g->quads[wrt_fkey_quad(g->fkeys[i])];
        wrt_quad wq;
        memset(&wq, 0, sizeof wq);
        for (int c = 0; c < 4; c++) wq.p[c] = (wrt_v3){gq->p[c][0], gq->p[c][1], gq->p[c][2]};
        wq.n = (wrt_v3){gq->n[0], gq->n[1], gq->n[2]};
        wq.area = gq->area;
        wq.parallelogram = (int)(gq->flags & 1);
        pw[i] = wrt_fkey_angular_root(g->fkeys[i])
                    ? wrt_func_power(&wq, wrt_fkey_snode(g->fkeys[i]), wrt_fkey_stype(g->fkeys[i])) : 0;
    }
    uint64_t other = g->size - g->nnz * 16;
    printf("| rule | entries | file MB (compact) | rel. Frobenius |\n|---|---|---|---|\n");
    for (int k = 0; k < nspec; k++) {
        drop_spec d;
        if (parse_spec(specs[k], &d) != 0) { fprintf(stderr, "codec_study: error: bad rule '%s' (e=E,s=S,r=R,f=F)\n", specs[k]); return 1; }
        for (uint32_t i = 0; i < n; i++) {
            double a = g->quads[wrt_fkey_quad(g->fkeys[i])].area;
            rw[i] = 1 / sqrt(a) * wrt_drop_row_scale(&d.r, g->fkeys[i]);
            cw[i] = sqrt(a) * wrt_drop_col_scale(&d.r, g->fkeys[i]);
        }
        memcpy(m.col, g->col_start, ((size_t)n + 1) * sizeof(uint64_t));
        memcpy(m.row, g->rows, g->nnz * sizeof(uint32_t));
        memcpy(m.val, g->vals, g->nnz * 3 * sizeof(float));
        m.nnz = g->nnz;
        wrt_csc_weights W = {rw, cw, pw, NULL, 0, NULL, 0};
        wrt_csc_compress(&m, d.e, &W);
        /* back in the file's places: a kept entry where its row is, 0 elsewhere */
        memset(q, 0, g->nnz * 3 * sizeof *q);
        for (uint32_t s = 0; s < n; s++) {
            uint64_t i = g->col_start[s];
            for (uint64_t j = m.col[s]; j < m.col[s + 1]; j++) {
                while (g->rows[i] != m.row[j]) i++;
                memcpy(&q[3 * i], &m.val[3 * j], 3 * sizeof *q);
            }
        }
        double frob, colmax;
        errors(g, q, &frob, &colmax);
        uint64_t kept;
        double bytes = compact_bytes(g, q, &kept);
        printf("| %s | %" PRIu64 " | %.2f | %.2e |\n", specs[k], kept, (other + bytes) / 1e6, frob);
        fflush(stdout);
        char path[4096];
        snprintf(path, sizeof path, "%s_%s.gto", prefix, specs[k]);
        if (write_copy(g, q, path) != 0) { fprintf(stderr, "codec_study: error: cannot write %s\n", path); return 3; }
    }
    free(rw); free(cw); free(pw); free(q); wrt_csc_free(&m);
    return 0;
}

int main(int argc, char **argv) {
    int drop = argc >= 5 && !strcmp(argv[2], "--drop"), kst = argc == 4 && !strcmp(argv[2], "--k");
    if (argc != 2 && !(argc == 4 && !strcmp(argv[2], "--write")) && !drop && !kst) {
        fprintf(stderr, "usage: codec_study FILE.gto [--write PREFIX | --drop PREFIX SPEC... | --k PREFIX]\n");
        return 1;
    }
    wrt_gto g;
    if (wrt_gto_open(argv[1], &g) != WRT_OK) {
        fprintf(stderr, "codec_study: error: %s\n", wrt_last_error());
        return 2;
    }
    if (kst) {
        int rc = g.kvals && g.knnz ? k_study(&g, argv[3]) : 2;
        if (rc == 2) fprintf(stderr, "codec_study: error: %s: no float K to study (bake with --float-k)\n", argv[1]);
        wrt_gto_close(&g);
        return rc;
    }
    if (!g.vals || g.nnz == 0) {
        fprintf(stderr, "codec_study: error: %s: no float entries to study\n", argv[1]);
        return 2;
    }
    if (drop) {
        int rc = drop_study(&g, argv[3], argc - 4, argv + 4);
        wrt_gto_close(&g);
        return rc;
    }
    float *q = malloc(g.nnz * 3 * sizeof *q);
    if (!q) { fprintf(stderr, "codec_study: error: out of memory\n"); return 4; }
    uint64_t nb16 = for_blocks(&g, 0, NULL, NULL), nb8 = for_blocks(&g, 1, NULL, NULL);
    double n = (double)g.nnz, cols = (double)g.nfuncs + 1;
    double row_u32 = 4, row_b16 = 2 + (8.0 * nb16 + 4 * cols) / n, row_d8 = 1 + (8.0 * nb8 + 4 * cols) / n;
    uint64_t other = g.size - g.nnz * 16;
    printf("%s: %" PRIu64 " entries, %u columns, %" PRIu64 " blocks (u16 rows), %" PRIu64 " blocks (u8 deltas); "
           "%.2f MB besides the entries\n", argv[1], g.nnz, g.nfuncs, nb16, nb8, other / 1e6);
    printf("| values | bytes/entry: values | + u32 rows | + u16 rows in blocks | + u8 deltas in blocks | file MB (u16 rows) | rel. Frobenius | max column |\n");
    printf("|---|---|---|---|---|---|---|---|\n");
    for (size_t k = 0; k < NV; k++) {
        const vcodec *c = &vcodecs[k];
        for_blocks(&g, 0, c, q);
        double frob, colmax;
        errors(&g, q, &frob, &colmax);
        double vb = c->bytes_entry + c->bytes_block * (double)nb16 / n;
        printf("| %s: %s | %.2f | %.2f | %.2f | %.2f | %.1f | %.2e | %.2e |\n", c->name, c->what, vb, vb + row_u32,
               vb + row_b16, vb + row_d8, (other + (vb + row_b16) * n) / 1e6, frob, colmax);
        fflush(stdout);
        if (argc == 4) {
            char path[4096];
            snprintf(path, sizeof path, "%s_%s.gto", argv[3], c->name);
            if (write_copy(&g, q, path) != 0) { fprintf(stderr, "codec_study: error: cannot write %s\n", path); return 3; }
        }
    }
    free(q);
    wrt_gto_close(&g);
    return 0;
}
