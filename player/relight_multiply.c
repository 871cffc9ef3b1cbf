/* relight_multiply.c: the multiply X = Op E of the indirect operator baked by the
 * precomputation (Kontkanen et al. 2006, section 5.2; docs/algorithm.md): Op streamed by
 * columns, touching only the columns whose source is non-zero, so that each row sums its
 * terms in column order whatever the thread count; with the first-bounce operator the
 * source is E' and Y is added (relight_bounce.c). Also the operator the multiply streams
 * when the final gather displays glossy quads: a copy without the rows nothing shows.
 * Depends on relight_internal.h and the mapped operator (formats/gto.h). */
#include "relight_internal.h"

#include <stdalign.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif
#ifdef __SSE4_1__
#include <smmintrin.h>
#endif

#define MUL_MAX_CHUNKS 256
#define MUL_PARALLEL_ENTRIES 3e7 /* entries touched above which the multiply is split */

typedef struct mul_ctx { const uint32_t *cols; uint32_t ncols; int nchunk; const float *src; float *X4; } mul_ctx;

/* Rows [lo, hi) of X = Op E (E: mc->src, r->E or with K r->k.Ep): each chunk scans every non-zero column and takes the
 * entries of its rows (rows ascend within a column), so each X entry sums its terms in
 * column order whatever the thread count. Single precision, 4 lanes an entry (the
 * operator and X are floats; measured against double sums: ~1e-6 relative). */
static void mul_chunk(wrt_relight *r, worker *w, int item, void *vctx) {
    (void)w;
    const mul_ctx *mc = vctx;
    const op_view *op = &r->mul.op;
    uint32_t nf = r->g->nfuncs;
    uint32_t lo = (uint32_t)((uint64_t)nf * item / mc->nchunk), hi = (uint32_t)((uint64_t)nf * (item + 1) / mc->nchunk);
    if (lo >= hi) return;
    memset(mc->X4 + (size_t)lo * 4, 0, (size_t)(hi - lo) * 4 * sizeof(float));
    for (uint32_t k = 0; k < mc->ncols; k++) {
        uint32_t s = mc->cols[k];
        uint64_t a = op->col_start[s], b = op->col_start[s + 1];
        if (a == b || op->rows[b - 1] < lo || op->rows[a] >= hi) continue;
        while (a < b) { /* first entry with row >= lo */
            uint64_t m = a + (b - a) / 2;
            if (op->rows[m] < lo) a = m + 1; else b = m;
        }
        const float *e = mc->src + (size_t)s * 3;
        uint64_t end = op->col_start[s + 1], vend = end < op->nnz ? end : op->nnz - 1; /* 4-float loads stay inside */
        uint64_t i = a;
#ifdef __SSE2__
        __m128 ev = _mm_set_ps(0.0f, e[2], e[1], e[0]);
        for (; i < vend && op->rows[i] < hi; i++) {
            float *x = mc->X4 + (size_t)op->rows[i] * 4;
            _mm_store_ps(x, _mm_add_ps(_mm_load_ps(x), _mm_mul_ps(ev, _mm_loadu_ps(op->vals + i * 3))));
        }
#endif
        for (; i < end && op->rows[i] < hi; i++) {
            float *x = mc->X4 + (size_t)op->rows[i] * 4;
            const float *v = op->vals + i * 3;
            x[0] += e[0] * v[0];
            x[1] += e[1] * v[1];
            x[2] += e[2] * v[2];
        }
    }
}

/* The compact operator's entries of one block added to X4 (rows [lo, hi) only, unless
 * all): the code's mantissas times the source scaled by 2^(base + e), ev4[e]. That is
 * the float operator's product to the bit (the decoded value m 2^(base + e) is exact,
 * and so is the source times a power of two unless it leaves the normal range), so a row sums the same terms in the same
 * order as from the decoded floats. The block is the first entry (its delta 0, its row
 * row0) and those after it up to the next delta 0, m at most; returns how many.
 * SSE4.1: the three mantissas sign-extended in one multiply and shift. */
