/* scenegen_gltf.c: wrt-scenegen's glTF writer: turns a built sg_scene (tools/scenegen.h)
 * into one self-contained glTF 2.0 text, its geometry packed into a single buffer
 * embedded as a base64 data URI, with the materials (metallic-roughness factors),
 * KHR_lights_punctual lights and the camera as nodes. Numbers are printed so that the
 * same scene gives the same bytes. The scenes themselves are built by scenegen.c.
 * Depends on common/wrt_common.h only. */
#define _POSIX_C_SOURCE 200809L
#include "tools/scenegen.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void sb_put(sbuf *b, const char *s, size_t n) {
    if (b->n + n + 1 > b->cap) {
        while (b->n + n + 1 > b->cap) b->cap = b->cap ? 2 * b->cap : 4096;
        b->p = wrt_xrealloc(b->p, b->cap);
    }
    memcpy(b->p + b->n, s, n);
    b->n += n;
    b->p[b->n] = 0;
}

static void sb_printf(sbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void sb_printf(sbuf *b, const char *fmt, ...) {
    char tmp[512];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n < 0) return;
    if ((size_t)n < sizeof tmp) { sb_put(b, tmp, (size_t)n); return; }
    char *big = wrt_xmalloc((size_t)n + 1);
    va_start(ap, fmt);
    vsnprintf(big, (size_t)n + 1, fmt, ap);
    va_end(ap);
    sb_put(b, big, (size_t)n);
    free(big);
}

/* Shortest decimal text that reads back as the same float (JSON numbers). */
static void sb_num(sbuf *b, double x) {
    float f = (float)x;
    if (f == 0) f = 0; /* no "-0" */
    char t[40];
    if (f == floorf(f) && fabsf(f) < 1e9f) {
        snprintf(t, sizeof t, "%.0f", (double)f);
        sb_put(b, t, strlen(t));
        return;
    }
    for (int prec = 1; prec <= 9; prec++) {
        snprintf(t, sizeof t, "%.*g", prec, (double)f);
        if (strtof(t, NULL) == f) break;
    }
    sb_put(b, t, strlen(t));
}

static void sb_vec(sbuf *b, const double *v, int n) {
    sb_put(b, "[", 1);
    for (int k = 0; k < n; k++) {
        if (k) sb_put(b, ",", 1);
        sb_num(b, v[k]);
    }
    sb_put(b, "]", 1);
}

static void sb_base64(sbuf *b, const unsigned char *d, size_t n) {
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    char q[4];
    for (size_t i = 0; i < n; i += 3) {
        uint32_t v = (uint32_t)d[i] << 16;
        if (i + 1 < n) v |= (uint32_t)d[i + 1] << 8;
        if (i + 2 < n) v |= d[i + 2];
        q[0] = tab[(v >> 18) & 63];
        q[1] = tab[(v >> 12) & 63];
        q[2] = i + 1 < n ? tab[(v >> 6) & 63] : '=';
        q[3] = i + 2 < n ? tab[v & 63] : '=';
        sb_put(b, q, 4);
    }
}

/* Little-endian binary buffer, whatever the host's byte order. */
typedef struct bbuf {
    unsigned char *p;
    size_t n, cap;
} bbuf;

static void bb_u32(bbuf *b, uint32_t v) {
    if (b->n + 4 > b->cap) {
        b->cap = b->cap ? 2 * b->cap : 4096;
        b->p = wrt_xrealloc(b->p, b->cap);
    }
    for (int k = 0; k < 4; k++) b->p[b->n++] = (unsigned char)(v >> (8 * k));
}

static void bb_f32(bbuf *b, float f) {
    uint32_t v;
    memcpy(&v, &f, 4);
    bb_u32(b, v);
}

/* Rotation taking the node's -Z to `dir` with +Y as close to `up` as possible, as a
 * unit quaternion (x, y, z, w). */
