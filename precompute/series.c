/* series.c: the Global Transport Operator by a Neumann series (paper 4.4; docs/algorithm.md).
 * S = T + T^2 + ... (= G - I, the indirect part the player needs), each term the previous
 * one times T, with non-linear compression (entries below eps_compress dropped) after
 * every product. The series stops when a term is empty after compression, when its norm
 * falls under 1e-6 of the sum, or when the ratio of successive norms has settled (the
 * dominant eigenvalue of T has taken over); the remaining tail is then added as the
 * geometric estimate P_n r / (1 - r), which matters at albedos near 1 (0.99 needs hundreds
 * of bounces otherwise). The gathered GTO T + T S (the fine DTO applied last) is computed
 * too, for its figures, and stored instead when asked.
 *
 * Compression weighs an entry (r, s) by sqrt(A_s / A_r), the areas of the quads of its
 * functions: an entry t moves t E_s into X_r, and coefficients scale as sqrt(area)
 * (basis.h: uniform E0 gives E0 sqrt(A/pi)), so t sqrt(A_s/A_r) is the entry's share of
 * the receiver's irradiance, a form factor. One threshold then means the same relative
 * accuracy on a 1 mm quad beside 1 km walls as on the walls, and does not change when
 * the scene is scaled. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "../formats/gto.h"
#include "series.h"
#include "series_power.h"
#include "balance.h"
#include "budget.h"
#include "links.h"
#include "cluster.h"
#include "drop_rule.h"
#include "dist.h"
#include "spill.h"
#include "series_stream.h"
#include "series_internal.h"

/* The streamed sum's working memory (series_stream.c): a block of the sum read back and
 * the block merged with the term's columns, at most the block size each (16 bytes an
 * entry), fewer where the sum and the term hold fewer. `entries`: the sum's and the
 * term's; 0 where the sum is in memory. Uncounted it was the peak of the small bakes
 * (cornell_shapes q3: 30 MB over the 44 MB counted). The last pass holds its blocks
 * WRT_SUM_FINAL_GROUP at a time, each that much smaller: the same. */
static uint64_t series_stream_need(const bake_ctx *b, uint64_t entries) {
    uint64_t block = b->opt.series_block > 0 ? (uint64_t)b->opt.series_block : WRT_SERIES_BLOCK_DEFAULT;
    return 2 * 16 * (entries < block ? entries : block);
}

/* The sum's overlay (series_stream.h) during the pass that adds a term of `est` entries:
 * the overlay held, and the next one where the term goes there (16 bytes an entry) */
static uint64_t series_overlay_need(const wrt_sum_stream *ss, uint64_t est) {
    uint64_t held = ss->over.nnz, next = held + est;
    return 16 * (held + (next <= ss->nnz / WRT_SUM_OVERLAY_SHARE ? next : 0));
}

/* Memory before each product: the product's entries, estimated from every 64th of its
 * columns (sparse.h; computed and discarded), and again from every 16th where that
 * estimate passes a quarter of the budget. The product holds its entries once, plus the
 * arrays of the 32nd of its columns being computed (wrt_csc_mul); the sum that follows
 * grows S in place by at most as many (wrt_csc_add3_into), while the term before is gone.
 * Streamed (ss), the sum's blocks are added (series_stream_need), and its overlay
 * (series_overlay_need).
 * The estimate is what is checked and recorded. (An upper bound from the column counts
 * decided the finer sample before; on the mazes it always passed, so every product paid
 * a 16th of itself to be estimated: 4% of the series.) */
static wrt_status series_memory_check_beside(const bake_ctx *b, wrt_bake_counters *C, const wrt_csc *P,
                                             const wrt_csc *T, double eps, const wrt_csc_weights *W, int bounce,
                                             const wrt_sum_stream *ss, const wrt_csc *beside, const wrt_csc *X);

static wrt_status series_memory_check(const bake_ctx *b, wrt_bake_counters *C, const wrt_csc *P, const wrt_csc *T,
                                      double eps, const wrt_csc_weights *W, int bounce, const wrt_sum_stream *ss) {
    return series_memory_check_beside(b, C, P, T, eps, W, bounce, ss, NULL, NULL);
}

/* The same, for a product made while the sum's pass adds the term `beside` (NULL: none;
 * series_bounces): ss the sum as that pass found it, and the overlay counted is that
 * pass's, old and new (the product's own pass comes with the next product's check).
 * X: the right factor U P of the factored product (series_factored_term; NULL: not that
 * product), freed after it. There the resident memory rose by about twice the product's
 * entries while it was made (the chunks appended by realloc, the threads' freed column
 * arrays: 54 MB for 1.80M entries on the atrium at 1,060 elements), and the sum's pass
 * then grows S in memory by the term's entries, of which X's freed arrays hold some: so
 * twice the product's need, plus what of it X does not cover. Measured on the atrium at
 * 1,060, 2,704 and 5,048 elements, --clusters -q 1: each bounce's peak under its check's
 * total (docs/clusters.md "The memory estimate with T never formed"). */
static wrt_status series_memory_check_beside(const bake_ctx *b, wrt_bake_counters *C, const wrt_csc *P,
                                             const wrt_csc *T, double eps, const wrt_csc_weights *W, int bounce,
                                             const wrt_sum_stream *ss, const wrt_csc *beside, const wrt_csc *X) {
    const double per = 16.0; /* bytes per entry: row index and three floats */
    char what[96];
    if (bounce > 0) snprintf(what, sizeof what, "bounce %d of the series", bounce);
    else snprintf(what, sizeof what, "the gathered operator T S");
    /* 1.25: the sample's spread, measured on the glossy asset (see the commit message) */
    uint64_t est = wrt_csc_mul_estimate(P, T, eps, W, 64, b->opt.threads);
    double need = per * 1.25 * (1 + 1.0 / 32) * (double)est;
    if ((double)wrt_bake_rss_bytes() + need > 0.25 * b->opt.max_memory_mb * 1024.0 * 1024.0) {
        est = wrt_csc_mul_estimate(P, T, eps, W, 16, b->opt.threads);
        need = per * 1.25 * (1 + 1.0 / 32) * (double)est;
    }
    if (X) need = 2 * need + fmax(0, need - per * (double)X->nnz);
    if (W && W->skip > 0 && !W->bands) need += (double)wrt_csc_mul_order_bytes(P); /* the skip's order of P */
    if (ss)
        need += (double)series_stream_need(b, wrt_sum_stream_nnz(ss) + est) +
                (double)series_overlay_need(ss, beside ? beside->nnz : est);
    return wrt_bake_memory_check(b->opt.max_memory_mb, &C->mem_estimate_mb, (uint64_t)need, what);
}

/* A product of the series: wrt_csc_mul, or under wrt-bake-mpi divided among the ranks by
 * columns and gathered (dist.h: the same entries) */
static wrt_status series_mul(const bake_ctx *b, const wrt_csc *a, const wrt_csc *m, double eps,
                             const wrt_csc_weights *W, int threads, wrt_csc *out) {
    if (!wrt_dist_on(b->opt.dist)) {
        *out = wrt_csc_mul(a, m, eps, W, threads);
        return WRT_OK;
    }
    return wrt_dist_mul(b->opt.dist, a, m, eps, W, threads, out);
}

/* The coarse cut (--series-coarse F, on by default with --clusters): the right factor of
 * the products from the second term on keeps only the rows of the spatial functions whose
 * support is at least F of the scene's area (a wavelet of node level l on quad q: a_q /
 * 4^l), and every quad's scaling function. Row k of the right factor is where the light
 * of one bounce lands before it is sent on: the cut keeps its mean over each quad and its
 * shape down to that size (on a parallelogram the scaling function carries all of a row's
 * power, its wavelets none), so every term's power is what the full product's would be
 * to the compression's rounding, and a furnace's light is exact; on other quads
 * (triangles, trapezoids) the wavelets carry a little power (sqrt(J) varies), which the
 * cut drops per product and series_power.c gives back, each column of the sum taking
 * the power of the full T's series at the end; the first bounce and every
 * term's receivers stay exact, only the re-emitted light is averaged below the cut's
 * size. The products then read only the cut's columns of each term (docs/clusters.md has
 * the figures). */