static inline __attribute__((always_inline)) uint64_t mul_block(float *X4, const float (*ev4)[4], const uint32_t *codes,
                             const uint8_t *deltas, uint32_t row, uint64_t m, uint32_t lo, uint32_t hi, int all) {
#ifdef __SSE4_1__
    const __m128i sh = _mm_set_epi32(0, 1 << 2, 1 << 12, 1 << 22);
#endif
    uint64_t j = 0;
    do {
        row += deltas[j];
        if (all || (row >= lo && row < hi)) {
            uint32_t c = codes[j];
            float *x = X4 + (size_t)row * 4;
#ifdef __SSE4_1__
            __m128i mm = _mm_srai_epi32(_mm_mullo_epi32(_mm_set1_epi32((int32_t)c), sh), 22);
            _mm_store_ps(x, _mm_add_ps(_mm_load_ps(x), _mm_mul_ps(_mm_cvtepi32_ps(mm), _mm_load_ps(ev4[c >> 30]))));
#else
            const float *e = ev4[c >> 30];
            for (int k = 0; k < 3; k++) x[k] += (float)((int32_t)(c << (22 - 10 * k)) >> 22) * e[k];
#endif
        }
        j++;
    } while (j < m && deltas[j] != 0);
    return j;
}

/* Rows [lo, hi) of X = Op E from the compact operator, as mul_chunk does from floats. */
static void mul_chunk_compact(wrt_relight *r, worker *w, int item, void *vctx) {
    (void)w;
    const mul_ctx *mc = vctx;
    const op_view *op = &r->mul.op;
    uint32_t nf = r->g->nfuncs;
    uint32_t lo = (uint32_t)((uint64_t)nf * item / mc->nchunk), hi = (uint32_t)((uint64_t)nf * (item + 1) / mc->nchunk);
    if (lo >= hi) return;
    int all = lo == 0 && hi == nf;
    memset(mc->X4 + (size_t)lo * 4, 0, (size_t)(hi - lo) * 4 * sizeof(float));
    for (uint32_t k = 0; k < mc->ncols; k++) {
        uint32_t s = mc->cols[k];
        const float *e = mc->src + (size_t)s * 3;
        uint64_t i = op->col_start[s], end = op->col_start[s + 1];
#ifdef __SSE2__
        const __m128 e3 = _mm_set_ps(0.0f, e[2], e[1], e[0]);
#endif
        for (uint32_t b = op->bcol[s]; b < op->bcol[s + 1]; b++) {
            uint32_t row0 = op->row0[b];
            int base = op->base[b];
            if (row0 >= hi) break; /* rows ascend within the column */
            alignas(16) float ev4[4][4];
#ifdef __SSE2__
            /* the scalar loop's products e[c] x 2^(base + x), four lanes at once (the
             * fourth 0 x 2^(base + x) = 0): the same bits, a fifth of the instructions of
             * a block's set-up (13.8 entries a block on the maze) */
            const __m128i one = _mm_set1_epi32(1 << 23);
            __m128i p2 = _mm_set1_epi32((base + 127) * (1 << 23)); /* 2^(base + x), a normal float */
            for (int x = 0; x < 4; x++, p2 = _mm_add_epi32(p2, one)) _mm_store_ps(ev4[x], _mm_mul_ps(e3, _mm_castsi128_ps(p2)));
#else
            union { uint32_t u; float f; } p2;
            for (int x = 0; x < 4; x++) {
                p2.u = (uint32_t)(base + x + 127) << 23; /* 2^(base + x), a normal float */
                for (int c = 0; c < 3; c++) ev4[x][c] = e[c] * p2.f;
                ev4[x][3] = 0.0f;
            }
#endif
            /* the whole range (one chunk, the usual case): the row test compiled out */
            if (all) i += mul_block(mc->X4, ev4, op->codes + i, op->deltas + i, row0, end - i, 0, nf, 1);
            else i += mul_block(mc->X4, ev4, op->codes + i, op->deltas + i, row0, end - i, lo, hi, 0);
        }
    }
}

/* With the final gather nothing shows the rows of X that are a glossy quad's angular
 * (non-root) functions: glossy quads are drawn from the gather, which reads every quad's
 * angular-root functions only (a diffuse quad has no others). The multiply then streams a
 * copy of the operator without those rows (on the glossy asset 34% of the entries are
 * kept), in the file's order, so every displayed row of X sums the same terms in the same
 * order (bit-identical); the others stay 0. A float file's copy is floats; a compact
 * file's is compact (display_rows_compact). Kept as the file's when it would save < 10%.
 * Returns -1 if there is no memory. */
