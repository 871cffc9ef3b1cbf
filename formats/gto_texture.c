/* gto_texture.c: the .gto's textures section (version 1.3, GTO_FORMAT.md "Textures",
 * docs/textures.md): the writer's encoding of a scene's base-colour textures, the
 * reader's structural check, and the accessors. Layout (little-endian, 8-byte aligned):
 *   u32 count, u32 reserved (0);
 *   count records of 48 bytes: u32 material (strictly ascending), u32 w, u32 h,
 *     u32 wrap_s, u32 wrap_t (0 repeat, 1 clamp, 2 mirror), u32 reserved (0),
 *     f32 factor[3], f32 mean[3] (finite, >= 0);
 *   then each texture's w x h x 3 sRGB bytes, row 0 first, each starting on an 8-byte
 *   boundary, zero padding between and after (the section's size is the end, rounded
 *   up to 8).
 * A copy, not a reference to the image file: the player needs neither the glTF nor its
 * images (embedded data URIs have no file), and the file stays one self-checked unit.
 * Textures larger than GTO_TEX_MAX a side are halved (box filter in linear light) until
 * they fit: the display needs no more, the bake used the full image. Depends on
 * gto_layout.h, common/texture.h. */
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gto_layout.h"
#include "scene.h"
#include "../common/texture.h"

#define GTO_TEX_MAX 1024u
#define TEX_HEAD 8u
#define TEX_REC 48u

static uint64_t align8(uint64_t x) { return (x + 7) & ~(uint64_t)7; }

