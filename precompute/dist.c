/* dist.c: the bake's work divided among ranks and merged back (dist.h, docs/mpi.md):
 * the shares by estimated cost, and the series' products by columns, gathered so that
 * every rank holds the product the single process computes. No MPI here: the ranks
 * talk through the caller's all-gather. */
#include <stdlib.h>
#include <time.h>
#include <string.h>

#include "dist.h"
#include "dto.h"

typedef struct cost_item { double cost; uint64_t i; } cost_item;

static int cmp_cost_desc(const void *pa, const void *pb) {
    const cost_item *a = pa, *b = pb;
    if (a->cost != b->cost) return a->cost > b->cost ? -1 : 1;
    return a->i < b->i ? -1 : a->i > b->i;
}

/* The prologue of every merge: the all-gather of this rank's `len` bytes at `mine`; every
 * rank's bytes in rank order in *all and their counts in *lens (both malloc'd, freed by
 * the caller; neither set on failure), the bytes sent and received counted in `phase`. */
static wrt_status dist_exchange(wrt_bake_dist *d, int phase, const void *mine, uint64_t len, uint8_t **all,
                                uint64_t **lens) {
    int nr = d->nranks;
    uint64_t *l = wrt_xcalloc((size_t)nr, sizeof *l);
    void *a = NULL;
    wrt_status st = d->allgather(d->user, mine, len, &a, l);
    if (st != WRT_OK) { free(a); free(l); return st; }
    d->bytes_sent[phase] += len * (uint64_t)(nr - 1);
    for (int r = 0; r < nr; r++)
        if (r != d->rank) d->bytes_recv[phase] += l[r];
    *all = a;
    *lens = l;
    return WRT_OK;
}

void wrt_dist_assign(const double *cost, uint64_t n, int nranks, int *owner) {
    cost_item *it = wrt_xmalloc((n ? n : 1) * sizeof *it);
    for (uint64_t i = 0; i < n; i++) it[i] = (cost_item){cost[i], i};
    qsort(it, n, sizeof *it, cmp_cost_desc);
    double *load = wrt_xcalloc((size_t)nranks, sizeof *load);
    for (uint64_t k = 0; k < n; k++) {
        int best = 0;
        for (int r = 1; r < nranks; r++)
            if (load[r] < load[best]) best = r;
        load[best] += it[k].cost;
        owner[it[k].i] = best;
    }
    free(load);
    free(it);
}

void wrt_dist_mul_cuts(const wrt_csc *a, const wrt_csc *b, int nranks, uint32_t *cut) {
    uint32_t n = b->n;
    double total = 0;
    for (uint32_t j = 0; j < n; j++)
        for (uint64_t k = b->col[j]; k < b->col[j + 1]; k++) total += 1.0 + (double)(a->col[b->row[k] + 1] - a->col[b->row[k]]);
    /* rank r's columns end where the running cost first reaches (r + 1) / nranks of it */
    double run = 0;
    int r = 0;
    cut[0] = 0;
    for (uint32_t j = 0; j < n && r < nranks - 1; j++) {
        for (uint64_t k = b->col[j]; k < b->col[j + 1]; k++) run += 1.0 + (double)(a->col[b->row[k] + 1] - a->col[b->row[k]]);
        while (r < nranks - 1 && run >= total * (double)(r + 1) / nranks) cut[++r] = j + 1;
    }
    while (r < nranks - 1) cut[++r] = n;
    cut[nranks] = n;
}

/* A rank's columns [c0, c1) of m as bytes: the counts (uint32 each), then the rows, then
 * the values. */
static void *pack_columns(const wrt_csc *m, uint32_t c0, uint32_t c1, uint64_t *len) {
    uint64_t nnz = m->col[c1] - m->col[c0];
    *len = (uint64_t)(c1 - c0) * 4 + nnz * 4 + nnz * 12;
    uint8_t *buf = wrt_xmalloc(*len ? *len : 1), *p = buf;
    for (uint32_t j = c0; j < c1; j++) {
        uint32_t cnt = (uint32_t)(m->col[j + 1] - m->col[j]);
        memcpy(p, &cnt, 4);
        p += 4;
    }
    memcpy(p, m->row + m->col[c0], nnz * 4);
    p += nnz * 4;
    memcpy(p, m->val + 3 * m->col[c0], nnz * 12);
    return buf;
}