static void look_quat(wrt_v3 dir, wrt_v3 up, double q[4]) {
    wrt_v3 f = v3_norm(dir);
    if (fabs(v3_dot(f, v3_norm(up))) > 0.999) up = fabs(f.y) > 0.5 ? v3(0, 0, -1) : v3(0, 1, 0);
    wrt_v3 r = v3_norm(v3_cross(f, up)), u = v3_cross(r, f), zb = v3_scale(f, -1);
    double m00 = r.x, m10 = r.y, m20 = r.z, m01 = u.x, m11 = u.y, m21 = u.z;
    double m02 = zb.x, m12 = zb.y, m22 = zb.z;
    double tr = m00 + m11 + m22, x, y, z, w;
    if (tr > 0) {
        double k = sqrt(tr + 1.0) * 2;
        w = k / 4; x = (m21 - m12) / k; y = (m02 - m20) / k; z = (m10 - m01) / k;
    } else if (m00 > m11 && m00 > m22) {
        double k = sqrt(1.0 + m00 - m11 - m22) * 2;
        w = (m21 - m12) / k; x = k / 4; y = (m01 + m10) / k; z = (m02 + m20) / k;
    } else if (m11 > m22) {
        double k = sqrt(1.0 + m11 - m00 - m22) * 2;
        w = (m02 - m20) / k; x = (m01 + m10) / k; y = k / 4; z = (m12 + m21) / k;
    } else {
        double k = sqrt(1.0 + m22 - m00 - m11) * 2;
        w = (m10 - m01) / k; x = (m02 + m20) / k; y = (m12 + m21) / k; z = k / 4;
    }
    double l = sqrt(x * x + y * y + z * z + w * w);
    if (w < 0) l = -l; /* canonical sign: w >= 0 */
    q[0] = x / l; q[1] = y / l; q[2] = z / l; q[3] = w / l;
}

static wrt_v3 world(const sg_scene *s, wrt_v3 p) {
    return v3_add(v3_scale(p, s->opt.scale), s->opt.offset);
}

/* Buffer data, accessors and buffer views: per mesh POSITION, NORMAL and indices. */
static void gltf_mesh_buffers(const sg_scene *s, bbuf *bin, sbuf *acc, sbuf *views) {
    int nacc = 0;
    /* per mesh: POSITION, NORMAL, indices; one buffer view each */
    for (int i = 0; i < s->nmeshes; i++) {
        const sg_mesh *m = &s->meshes[i];
        size_t nqv = (size_t)m->nquads * 4, nv = nqv + (size_t)m->ntris * 3;
        float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
        for (size_t v = 0; v < nv; v++)
            for (int c = 0; c < 3; c++) {
                float x = v < nqv ? m->pos[3 * v + c] : m->tpos[3 * (v - nqv) + c];
                if (v == 0 || x < lo[c]) lo[c] = x;
                if (v == 0 || x > hi[c]) hi[c] = x;
            }
        for (int part = 0; part < 3; part++) {
            size_t off = bin->n;
            if (part < 2) {
                const float *src = part == 0 ? m->pos : m->nrm, *tsrc = part == 0 ? m->tpos : m->tnrm;
                for (size_t k = 0; k < 3 * nqv; k++) bb_f32(bin, src[k]);
                for (size_t k = 0; k < 3 * (nv - nqv); k++) bb_f32(bin, tsrc[k]);
            } else {
                for (uint32_t q = 0; q < (uint32_t)m->nquads; q++) {
                    uint32_t b = 4 * q;
                    bb_u32(bin, b); bb_u32(bin, b + 1); bb_u32(bin, b + 2);
                    bb_u32(bin, b); bb_u32(bin, b + 2); bb_u32(bin, b + 3);
                }
                for (uint32_t k = 0; k < 3 * (uint32_t)m->ntris; k++) bb_u32(bin, (uint32_t)nqv + k);
            }
            sb_printf(views, "%s\n    {\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu,\"target\":%d}",
                      nacc ? "," : "", off, bin->n - off, part < 2 ? 34962 : 34963);
            if (part < 2) {
                sb_printf(acc, "%s\n    {\"bufferView\":%d,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\"",
                          nacc ? "," : "", nacc, nv);
                if (part == 0) {
                    double dlo[3] = {lo[0], lo[1], lo[2]}, dhi[3] = {hi[0], hi[1], hi[2]};
                    sb_printf(acc, ",\"min\":");
                    sb_vec(acc, dlo, 3);
                    sb_printf(acc, ",\"max\":");
                    sb_vec(acc, dhi, 3);
                }
                sb_printf(acc, "}");
            } else {
                sb_printf(acc, ",\n    {\"bufferView\":%d,\"componentType\":5125,\"count\":%zu,\"type\":\"SCALAR\"}",
                          nacc, (size_t)m->nquads * 6 + (size_t)m->ntris * 3);
            }
            nacc++;
        }
    }
}

