/* reconstruct.h: smooth display of each quad's indirect light. The bake's Haar solution
 * is piecewise constant over its cells; shown as is it draws the cell grid on the screen.
 * This module resamples it into a smooth single-level grid per quad before display (the
 * "flattening" of Lehtinen et al. 2008), continuous inside a quad and across the edges
 * shared by coplanar neighbours, and never across a crease, a contact line or a wall.
 *
 * The method, average-interpolating subdivision: level by level from a quad's root, a
 * cell whose children's averages are kept (wrt_recon_params: the bake stored a function
 * there, above a level or with sharp details) takes the bake's children averages; any
 * other cell is split by the quadratic average-interpolating rule, child = a +
 * sx (a_E - a_W)/8 + sy (a_N - a_S)/8 + sx sy (a_NE - a_NW - a_SE + a_SW)/64 (sx, sy = -1
 * or +1 toward the child), its slopes limited so that no child leaves the range of its
 * neighbours (then without the cross term). Each split keeps the cell's average exactly
 * (so every kept average is kept) and reproduces a linear function exactly. Neighbours
 * across an edge come from the neighbouring quad (same level, along the shared edge);
 * where there is none, linear extrapolation from the quad's own cells. The output's
 * texels are the output level's averages, except that texels on a shared edge hold the
 * mean of the two cells beside the edge and corner texels the mean of the cells around
 * the corner, so that a clamped bilinear lookup (GL_LINEAR, CLAMP_TO_EDGE) is continuous
 * across the edge: both quads show exactly the same values along it. What such a texel
 * gains, the texel one step inside gives back (from 4 texels a side), so each quad's
 * texel sum, which is exactly the integral of its clamped bilinear display, is kept.
 * Negative values (an undershoot where a sharp detail is kept) are clamped to 0.
 *
 * Neighbours: two quads are smooth neighbours across an edge when they share it (both
 * end points within 1e-6 of the scene's size), lie in one plane, face the same way and
 * have the same material, and no other quad has an edge lying along the shared edge (a
 * wall standing on it, a box's side on a floor). Groups: the connected sets of quads
 * under that relation; a group is reconstructed together and at one resolution.
 *
 * Partial neighbours (T-junctions): an edge without a whole neighbour may meet other
 * quads' edges over a part of it, as a UV sphere's paired quad meets the two half-edges of
 * a pole triangle's quads. Collinear edges that overlap (by more than the tolerance, not
 * both ends shared), of quads on either side of the line, under the same rules (one plane
 * or agreeing corner normals at both ends of the overlap, same material, no third quad's
 * edge along the overlap), are partial neighbours; they join groups. A ghost cell across
 * such an edge is the neighbours' edge cells over the same stretch of the edge, at the
 * current level: over whole cells their mean (a half-edge's two cells for the whole
 * edge's one, one level coarser), inside one cell its value at the stretch's centre, with
 * the slope along the edge (the along-edge part of the prediction). At the output, the
 * longer edge's texels take the mean of their own cell and the shorter edges' over the
 * same stretch; then a shorter edge (one lying inside the longer one) shows the longer
 * one's display (its texels read along that edge at their positions), and a T-junction's
 * vertex (a corner of the shorter edges, inside the longer one) its value there; texel
 * centres of different sizes never line up, so the two sides differ where a side's
 * display is flat within half a texel of a corner (first order in the texel size) and
 * elsewhere only by the bend of the longer side's display between two texel centres of
 * the shorter side (second order; measured in docs/triangles.md).
 *
 * Pure functions of their arguments: no OpenGL, no globals; depends on libc only (so it
 * sits in common/: the runtime uses it for its textures, the verification for its seams).
 * Reentrant: distinct groups may be reconstructed in parallel. */
#ifndef WRT_RECONSTRUCT_H
#define WRT_RECONSTRUCT_H

#include <stddef.h>
#include <stdint.h>

typedef struct wrt_recon wrt_recon;

/* Adjacency of `n` quads: corners[q] in (u,v) order (0,0), (1,0), (1,1), (0,1), world
 * space; material[q] any identifier (equal = same material). NULL on out of memory. */
wrt_recon *wrt_recon_create(int n, const double (*corners)[4][3], const uint32_t *material);
/* The same with the caller's allocator (alloc NULL: malloc and free), used for the
 * adjacency and for wrt_recon_run's scratch (then from the threads that run it). */
typedef struct wrt_recon_allocator {
    void *(*alloc)(void *user, size_t size); /* the user pointer first, as everywhere in wrt */
    void (*free)(void *user, void *p);
    void *user;
} wrt_recon_allocator;
wrt_recon *wrt_recon_create_with(int n, const double (*corners)[4][3], const uint32_t *material,
                                 const wrt_recon_allocator *a);
/* The same on a curved mesh: with each quad's corner normals (normals[q][k] at corners[q][k],
 * unit; NULL: none, as wrt_recon_create_with), two quads that share an edge and a material
 * but do not lie in one plane are also smooth neighbours when their normals agree at both
 * ends of the edge (cosine >= cos_tol) and their faces are not folded onto each other
 * (flat normals at most 120 degrees apart); the wall test still applies. So the display is
 * continuous across a smooth mesh's edges and stops at a crease, where the mesh's normals
 * split. WRT_RECON_SMOOTH_COS is the runtime's tolerance (docs/triangles.md). */
#define WRT_RECON_SMOOTH_COS 0.9998 /* about 1.1 degrees */
wrt_recon *wrt_recon_create_smooth(int n, const double (*corners)[4][3], const uint32_t *material,
                                   const float (*normals)[4][3], double cos_tol, const wrt_recon_allocator *a);
