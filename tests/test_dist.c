/* test_dist.c: the bake divided among ranks (precompute/dist.h) without MPI: the ranks
 * are threads here, their all-gather a barrier, so that the division and its merges are
 * checked on every machine (tests/mpi.sh runs the real program where Open MPI is).
 * The truths: the single process's own results, which the divided bake must give bit
 * for bit (the file's bytes follow from them), and the greedy division's bound. */
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "precompute/bake.h"
#include "precompute/dist.h"
#include "precompute/sparse.h"
#include "bake_helpers.h"
#include "scene_build.h"
#include "test.h"

/* ---- ranks as threads: the all-gather through a barrier */
#define MAXR 4
typedef struct sim {
    int nranks;
    pthread_barrier_t bar;
    const void *buf[MAXR];
    uint64_t len[MAXR];
    uint64_t calls[MAXR];
    const uint64_t *lens[MAXR]; /* the all-to-all's segment sizes */
    uint64_t a2a[MAXR];          /* all-to-alls per rank */
    uint64_t a2a_most[MAXR];     /* the most bytes a rank sent in one all-to-all */
} sim;

static __thread int sim_rank; /* the calling thread's rank */

static wrt_status sim_allgather(void *user, const void *mine, uint64_t len, void **all, uint64_t *lens) {
    sim *s = user;
    s->buf[sim_rank] = mine;
    s->len[sim_rank] = len;
    s->calls[sim_rank]++;
    pthread_barrier_wait(&s->bar);
    uint64_t total = 0;
    for (int k = 0; k < s->nranks; k++) { lens[k] = s->len[k]; total += s->len[k]; }
    uint8_t *out = malloc(total ? total : 1), *p = out;
    for (int k = 0; k < s->nranks; k++) { if (s->len[k]) memcpy(p, s->buf[k], s->len[k]); p += s->len[k]; }
    pthread_barrier_wait(&s->bar); /* every rank has copied before any buffer is reused */
    *all = out;
    return WRT_OK;
}

/* The all-to-all (dist.h) through the same barrier: each rank copies its segment out of
 * every rank's buffer */
static wrt_status sim_alltoall(void *user, const void *send, const uint64_t *sendlens, void **recv, uint64_t *recvlens) {
    sim *s = user;
    s->buf[sim_rank] = send;
    s->lens[sim_rank] = sendlens;
    s->a2a[sim_rank]++;
    uint64_t sent = 0;
    for (int q = 0; q < s->nranks; q++) sent += sendlens[q];
    if (sent > s->a2a_most[sim_rank]) s->a2a_most[sim_rank] = sent;
    pthread_barrier_wait(&s->bar);
    uint64_t total = 0;
    for (int k = 0; k < s->nranks; k++) { recvlens[k] = s->lens[k][sim_rank]; total += recvlens[k]; }
    uint8_t *out = malloc(total ? total : 1), *p = out;
    for (int k = 0; k < s->nranks; k++) {
        uint64_t at = 0;
        for (int q = 0; q < sim_rank; q++) at += s->lens[k][q];
        if (recvlens[k]) memcpy(p, (const uint8_t *)s->buf[k] + at, recvlens[k]);
        p += recvlens[k];
    }
    pthread_barrier_wait(&s->bar);
    *recv = out;
    return WRT_OK;
}

/* Runs fn(arg + k * size) on nranks threads, thread k being rank k. */
typedef struct rank_start { void *(*fn)(void *); void *arg; int rank; } rank_start;
static void *rank_main(void *p) {
    rank_start *rs = p;
    sim_rank = rs->rank;
    return rs->fn(rs->arg);
}
static void run_ranks(int nranks, void *(*fn)(void *), void *args, size_t size) {
    pthread_t th[MAXR];
    rank_start rs[MAXR];
    for (int k = 0; k < nranks; k++) {
        rs[k] = (rank_start){fn, (char *)args + (size_t)k * size, k};
        pthread_create(&th[k], NULL, rank_main, &rs[k]);
    }
    for (int k = 0; k < nranks; k++) pthread_join(th[k], NULL);
}

