/* scenegen.c: wrt-scenegen, the generator of wrt's reference scenes. It writes
 * self-contained glTF 2.0 files (.gltf, one buffer embedded as a base64 data URI)
 * made only of quads, each stored as two indexed triangles (0,1,2)+(0,2,3) sharing
 * the 0-2 diagonal, corners counter-clockwise seen from the front so that the glTF
 * front face looks into the room. Materials are glTF metallic-roughness factors,
 * lights are KHR_lights_punctual point, spot or directional lights (intensity in
 * candela, in lux for a directional one; the spot's axis and the sun's direction are
 * the node's -Z), plus one perspective camera. Units are metres,
 * +Y is up. Scenes: the Cornell box, the maze and the glossy test scene of the
 * paper's section 6 (Table 1, Figure 10), and small test scenes for the bake
 * (facing, perpendicular, furnace, tworooms, grazing). Every surface is an
 * axis-aligned rectangle or a vertical/horizontal extrusion, and subdivision
 * interpolates each coordinate symmetrically, so quads are exactly planar in
 * float and neighbouring quads share bit-identical corners. Output depends only
 * on the options (same options, same bytes). The glTF text itself is written by
 * scenegen_gltf.c (write_gltf, tools/scenegen.h). Depends on wrt_common.h only. */
#define _POSIX_C_SOURCE 200809L
#include "cli/cli.h"
#include "common/wrt_common.h"
#include "common/outfile.h"
#include "tools/scenegen.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---------------------------------------------------------------- options */

static sg_options sg_defaults(void) {
    sg_options o;
    memset(&o, 0, sizeof o);
    o.res = 1;
    o.albedo = 0.75;
    o.scale = 1.0;
    o.offset = v3(0, 0, 0);
    o.dist = 1.0;
    o.angle = 1.0;
    o.thick = 0.02;
    o.light = LIGHT_DEFAULT;
    o.intensity = 0.0;
    o.cells = 6;
    o.seed = 1;
    o.roughness = 0.3;
    o.detail = 1.0;
    return o;
}

/* ------------------------------------------------------------ scene model */

static int add_material(sg_scene *s, const char *name, double r, double g, double b,
                        double metallic, double roughness) {
    sg_material *m = &s->mats[s->nmats];
    snprintf(m->name, sizeof m->name, "%s", name);
    m->rgb[0] = r; m->rgb[1] = g; m->rgb[2] = b;
    m->metallic = metallic;
    m->roughness = roughness;
    return s->nmats++;
}

static int add_mesh(sg_scene *s, const char *name, int material) {
    sg_mesh *m = &s->meshes[s->nmeshes];
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "%s", name);
    m->material = material;
    return s->nmeshes++;
}

static void add_light(sg_scene *s, const char *name, int type, wrt_v3 pos, wrt_v3 target,
                      double intensity, double r, double g, double b, double inner_deg,
                      double outer_deg) {
    sg_light *l = &s->lights[s->nlights++];
    snprintf(l->name, sizeof l->name, "%s", name);
    l->type = type;
    l->pos = pos;
    l->dir = v3_norm(v3_sub(target, pos));
    l->rgb[0] = r; l->rgb[1] = g; l->rgb[2] = b;
    l->intensity = intensity;
    l->inner = inner_deg * WRT_PI / 180.0;
    l->outer = outer_deg * WRT_PI / 180.0;
}

static void set_camera(sg_scene *s, wrt_v3 eye, wrt_v3 target, double yfov_deg) {
    s->eye = eye;
    s->target = target;
    s->up = v3(0, 1, 0);
    s->yfov = yfov_deg * WRT_PI / 180.0;
}

/* World position of a scene point: scale, then offset, rounded once to float. */
static void put_point(const sg_scene *s, float *dst, wrt_v3 p) {
    dst[0] = (float)(p.x * s->opt.scale + s->opt.offset.x);
    dst[1] = (float)(p.y * s->opt.scale + s->opt.offset.y);
    dst[2] = (float)(p.z * s->opt.scale + s->opt.offset.z);
}

/* Interpolates a coordinate between a and b at i/n, giving the same bits whichever
 * end it starts from, so quads on both sides of an edge share their vertices. */
static double lerp_sym(double a, double b, int i, int n) {
    if (i == 0) return a;
    if (i == n) return b;
    if (a <= b) return a + (b - a) * ((double)i / n);
    return b + (a - b) * ((double)(n - i) / n);
}

static wrt_v3 lerp_sym3(wrt_v3 a, wrt_v3 b, int i, int n) {
    return v3(lerp_sym(a.x, b.x, i, n), lerp_sym(a.y, b.y, i, n), lerp_sym(a.z, b.z, i, n));
}

/* Point (i,j) of the n x n grid on the quad p0 p1 p2 p3 (i along p0->p1). */
static wrt_v3 grid_point(const wrt_v3 p[4], int i, int j, int n) {
    return lerp_sym3(lerp_sym3(p[0], p[1], i, n), lerp_sym3(p[3], p[2], i, n), j, n);
}

static void push_quad(sg_scene *s, sg_mesh *m, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 d,
                      wrt_v3 n) {
    if (m->nquads == m->cap) {
        m->cap = m->cap ? 2 * m->cap : 16;
        m->pos = wrt_xrealloc(m->pos, (size_t)m->cap * 12 * sizeof(float));
        m->nrm = wrt_xrealloc(m->nrm, (size_t)m->cap * 12 * sizeof(float));
    }
    float *pp = m->pos + (size_t)m->nquads * 12, *nn = m->nrm + (size_t)m->nquads * 12;
    put_point(s, pp + 0, a);
    put_point(s, pp + 3, b);
    put_point(s, pp + 6, c);
    put_point(s, pp + 9, d);
    for (int k = 0; k < 4; k++) {
        nn[3 * k + 0] = (float)n.x;
        nn[3 * k + 1] = (float)n.y;
        nn[3 * k + 2] = (float)n.z;
    }
    m->nquads++;
}

/* A triangle a b c (counter-clockwise seen from its front) with a normal per vertex
 * (the smooth surface's, for a curved mesh). */
static void push_tri(sg_scene *s, sg_mesh *m, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 na, wrt_v3 nb, wrt_v3 nc) {
    if (m->ntris == m->tcap) {
        m->tcap = m->tcap ? 2 * m->tcap : 16;
        m->tpos = wrt_xrealloc(m->tpos, (size_t)m->tcap * 9 * sizeof(float));
        m->tnrm = wrt_xrealloc(m->tnrm, (size_t)m->tcap * 9 * sizeof(float));
    }
    float *pp = m->tpos + (size_t)m->ntris * 9, *nn = m->tnrm + (size_t)m->ntris * 9;
    wrt_v3 p[3] = {a, b, c}, n[3] = {na, nb, nc};
    for (int k = 0; k < 3; k++) {
        put_point(s, pp + 3 * k, p[k]);
        wrt_v3 u = v3_norm(n[k]);
        nn[3 * k + 0] = (float)u.x;
        nn[3 * k + 1] = (float)u.y;
        nn[3 * k + 2] = (float)u.z;
    }
    m->ntris++;
}

/* A planar face a b c d as two triangles (a b c, a c d), as a mesh exporter writes it. */
static void push_tri_quad(sg_scene *s, sg_mesh *m, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 d) {
    wrt_v3 n = v3_cross(v3_sub(b, a), v3_sub(d, a));
    push_tri(s, m, a, b, c, n, n, n);
    push_tri(s, m, a, c, d, n, n, n);
}