void wrt_recon_destroy(wrt_recon *rc); /* NULL is a no-op */

int wrt_recon_ngroups(const wrt_recon *rc);
int wrt_recon_group(const wrt_recon *rc, int q);
/* The members of group `gr`, ascending; *count their number. */
const int *wrt_recon_members(const wrt_recon *rc, int gr, int *count);
/* Quad q's smooth neighbour across edge e (0: v = 0, 1: u = 1, 2: v = 1, 3: u = 0), or -1;
 * *nedge its edge, *flip 1 if it runs the shared edge the other way. */
int wrt_recon_neighbour(const wrt_recon *rc, int q, int e, int *nedge, int *flip);
/* Quad q's i-th partial neighbour along edge e (a T-junction: an edge that meets another
 * over a part of it, as a paired quad's whole edge meets the two half-edges of a
 * triangle's quads), or -1 past the last; *nedge its edge, range[0 .. 1] the overlap on
 * q's edge (its parameter, 0 at the edge's first corner, ascending), range[2 .. 3] the same
 * two points on the neighbour's edge. Only edges without a whole neighbour have them. */
int wrt_recon_partial(const wrt_recon *rc, int q, int e, int i, int *nedge, double range[4]);
/* 1 if quad q is joined to a smooth neighbour that does not lie in its plane (a curved
 * mesh's edge, by the corner normals), else 0. */
int wrt_recon_curved(const wrt_recon *rc, int q);

/* Index of node (level l, x, y) in a `known` mask: levels 0 .. L-1, level by level, row
 * by row: (4^l - 1)/3 + y 2^l + x. A mask for levels < L holds (4^L - 1)/3 bytes. */
static inline uint32_t wrt_recon_node(int l, int x, int y) {
    return (uint32_t)((((uint32_t)1 << (2 * l)) - 1) / 3 + ((uint32_t)y << l) + (uint32_t)x);
}

/* Which of the bake's averages are kept (NULL: the defaults). A node's children keep the
 * bake's averages if it holds a function and lies above level `keep`, or below it if the
 * prediction misses its details: a child's offset from the node's average differs from
 * the limited prediction's by more than `sharp` times the larger of the node's average
 * and the quad's mean (0: never); the rest are predicted. `limit` 1: the prediction's slopes are limited
 * (monotonized central: no child beyond its neighbours' range, so a dark cell beside a lit
 * one stays dark, and linear functions are still reproduced exactly). `linear` 1: the
 * output is a fixed linear function of the input (the sum of two inputs' outputs is the
 * output of their sum, to float rounding): `limit` and `sharp` are ignored (no limiter; a
 * node keeps its children's averages if it holds a function and lies above `keep`, a
 * choice from `known` alone) and negative texels are kept, not clamped to 0. The default (0) is
 * not linear: the limiter, the sharpness test and the clamp all depend on the data.
 * A curved quad (wrt_recon_curved: joined to a neighbour across a bent edge by its corner
 * normals) keeps only its mean, plus the details the prediction misses by more than
 * half of `sharp`, and its prediction is not limited: its bake cells and means are those of a flat
 * facet, and kept as they are they showed each facet as a tile of its own, bordered where
 * the edges are averaged (docs/triangles.md). `facets` 1: curved quads as flat ones (the
 * display before; for comparisons).
 * The vertex blend (default; created with corner normals): in a group holding a curved
 * quad, each vertex of the mesh (a paired quad's corner, a triangle's vertex; triangles are
 * rebuilt from their parts as common/smooth.h does) takes the mean of the members' means
 * around it, weighted by their interior angles there, and every curved quad shows the
 * blend of its source polygon's vertex values (barycentric over a triangle, bilinear over
 * a paired quad), edge texels at the edge, the others at their centres: no facet is seen,
 * and the display is continuous across every edge and T-junction of the mesh. Its means
 * are not kept (a facet's own light is spread to its vertices). A flat member's edge and
 * corner texels beside a curved quad take the same blend (given back inside, as above).
 * Linear in the input. `facet_means` 1: curved quads keep their facets' means as above
 * (the display of session 7; for comparisons). */
typedef struct wrt_recon_params { int keep; float sharp; int limit; int linear; int facets; int facet_means; } wrt_recon_params;
#define WRT_RECON_KEEP 3
#define WRT_RECON_SHARP 0.1f

/* Reconstructs every member of group `gr`: in[q] holds quad q's 2^L x 2^L cell averages
 * (nc floats a cell, cell (i, j) at (j 2^L + i) nc, i along u), known[q] its mask for
 * levels < L (1: the bake stored a function at the node, so its children's averages are
 * known; NULL: all known), out[q] receives 2^Lo x 2^Lo cells in the same layout (Lo < L:
 * the input's details below level Lo are averaged out). in, known and out are indexed by quad; only the group's members are read.
 * Returns 0, or -1 on out of memory (out untouched). */
int wrt_recon_run(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                  const uint8_t *const *known, float *const *out, const wrt_recon_params *p);

/* The same with the caller's scratch (no allocation): buf holds at least
 * wrt_recon_scratch(rc, gr, L, Lo, nc) floats, not read before written
 * (its last 4 floats are padding that 4-float loads of RGB values may read). */
size_t wrt_recon_scratch(const wrt_recon *rc, int gr, int L, int Lo, int nc);
void wrt_recon_run_in(const wrt_recon *rc, int gr, int L, int Lo, int nc, const float *const *in,
                      const uint8_t *const *known, float *const *out, const wrt_recon_params *p, float *buf);

#endif
