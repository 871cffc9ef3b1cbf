/* gto.h: the .gto file, wrt's baked light transport, and its reader and writer.
 * Byte layout, alignment, version rules and checksums are specified in
 * formats/GTO_FORMAT.md; the structs here are that layout (little-endian, checked
 * by static asserts in gto_layout.h). The player maps the file and uses these arrays in
 * place: nothing is parsed. Depends on common/scene_types.h (not on the loader). */
#ifndef WRT_GTO_H
#define WRT_GTO_H

#include "../common/wrt_common.h"
#include "../common/scene_types.h"

typedef struct wrt_scene wrt_scene; /* formats/scene.h: only the writer takes one */

#include <stdio.h>

/* Format version. The major version (WRT_GTO_VERSION) changes when an older reader
 * would misread a newer file; the minor version when a newer file only adds what an
 * older reader may skip (a new section id below 256, a field in a reserved slot whose
 * zero means "as before"). A reader accepts every minor of the majors it knows (1 to
 * 3) and refuses any other major with WRT_ERR_UNSUPPORTED, naming both versions. Since
 * 2.0 a section id >= 256 is critical: a reader that does not know it refuses the file,
 * naming the section; ids below 256 that it does not know it skips.
 * Checklist for a bump (GTO_FORMAT.md, "Changing the format", says the same):
 *   1. Decide major or minor by the rule above; a struct size or field meaning that
 *      changes is a major bump; a new section or a used reserved slot is a minor bump.
 *   2. Bump WRT_GTO_VERSION (and reset WRT_GTO_VERSION_MINOR to 0) or bump the minor.
 *   3. Update the static asserts in gto_layout.h and the tables in GTO_FORMAT.md.
 *   4. Keep tests/data/gto/v1_small.gto: a major bump makes the test expect
 *      WRT_ERR_UNSUPPORTED for it (or add a converter); a minor bump must still open it.
 *   5. Regenerate the golden file of the new version (test_gto --regen) and commit it. */
#define WRT_GTO_VERSION 3
#define WRT_GTO_VERSION_MINOR 0 /* 1.1: the optional first-bounce operator K (sections 12-15).
                                 * 1.2: the optional quad-to-source map (section 16).
                                 * 1.3: the optional corner normals (section 18) and
                                 * base-colour textures (section 21).
                                 * 2.0: the compact operator (section 17 in place of 8 and 9),
                                 * critical section ids (>= 256), the cluster tree (257),
                                 * K's entries compact (260, in place of 14 and 15).
                                 * 3.0: the compact operator's stream (261, in place of 7
                                 * and 17): the same codes and row deltas, the blocks'
                                 * first rows and bases without their counts, col_start
                                 * rebuilt on load.
                                 * The writer puts the lowest version that has what the file
                                 * holds: float entries without K or the map are 1.0, byte
                                 * for byte as before. */
#define WRT_GTO_VERSION_FLOAT 1 /* the major of files with float entries (sections 8, 9) */
#define WRT_GTO_VERSION_OPCODE 2 /* the major of files with section opcode (17), or only ctree / kcode */
/* Critical sections (GTO_FORMAT.md): a section id >= 256 is critical: a reader that does
 * not know it refuses the file, naming it. The cluster tree (section 257, from `wrt-bake
 * --clusters`) is one: the quads' root slots then hold the tree's functions (docs/clusters.md).
 * This reader reads majors WRT_GTO_VERSION_FLOAT to WRT_GTO_VERSION_MAX. */
#define WRT_GTO_VERSION_MAX WRT_GTO_VERSION
/* A node of the cluster tree (section ctree, 257): children (left -1 for a leaf, whose
 * right is then its quad) and area; node 0 is the root, children follow their parent. */
typedef struct wrt_gto_cnode { int32_t left, right; double area; } wrt_gto_cnode; /* 16 bytes */

