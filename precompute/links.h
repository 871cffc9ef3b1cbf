/* links.h: the index of a function key and the link count of a matrix over the keys
 * (links.c). Depends on sparse.h. */
#ifndef WRT_LINKS_H
#define WRT_LINKS_H

#include <stdint.h>

#include "sparse.h"

/* Counts links (groups of entries sharing the four supports) of a matrix over fkeys. */
uint64_t wrt_count_links(const wrt_csc *m, const uint64_t *fkeys);

/* Index of a key in the sorted fkeys, or -1. */
int64_t wrt_fkey_find(const uint64_t *fkeys, uint32_t n, uint64_t key);

#endif