/* ---- the products by columns */
static wrt_csc random_csc(uint32_t n, double density, uint64_t seed) {
    wrt_triplet *t = malloc((size_t)n * n * sizeof *t);
    uint64_t m = 0, h = seed;
    for (uint32_t j = 0; j < n; j++)
        for (uint32_t i = 0; i < n; i++) {
            h = h * 6364136223846793005ULL + 1442695040888963407ULL;
            if ((double)(h >> 11) / 9007199254740992.0 >= density) continue;
            float v = (float)((h >> 40) % 1000) / 2000.0f + 0.01f;
            t[m++] = (wrt_triplet){i, j, {v, v * 0.9f, v * 1.1f}};
        }
    wrt_csc c = wrt_csc_from_triplets(n, t, m);
    free(t);
    return c;
}

static int csc_same(const wrt_csc *a, const wrt_csc *b) {
    return a->n == b->n && a->nnz == b->nnz && !memcmp(a->col, b->col, ((size_t)a->n + 1) * sizeof *a->col) &&
           !memcmp(a->row, b->row, a->nnz * sizeof *a->row) && !memcmp(a->val, b->val, a->nnz * 3 * sizeof *a->val);
}

typedef struct mul_arg {
    sim *s;
    const wrt_csc *a, *b;
    const wrt_csc_weights *w;
    double drop;
    wrt_csc out;
    wrt_status st;
} mul_arg;

static void *mul_rank(void *p) {
    mul_arg *m = p;
    wrt_bake_dist d = {.rank = sim_rank, .nranks = m->s->nranks, .allgather = sim_allgather, .user = m->s};
    m->st = wrt_dist_mul(&d, m->a, m->b, m->drop, m->w, 1, &m->out);
    return NULL;
}

/* A product divided among 1 to 4 ranks: every rank holds wrt_csc_mul's matrix, bit for
 * bit, with the compression and its power hand-over on (per column, so unchanged). */
static void dist_mul_same(void) {
    uint32_t n = 300;
    wrt_csc a = random_csc(n, 0.03, 1), b = random_csc(n, 0.05, 2);
    double *rw = malloc(n * sizeof *rw), *cw = malloc(n * sizeof *cw), *pw = malloc(n * sizeof *pw);
    for (uint32_t i = 0; i < n; i++) { rw[i] = 1.0 + (i % 7) * 0.1; cw[i] = 1.0 / rw[i]; pw[i] = i % 3 ? 0 : 1.0; }
    wrt_csc_weights w = {rw, cw, pw, NULL, 0, NULL, 0};
    wrt_csc want = wrt_csc_mul(&a, &b, 0.02, &w, 2);
    CHECK(want.nnz > 1000 && want.nnz < (uint64_t)n * n, "the product keeps %llu entries: some dropped, many kept",
          (unsigned long long)want.nnz);
    for (int nr = 1; nr <= MAXR; nr++) {
        sim s = {.nranks = nr};
        pthread_barrier_init(&s.bar, NULL, (unsigned)nr);
        mul_arg m[MAXR];
        for (int k = 0; k < nr; k++) m[k] = (mul_arg){.s = &s, .a = &a, .b = &b, .w = &w, .drop = 0.02};
        run_ranks(nr, mul_rank, m, sizeof *m);
        for (int k = 0; k < nr; k++) {
            CHECK(m[k].st == WRT_OK && csc_same(&m[k].out, &want), "%d ranks: rank %d's product differs", nr, k);
            wrt_csc_free(&m[k].out);
        }
        pthread_barrier_destroy(&s.bar);
    }
    /* the cuts: contiguous, covering every column */
    uint32_t cut[MAXR + 1];
    wrt_dist_mul_cuts(&a, &b, 4, cut);
    CHECK(cut[0] == 0 && cut[4] == n && cut[1] <= cut[2] && cut[2] <= cut[3] && cut[3] <= cut[4],
          "cuts 0 %u %u %u %u", cut[1], cut[2], cut[3], cut[4]);
    wrt_csc_free(&a); wrt_csc_free(&b); wrt_csc_free(&want);
    free(rw); free(cw); free(pw);
}

/* Columns [c0, c1) of m, the others empty */
static wrt_csc csc_cols(const wrt_csc *m, uint32_t c0, uint32_t c1) {
    wrt_csc r = {.n = m->n};
    r.col = calloc((size_t)m->n + 1, sizeof *r.col);
    for (uint32_t j = 0; j < m->n; j++) r.col[j + 1] = r.col[j] + (j >= c0 && j < c1 ? m->col[j + 1] - m->col[j] : 0);
    r.nnz = r.col[m->n];
    r.row = malloc((r.nnz + 1) * sizeof *r.row);
    r.val = malloc((r.nnz + 1) * 3 * sizeof *r.val);
    memcpy(r.row, m->row + m->col[c0], r.nnz * sizeof *r.row);
    memcpy(r.val, m->val + 3 * m->col[c0], r.nnz * 3 * sizeof *r.val);
    return r;
}