/* On-disk records (all little-endian, naturally aligned, sizes fixed). */
typedef struct wrt_gto_quad {
    double p[4][3];      /* corners, world space (double: scenes far from the origin) */
    float n[3], t[3], b[3];
    float area;
    uint32_t material;
    uint32_t name;       /* index into the names table, WRT_GTO_NO_NAME if none */
    uint32_t func_first; /* this quad's basis functions: fkeys[func_first .. +func_count) */
    uint32_t func_count;
    uint32_t flags;      /* bit 0: parallelogram */
    uint32_t slevel;     /* deepest spatial level among its functions */
    uint32_t alevel;     /* deepest angular level among its functions (0: diffuse only) */
    uint32_t reserved;
} wrt_gto_quad; /* 168 bytes */

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

#define WRT_GTO_NO_NAME 0xFFFFFFFFu

/* The quad-to-source map (version 1.2, section srcmap): one record per quad, where it
 * came from in the glTF scene. -1 in an index: not known (a scene built in code). */
typedef struct wrt_gto_srcmap {
    int32_t node, mesh, prim; /* glTF node, mesh, primitive within the mesh */
    int32_t tri[2];      /* triangles (index / 3 in the primitive's indices); kind 1: tri[1] = -1 */
    uint32_t kind;       /* WRT_ELEM_QUAD (two triangles) or WRT_ELEM_TRIANGLE (one of its 3 quads) */
    uint32_t part;       /* WRT_ELEM_TRIANGLE: 0..2, else 0 */
    uint32_t flags;      /* WRT_GTO_SRC_TWIN, WRT_GTO_SRC_UV; other bits 0 */
    int32_t twin_of;     /* with WRT_GTO_SRC_TWIN: the front quad (< this quad), else -1 */
    uint32_t reserved;   /* 0 */
    float uv[4][2];      /* with WRT_GTO_SRC_UV: TEXCOORD_0 at p0..p3 (finite), else 0 */
} wrt_gto_srcmap; /* 72 bytes */
#define WRT_GTO_SRC_TWIN 1u /* the back twin of a double-sided quad */
#define WRT_GTO_SRC_UV 2u   /* uv holds the primitive's TEXCOORD_0 */

/* Corner normals (version 1.3, section normals): one record per quad, the mesh's vertex
 * normals (glTF NORMAL) at p0..p3, unit, world space; a quad without normals holds its
 * flat normal n at all four. Written only when some quad's corner normals differ from its
 * flat normal; used to shade and to join the smooth display across a smooth mesh's
 * edges, never by the transport. */
typedef struct wrt_gto_normals {
    float n[4][3];
} wrt_gto_normals; /* 48 bytes */

/* Figures of the bake, stored in the file and printed by `wrt-bake --info`. */
typedef struct wrt_gto_stats {
    double t_dto, t_gto, t_write, t_total;  /* seconds */
    uint64_t links_dto, links_gto, links_gathered;
    uint64_t entries_dto, entries_op;       /* non-zero RGB entries */
    uint64_t rays_traced, rays_skipped;
    uint64_t bounces;
    double energy_left;                     /* relative norm of the last term dropped */
    uint64_t reserved[6];
} wrt_gto_stats; /* 152 bytes */

/* What the operator in the file is. */
enum {
    WRT_GTO_OP_INDIRECT = 0, /* G - I = T + T^2 + ...           */
    WRT_GTO_OP_GATHERED = 1  /* T_fine G = T_fine + T_fine T + ... */
};

/* The compact operator (version 2.0, section opcode; GTO_FORMAT.md "The compact
 * operator"): a column's entries in blocks of up to 64, each block one record. */
typedef struct wrt_gto_block {
    uint32_t row0;   /* the block's first row (a function index) */
    uint8_t n;       /* entries, 1..WRT_GTO_BLOCK_MAX */
    uint8_t reserved;/* 0 */
    int16_t base;    /* entry value = mantissa * 2^(base + e), WRT_GTO_BASE_MIN..MAX */
} wrt_gto_block;
#define WRT_GTO_BLOCK_MAX 64
#define WRT_GTO_BASE_MIN (-126)
#define WRT_GTO_BASE_MAX 36 /* 511 * 2^(36 + 3) < 2^48, the largest value a file may hold */
#define WRT_GTO_CODEC 1     /* section opcode's encoding (2.0): 3 x 10-bit mantissas, 2-bit e */
#define WRT_GTO_CODEC3 3    /* section opstream's (3.0): the same entries, blocks without counts */
#define WRT_GTO_KCODEC 2    /* K's compact encoding (section kcode): a 14-bit mantissa, 2-bit e */
#define WRT_GTO_KMANT_MAX 8191 /* |K mantissa| <= 8191: 14 bits, two's complement, -8192 unused */

