/* dto.h: the Direct Transport Operator, pair by pair (dto.c): refines, integrates and
 * analyses the links from one quad to another. Called by the driver (bake.c); its
 * results (pair_out) feed the power balance (balance.h). Depends on bake_ctx.h. */
#ifndef WRT_DTO_H
#define WRT_DTO_H

#include "bake_ctx.h"

typedef struct pair_entry { uint64_t r, s; float v[3]; } pair_entry;
/* A diffuse pair's entries, held compactly until they are assembled (dto.c): one record
 * per receiver and sender function of a link whose entry T[r][s] or transposed entry
 * T[s][r] was kept: the two functions' keys within their quads (wrt_fkey bits 16..41:
 * cell and type; the angular part is the root), the two kept bits, and the kernel's
 * value g, of which the entries are (float)(g rho_S) and (float)(g rho_R) exactly as the
 * DTO made them. 16 bytes for up to two entries, where a pair_entry is 32 for one (the
 * 12 x 12 maze's 30.1M entries were 918 MB, the bake's peak). */
typedef struct pair_dent { uint64_t keys; double g; } pair_dent;
/* A leaf link of a pair with a diffuse sender, kept for the power balance (balance.c):
 * the receiver and sender cells (dto.c's node packing) and the visible share of the
 * link's sampled form factor (1 where no occluder can lie between the quads). */
typedef struct leaf_rec { uint32_t rn, sn; float vis; } leaf_rec;
typedef struct pair_out {
    pair_entry *e; size_t count; /* count: the pair's entries, in e or in d */
    pair_dent *d; size_t nd;     /* the compact records (diffuse pairs; e is then NULL) */
    int r, s;                    /* the quads (receiver, sender) wrt_dto_pair was given */
    leaf_rec *leaf; size_t nleaf;
    int occluded;          /* an occluder may lie between the quads */
    int leaf_dirs;         /* bit 0: the leaves serve sender s; bit 1: also sender r (reciprocal pair) */
    uint64_t links;
    uint64_t angular;      /* entries with an angular wavelet on either side */
    int glossy;            /* the pair touches a glossy quad */
    int kmode;             /* entries of the first-bounce operator K (columns: s's outgoing functions) */
    int cancelled;
} pair_out;

/* Refines, integrates and analyses the links from quad s to quad r (dto.c). */
/* flags: bit 0 an occluder may lie between, bit 1 diffuse pair computed once for both
 * directions (the entries of T[s][r] are emitted too), bit 2 the first-bounce operator K
 * instead of T (s glossy; one value, copied to the three channels of each entry). */
void wrt_dto_pair(const bake_ctx *b, int r, int s, int flags, bake_thread_counters *tc, pair_out *out);

/* The entries of a pair in the order the DTO made them: o->e, or o's compact records
 * decoded into *buf (grown as needed, *cap its length; the caller frees it). */
const pair_entry *wrt_pair_entries(const bake_ctx *b, const pair_out *o, pair_entry **buf, size_t *cap);
/* The bytes o's entries hold (records or entries, not the leaves). */
size_t wrt_pair_bytes(const pair_out *o);

/* WRT_DTO_TIMES: the per-pair DTO's pairs, rays and cover tests (nt threads' counters)
 * on stderr. */
void wrt_dto_times_cover(const bake_thread_counters *tc, int nt, size_t np, uint64_t rays);

/* The angular function of index idx (common/brdf_table.h's order): node and type. */
void wrt_angular_func(int idx, wrt_node *n, int *type);


#endif