typedef struct move_arg {
    sim *s;
    wrt_csc m;
    const uint32_t *cut, *to;
    wrt_status st;
} move_arg;

static void *move_rank(void *p) {
    move_arg *a = p;
    wrt_bake_dist d = {.rank = sim_rank, .nranks = a->s->nranks, .allgather = sim_allgather,
                       .alltoall = sim_alltoall, .user = a->s, .piece_bytes = 3000};
    a->st = wrt_dist_share_move(&d, &a->m, a->cut, a->to);
    return NULL;
}

/* A re-cut's move (wrt_dist_share_move, in rounds of 3000 bytes): every rank ends with
 * exactly the columns of its new range of one matrix, whatever the old and new ranges
 * share (overlapping, disjoint, empty); and the cut by costs holds each rank's cost
 * within the largest column's of the mean. */
static void dist_share_move_same(void) {
    uint32_t n = 300;
    wrt_csc m = random_csc(n, 0.05, 3);
    uint64_t cost[300], total = 0, big = 0;
    for (uint32_t j = 0; j < n; j++) {
        cost[j] = (m.col[j + 1] - m.col[j]) * (1 + j % 5);
        total += cost[j];
        if (cost[j] > big) big = cost[j];
    }
    uint32_t bycost[4];
    wrt_dist_cost_cuts(cost, n, 3, bycost);
    int bad = bycost[0] != 0 || bycost[3] != n;
    for (int r = 0; r < 3; r++) {
        uint64_t l = 0;
        for (uint32_t j = bycost[r]; j < bycost[r + 1]; j++) l += cost[j];
        bad |= bycost[r] > bycost[r + 1] || 3 * l > total + 3 * big;
    }
    CHECK(!bad, "the cut by costs 0 %u %u %u: contiguous, each rank within the largest column of the mean", bycost[1],
          bycost[2], bycost[3]);
    const uint32_t cuts[][4] = {{0, 100, 200, 300}, {0, 250, 280, 300}, {0, 0, 150, 300}, {0, 290, 300, 300}};
    for (int c = 0; c < 4; c++) {
        const uint32_t *cut = cuts[c], *to = c < 3 ? cuts[c + 1] : bycost;
        sim s = {.nranks = 3};
        pthread_barrier_init(&s.bar, NULL, 3);
        move_arg a[3];
        for (int k = 0; k < 3; k++) a[k] = (move_arg){.s = &s, .m = csc_cols(&m, cut[k], cut[k + 1]), .cut = cut, .to = to};
        run_ranks(3, move_rank, a, sizeof *a);
        for (int k = 0; k < 3; k++) {
            wrt_csc want = csc_cols(&m, to[k], to[k + 1]);
            CHECK(a[k].st == WRT_OK && csc_same(&a[k].m, &want), "ranges %u %u -> %u %u: rank %d holds its new columns",
                  cut[1], cut[2], to[1], to[2], k);
            wrt_csc_free(&want);
            wrt_csc_free(&a[k].m);
        }
        CHECK(s.a2a[0] > 1, "the move went in rounds (%llu)", (unsigned long long)s.a2a[0]);
        pthread_barrier_destroy(&s.bar);
    }
    wrt_csc_free(&m);
}

/* The greedy division (largest first to the least loaded): every item has a rank, and
 * the loads differ by at most the largest item (the bound of that rule). */
static void dist_assign_bound(void) {
    enum { N = 1000 };
    double cost[N], load[MAXR] = {0}, big = 0;
    int owner[N];
    uint64_t h = 7;
    for (int i = 0; i < N; i++) {
        h = h * 6364136223846793005ULL + 1442695040888963407ULL;
        cost[i] = 1.0 + (double)(h >> 44) / 1024.0;
        if (cost[i] > big) big = cost[i];
    }
    wrt_dist_assign(cost, N, 3, owner);
    int bad = 0;
    for (int i = 0; i < N; i++) {
        if (owner[i] < 0 || owner[i] > 2) bad++;
        else load[owner[i]] += cost[i];
    }
    CHECK(bad == 0, "%d items without a rank", bad);
    double lo = fmin(load[0], fmin(load[1], load[2])), hi = fmax(load[0], fmax(load[1], load[2]));
    CHECK(hi - lo <= big, "loads %.1f %.1f %.1f differ by more than the largest item %.1f", load[0], load[1], load[2], big);
}

