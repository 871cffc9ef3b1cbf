/* links.c: what the bake's stages ask of the sorted function keys (wrt_fkey of
 * common/basis.h): the index of a key, and the number of links of a matrix over the keys
 * (entries grouped by the supports of their two functions, the paper's link count).
 * Used by the driver (bake.c), the power balance and the series. Depends on sparse.h
 * and wrt_common. */
#include "links.h"

#include <stdlib.h>

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

/* The link of a function: its key without the wavelet types. */
static uint64_t support_of(uint64_t k) { return k & ~((3ULL << 16) | (3ULL << 6)); }

typedef struct link_pair { uint64_t r, s; } link_pair;
static int cmp_lp(const void *pa, const void *pb) {
    const link_pair *a = pa, *b = pb;
    if (a->r != b->r) return a->r < b->r ? -1 : 1;
    return a->s < b->s ? -1 : a->s > b->s;
}

uint64_t wrt_count_links(const wrt_csc *m, const uint64_t *fkeys) {
    if (!m->nnz) return 0;
    link_pair *lp = wrt_xmalloc(m->nnz * sizeof *lp);
    uint64_t k = 0;
    for (uint32_t j = 0; j < m->n; j++)
        for (uint64_t i = m->col[j]; i < m->col[j + 1]; i++)
            lp[k++] = (link_pair){support_of(fkeys[m->row[i]]), support_of(fkeys[j])};
    qsort(lp, k, sizeof *lp, cmp_lp);
    uint64_t links = 0;
    for (uint64_t i = 0; i < k; i++)
        if (i == 0 || lp[i].r != lp[i - 1].r || lp[i].s != lp[i - 1].s) links++;
    free(lp);
    return links;
}
