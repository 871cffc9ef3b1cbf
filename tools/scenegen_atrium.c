/* scenegen_atrium.c: wrt-scenegen's `atrium`, a proxy of the Sponza atrium for the
 * scale benchmark (issue 22): a closed rectangular courtyard, 16 x 8 m and 8 m high,
 * its two long sides lined by two storeys of arcades (round columns, semicircular
 * arches on rectangular piers at the ends) with a 2 m deep gallery behind each, hanging
 * banners in front of the upper arcade, a floor and a flat roof over everything. The
 * building is closed (a roof, not the sky): a point light in the courtyard then lights
 * the galleries only through the arches, by bounces, and no energy leaves the scene,
 * so furnace-like checks hold. Geometry is written as a modelling tool exports it:
 * flat faces as quads (two indexed triangles each, gridded at about 1/--detail m), the upper arcade's
 * spandrels as fans of triangles, the lower one's as strips of quads, the columns as
 * cylinders of quads with smooth per-vertex normals. Elements grow as about detail^1.75
 * (1,060 at 0.5, 2,700 at 1, 28,500 at 4, 108,000 at 8). Only solid-to-air boundaries are emitted (the slab between the
 * storeys and the arcade walls are closed solids, the end walls are cut around them).
 * Output depends only on the options. Depends on tools/scenegen.h (scenegen.c). */
#include "tools/scenegen.h"

#include <math.h>

/* The meshes: quads in some, loose triangles (_FANS, _COLUMNS, _TIP_*) in others. */
enum { A_FLOOR, A_ROOF, A_WALLS, A_STONE, A_FANS, A_COLUMNS, A_BANNER_RED, A_BANNER_BLUE, A_TIP_RED, A_TIP_BLUE, A_NMESH };

typedef struct atrium {
    sg_scene *s;
    int mesh[A_NMESH];
    double d; /* --detail: cells per metre on flat faces */
} atrium;

/* Courtyard half-length and half-width, arcade wall thickness, gallery depth, storey
 * height, slab thickness, column radius, springing height above a storey's floor,
 * bays per arcade (metres). */
static const double HX = 8.0, HZ = 4.0, WALL = 0.4, GAL = 2.0, STOREY = 4.0, SLAB = 0.2, RC = 0.2,
                    SPRING = 2.5;
static const int BAYS = 6;

static int cells(const atrium *a, double len) {
    int n = (int)lround(fabs(len) * a->d);
    return n < 1 ? 1 : n;
}

static wrt_v3 lerp3(wrt_v3 p, wrt_v3 q, double t) { return v3_add(p, v3_scale(v3_sub(q, p), t)); }

/* Triangle a b c whose front faces `facing` (flat normal). */
static void tri_f(atrium *a, int mesh, wrt_v3 p, wrt_v3 q, wrt_v3 r, wrt_v3 facing) {
    wrt_v3 n = v3_cross(v3_sub(q, p), v3_sub(r, p));
    if (v3_dot(n, facing) < 0) {
        wrt_v3 t = q; q = r; r = t;
        n = v3_scale(n, -1);
    }
    sg_push_tri(a->s, a->mesh[mesh], p, q, r, n, n, n);
}

/* Planar convex quad p q r t (in order around it) whose front faces `facing`. */
static void quad_f(atrium *a, int mesh, wrt_v3 p, wrt_v3 q, wrt_v3 r, wrt_v3 t, wrt_v3 facing) {
    wrt_v3 n = v3_cross(v3_sub(q, p), v3_sub(t, p));
    if (v3_dot(n, facing) < 0) sg_push_quad(a->s, a->mesh[mesh], p, t, r, q);
    else sg_push_quad(a->s, a->mesh[mesh], p, q, r, t);
}

/* Parallelogram o, o+u, o+u+v, o+v cut into cells of about 1/detail m. */
static void grid_f(atrium *a, int mesh, wrt_v3 o, wrt_v3 u, wrt_v3 v, wrt_v3 facing) {
    int nu = cells(a, sqrt(v3_dot(u, u))), nv = cells(a, sqrt(v3_dot(v, v)));
    for (int j = 0; j < nv; j++)
        for (int i = 0; i < nu; i++) {
            wrt_v3 c[4];
            int ii[4] = {i, i + 1, i + 1, i}, jj[4] = {j, j, j + 1, j + 1};
            for (int k = 0; k < 4; k++)
                c[k] = v3_add(o, v3_add(v3_scale(u, (double)ii[k] / nu), v3_scale(v, (double)jj[k] / nv)));
            quad_f(a, mesh, c[0], c[1], c[2], c[3], facing);
        }
}

