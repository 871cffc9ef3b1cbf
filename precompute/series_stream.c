/* series_stream.c: the series' sum in a scratch file between bounces (series_stream.h).
 * Column j of S + s P depends on column j of S and of P alone, and so does column j of a
 * compression (its weights are the row's, the column's and the power the column moves
 * among its own entries), so the sum can be carried through by blocks of columns: a block
 * of S read back, merged with the same columns of the term in memory (wrt_csc_add3 on
 * the block: the same entries and roundings as wrt_csc_add3_into on the whole), written
 * to the next file, freed. The sum's norm is summed block after block in storage order,
 * as wrt_csc_norm sums it. Memory: a block, the term, and the column starts. Depends on
 * spill.h, sparse.h. */
#include "series_stream.h"

#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "../common/wrt_common.h"

void wrt_sum_stream_start(wrt_sum_stream *ss, wrt_spill *first, uint64_t block, int threads) {
    memset(ss, 0, sizeof *ss);
    ss->threads = threads;
    ss->cur = first;
    ss->block = block ? block : 1;
    ss->c1 = UINT32_MAX;
    ss->nnz = first->nnz;
}

void wrt_sum_stream_range(wrt_sum_stream *ss, uint32_t c0, uint32_t c1) {
    ss->c0 = c0;
    ss->c1 = c1;
}

uint64_t wrt_sum_stream_nnz(const wrt_sum_stream *ss) { return ss->nnz; }

static uint64_t overlay_cap(const wrt_sum_stream *ss) {
    return ss->c0 == 0 && ss->c1 == UINT32_MAX ? ss->nnz / WRT_SUM_OVERLAY_SHARE : 0;
}

/* The end of the block that starts at column j0: columns until the file's, the overlay's
 * and the term's entries in them reach the block size (one column at least). */
static uint32_t block_end_at(const wrt_sum_stream *ss, const wrt_csc *P, uint32_t j0, uint64_t block) {
    const uint64_t *c = ss->cur->col, *o = ss->over.col;
    uint32_t n = ss->cur->n, j1 = j0 + 1;
    while (j1 < n && (c[j1 + 1] - c[j0]) + (P ? P->col[j1 + 1] - P->col[j0] : 0) + (o ? o[j1 + 1] - o[j0] : 0) <= block)
        j1++;
    return j1;
}

static uint32_t block_end(const wrt_sum_stream *ss, const wrt_csc *P, uint32_t j0) {
    return block_end_at(ss, P, j0, ss->block);
}

/* An entry's three values appended to the outputs of merge3 */
typedef struct {
    wrt_csc *full; /* the whole block (columns from 0), or NULL */
    wrt_csc *ov;   /* the new overlay (the whole matrix's columns), or NULL */
    double *acc;   /* the squares' sum, or NULL */
} merge_out;

static inline void emit(merge_out *mo, uint32_t r, const float v[3]) {
    if (mo->full) {
        mo->full->row[mo->full->nnz] = r;
        memcpy(&mo->full->val[3 * mo->full->nnz++], v, 3 * sizeof *v);
    }
    if (mo->ov) {
        mo->ov->row[mo->ov->nnz] = r;
        memcpy(&mo->ov->val[3 * mo->ov->nnz++], v, 3 * sizeof *v);
    }
    if (mo->acc) /* wrt_csc_sumsq's order: entry after entry, channel after channel */
        for (int c = 0; c < 3; c++) *mo->acc += (double)v[c] * v[c];
}

/* Columns [j0, j1) of S + s P: a the file's block (columns from 0), o the overlay and p
 * the term (each NULL where there is none; their own column starts). An entry of the
 * overlay replaces the file's; a term's entry is added to the value there as
 * wrt_csc_add3 adds it, or is s times its own where there is none. Written to mo's
 * outputs: the full block, the entries in the overlay's or the term's places (the next
 * overlay), the squares. Returns the block's entries. */