static int series_coarse_keep(const bake_ctx *b, uint64_t f, double amin) {
    int d = wrt_drop_depth(f);
    /* angular functions (glossy) are kept whole */
    return !(wrt_fkey_angular_root(f) && d > 0 && ldexp(b->quads[wrt_fkey_quad(f)].area, -2 * (d - 1)) < amin);
}

/* cols 0: the rows of m cut (P_k (D T), the terms multiplied from the right); 1: its
 * columns ((T D) P_k, from the left: series_tree_on) */
static void series_coarse_cut(const bake_ctx *b, wrt_csc *m, const uint64_t *fkeys, uint32_t nkeys, double F,
                              int cols) {
    double total = 0;
    for (int q = 0; q < b->nq; q++) total += b->quads[q].area;
    double amin = F * total;
    uint64_t w = 0, k = 0;
    for (uint32_t c = 0; c < m->n; c++) {
        uint64_t end = m->col[c + 1];
        int keep_col = !cols || c >= nkeys || series_coarse_keep(b, fkeys[c], amin); /* nodes' (factored) kept */
        for (; k < end; k++) {
            if (!keep_col || (!cols && !series_coarse_keep(b, fkeys[m->row[k]], amin))) continue;
            m->row[w] = m->row[k];
            memmove(&m->val[3 * w], &m->val[3 * k], 3 * sizeof *m->val);
            w++;
        }
        m->col[c + 1] = w;
    }
    m->nnz = w;
}

/* The area under which a sender's threshold shrinks with its quad (bake.h small_share): an
 * entry's weight t sqrt(A_s / A_r) is the sender's share of the receiver's irradiance, a
 * form factor, which shrinks as 1 / N when a surface is cut into N elements (a closed
 * icosphere of 1,280 triangles at albedo 0.9: every entry about rho / N = 2.3e-4, below
 * quality 1's 1e-3, so the products stopped after 3 terms and the final compression kept
 * 40,080 of the 15,360^2 entries: G - I's flux -99.2%). Below the share the threshold is
 * held against the form factor per unit of the sender's share of the scene's area, a
 * kernel, which does not shrink with N: the icosphere's entries rho^k / N are then kept
 * while rho^k >= 1 / small_share, at any N. The share is small_share x eps_compress (10 by
 * default: 1% of the scene's area at quality 1, 0.0625% at quality 5), so a quad that large
 * keeps the threshold of before (cornell's and glossy's quads at every quality, the maze's at
 * quality 5: the same bytes; the maze at quality 1-4 keeps more). 0: off.
 * What the flux needs is held, not more (session 7): the lower threshold (sparse.h
 * boost_w) is a small quad's scaling function's, never its wavelets' (their light is
 * zero-mean), and applies to its entries at rows that carry power only, in the columns
 * where the plain threshold would drop more than small_lost of the column's power. The
 * icosphere's light is its elements' means (960 x 960 entries a term at 320 triangles);
 * on the atrium most of what the old rule (every function of a small quad, every row)
 * held was wavelets' (docs/bench.md "The small senders' rule: the quads' means only"). */
double wrt_series_small_area(const bake_ctx *b) {
    if (!(b->opt.small_share > 0)) return 0;
    double total = 0;
    for (int q = 0; q < b->nq; q++) total += b->quads[q].area;
    return b->opt.small_share * b->opt.eps_compress * total;
}

/* Stage 1: the compression weights */
static void series_weights(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_result *res = s->res;
    uint32_t n = res->nfuncs;
    double *rw = wrt_xmalloc(((size_t)n + 1) * sizeof *rw), *cw = wrt_xmalloc(((size_t)n + 1) * sizeof *cw);
    double small = wrt_series_small_area(b);
    double *boost = small > 0 ? wrt_xmalloc(((size_t)n + 1) * sizeof *boost) : NULL;
    for (uint32_t i = 0; i < n; i++) {
        double a = b->quads[wrt_fkey_quad(res->fkeys[i])].area;
        rw[i] = 1 / sqrt(a);
        cw[i] = sqrt(a);
        if (boost) boost[i] = a < small && wrt_drop_depth(res->fkeys[i]) == 0 ? small / a : 1;
    }
    /* power weights (irradiance x area per unit coefficient: sqrt(A) on a parallelogram's
     * root, 0 on its wavelets): compression keeps each column's power */
    double *pw = wrt_power_weights(b, res->fkeys, n);
    s->rw = rw; s->cw = cw; s->pw = pw; s->boost = boost;
    s->W = (wrt_csc_weights){rw, cw, pw, boost, fmax(b->opt.small_lost, 0), NULL, 0};
}

/* T compressed at drop: from T (without a full copy first), or where T is streamed and
 * gone, from its scratch file by blocks of columns (the same entries) */
static wrt_csc series_compress_T(series_state *s, const wrt_csc *T, double drop) {
    if (T) return wrt_csc_copy_compress(T, drop, &s->W);
    wrt_csc m;
    const double none[3] = {0, 0, 0};
    if (wrt_sum_stream_final(&s->ss, NULL, none, NULL, drop, &s->W, NULL, NULL, &m) != 1) m = (wrt_csc){0};
    return m;
}

/* Stage 1 too: the first term P = T compressed, and the later products' right factor
 * (from T in memory, or from its scratch file once T is streamed: then T and the first
 * term are never held together). 0 where the scratch file could not be read. */
static int series_first_terms(series_state *s) {
    const bake_ctx *b = s->b;
    if (s->no_t) return 1; /* the first term made with the sum's first state (series_first.c) */
    const wrt_csc *T = s->T ? s->T : s->streamed ? NULL : &s->S; /* consumed in memory: S is T still */
    s->P = series_compress_T(s, T, s->eps);
    if (!s->P.col) return 0;
    if (s->fac) return 1; /* the right factor is E1's (wrt_series_factored_start) */
    if (b->opt.series_right == 1) {
        /* the first term is that matrix already: one copy, not two (on the 12 x 12 maze
         * 260 MB of the peak) */
        s->Tr = s->P;
        s->shared = 1;
    } else if (b->opt.series_right > 0) {
        s->Tr = series_compress_T(s, T, b->opt.series_right * s->eps);
        if (!s->Tr.col) return 0;
    }
    if (b->opt.series_coarse > 0) {
        if (!s->Tr.col || s->shared) s->Tr = wrt_csc_copy(s->Tr.col ? &s->Tr : T);
        s->shared = 0;
        series_coarse_cut(b, &s->Tr, s->res->fkeys, s->res->nfuncs, b->opt.series_coarse, s->tree);
    }
    return 1;
}

/* When the bake may consume T (wrt_bake_options.consume_dto: wrt-bake, whose file does
 * not hold T) and T has no use after the first term but the power iteration (the later
 * products' right factor is Tr; no gathered operator), the sum S takes T's arrays instead
 * of a copy: the power targets are computed first (the same operations as at the tail,
 * so the same bits), T is written to a scratch file for the power iteration (spill_write;
 * each bounce reads it back once, in wrt_csc_apply's order: the same bits), and the
 * bounces hold S, Tr and the terms, not T beside them (on the 12 x 12 maze 515 MB of the
 * peak; issue 22). Where the file cannot be written, T stays and S is a copy. Streamed
 * (series_block >= 0, the default), S does not take T's arrays either: T's file is the
 * sum's first state (series_stream.h), T is freed, and the first term and the right
 * factor are then compressed from the file by blocks (series_first_terms), so the
 * series' start holds T or its first term, not both, and the bounces hold neither T nor S
 * (on the 12 x 12 maze the series' peak 1,288 -> about 500 MB). */