/* Axis-aligned rectangle at y = c (x0..x1 by z0..z1) or at z = c (x0..x1 by y0..y1) or
 * at x = c (z0..z1 by y0..y1), gridded, front along +/- its axis (sign). */
static void rect_y(atrium *a, int mesh, double y, double x0, double x1, double z0, double z1, int sign) {
    grid_f(a, mesh, v3(x0, y, z0), v3(x1 - x0, 0, 0), v3(0, 0, z1 - z0), v3(0, sign, 0));
}
static void rect_z(atrium *a, int mesh, double z, double x0, double x1, double y0, double y1, int sign) {
    grid_f(a, mesh, v3(x0, y0, z), v3(x1 - x0, 0, 0), v3(0, y1 - y0, 0), v3(0, 0, sign));
}
static void rect_x(atrium *a, int mesh, double x, double z0, double z1, double y0, double y1, int sign) {
    grid_f(a, mesh, v3(x, y0, z0), v3(0, 0, z1 - z0), v3(0, y1 - y0, 0), v3(sign, 0, 0));
}

/* Points of the arch over the bay between the piers at xa and xb (springing at ys):
 * n + 1 points on the semicircle of radius (xb - xa)/2 - RC from left to right. */
static wrt_v3 arch_point(double xa, double xb, double ys, double z, int k, int n) {
    double xm = 0.5 * (xa + xb), r = 0.5 * (xb - xa) - RC, t = WRT_PI * (double)k / n;
    if (k == n) t = WRT_PI; /* exact ends */
    return v3(k == 0 ? xa + RC : k == n ? xb - RC : xm - r * cos(t), k == 0 || k == n ? ys : ys + r * sin(t), z);
}

/* One face (plane z, front along fz) of one bay of an arcade wall: the pier strips
 * beside the arch (down to ylo_l / ylo_r: the springing at a column, the storey's floor
 * at an end pier) and the spandrel above the arch, up to ytop; as a fan of triangles
 * (fan) or as vertical strips of quads gridded upwards. */
static void bay_face(atrium *a, double xa, double xb, double ys, double ytop, double ylo_l, double ylo_r,
                     double z, int fz, int fan, int n) {
    wrt_v3 f = v3(0, 0, fz);
    rect_z(a, A_STONE, z, xa, xa + RC, ylo_l, ytop, fz);
    rect_z(a, A_STONE, z, xb - RC, xb, ylo_r, ytop, fz);
    wrt_v3 tl = v3(xa + RC, ytop, z), tr = v3(xb - RC, ytop, z);
    for (int k = 0; k < n; k++) {
        wrt_v3 p = arch_point(xa, xb, ys, z, k, n), q = arch_point(xa, xb, ys, z, k + 1, n);
        if (fan) {
            tri_f(a, A_FANS, p, q, 2 * k < n ? tl : tr, f);
            continue;
        }
        double ymax = fmax(p.y, q.y);
        int nv = cells(a, ytop - ymax);
        double y1 = ymax + (ytop - ymax) / nv;
        quad_f(a, A_STONE, p, q, v3(q.x, y1, z), v3(p.x, y1, z), f);
        for (int j = 1; j < nv; j++) { /* the rest of the strip, up to ytop */
            double ya = y1 + (ytop - y1) * (j - 1) / (nv - 1), yb = j + 1 == nv ? ytop : y1 + (ytop - y1) * j / (nv - 1);
            quad_f(a, A_STONE, v3(p.x, ya, z), v3(q.x, ya, z), v3(q.x, yb, z), v3(p.x, yb, z), f);
        }
    }
    if (fan) tri_f(a, A_FANS, tl, arch_point(xa, xb, ys, z, n / 2, n), tr, f);
}

/* The underside of the arch between the faces at z0 and z1: a strip of n quads facing
 * the arch's axis. */
