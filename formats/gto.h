/* gto.h: the .gto file, wrt's baked light transport, and its reader and writer.
 * Byte layout, alignment, version rules and checksums are specified in
 * formats/GTO_FORMAT.md; the structs here are that layout (little-endian, checked
 * by static asserts in gto.c). The player maps the file and uses these arrays in
 * place: nothing is parsed. Depends on wrt_common.h and scene.h. */
#ifndef WRT_GTO_H
#define WRT_GTO_H

#include "../common/wrt_common.h"
#include "scene.h"

#define WRT_GTO_VERSION 1

/* On-disk records (all little-endian, naturally aligned, sizes fixed). */
typedef struct wrt_gto_quad {
    double p[4][3];      /* corners, world space (double: scenes far from the origin) */
    float n[3], t[3], b[3];
    float area;
    uint32_t material;
    uint32_t name;       /* index into the names table */
    uint32_t func_first; /* this quad's basis functions: fkeys[func_first .. +func_count) */
    uint32_t func_count;
    uint32_t flags;      /* bit 0: parallelogram */
    uint32_t slevel;     /* deepest spatial level among its functions */
    uint32_t alevel;     /* deepest angular level among its functions (0: diffuse only) */
    uint32_t reserved;
} wrt_gto_quad; /* 160 bytes */

typedef struct wrt_gto_material {
    char name[64];
    float base_color[3];
    float metallic, roughness;
    float emissive[3];
    uint32_t lambertian;
    uint32_t alevel;     /* angular resolution the bake used for this material */
} wrt_gto_material; /* 104 bytes */

typedef struct wrt_gto_light {
    char name[64];
    uint32_t type;       /* wrt_light_type */
    float color[3];
    double pos[3], dir[3];
    float intensity, range, inner_cone, outer_cone;
} wrt_gto_light; /* 144 bytes */

typedef struct wrt_gto_camera {
    double pos[3], dir[3], up[3];
    double yfov, aspect, znear, zfar;
} wrt_gto_camera; /* 104 bytes */

/* Figures of the bake, stored in the file and printed by `wrt-bake --info`. */
typedef struct wrt_gto_stats {
    double t_dto, t_gto, t_write, t_total;  /* seconds */
    uint64_t links_dto, links_gto, links_gathered;
    uint64_t entries_dto, entries_op;       /* non-zero RGB entries */
    uint64_t rays_traced, rays_skipped;
    uint64_t bounces;
    double energy_left;                     /* relative norm of the last term dropped */
    uint64_t reserved[6];
} wrt_gto_stats; /* 144 bytes */

/* What the operator in the file is. */
enum {
    WRT_GTO_OP_INDIRECT = 0, /* G - I = T + T^2 + ...           */
    WRT_GTO_OP_GATHERED = 1  /* T_fine G = T_fine + T_fine T + ... */
};

/* A mapped, validated file. All pointers point into the mapping. */
typedef struct wrt_gto {
    void *map; size_t size;
    uint32_t version, op_kind;
    uint32_t nquads, nmaterials, nlights, nnames, nfuncs;
    uint64_t nnz;
    const wrt_gto_quad *quads;
    const wrt_gto_material *materials;
    const wrt_gto_light *lights;
    const wrt_gto_camera *camera;
    const char (*names)[64];
    const uint64_t *fkeys;     /* nfuncs, sorted ascending (wrt_fkey of basis.h) */
    const uint64_t *col_start; /* nfuncs + 1: column s is entries [col_start[s], col_start[s+1]) */
    const uint32_t *rows;      /* nnz receiver function indices, ascending within a column */
    const float *vals;         /* nnz x 3 RGB values */
    const wrt_gto_stats *stats;
    const char *provenance; size_t provenance_len; /* JSON text, not NUL-terminated */
} wrt_gto;

/* Maps and validates `path`: magic, version, byte order, every section's offset and
 * size against the file length, checksums, and the operator's index ranges.
 * Errors: WRT_ERR_IO (cannot open), WRT_ERR_NOT_OURS (foreign), WRT_ERR_CORRUPT
 * (truncated, bad offsets, checksum), WRT_ERR_UNSUPPORTED (newer version). */
wrt_status wrt_gto_open(const char *path, wrt_gto *out);
void wrt_gto_close(wrt_gto *g);

/* Everything the writer needs, in memory. */
typedef struct wrt_gto_contents {
    const wrt_scene *scene;
    const uint64_t *fkeys; uint32_t nfuncs;
    const uint64_t *col_start; const uint32_t *rows; const float *vals;
    uint32_t op_kind;
    const uint8_t *material_alevel; /* per material, may be NULL */
    wrt_gto_stats stats;
    const char *provenance;          /* JSON text */
} wrt_gto_contents;

/* Writes atomically: PATH.tmp.XXXXXX, fsync, rename over `path`. On any failure the
 * temporary is removed and `path` is untouched. */
wrt_status wrt_gto_write(const char *path, const wrt_gto_contents *c);

#endif