/* Adds the planar convex quad with corners p0..p3 (in order around it) to mesh
 * `mesh`, subdivided res x res, its front face towards `facing`: the corner order
 * is reversed if needed, so the caller states intent instead of a winding. */
static void add_quad(sg_scene *s, int mesh, wrt_v3 p0, wrt_v3 p1, wrt_v3 p2, wrt_v3 p3,
                     wrt_v3 facing) {
    wrt_v3 p[4] = {p0, p1, p2, p3};
    wrt_v3 n = v3_cross(v3_sub(p1, p0), v3_sub(p3, p0));
    if (v3_dot(n, facing) < 0) {
        p[1] = p3;
        p[3] = p1;
        n = v3_scale(n, -1);
    }
    n = v3_norm(n);
    int r = s->opt.res;
    for (int j = 0; j < r; j++)
        for (int i = 0; i < r; i++)
            push_quad(s, &s->meshes[mesh], grid_point(p, i, j, r), grid_point(p, i + 1, j, r),
                      grid_point(p, i + 1, j + 1, r), grid_point(p, i, j + 1, r), n);
}

/* Axis-aligned rectangle: `axis` 0/1/2 is the constant coordinate (value c), the
 * other two span [lo0,hi0] x [lo1,hi1] in cyclic order (x: y,z; y: z,x; z: x,y);
 * `sign` +1/-1 says which way along `axis` the front face looks. */
static void add_rect(sg_scene *s, int mesh, int axis, double c, double lo0, double hi0,
                     double lo1, double hi1, int sign) {
    wrt_v3 q[4];
    double u[4] = {lo0, hi0, hi0, lo0}, v[4] = {lo1, lo1, hi1, hi1};
    for (int k = 0; k < 4; k++) {
        double w[3];
        w[axis] = c;
        w[(axis + 1) % 3] = u[k];
        w[(axis + 2) % 3] = v[k];
        q[k] = v3(w[0], w[1], w[2]);
    }
    double f[3] = {0, 0, 0};
    f[axis] = sign;
    add_quad(s, mesh, q[0], q[1], q[2], q[3], v3(f[0], f[1], f[2]));
}

/* Closed axis-aligned box [lo,hi] seen from inside: 6 quads facing inwards. */
static void add_room(sg_scene *s, int mesh, wrt_v3 lo, wrt_v3 hi) {
    add_rect(s, mesh, 0, lo.x, lo.y, hi.y, lo.z, hi.z, +1);
    add_rect(s, mesh, 0, hi.x, lo.y, hi.y, lo.z, hi.z, -1);
    add_rect(s, mesh, 1, lo.y, lo.z, hi.z, lo.x, hi.x, +1);
    add_rect(s, mesh, 1, hi.y, lo.z, hi.z, lo.x, hi.x, -1);
    add_rect(s, mesh, 2, lo.z, lo.x, hi.x, lo.y, hi.y, +1);
    add_rect(s, mesh, 2, hi.z, lo.x, hi.x, lo.y, hi.y, -1);
}

/* A box standing on y = 0: footprint w x d centred at (cx, cz) turned by `deg`
 * degrees about +Y, height h; 4 sides and the top, facing outwards (no bottom). */
static void add_block(sg_scene *s, int mesh, double cx, double cz, double w, double d,
                      double h, double deg) {
    double a = deg * WRT_PI / 180.0, ca = cos(a), sa = sin(a);
    double lx[4] = {-w / 2, w / 2, w / 2, -w / 2}, lz[4] = {-d / 2, -d / 2, d / 2, d / 2};
    wrt_v3 b[4], t[4];
    for (int k = 0; k < 4; k++) {
        double x = cx + ca * lx[k] + sa * lz[k], z = cz - sa * lx[k] + ca * lz[k];
        b[k] = v3(x, 0, z);
        t[k] = v3(x, h, z);
    }
    wrt_v3 centre = v3(cx, h / 2, cz);
    for (int k = 0; k < 4; k++) {
        int k1 = (k + 1) % 4;
        wrt_v3 mid = v3_scale(v3_add(b[k], b[k1]), 0.5);
        wrt_v3 out = v3_sub(mid, v3(centre.x, 0, centre.z));
        add_quad(s, mesh, b[k], b[k1], t[k1], t[k], out);
    }
    add_quad(s, mesh, t[0], t[1], t[2], t[3], v3(0, 1, 0));
}

/* ----------------------------------------------------------------- scenes */

/* Cornell box, 1 m: x in [-0.5,0.5] (red wall at -x, i.e. left as seen by the camera
 * at +z), y in [0,1], z in [-0.5,0.5], open at +z. Dimensions follow the measured
 * box (555 mm) divided by 555; the short and tall boxes stand where they do there. */
static void cornell_build(sg_scene *s, int glossy_back) {
    double a = s->opt.albedo;
    int white = add_material(s, "white", a, a, a, 0, 1);
    int red = add_material(s, "red", 0.63, 0.065, 0.05, 0, 1);
    int green = add_material(s, "green", 0.14, 0.45, 0.09, 0, 1);
    int back = glossy_back ? add_material(s, "glossy_metal", 0.9, 0.9, 0.9, 1, s->opt.roughness) : white;
    add_rect(s, add_mesh(s, "floor", white), 1, 0.0, -0.5, 0.5, -0.5, 0.5, +1);
    add_rect(s, add_mesh(s, "ceiling", white), 1, 1.0, -0.5, 0.5, -0.5, 0.5, -1);
    add_rect(s, add_mesh(s, "back_wall", back), 2, -0.5, -0.5, 0.5, 0.0, 1.0, +1);
    add_rect(s, add_mesh(s, "left_wall", red), 0, -0.5, 0.0, 1.0, -0.5, 0.5, +1);
    add_rect(s, add_mesh(s, "right_wall", green), 0, 0.5, 0.0, 1.0, -0.5, 0.5, -1);
    add_block(s, add_mesh(s, "short_box", white), 0.17, 0.20, 0.30, 0.30, 0.30, -17);
    add_block(s, add_mesh(s, "tall_box", white), -0.16, -0.13, 0.30, 0.30, 0.60, 17);
    add_light(s, "ceiling_light", LIGHT_POINT, v3(0, 0.85, 0), v3(0, 0, 0), 2.5, 1, 1, 1, 60, 80);
    set_camera(s, v3(0, 0.5, 1.9), v3(0, 0.5, 0), 39.3);
}

static void scene_cornell(sg_scene *s) { cornell_build(s, 0); }

/* The Cornell box lit only by an emissive ceiling panel (docs/emitters.md): a 0.35 m
 * square 5 mm under the ceiling, facing down, albedo 0.78, emitted radiance
 * (1, 0.9, 0.75) x 10 (emissiveFactor x KHR_materials_emissive_strength); no lamp. */
static void scene_cornell_emit(sg_scene *s) {
    cornell_build(s, 0);
    s->nlights = 0;
    int panel = add_material(s, "panel", 0.78, 0.78, 0.78, 0, 1);
    s->mats[panel].emissive[0] = 1; s->mats[panel].emissive[1] = 0.9; s->mats[panel].emissive[2] = 0.75;
    s->mats[panel].strength = 10;
    add_rect(s, add_mesh(s, "panel", panel), 1, 0.995, -0.175, 0.175, -0.175, 0.175, -1);
}