/* The compact file's copy without the rows nothing shows: each kept entry keeps its code
 * and its block's base (so the multiply's products are the file's, to the bit); a block
 * of the copy holds kept entries of consecutive blocks of the file with the same base (a
 * third of the entries kept: fewer, fuller blocks, each set up once), and a new one starts
 * at another base or where the row step between kept entries would not fit a delta byte.
 * keep: the kept entries. */
static int display_rows_compact(wrt_relight *r, uint64_t keep) {
    const wrt_gto *g = r->g;
    uint32_t nf = g->nfuncs;
    uint64_t nb = 0;
    for (int pass = 0; pass < 2; pass++) { /* 0: count the blocks, 1: fill */
        uint64_t *cs = NULL;
        uint32_t *bc = NULL, *codes = NULL, *row0 = NULL;
        int8_t *base = NULL;
        uint8_t *dl = NULL;
        if (pass) {
            cs = relight_calloc(r, (size_t)nf + 1, sizeof *cs);
            bc = relight_calloc(r, (size_t)nf + 1, sizeof *bc);
            row0 = relight_calloc(r, nb ? nb * 5 : 1, 1); /* row0, then base */
            codes = relight_calloc(r, keep ? keep : 1, sizeof *codes);
            dl = relight_calloc(r, keep ? keep : 1, 1);
            if (!cs || !bc || !row0 || !codes || !dl) {
                relight_free(r, cs); relight_free(r, bc); relight_free(r, row0); relight_free(r, codes); relight_free(r, dl);
                return -1;
            }
            base = (int8_t *)(row0 + nb);
        }
        uint64_t n = 0, m = 0;
        wrt_gto_walk wk = wrt_gto_walk_at(g, 0);
        float v[3];
        for (uint32_t c = 0; c < nf; c++) {
            if (pass) { cs[c] = n; bc[c] = (uint32_t)m; }
            uint32_t last = 0;
            int open = 0, cbase = 0; /* a block of the copy is open (its base) */
            for (uint64_t i = g->col_start[c]; i < g->col_start[c + 1]; i++) {
                uint32_t row = wrt_gto_entry(g, &wk, i, v);
                if (r->fn_ang[row] != 0) continue;
                int start = !open || wk.base != cbase || row - last > 255;
                if (start) {
                    if (pass) { row0[m] = row; base[m] = (int8_t)wk.base; }
                    m++;
                    open = 1;
                    cbase = wk.base;
                }
                if (pass) {
                    codes[n] = g->op_codes[i];
                    dl[n] = start ? 0 : (uint8_t)(row - last);
                }
                last = row;
                n++;
            }
        }
        if (!pass) { nb = m; continue; }
        cs[nf] = n; bc[nf] = (uint32_t)m;
        op_view *op = &r->mul.op;
        op->col_start = cs; op->bcol = bc; op->row0 = row0; op->base = base; op->codes = codes; op->deltas = dl;
        op->nnz = n;
        r->mul.own[0] = cs; r->mul.own[1] = bc; r->mul.own[2] = row0; r->mul.own[3] = codes; r->mul.own[4] = dl;
    }
    return 0;
}

int relight_display_rows_operator(wrt_relight *r) {
    const wrt_gto *g = r->g;
    uint32_t nf = g->nfuncs;
    uint64_t keep = 0;
    wrt_gto_walk wk = wrt_gto_walk_at(g, 0);
    float v[3];
    for (uint64_t i = 0; i < g->nnz; i++) keep += r->fn_ang[wrt_gto_entry(g, &wk, i, v)] == 0;
    if (keep >= 0.9 * (double)g->nnz) return 0;
    if (!g->rows) return display_rows_compact(r, keep);
    uint64_t *cs = relight_calloc(r, (size_t)nf + 1, sizeof *cs);
    uint32_t *rows = relight_calloc(r, keep ? keep : 1, sizeof *rows);
    float *vals = relight_calloc(r, (keep ? keep : 1) * 3 + 1, sizeof *vals); /* + 1: 4-float loads */
    if (!cs || !rows || !vals) { relight_free(r, cs); relight_free(r, rows); relight_free(r, vals); return -1; }
    uint64_t n = 0;
    wk = wrt_gto_walk_at(g, 0);
    for (uint32_t c = 0; c < nf; c++) {
        cs[c] = n;
        for (uint64_t i = g->col_start[c]; i < g->col_start[c + 1]; i++) {
            uint32_t row = wrt_gto_entry(g, &wk, i, v);
            if (r->fn_ang[row] != 0) continue;
            rows[n] = row;
            memcpy(vals + n * 3, v, 3 * sizeof *vals);
            n++;
        }
    }
    cs[nf] = n;
    r->mul.op.col_start = cs; r->mul.op.rows = rows; r->mul.op.vals = vals; r->mul.op.nnz = n;
    r->mul.own[0] = cs; r->mul.own[1] = rows; r->mul.own[2] = vals;
    return 0;
}