/* The KHR_lights_punctual extension with every light, when the scene has lights. */
static void gltf_lights(const sg_scene *s, sbuf *out) {
    int nl = s->nlights;
    int strength = 0;
    for (int i = 0; i < s->nmats; i++) strength |= s->mats[i].strength > 0 && s->mats[i].strength != 1;
    if (strength && nl == 0) sb_printf(out, "  \"extensionsUsed\":[\"KHR_materials_emissive_strength\"],\n");
    if (nl > 0) {
        if (strength)
            sb_printf(out, "  \"extensionsUsed\":[\"KHR_lights_punctual\",\"KHR_materials_emissive_strength\"],\n");
        else
            sb_printf(out, "  \"extensionsUsed\":[\"KHR_lights_punctual\"],\n");
        sb_printf(out, "  \"extensions\":{\"KHR_lights_punctual\":{\"lights\":[");
        for (int i = 0; i < nl; i++) {
            const sg_light *l = &s->lights[i];
            double inten = s->opt.intensity > 0 ? s->opt.intensity
                           : l->type == LIGHT_SUN   ? l->intensity /* lux: no falloff, no scaling */
                                                    : l->intensity * s->opt.scale * s->opt.scale;
            sb_printf(out, "%s\n    {\"name\":\"%s\",\"type\":\"%s\",\"color\":", i ? "," : "",
                      l->name, l->type == LIGHT_SPOT ? "spot" : l->type == LIGHT_SUN ? "directional" : "point");
            sb_vec(out, l->rgb, 3);
            sb_printf(out, ",\"intensity\":");
            sb_num(out, inten);
            if (l->type == LIGHT_SPOT) {
                sb_printf(out, ",\"spot\":{\"innerConeAngle\":");
                sb_num(out, l->inner);
                sb_printf(out, ",\"outerConeAngle\":");
                sb_num(out, l->outer);
                sb_printf(out, "}");
            }
            sb_printf(out, "}");
        }
        sb_printf(out, "]}},\n");
    }
}

/* The scene and its nodes: meshes, lights, camera. */
static void gltf_nodes(const sg_scene *s, sbuf *out) {
    int nl = s->nlights;
    /* nodes: meshes, lights, camera */
    int nnodes = s->nmeshes + nl + 1;
    sb_printf(out, "  \"scene\":0,\n  \"scenes\":[{\"name\":\"%s\",\"nodes\":[", s->name);
    for (int i = 0; i < nnodes; i++) sb_printf(out, "%s%d", i ? "," : "", i);
    sb_printf(out, "]}],\n  \"nodes\":[");
    for (int i = 0; i < s->nmeshes; i++)
        sb_printf(out, "%s\n    {\"name\":\"%s\",\"mesh\":%d}", i ? "," : "", s->meshes[i].name, i);
    for (int i = 0; i < nl; i++) {
        const sg_light *l = &s->lights[i];
        wrt_v3 p = world(s, l->pos);
        double t[3] = {p.x, p.y, p.z}, q[4];
        if (l->type == LIGHT_SPOT || l->type == LIGHT_SUN) look_quat(l->dir, v3(0, 1, 0), q);
        else { q[0] = q[1] = q[2] = 0; q[3] = 1; }
        sb_printf(out, ",\n    {\"name\":\"%s\",\"translation\":", l->name);
        sb_vec(out, t, 3);
        sb_printf(out, ",\"rotation\":");
        sb_vec(out, q, 4);
        sb_printf(out, ",\"extensions\":{\"KHR_lights_punctual\":{\"light\":%d}}}", i);
    }
    {
        wrt_v3 e = world(s, s->eye);
        double t[3] = {e.x, e.y, e.z}, q[4];
        look_quat(v3_sub(s->target, s->eye), s->up, q);
        sb_printf(out, ",\n    {\"name\":\"camera\",\"camera\":0,\"translation\":");
        sb_vec(out, t, 3);
        sb_printf(out, ",\"rotation\":");
        sb_vec(out, q, 4);
        sb_printf(out, "}");
    }
}