/* ---- a whole bake divided among 3 ranks against the single process */
typedef struct bake_arg {
    sim *s;
    const wrt_scene *scene;
    wrt_bake_options o;
    wrt_bake_result r;
    wrt_status st;
    int share; /* the ranks given an all-to-all: the series by shares */
    uint64_t piece; /* the merges' round size (dist.h's piece_bytes; 0: the default) */
    uint64_t recv_dto; /* the bytes the rank received in the DTO phase */
    uint64_t sent_series; /* and sent in the series */
    double recut_at; /* dist.h's: re-cut wherever a rank's cost is above that times the mean */
    uint32_t recuts; /* the tree series' ranges re-cut (series_recut.c) */
} bake_arg;

static void *bake_rank(void *p) {
    bake_arg *a = p;
    wrt_bake_dist d = {.rank = sim_rank, .nranks = a->s->nranks, .allgather = sim_allgather, .user = a->s};
    if (a->share) d.alltoall = sim_alltoall;
    d.piece_bytes = a->piece;
    d.recut_at = a->recut_at;
    a->o.dist = &d;
    a->st = wrt_bake_run(a->scene, &a->o, &a->r);
    a->o.dist = NULL;
    a->recv_dto = d.bytes_recv[WRT_DIST_DTO];
    a->sent_series = d.bytes_sent[WRT_DIST_SERIES];
    a->recuts = d.recuts;
    return NULL;
}

/* The bake in one process (*want, its status returned), then on NR_BAKE ranks (threads),
 * barrier set up in *sm; the ranks' results in a[] */
enum { NR_BAKE = 3 };
static wrt_status bake_on_ranks(sim *sm, bake_arg *a, const wrt_scene *s, wrt_bake_options o, wrt_bake_result *want) {
    wrt_status st = wrt_bake_run(s, &o, want);
    *sm = (sim){.nranks = NR_BAKE};
    pthread_barrier_init(&sm->bar, NULL, NR_BAKE);
    for (int k = 0; k < NR_BAKE; k++) a[k] = (bake_arg){.s = sm, .scene = s, .o = o};
    run_ranks(NR_BAKE, bake_rank, a, sizeof *a);
    return st;
}

/* Rank k baked, and its basis functions, T and G - I are the single process's, bit for
 * bit; 1 if it baked */
static int same_operator(int k, const bake_arg *a, const wrt_bake_result *want) {
    CHECK(a->st == WRT_OK, "rank %d baked", k);
    if (a->st != WRT_OK) return 0;
    const wrt_bake_result *r = &a->r;
    CHECK(r->nfuncs == want->nfuncs && !memcmp(r->fkeys, want->fkeys, want->nfuncs * sizeof *want->fkeys),
          "rank %d: the same basis functions", k);
    CHECK(csc_same(&r->dto, &want->dto), "rank %d: the same T (%llu entries, want %llu)", k,
          (unsigned long long)r->dto.nnz, (unsigned long long)want->dto.nnz);
    CHECK(csc_same(&r->op, &want->op), "rank %d: the same G - I", k);
    return 1;
}

/* A closed box of 3 x 3 quads a face with a floating panel inside (occluded pairs): T,
 * G - I and the counters the file records are the single process's on every rank. */
/* The unit box of 3 x 3 quads a face with a floating panel inside, albedo r, g, b */
static void box_with_panel(wrt_scene *s, double r, double g, double b) {
    tsb_init(s);
    int mat = tsb_material(s, r, g, b);
    tsb_box_inward(s, P(0, 0, 0), P(1, 1, 1), 3, mat);
    tsb_quad(s, P(0.3, 0.5, 0.3), P(0.7, 0.5, 0.3), P(0.7, 0.5, 0.7), P(0.3, 0.5, 0.7), mat);
}