wrt_status wrt_dist_mul(wrt_bake_dist *d, const wrt_csc *a, const wrt_csc *b, double drop, const wrt_csc_weights *w,
                        int threads, wrt_csc *out) {
    int nr = d->nranks;
    uint32_t *cut = wrt_xmalloc(((size_t)nr + 1) * sizeof *cut);
    wrt_dist_mul_cuts(a, b, nr, cut);
    wrt_csc mine = wrt_csc_mul_cols(a, b, drop, w, threads, cut[d->rank], cut[d->rank + 1]);
    uint64_t len;
    void *buf = pack_columns(&mine, cut[d->rank], cut[d->rank + 1], &len);
    wrt_csc_free(&mine);
    uint8_t *all;
    uint64_t *lens;
    wrt_status st = dist_exchange(d, WRT_DIST_SERIES, buf, len, &all, &lens);
    free(buf);
    if (st != WRT_OK) { free(cut); return st; }
    /* the columns in order: rank r's block holds columns cut[r] .. cut[r + 1] */
    uint32_t n = a->n;
    wrt_csc m = {.n = n};
    m.col = wrt_xcalloc((size_t)n + 1, sizeof *m.col);
    uint64_t total = 0;
    for (int r = 0; r < nr; r++) total += (lens[r] - 4ull * (cut[r + 1] - cut[r])) / 16;
    m.nnz = total;
    m.row = wrt_xmalloc((total ? total : 1) * sizeof *m.row);
    m.val = wrt_xmalloc((total ? total : 1) * 3 * sizeof *m.val);
    const uint8_t *p = all;
    for (int r = 0; r < nr; r++) {
        uint32_t c0 = cut[r], c1 = cut[r + 1];
        uint64_t nnz = (lens[r] - 4ull * (c1 - c0)) / 16, at = m.col[c0];
        for (uint32_t j = c0; j < c1; j++) {
            uint32_t cnt;
            memcpy(&cnt, p + 4ull * (j - c0), 4);
            m.col[j + 1] = m.col[j] + cnt;
        }
        p += 4ull * (c1 - c0);
        memcpy(m.row + at, p, nnz * 4);
        p += nnz * 4;
        memcpy(m.val + 3 * at, p, nnz * 12);
        p += nnz * 12;
    }
    free(all); free(lens); free(cut);
    *out = m;
    return WRT_OK;
}

wrt_status wrt_dist_sum_u64(wrt_bake_dist *d, uint64_t *v, int n) {
    uint8_t *all;
    uint64_t *lens;
    wrt_status st = dist_exchange(d, WRT_DIST_COUNTERS, v, (uint64_t)n * 8, &all, &lens);
    if (st != WRT_OK) return st;
    for (int i = 0; i < n; i++) v[i] = 0;
    for (int r = 0; r < d->nranks; r++)
        for (int i = 0; i < n; i++) {
            uint64_t x;
            memcpy(&x, all + 8 * ((size_t)r * n + i), 8);
            v[i] += x;
        }
    free(all); free(lens);
    return WRT_OK;
}

/* ---------------------------------------------------------------- per-item records */

/* The bytes all the ranks send together in one round of a merge (wrt_bake_dist.piece_bytes;
 * 0: this), each rank a share (at least 64 KiB); an item larger than its share goes alone. */
#define DIST_ROUND_BYTES ((uint64_t)32 << 20)

/* The items from `from` on that this rank owns and that fit in one piece (at least one):
 * their bytes with headers in *len; returns the index after the last taken. */
static size_t piece_end(const wrt_bake_dist *d, const int *owner, size_t n, const wrt_dist_items *f, size_t from,
                        uint64_t cap, uint64_t *len) {
    uint64_t l = 0;
    size_t i = from;
    for (; i < n; i++) {
        if (owner[i] != d->rank) continue;
        uint64_t sz = 16 + f->size(f->user, i);
        if (l && l + sz > cap) break;
        l += sz;
    }
    *len = l;
    return i;
}

/* In rounds: each rank sends about piece_bytes / nranks a round (its items in index
 * order), and each round's items are unpacked before the next is gathered, so a rank
 * holds the merged items and one round's bytes, not every rank's bytes at once beside
 * them (on the 12 x 12 maze the whole gather set a rank's peak: docs/mpi.md). The rounds'
 * count is agreed first (the most any rank needs). */