/* An entry's RGB value from its 32-bit code: bits 0-9, 10-19, 20-29 the red, green and
 * blue mantissas (two's complement, -511..511), bits 30-31 the exponent e above the
 * block's base. Exact: every value is a float (10 significant bits). */
static inline void wrt_gto_decode(uint32_t code, int base, float rgb[3]) {
    union { uint32_t u; float f; } sc;
    sc.u = (uint32_t)(base + (int)(code >> 30) + 127) << 23;
    for (int c = 0; c < 3; c++) {
        int32_t m = (int32_t)(code << (22 - 10 * c)) >> 22;
        rgb[c] = (float)m * sc.f;
    }
}

/* A K entry's value from its 16-bit code (section kcode, GTO_FORMAT.md "The compact
 * first-bounce operator"): bits 0-13 the mantissa (two's complement, -8191..8191), bits
 * 14-15 the exponent e above the block's base. Exact: every value is a float. */
static inline float wrt_gto_kdecode(uint16_t code, int base) {
    union { uint32_t u; float f; } sc;
    sc.u = (uint32_t)(base + (int)(code >> 14) + 127) << 23;
    int32_t m = (int32_t)((uint32_t)code << 18) >> 18;
    return (float)m * sc.f;
}

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
    uint32_t version_minor;
    int owns_map;              /* 1: close unmaps (wrt_gto_open); 0: caller's memory */
    /* The first-bounce operator K (version 1.1, GTO_FORMAT.md "The first-bounce operator
     * K"): one channel, rows = fkeys indices, columns = outgoing functions of glossy
     * quads. All zero / NULL when the file has none. */
    uint32_t nkcols;            /* K's columns (0: the file has no first-bounce operator) */
    uint64_t knnz;
    const uint64_t *kkeys;      /* nkcols, ascending: outgoing functions of glossy quads */
    const uint64_t *kcol_start; /* nkcols + 1 */
    const uint32_t *krows;      /* knnz, fkeys indices, ascending within a column */
    const float *kvals;         /* knnz, one channel */
    /* The quad-to-source map (version 1.2): nquads records, NULL when the file has none
     * (1.0 and 1.1 files, or written with no_srcmap). */
    const wrt_gto_srcmap *srcmap;
    /* Base-colour textures (version 1.3, section textures; docs/textures.md): the
     * section's bytes (NULL, 0 when the file has none); read with wrt_gto_texture. */
    const uint8_t *textures; uint64_t textures_size;
    /* Corner normals (version 1.3): nquads records, NULL when the file has none. */
    const wrt_gto_normals *normals;
    /* The cluster tree (version 2.0, section ctree): 2 nquads - 1 nodes, checked by the
     * reader (common/cluster_tree.h's rules); NULL when the file has none. */
    const wrt_gto_cnode *ctree;
    uint32_t nctree;
    /* 1: the tree's basis is on the senders' side only (section csend, 270): the columns
     * in the quads' root slots are the tree's functions, the rows the quads' functions as
     * in a file without a tree (the runtime transforms the light forward, no inverse on
     * the result); 0: both sides (or no tree). */
    int ctree_senders;
    /* The compact operator (version 2.0, section opcode; version 3.0, section opstream):
     * then rows and vals are NULL and column s's entries [col_start[s], col_start[s+1])
     * are in blocks [op_bcol[s], op_bcol[s+1]); block b's entries follow those of block
     * b - 1. Entry i starts a block exactly when op_deltas[i] is 0: its row is then the
     * block's op_row0, else the previous entry's row + op_deltas[i]; its value is
     * wrt_gto_decode(op_codes[i], the block's op_base). The same view for both versions:
     * a 2.0 file's row0 and base are copied out of its block records on load, a 3.0
     * file's col_start is rebuilt on load (both in `owned`). NULL / 0 in a file with float
     * entries. */
    uint64_t nblocks;
    const uint32_t *op_bcol;          /* nfuncs + 1 */
    const uint32_t *op_row0;          /* nblocks: each block's first row */
    const int8_t *op_base;            /* nblocks: each block's base exponent */
    const uint32_t *op_codes;         /* nnz */
    const uint8_t *op_deltas;         /* nnz */
    void *owned;                      /* what the reader allocated for this view (close frees it) */
    void *(*owned_alloc)(void *user, size_t size); /* where `owned` came from (NULL: malloc) */
    void (*owned_free)(void *user, void *p);
    void *owned_user;
    /* The compact first-bounce operator (version 2.0, critical section kcode, 260): then
     * krows and kvals are NULL and K's column j holds entries [kcol_start[j],
     * kcol_start[j+1]) in blocks [k_bcol[j], k_bcol[j+1]), laid out as the operator's
     * (a u16 code per entry, wrt_gto_kdecode); wrt_gto_k_entries decodes them. */
    uint64_t knblocks;
    const uint32_t *k_bcol;           /* nkcols + 1 */
    const wrt_gto_block *k_blocks;    /* knblocks */
    const uint16_t *k_codes;          /* knnz */
    const uint8_t *k_deltas;          /* knnz */
} wrt_gto;

