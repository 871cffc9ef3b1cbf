/* reconstruct_internal.h: the adjacency that reconstruct.c builds and reconstruct_run.c
 * reads (struct wrt_recon, its corner sets and partial neighbours). Only those two
 * files include it; reconstruct.h is the interface. */
#ifndef WRT_RECONSTRUCT_INTERNAL_H
#define WRT_RECONSTRUCT_INTERNAL_H

#include <stdlib.h>

#include "reconstruct.h"

#define MAX_AROUND 40 /* quads around one corner within a group (a 32-segment UV sphere's pole: 32) */

#define MAX_TREF 4    /* edges of other quads passing through one corner (a T-junction's vertex) */

/* The quads around a corner, and the edges it lies inside of (a T-junction: the vertex
 * where a triangle's two half-edges meet lies inside the paired quad's whole edge): each
 * T-reference is quad tquad's edge tedge at its parameter ts. */
typedef struct corner_set {
    int n, nt;
    int quad[MAX_AROUND], corner[MAX_AROUND];
    int tquad[MAX_TREF], tedge[MAX_TREF];
    double ts[MAX_TREF];
} corner_set;

/* A neighbour along a part of an edge (a T-junction, or any overlap of two collinear
 * edges that do not share both ends): the overlap is [t0, t1] (t0 < t1) on this edge, in
 * its parameter (0 at E_END[e][0], 1 at E_END[e][1]), and runs from s0 to s1 on the
 * neighbour's edge f, in that edge's parameter. */
typedef struct part_nb { int o, f, bent; double t0, t1, s0, s1; } part_nb; /* bent: joined by the corner normals */

struct wrt_recon {
    int n, ngroups;
    int (*nb)[4], (*nbe)[4], (*flip)[4];
    uint8_t (*bent)[4];          /* the edge's neighbour was joined by the corner normals */
    uint8_t *curved;             /* joined to a neighbour across a bent edge (corner normals) */
    int *group, *slot;           /* slot: position within its group */
    int *gfirst, *gquads;        /* members of group g: gquads[gfirst[g] .. gfirst[g+1]) */
    corner_set (*around)[4];     /* quads around each corner (itself included), ascending */
    int *pfirst;                 /* edge e of quad q: its partial neighbours pnb[pfirst[4q+e] .. pfirst[4q+e+1]) */
    part_nb *pnb;                /* ascending quad, edge, t0 */
    /* The vertex blend (groups with a curved quad; NULL without normals): each member's
     * smooth source (a triangle's part: its triangle; a paired quad: its corners), its
     * vertices numbered within the group, and the weight the member's mean gives each of
     * them (its interior angle at that vertex where it is one of its own corners, else 0). */
    uint8_t *bkind;              /* 0: no blend (the group has no curved quad), 3: a triangle's part, 4: a paired quad */
    uint8_t *bshow;              /* 1: shows the blend (curved, or its corner normals leave its plane) */
    int (*bvid)[4];
    float (*bw)[4];
    int *gnv;                    /* group g's source vertices (0: the group is not blended) */
    uint8_t *gall;               /* 1: every member of group g shows the blend (only the means are read) */
    wrt_recon_allocator al;      /* alloc NULL: malloc and free */
};

static inline void *rc_alloc(const wrt_recon_allocator *al, size_t n) { return al->alloc ? al->alloc(al->user, n ? n : 1) : malloc(n ? n : 1); }
static inline void rc_free(const wrt_recon_allocator *al, void *p) { if (p) { if (al->alloc) al->free(al->user, p); else free(p); } }

#endif