wrt_status wrt_dist_merge_items(wrt_bake_dist *d, int phase, const int *owner, size_t n, const wrt_dist_items *f) {
    uint64_t cap = (d->piece_bytes ? d->piece_bytes : DIST_ROUND_BYTES) / (uint64_t)d->nranks, len, rounds = 0;
    if (cap < 65536 && !d->piece_bytes) cap = 65536;
    for (size_t i = 0; i < n; rounds++) {
        i = piece_end(d, owner, n, f, i, cap, &len);
        if (!len) break;
    }
    uint8_t *all;
    uint64_t *lens;
    wrt_status st = dist_exchange(d, phase, &rounds, 8, &all, &lens);
    if (st != WRT_OK) return st;
    uint64_t most = 0;
    for (int r = 0; r < d->nranks; r++) {
        uint64_t x;
        memcpy(&x, all + 8 * (size_t)r, 8);
        if (x > most) most = x;
    }
    free(all); free(lens);
    size_t next = 0;
    for (uint64_t k = 0; k < most && st == WRT_OK; k++) {
        size_t end = piece_end(d, owner, n, f, next, cap, &len);
        uint8_t *buf = wrt_xmalloc(len ? len : 1), *p = buf;
        for (size_t i = next; i < end; i++) {
            if (owner[i] != d->rank) continue;
            uint64_t h[2] = {i, f->size(f->user, i)};
            memcpy(p, h, 16);
            f->pack(f->user, i, p + 16);
            p += 16 + h[1];
        }
        next = end;
        st = dist_exchange(d, phase, buf, len, &all, &lens);
        free(buf);
        if (st != WRT_OK) break;
        const uint8_t *q = all;
        for (int r = 0; r < d->nranks; r++) {
            const uint8_t *stop = q + lens[r];
            if (r == d->rank) { q = stop; continue; }
            while (q < stop) {
                uint64_t h[2];
                memcpy(h, q, 16);
                f->unpack(f->user, (size_t)h[0], q + 16, h[1]);
                q += 16 + h[1];
            }
        }
        free(all); free(lens);
    }
    return st;
}

/* ---------------------------------------------------------------- the DTO's pairs */

/* One pair's record: its sizes and flags, then its entries (a diffuse pair's compact
 * records, 16 bytes for up to two entries, as the DTO keeps them; else full entries) and
 * its leaves. */
typedef struct pair_head {
    uint64_t count, nd, nleaf, links, angular;
    int32_t r, s, occluded, leaf_dirs, glossy, kmode, cancelled, compact;
} pair_head;

static uint64_t pair_size(void *user, size_t i) {
    const pair_out *o = (const pair_out *)user + i;
    return sizeof(pair_head) + wrt_pair_bytes(o) + o->nleaf * sizeof(leaf_rec);
}

static void pair_pack(void *user, size_t i, uint8_t *p) {
    const pair_out *o = (const pair_out *)user + i;
    pair_head h = {o->count, o->nd, o->nleaf, o->links, o->angular, o->r, o->s, o->occluded, o->leaf_dirs, o->glossy,
                   o->kmode, o->cancelled, o->d != NULL};
    memcpy(p, &h, sizeof h);
    p += sizeof h;
    uint64_t eb = wrt_pair_bytes(o);
    if (eb) memcpy(p, o->d ? (const void *)o->d : (const void *)o->e, eb);
    p += eb;
    if (o->nleaf) memcpy(p, o->leaf, o->nleaf * sizeof(leaf_rec));
}

static void pair_unpack(void *user, size_t i, const uint8_t *q, uint64_t len) {
    (void)len;
    pair_out *o = (pair_out *)user + i;
    pair_head h;
    memcpy(&h, q, sizeof h);
    q += sizeof h;
    *o = (pair_out){.count = h.count, .nleaf = h.nleaf, .links = h.links, .angular = h.angular, .r = h.r, .s = h.s,
                    .occluded = h.occluded, .leaf_dirs = h.leaf_dirs, .glossy = h.glossy, .kmode = h.kmode,
                    .cancelled = h.cancelled};
    if (h.compact) {
        o->nd = h.nd;
        o->d = wrt_xmalloc((h.nd ? h.nd : 1) * sizeof(pair_dent));
        if (h.nd) memcpy(o->d, q, h.nd * sizeof(pair_dent));
    } else if (h.count) {
        o->e = wrt_xmalloc(h.count * sizeof(pair_entry));
        memcpy(o->e, q, h.count * sizeof(pair_entry));
    }
    q += wrt_pair_bytes(o);
    o->leaf = h.nleaf ? wrt_xmalloc(h.nleaf * sizeof(leaf_rec)) : NULL;
    if (h.nleaf) memcpy(o->leaf, q, h.nleaf * sizeof(leaf_rec));
}