static uint32_t rd32(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static float rdf(const uint8_t *p) { float v; memcpy(&v, p, 4); return v; }

/* The sRGB byte whose linear value is nearest x (exact for the loader's own values). */
static uint8_t srgb_byte(float x, const float lut[256]) {
    int lo = 0, hi = 255;
    while (lo < hi) { /* first entry >= x */
        int mid = (lo + hi) / 2;
        if (lut[mid] < x) lo = mid + 1; else hi = mid;
    }
    if (lo > 0 && x - lut[lo - 1] <= lut[lo] - x) lo--;
    return (uint8_t)lo;
}

/* t in linear floats, halved until it fits GTO_TEX_MAX (a new block, or NULL when it
 * already fits: its bytes are then stored as they are). */
static float *fit_texture(const wrt_texture *t, uint32_t *w, uint32_t *h) {
    *w = (uint32_t)t->w; *h = (uint32_t)t->h;
    if (*w <= GTO_TEX_MAX && *h <= GTO_TEX_MAX) return NULL;
    float *cur = wrt_xmalloc((size_t)*w * *h * 3 * sizeof(float));
    for (size_t i = 0; i < (size_t)*w * *h * 3; i++) cur[i] = t->lut[t->srgb[i]];
    while (*w > GTO_TEX_MAX || *h > GTO_TEX_MAX) {
        uint32_t nw = *w > 1 ? *w / 2 : 1, nh = *h > 1 ? *h / 2 : 1;
        for (uint32_t j = 0; j < nh; j++)
            for (uint32_t i = 0; i < nw; i++)
                for (int c = 0; c < 3; c++) {
                    uint32_t x0 = 2 * i < *w ? 2 * i : *w - 1, y0 = 2 * j < *h ? 2 * j : *h - 1;
                    uint32_t x1 = x0 + 1 < *w ? x0 + 1 : x0, y1 = y0 + 1 < *h ? y0 + 1 : y0;
                    float s = cur[((size_t)y0 * *w + x0) * 3 + c] + cur[((size_t)y0 * *w + x1) * 3 + c] +
                              cur[((size_t)y1 * *w + x0) * 3 + c] + cur[((size_t)y1 * *w + x1) * 3 + c];
                    cur[((size_t)j * nw + i) * 3 + c] = 0.25f * s; /* in place: (i, j) <= (2i, 2j) */
                }
        *w = nw; *h = nh;
    }
    return cur;
}

uint8_t *gto_build_textures(const wrt_scene *s, uint64_t *size) {
    *size = 0;
    uint32_t n = 0;
    uint64_t total = TEX_HEAD;
    for (int m = 0; m < s->nmaterials; m++) {
        int t = s->materials[m].base_tex;
        if (t <= 0 || t > s->ntextures) continue;
        uint32_t w = (uint32_t)s->textures[t - 1].w, h = (uint32_t)s->textures[t - 1].h;
        while (w > GTO_TEX_MAX || h > GTO_TEX_MAX) { w = w > 1 ? w / 2 : 1; h = h > 1 ? h / 2 : 1; }
        n++;
        total += TEX_REC + align8((uint64_t)w * h * 3);
    }
    if (!n) return NULL;
    uint8_t *b = wrt_xcalloc(total, 1);
    float lut[256];
    wrt_texture_srgb_table(lut);
    memcpy(b, &n, 4);
    uint64_t data = TEX_HEAD + (uint64_t)n * TEX_REC;
    uint32_t k = 0;
    for (int m = 0; m < s->nmaterials; m++) {
        int ti = s->materials[m].base_tex;
        if (ti <= 0 || ti > s->ntextures) continue;
        const wrt_texture *t = &s->textures[ti - 1];
        uint32_t w, h;
        float *fit = fit_texture(t, &w, &h);
        uint32_t rec[6] = {(uint32_t)m, w, h, (uint32_t)t->wrap[0], (uint32_t)t->wrap[1], 0};
        uint8_t *r = b + TEX_HEAD + (uint64_t)k * TEX_REC;
        memcpy(r, rec, sizeof rec);
        memcpy(r + 24, t->factor, 12);
        memcpy(r + 36, t->mean, 12);
        if (fit)
            for (uint64_t i = 0; i < (uint64_t)w * h * 3; i++) b[data + i] = srgb_byte(fit[i], lut);
        else
            memcpy(b + data, t->srgb, (size_t)w * h * 3);
        data += align8((uint64_t)w * h * 3);
        free(fit);
        k++;
    }
    *size = total;
    return b;
}

wrt_status gto_check_textures(const uint8_t *b, uint64_t size, uint32_t nmaterials) {
    if (size < TEX_HEAD || size % 8)
        return wrt_fail(WRT_ERR_CORRUPT, "section textures: %" PRIu64 " bytes, not a multiple of 8 of at least 8", size);
    uint32_t n = rd32(b);
    if (rd32(b + 4) != 0) return wrt_fail(WRT_ERR_CORRUPT, "section textures: reserved word not zero");
    if (n == 0 || n > nmaterials || (uint64_t)n * TEX_REC > size - TEX_HEAD)
        return wrt_fail(WRT_ERR_CORRUPT, "section textures: %u textures for %u materials in %" PRIu64 " bytes", n,
                        nmaterials, size);
    uint64_t data = TEX_HEAD + (uint64_t)n * TEX_REC;
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *r = b + TEX_HEAD + (uint64_t)i * TEX_REC;
        uint32_t m = rd32(r), w = rd32(r + 4), h = rd32(r + 8);
        if (m >= nmaterials || (i > 0 && m <= rd32(r - TEX_REC)))
            return wrt_fail(WRT_ERR_CORRUPT, "section textures: texture %u: material %u out of range or order", i, m);
        if (w < 1 || h < 1 || w > GTO_TEX_MAX || h > GTO_TEX_MAX)
            return wrt_fail(WRT_ERR_CORRUPT, "section textures: texture %u: size %u x %u (1..%u a side)", i, w, h,
                            GTO_TEX_MAX);
        if (rd32(r + 12) > 2 || rd32(r + 16) > 2 || rd32(r + 20) != 0)
            return wrt_fail(WRT_ERR_CORRUPT, "section textures: texture %u: wrap modes %u %u or reserved word", i,
                            rd32(r + 12), rd32(r + 16));
        for (int c = 0; c < 6; c++) {
            float f = rdf(r + 24 + 4 * c);
            if (!(f >= 0) || !isfinite(f))
                return wrt_fail(WRT_ERR_CORRUPT, "section textures: texture %u: %s[%d] %g is not finite and >= 0", i,
                                c < 3 ? "factor" : "mean", c % 3, (double)f);
        }
        uint64_t bytes = (uint64_t)w * h * 3;
        if (bytes > size - data)
            return wrt_fail(WRT_ERR_CORRUPT, "section textures: texture %u's texels run past the section", i);
        for (uint64_t p = data + bytes; p < align8(data + bytes); p++)
            if (b[p]) return wrt_fail(WRT_ERR_CORRUPT, "section textures: non-zero padding after texture %u", i);
        data = align8(data + bytes);
    }
    if (data != size)
        return wrt_fail(WRT_ERR_CORRUPT, "section textures: %" PRIu64 " bytes, the textures take %" PRIu64, size, data);
    return WRT_OK;
}

uint32_t wrt_gto_texture_count(const wrt_gto *g) { return g && g->textures ? rd32(g->textures) : 0; }

int wrt_gto_texture_get(const wrt_gto *g, uint32_t i, wrt_gto_texture *out) {
    uint32_t n = wrt_gto_texture_count(g);
    if (i >= n) return 0;
    uint64_t data = TEX_HEAD + (uint64_t)n * TEX_REC;
    for (uint32_t k = 0; k < i; k++) {
        const uint8_t *r = g->textures + TEX_HEAD + (uint64_t)k * TEX_REC;
        data = align8(data + (uint64_t)rd32(r + 4) * rd32(r + 8) * 3);
    }
    const uint8_t *r = g->textures + TEX_HEAD + (uint64_t)i * TEX_REC;
    out->material = rd32(r); out->w = rd32(r + 4); out->h = rd32(r + 8);
    out->wrap[0] = rd32(r + 12); out->wrap[1] = rd32(r + 16);
    for (int c = 0; c < 3; c++) { out->factor[c] = rdf(r + 24 + 4 * c); out->mean[c] = rdf(r + 36 + 4 * c); }
    out->srgb = g->textures + data;
    return 1;
}