static uint64_t merge3(const wrt_csc *a, const wrt_csc *o, const wrt_csc *p, const double s[3], uint32_t j0, uint32_t j1,
                       merge_out *mo) {
    uint64_t total = 0;
    if (mo->full) mo->full->nnz = 0;
    for (uint32_t j = j0; j < j1; j++) {
        uint64_t ia = a->col[j - j0], ea = a->col[j - j0 + 1];
        uint64_t io = o ? o->col[j] : 0, eo = o ? o->col[j + 1] : 0, ip = p ? p->col[j] : 0, ep = p ? p->col[j + 1] : 0;
        for (;;) {
            uint32_t ro = io < eo ? o->row[io] : UINT32_MAX, rp = ip < ep ? p->row[ip] : UINT32_MAX;
            uint32_t rn = ro < rp ? ro : rp;
            /* the file's entries before the next overlay or term entry, as one run */
            uint64_t run = ia;
            while (run < ea && a->row[run] < rn) run++;
            if (run > ia) {
                if (mo->full) {
                    memcpy(&mo->full->row[mo->full->nnz], &a->row[ia], (run - ia) * sizeof *a->row);
                    memcpy(&mo->full->val[3 * mo->full->nnz], &a->val[3 * ia], 3 * (run - ia) * sizeof *a->val);
                    mo->full->nnz += run - ia;
                }
                if (mo->acc) {
                    double acc = *mo->acc;
                    for (uint64_t i = 3 * ia; i < 3 * run; i++) acc += (double)a->val[i] * a->val[i];
                    *mo->acc = acc;
                }
                total += run - ia;
                ia = run;
            }
            if (rn == UINT32_MAX) break;
            float v[3];
            int have = 0;
            if (ia < ea && a->row[ia] == rn) {
                memcpy(v, &a->val[3 * ia++], sizeof v);
                have = 1;
            }
            if (ro == rn) {
                memcpy(v, &o->val[3 * io++], sizeof v);
                have = 1;
            }
            if (rp == rn) {
                const float *b = &p->val[3 * ip++];
                for (int c = 0; c < 3; c++) v[c] = have ? (float)((double)v[c] + s[c] * b[c]) : (float)(s[c] * b[c]);
            }
            emit(mo, rn, v);
            total++;
        }
        if (mo->full) mo->full->col[j - j0 + 1] = mo->full->nnz;
        if (mo->ov) mo->ov->col[j + 1] = mo->ov->nnz;
    }
    return total;
}

/* Columns [j0, j1) of S + s P (P may be NULL: S's block alone) into *m, from a, the
 * file's block (taken: freed, or become *m), and the overlay. */
static void merge_block(const wrt_sum_stream *ss, const wrt_csc *P, const double s[3], uint32_t j0, uint32_t j1,
                        wrt_csc *a, wrt_csc *m) {
    const wrt_csc *o = ss->over.col ? &ss->over : NULL;
    if (!P && !o) {
        *m = *a;
        memset(a, 0, sizeof *a);
        return;
    }
    uint64_t cap = a->nnz + (P ? P->col[j1] - P->col[j0] : 0) + (o ? o->col[j1] - o->col[j0] : 0);
    *m = (wrt_csc){.n = j1 - j0};
    m->col = wrt_xcalloc((size_t)m->n + 1, sizeof *m->col);
    m->row = wrt_xmalloc((cap ? cap : 1) * sizeof *m->row);
    m->val = wrt_xmalloc((cap ? cap : 1) * 3 * sizeof *m->val);
    merge_out mo = {m, NULL, NULL};
    merge3(a, o, P, s, j0, j1, &mo);
    wrt_csc_free(a);
}

/* The same, the file's block read in order first. 0 on a read error. */
static int merged_block(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], uint32_t j0, uint32_t j1, wrt_csc *m) {
    wrt_csc a;
    if (!wrt_spill_read(ss->cur, j1 - j0, &a)) return 0;
    merge_block(ss, P, s, j0, j1, &a, m);
    return 1;
}