/* The operator's entries one by one, whichever form the file holds them in: call
 * wrt_gto_entry for entries i, i + 1, ... in order, starting with a column's first entry
 * (col_start[s]) and a walk made by wrt_gto_walk_at(g, s) (a walk started at column 0
 * may run on across columns). Returns entry i's row and puts its value in v (the
 * compact entries' exact decode). */
typedef struct wrt_gto_walk { uint64_t b; uint32_t row; int base; } wrt_gto_walk;
static inline wrt_gto_walk wrt_gto_walk_at(const wrt_gto *g, uint32_t s) {
    wrt_gto_walk w = {g->op_bcol ? g->op_bcol[s] : 0, 0, 0};
    return w;
}
static inline uint32_t wrt_gto_entry(const wrt_gto *g, wrt_gto_walk *w, uint64_t i, float v[3]) {
    if (g->rows) { for (int c = 0; c < 3; c++) v[c] = g->vals[i * 3 + c]; return g->rows[i]; }
    if (g->op_deltas[i] == 0) { w->row = g->op_row0[w->b]; w->base = g->op_base[w->b]; w->b++; }
    else w->row += g->op_deltas[i];
    wrt_gto_decode(g->op_codes[i], w->base, v);
    return w->row;
}

/* K's entries in compressed-column order, whichever form the file holds them in: rows
 * (fkeys indices) and values into caller arrays of g->knnz each. The compact form's
 * values are exact decodes (wrt_gto_kdecode). */
void wrt_gto_k_entries(const wrt_gto *g, uint32_t *rows, float *vals);

/* One texture of the textures section: the material it belongs to, its size, glTF wrap
 * modes (0 repeat, 1 clamp, 2 mirror along s and t), the material's baseColorFactor and
 * the texture's mean (linear; the material's base_color is clamp(factor x mean)), and
 * w x h x 3 sRGB-encoded bytes, row 0 (t = 0) first. */
typedef struct wrt_gto_texture {
    uint32_t material, w, h, wrap[2];
    float factor[3], mean[3];
    const uint8_t *srgb;
} wrt_gto_texture;
/* Number of textures in g (0: none) and the i-th; returns 0 if i is out of range. */
uint32_t wrt_gto_texture_count(const wrt_gto *g);
int wrt_gto_texture_get(const wrt_gto *g, uint32_t i, wrt_gto_texture *out);

/* Maps and validates `path`: magic, version, byte order, every section's offset and
 * size against the file length, checksums, and the index ranges of the operator and of
 * the first-bounce operator K (if present).
 * Errors: WRT_ERR_IO (cannot open), WRT_ERR_NOT_OURS (foreign), WRT_ERR_CORRUPT
 * (truncated, bad offsets, checksum), WRT_ERR_UNSUPPORTED (newer version). */