static int series_can_consume(const bake_ctx *b) {
    return !wrt_series_tree_on(b) && b->opt.consume_dto && !b->opt.gathered && !b->opt.report_gathered &&
           b->opt.series_right > 0 && b->opt.series_right_from <= 2;
}

/* T written to its scratch file (series_consume), on a thread of its own */
typedef struct {
    wrt_spill *sp;
    const wrt_csc *T;
    int ok;
} spill_task;

static void spill_task_run(void *user) {
    spill_task *t = user;
    t->ok = wrt_spill_write(t->sp, t->T);
}

static void series_consume(series_state *s) {
    const bake_ctx *b = s->b;
    if (!series_can_consume(b) || !s->pw || s->T != &s->res->dto) return;
    /* the file is written while the power targets are computed (both read T; on the 12 x
     * 12 maze the 480 MB write was a second of one thread alone) */
    spill_task sk = {&s->Tf, s->T, 0};
    wrt_task task;
    int beside = wrt_threads_resolve(s->threads) > 1;
    if (beside) wrt_task_start(&task, spill_task_run, &sk);
    wrt_power_iter_start(&s->pi, s->T, s->pw);
    if (!b->opt.no_tail) s->u = wrt_series_power_targets(s->T, s->pw, s->threads, b->opt.max_bounces, &s->u_bounces);
    if (beside) wrt_task_join(&task);
    else spill_task_run(&sk);
    if (!sk.ok) { /* the iteration goes on in memory, the targets are made again at the tail */
        free(s->u);
        s->u = NULL;
        return;
    }
    if (b->opt.series_block >= 0) {
        /* streamed: the sum starts as T's scratch file, and T goes */
        wrt_sum_stream_start(&s->ss, &s->Tf, b->opt.series_block ? (uint64_t)b->opt.series_block : WRT_SERIES_BLOCK_DEFAULT,
                             s->threads);
        s->streamed = 1;
        wrt_csc_free(&s->res->dto);
        wrt_bake_memory_trim();
    } else {
        s->S = s->res->dto; /* S = T, its first term, without a copy */
        memset(&s->res->dto, 0, sizeof s->res->dto);
    }
    s->T = NULL;
    s->consumed = 1;
}

/* ---- wrt-bake-mpi by shares (docs/mpi.md "Each rank holds its share of the series").
 * Streamed, a term's column j is made from the right factor's column j and the columns
 * of the term before that it names, and is added to the sum's column j alone; so with one
 * column range a rank for the whole series (cut once, by the first product's cost), a
 * rank keeps its range of the terms, of the right factor and of the sum, and fetches
 * before each product only the other ranks' columns that its range of the right factor
 * names (dist.h, an all-to-all). Every column is computed as in the single process; the
 * norms are summed in its order, rank after rank (wrt_dist_chain_sum); the stored
 * operator is gathered on rank 0, the rank that writes. */



/* Columns [c0, c1) of m (the others empty), in arrays of their own */
wrt_csc wrt_series_csc_range(const wrt_csc *m, uint32_t c0, uint32_t c1) {
    wrt_csc r = {.n = m->n};
    r.col = wrt_xcalloc((size_t)m->n + 1, sizeof *r.col);
    uint64_t a = m->col[c0], z = m->col[c1];
    for (uint32_t j = c0; j < c1; j++) r.col[j + 1] = m->col[j + 1] - a;
    for (uint32_t j = c1; j < m->n; j++) r.col[j + 1] = z - a;
    r.nnz = z - a;
    r.row = wrt_xmalloc((r.nnz ? r.nnz : 1) * sizeof *r.row);
    r.val = wrt_xmalloc((r.nnz ? r.nnz : 1) * 3 * sizeof *r.val);
    if (r.nnz) {
        memcpy(r.row, m->row + a, r.nnz * sizeof *r.row);
        memcpy(r.val, m->val + 3 * a, r.nnz * 3 * sizeof *r.val);
    }
    return r;
}

/* The plain series' products' weights: the compression's, with the skip (bake.h
 * series_skip; sparse.c mul_order): P_k's single contributions that carry no power and
 * lie under series_skip x the threshold are not summed. From the right (P_k T), what a
 * product leaves out reaches the light as D (I - T)^-1 x, not carried by every later
 * bounce as from the left (docs/algorithm.md "Contributions under the threshold not
 * summed"; docs/bench.md "The 12 x 12 maze in session 24"). */
static wrt_csc_weights series_plain_weights(const series_state *s) {
    wrt_csc_weights w = s->W;
    w.skip = s->b->opt.series_skip > 0 ? s->b->opt.series_skip : 0;
    return w;
}

static const wrt_csc *series_right(const series_state *s, int bounce);

/* The series in the senders' tree basis by shares (series_tree_on, docs/mpi.md "Session 11
 * (s11-mpi)"): multiplied from the left, a term's column j is T's
 * coarse-cut columns (every rank holds T and its cut whole) times the term before's
 * column j alone, and the sum's column j is the terms' columns j. So each rank keeps one
 * column range of the terms and of the sum for the whole series, cut once by the first
 * product's cost (wrt_dist_mul_cuts: per column, the first term's entries times the
 * right factor's columns they read), and nothing travels during the products but the
 * terms' entry counts and the norms, summed in the single process's order
 * (wrt_dist_chain_sum). The final compression is per column (wrt_csc_compress), so each
 * rank compresses its own range and only the stored columns go to rank 0, in rounds. */
static void series_tree_share_start(series_state *s) {
    wrt_bake_dist *d = s->b->opt.dist;
    int nr = d->nranks;
    s->cut = wrt_xmalloc(((size_t)nr + 1) * sizeof *s->cut);
    d->products_peak = 0; /* the re-cuts' measure (series_recut.c) */
    if (s->fac) { /* the product E1 (U P): its cost read from U P */
        wrt_csc X = wrt_series_factored_right(s, &s->P);
        wrt_series_factored_trim(s, &X);
        wrt_dist_mul_cuts(&s->Tr, &X, nr, s->cut);
        wrt_csc_free(&X);
    } else {
        wrt_dist_mul_cuts(series_right(s, 2), &s->P, nr, s->cut);
    }
    uint32_t c0 = s->cut[d->rank], c1 = s->cut[d->rank + 1];
    wrt_csc p = wrt_series_csc_range(&s->P, c0, c1);
    s->p_all = s->P.nnz;
    wrt_csc_free(&s->P);
    s->P = p;
    s->share = 1;
    wrt_bake_memory_trim();
}

/* Under wrt-bake-mpi with an all-to-all, streamed (or the tree series in memory:
 * series_tree_share_start): the ranges cut by the first product's
 * cost, every rank's needed columns, and this rank's share of P, Tr and the sum kept */
static void series_share_start(series_state *s) {
    wrt_bake_dist *d = s->b->opt.dist;
    if (wrt_dist_on(d) && d->alltoall && s->tree && !s->streamed) {
        series_tree_share_start(s);
        return;
    }
    if (!wrt_dist_on(d) || !d->alltoall || !s->streamed || !s->Tr.col) return;
    int nr = d->nranks;
    s->cut = wrt_xmalloc(((size_t)nr + 1) * sizeof *s->cut);
    wrt_dist_mul_cuts(&s->P, &s->Tr, nr, s->cut);
    s->need = wrt_dist_share_need(&s->Tr, nr, s->cut);
    uint32_t c0 = s->cut[d->rank], c1 = s->cut[d->rank + 1];
    wrt_csc p = wrt_series_csc_range(&s->P, c0, c1), r = wrt_series_csc_range(&s->Tr, c0, c1);
    s->p_all = s->P.nnz;
    wrt_series_free_right(s);
    wrt_csc_free(&s->P);
    s->P = p;
    s->Tr = r;
    wrt_sum_stream_range(&s->ss, c0, c1);
    s->share = 1;
    wrt_bake_memory_trim();
}

/* The term's entries: this rank's are not all of them by shares (every rank must take
 * the same turns) */
static uint64_t series_term_nnz(const series_state *s) { return s->share ? s->p_all : s->P.nnz; }