/* The camera, mesh and material sections. */
static void gltf_cameras_meshes_materials(const sg_scene *s, sbuf *out) {
    sb_printf(out, "\n  ],\n  \"cameras\":[{\"name\":\"camera\",\"type\":\"perspective\",\"perspective\":{\"yfov\":");
    sb_num(out, s->yfov);
    sb_printf(out, ",\"znear\":");
    sb_num(out, 0.01 * s->opt.scale);
    sb_printf(out, ",\"zfar\":");
    sb_num(out, 1000 * s->opt.scale);
    sb_printf(out, "}}],\n  \"meshes\":[");
    for (int i = 0; i < s->nmeshes; i++)
        sb_printf(out, "%s\n    {\"name\":\"%s\",\"primitives\":[{\"attributes\":{\"POSITION\":%d,\"NORMAL\":%d},\"indices\":%d,\"material\":%d,\"mode\":4}]}",
                  i ? "," : "", s->meshes[i].name, 3 * i, 3 * i + 1, 3 * i + 2, s->meshes[i].material);
    sb_printf(out, "\n  ],\n  \"materials\":[");
    for (int i = 0; i < s->nmats; i++) {
        const sg_material *m = &s->mats[i];
        double bc[4] = {m->rgb[0], m->rgb[1], m->rgb[2], 1};
        sb_printf(out, "%s\n    {\"name\":\"%s\",\"pbrMetallicRoughness\":{\"baseColorFactor\":", i ? "," : "", m->name);
        sb_vec(out, bc, 4);
        sb_printf(out, ",\"metallicFactor\":");
        sb_num(out, m->metallic);
        sb_printf(out, ",\"roughnessFactor\":");
        sb_num(out, m->roughness);
        sb_printf(out, "}");
        if (m->emissive[0] > 0 || m->emissive[1] > 0 || m->emissive[2] > 0) {
            sb_printf(out, ",\"emissiveFactor\":");
            sb_vec(out, m->emissive, 3);
            if (m->strength > 0 && m->strength != 1) {
                sb_printf(out, ",\"extensions\":{\"KHR_materials_emissive_strength\":{\"emissiveStrength\":");
                sb_num(out, m->strength);
                sb_printf(out, "}}");
            }
        }
        sb_printf(out, "}");
    }
}

/* Serializes the scene to glTF JSON text in `out`. */
void write_gltf(const sg_scene *s, sbuf *out) {
    bbuf bin = {0};
    sbuf acc = {0}, views = {0};
    gltf_mesh_buffers(s, &bin, &acc, &views);

    sb_printf(out, "{\n  \"asset\":{\"version\":\"2.0\",\"generator\":\"wrt-scenegen %s\"},\n",
              WRT_VERSION_STRING);
    gltf_lights(s, out);
    gltf_nodes(s, out);
    gltf_cameras_meshes_materials(s, out);
    sb_printf(out, "\n  ],\n  \"accessors\":[%s\n  ],\n  \"bufferViews\":[%s\n  ],\n", acc.p, views.p);
    sb_printf(out, "  \"buffers\":[{\"byteLength\":%zu,\"uri\":\"data:application/octet-stream;base64,", bin.n);
    sb_base64(out, bin.p, bin.n);
    sb_printf(out, "\"}]\n}\n");
    free(bin.p);
    free(acc.p);
    free(views.p);
}

/* Writes `text` to `path` through a temporary file renamed over it. */