static void dist_bake_same(void) {
    wrt_scene s;
    box_with_panel(&s, 0.7, 0.6, 0.5);
    wrt_bake_options o = opts(2, 0, 3);
    o.threads = 1;
    wrt_bake_result want;
    sim sm;
    bake_arg a[NR_BAKE];
    wrt_status st = bake_on_ranks(&sm, a, &s, o, &want);
    CHECK(st == WRT_OK && want.op.nnz > 0, "the single process bakes (%s)", wrt_last_error());
    for (int k = 0; k < NR_BAKE; k++) {
        if (!same_operator(k, &a[k], &want)) continue;
        const wrt_bake_counters *c = &a[k].r.c, *w = &want.c;
        CHECK(c->rays_traced == w->rays_traced && c->samples == w->samples && c->links_leaf == w->links_leaf &&
                  c->links_dto == w->links_dto && c->pairs_unoccluded == w->pairs_unoccluded &&
                  c->bounces == w->bounces && c->balance_entries == w->balance_entries,
              "rank %d: the same counters (rays %llu / %llu)", k, (unsigned long long)c->rays_traced,
              (unsigned long long)w->rays_traced);
        wrt_bake_result_free(&a[k].r);
    }
    CHECK(want.c.pairs_unoccluded < want.c.pairs_exchange, "some pairs are occluded (%llu of %llu free)",
          (unsigned long long)want.c.pairs_unoccluded, (unsigned long long)want.c.pairs_exchange);
    CHECK(sm.calls[0] > 3 && sm.calls[0] == sm.calls[1] && sm.calls[1] == sm.calls[2],
          "the ranks met in the same %llu all-gathers", (unsigned long long)sm.calls[0]);
    /* The pairs travel as the DTO keeps them, a diffuse pair's entries two to a 16-byte
     * record: a rank receives less than the 32 bytes a full entry would take for the other
     * ranks' share of T's entries (at least 2/3 of them on 3 ranks, less the balance's few) */
    CHECK(a[1].recv_dto > 0 && (double)a[1].recv_dto < 32.0 * 2.0 / 3.0 * (double)want.c.entries_dto,
          "rank 1 received %llu bytes in the DTO phase, under 32 a full entry for 2/3 of T's %llu",
          (unsigned long long)a[1].recv_dto, (unsigned long long)want.c.entries_dto);
    /* The merges in rounds of 2 KiB of every rank's records (the default takes the box's
     * whole DTO in one): the ranks meet in many more all-gathers, the same on each, and
     * every rank still holds the single process's T and G - I bit for bit */
    uint64_t calls_whole = sm.calls[0];
    pthread_barrier_destroy(&sm.bar);
    sm = (sim){.nranks = NR_BAKE};
    pthread_barrier_init(&sm.bar, NULL, NR_BAKE);
    for (int k = 0; k < NR_BAKE; k++) a[k] = (bake_arg){.s = &sm, .scene = &s, .o = o, .piece = 2048};
    run_ranks(NR_BAKE, bake_rank, a, sizeof *a);
    for (int k = 0; k < NR_BAKE; k++)
        if (same_operator(k, &a[k], &want)) wrt_bake_result_free(&a[k].r);
    CHECK(sm.calls[0] > calls_whole + 10 && sm.calls[0] == sm.calls[1] && sm.calls[1] == sm.calls[2],
          "in 2 KiB rounds the ranks met in the same %llu all-gathers (%llu in whole merges)",
          (unsigned long long)sm.calls[0], (unsigned long long)calls_whole);
    pthread_barrier_destroy(&sm.bar);
    wrt_bake_result_free(&want);
    tsb_free(&s);
}

/* --clusters on 3 ranks: the cluster tree's node pairs below its serial top divided by
 * rank (cluster_link.c) and merged in their order: a long box of 4 x 4 quads a face (far
 * walls linked as clusters, near ones refined to leaf pairs) gives every rank the single
 * process's links, leaf pairs, oracle counts, T and G - I; 2 threads a rank, so the ranks'
 * tasks also run in parallel within each. */
/* The long box, 4 x 1 x 1 with 4 x 4 quads a face, albedo r, g, b, and its --clusters
 * options */
static wrt_bake_options long_box(wrt_scene *s, double r, double g, double b) {
    tsb_init(s);
    tsb_box_inward(s, P(0, 0, 0), P(4, 1, 1), 4, tsb_material(s, r, g, b));
    wrt_bake_options o = opts(1, 0, 2);
    o.clusters = 1;
    return o;
}