/* The block's columns outside the kept range [c0, c1) emptied (block m starts at column j0) */
static void keep_range(const wrt_sum_stream *ss, uint32_t j0, wrt_csc *m) {
    if (ss->c0 <= j0 && (uint64_t)j0 + m->n <= ss->c1) return;
    uint64_t w = 0, k = 0;
    for (uint32_t c = 0; c < m->n; c++) {
        uint64_t end = m->col[c + 1];
        int keep = j0 + c >= ss->c0 && j0 + c < ss->c1;
        for (; k < end; k++) {
            if (!keep) continue;
            m->row[w] = m->row[k];
            memmove(&m->val[3 * w], &m->val[3 * k], 3 * sizeof *m->val);
            w++;
        }
        m->col[c + 1] = w;
    }
    m->nnz = w;
}

int wrt_sum_stream_sumsq(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq) {
    if (!wrt_spill_rewind(ss->cur)) return 0;
    double acc = *sumsq;
    for (uint32_t j0 = 0, n = ss->cur->n; j0 < n;) {
        uint32_t j1 = block_end(ss, P, j0);
        wrt_csc m;
        if (!merged_block(ss, P, s, j0, j1, &m)) return 0;
        keep_range(ss, j0, &m);
        acc = wrt_csc_sumsq(&m, acc);
        wrt_csc_free(&m);
        j0 = j1;
    }
    *sumsq = acc;
    return 1;
}

/* S += s P into the overlay: the file read block by block, the next overlay made of the
 * entries in the old one's or P's places, the squares summed on the way. */
static int add_to_overlay(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq) {
    if (!wrt_spill_rewind(ss->cur)) return 0;
    uint32_t n = ss->cur->n;
    const wrt_csc *o = ss->over.col ? &ss->over : NULL;
    uint64_t cap = P->nnz + (o ? o->nnz : 0), total = 0;
    wrt_csc ov = {.n = n};
    ov.col = wrt_xcalloc((size_t)n + 1, sizeof *ov.col);
    ov.row = wrt_xmalloc((cap ? cap : 1) * sizeof *ov.row);
    ov.val = wrt_xmalloc((cap ? cap : 1) * 3 * sizeof *ov.val);
    double acc = 0;
    merge_out mo = {NULL, &ov, &acc};
    for (uint32_t j0 = 0; j0 < n;) {
        uint32_t j1 = block_end(ss, P, j0);
        wrt_csc a;
        if (!wrt_spill_read(ss->cur, j1 - j0, &a)) {
            wrt_csc_free(&ov);
            return 0;
        }
        total += merge3(&a, o, P, s, j0, j1, &mo);
        wrt_csc_free(&a);
        j0 = j1;
    }
    ov.nnz = ov.col[n];
    ov.row = wrt_xrealloc(ov.row, (ov.nnz ? ov.nnz : 1) * sizeof *ov.row);
    ov.val = wrt_xrealloc(ov.val, (ov.nnz ? ov.nnz : 1) * 3 * sizeof *ov.val);
    wrt_csc_free(&ss->over);
    ss->over = ov;
    ss->nnz = total;
    ss->kept++;
    *sumsq = acc;
    return 1;
}

int wrt_sum_stream_add(wrt_sum_stream *ss, const wrt_csc *P, const double s[3], double *sumsq) {
    if (P->nnz + ss->over.nnz <= overlay_cap(ss)) return add_to_overlay(ss, P, s, sumsq);
    wrt_spill next;
    if (!wrt_spill_rewind(ss->cur) || !wrt_spill_open(&next, ss->cur->n)) return 0;
    double acc = 0;
    int ok = 1;
    for (uint32_t j0 = 0, n = ss->cur->n; j0 < n && ok;) {
        uint32_t j1 = block_end(ss, P, j0);
        wrt_csc m;
        ok = merged_block(ss, P, s, j0, j1, &m);
        if (!ok) break;
        keep_range(ss, j0, &m);
        acc = wrt_csc_sumsq(&m, acc);
        ok = wrt_spill_append(&next, &m);
        wrt_csc_free(&m);
        j0 = j1;
    }
    if (ok) ok = wrt_spill_finish(&next);
    if (!ok) {
        wrt_spill_free(&next);
        return 0;
    }
    if (ss->cur == &ss->own) wrt_spill_free(&ss->own);
    ss->own = next;
    ss->cur = &ss->own;
    wrt_csc_free(&ss->over); /* in the file now */
    ss->nnz = ss->own.nnz;
    ss->written++;
    *sumsq = acc;
    return 1;
}