wrt_status wrt_dist_merge_pairs(wrt_bake_dist *d, const int *owner, pair_out *out, size_t np) {
    wrt_dist_items f = {pair_size, pair_pack, pair_unpack, out};
    return wrt_dist_merge_items(d, WRT_DIST_DTO, owner, np, &f);
}

double wrt_dist_cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---------------------------------------------------------------- per-item triplets */

typedef struct trip_items { wrt_triplet **res; uint64_t *nres; } trip_items;

static uint64_t trip_size(void *user, size_t s) { return ((trip_items *)user)->nres[s] * sizeof(wrt_triplet); }

static void trip_pack(void *user, size_t s, uint8_t *p) {
    trip_items *t = user;
    if (t->nres[s]) memcpy(p, t->res[s], t->nres[s] * sizeof(wrt_triplet));
}

static void trip_unpack(void *user, size_t s, const uint8_t *q, uint64_t len) {
    trip_items *t = user;
    uint64_t n = len / sizeof(wrt_triplet);
    free(t->res[s]);
    t->nres[s] = n;
    t->res[s] = n ? wrt_xmalloc(n * sizeof(wrt_triplet)) : NULL;
    if (n) memcpy(t->res[s], q, n * sizeof(wrt_triplet));
}

wrt_status wrt_dist_merge_triplets(wrt_bake_dist *d, const int *owner, wrt_triplet **res, uint64_t *nres, size_t n) {
    trip_items t = {res, nres};
    wrt_dist_items f = {trip_size, trip_pack, trip_unpack, &t};
    return wrt_dist_merge_items(d, WRT_DIST_DTO, owner, n, &f);
}

uint8_t *wrt_dist_gather_rows(wrt_bake_dist *d, const int *owner, size_t nrows, const uint8_t *mine, size_t width) {
    uint64_t len = 0;
    for (size_t i = 0; i < nrows; i++) len += owner[i] == d->rank ? width : 0;
    int nr = d->nranks;
    uint8_t *all;
    uint64_t *lens;
    if (dist_exchange(d, WRT_DIST_DTO, mine, len, &all, &lens) != WRT_OK) return NULL;
    uint64_t *at = wrt_xcalloc((size_t)nr, sizeof *at);
    for (int r = 1; r < nr; r++) at[r] = at[r - 1] + lens[r - 1];
    uint8_t *rows = wrt_xmalloc(nrows * width + 1);
    for (size_t i = 0; i < nrows; i++) {
        memcpy(rows + i * width, all + at[owner[i]], width); /* a rank's rows in their order */
        at[owner[i]] += width;
    }
    free(at); free(lens); free(all);
    return rows;
}

/* ---------------------------------------------------------------- the series by shares */

uint8_t *wrt_dist_share_need(const wrt_csc *r, int nranks, const uint32_t *cut) {
    size_t n = r->n;
    uint8_t *need = wrt_xcalloc((size_t)nranks * n + 1, 1);
    for (int q = 0; q < nranks; q++)
        for (uint32_t j = cut[q]; j < cut[q + 1]; j++)
            for (uint64_t k = r->col[j]; k < r->col[j + 1]; k++) need[(size_t)q * n + r->row[k]] = 1;
    return need;
}

/* A column's record: its index and count (uint32 each), its rows, its values */
static uint64_t col_record_size(const wrt_csc *m, uint32_t j) { return 8 + 16 * (m->col[j + 1] - m->col[j]); }