/* A product by shares: the needed columns of P fetched with every one of this rank's own,
 * whose share of P is then freed (the fetched matrix holds it: the product holds one copy
 * of the term, not two of this rank's columns), the memory checked, this rank's columns
 * computed; *nnz: the product's entries on all the ranks. Where that is none, the rank's
 * share of P is taken back from the fetched columns (the tail reads the last term). */
static wrt_status series_share_mul(series_state *s, const wrt_csc *R, int bounce, wrt_csc *out, uint64_t *nnz) {
    wrt_bake_dist *d = s->b->opt.dist;
    uint32_t c0 = s->cut[d->rank], c1 = s->cut[d->rank + 1];
    wrt_csc in;
    wrt_status st = wrt_dist_share_fetch(d, &s->P, s->cut, s->need, &in);
    if (st != WRT_OK) return st;
    wrt_csc_free(&s->P);
    wrt_csc_weights PW = series_plain_weights(s);
    st = series_memory_check(s->b, s->C, &in, R, s->eps, &PW, bounce, s->streamed ? &s->ss : NULL);
    if (st == WRT_OK) {
        *out = wrt_csc_mul_cols(&in, R, s->eps, &PW, s->threads, c0, c1);
        *nnz = out->nnz;
        st = wrt_dist_sum_u64(d, nnz, 1);
        if (st != WRT_OK) wrt_csc_free(out);
    }
    if (st != WRT_OK || !*nnz) s->P = wrt_series_csc_range(&in, c0, c1);
    wrt_csc_free(&in);
    return st;
}

/* A product of the tree series by shares (series_tree_share_start): this rank's columns
 * of T D P_k from its own columns of P_k, checked first unless `checked` (the estimate
 * then samples this rank's columns: its share); *nnz the term's entries on every rank */
static wrt_status series_tree_share_mul(series_state *s, const wrt_csc *R, int bounce, int checked, wrt_csc *out,
                                        uint64_t *nnz);

static int csc_sumsq_fn(void *user, double *acc) {
    *acc = wrt_csc_sumsq(user, *acc);
    return 1;
}

/* A term's norm: its own, or by shares summed in the single process's order */
static wrt_status series_term_norm(const series_state *s, const wrt_csc *P, double *pn) {
    if (!s->share) {
        *pn = wrt_csc_norm(P);
        return WRT_OK;
    }
    double acc = 0;
    wrt_status st = wrt_dist_chain_sum(s->b->opt.dist, &acc, csc_sumsq_fn, (void *)P);
    *pn = sqrt(acc);
    return st;
}

typedef struct { wrt_sum_stream *ss; const wrt_csc *P; const double *k; } stream_sumsq;

static int stream_sumsq_fn(void *user, double *acc) {
    stream_sumsq *u = user;
    return wrt_sum_stream_sumsq(u->ss, u->P, u->k, acc);
}

/* The streamed sum's (plus k P where P) squares by shares, in the single process's order */
static wrt_status series_share_sumsq(series_state *s, const wrt_csc *P, const double k[3], double *sq) {
    stream_sumsq u = {&s->ss, P, k};
    *sq = 0;
    return wrt_dist_chain_sum(s->b->opt.dist, sq, stream_sumsq_fn, &u);
}

/* S += P, the new term; *sn the sum's norm: in place in memory, or streamed through the
 * sum's scratch files (the same entries and bits) */
static wrt_status series_add_term(series_state *s, double *sn) {
    const double one[3] = {1, 1, 1};
    if (!s->streamed) {
        wrt_csc_add3_into(&s->S, &s->P, one); /* in place: no second copy of the sum */
        return series_term_norm(s, &s->S, sn); /* by tree shares, in the single process's order */
    }
    double sq;
    if (!wrt_sum_stream_add(&s->ss, &s->P, one, &sq))
        return wrt_fail(WRT_ERR_IO, "the series could not stream its sum through a scratch file");
    if (s->share) { /* this rank's squares alone: again in the single process's order */
        wrt_status st = series_share_sumsq(s, NULL, one, &sq);
        if (st != WRT_OK) return st;
    }
    *sn = sqrt(sq);
    return WRT_OK;
}

/* The right factor of bounce k: T, or from series_right_from on (default: every product
 * after the first term), T compressed at series_right x eps (default 1: the products'
 * own threshold; each column's power kept by the compression's hand-over). The light a
 * product carries on has been through a bounce at least, and the entries of T below the
 * threshold, 40% of them on the maze asset at q5 (8.1M, 4.8M above eps), move it between
 * neighbouring functions. Measured against one path-traced reference, debiased cell /
 * image error, and the bake's CPU seconds:
 *   maze asset q5: full T 1.66% / 0.65%, 29.2 s; 1 x eps 1.66% / 0.65%, 21.1 s;
 *                  4 x eps 1.65% / 0.65%, 18.2 s; 16 x eps 1.73% / 0.65%, 17.9 s.
 * But a closed box with a floor of 8 x 8 small quads at quality 4 (test_bake's
 * small-quads furnace, tolerance 4.1%): worst quad 3.85% with the full T, 3.97% at 1 x
 * eps, 5.53% at 2 x, 7.72% at 4 x (also with the roots' rows kept at 1 x); and a
 * coloured box at albedo 0.99 lost 0.31% of its flux at 16 x. Hence 1. The first term
 * and the tail's power iteration keep the full T. */
static const wrt_csc *series_right(const series_state *s, int bounce) {
    return s->Tr.col && (s->consumed || bounce >= s->b->opt.series_right_from) ? &s->Tr : s->T;
}

/* Frees the right factor, unless the term P still is that matrix (P then owns it). */
void wrt_series_free_right(series_state *s) {
    if (s->shared) memset(&s->Tr, 0, sizeof s->Tr);
    else wrt_csc_free(&s->Tr);
    s->shared = 0;
    s->Trb.a.row = NULL; /* Tr's (wrt_series_factored_bands) */
    s->Trb.a.val = NULL;
    wrt_csc_bands_free(&s->Trb);
    s->FW.bands = NULL;
}

/* A bounce's passes that do not depend on each other, on two threads where the bake has
 * them: the sum's (S += P and its norm; item 0) and the power iteration's step with the
 * term's norm (item 1). Each is one pass in its own order: the same bits. Not under
 * wrt-bake-mpi, whose sum's pass exchanges with the other ranks. */
typedef struct {
    series_state *s;
    const wrt_csc *T;
    double sn, pn, rnext[3];
    wrt_status ast;
    int pok;
} bounce_pass;

static void bounce_pass_run(size_t i, int th, void *user) {
    (void)th;
    bounce_pass *bp = user;
    if (i == 0) {
        bp->ast = series_add_term(bp->s, &bp->sn);
    } else {
        bp->pn = wrt_csc_norm(&bp->s->P);
        bp->pok = wrt_power_iter_step(&bp->s->pi, bp->T, &bp->s->Tf, bp->s->pw, bp->rnext);
    }
}

/* The memory check of the term after P, the product by the right factor of `bounce` (ss
 * and beside: series_memory_check_beside's; NULL, NULL: the sum as it is, the product's
 * own pass counted), the message said on this thread */
static wrt_status series_next_check(series_state *s, int bounce, const wrt_sum_stream *ss, const wrt_csc *beside) {
    /* in the senders' tree basis from the left, T P_k (series_tree_on) */
    const wrt_csc *R = series_right(s, bounce);
    const wrt_csc *La = s->tree ? R : &s->P, *Rb = s->tree ? &s->P : R;
    wrt_csc_weights PW = series_plain_weights(s);
    wrt_status mst = series_memory_check_beside(s->b, s->C, La, Rb, s->eps, s->tree ? &s->TW : &PW, bounce,
                                                ss ? ss : s->streamed ? &s->ss : NULL, beside, NULL);
    if (mst != WRT_OK) {
        char msg[1024];
        snprintf(msg, sizeof msg, "%s", wrt_last_error());
        return wrt_fail(mst, "%s", msg);
    }
    return WRT_OK;
}