/* X4 = Op src over the non-zero sources only, in column order for every row: the
 * columns are src's non-zero ones, found by a scan, or among `cand` (n of them,
 * ascending) when given. */
static void mul_run(wrt_relight *r, const float *src, const uint32_t *cand, size_t n, float *X4) {
    uint32_t nf = r->g->nfuncs, ncols = 0;
    double entries = 0;
    for (size_t k = 0; k < (cand ? n : nf); k++) {
        uint32_t c = cand ? cand[k] : (uint32_t)k;
        const float *e = src + (size_t)c * 3;
        if (e[0] == 0 && e[1] == 0 && e[2] == 0) continue;
        r->mul.cols[ncols++] = c;
        entries += (double)(r->mul.op.col_start[c + 1] - r->mul.op.col_start[c]);
    }
    mul_ctx mc = {r->mul.cols, ncols, 0, src, X4};
    r->run.n.entries_streamed += (long long)entries;
    /* Bound by memory: threads that stream halves of the same columns were measured
     * slower than one on 2 cores (maze 4.2 vs 2.8 ms, glossy 14 vs 11 ms). */
    int nchunk = entries > MUL_PARALLEL_ENTRIES ? r->nthreads : 1;
    if (nchunk > MUL_MAX_CHUNKS) nchunk = MUL_MAX_CHUNKS;
    mc.nchunk = nchunk;
    relight_parallel_for(r, nchunk, 1e9, r->mul.op.rows ? mul_chunk : mul_chunk_compact, &mc);
}

/* X = sum over k < n of sc[k] x4[k] (4 floats a function; with one term of scale 1, x4[0]
 * itself to the bit), + Y with K, then per quad whether its rows of X changed since the
 * last multiply (r->resynth) and whether any is non-zero (r->x_nonzero). */
