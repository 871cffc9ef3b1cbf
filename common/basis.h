/* basis.h: the 4D Haar basis of the paper (Kontkanen et al. 2006, sections 4.1-4.2),
 * with every constant written down once.
 *
 * Per quad, a basis function is (spatial 2D function) x (angular 2D function).
 * Each 2D subspace uses the non-standard (quadtree) Haar basis on [0,1]^2: one
 * scaling function at the root, and three wavelets at every node. Between the
 * spatial and the angular subspace the refinement is standard (independent levels).
 *
 * L2-normalised on [0,1]^2: a node at level l covers 2^-l x 2^-l and
 *   scaling  (type 0, root only):   1
 *   type 1: psi(u) phi(v)  = +-2^l, + on the lower half in u
 *   type 2: phi(u) psi(v)  = +-2^l, + on the lower half in v
 *   type 3: psi(u) psi(v)  = +-2^l, product of the two signs
 * An intermediate (non-root) node's scaling function, 2^l on its support, is not in
 * the basis; in terms of its parent P (child quadrant cx, cy in {0,1}):
 *   phi_child = 1/2 (phi_P + s1 psi1_P + s2 psi2_P + s1 s2 psi3_P),  s1 = cx ? -1 : 1, s2 = cy ? -1 : 1
 *
 * The 4D function on quad k, with spatial 2D Haar h(u,v) and angular 2D Haar g(a,b), is
 *   B(x, w) = h(u,v) g(M^-1(w)) / sqrt(pi J_k(u,v))
 * with M the cosine-weighted concentric map (Shirley-Chiu disk, lifted by Malley) in
 * the quad's tangent frame and J_k the parameterization's Jacobian. Under the inner
 * product <f,g> = int f g cos(theta) dw dA these are orthonormal, for parallelograms
 * and for general planar convex quads alike (dividing by sqrt(J) absorbs the bilinear
 * Jacobian). Consequences used everywhere:
 *   - uniform irradiance E0 on a parallelogram of area A: coefficient E0 sqrt(A/pi) on
 *     (spatial root, angular root);
 *   - irradiance at (u,v): E(u,v) = sqrt(pi / J(u,v)) * sum_h c(h, angular root) h(u,v).
 */
#ifndef WRT_BASIS_H
#define WRT_BASIS_H

#include <math.h>
#include <stdint.h>

#include "wrt_common.h"

#define WRT_MAX_SLEVEL 10 /* deepest spatial level (1024 x 1024 cells) */
#define WRT_MAX_ALEVEL 3  /* deepest angular level (8 x 8 direction cells) */
/* The deepest outgoing angular level of the first-bounce operator K (16 x 16 direction
 * cells: node levels 0..3, all that a key's 2 bits of angular level can name, and
 * common/brdf_table.h's 256 functions). */
#define WRT_K_MAX_LEVEL 4

/* A quadtree node: level and cell indices, packed. */
typedef struct wrt_node { uint8_t level; uint16_t x, y; } wrt_node;

static inline wrt_node wrt_node_root(void) { wrt_node n = {0, 0, 0}; return n; }
static inline wrt_node wrt_node_child(wrt_node n, int cx, int cy) {
    wrt_node c = {(uint8_t)(n.level + 1), (uint16_t)(2 * n.x + cx), (uint16_t)(2 * n.y + cy)};
    return c;
}
static inline wrt_node wrt_node_parent(wrt_node n) {
    wrt_node p = {(uint8_t)(n.level - 1), (uint16_t)(n.x >> 1), (uint16_t)(n.y >> 1)};
    return p;
}
/* Support of the node in [0,1]^2: [x0, x0 + size) x [y0, y0 + size). */
static inline double wrt_node_size(wrt_node n) { return wrt_pow2(-(int)n.level); }
static inline double wrt_node_x0(wrt_node n) { return n.x * wrt_node_size(n); }
static inline double wrt_node_y0(wrt_node n) { return n.y * wrt_node_size(n); }

/* Value of the 2D Haar function (node, type) at (u,v); 0 outside its support. */
static inline double wrt_haar2(wrt_node n, int type, double u, double v) {
    if (u >= 1.0) u = 0x1.fffffffffffffp-1; /* the closed upper edge belongs to the last cell */
    if (v >= 1.0) v = 0x1.fffffffffffffp-1;
    double s = wrt_pow2(n.level);
    double lu = u * s - n.x, lv = v * s - n.y;
    if (lu < 0 || lu >= 1 || lv < 0 || lv >= 1) return 0;
    double su = lu < 0.5 ? 1.0 : -1.0, sv = lv < 0.5 ? 1.0 : -1.0;
    switch (type) {
    case 0: return s;
    case 1: return s * su;
    case 2: return s * sv;
    default: return s * su * sv;
    }
}