/* Reads each byte once (the checksum pass, with the index checks on the data while it
 * is in cache). On failure *out is zeroed and wrt_last_error() names the check that
 * failed (and the section). Thread-safe; the result is read-only and may be shared. */
wrt_status wrt_gto_open(const char *path, wrt_gto *out);
/* Same checks on a file image in memory (`data` must stay valid and unchanged while
 * `out` is used, and be 8-byte aligned; used by tests and fuzzing). */
wrt_status wrt_gto_open_memory(const void *data, size_t size, wrt_gto *out);
/* The same, with the arrays the reader keeps for the compact entries' view (a 3.0 file's
 * column starts, a 2.0 file's block rows and bases: `owned`) taken from alloc(user, n)
 * and given back by free(user, p) on close (both NULL: malloc and free). For a library
 * whose caller supplies the memory (libwrt's wrt_allocator). */
wrt_status wrt_gto_open_alloc(const char *path, void *(*alloc)(void *, size_t), void (*free_fn)(void *, void *),
                              void *user, wrt_gto *out);
wrt_status wrt_gto_open_memory_alloc(const void *data, size_t size, void *(*alloc)(void *, size_t),
                                     void (*free_fn)(void *, void *), void *user, wrt_gto *out);
/* Unmaps (if wrt_gto_open mapped it), frees what it keeps, and zeroes *g. NULL or a zeroed g: no-op. */
void wrt_gto_close(wrt_gto *g);

/* Prints what a file holds: header, section table (bytes per section), counts, the
 * bake's statistics, provenance, and the integrity check result; one JSON object if
 * `json`. Returns the result of the integrity check (WRT_OK if the file is sound);
 * prints as much as could be read even if it is not. `wrt-bake --info FILE.gto`. */
wrt_status wrt_gto_print_info(const char *path, int json, FILE *f);

/* The section checksum (GTO_FORMAT.md, "Checksums"): a 64-bit hash reading 8 bytes
 * at a time in 4 independent lanes. Any change confined to one aligned 8-byte word
 * always changes it. Not cryptographic. */
uint64_t wrt_gto_checksum(const void *data, size_t n);

/* The first n bytes of a file of file_len bytes (read WRT_GTO_HEAD_BYTES of them): refuses
 * a file whose full header is not a .gto's or gives another size (WRT_ERR_NOT_OURS,
 * WRT_ERR_CORRUPT), before a copy of the whole file is allocated; WRT_OK otherwise. */
#define WRT_GTO_HEAD_BYTES 64
wrt_status wrt_gto_check_head(const void *head, size_t n, uint64_t file_len);

/* Everything the writer needs, in memory. */
typedef struct wrt_gto_contents {
    const wrt_scene *scene;
    const uint64_t *fkeys; uint32_t nfuncs;
    const uint64_t *col_start; const uint32_t *rows; const float *vals;
    uint32_t op_kind;
    const uint8_t *material_alevel; /* per material, may be NULL */
    wrt_gto_stats stats;
    const char *provenance;          /* JSON text */
    /* The first-bounce operator K, compressed columns as the operator (nkcols 0: none;
     * no K sections are written and the file is version 1.0, as before K existed). */
    uint32_t nkcols;
    const uint64_t *kkeys;           /* nkcols, strictly ascending wrt_fkey of glossy quads */
    const uint64_t *kcol_start;      /* nkcols + 1, from 0; kcol_start[nkcols] = knnz */
    const uint32_t *krows;           /* knnz fkeys indices, ascending within a column */
    const float *kvals;              /* knnz, finite */
    /* 0: the quad-to-source map is written from the scene's quads (section srcmap, version
     * 1.2); 1: not (the file is then as before version 1.2). */
    int no_srcmap;
    /* The cluster tree (nctree 0: none; else 2 nquads - 1 nodes): written as section ctree
     * (257), and the file as version 2.0. */
    const wrt_gto_cnode *ctree;
    uint32_t nctree;
    /* 1 (with a tree): the tree's basis on the senders' side only, section csend (270) */
    int ctree_senders;
    /* 1: the operator's entries are written compact (section opstream, version 3.0:
     * GTO_FORMAT.md "The compact operator"; 5.2-5.5 bytes an entry instead of 16, each
     * value within 2^-10 of its entry's largest channel); 0: as floats (sections rows
     * and vals, version 1.x). */
    int compact;
    /* With compact: 1 writes the same entries as version 2.0's section opcode (17, with
     * col_start), for a 2.x reader; 0 (default) version 3.0's opstream (261). */
    int opcode_v2;
    /* With compact: 0 writes K compact too (section kcode, 260, in place of krows and
     * kvals; about 3 bytes an entry instead of 8, each value within 1/8191 of the larger
     * of itself and an eighth of its block's largest); 1 keeps K's float sections. */
    int k_float;
} wrt_gto_contents;