static uint8_t *col_record_put(const wrt_csc *m, uint32_t j, uint8_t *p) {
    uint32_t cnt = (uint32_t)(m->col[j + 1] - m->col[j]);
    memcpy(p, &j, 4);
    memcpy(p + 4, &cnt, 4);
    p += 8;
    memcpy(p, m->row + m->col[j], (size_t)cnt * 4);
    p += (size_t)cnt * 4;
    memcpy(p, m->val + 3 * m->col[j], (size_t)cnt * 12);
    return p + (size_t)cnt * 12;
}

/* A sender's place in its records: the receiver q it packs for, and the column from which */
typedef struct share_cursor { int q; uint32_t j; } share_cursor;

typedef int (*share_want)(const void *user, int q, uint32_t j);

/* Packs (p non-NULL) or counts this rank's records from *c on, receivers in order and each
 * one's columns ascending, while they fit in cap bytes (at least one record); a
 * receiver's bytes in sl[q] (added to), its entries in ent[q] (when non-NULL); returns the
 * bytes taken. */
static uint64_t share_piece(const wrt_bake_dist *d, const wrt_csc *own, const uint32_t *cut, share_want want,
                            const void *user, share_cursor *c, uint64_t cap, uint8_t *p, uint64_t *sl, uint64_t *ent) {
    uint64_t l = 0;
    uint32_t c1 = cut[d->rank + 1];
    for (; c->q < d->nranks; c->q++, c->j = cut[d->rank]) {
        for (; c->j < c1; c->j++) {
            uint32_t j = c->j;
            if (own->col[j + 1] == own->col[j] || !want(user, c->q, j)) continue;
            uint64_t sz = col_record_size(own, j);
            if (l && l + sz > cap) return l;
            if (p) p = col_record_put(own, j, p);
            l += sz;
            sl[c->q] += sz;
            if (ent) ent[c->q] += own->col[j + 1] - own->col[j];
        }
    }
    return l;
}

/* Puts the records in `buf` (len bytes, one sender's, columns ascending) into m's arrays
 * from entry *at on, their counts into cnt[j + 1] */
static void col_records_place(wrt_csc *m, uint64_t *cnt, uint64_t *at, const uint8_t *buf, uint64_t len) {
    for (const uint8_t *p = buf; p < buf + len;) {
        uint32_t h[2];
        memcpy(h, p, 8);
        p += 8;
        cnt[h[0] + 1] = h[1];
        memcpy(m->row + *at, p, (size_t)h[1] * 4);
        p += (size_t)h[1] * 4;
        memcpy(m->val + 3 * *at, p, (size_t)h[1] * 12);
        p += (size_t)h[1] * 12;
        *at += h[1];
    }
}

/* The exchange of the columns that want(q, j) picks among this rank's, streamed: in
 * rounds of an all-to-all where each rank sends at most piece_bytes / nranks (its records
 * in receiver and column order), each round's records put straight into *in at their
 * sender's place (the ranks' ranges are in column order) and freed before the next. Each
 * rank's entries for every other and its rounds go first (an all-gather), so *in is made
 * once at its size and every rank takes the same turns. A rank holds its share, the
 * matrix it builds and one round, not the records it sends (on the atrium at detail 1.5
 * the sender's whole buffer, its range about three times over, set the peak:
 * docs/mpi.md); with free_own, its share is freed once sent. */
