/* links.c: what the bake's stages ask of the sorted function keys (wrt_fkey of
 * common/basis.h): the index of a key, and the number of links of a matrix over the keys
 * (entries grouped by the supports of their two functions, the paper's link count).
 * Used by the driver (bake.c), the power balance and the series. Depends on sparse.h
 * and wrt_common. */
#include "links.h"

#include <stdlib.h>
#include <string.h>

#include "../common/threads.h"
#include "../common/wrt_common.h"

int64_t wrt_fkey_find(const uint64_t *fkeys, uint32_t n, uint64_t key) {
    uint32_t lo = 0, hi = n;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2;
        if (fkeys[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    return (lo < n && fkeys[lo] == key) ? (int64_t)lo : -1;
}

/* a 64-bit finaliser: keys differ in few low bits, the slots need all of them mixed */
static size_t key_hash(uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return (size_t)k;
}

static void fkey_set_grow(wrt_fkey_set *s) {
    size_t ncap = s->cap ? 2 * s->cap : 1024;
    uint64_t *nk = wrt_xmalloc(ncap * sizeof *nk);
    uint32_t *ni = wrt_xmalloc(ncap * sizeof *ni);
    for (size_t i = 0; i < ncap; i++) ni[i] = UINT32_MAX;
    for (size_t i = 0; i < s->cap; i++) {
        if (s->idx[i] == UINT32_MAX) continue;
        size_t h = key_hash(s->key[i]) & (ncap - 1);
        while (ni[h] != UINT32_MAX) h = (h + 1) & (ncap - 1);
        nk[h] = s->key[i]; ni[h] = s->idx[i];
    }
    free(s->key); free(s->idx);
    s->key = nk; s->idx = ni; s->cap = ncap;
}

void wrt_fkey_set_add(wrt_fkey_set *s, uint64_t key) {
    if (2 * (s->n + 1) > s->cap) fkey_set_grow(s);
    size_t h = key_hash(key) & (s->cap - 1);
    while (s->idx[h] != UINT32_MAX) {
        if (s->key[h] == key) return;
        h = (h + 1) & (s->cap - 1);
    }
    s->key[h] = key; s->idx[h] = 0;
    s->n++;
}

int64_t wrt_fkey_set_find(const wrt_fkey_set *s, uint64_t key) {
    if (!s->cap) return -1;
    size_t h = key_hash(key) & (s->cap - 1);
    while (s->idx[h] != UINT32_MAX) {
        if (s->key[h] == key) return s->idx[h];
        h = (h + 1) & (s->cap - 1);
    }
    return -1;
}

uint64_t *wrt_fkey_set_sorted(wrt_fkey_set *s) {
    if (!s->n) return NULL;
    uint64_t *keys = wrt_xmalloc(s->n * sizeof *keys);
    size_t k = 0;
    for (size_t i = 0; i < s->cap; i++)
        if (s->idx[i] != UINT32_MAX) keys[k++] = s->key[i];
    wrt_sort_u64(keys, k);
    for (size_t i = 0; i < k; i++) {
        size_t h = key_hash(keys[i]) & (s->cap - 1);
        while (s->key[h] != keys[i] || s->idx[h] == UINT32_MAX) h = (h + 1) & (s->cap - 1);
        s->idx[h] = (uint32_t)i;
    }
    return keys;
}

void wrt_fkey_set_free(wrt_fkey_set *s) {
    free(s->key); free(s->idx);
    memset(s, 0, sizeof *s);
}

/* The link of a function: its key without the wavelet types. */
static uint64_t support_of(uint64_t k) { return k & ~((3ULL << 16) | (3ULL << 6)); }

/* The number of distinct values among n sorted ones. */
static uint64_t count_distinct(const uint64_t *a, uint64_t n) {
    uint64_t d = 0;
    for (uint64_t i = 0; i < n; i++) d += i == 0 || a[i] != a[i - 1];
    return d;
}

static int cmp_u64(const void *pa, const void *pb) {
    uint64_t a = *(const uint64_t *)pa, b = *(const uint64_t *)pb;
    return a < b ? -1 : a > b;
}

/* Links are counted a group of columns at a time: the columns whose keys share the
 * sender's spatial node (key >> 18: quad, level, y, x) are adjacent in the sorted keys
 * and hold every link of their sender supports (a support differs from its node only by
 * the angular cell), so their distinct pairs add up. The scratch is the largest group's
 * entries, not the whole matrix's: a copy of every entry (16 bytes each, the operator's
 * own size) was the bake's peak at its end, uncounted by its memory estimate (the
 * 10,065-triangle --clusters bake: 2.3 GB of its 6.6 GB). Unsorted keys: one group.
 * Within a group each entry's pair of supports is one 64-bit number (the supports
 * numbered in key order), radix-sorted and counted: qsort of 16-byte pairs with its
 * comparator was 1.5% of a maze bake, serial (perf). */
/* The link count's groups on the threads: each thread its scratch and its count */
typedef struct {
    const wrt_csc *m;
    const uint32_t *id, *g0; /* the supports' numbers; group i is columns [g0[i], g0[i + 1]) */
    uint64_t **lp, *cap, *links;
} links_job;

static void count_group(size_t i, int th, void *user) {
    links_job *c = user;
    const wrt_csc *m = c->m;
    uint32_t j0 = c->g0[i], j1 = c->g0[i + 1];
    uint64_t k = 0, need = m->col[j1] - m->col[j0];
    if (need > c->cap[th]) {
        free(c->lp[th]);
        c->cap[th] = need;
        c->lp[th] = wrt_xmalloc(need * sizeof *c->lp[th]);
    }
    uint64_t *lp = c->lp[th];
    for (uint32_t j = j0; j < j1; j++)
        for (uint64_t e = m->col[j]; e < m->col[j + 1]; e++) lp[k++] = (uint64_t)c->id[m->row[e]] << 32 | c->id[j];
    /* the radix sort clears a 65,536-count table a digit: for a small group qsort */
    if (k < 16384) qsort(lp, k, sizeof *lp, cmp_u64);
    else wrt_sort_u64(lp, k);
    c->links[th] += count_distinct(lp, k);
}

uint64_t wrt_count_links(const wrt_csc *m, const uint64_t *fkeys, int threads) {
    if (!m->nnz) return 0;
    uint32_t n = m->n;
    uint64_t *sup = wrt_xmalloc(((size_t)n + 1) * sizeof *sup);
    for (uint32_t i = 0; i < n; i++) sup[i] = support_of(fkeys[i]);
    wrt_sort_u64(sup, n);
    uint32_t ns = 0;
    for (uint32_t i = 0; i < n; i++)
        if (i == 0 || sup[i] != sup[i - 1]) sup[ns++] = sup[i];
    uint32_t *id = wrt_xmalloc(((size_t)n + 1) * sizeof *id);
    for (uint32_t i = 0; i < n; i++) {
        uint64_t k = support_of(fkeys[i]);
        uint32_t lo = 0, hi = ns;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2;
            if (sup[mid] < k) lo = mid + 1;
            else hi = mid;
        }
        id[i] = lo;
    }
    free(sup);
    int sorted = 1;
    for (uint32_t j = 1; j < n && sorted; j++) sorted = fkeys[j] >> 18 >= fkeys[j - 1] >> 18;
    /* the groups' first columns, then each group on a thread (a count: the same whatever
     * the threads) */
    uint32_t *g0 = wrt_xmalloc(((size_t)n + 1) * sizeof *g0), ng = 0;
    for (uint32_t j0 = 0; j0 < n;) {
        uint32_t j1 = sorted ? j0 + 1 : n;
        while (j1 < n && fkeys[j1] >> 18 == fkeys[j0] >> 18) j1++;
        g0[ng++] = j0;
        j0 = j1;
    }
    g0[ng] = n;
    int nt = wrt_threads_resolve(threads);
    links_job c = {m, id, g0, wrt_xcalloc((size_t)nt, sizeof *c.lp), wrt_xcalloc((size_t)nt, sizeof *c.cap),
                   wrt_xcalloc((size_t)nt, sizeof *c.links)};
    wrt_parallel_for(ng, nt, count_group, &c);
    uint64_t links = 0;
    for (int t = 0; t < nt; t++) {
        links += c.links[t];
        free(c.lp[t]);
    }
    free(c.lp); free(c.cap); free(c.links);
    free(g0);
    free(id);
    return links;
}