static void dist_clusters_same(void) {
    wrt_scene s;
    wrt_bake_options o = long_box(&s, 0.7, 0.6, 0.5);
    wrt_bake_result want;
    sim sm;
    bake_arg a[NR_BAKE];
    wrt_status st = bake_on_ranks(&sm, a, &s, o, &want);
    CHECK(st == WRT_OK && want.c.cluster_links > 0 && want.c.cluster_leaf_pairs > 0,
          "the single process bakes with cluster links (%llu) and leaf pairs (%llu) (%s)",
          (unsigned long long)want.c.cluster_links, (unsigned long long)want.c.cluster_leaf_pairs, wrt_last_error());
    for (int k = 0; k < NR_BAKE; k++) {
        if (!same_operator(k, &a[k], &want)) continue;
        const wrt_bake_counters *c = &a[k].r.c, *w = &want.c;
        CHECK(c->cluster_links == w->cluster_links && c->cluster_leaf_pairs == w->cluster_leaf_pairs &&
                  c->cluster_visits == w->cluster_visits && c->cluster_oracle == w->cluster_oracle &&
                  c->cluster_rays == w->cluster_rays && c->cluster_partial == w->cluster_partial,
              "rank %d: the same cluster links (%llu / %llu), leaf pairs and oracle counts", k,
              (unsigned long long)c->cluster_links, (unsigned long long)w->cluster_links);
        wrt_bake_result_free(&a[k].r);
    }
    pthread_barrier_destroy(&sm.bar);
    wrt_bake_result_free(&want);
    tsb_free(&s);
}

/* The series by shares (series.c; wrt-bake's consumed, streamed series, the ranks given an
 * all-to-all): each rank holds its columns of the terms, the right factor and the sum,
 * fetches the columns it needs, and sums the norms in the single process's order. On a
 * closed box with a panel (occluded pairs, 3 ranks, blocks of 500 entries so that the
 * sum is streamed through many blocks), rank 0 ends with the single process's G - I bit
 * for bit and its bounces and energy left (the norms' bits decide both), the others with
 * no operator, and every rank met in the same all-to-alls. Then again with the exchange
 * in rounds of 2 KiB of all the ranks' records: the same G - I from many more
 * all-to-alls, none of which sends more than a round's share (2048 / 3 bytes) or one
 * column (8 + 16 bytes an entry, at most a column's every function). */
static void share_on_ranks(const wrt_scene *s, wrt_bake_options o, uint64_t piece, const wrt_bake_result *want,
                           sim *sm) {
    *sm = (sim){.nranks = NR_BAKE};
    pthread_barrier_init(&sm->bar, NULL, NR_BAKE);
    bake_arg a[NR_BAKE];
    for (int k = 0; k < NR_BAKE; k++) a[k] = (bake_arg){.s = sm, .scene = s, .o = o, .share = 1, .piece = piece};
    run_ranks(NR_BAKE, bake_rank, a, sizeof *a);
    for (int k = 0; k < NR_BAKE; k++) {
        CHECK(a[k].st == WRT_OK, "rank %d baked (%s)", k, wrt_last_error());
        if (a[k].st != WRT_OK) continue;
        if (k == 0) {
            CHECK(csc_same(&a[k].r.op, &want->op), "rank 0: the same G - I (%llu entries, want %llu; rounds %llu)",
                  (unsigned long long)a[k].r.op.nnz, (unsigned long long)want->op.nnz, (unsigned long long)piece);
            CHECK(a[k].r.c.bounces == want->c.bounces && a[k].r.c.energy_left == want->c.energy_left &&
                      a[k].r.c.tail_fraction == want->c.tail_fraction && a[k].r.c.links_gto == want->c.links_gto,
                  "rank 0: the same bounces (%llu / %llu), energy left, tail and links",
                  (unsigned long long)a[k].r.c.bounces, (unsigned long long)want->c.bounces);
        } else {
            CHECK(a[k].r.op.nnz == 0, "rank %d holds no operator (%llu entries)", k, (unsigned long long)a[k].r.op.nnz);
        }
        wrt_bake_result_free(&a[k].r);
    }
    CHECK(sm->a2a[0] > 3 && sm->a2a[0] == sm->a2a[1] && sm->a2a[1] == sm->a2a[2],
          "the ranks met in the same %llu all-to-alls", (unsigned long long)sm->a2a[0]);
    pthread_barrier_destroy(&sm->bar);
}