static wrt_status share_send(wrt_bake_dist *d, wrt_csc *own, int free_own, const uint32_t *cut, share_want want,
                             const void *user, wrt_csc *in) {
    int nr = d->nranks, me = d->rank;
    uint32_t n = own->n;
    uint64_t cap = (d->piece_bytes ? d->piece_bytes : DIST_ROUND_BYTES) / (uint64_t)nr;
    if (cap < 65536 && !d->piece_bytes) cap = 65536;
    uint64_t *sl = wrt_xcalloc((size_t)nr, sizeof *sl), *rl = wrt_xcalloc((size_t)nr, sizeof *rl);
    /* what every rank tells the others: its rounds, then its entries for each rank */
    uint64_t *head = wrt_xcalloc((size_t)nr + 1, sizeof *head);
    share_cursor c = {0, cut[me]};
    while (share_piece(d, own, cut, want, user, &c, cap, NULL, sl, head + 1)) head[0]++;
    uint8_t *all;
    uint64_t *lens;
    wrt_status st = dist_exchange(d, WRT_DIST_SERIES, head, ((uint64_t)nr + 1) * 8, &all, &lens);
    free(head);
    wrt_csc m = {.n = n};
    uint64_t *cnt = wrt_xcalloc((size_t)n + 1, sizeof *cnt), *at = wrt_xcalloc((size_t)nr, sizeof *at), rounds = 0;
    if (st == WRT_OK) {
        uint64_t total = 0;
        for (int t = 0; t < nr; t++) {
            uint64_t h[2];
            memcpy(&h[0], all + 8 * ((size_t)t * (nr + 1)), 8);
            memcpy(&h[1], all + 8 * ((size_t)t * (nr + 1) + 1 + me), 8);
            if (h[0] > rounds) rounds = h[0];
            at[t] = total; /* rank t's columns go after the lower ranks' */
            total += h[1];
        }
        free(all); free(lens);
        m.nnz = total;
        m.row = wrt_xmalloc((total + 1) * sizeof *m.row);
        m.val = wrt_xmalloc((total + 1) * 3 * sizeof *m.val);
    }
    c = (share_cursor){0, cut[me]};
    for (uint64_t k = 0; k < rounds && st == WRT_OK; k++) {
        memset(sl, 0, (size_t)nr * sizeof *sl);
        share_cursor c0 = c;
        uint64_t len = own->col ? share_piece(d, own, cut, want, user, &c, cap, NULL, sl, NULL) : 0;
        uint8_t *buf = wrt_xmalloc(len ? len : 1);
        if (len) {
            memset(sl, 0, (size_t)nr * sizeof *sl);
            share_piece(d, own, cut, want, user, &c0, cap, buf, sl, NULL);
        }
        if (free_own && c.q == nr) wrt_csc_free(own); /* every record sent: the share is done */
        void *rv = NULL;
        st = d->alltoall(d->user, buf, sl, &rv, rl);
        free(buf);
        if (st == WRT_OK) {
            const uint8_t *p = rv;
            for (int t = 0; t < nr; t++) {
                if (t != me) {
                    d->bytes_sent[WRT_DIST_SERIES] += sl[t];
                    d->bytes_recv[WRT_DIST_SERIES] += rl[t];
                }
                col_records_place(&m, cnt, &at[t], p, rl[t]);
                p += rl[t];
            }
        }
        free(rv);
    }
    if (free_own && own->col) wrt_csc_free(own);
    free(sl); free(rl); free(at);
    if (st != WRT_OK) {
        free(cnt);
        wrt_csc_free(&m);
        return st;
    }
    m.col = cnt;
    for (uint32_t j = 0; j < n; j++) m.col[j + 1] += m.col[j];
    *in = m;
    return WRT_OK;
}

typedef struct need_user { const uint8_t *need; uint32_t n; int self; } need_user;

/* a rank's own columns all go to itself (the term's share the caller may then free) */
static int want_needed(const void *user, int q, uint32_t j) {
    const need_user *u = user;
    return q == u->self || u->need[(size_t)q * u->n + j];
}

wrt_status wrt_dist_share_fetch(wrt_bake_dist *d, const wrt_csc *own, const uint32_t *cut, const uint8_t *need,
                                wrt_csc *in) {
    need_user u = {need, own->n, d->rank};
    return share_send(d, (wrt_csc *)own, 0, cut, want_needed, &u, in);
}

static int want_root(const void *user, int q, uint32_t j) {
    (void)user; (void)j;
    return q == 0;
}

wrt_status wrt_dist_share_to_root(wrt_bake_dist *d, wrt_csc *own, const uint32_t *cut, wrt_csc *all) {
    return share_send(d, own, 1, cut, want_root, NULL, all);
}

wrt_status wrt_dist_chain_sum(wrt_bake_dist *d, double *acc, int (*fn)(void *user, double *acc), void *user) {
    for (int t = 0; t < d->nranks; t++) {
        /* rank t's running sum and whether it could be made */
        double rec[2] = {*acc, 1};
        if (d->rank == t) rec[1] = fn(user, &rec[0]);
        uint8_t *all;
        uint64_t *lens;
        wrt_status st = dist_exchange(d, WRT_DIST_SERIES, rec, d->rank == t ? sizeof rec : 0, &all, &lens);
        if (st != WRT_OK) return st;
        memcpy(rec, all, sizeof rec); /* rank t's is the only record */
        free(all); free(lens);
        if (rec[1] == 0) return wrt_fail(WRT_ERR_IO, "rank %d of %d could not sum its share of the series", t, d->nranks);
        *acc = rec[0];
    }
    return WRT_OK;
}