/* The term after P with the left factor kept as T = E1 U (series_tree.c): E1 (U D P),
 * the memory checked on that product unless `checked`. U D P holds P's entries, so P's
 * arrays are freed while the product is made (P is not read again once its successor
 * exists) and taken back from it where the product failed or came out empty (the last
 * term then stays for the tail): the same values. By tree shares (range: this rank's
 * columns [range[0], range[1]), which alone P holds): U P on those columns (U acts on a
 * column alone) and the same columns of E1 (U P), series_mul's entries; every rank takes
 * the same turns, *nnz the term's entries on all of them, P taken back where that is 0.
 * In one process, by blocks of P's columns (series_blocks.c: the same entries, a block of
 * U P held, not the whole); under wrt-bake-mpi unshared U P's memory is checked before it
 * is made: 2.6 bytes for every byte of P (X holds 1.28 to 1.52 times P's entries on the
 * atrium, and the build raised the resident memory by 1.5 times X's bytes); by shares
 * the ranks' turns must stay the same, and the product's check counts X once made. The
 * freed memory of the last product and sum pass goes back to the system first: the
 * pull-up stacked on it was the bake's peak (the atrium at 1,060 elements: 224 to 249 MB
 * against 198 to 202 MB with it given back). */
static wrt_status series_factored_term(series_state *s, int bounce, int checked, const uint32_t *range, wrt_csc *N,
                                       uint64_t *nnz) {
    wrt_bake_dist *d = s->b->opt.dist;
    if (!range && !wrt_dist_on(d)) { /* one process: by blocks (series_blocks.c), P freed once used */
        wrt_status bst = wrt_series_factored_blocks(s, bounce, checked, N);
        if ((*nnz = N->nnz) && !s->shared) wrt_csc_free(&s->P);
        return bst;
    }
    double t0 = wrt_dist_cpu_now(), t1 = t0;
    wrt_status st = WRT_OK;
    if (!range && !checked) { /* wrt_bake_memory_check gives the freed memory back first */
        char what[64];
        snprintf(what, sizeof what, "bounce %d of the series, U P", bounce);
        st = wrt_bake_memory_check(s->b->opt.max_memory_mb, &s->C->mem_estimate_mb,
                                   (uint64_t)(16 * 2.6 * (double)s->P.nnz), what);
    } else {
        wrt_bake_memory_trim();
    }
    wrt_csc X = st == WRT_OK ? wrt_series_factored_right(s, &s->P) : (wrt_csc){0};
    int freed = 0;
    if (range) { /* P, now in X, re-cut with it (P taken back from X below where needed) */
        t1 = wrt_dist_cpu_now();
        if ((freed = !s->shared)) wrt_csc_free(&s->P);
        st = wrt_series_share_recut(s, &s->Tr, &X);
    }
    if (st == WRT_OK && !checked)
        st = series_memory_check_beside(s->b, s->C, &s->Tr, &X, s->eps, &s->FW, bounce, NULL, NULL, &X);
    char msg[1024] = "";
    if (st != WRT_OK) snprintf(msg, sizeof msg, "%s", wrt_last_error());
    if (st == WRT_OK && !range && (freed = !s->shared)) wrt_csc_free(&s->P);
    if (st == WRT_OK && range) {
        double t2 = wrt_dist_cpu_now();
        *N = wrt_csc_mul_cols(&s->Tr, &X, s->eps, &s->FW, s->threads, range[0], range[1]);
        d->cpu_products += (t1 - t0) + (wrt_dist_cpu_now() - t2);
    } else if (st == WRT_OK) {
        st = series_mul(s->b, &s->Tr, &X, s->eps, &s->FW, s->threads, N);
    }
    if (N->col) wrt_series_factored_trim(s, N);
    *nnz = N->nnz;
    if (range) {
        wrt_status cst = wrt_dist_sum_u64(d, nnz, 1);
        if (st == WRT_OK) st = cst;
    }
    if (freed && (st != WRT_OK || *nnz == 0)) s->P = wrt_series_factored_left(s, &X);
    wrt_csc_free(&X);
    if (st != WRT_OK) wrt_csc_free(N);
    return st != WRT_OK && msg[0] ? wrt_fail(st, "%s", msg) : st;
}

static wrt_status series_tree_share_mul(series_state *s, const wrt_csc *R, int bounce, int checked, wrt_csc *out,
                                        uint64_t *nnz) {
    wrt_bake_dist *d = s->b->opt.dist;
    if (s->fac && R == &s->Tr) return series_factored_term(s, bounce, checked, s->cut + d->rank, out, nnz);
    wrt_status st = wrt_series_share_recut(s, R, &s->P);
    if (st == WRT_OK && !checked) st = series_next_check(s, bounce, NULL, NULL);
    /* every rank takes the same turns: a rank that failed its check still sums the count */
    double c0 = wrt_dist_cpu_now();
    *out = st == WRT_OK ? wrt_csc_mul_cols(R, &s->P, s->eps, &s->TW, s->threads, s->cut[d->rank], s->cut[d->rank + 1])
                        : (wrt_csc){0};
    d->cpu_products += wrt_dist_cpu_now() - c0;
    *nnz = out->nnz;
    wrt_status cst = wrt_dist_sum_u64(d, nnz, 1);
    if (st == WRT_OK) st = cst;
    if (st != WRT_OK) wrt_csc_free(out);
    return st;
}

/* The term after P: checked first unless `checked`; by shares, *nnz is the term's entries
 * on every rank */
static wrt_status series_next_term(series_state *s, int bounce, int checked, wrt_csc *N, uint64_t *nnz) {
    const bake_ctx *b = s->b;
    const wrt_csc *R = series_right(s, bounce);
    memset(N, 0, sizeof *N);
    if (s->share && s->tree) return series_tree_share_mul(s, R, bounce, checked, N, nnz);
    if (s->share) return series_share_mul(s, R, bounce, N, nnz);
    if (s->fac && R == &s->Tr) return series_factored_term(s, bounce, checked, NULL, N, nnz);
    wrt_status mst = checked ? WRT_OK : series_next_check(s, bounce, NULL, NULL);
    if (mst != WRT_OK) return mst;
    const wrt_csc *La = s->tree ? R : &s->P, *Rb = s->tree ? &s->P : R;
    wrt_csc_weights PW = series_plain_weights(s);
    wrt_status pst = series_mul(b, La, Rb, s->eps, s->tree ? &s->TW : &PW, s->threads, N);
    *nnz = N->nnz;
    return pst;
}

/* Beside a bounce's sum pass (series_bounces), on a thread of its own (wrt_task): the
 * term's norm, the power step and, where `next` and its memory check passed (st), the
 * next term, with its status and message (the error text is the thread's) */
typedef struct {
    series_state *s;
    const wrt_csc *T;
    int next, pok;
    double pn, rnext[3];
    wrt_status st;
    char msg[1024];
    wrt_csc N;
    uint64_t nnz;
} next_task;

static void next_task_run(void *user) {
    next_task *t = user;
    series_state *s = t->s;
    t->pn = wrt_csc_norm(&s->P);
    t->pok = wrt_power_iter_step(&s->pi, t->T, &s->Tf, s->pw, t->rnext);
    if (!t->pok || !t->next || t->st != WRT_OK) return;
    t->st = series_next_term(s, (int)s->C->bounces + 1, 1, &t->N, &t->nnz);
    if (t->st != WRT_OK) snprintf(t->msg, sizeof t->msg, "%s", wrt_last_error());
}

/* Stage 2: the bounces, each term the previous one times T, with the power iteration that
 * measures the tail's ratio; stops as described at the top of the file */