static void dist_share_same(void) {
    wrt_scene s;
    box_with_panel(&s, 0.8, 0.7, 0.6);
    wrt_bake_options o = opts(2, 0, 3);
    o.threads = 1;
    o.consume_dto = 1;
    o.series_block = 500;
    wrt_bake_result want;
    wrt_status st = wrt_bake_run(&s, &o, &want);
    CHECK(st == WRT_OK && want.op.nnz > 0 && want.c.bounces > 3, "the single process bakes (%llu bounces; %s)",
          (unsigned long long)want.c.bounces, wrt_last_error());
    sim one, many;
    share_on_ranks(&s, o, 0, &want, &one);
    share_on_ranks(&s, o, 2048, &want, &many);
    uint64_t most = 0, bound = 2048 / NR_BAKE + 8 + 16 * (uint64_t)want.nfuncs, whole = 0;
    for (int k = 0; k < NR_BAKE; k++) {
        if (many.a2a_most[k] > most) most = many.a2a_most[k];
        if (one.a2a_most[k] > whole) whole = one.a2a_most[k];
    }
    CHECK(many.a2a[0] > 4 * one.a2a[0] && most <= bound && most < whole,
          "in 2 KiB rounds: %llu all-to-alls (%llu in one round a product), at most %llu bytes sent in one "
          "(bound %llu; %llu in one round)",
          (unsigned long long)many.a2a[0], (unsigned long long)one.a2a[0], (unsigned long long)most,
          (unsigned long long)bound, (unsigned long long)whole);
    wrt_bake_result_free(&want);
    tsb_free(&s);
}

/* --clusters' series in the senders' tree basis by column shares (series.c
 * series_tree_share_start; the ranks given an all-to-all): on a long box of 4 x 4 quads a
 * face at albedo 0.8 on 3 ranks, rank 0 ends with the single process's G - I bit for bit,
 * its bounces, energy left, tail and links (the norms' bits decide them), the others with
 * no operator. Each rank holds its own columns of the sum: the ranks' sums before the
 * stored compression add up to the single process's, entry for entry, and none holds
 * more than 3/4 of it. Nothing travels in the products: the series' bytes, all the ranks
 * together, stay under 24 an entry of the stored operator (each rank's stored columns
 * sent to rank 0 once, 8 bytes a column and 16 an entry) and 256 a bounce a rank (the
 * norms' chains); the products gathered whole (no all-to-all) send more than that. */
static void dist_tree_share_same(void) {
    wrt_scene s;
    wrt_bake_options o = long_box(&s, 0.8, 0.75, 0.7);
    o.threads = 1;
    o.series_columns = -1; /* the terms whole, each product divided (dist_tree_cols_same: by blocks) */
    wrt_bake_result want;
    wrt_status st = wrt_bake_run(&s, &o, &want);
    CHECK(st == WRT_OK && want.op.nnz > 0 && want.c.bounces > 3 && want.c.cluster_senders_basis &&
              want.c.cluster_factored_entries > 0,
          "the single process bakes in the senders' tree basis, its products factored E1 (U P) (%llu bounces, "
          "E1 %llu entries; %s)",
          (unsigned long long)want.c.bounces, (unsigned long long)want.c.cluster_factored_entries, wrt_last_error());
    uint64_t sent[2] = {0, 0};
    uint32_t recuts = 0;
    for (int share = 1; share >= 0; share--) {
        sim sm = {.nranks = NR_BAKE};
        pthread_barrier_init(&sm.bar, NULL, NR_BAKE);
        bake_arg a[NR_BAKE];
        for (int k = 0; k < NR_BAKE; k++) a[k] = (bake_arg){.s = &sm, .scene = &s, .o = o, .share = share, .recut_at = 1.001};
        run_ranks(NR_BAKE, bake_rank, a, sizeof *a);
        uint64_t held = 0, most = 0;
        for (int k = 0; k < NR_BAKE; k++) {
            CHECK(a[k].st == WRT_OK, "rank %d baked (%s)", k, wrt_last_error());
            if (a[k].st != WRT_OK) continue;
            sent[share] += a[k].sent_series;
            if (share) recuts += a[k].recuts;
            held += a[k].r.c.sum_held;
            if (a[k].r.c.sum_held > most) most = a[k].r.c.sum_held;
            if (share && k > 0)
                CHECK(a[k].r.op.nnz == 0, "rank %d holds no operator (%llu entries)", k,
                      (unsigned long long)a[k].r.op.nnz);
            if (k == 0 || !share) {
                CHECK(csc_same(&a[k].r.op, &want.op), "rank %d (shares %d): the same G - I (%llu entries, want %llu)",
                      k, share, (unsigned long long)a[k].r.op.nnz, (unsigned long long)want.op.nnz);
                CHECK(a[k].r.c.bounces == want.c.bounces && a[k].r.c.energy_left == want.c.energy_left &&
                          a[k].r.c.tail_fraction == want.c.tail_fraction && a[k].r.c.links_gto == want.c.links_gto,
                      "rank %d (shares %d): the same bounces (%llu / %llu), energy left, tail and links", k, share,
                      (unsigned long long)a[k].r.c.bounces, (unsigned long long)want.c.bounces);
            }
            wrt_bake_result_free(&a[k].r);
        }
        if (share)
            CHECK(held == want.c.sum_held && most > 0 && 4 * most <= 3 * want.c.sum_held,
                  "the ranks' sums hold %llu entries together (one process %llu), the most on one rank %llu", 
                  (unsigned long long)held, (unsigned long long)want.c.sum_held, (unsigned long long)most);
        pthread_barrier_destroy(&sm.bar);
    }
    CHECK(recuts > 0 && recuts % NR_BAKE == 0, "the ranges were re-cut on every rank alike (%u re-cuts in all)", recuts);
    uint64_t bound = 24 * want.op.nnz + 256 * want.c.bounces * NR_BAKE;
    CHECK(sent[1] <= bound && sent[0] > bound,
          "the series sent %llu bytes by shares (bound %llu), %llu with its products gathered",
          (unsigned long long)sent[1], (unsigned long long)bound, (unsigned long long)sent[0]);
    wrt_bake_result_free(&want);
    tsb_free(&s);
}