/* The last pass's blocks, WRT_SUM_FINAL_GROUP at a time and each that much smaller (the
 * memory of one block of before): read in order (the next group while this one is
 * worked on), then merged on the stream's threads, their squares summed in order,
 * compressed on the threads, appended in order. */
#define FINAL_GROUP WRT_SUM_FINAL_GROUP
typedef struct {
    const wrt_sum_stream *ss;
    const wrt_csc *P;
    const double *k;
    double drop;
    const wrt_csc_weights *W;
    int stage; /* 0: merge, 1: compress */
    uint32_t j0[FINAL_GROUP], j1[FINAL_GROUP];
    wrt_csc a[FINAL_GROUP], m[FINAL_GROUP];
} final_group;

static void final_item(size_t i, int th, void *user) {
    (void)th;
    final_group *g = user;
    uint32_t j0 = g->j0[i];
    if (g->stage == 0) {
        merge_block(g->ss, g->P, g->k, j0, g->j1[i], &g->a[i], &g->m[i]);
        keep_range(g->ss, j0, &g->m[i]);
        return;
    }
    /* the block's columns compressed with their own column weights */
    const wrt_csc_weights *W = g->W;
    wrt_csc_weights wb = {0};
    if (W)
        wb = (wrt_csc_weights){W->row_w, W->col_w ? W->col_w + j0 : NULL, W->power_w,
                               W->boost_w ? W->boost_w + j0 : NULL, W->boost_lost, NULL, 0};
    wrt_csc_compress(&g->m[i], g->drop, W ? &wb : NULL);
}

/* The last pass's next group of blocks read from the sum's file (on a thread of its own
 * while the group before is merged and compressed: the file is read by nothing else
 * then). ok 0 on a read error, the blocks read so far kept for freeing. */
typedef struct {
    wrt_sum_stream *ss;
    const wrt_csc *P;
    uint32_t j0;        /* the group's first column; past its last after the read */
    size_t ng;
    int ok;
    uint32_t b0[FINAL_GROUP], b1[FINAL_GROUP];
    wrt_csc a[FINAL_GROUP];
} group_read;

static void group_read_run(void *user) {
    group_read *r = user;
    uint32_t n = r->ss->cur->n;
    r->ok = 1;
    for (r->ng = 0; r->ng < FINAL_GROUP && r->j0 < n; r->ng++) {
        uint32_t j1 = block_end_at(r->ss, r->P, r->j0, (r->ss->block + FINAL_GROUP - 1) / FINAL_GROUP);
        if (!wrt_spill_read(r->ss->cur, j1 - r->j0, &r->a[r->ng])) {
            r->ok = 0;
            break;
        }
        r->b0[r->ng] = r->j0;
        r->b1[r->ng] = j1;
        r->j0 = j1;
    }
}

static void group_read_free(group_read *r) {
    for (size_t i = 0; i < r->ng; i++) wrt_csc_free(&r->a[i]);
    r->ng = 0;
}