static void intrados(atrium *a, double xa, double xb, double ys, double z0, double z1, int n) {
    wrt_v3 axis = v3(0.5 * (xa + xb), ys, 0.5 * (z0 + z1));
    for (int k = 0; k < n; k++) {
        wrt_v3 p0 = arch_point(xa, xb, ys, z0, k, n), q0 = arch_point(xa, xb, ys, z0, k + 1, n);
        wrt_v3 p1 = arch_point(xa, xb, ys, z1, k, n), q1 = arch_point(xa, xb, ys, z1, k + 1, n);
        wrt_v3 mid = lerp3(p0, q1, 0.5);
        quad_f(a, A_STONE, p0, q0, q1, p1, v3_sub(axis, mid));
    }
}

/* A column of radius RC about (x, zc) from y0 to y1: `seg` sides, cells along the
 * height, smooth normals; no caps (it stands on a floor and carries a pier). */
static void column(atrium *a, double x, double zc, double y0, double y1, int seg) {
    int nh = cells(a, y1 - y0);
    for (int i = 0; i < seg; i++) {
        double t0 = 2 * WRT_PI * i / seg, t1 = 2 * WRT_PI * ((i + 1) % seg) / seg;
        wrt_v3 n0 = v3(cos(t0), 0, -sin(t0)), n1 = v3(cos(t1), 0, -sin(t1));
        for (int j = 0; j < nh; j++) {
            double ya = y0 + (y1 - y0) * j / nh, yb = j + 1 == nh ? y1 : y0 + (y1 - y0) * (j + 1) / nh;
            wrt_v3 b0 = v3(x + RC * n0.x, ya, zc + RC * n0.z), b1 = v3(x + RC * n1.x, ya, zc + RC * n1.z);
            wrt_v3 t0p = v3(b0.x, yb, b0.z), t1p = v3(b1.x, yb, b1.z);
            sg_push_tri(a->s, a->mesh[A_COLUMNS], b0, b1, t1p, n0, n1, n1);
            sg_push_tri(a->s, a->mesh[A_COLUMNS], b0, t1p, t0p, n0, n1, n0);
        }
    }
}

/* One storey (0 or 1) of the arcade on side sz (+1: z > 0): both faces of each bay,
 * the arches' undersides, the columns with the piers' undersides above them, and the
 * end piers' inner sides. */
static void arcade(atrium *a, int storey, int sz) {
    double y0 = storey * STOREY, ys = y0 + SPRING, ytop = y0 + STOREY;
    double ytop_back = storey == 0 ? STOREY - SLAB : 2 * STOREY; /* the slab under the upper gallery */
    double zf = sz * HZ, zb = sz * (HZ + WALL), bay = 2 * HX / BAYS;
    int n = 2 * cells(a, 4.0); /* arch segments, even */
    int seg = 2 * cells(a, 4.0); /* column sides */
    for (int i = 0; i < BAYS; i++) {
        double xa = -HX + i * bay, xb = xa + bay;
        double ylo_l = i == 0 ? y0 : ys, ylo_r = i == BAYS - 1 ? y0 : ys;
        bay_face(a, xa, xb, ys, ytop, ylo_l, ylo_r, zf, -sz, storey == 1, n);
        bay_face(a, xa, xb, ys, ytop_back, ylo_l, ylo_r, zb, sz, storey == 1, n);
        intrados(a, xa, xb, ys, zf, zb, n);
    }
    for (int i = 1; i < BAYS; i++) {
        double x = -HX + i * bay;
        column(a, x, sz * (HZ + 0.5 * WALL), y0, ys, seg);
        rect_y(a, A_STONE, ys, x - RC, x + RC, fmin(zf, zb), fmax(zf, zb), -1);
    }
    rect_x(a, A_STONE, -HX + RC, fmin(zf, zb), fmax(zf, zb), y0, ys, +1);
    rect_x(a, A_STONE, HX - RC, fmin(zf, zb), fmax(zf, zb), y0, ys, -1);
}

/* A banner hanging in front of the upper arcade at x on side sz: a pennant (a
 * rectangle and a triangular tip) as two thin sheets 1 cm apart, one facing the
 * courtyard and one the wall. */
static void banner(atrium *a, int red, double x, int sz) {
    int mesh = red ? A_BANNER_RED : A_BANNER_BLUE, tipmesh = red ? A_TIP_RED : A_TIP_BLUE;
    const double w = 0.3, top = 2 * STOREY - 0.1, bottom = STOREY + 1.3, tip = STOREY + 0.9;
    for (int side = 0; side < 2; side++) {
        double z = sz * (HZ - 0.31 + 0.01 * side); /* the courtyard's sheet nearer the courtyard */
        int fz = side == 0 ? -sz : sz;
        rect_z(a, mesh, z, x - w, x + w, bottom, top, fz);
        tri_f(a, tipmesh, v3(x - w, bottom, z), v3(x + w, bottom, z), v3(x, tip, z), v3(0, 0, fz));
    }
}