/* The series by blocks of columns (series_cols.c, the default with --clusters) on 3 ranks:
 * by shares each rank takes its own range through every bounce, without shares every rank
 * all of them; rank 0 ends with the single process's G - I bit for bit, its bounces,
 * energy left and tail (from the power iteration, which every rank runs), and by shares
 * nothing travels but the stored columns, once, to rank 0 (8 bytes a column and 16 an
 * entry) and the power iteration's nothing: under 24 bytes an entry of the stored
 * operator. */
static void dist_tree_cols_same(void) {
    wrt_scene s;
    wrt_bake_options o = long_box(&s, 0.8, 0.75, 0.7);
    o.threads = 1;
    wrt_bake_result want;
    wrt_status st = wrt_bake_run(&s, &o, &want);
    CHECK(st == WRT_OK && want.op.nnz > 0 && want.c.bounces > 3 && want.c.cluster_senders_basis,
          "the single process bakes by blocks of columns (%llu bounces; %s)", (unsigned long long)want.c.bounces,
          wrt_last_error());
    for (int share = 1; share >= 0; share--) {
        sim sm = {.nranks = NR_BAKE};
        pthread_barrier_init(&sm.bar, NULL, NR_BAKE);
        bake_arg a[NR_BAKE];
        for (int k = 0; k < NR_BAKE; k++) a[k] = (bake_arg){.s = &sm, .scene = &s, .o = o, .share = share};
        run_ranks(NR_BAKE, bake_rank, a, sizeof *a);
        uint64_t sent = 0;
        for (int k = 0; k < NR_BAKE; k++) {
            CHECK(a[k].st == WRT_OK, "rank %d baked (%s)", k, wrt_last_error());
            if (a[k].st != WRT_OK) continue;
            sent += a[k].sent_series;
            if (k == 0 || !share) {
                CHECK(csc_same(&a[k].r.op, &want.op), "blocks, rank %d (shares %d): the same G - I (%llu entries, want %llu)",
                      k, share, (unsigned long long)a[k].r.op.nnz, (unsigned long long)want.op.nnz);
                CHECK(a[k].r.c.bounces == want.c.bounces && a[k].r.c.energy_left == want.c.energy_left &&
                          a[k].r.c.tail_fraction == want.c.tail_fraction,
                      "blocks, rank %d (shares %d): the same bounces (%llu / %llu), energy left and tail", k, share,
                      (unsigned long long)a[k].r.c.bounces, (unsigned long long)want.c.bounces);
            }
            wrt_bake_result_free(&a[k].r);
        }
        if (share)
            CHECK(sent <= 24 * want.op.nnz, "blocks by shares: the series sent %llu bytes (bound %llu)",
                  (unsigned long long)sent, (unsigned long long)(24 * want.op.nnz));
        pthread_barrier_destroy(&sm.bar);
    }
    wrt_bake_result_free(&want);
    tsb_free(&s);
}

int main(int argc, char **argv) {
    TEST_RUN(dist_mul_same);
    TEST_RUN(dist_assign_bound);
    TEST_RUN(dist_share_move_same);
    TEST_RUN(dist_bake_same);
    TEST_RUN(dist_clusters_same);
    TEST_RUN(dist_share_same);
    TEST_RUN(dist_tree_share_same);
    TEST_RUN(dist_tree_cols_same);
    TEST_END();
}