static wrt_status series_bounces(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_counters *C = s->C;
    const wrt_csc *T = s->T;
    int threads = s->threads;
    double *rc = s->rc;
    /* The tail's ratio is measured by power iteration on a smooth start vector (each quad's
     * root coefficient, i.e. a uniform irradiance), per channel, as the ratio of the
     * power (sum of sqrt(A) x root coefficient) of successive terms. Norms of the whole
     * terms keep the faster-decaying detail of every mode (at albedo 0.9 the matrix-norm
     * ratio read 0.9046 when it looked settled, a 5% error in r/(1-r)); norms of the
     * iterate still mix the second eigenvector in (a closed box with a box inside at
     * albedo 0.999 stopped at 0.998971: -2.8%). The power is what the tail must get right,
     * and with the power balance a closed scene's power ratio is the albedo from the first
     * bounce. */
    /* the iteration runs on T itself, not on the compressed terms, whose power drifts by
     * what compression drops (at albedo 0.999 a drift of 2e-5 per bounce is 2% of the tail);
     * started here, or in series_consume before T was consumed */
    if (!s->pi.x) wrt_power_iter_start(&s->pi, T, s->pw);
    double rc_prev[3] = {-1, -1, -1};
    double ratio = 0;
    int stable = 0;
    C->bounces = 1;
    /* Overlapped (the streamed sum, one process, two threads or more; in memory the sum
     * would grow beside the product, uncounted): while this thread makes a bounce's sum
     * pass, a thread of its own takes the term's norm and the power step and then makes
     * the next term on the bake's threads (the product reads the term and the right
     * factor, the pass the term and the sum's files: neither writes what the other
     * reads). Whether that next term is wanted is known only from the pass's norm: where
     * the series stops at this bounce, it is discarded. The same terms, sums and bits as
     * one after the other; the pass (on the 12 x 12 maze two rewrites of a 640 MB file and
     * eight reads of it) no longer leaves the other core idle. */
    int overlap = s->streamed && !wrt_dist_on(b->opt.dist) && wrt_threads_resolve(threads) > 1;
    wrt_csc N = {0};
    uint64_t nnz = 0;
    int have = 0;                /* N is the next term, made beside the last pass */
    wrt_status nst = WRT_OK;     /* and its product's status, with the message */
    char nmsg[1024] = "";
    wrt_status st = WRT_OK;
    while ((int)C->bounces < b->opt.max_bounces && series_term_nnz(s)) {
        if (have && nst != WRT_OK) {
            st = wrt_fail(nst, "%s", nmsg);
            break;
        }
        if (!have && (st = series_next_term(s, (int)C->bounces + 1, 0, &N, &nnz)) != WRT_OK) break;
        have = 0;
        if (!nnz) {
            /* every entry of the next term fell under the threshold, but together they
             * still carry ratio / (1 - ratio) of the last term (0.2% of the total at
             * albedo 0.5, measured): the last term stays for the tail estimate below */
            wrt_csc_free(&N);
            break;
        }
        if (s->shared) s->shared = 0; /* the first term stays on as the right factor */
        else wrt_csc_free(&s->P);       /* the last term, used: its product is made */
        s->P = N;
        memset(&N, 0, sizeof N);
        s->p_all = nnz;
        C->bounces++;
        double pn, sn = 0;
        /* the next iterate's ratios (T in memory, or read back from its scratch file) */
        double rnext[3];
        if (overlap) {
            /* the next product's memory checked before the pass starts (the resident
             * memory then does not hold the pass's blocks, which the check counts); the
             * pass on this thread (its blocks and overlay in this thread's heap, as
             * before: from another thread's, glibc's, they stayed resident after it) */
            next_task nt = {.s = s, .T = T, .next = (int)C->bounces < b->opt.max_bounces};
            if (nt.next && (nt.st = series_next_check(s, (int)C->bounces + 1, &s->ss, &s->P)) != WRT_OK)
                snprintf(nt.msg, sizeof nt.msg, "%s", wrt_last_error());
            wrt_task task;
            wrt_task_start(&task, next_task_run, &nt);
            wrt_status ast = series_add_term(s, &sn);
            wrt_task_join(&task);
            pn = nt.pn;
            memcpy(rnext, nt.rnext, sizeof rnext);
            if (nt.pok && nt.next) {
                N = nt.N;
                nnz = nt.nnz;
                nst = nt.st;
                memcpy(nmsg, nt.msg, sizeof nmsg);
                have = 1;
            }
            if (ast != WRT_OK) {
                st = ast;
                break;
            }
            if (!nt.pok) {
                st = wrt_fail(WRT_ERR_IO, "the series could not read back its scratch copy of T");
                break;
            }
        } else if (!wrt_dist_on(b->opt.dist)) {
            bounce_pass bp = {.s = s, .T = T};
            wrt_parallel_for(2, threads, bounce_pass_run, &bp);
            if (bp.ast != WRT_OK) /* said again on this thread (the error text is the thread's) */
                return wrt_fail(bp.ast, "the series could not stream its sum through a scratch file");
            if (!bp.pok) return wrt_fail(WRT_ERR_IO, "the series could not read back its scratch copy of T");
            pn = bp.pn;
            sn = bp.sn;
            memcpy(rnext, bp.rnext, sizeof rnext);
        } else {
            wrt_status ast = series_term_norm(s, &s->P, &pn);
            if (ast == WRT_OK) ast = series_add_term(s, &sn);
            if (ast != WRT_OK) return ast;
            if (!wrt_power_iter_step(&s->pi, T, &s->Tf, s->pw, rnext))
                return wrt_fail(WRT_ERR_IO, "the series could not read back its scratch copy of T");
        }
        int settled = 1;
        ratio = 0;
        C->energy_left = sn > 0 ? pn / sn : 0;
        for (int ch = 0; ch < 3; ch++) {
            rc[ch] = rnext[ch];
            ratio = fmax(ratio, rc[ch]);
            /* settled when the ratio has stopped moving, or when what its movement could
             * still change in the tail, |dr| / (1 - r)^2 times the last term's share of
             * the sum, is under 1e-6 (cornell q5: 15 bounces instead of 21, the maze 12
             * instead of 16, the cell error against the path tracer the same to 1e-6) */
            double dr = fabs(rc[ch] - rc_prev[ch]);
            settled &= rc_prev[ch] >= 0 &&
                       (dr <= 1e-5 * rc[ch] || (rc[ch] < 1 && dr / ((1 - rc[ch]) * (1 - rc[ch])) * C->energy_left <= 1e-6));
            rc_prev[ch] = rc[ch];
        }
        stable = settled ? stable + 1 : 0;
        /* how far: the light left on its way from 1 down to the 1e-6 where the series stops
         * at the latest (it often stops sooner, when the tail can be added) */
        double done = C->energy_left > 0 ? log(C->energy_left) / log(1e-6) : 1;
        if (b->opt.progress && !b->opt.progress("gto", fmin(1.0, fmax(done, 0.0)), b->opt.progress_user)) {
            st = wrt_fail(WRT_ERR_CANCELLED, "bake cancelled");
            break;
        }
        if (s->timing) {
            char what[64];
            snprintf(what, sizeof what, "bounce %d (%llu entries)", (int)C->bounces, (unsigned long long)s->P.nnz);
            wrt_series_mark(s, what);
        }
        if (C->energy_left < 1e-6) break;
        if (!b->opt.no_tail && stable >= 3 && C->bounces >= 8) break;
    }
    wrt_csc_free(&N); /* a next term the series did not take */
    if (st != WRT_OK) return st;
    wrt_series_free_right(s);
    wrt_power_iter_free(&s->pi);
    if (!s->streamed) wrt_spill_free(&s->Tf); /* streamed, it may still be the sum */
    s->ratio = ratio;
    return WRT_OK;
}

/* The stored operator's compression: its own threshold (eps_final >= eps_compress drops
 * what the products needed but the display does not), weighted by the drop rule
 * (drop_rule.h) on top of the products' weights; the rule's scales are <= 1, so it only
 * drops more. The threshold returned; *W the weights, whose arrays *own (malloc'd, NULL
 * where the rule is off and *W is the products') are the caller's to free. */