int wrt_sum_stream_final(wrt_sum_stream *ss, const wrt_csc *P, const double k[3], double *sumsq, double drop,
                         const wrt_csc_weights *W, int (*check)(void *user, uint64_t kept, uint64_t projected),
                         void *user, wrt_csc *out) {
    uint32_t n = ss->cur->n;
    memset(out, 0, sizeof *out);
    if (!wrt_spill_rewind(ss->cur)) return 0;
    out->n = n;
    out->col = wrt_xcalloc((size_t)n + 1, sizeof *out->col);
    uint64_t cap = 1, total = ss->cur->nnz + ss->over.nnz + (P ? P->nnz : 0), done = 0, last = 0;
    out->row = wrt_xmalloc(cap * sizeof *out->row);
    out->val = wrt_xmalloc(3 * cap * sizeof *out->val);
    double acc = 0;
    int ret = 1, ahead = wrt_threads_resolve(ss->threads) > 1;
    final_group g = {.ss = ss, .P = P, .k = k, .drop = drop, .W = W};
    group_read cur = {.ss = ss, .P = P, .j0 = 0};
    group_read_run(&cur);
    while (ret == 1) {
        if (!cur.ok) {
            group_read_free(&cur);
            ret = 0;
            break;
        }
        size_t ng = cur.ng;
        if (!ng) break;
        /* the next group read beside this one's merge and compression */
        group_read next = {.ss = ss, .P = P, .j0 = cur.j0};
        wrt_task task;
        int more = next.j0 < n;
        if (more && ahead) wrt_task_start(&task, group_read_run, &next);
        for (size_t i = 0; i < ng; i++) {
            g.j0[i] = cur.b0[i];
            g.j1[i] = cur.b1[i];
            g.a[i] = cur.a[i];
        }
        g.stage = 0;
        wrt_parallel_for(ng, ss->threads, final_item, &g);
        if (P)
            for (size_t i = 0; i < ng; i++) acc = wrt_csc_sumsq(&g.m[i], acc);
        g.stage = 1;
        wrt_parallel_for(ng, ss->threads, final_item, &g);
        for (size_t i = 0; i < ng; i++) {
            wrt_csc *m = &g.m[i];
            uint32_t b0 = g.j0[i], b1 = g.j1[i];
            if (ret == 1) {
                done += (ss->cur->col[b1] - ss->cur->col[b0]) + (P ? P->col[b1] - P->col[b0] : 0) +
                        (ss->over.col ? ss->over.col[b1] - ss->over.col[b0] : 0);
                if (out->nnz + m->nnz > cap) {
                    while (cap < out->nnz + m->nnz) cap *= 2;
                    out->row = wrt_xrealloc(out->row, cap * sizeof *out->row);
                    out->val = wrt_xrealloc(out->val, 3 * cap * sizeof *out->val);
                }
                memcpy(&out->row[out->nnz], m->row, m->nnz * sizeof *m->row);
                memcpy(&out->val[3 * out->nnz], m->val, 3 * m->nnz * sizeof *m->val);
                for (uint32_t j = b0; j < b1; j++) out->col[j + 1] = out->nnz + m->col[j - b0 + 1];
                out->nnz += m->nnz;
                /* at each tenth of the input, the kept entries' total projected from there
                 * (the first tenth: what is kept so far) */
                uint64_t tenth = total ? done * 10 / total : 10;
                if (tenth != last) {
                    last = tenth;
                    uint64_t projected = tenth ? (uint64_t)((double)out->nnz * (double)total / (double)done) : out->nnz;
                    if (check && !check(user, out->nnz, projected)) ret = -1;
                }
            }
            wrt_csc_free(m);
        }
        if (more && ahead) wrt_task_join(&task);
        else if (more && ret == 1) group_read_run(&next);
        else next.ok = 1;
        cur = next;
        if (ret != 1) group_read_free(&cur);
    }
    if (ret != 1) {
        wrt_csc_free(out);
        return ret;
    }
    /* the arrays cut to the entries */
    out->row = wrt_xrealloc(out->row, (out->nnz ? out->nnz : 1) * sizeof *out->row);
    out->val = wrt_xrealloc(out->val, 3 * (out->nnz ? out->nnz : 1) * sizeof *out->val);
    if (P) *sumsq = acc;
    return 1;
}

void wrt_sum_stream_free(wrt_sum_stream *ss) {
    wrt_spill_free(&ss->own);
    wrt_csc_free(&ss->over);
    memset(ss, 0, sizeof *ss);
}
