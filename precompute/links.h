/* links.h: the index of a function key and the link count of a matrix over the keys
 * (links.c). Depends on sparse.h. */
#ifndef WRT_LINKS_H
#define WRT_LINKS_H

#include <stdint.h>

#include "sparse.h"

/* Counts links (groups of entries sharing the four supports) of a matrix over fkeys, on
 * `threads` threads (0: all cores). */
uint64_t wrt_count_links(const wrt_csc *m, const uint64_t *fkeys, int threads);

/* Index of a key in the sorted fkeys, or -1. */
int64_t wrt_fkey_find(const uint64_t *fkeys, uint32_t n, uint64_t key);

/* A set of function keys by open addressing: the distinct keys of the bake's entries
 * collected without an array of every entry's two keys, then sorted, and each key's
 * index found without a binary search. */
typedef struct wrt_fkey_set {
    uint64_t *key;
    uint32_t *idx;  /* UINT32_MAX: empty slot; after wrt_fkey_set_sorted, the key's index */
    size_t cap, n;
} wrt_fkey_set;
void wrt_fkey_set_add(wrt_fkey_set *s, uint64_t key);
/* The distinct keys, sorted (a new array of s->n; NULL if the set is empty), and each
 * key's index in it recorded for wrt_fkey_set_find. */
uint64_t *wrt_fkey_set_sorted(wrt_fkey_set *s);
/* The index of a key of the set (after wrt_fkey_set_sorted), or -1. */
int64_t wrt_fkey_set_find(const wrt_fkey_set *s, uint64_t key);
void wrt_fkey_set_free(wrt_fkey_set *s);

#endif