double wrt_series_final_weights(series_state *s, wrt_csc_weights *W, double **own) {
    const bake_ctx *b = s->b;
    double eps = b->opt.eps_final > s->eps ? b->opt.eps_final : s->eps;
    wrt_drop_rule r = {fmax(b->opt.drop_sender, 0), fmax(b->opt.drop_receiver, 0),
                       b->opt.drop_receiver_from > 0 ? b->opt.drop_receiver_from : 0,
                       fmax(b->opt.drop_sender_size, 0) * b->scene_size};
    *W = s->W;
    *own = NULL;
    if (r.sender == 0 && r.receiver == 0) return eps;
    uint32_t n = s->res->nfuncs;
    double *rw = *own = wrt_xmalloc(2 * ((size_t)n + 1) * sizeof *rw), *cw = rw + n + 1;
    for (uint32_t i = 0; i < n; i++) {
        rw[i] = s->rw[i] * wrt_drop_row_scale(&r, s->res->fkeys[i]);
        cw[i] = s->cw[i] * wrt_drop_col_scale_sized(&r, s->res->fkeys[i], sqrt(b->quads[wrt_fkey_quad(s->res->fkeys[i])].area));
    }
    *W = (wrt_csc_weights){rw, cw, s->pw, s->boost, s->W.boost_lost, NULL, 0};
    return eps;
}

/* The streamed sum's last pass (series_tail): the memory the stored operator will take,
 * projected from the columns done, against the budget */
static int series_final_check(void *user, uint64_t kept, uint64_t projected) {
    series_state *s = user;
    uint64_t sum = s->ss.cur ? wrt_sum_stream_nnz(&s->ss) + s->P.nnz : 0;
    /* the pass's blocks and the overlay it reads (the next group, read beside them, is
     * resident as this is checked) */
    return wrt_bake_memory_check(s->b->opt.max_memory_mb, &s->C->mem_estimate_mb,
                                 16 * (projected - kept) + series_stream_need(s->b, sum) +
                                     16 * s->ss.over.nnz,
                                 "the stored operator") == WRT_OK;
}

/* By shares: the stored operator whole on rank 0, the rank that writes (the others' S
 * then empty) */
static wrt_status series_share_root(series_state *s) {
    wrt_csc all;
    wrt_status st = wrt_dist_share_to_root(s->b->opt.dist, &s->S, s->cut, &all);
    wrt_csc_free(&s->S);
    if (st == WRT_OK) s->S = all;
    wrt_bake_memory_trim(); /* the rounds' buffers, freed, back to the system */
    return st;
}

/* The sum plus k P where add (the tail), then compressed for storing, into s->S: in place
 * in memory, or by the streamed sum's last pass; *sn the norm after the tail (if add) */
static wrt_status series_final_sum(series_state *s, int add, const double k[3], double *sn) {
    wrt_csc_weights W;
    double *own[3];
    double eps = wrt_series_final_weights_tree(s, &W, own);
    wrt_status st = WRT_OK;
    if (!s->streamed) {
        if (add) {
            wrt_csc_add3_into(&s->S, &s->P, k);
            st = series_term_norm(s, &s->S, sn);
        }
        s->C->sum_held = s->S.nnz;
        wrt_csc_compress(&s->S, eps, &W); /* column by column: by shares, this rank's */
        if (st == WRT_OK && s->share) st = series_share_root(s);
    } else {
        double sq = 0, mine;
        if (s->share && add) st = series_share_sumsq(s, &s->P, k, &sq); /* in the single process's order */
        int r = st != WRT_OK ? 1 : wrt_sum_stream_final(&s->ss, add ? &s->P : NULL, k, s->share ? &mine : &sq, eps, &W,
                                                        series_final_check, s, &s->S);
        if (r == 0) st = wrt_fail(WRT_ERR_IO, "the series could not read back its sum's scratch file");
        else if (r < 0) st = WRT_ERR_NOMEM; /* the check's message stands */
        if (add) *sn = sqrt(sq);
        if (st == WRT_OK && s->share) st = series_share_root(s);
        s->C->sum_kept = s->ss.kept;
        s->C->sum_written = s->ss.written;
        wrt_sum_stream_free(&s->ss);
        wrt_spill_free(&s->Tf);
    }
    free(own[0]); free(own[1]); free(own[2]);
    return st;
}

static wrt_status series_finish(series_state *s);

/* Stage 3: refuse a diverging series, else add the geometric tail and compress the sum */
static wrt_status series_tail(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_counters *C = s->C;
    const double *rc = s->rc;
    double ratio = s->ratio;
    C->series_ratio = ratio;
    if (series_term_nnz(s)) {
        wrt_status dst = wrt_series_diverging(s, C->energy_left, (int)C->bounces);
        if (dst != WRT_OK) return dst;
    }
    int add = !b->opt.no_tail && series_term_nnz(s) && ratio > 0 && ratio < 1;
    double k[3] = {0, 0, 0}, sn = 0;
    for (int ch = 0; ch < 3 && add; ch++) k[ch] = rc[ch] > 0 && rc[ch] < 1 ? rc[ch] / (1 - rc[ch]) : 0;
    wrt_status st = series_final_sum(s, add, k, &sn);
    if (st != WRT_OK) return st;
    if (add) {
        double pn;
        st = series_term_norm(s, &s->P, &pn);
        if (st != WRT_OK) return st;
        C->tail_fraction = sn > 0 ? fmax(k[0], fmax(k[1], k[2])) * pn / sn : 0;
    }
    wrt_csc_free(&s->P);
    return series_finish(s);
}

/* Stage 3's end: each column's power fixed, the stored operator counted */
static wrt_status series_finish(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_counters *C = s->C;
    /* by shares, the ranks but 0 hold no operator now: nothing to fix or count */
    if (s->share && b->opt.dist->rank != 0) return WRT_OK;
    /* each column's power made the DTO's own series' (series_power.c), after the drop */
    if (!b->opt.no_tail && s->pw) {
        wrt_series_power_stats ps;
        if (s->u) { /* the targets, computed before T was consumed */
            memset(&ps, 0, sizeof ps);
            ps.bounces = s->u_bounces;
            wrt_series_power_apply(s->u, s->pw, s->threads, &s->S, &ps);
        } else if (s->tree) {
            wrt_series_tree_power(s, &ps);
            wrt_series_mark(s, "power rule's correction");
        } else {
            wrt_series_power_fix(s->T, s->pw, s->threads, b->opt.max_bounces, &s->S, &ps);
        }
    }
    C->entries_gto = s->S.nnz;
    C->links_gto = wrt_count_links(&s->S, s->res->fkeys, s->threads);
    return WRT_OK;
}

/* Stage 4: the gathered operator, with its memory check */
static wrt_status series_gathered(series_state *s) {
    const bake_ctx *b = s->b;
    wrt_bake_counters *C = s->C;
    const wrt_csc *T = s->T;
    /* gathered: T + T S, computed when stored or when its figures are asked for */
    if (b->opt.gathered || b->opt.report_gathered) {
        /* T S: the same check, with T on the left (column j of T S gathers T's columns) */
        wrt_status mst = series_memory_check(b, C, T, &s->S, s->eps, &s->W, 0, NULL);
        if (mst != WRT_OK) {
            char msg[1024];
            snprintf(msg, sizeof msg, "%s", wrt_last_error());
            return wrt_fail(mst, "%s", msg);
        }
        wrt_csc TS;
        wrt_status pst = series_mul(b, T, &s->S, s->eps, &s->W, s->threads, &TS);
        if (pst != WRT_OK) return pst;
        wrt_csc Gg = wrt_csc_add(&TS, T, 1.0);
        wrt_csc_free(&TS);
        C->entries_gathered = Gg.nnz;
        C->links_gathered = wrt_count_links(&Gg, s->res->fkeys, s->threads);
        if (b->opt.gathered) {
            wrt_csc_free(&s->S);
            s->S = Gg;
        } else {
            wrt_csc_free(&Gg);
        }
    }
    return WRT_OK;
}