/* Sign of wavelet `type` (1..3) of a node on its child quadrant (cx, cy). */
static inline double wrt_haar_sign(int type, int cx, int cy) {
    double s1 = cx ? -1.0 : 1.0, s2 = cy ? -1.0 : 1.0;
    return type == 1 ? s1 : type == 2 ? s2 : type == 3 ? s1 * s2 : 1.0;
}

/* A 4D basis function key: quad, spatial node + type, angular node + type.
 * Packed in 64 bits so that sorting keys groups functions by quad, then spatial
 * level, then position: quad 22 bits | slevel 4 | sy 10 | sx 10 | stype 2 |
 * alevel 2 | ay 3 | ax 3 | atype 2 | 6 spare. */
typedef uint64_t wrt_fkey;

static inline wrt_fkey wrt_fkey_make(uint32_t quad, wrt_node s, int stype, wrt_node a, int atype) {
    return ((uint64_t)quad << 42) | ((uint64_t)s.level << 38) | ((uint64_t)s.y << 28) |
           ((uint64_t)s.x << 18) | ((uint64_t)stype << 16) | ((uint64_t)a.level << 14) |
           ((uint64_t)a.y << 11) | ((uint64_t)a.x << 8) | ((uint64_t)atype << 6);
}
static inline uint32_t wrt_fkey_quad(wrt_fkey k) { return (uint32_t)(k >> 42); }
static inline wrt_node wrt_fkey_snode(wrt_fkey k) {
    wrt_node n = {(uint8_t)((k >> 38) & 15), (uint16_t)((k >> 18) & 1023), (uint16_t)((k >> 28) & 1023)};
    return n;
}
static inline int wrt_fkey_stype(wrt_fkey k) { return (int)((k >> 16) & 3); }
static inline wrt_node wrt_fkey_anode(wrt_fkey k) {
    wrt_node n = {(uint8_t)((k >> 14) & 3), (uint16_t)((k >> 8) & 7), (uint16_t)((k >> 11) & 7)};
    return n;
}
static inline int wrt_fkey_atype(wrt_fkey k) { return (int)((k >> 6) & 3); }
/* 1 if the angular factor is the angular root scaling function (what diffuse uses). */
static inline int wrt_fkey_angular_root(wrt_fkey k) { return ((k >> 6) & 0xFFu) == 0; }

/* Cosine-weighted concentric map: (a,b) in [0,1]^2 -> unit direction (x,y,z) in the
 * local frame, z >= 0 along the normal. pi * da db = cos(theta) dw. */
static inline void wrt_concentric_dir(double a, double b, double d[3]) {
    double sx = 2 * a - 1, sy = 2 * b - 1, r, phi;
    if (sx == 0 && sy == 0) { d[0] = 0; d[1] = 0; d[2] = 1; return; }
    if (fabs(sx) > fabs(sy)) { r = sx; phi = (M_PI / 4) * (sy / sx); }
    else { r = sy; phi = (M_PI / 2) - (M_PI / 4) * (sx / sy); }
    double x = r * cos(phi), y = r * sin(phi), z2 = 1 - x * x - y * y;
    d[0] = x; d[1] = y; d[2] = z2 > 0 ? sqrt(z2) : 0;
}
/* Inverse: a local unit direction with z >= 0 -> (a,b) in [0,1]^2. */
static inline void wrt_concentric_inv(const double d[3], double *a, double *b) {
    double x = d[0], y = d[1], r = sqrt(x * x + y * y), sx, sy;
    if (r == 0) { *a = 0.5; *b = 0.5; return; }
    double phi = atan2(y, x); /* (-pi, pi] */
    if (phi < -M_PI / 4) phi += 2 * M_PI; /* [-pi/4, 7pi/4) */
    if (phi < M_PI / 4) { sx = r; sy = r * phi / (M_PI / 4); }
    else if (phi < 3 * M_PI / 4) { sy = r; sx = r * (M_PI / 2 - phi) / (M_PI / 4); }
    else if (phi < 5 * M_PI / 4) { sx = -r; sy = -r * (phi - M_PI) / (M_PI / 4); }
    else { sy = -r; sx = -r * (3 * M_PI / 2 - phi) / (M_PI / 4); }
    *a = 0.5 * (sx + 1); *b = 0.5 * (sy + 1);
    *a = *a < 0 ? 0 : *a > 1 ? 1 : *a;
    *b = *b < 0 ? 0 : *b > 1 ? 1 : *b;
}

#endif