/* The Cornell box with a glossy metal back wall (base colour 0.9, metallic 1,
 * roughness --roughness): the reflections of the lit ceiling and of the boxes are
 * glossy-to-diffuse-to-glossy transport a path tracer shows. */
static void scene_cornell_glossy(sg_scene *s) { cornell_build(s, 1); }

/* splitmix64: a tiny PRNG whose sequence is fixed by its seed on every platform. */
static uint64_t rng_next(uint64_t *st) {
    uint64_t z = (*st += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

/* Maze: `cells` x `cells` corridors of 1 m separated by 0.2 m thick, 1 m high walls,
 * carved by a depth-first search from a fixed seed. The layout is a grid of
 * (2N+1)^2 blocks: odd/odd are corridor cells, even/even pillars, the rest walls that
 * stand or were carved. Only the boundary between solid and open blocks is emitted
 * (wall faces, tops of solid blocks, floor tiles of open blocks) plus the outside
 * of the boundary wall, so no quad is hidden or overlapping and the whole surface
 * is one consistently oriented sheet, open only along the bottom of its outside.
 * Lit from above by three spotlights. */
static void scene_maze(sg_scene *s) {
    const double cw = 1.0, tw = 0.2, h = 1.0;
    int n = s->opt.cells, g = 2 * n + 1;
    unsigned char *solid = wrt_xcalloc((size_t)g * g, 1);
    for (int z = 0; z < g; z++)
        for (int x = 0; x < g; x++) solid[z * g + x] = !((x & 1) && (z & 1));
    /* depth-first carving over cells (cx, cz) */
    int *stack = wrt_xmalloc((size_t)n * n * sizeof(int));
    unsigned char *seen = wrt_xcalloc((size_t)n * n, 1);
    uint64_t st = s->opt.seed;
    int sp = 0;
    stack[sp++] = 0;
    seen[0] = 1;
    while (sp > 0) {
        int c = stack[sp - 1], cx = c % n, cz = c / n;
        int cand[4], nc = 0;
        static const int dx[4] = {1, -1, 0, 0}, dz[4] = {0, 0, 1, -1};
        for (int k = 0; k < 4; k++) {
            int x = cx + dx[k], z = cz + dz[k];
            if (x >= 0 && x < n && z >= 0 && z < n && !seen[z * n + x]) cand[nc++] = k;
        }
        if (nc == 0) { sp--; continue; }
        int k = cand[rng_next(&st) % (uint64_t)nc];
        int x = cx + dx[k], z = cz + dz[k];
        solid[(2 * cz + 1 + dz[k]) * g + (2 * cx + 1 + dx[k])] = 0;
        seen[z * n + x] = 1;
        stack[sp++] = z * n + x;
    }
    /* block edges along x and z: position of grid line k */
    double *line = wrt_xmalloc((size_t)(g + 1) * sizeof(double));
    double half = (n * cw + (n + 1) * tw) / 2;
    line[0] = -half;
    for (int k = 0; k < g; k++) line[k + 1] = line[k] + ((k & 1) ? cw : tw);
    line[g] = half;

    double a = s->opt.albedo;
    int m_floor = add_material(s, "floor_grey", 0.5, 0.5, 0.5, 0, 1);
    int m_white = add_material(s, "wall_white", a, a, a, 0, 1);
    int m_ochre = add_material(s, "wall_ochre", 0.72, 0.55, 0.25, 0, 1);
    int m_blue = add_material(s, "wall_blue", 0.25, 0.35, 0.65, 0, 1);
    int mfloor = add_mesh(s, "floor", m_floor);
    int tops = add_mesh(s, "wall_tops", m_white);
    int walls[3] = {add_mesh(s, "walls_white", m_white), add_mesh(s, "walls_ochre", m_ochre),
                    add_mesh(s, "walls_blue", m_blue)};
    for (int z = 0; z < g; z++)
        for (int x = 0; x < g; x++) {
            double x0 = line[x], x1 = line[x + 1], z0 = line[z], z1 = line[z + 1];
            if (solid[z * g + x]) {
                add_rect(s, tops, 1, h, z0, z1, x0, x1, +1);
                continue;
            }
            add_rect(s, mfloor, 1, 0.0, z0, z1, x0, x1, +1);
            /* faces of the solid neighbours that look into this open block */
            int nx[4] = {x - 1, x + 1, x, x}, nz[4] = {z, z, z - 1, z + 1};
            for (int k = 0; k < 4; k++) {
                if (nx[k] < 0 || nx[k] >= g || nz[k] < 0 || nz[k] >= g) continue;
                if (!solid[nz[k] * g + nx[k]]) continue;
                int pick = (int)(rng_next(&st) % 10);
                int mesh = walls[pick < 6 ? 0 : pick < 8 ? 1 : 2];
                if (k == 0) add_rect(s, mesh, 0, x0, 0, h, z0, z1, +1);
                if (k == 1) add_rect(s, mesh, 0, x1, 0, h, z0, z1, -1);
                if (k == 2) add_rect(s, mesh, 2, z0, x0, x1, 0, h, +1);
                if (k == 3) add_rect(s, mesh, 2, z1, x0, x1, 0, h, -1);
            }
        }
    /* the outside of the boundary wall, so the maze looks solid from the camera */
    for (int k = 0; k < g; k++) {
        add_rect(s, walls[0], 0, -half, 0, h, line[k], line[k + 1], -1);
        add_rect(s, walls[0], 0, half, 0, h, line[k], line[k + 1], +1);
        add_rect(s, walls[0], 2, -half, line[k], line[k + 1], 0, h, -1);
        add_rect(s, walls[0], 2, half, line[k], line[k + 1], 0, h, +1);
    }
    double f = half / 3.7; /* light layout designed for the 6 x 6 maze */
    add_light(s, "spot_warm", LIGHT_SPOT, v3(-2.0 * f, 3.0, -2.0 * f), v3(-1.5 * f, 0, -1.2 * f),
              30, 1.0, 0.9, 0.75, 30, 40);
    add_light(s, "spot_cool", LIGHT_SPOT, v3(2.2 * f, 3.2, -0.5 * f), v3(1.5 * f, 0, 0.3 * f),
              30, 0.75, 0.85, 1.0, 30, 40);
    add_light(s, "spot_white", LIGHT_SPOT, v3(-0.5 * f, 3.0, 2.5 * f), v3(0.2 * f, 0, 1.8 * f),
              30, 1, 1, 1, 30, 40);
    set_camera(s, v3(0, 6.5 * f, 7.5 * f), v3(0, 0, 0.3 * f), 50);
    free(line);
    free(seen);
    free(stack);
    free(solid);
}

/* Glossy test scene: 3 x 3 m glossy floor (roughness 0.3), glossy back and side
 * walls 2 m high (roughness 0.4, one blue), a diffuse orange box in the middle,
 * one spotlight aimed at the box from the front right. With diffuse_walls the walls
 * are Lambertian (roughness 1): the light they get from the floor's reflection of the
 * spotlight is then nothing but the floor's first glossy bounce. */
static void glossy_build(sg_scene *s, int diffuse_walls) {
    double a = s->opt.albedo, rw = diffuse_walls ? 1 : 0.4;
    int m_floor = add_material(s, "glossy_floor", 0.55, 0.55, 0.55, 0, 0.3);
    int m_wall = add_material(s, "glossy_wall", a, a, a, 0, rw);
    int m_blue = add_material(s, "glossy_blue", 0.2, 0.3, 0.7, 0, rw);
    int m_box = add_material(s, "orange", 0.8, 0.35, 0.1, 0, 1);
    add_rect(s, add_mesh(s, "floor", m_floor), 1, 0.0, -1.5, 1.5, -1.5, 1.5, +1);
    add_rect(s, add_mesh(s, "back_wall", m_wall), 2, -1.5, -1.5, 1.5, 0.0, 2.0, +1);
    add_rect(s, add_mesh(s, "left_wall", m_blue), 0, -1.5, 0.0, 2.0, -1.5, 1.5, +1);
    add_rect(s, add_mesh(s, "right_wall", m_wall), 0, 1.5, 0.0, 2.0, -1.5, 1.5, -1);
    add_block(s, add_mesh(s, "box", m_box), 0, 0, 0.6, 0.6, 0.6, 25);
    add_light(s, "spot", LIGHT_SPOT, v3(1.2, 2.2, 1.4), v3(0, 0.3, 0), 20, 1, 1, 1, 25, 35);
    set_camera(s, v3(0, 1.4, 4.2), v3(0, 0.6, 0), 45);
}
static void scene_glossy(sg_scene *s) { glossy_build(s, 0); }
static void scene_glossy_floor(sg_scene *s) { glossy_build(s, 1); }

/* Two unit squares facing each other across --dist along z, light half-way. */
static void scene_facing(sg_scene *s) {
    double a = s->opt.albedo, d = s->opt.dist;
    int m = add_material(s, "grey", a, a, a, 0, 1);
    add_rect(s, add_mesh(s, "square_a", m), 2, 0.0, -0.5, 0.5, -0.5, 0.5, +1);
    add_rect(s, add_mesh(s, "square_b", m), 2, d, -0.5, 0.5, -0.5, 0.5, -1);
    add_light(s, "light", LIGHT_POINT, v3(0, 0, d / 2), v3(0, 0, 0), 1, 1, 1, 1, 45, 60);
    set_camera(s, v3(2.5, 0.8, d / 2 + 1.0), v3(0, 0, d / 2), 45);
}

/* Two unit squares at right angles sharing the edge y = z = 0, x in [0,1]: a floor
 * (facing +y) and a wall (facing +z). */
static void scene_perpendicular(sg_scene *s) {
    double a = s->opt.albedo;
    int m = add_material(s, "grey", a, a, a, 0, 1);
    add_rect(s, add_mesh(s, "floor", m), 1, 0.0, 0, 1, 0, 1, +1);
    add_rect(s, add_mesh(s, "wall", m), 2, 0.0, 0, 1, 0, 1, +1);
    add_light(s, "light", LIGHT_POINT, v3(0.5, 0.5, 0.5), v3(0.5, 0, 0.5), 1, 1, 1, 1, 45, 60);
    set_camera(s, v3(0.5, 1.5, 2.5), v3(0.5, 0.4, 0.4), 45);
}

/* Closed unit cube centred at the origin, 6 inward faces of --albedo, light at the
 * centre: the furnace test (radiosity B = E/(1-rho) in closed form). */
static void scene_furnace(sg_scene *s) {
    double a = s->opt.albedo;
    int m = add_material(s, "grey", a, a, a, 0, 1);
    add_room(s, add_mesh(s, "cube", m), v3(-0.5, -0.5, -0.5), v3(0.5, 0.5, 0.5));
    add_light(s, "light", LIGHT_POINT, v3(0, 0, 0), v3(0, -1, 0), 1, 1, 1, 1, 45, 60);
    set_camera(s, v3(0, 0, 0.4), v3(0, 0, -0.5), 60);
}

/* Closed 1 m cube of glossy metal (base colour --albedo, metallic 1, roughness
 * --roughness) with a point light at the centre: the closed glossy box whose total
 * flux must match the path tracer's (no energy created, also near a mirror). */
static void scene_glossy_box(sg_scene *s) {
    double a = s->opt.albedo;
    int m = add_material(s, "metal", a, a, a, 1, s->opt.roughness);
    add_room(s, add_mesh(s, "cube", m), v3(-0.5, -0.5, -0.5), v3(0.5, 0.5, 0.5));
    add_light(s, "light", LIGHT_POINT, v3(0.1, 0.15, -0.05), v3(0, -1, 0), 1, 1, 1, 1, 45, 60);
    set_camera(s, v3(0, 0, 0.4), v3(0, 0, -0.5), 60);
}

/* Two closed 1 m rooms side by side along x, separated by a wall --thick thick
 * (room A's +x face and room B's -x face back to back); the light is in room A,
 * so room B must stay black (light leak test). */
static void scene_tworooms(sg_scene *s) {
    double a = s->opt.albedo, t = s->opt.thick / 2;
    int m = add_material(s, "grey", a, a, a, 0, 1);
    add_room(s, add_mesh(s, "room_a", m), v3(-1 - t, 0, -0.5), v3(-t, 1, 0.5));
    add_room(s, add_mesh(s, "room_b", m), v3(t, 0, -0.5), v3(1 + t, 1, 0.5));
    add_light(s, "light", LIGHT_POINT, v3(-0.5 - t, 0.5, 0), v3(-0.5 - t, 0, 0), 1, 1, 1, 1, 45, 60);
    set_camera(s, v3(-0.95 - t, 0.6, 0.4), v3(-t, 0.4, -0.2), 60);
}

/* Two unit squares hinged on the z axis (x = y = 0, z in [0,1]) with an opening
 * angle of --angle degrees: A lies in y = 0 along +x facing +y, B leaves the hinge
 * at that angle above A and faces into the wedge. No light unless asked for. */
static void scene_grazing(sg_scene *s) {
    double a = s->opt.albedo, ang = s->opt.angle * WRT_PI / 180.0;
    double c = cos(ang), sn = sin(ang);
    int m = add_material(s, "grey", a, a, a, 0, 1);
    add_rect(s, add_mesh(s, "square_a", m), 1, 0.0, 0, 1, 0, 1, +1);
    add_quad(s, add_mesh(s, "square_b", m), v3(0, 0, 0), v3(c, sn, 0), v3(c, sn, 1), v3(0, 0, 1),
             v3(sn, -c, 0));
    double hb = ang / 2;
    add_light(s, "light", LIGHT_POINT, v3(0.7 * cos(hb), 0.7 * sin(hb), 0.5), v3(0, 0, 0.5), 1, 1,
              1, 1, 45, 60);
    s->nlights = s->opt.light == LIGHT_DEFAULT ? 0 : s->nlights; /* default: unlit */
    set_camera(s, v3(1.2, 1.0, 2.6), v3(0.4, 0.1, 0.5), 45);
}
/* A closed room 2 x 1.5 x 2 m (x in [-1,1], y in [0,1.5], z in [-1,1]) with a window
 * 0.8 m wide and 0.6 m high in its -x wall (y in [0.7,1.3], z in [-0.4,0.4]), that wall
 * made of the four rectangles around the hole; a white box on the floor, lit only by a
 * sun of 10 lux shining in through the window and down (its light travels along
 * (1, -0.8, -0.3)), so its patch lands on the floor and the box. The camera stands
 * inside by the +z wall. */
static void scene_sun_room(sg_scene *s) {
    double a = s->opt.albedo;
    int white = add_material(s, "white", a, a, a, 0, 1);
    int floor_m = add_material(s, "floor", 0.55, 0.42, 0.3, 0, 1);
    add_rect(s, add_mesh(s, "floor", floor_m), 1, 0.0, -1, 1, -1, 1, +1);
    add_rect(s, add_mesh(s, "ceiling", white), 1, 1.5, -1, 1, -1, 1, -1);
    add_rect(s, add_mesh(s, "back_wall", white), 2, -1, -1, 1, 0, 1.5, +1);
    add_rect(s, add_mesh(s, "front_wall", white), 2, 1, -1, 1, 0, 1.5, -1);
    add_rect(s, add_mesh(s, "right_wall", white), 0, 1, 0, 1.5, -1, 1, -1);
    int win = add_mesh(s, "window_wall", white);
    add_rect(s, win, 0, -1, 0, 1.5, -1, -0.4, +1);
    add_rect(s, win, 0, -1, 0, 1.5, 0.4, 1, +1);
    add_rect(s, win, 0, -1, 0, 0.7, -0.4, 0.4, +1);
    add_rect(s, win, 0, -1, 1.3, 1.5, -0.4, 0.4, +1);
    add_block(s, add_mesh(s, "box", white), 0.35, 0.0, 0.3, 0.3, 0.4, 20);
    add_light(s, "sun", LIGHT_SUN, v3(-2, 2.6, 0.3), v3(-1, 1.8, 0), 10, 1, 0.95, 0.85, 0, 0);
    set_camera(s, v3(0.7, 1.1, 0.9), v3(-0.4, 0.45, -0.5), 75);
}

/* ------------------------------------------------- triangle meshes (issue 21) */

/* A UV sphere of radius r about c, `seg` segments around and `rings` rings, outward:
 * the bands' faces are planar trapezoids (they pair back into quads), the two caps
 * fans of triangles. Normals: the sphere's, per vertex. */
static void add_uv_sphere(sg_scene *s, int mesh, wrt_v3 c, double r, int seg, int rings) {
    sg_mesh *m = &s->meshes[mesh];
    for (int j = 0; j < rings; j++)
        for (int i = 0; i < seg; i++) {
            wrt_v3 d[4];
            int ii[4] = {i, i + 1, i + 1, i}, jj[4] = {j, j, j + 1, j + 1};
            for (int k = 0; k < 4; k++) {
                double th = WRT_PI * jj[k] / rings, ph = 2 * WRT_PI * (ii[k] % seg) / seg;
                d[k] = v3(sin(th) * cos(ph), cos(th), -sin(th) * sin(ph));
            }
            wrt_v3 p[4];
            for (int k = 0; k < 4; k++) p[k] = v3_add(c, v3_scale(d[k], r));
            /* from the top (theta 0) down; counter-clockwise seen from outside: 0 3 2 1 */
            if (j == 0) push_tri(s, m, p[0], p[3], p[2], d[0], d[3], d[2]);
            else if (j == rings - 1) push_tri(s, m, p[0], p[3], p[1], d[0], d[3], d[1]);
            else {
                push_tri(s, m, p[0], p[3], p[2], d[0], d[3], d[2]);
                push_tri(s, m, p[0], p[2], p[1], d[0], d[2], d[1]);
            }
        }
}

/* A cylinder standing on y = 0 about (cx, cz), radius r, height h, `seg` sides and a
 * top cap (a fan), outward; no bottom (it stands on the floor). Side normals are the
 * cylinder's, per vertex; the cap's is +y. */
static void add_cylinder(sg_scene *s, int mesh, double cx, double cz, double r, double h, int seg) {
    sg_mesh *m = &s->meshes[mesh];
    wrt_v3 top = v3(cx, h, cz), up = v3(0, 1, 0);
    for (int i = 0; i < seg; i++) {
        double a0 = 2 * WRT_PI * i / seg, a1 = 2 * WRT_PI * ((i + 1) % seg) / seg;
        wrt_v3 n0 = v3(cos(a0), 0, -sin(a0)), n1 = v3(cos(a1), 0, -sin(a1));
        wrt_v3 b0 = v3(cx + r * n0.x, 0, cz + r * n0.z), b1 = v3(cx + r * n1.x, 0, cz + r * n1.z);
        wrt_v3 t0 = v3(b0.x, h, b0.z), t1 = v3(b1.x, h, b1.z);
        push_tri(s, m, b0, b1, t1, n0, n1, n1);
        push_tri(s, m, b0, t1, t0, n0, n1, n0);
        push_tri(s, m, top, t0, t1, up, up, up);
    }
}

/* A box w x h x d standing on y = 0 about (cx, cz), turned by `deg` about +Y, its edges
 * chamfered by `bev` (one bevel segment): 5 shrunk faces, 8 edge strips and 4 corner
 * triangles at the top, the vertical edges' strips down to the floor; no bottom. All
 * faces flat, written as triangles. */
static void add_bevel_box(sg_scene *s, int mesh, double cx, double cz, double w, double h, double d, double bev,
                          double deg) {
    sg_mesh *m = &s->meshes[mesh];
    double a = deg * WRT_PI / 180.0, ca = cos(a), sa = sin(a);
    double hx = w / 2, hz = d / 2;
#define BB(x, y, z) v3(cx + ca * (x) + sa * (z), (y), cz - sa * (x) + ca * (z))
    /* the top face */
    push_tri_quad(s, m, BB(-hx + bev, h, hz - bev), BB(hx - bev, h, hz - bev), BB(hx - bev, h, -hz + bev),
                  BB(-hx + bev, h, -hz + bev));
    /* around: for each side k (outward normal along x or z), its face, its top strip,
     * the vertical strip after it and the top corner triangle after it */
    double sx[4] = {0, 1, 0, -1}, sz[4] = {1, 0, -1, 0};
    for (int k = 0; k < 4; k++) {
        int k1 = (k + 1) % 4;
        /* side k spans from corner (k) to corner (k+1) going counter-clockwise seen from +y */
        double nx = sx[k], nz = sz[k], tx = -nz, tz = nx; /* tangent: along the side, ccw from above is -t */
        double ext = (nx != 0) ? hx : hz, half = (nx != 0) ? hz : hx;
        /* face corners: the face lies at distance ext, spans +-(half - bev) along t, y from 0 to h - bev */
        wrt_v3 f0 = BB(nx * ext + tx * (half - bev), 0, nz * ext + tz * (half - bev));
        wrt_v3 f1 = BB(nx * ext - tx * (half - bev), 0, nz * ext - tz * (half - bev));
        wrt_v3 f2 = BB(nx * ext - tx * (half - bev), h - bev, nz * ext - tz * (half - bev));
        wrt_v3 f3 = BB(nx * ext + tx * (half - bev), h - bev, nz * ext + tz * (half - bev));
        wrt_v3 n = v3_cross(v3_sub(f1, f0), v3_sub(f3, f0));
        if (v3_dot(n, v3_sub(f0, v3(cx, f0.y, cz))) < 0) { wrt_v3 t = f1; f1 = f0; f0 = t; t = f2; f2 = f3; f3 = t; }
        push_tri_quad(s, m, f0, f1, f2, f3);
        /* top strip: from the face's top edge to the top face's edge */
        wrt_v3 g0 = BB(nx * (ext - bev) + tx * (half - bev), h, nz * (ext - bev) + tz * (half - bev));
        wrt_v3 g1 = BB(nx * (ext - bev) - tx * (half - bev), h, nz * (ext - bev) - tz * (half - bev));
        /* f3 and f2 sit under g0 and g1 in the same order as f0, f1 (after a possible swap) */
        wrt_v3 top0 = v3_len(v3_sub(g0, f3)) < v3_len(v3_sub(g1, f3)) ? g0 : g1;
        wrt_v3 top1 = top0.x == g0.x && top0.z == g0.z ? g1 : g0;
        push_tri_quad(s, m, f3, f2, top1, top0);
        (void)k1;
    }
    /* the four vertical corner strips and the top corner triangles */
    double cxs[4] = {1, 1, -1, -1}, czs[4] = {1, -1, -1, 1};
    for (int k = 0; k < 4; k++) {
        double X = cxs[k] * hx, Z = czs[k] * hz;
        wrt_v3 p0 = BB(X, 0, Z - czs[k] * bev), p1 = BB(X - cxs[k] * bev, 0, Z);
        wrt_v3 q0 = BB(X, h - bev, Z - czs[k] * bev), q1 = BB(X - cxs[k] * bev, h - bev, Z);
        wrt_v3 tp = BB(X - cxs[k] * bev, h, Z - czs[k] * bev);
        wrt_v3 out = v3_sub(BB(X, 0, Z), v3(cx, 0, cz));
        wrt_v3 n = v3_cross(v3_sub(p1, p0), v3_sub(q0, p0));
        if (v3_dot(n, out) < 0) { wrt_v3 t = p0; p0 = p1; p1 = t; t = q0; q0 = q1; q1 = t; }
        push_tri_quad(s, m, p0, p1, q1, q0);
        wrt_v3 tn = v3_cross(v3_sub(q1, q0), v3_sub(tp, q0));
        if (tn.y > 0) push_tri(s, m, q0, q1, tp, tn, tn, tn);
        else push_tri(s, m, q1, q0, tp, v3_scale(tn, -1), v3_scale(tn, -1), v3_scale(tn, -1));
    }
#undef BB
}

/* The Cornell box's room (no boxes) holding a UV sphere (16 x 8), a cylinder (12 sides)
 * and a bevelled box, all made of triangles, under the same point light. --detail D
 * multiplies the sphere's segments and rings and the cylinder's sides by D (rounded;
 * at least 3 x 2 and 3), so the triangle count grows as about 256 D^2 (the cost against
 * triangle count, docs/triangles.md); D = 1 is the scene as it always was. */
static void scene_cornell_shapes(sg_scene *s) {
    double a = s->opt.albedo;
    int white = add_material(s, "white", a, a, a, 0, 1);
    int red = add_material(s, "red", 0.63, 0.065, 0.05, 0, 1);
    int green = add_material(s, "green", 0.14, 0.45, 0.09, 0, 1);
    int blue = add_material(s, "blue", 0.2, 0.3, 0.7, 0, 1);
    add_rect(s, add_mesh(s, "floor", white), 1, 0.0, -0.5, 0.5, -0.5, 0.5, +1);
    add_rect(s, add_mesh(s, "ceiling", white), 1, 1.0, -0.5, 0.5, -0.5, 0.5, -1);
    add_rect(s, add_mesh(s, "back_wall", white), 2, -0.5, -0.5, 0.5, 0.0, 1.0, +1);
    add_rect(s, add_mesh(s, "left_wall", red), 0, -0.5, 0.0, 1.0, -0.5, 0.5, +1);
    add_rect(s, add_mesh(s, "right_wall", green), 0, 0.5, 0.0, 1.0, -0.5, 0.5, -1);
    double d = s->opt.detail;
    int seg = (int)lround(16 * d), rings = (int)lround(8 * d), sides = (int)lround(12 * d);
    add_uv_sphere(s, add_mesh(s, "sphere", white), v3(-0.2, 0.18, 0.1), 0.18, seg < 3 ? 3 : seg,
                  rings < 2 ? 2 : rings);
    add_cylinder(s, add_mesh(s, "cylinder", blue), 0.22, -0.2, 0.12, 0.45, sides < 3 ? 3 : sides);
    add_bevel_box(s, add_mesh(s, "bevel_box", white), 0.2, 0.22, 0.22, 0.22, 0.22, 0.03, -20);
    add_light(s, "ceiling_light", LIGHT_POINT, v3(0, 0.85, 0), v3(0, 0, 0), 2.5, 1, 1, 1, 60, 80);
    set_camera(s, v3(0, 0.5, 1.9), v3(0, 0.5, 0), 39.3);
}

/* A closed icosphere of radius 1 about the origin, 20 x 4^--res triangles facing
 * inwards, --albedo, a point light at the centre: the furnace of triangles (indirect
 * flux 4 pi I rho / (1 - rho)). */
static void scene_icosphere(sg_scene *s) {
    double a = s->opt.albedo;
    int m = add_material(s, "grey", a, a, a, 0, 1);
    int mesh = add_mesh(s, "icosphere", m);
    const double t = (1 + sqrt(5.0)) / 2;
    static const int ff[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                  {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                                  {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    const double vv[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                              {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    int sub = s->opt.res > 6 ? 6 : s->opt.res, ntri = 20;
    wrt_v3 *tri = wrt_xmalloc((size_t)ntri * 3 * sizeof *tri);
    for (int f = 0; f < 20; f++)
        for (int k = 0; k < 3; k++) tri[3 * f + k] = v3_norm(v3(vv[ff[f][k]][0], vv[ff[f][k]][1], vv[ff[f][k]][2]));
    for (int l = 0; l < sub; l++) {
        wrt_v3 *nt = wrt_xmalloc((size_t)ntri * 12 * sizeof *nt);
        for (int f = 0; f < ntri; f++) {
            wrt_v3 p = tri[3 * f], q = tri[3 * f + 1], r = tri[3 * f + 2];
            wrt_v3 pq = v3_norm(v3_add(p, q)), qr = v3_norm(v3_add(q, r)), rp = v3_norm(v3_add(r, p));
            wrt_v3 o[12] = {p, pq, rp, pq, q, qr, rp, qr, r, pq, qr, rp};
            memcpy(&nt[12 * f], o, sizeof o);
        }
        free(tri);
        tri = nt;
        ntri *= 4;
    }
    for (int f = 0; f < ntri; f++) {
        wrt_v3 p = tri[3 * f], q = tri[3 * f + 1], r = tri[3 * f + 2];
        wrt_v3 in0 = v3_scale(p, -1), in1 = v3_scale(q, -1), in2 = v3_scale(r, -1);
        if (v3_dot(v3_cross(v3_sub(q, p), v3_sub(r, p)), p) > 0) push_tri(s, &s->meshes[mesh], p, r, q, in0, in2, in1);
        else push_tri(s, &s->meshes[mesh], p, q, r, in0, in1, in2);
    }
    free(tri);
    add_light(s, "light", LIGHT_POINT, v3(0, 0, 0), v3(0, -1, 0), 1, 1, 1, 1, 45, 60);
    set_camera(s, v3(0, 0, 0.6), v3(0, 0, -1), 70);
}

/* The builders tools/scenegen_atrium.c uses (tools/scenegen.h): thin names for the
 * static helpers above, so the larger scenes can live in files of their own. */
int sg_add_material(sg_scene *s, const char *name, double r, double g, double b, double metallic, double roughness) {
    return add_material(s, name, r, g, b, metallic, roughness);
}
int sg_add_mesh(sg_scene *s, const char *name, int material) { return add_mesh(s, name, material); }
void sg_add_point_light(sg_scene *s, const char *name, wrt_v3 pos, double intensity) {
    add_light(s, name, LIGHT_POINT, pos, v3_sub(pos, v3(0, 1, 0)), intensity, 1, 1, 1, 45, 60);
}
void sg_set_camera(sg_scene *s, wrt_v3 eye, wrt_v3 target, double yfov_deg) { set_camera(s, eye, target, yfov_deg); }
void sg_push_tri(sg_scene *s, int mesh, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 na, wrt_v3 nb, wrt_v3 nc) {
    push_tri(s, &s->meshes[mesh], a, b, c, na, nb, nc);
}
void sg_push_quad(sg_scene *s, int mesh, wrt_v3 a, wrt_v3 b, wrt_v3 c, wrt_v3 d) {
    push_quad(s, &s->meshes[mesh], a, b, c, d, v3_norm(v3_cross(v3_sub(b, a), v3_sub(d, a))));
}

typedef struct sg_entry {
    const char *name;
    void (*build)(sg_scene *);
    const char *file; /* path under --all DIR; NULL: not written by --all */
    const char *what;
} sg_entry;

static const sg_entry scenes[] = {
    {"cornell", scene_cornell, "cornell.gltf", "1 m Cornell box, point light under the ceiling"},
    {"maze", scene_maze, "maze.gltf", "maze of --cells^2 corridors, 3 spotlights"},
    {"glossy", scene_glossy, "glossy.gltf", "glossy floor and walls, diffuse box, spotlight"},
    {"facing", scene_facing, "test/facing.gltf", "two unit squares facing at --dist"},
    {"perpendicular", scene_perpendicular, "test/perpendicular.gltf",
     "two unit squares at right angles sharing an edge"},
    {"furnace", scene_furnace, "test/furnace.gltf", "closed cube, light at the centre"},
    {"tworooms", scene_tworooms, "test/tworooms.gltf", "two closed rooms, light in one"},
    {"grazing", scene_grazing, "test/grazing.gltf", "two squares at an --angle degree edge"},
    {"cornell-glossy", scene_cornell_glossy, "test/cornell_glossy.gltf",
     "Cornell box, back wall glossy metal of --roughness"},
    {"glossy-box", scene_glossy_box, "test/glossy_box.gltf", "closed metal cube of --roughness, point light"},
    {"glossy-floor", scene_glossy_floor, "test/glossy_floor.gltf", "the glossy scene with diffuse walls"},
    {"cornell-shapes", scene_cornell_shapes, "test/cornell_shapes.gltf",
     "Cornell room with a UV sphere, a cylinder and a bevelled box made of triangles"},
    {"icosphere", scene_icosphere, "test/icosphere.gltf",
     "closed icosphere of 20 x 4^--res inward triangles (--res <= 6), light at the centre"},
    {"sun-room", scene_sun_room, "sun_room.gltf", "closed room lit by a sun through a window"},
    {"cornell-emit", scene_cornell_emit, "test/cornell_emit.gltf", "Cornell box lit only by an emissive ceiling panel"},
    {"atrium", scene_atrium, NULL, /* large: not in --all; the scale benchmark makes it */
     "closed Sponza-like atrium: two storeys of arcades, columns, arches, banners (--detail)"},
};
#define NSCENES ((int)(sizeof scenes / sizeof scenes[0]))

static wrt_status write_file(const char *path, const char *text, size_t n) {
    wrt_output o; /* a regular file only, through a temporary (common/outfile.h) */
    wrt_status st = wrt_output_begin(path, "wb", &o);
    if (st != WRT_OK) return st;
    fwrite(text, 1, n, o.f);
    return wrt_output_commit(&o);
}

static void free_scene(sg_scene *s) {
    for (int i = 0; i < s->nmeshes; i++) {
        free(s->meshes[i].pos);
        free(s->meshes[i].nrm);
        free(s->meshes[i].tpos);
        free(s->meshes[i].tnrm);
    }
}

static wrt_status generate(const sg_entry *e, const sg_options *opt, const char *path) {
    sg_scene s;
    memset(&s, 0, sizeof s);
    snprintf(s.name, sizeof s.name, "%s", e->name);
    s.opt = *opt;
    e->build(&s);
    if (opt->light == LIGHT_NONE) s.nlights = 0;
    for (int i = 0; i < s.nlights && opt->light > 0; i++)
        s.lights[i].type = opt->light == LIGHT_SPOT ? LIGHT_SPOT : LIGHT_POINT;
    sbuf text = {0};
    write_gltf(&s, &text);
    int nq = 0, nt = 0;
    for (int i = 0; i < s.nmeshes; i++) nq += s.meshes[i].nquads, nt += s.meshes[i].ntris;
    wrt_status st = write_file(path, text.p, text.n);
    if (st == WRT_OK)
        printf("%s: %s, %d quads, %d triangles, %d lights, %zu bytes\n", path, e->name, nq,
               2 * nq + nt, s.nlights, text.n);
    free(text.p);
    free_scene(&s);
    return st;
}

/* -------------------------------------------------------------- front end */

static void usage(FILE *f) {
    fprintf(f,
            "usage: wrt-scenegen SCENE [options] -o FILE     (-o and --out are the same)\n"
            "       wrt-scenegen --all DIR [options]   (test scenes go to DIR/test/)\n"
            "options:\n"
            "  --res N          subdivide every quad into N x N, 1..128 (default 1)\n"
            "  --albedo R       albedo of the white/grey surfaces (default 0.75)\n"
            "  --scale S        scale the scene; light intensities scale by S^2 (default 1)\n"
            "  --offset X,Y,Z   translate everything, lights and camera included\n"
            "  --dist D         facing: distance between the squares (default 1)\n"
            "  --angle A        grazing: opening angle in degrees (default 1)\n"
            "  --thick T        tworooms: thickness of the shared wall (default 0.02)\n"
            "  --light none|point|spot  change the lights' type or remove them\n"
            "  --intensity I    every light's intensity in candela, lux for a sun (after scaling)\n"
            "  --cells N        maze: corridors per side (default 6)\n"
            "  --seed N         maze: layout seed (default 1)\n"
            "  --roughness R    cornell-glossy, glossy-box: the metal's roughness (default 0.3)\n"
            "  --detail D       atrium: tessellation, 0.25..16; elements grow as about D^1.75:\n"
            "                   1,060 at 0.5, 2,700 at 1 (default), 8,200 at 2, 28,500 at 4,\n"
            "                   108,000 at 8 (wrt-bake --scan counts them); cornell-shapes:\n"
            "                   the sphere's and cylinder's segments x D, triangles about\n"
            "                   256 D^2: 1,072 at 2, 3,190 at 3.5, 10,065 at 6.25\n"
            "scenes:\n");
    for (int i = 0; i < NSCENES; i++) fprintf(f, "  %-14s %s\n", scenes[i].name, scenes[i].what);
    fprintf(f, "\n");
    wrt_cli_exit_table(f);
}

static int parse_num(const char *s, double lo, double hi, double *out) {
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v) || v < lo || v > hi) return 0;
    *out = v;
    return 1;
}

static int mkdir_p(const char *dir) {
    char buf[4096];
    size_t n = strlen(dir);
    if (n == 0 || n >= sizeof buf) return 0;
    memcpy(buf, dir, n + 1);
    for (size_t i = 1; i <= n; i++)
        if (buf[i] == '/' || buf[i] == 0) {
            char c = buf[i];
            buf[i] = 0;
            if (mkdir(buf, 0777) != 0 && errno != EEXIST) return 0;
            buf[i] = c;
        }
    return 1;
}

int main(int argc, char **argv) {
    wrt_cli_init("wrt-scenegen"); /* stdout checked at exit (3), out of memory: exit 7 */
    sg_options opt = sg_defaults();
    const char *scene = NULL, *out = NULL, *all = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double x;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { usage(stdout); return 0; }
        if (!strcmp(a, "--version")) { printf("wrt-scenegen %s (writes glTF 2.0)\n", WRT_VERSION_STRING); return 0; } /* no .gto */
        if (a[0] != '-') {
            if (scene) { fprintf(stderr, "wrt-scenegen: error: two scene names: %s, %s\n", scene, a); return WRT_EXIT_USAGE; }
            scene = a;
            continue;
        }
        static const char *const known[] = {"--out", "-o", "--all", "--res", "--albedo", "--scale", "--dist", "--angle",
                                            "--thick", "--intensity", "--cells", "--seed", "--light", "--offset",
                                            "--roughness", "--detail"};
        int is_known = 0;
        for (size_t k = 0; k < sizeof known / sizeof *known; k++) is_known |= !strcmp(a, known[k]);
        if (!is_known) { fprintf(stderr, "wrt-scenegen: error: unknown option %s (see --help)\n", a); return WRT_EXIT_USAGE; }
        if (!v) { fprintf(stderr, "wrt-scenegen: error: %s needs a value\n", a); return WRT_EXIT_USAGE; }
        i++;
        int ok = 1;
        if (!strcmp(a, "--out") || !strcmp(a, "-o")) out = v;
        else if (!strcmp(a, "--all")) all = v;
        else if (!strcmp(a, "--res")) { ok = parse_num(v, 1, 128, &x) && x == floor(x); opt.res = (int)x; }
        else if (!strcmp(a, "--albedo")) ok = parse_num(v, 0, 1, &opt.albedo);
        else if (!strcmp(a, "--scale")) ok = parse_num(v, 1e-6, 1e6, &opt.scale);
        else if (!strcmp(a, "--dist")) ok = parse_num(v, 1e-6, 1e6, &opt.dist);
        else if (!strcmp(a, "--angle")) ok = parse_num(v, 1e-3, 180, &opt.angle);
        else if (!strcmp(a, "--thick")) ok = parse_num(v, 1e-6, 1, &opt.thick);
        else if (!strcmp(a, "--intensity")) ok = parse_num(v, 1e-9, 1e12, &opt.intensity);
        else if (!strcmp(a, "--cells")) { ok = parse_num(v, 2, 64, &x) && x == floor(x); opt.cells = (int)x; }
        else if (!strcmp(a, "--seed")) { ok = parse_num(v, 0, 4e15, &x) && x == floor(x); opt.seed = (uint64_t)x; }
        else if (!strcmp(a, "--roughness")) ok = parse_num(v, 0, 1, &opt.roughness);
        else if (!strcmp(a, "--detail")) ok = parse_num(v, 0.25, 16, &opt.detail);
        else if (!strcmp(a, "--light")) {
            opt.light = !strcmp(v, "none") ? LIGHT_NONE : !strcmp(v, "point") ? LIGHT_POINT
                      : !strcmp(v, "spot") ? LIGHT_SPOT : -2;
            ok = opt.light != -2;
        } else if (!strcmp(a, "--offset")) {
            char *e1, *e2, *e3;
            opt.offset.x = strtod(v, &e1);
            ok = *e1 == ',';
            if (ok) { opt.offset.y = strtod(e1 + 1, &e2); ok = *e2 == ','; }
            if (ok) { opt.offset.z = strtod(e2 + 1, &e3); ok = *e3 == 0 && v3_finite(opt.offset); }
            ok = ok && fabs(opt.offset.x) < 1e9 && fabs(opt.offset.y) < 1e9 && fabs(opt.offset.z) < 1e9;
        } else {
            fprintf(stderr, "wrt-scenegen: error: unknown option %s (see --help)\n", a);
            return WRT_EXIT_USAGE;
        }
        if (!ok) { fprintf(stderr, "wrt-scenegen: error: bad value for %s: %s\n", a, v); return WRT_EXIT_USAGE; }
    }
    /* The icosphere subdivides --res times (20 x 4^res triangles); it stops at 6 (81,920),
     * and --res 20 gave 81,920 triangles without a word. */
    if (opt.res > 6 && (all || (scene && !strcmp(scene, "icosphere")))) {
        fprintf(stderr, "wrt-scenegen: error: --res %d: the icosphere%s takes --res 1..6 (20 x 4^6 = 81,920 "
                "triangles at most)\n", opt.res, all ? " (one of --all's scenes)" : "");
        return WRT_EXIT_USAGE;
    }
    if (all) {
        if (scene || out) { fprintf(stderr, "wrt-scenegen: error: --all takes no scene or --out\n"); return WRT_EXIT_USAGE; }
        char path[4096];
        snprintf(path, sizeof path, "%s/test", all);
        if (!mkdir_p(path)) { fprintf(stderr, "wrt-scenegen: error: cannot create %s: %s\n", path, strerror(errno)); return WRT_EXIT_OUTPUT; }
        for (int i = 0; i < NSCENES; i++) {
            if (!scenes[i].file) continue;
            snprintf(path, sizeof path, "%s/%s", all, scenes[i].file);
            if (generate(&scenes[i], &opt, path) != WRT_OK) {
                fprintf(stderr, "wrt-scenegen: error: %s\n", wrt_last_error());
                return WRT_EXIT_OUTPUT;
            }
        }
        return 0;
    }
    if (!scene && !out) { usage(stderr); return WRT_EXIT_USAGE; }
    if (!scene) { fprintf(stderr, "wrt-scenegen: error: no scene name before -o %s (see --help for the list)\n", out); return WRT_EXIT_USAGE; }
    if (!out) { fprintf(stderr, "wrt-scenegen: error: no output file: wrt-scenegen %s -o FILE.gltf\n", scene); return WRT_EXIT_USAGE; }
    /* It writes glTF's JSON form: -o x.glb wrote JSON under the binary form's name, which
     * other glTF readers refuse (wrt-bake reads either by their first bytes). */
    size_t outlen = strlen(out);
    if (outlen >= 4 && !strcasecmp(out + outlen - 4, ".glb")) {
        fprintf(stderr, "wrt-scenegen: error: %s: wrt-scenegen writes glTF JSON (.gltf), not binary glTF (.glb)\n", out);
        return WRT_EXIT_USAGE;
    }
    for (int i = 0; i < NSCENES; i++)
        if (!strcmp(scenes[i].name, scene)) {
            if (generate(&scenes[i], &opt, out) != WRT_OK) {
                fprintf(stderr, "wrt-scenegen: error: %s\n", wrt_last_error());
                return WRT_EXIT_OUTPUT;
            }
            return 0;
        }
    fprintf(stderr, "wrt-scenegen: error: unknown scene %s (see --help)\n", scene);
    return WRT_EXIT_USAGE;
}