/* Frees what the state holds (after a failure: the sum too) */
static void series_state_free(series_state *s) {
    wrt_csc_mul_scratch_free(); /* the products are done */
    wrt_series_free_right(s);
    wrt_power_iter_free(&s->pi);
    wrt_csc_free(&s->P); wrt_csc_free(&s->S);
    wrt_spill_free(&s->Tf);
    wrt_sum_stream_free(&s->ss);
    free(s->rw); free(s->cw); free(s->pw); free(s->u); free(s->boost);
    s->rw = s->cw = s->pw = s->u = s->boost = NULL;
    free(s->cut); free(s->need);
    free(s->troot); free(s->tcw); free(s->tboost); free(s->fcw); free(s->fboost); free(s->apart);
    s->apart = NULL;
    s->troot = NULL; s->tcw = s->tboost = s->fcw = s->fboost = NULL;
    if (s->b->opt.cluster_factored < 2) wrt_csc_free(&s->res->dto_e1);
    s->cut = NULL;
    s->need = NULL;
}

wrt_status wrt_series_run(const bake_ctx *b, wrt_bake_result *res) {
    series_state s = {.b = b, .res = res, .C = &res->c, .T = &res->dto, .eps = b->opt.eps_compress,
                      .timing = getenv("WRT_DTO_TIMES") != NULL,
                      .threads = b->opt.threads, .tree = wrt_series_tree_on(b),
                      .fac = wrt_series_factored_on(b, res)};
    if (!s.fac) wrt_csc_free(&res->dto_e1);
    s.no_t = s.fac && res->c.t_unformed;
    if (s.no_t) { /* T = E1 U read from E1 (series_first.c) */
        s.T = NULL;
        s.E1 = &res->dto_e1;
        s.pi.apply = wrt_series_factored_apply;
        s.pi.user = &s;
        s.pi.n = res->nfuncs;
    }
    /* the start's memory: the first term (at most T's entries, 16 bytes each), a second
     * right factor where it is not the first term, and the sum's copy of T where T is
     * not consumed; streamed, T goes to its scratch file before the first term is made,
     * which then takes T's place instead of joining it (then the bounces' checks,
     * series_memory_check, and the last pass's, series_final_check) */
    int streamed = series_can_consume(b) && b->opt.series_block >= 0;
    uint64_t copies = 1 + (b->opt.series_right != 1 || b->opt.series_coarse > 0) + !series_can_consume(b) - streamed +
                      s.tree; /* the tree's first term beside the sum */
    /* T never formed: E1 is held to the end of the start, and the sum's first state (T W^T:
     * its tree columns compressed, docs/clusters.md "T never formed") is made beside it,
     * then the right factor (wrt_series_factored_check). The sum's first state with its walk's
     * scratch measured (WRT_DTO_TIMES' stage peaks, session 18) at 3.6, 2.4 and 1.7 times
     * E1's bytes on the atrium at 2,704 and 22,224 elements (quality 1) and 5,048 (quality
     * 5), so 4. Until session 18 one check counted the whole start at 5 times E1 (measured
     * 2.4 to 4.3): it refused the 53,122-element atrium at quality 5 at the default budget,
     * 12,140 MB asked against a peak of 9,326. Plus 8 MB a thread: the walk's threads' own
     * arenas (596 atrium elements, q1: peaks 63-66 or 75-78 MB in 24 runs against 75) */
    uint64_t start_need = s.no_t ? 4 * 16 * res->dto_e1.nnz + (uint64_t)wrt_threads_resolve(s.threads) * (8u << 20)
                                 : copies * 16 * res->dto.nnz;
    wrt_status st = wrt_bake_memory_check(b->opt.max_memory_mb, &res->c.mem_estimate_mb, start_need,
                                          "the series' first term");
    if (st != WRT_OK) return st;
    wrt_series_mark(&s, "");
    series_weights(&s);
    series_consume(&s);
    if (!series_first_terms(&s)) {
        series_state_free(&s);
        return wrt_fail(WRT_ERR_IO, "the series could not read back its scratch copy of T");
    }
    if (s.tree) wrt_series_tree_start(&s);
    else if (!s.consumed) s.S = wrt_csc_copy(s.T);
    wrt_series_mark(&s, "first term");
    if (s.fac) {
        st = wrt_series_factored_check(&s);
        if (st != WRT_OK) {
            series_state_free(&s);
            return st;
        }
        wrt_series_factored_start(&s);
        if (b->opt.series_coarse > 0)
            series_coarse_cut(b, &s.Tr, res->fkeys, res->nfuncs, b->opt.series_coarse, 1);
        res->c.cluster_factored_entries = s.Tr.nnz;
        wrt_series_factored_bands(&s);
        wrt_series_mark(&s, "right factor");
        if (s.timing) fprintf(stderr, "series-times: E1 %llu entries\n", (unsigned long long)res->dto_e1.nnz);
    }
    series_share_start(&s);
    if (s.tree && s.share) /* the sum's first state, whole (wrt_series_tree_start): this rank's columns */
        wrt_series_tree_sum_start(&s, s.cut[b->opt.dist->rank], s.cut[b->opt.dist->rank + 1]);
    if (wrt_series_cols_on(&s)) { /* one block of columns through every bounce at a time */
        st = wrt_series_cols(&s);
        wrt_series_free_right(&s);
        if (st == WRT_OK && s.share) st = series_share_root(&s);
        if (st == WRT_OK) st = series_finish(&s);
    } else {
        st = series_bounces(&s);
        wrt_csc_mul_scratch_free();
        if (st == WRT_OK) st = series_tail(&s);
        if (st == WRT_OK) wrt_series_mark(&s, "tail and stored operator");
    }
    if (st == WRT_OK) st = series_gathered(&s);
    if (st != WRT_OK) {
        series_state_free(&s);
        return st;
    }
    if (s.tree) res->c.entries_gto = s.S.nnz; /* the senders' tree basis already */
    else if (b->cl && !b->opt.cluster_tree && b->opt.cluster_senders >= 0 && !b->opt.gathered &&
             !(s.share && b->opt.dist->rank != 0))
        wrt_series_senders(&s);
    if ((st = wrt_series_receivers(&s)) != WRT_OK) { /* where it applies (series_tree.c) */
        series_state_free(&s);
        return st;
    }
    if (b->cl && b->opt.cluster_tree && !(s.share && b->opt.dist->rank != 0)) {
        /* --clusters-tree-basis: the operator in the tree's basis, compressed there with
         * the tree's weights, is stored when it has fewer entries than in the quads' (else
         * the file keeps the quads' basis and no tree). Not by default: the trial costs a
         * copy and a transform of G - I, and it lost on every scene measured but closed
         * boxes (docs/clusters.md: on the maze asset at quality 5, 8.41M entries against
         * 7.30M; on cornell 0.87M against 0.84M) */
        wrt_csc Tt = wrt_csc_copy(&s.S);
        wrt_clusters_to_tree(b, b->cl, res->fkeys, Tt.n, &Tt);
        wrt_clusters_series_weights(b, b->cl, res->fkeys, Tt.n, s.rw, s.cw, s.pw, s.boost);
        res->c.cluster_tree_entries = Tt.nnz;
        wrt_csc_compress(&Tt, s.eps, &s.W);
        res->c.cluster_tree_compressed = Tt.nnz;
        if (Tt.nnz < s.S.nnz || b->opt.cluster_tree > 1) {
            wrt_csc_free(&s.S);
            s.S = Tt;
            res->c.cluster_tree_basis = 1;
            res->c.entries_gto = s.S.nnz;
        } else {
            wrt_csc_free(&Tt);
        }
    }
    res->op = s.S;
    memset(&s.S, 0, sizeof s.S);
    res->op_kind = b->opt.gathered ? WRT_GTO_OP_GATHERED : WRT_GTO_OP_INDIRECT;
    series_state_free(&s);
    return WRT_OK;
}