static void x_store(wrt_relight *r, const float *const *x4, const float *sc, int n) {
    const wrt_gto *g = r->g;
    uint32_t nq = g->nquads, nf = g->nfuncs;
    /* X from the sum (+ Y with K, on the rows the multiply computes: all but a glossy quad's
     * angular rows when the final gather displays it), each value compared with the one
     * it replaces as it is written (X keeps its address; the quads' ranges follow each
     * other over every function: gto_check_quad_ranges). With the cluster tree the
     * values compared are the tree's: relight_cluster_inverse compares again, on the
     * quads' functions, against this copy of the last X. */
    if (r->ct.inv) memcpy(r->Xprev, r->X, (size_t)nf * 3 * sizeof(float));
    const float *Y = g->nkcols ? r->k.Y : NULL;
    for (uint32_t q = 0; q < nq; q++) {
        const wrt_gto_quad *gq = &g->quads[q];
        uint32_t changed = 0, nz = 0;
        size_t f = gq->func_first, fend = (size_t)gq->func_first + gq->func_count;
#ifdef __SSE2__
        /* without Y: each function's RGB at once, the same bits written and compared; the
         * fourth lane of the loads (X4's unused one, X's next value) is masked out */
        if (!Y) {
            const __m128i m3 = _mm_set_epi32(0, -1, -1, -1);
            __m128i ch = _mm_setzero_si128(), nzv = _mm_setzero_si128();
            for (; f < fend; f++) {
                __m128 v = _mm_setzero_ps();
                for (int k = 0; k < n; k++) {
                    __m128 t = _mm_mul_ps(_mm_set1_ps(sc[k]), _mm_load_ps(x4[k] + f * 4));
                    v = k ? _mm_add_ps(v, t) : t;
                }
                float *x = r->X + f * 3;
                __m128i o = _mm_castps_si128(_mm_loadu_ps(x)), nw = _mm_castps_si128(v);
                ch = _mm_or_si128(ch, _mm_and_si128(_mm_xor_si128(o, nw), m3));
                nzv = _mm_or_si128(nzv, _mm_and_si128(_mm_castps_si128(_mm_cmpneq_ps(v, _mm_setzero_ps())), m3));
                _mm_storel_pi((__m64 *)x, v);
                _mm_store_ss(x + 2, _mm_movehl_ps(v, v));
            }
            changed = _mm_movemask_epi8(_mm_cmpeq_epi8(ch, _mm_setzero_si128())) != 0xFFFF;
            nz = _mm_movemask_epi8(_mm_cmpeq_epi8(nzv, _mm_setzero_si128())) != 0xFFFF;
        }
#endif
        for (; f < fend; f++) {
            int addy = Y && (!r->mul.own[0] || r->fn_ang[f] == 0);
            for (int c = 0; c < 3; c++) {
                float v = 0;
                for (int k = 0; k < n; k++) {
                    float t = sc[k] * x4[k][f * 4 + c];
                    v = k ? v + t : t;
                }
                if (addy) v += Y[f * 3 + c];
                uint32_t ov, nv;
                memcpy(&ov, &r->X[f * 3 + c], 4);
                memcpy(&nv, &v, 4);
                changed |= ov ^ nv;
                nz |= v != 0;
                r->X[f * 3 + c] = v;
            }
        }
        if (r->ct.inv) continue; /* relight_cluster_inverse marks the quads */
        if (changed) r->resynth[q] = 1;
        r->x_nonzero[q] = (uint8_t)(nz != 0);
    }
}

/* X = Op src over the non-zero sources only, in column order for every row (+ Y with K),
 * then per quad whether its rows of X changed since the last multiply (r->resynth) and
 * whether any is non-zero (r->x_nonzero). */
void relight_multiply(wrt_relight *r, const float *src) {
    mul_run(r, src, NULL, 0, r->mul.X4);
    const float *x4 = r->mul.X4, one = 1.0f;
    x_store(r, &x4, &one, 1);
}

/* Linear in the lights: X = sum_i scale_i Op E_i. A light whose projection did not change
 * keeps its product, so moving one light of three streams that light's lit columns only,
 * and a change of intensity or colour scale none. Each X4_i depends on E_i alone and the
 * sum runs in light order, so X depends on the lights, not on the history of updates. */
void relight_multiply_lights(wrt_relight *r) {
    uint32_t nf = r->g->nfuncs;
    const float *x4[WRT_RELIGHT_SUM_MAX];
    float sc[WRT_RELIGHT_SUM_MAX];
    int n = 0;
    for (int i = 0; i < r->nlights; i++) {
        light_state *ls = &r->lights[i];
        if (ls->scale == 0 || !ls->have_proj) continue;
        if (ls->x_gen != ls->proj_gen) {
            float *Ed = r->mul.Ed;
            for (size_t k = 0; k < ls->n; k++) memcpy(Ed + (size_t)ls->idx[k] * 3, ls->val + k * 3, 3 * sizeof(float));
            /* the light's functions ascend (quad by quad, the quads' functions in order);
             * the cluster tree's basis spreads them: then a scan */
            if (r->ct.on) mul_run(r, relight_cluster_forward(r, Ed), NULL, 0, ls->X4);
            else mul_run(r, Ed, ls->idx, ls->n, ls->X4);
            for (size_t k = 0; k < ls->n; k++) memset(Ed + (size_t)ls->idx[k] * 3, 0, 3 * sizeof(float));
            ls->x_gen = ls->proj_gen;
        }
        x4[n] = ls->X4;
        sc[n++] = ls->scale;
    }
    if (n == 0) {
        memset(r->mul.X4, 0, (size_t)nf * 4 * sizeof(float));
        x4[n] = r->mul.X4;
        sc[n++] = 1.0f;
    }
    x_store(r, x4, sc, n);
}