/* The shell: floor, roof, the galleries' back walls, the slab between the storeys in
 * each gallery (underside and top) and the end walls, cut around the solids. */
static void shell(atrium *a) {
    double zo = HZ + WALL + GAL, zw = HZ + WALL, ys = STOREY - SLAB;
    rect_y(a, A_FLOOR, 0, -HX, HX, -zo, zo, +1);
    rect_y(a, A_ROOF, 2 * STOREY, -HX, HX, -zo, zo, -1);
    for (int sz = -1; sz <= 1; sz += 2) {
        rect_z(a, A_WALLS, sz * zo, -HX, HX, 0, ys, -sz);
        rect_z(a, A_WALLS, sz * zo, -HX, HX, STOREY, 2 * STOREY, -sz);
        rect_y(a, A_WALLS, ys, -HX, HX, fmin(sz * zw, sz * zo), fmax(sz * zw, sz * zo), -1);
        rect_y(a, A_FLOOR, STOREY, -HX, HX, fmin(sz * HZ, sz * zo), fmax(sz * HZ, sz * zo), +1);
        for (int sx = -1; sx <= 1; sx += 2) {
            rect_x(a, A_WALLS, sx * HX, fmin(sz * zw, sz * zo), fmax(sz * zw, sz * zo), 0, ys, -sx);
            rect_x(a, A_WALLS, sx * HX, fmin(sz * zw, sz * zo), fmax(sz * zw, sz * zo), STOREY, 2 * STOREY, -sx);
        }
    }
    for (int sx = -1; sx <= 1; sx += 2) rect_x(a, A_WALLS, sx * HX, -HZ, HZ, 0, 2 * STOREY, -sx);
}

void scene_atrium(sg_scene *s) {
    atrium a = {.s = s, .d = s->opt.detail};
    double w = s->opt.albedo;
    int m_floor = sg_add_material(s, "floor_stone", 0.50, 0.45, 0.40, 0, 1);
    int m_plaster = sg_add_material(s, "plaster", w, w, w, 0, 1);
    int m_stone = sg_add_material(s, "sandstone", 0.70, 0.62, 0.50, 0, 1);
    int m_red = sg_add_material(s, "banner_red", 0.70, 0.10, 0.08, 0, 1);
    int m_blue = sg_add_material(s, "banner_blue", 0.10, 0.20, 0.60, 0, 1);
    a.mesh[A_FLOOR] = sg_add_mesh(s, "floor", m_floor);
    a.mesh[A_ROOF] = sg_add_mesh(s, "roof", m_plaster);
    a.mesh[A_WALLS] = sg_add_mesh(s, "walls", m_plaster);
    a.mesh[A_STONE] = sg_add_mesh(s, "arcades", m_stone);
    a.mesh[A_FANS] = sg_add_mesh(s, "arcade_fans", m_stone);
    a.mesh[A_COLUMNS] = sg_add_mesh(s, "columns", m_stone);
    a.mesh[A_BANNER_RED] = sg_add_mesh(s, "banners_red", m_red);
    a.mesh[A_BANNER_BLUE] = sg_add_mesh(s, "banners_blue", m_blue);
    a.mesh[A_TIP_RED] = sg_add_mesh(s, "banner_tips_red", m_red);
    a.mesh[A_TIP_BLUE] = sg_add_mesh(s, "banner_tips_blue", m_blue);
    shell(&a);
    double bay = 2 * HX / BAYS;
    for (int sz = -1; sz <= 1; sz += 2) {
        arcade(&a, 0, sz);
        arcade(&a, 1, sz);
        for (int i = 1; i < BAYS; i += 2)
            banner(&a, (i / 2 + (sz > 0)) % 2, -HX + i * bay, sz);
    }
    sg_add_point_light(s, "courtyard_light", v3(0, 3.0, 0), 150);
    sg_set_camera(s, v3(-HX + 0.6, 1.7, 0), v3(HX, 3.0, 0), 65);
}