void wrt_dist_cost_cuts(const uint64_t *cost, uint32_t n, int nranks, uint32_t *cut) {
    uint64_t total = 0, run = 0;
    for (uint32_t j = 0; j < n; j++) total += cost[j];
    /* rank r's columns end where the running cost first reaches (r + 1) / nranks of it */
    int r = 0;
    cut[0] = 0;
    for (uint32_t j = 0; j < n && r < nranks - 1; j++) {
        run += cost[j];
        while (r < nranks - 1 && (double)run * nranks >= (double)total * (r + 1)) cut[++r] = j + 1;
    }
    while (r < nranks - 1) cut[++r] = n;
    cut[nranks] = n;
}

wrt_status wrt_dist_share_costs(wrt_bake_dist *d, const uint64_t *mine, const uint32_t *cut, uint64_t *all) {
    uint32_t c0 = cut[d->rank], c1 = cut[d->rank + 1];
    uint8_t *got;
    uint64_t *lens;
    wrt_status st = dist_exchange(d, WRT_DIST_SERIES, mine, 8ull * (c1 - c0), &got, &lens);
    if (st != WRT_OK) return st;
    /* the ranks' ranges in rank order are the columns in order */
    memcpy(all, got, 8ull * cut[d->nranks]);
    free(got); free(lens);
    return WRT_OK;
}

typedef struct move_user { const uint32_t *to; int self; } move_user;

/* the columns another rank's new range holds */
static int want_moved(const void *user, int q, uint32_t j) {
    const move_user *u = user;
    return q != u->self && j >= u->to[q] && j < u->to[q + 1];
}

wrt_status wrt_dist_share_move(wrt_bake_dist *d, wrt_csc *m, const uint32_t *cut, const uint32_t *to) {
    int me = d->rank;
    move_user u = {to, me};
    wrt_csc in;
    wrt_status st = share_send(d, m, 0, cut, want_moved, &u, &in);
    if (st != WRT_OK) return st;
    /* the columns kept, [k0, k1), stay one block: moved to their new place in the arrays,
     * the arrivals (before k0 and from k1 on: the ranges are contiguous) copied around it */
    uint32_t n = m->n, t0 = to[me], t1 = to[me + 1];
    uint32_t k0 = cut[me] > t0 ? cut[me] : t0, k1 = cut[me + 1] < t1 ? cut[me + 1] : t1;
    if (k1 < k0) k1 = k0;
    uint64_t a = m->col[k0], z = m->col[k1], before = in.col[k0], nnz = in.nnz + (z - a);
    if (nnz > m->nnz) {
        m->row = wrt_xrealloc(m->row, nnz * sizeof *m->row);
        m->val = wrt_xrealloc(m->val, nnz * 3 * sizeof *m->val);
    }
    memmove(m->row + before, m->row + a, (z - a) * sizeof *m->row);
    memmove(m->val + 3 * before, m->val + 3 * a, (z - a) * 3 * sizeof *m->val);
    memcpy(m->row, in.row, before * sizeof *m->row);
    memcpy(m->val, in.val, before * 3 * sizeof *m->val);
    memcpy(m->row + before + (z - a), in.row + before, (in.nnz - before) * sizeof *m->row);
    memcpy(m->val + 3 * (before + (z - a)), in.val + 3 * before, (in.nnz - before) * 3 * sizeof *m->val);
    uint64_t *col = wrt_xcalloc((size_t)n + 1, sizeof *col);
    for (uint32_t j = 0; j < n; j++) {
        int kept = j >= k0 && j < k1;
        col[j + 1] = col[j] + (kept ? m->col[j + 1] - m->col[j] : in.col[j + 1] - in.col[j]);
    }
    free(m->col);
    m->col = col;
    m->nnz = nnz;
    m->row = wrt_xrealloc(m->row, (nnz ? nnz : 1) * sizeof *m->row);
    m->val = wrt_xrealloc(m->val, (nnz ? nnz : 1) * 3 * sizeof *m->val);
    wrt_csc_free(&in);
    return WRT_OK;
}