/* Writes atomically: a temporary (see wrt_gto_write_pending), fsync, rename over
 * `path`, fsync the directory.
 * On any failure the temporary is removed and `path` is untouched. Checks the
 * contents first as the reader would (WRT_ERR_INVALID_ARG naming what is wrong): fkeys
 * strictly ascending with quads < nquads, col_start monotone from 0, rows < nfuncs and
 * ascending within a column, vals finite, material and name indices in range; with K
 * (nkcols > 0) also K's checks (GTO_FORMAT.md): kkeys strictly ascending on glossy
 * quads, kcol_start monotone from 0, krows < nfuncs, ascending
 * within a column and on another quad than the column's, kvals finite; with the source
 * map (no_srcmap 0) its checks (GTO_FORMAT.md: kinds, parts, twins naming an earlier
 * front of the same triangles, finite uv).
 * `c->provenance` may be NULL (empty). Same contents give the same bytes. */
wrt_status wrt_gto_write(const char *path, const wrt_gto_contents *c);

/* The same in two steps, for a caller that checks the file before it replaces the
 * target (wrt-bake --max-error): wrt_gto_write_pending writes and syncs a private
 * temporary in the target's folder (unnamed with O_TMPFILE where the file system has
 * it, so that nothing is left whatever ends the process; else PATH.tmp.PID.XXXXXX,
 * removed by the signal handler and by a later write to the same path once PID is
 * gone); wrt_gto_open_pending maps and validates it; wrt_gto_commit renames it over the
 * target; wrt_gto_discard drops it (the target untouched). Each pending file ends in
 * exactly one commit or discard (commit discards on failure). */
typedef struct wrt_gto_pending {
    int fd;       /* the open temporary, -1 if none */
    char *path;   /* the target */
    char *tmp;    /* the temporary's name, NULL while it has none */
    int slot;     /* signal-handler slot, -1 if none */
} wrt_gto_pending;
wrt_status wrt_gto_write_pending(const char *path, const wrt_gto_contents *c, wrt_gto_pending *p);
wrt_status wrt_gto_open_pending(const wrt_gto_pending *p, wrt_gto *out);
wrt_status wrt_gto_commit(wrt_gto_pending *p);
void wrt_gto_discard(wrt_gto_pending *p);

/* Before a long computation: refuses an output that is a directory or the same file
 * (device and inode, so also through links) as one of `inputs` (WRT_ERR_INVALID_ARG),
 * and one in whose folder no temporary can be created (WRT_ERR_IO). */
wrt_status wrt_gto_check_output(const char *path, const char *const *inputs, int ninputs);

/* For tests: named temporaries even where O_TMPFILE works. */
void wrt_gto_force_named_temporaries(int on);

/* Installs SIGINT/SIGTERM/SIGHUP handlers (where not ignored) that remove the
 * temporary file of a wrt_gto_write in progress, then re-raise the signal with its
 * default action. Call once from main(), before threads start. Idempotent. */
void wrt_gto_install_signal_cleanup(void);
/* What that handler does, for a program with its own signal handler: removes the
 * temporaries of the writes in progress. Async-signal-safe. */
void wrt_gto_remove_temporaries(void);

/* For tests: called by wrt_gto_write once the temporary exists, before any payload
 * is written, with its name (/proc/self/fd/N for an unnamed one) (NULL: none). Not
 * thread-safe; set it before writing. */
typedef void (*wrt_gto_write_hook)(const char *tmp_path);
void wrt_gto_set_write_hook(wrt_gto_write_hook hook);

#endif
