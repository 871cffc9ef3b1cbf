/* gto_layout.h: the .gto file's on-disk layout and what the reader, the writer and the
 * inspector share inside formats/ (internal: nothing outside formats/ includes it). The
 * header and section-table records with static asserts on their sizes and offsets, the
 * section ids and their element sizes, and the three stages of validation: the layout
 * (header and table, gto_read.c), the payload's content checks and checksum (gto_check.c,
 * also run by the writer on its own input) and the mapping of a file. The layout is
 * specified in GTO_FORMAT.md; the public records are the structs of gto.h. Depends on
 * gto.h and wrt_common. */
#ifndef WRT_GTO_LAYOUT_H
#define WRT_GTO_LAYOUT_H

#include <stddef.h>
#include <stdint.h>

#include "gto.h"

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the .gto file is little-endian and is used in place: a big-endian port needs a converting reader"
#endif

/* ------------------------------------------------------------------------------------
 * Layout: header, section table, sections. See GTO_FORMAT.md.
 * ---------------------------------------------------------------------------------- */

#define GTO_MAGIC "\x89WRT\r\n\x1a\n"
#define GTO_MAGIC_LEN 8
#define GTO_BOM 0x01020304u         /* written natively: bytes 04 03 02 01 */
#define GTO_BOM_SWAPPED 0x04030201u
#define GTO_ALIGN 64u
#define GTO_MAX_SECTIONS 64u

typedef struct gto_header {
    uint8_t magic[8];
    uint32_t byte_order;
    uint16_t version_major, version_minor;
    uint64_t file_size;
    uint32_t header_size;   /* 64 + 48 * nsections */
    uint32_t nsections;
    uint32_t op_kind;
    uint32_t flags;         /* 0 in version 1.0 */
    uint64_t header_checksum;
    uint8_t reserved[16];
} gto_header;

typedef struct gto_section {
    uint32_t id, elem_size;
    uint64_t offset, size, count, checksum;
    uint32_t flags, reserved; /* 0 in version 1.0 */
} gto_section;

_Static_assert(sizeof(gto_header) == 64, "header is 64 bytes");
_Static_assert(offsetof(gto_header, byte_order) == 8, "layout");
_Static_assert(offsetof(gto_header, version_major) == 12, "layout");
_Static_assert(offsetof(gto_header, version_minor) == 14, "layout");
_Static_assert(offsetof(gto_header, file_size) == 16, "layout");
_Static_assert(offsetof(gto_header, header_size) == 24, "layout");
_Static_assert(offsetof(gto_header, nsections) == 28, "layout");
_Static_assert(offsetof(gto_header, op_kind) == 32, "layout");
_Static_assert(offsetof(gto_header, header_checksum) == 40, "layout");
_Static_assert(sizeof(gto_section) == 48, "section entry is 48 bytes");
_Static_assert(offsetof(gto_section, offset) == 8, "layout");
_Static_assert(offsetof(gto_section, size) == 16, "layout");
_Static_assert(offsetof(gto_section, count) == 24, "layout");
_Static_assert(offsetof(gto_section, checksum) == 32, "layout");

_Static_assert(sizeof(wrt_gto_quad) == 168, "quad record");
_Static_assert(offsetof(wrt_gto_quad, n) == 96, "layout");
_Static_assert(offsetof(wrt_gto_quad, area) == 132, "layout");
_Static_assert(offsetof(wrt_gto_quad, material) == 136, "layout");
_Static_assert(offsetof(wrt_gto_quad, func_first) == 144, "layout");
_Static_assert(offsetof(wrt_gto_quad, func_count) == 148, "layout");
_Static_assert(offsetof(wrt_gto_quad, flags) == 152, "layout");
_Static_assert(offsetof(wrt_gto_quad, slevel) == 156, "layout");
_Static_assert(offsetof(wrt_gto_quad, reserved) == 164, "layout");
_Static_assert(sizeof(wrt_gto_material) == 104, "material record");
_Static_assert(offsetof(wrt_gto_material, base_color) == 64, "layout");
_Static_assert(offsetof(wrt_gto_material, emissive) == 84, "layout");
_Static_assert(offsetof(wrt_gto_material, lambertian) == 96, "layout");
_Static_assert(offsetof(wrt_gto_material, alevel) == 100, "layout");
_Static_assert(sizeof(wrt_gto_light) == 144, "light record");
_Static_assert(offsetof(wrt_gto_light, type) == 64, "layout");
_Static_assert(offsetof(wrt_gto_light, pos) == 80, "layout");
_Static_assert(offsetof(wrt_gto_light, dir) == 104, "layout");
_Static_assert(offsetof(wrt_gto_light, intensity) == 128, "layout");
_Static_assert(offsetof(wrt_gto_light, outer_cone) == 140, "layout");
_Static_assert(sizeof(wrt_gto_camera) == 104, "camera record");
_Static_assert(offsetof(wrt_gto_camera, yfov) == 72, "layout");
_Static_assert(offsetof(wrt_gto_camera, zfar) == 96, "layout");
_Static_assert(sizeof(wrt_gto_stats) == 152, "stats record");
_Static_assert(offsetof(wrt_gto_stats, links_dto) == 32, "layout");
_Static_assert(offsetof(wrt_gto_stats, entries_dto) == 56, "layout");
_Static_assert(offsetof(wrt_gto_stats, rays_traced) == 72, "layout");
_Static_assert(offsetof(wrt_gto_stats, bounces) == 88, "layout");
_Static_assert(offsetof(wrt_gto_stats, energy_left) == 96, "layout");
_Static_assert(offsetof(wrt_gto_stats, reserved) == 104, "layout");
_Static_assert(sizeof(wrt_gto_srcmap) == 72, "srcmap record");
_Static_assert(offsetof(wrt_gto_srcmap, tri) == 12, "layout");
_Static_assert(offsetof(wrt_gto_srcmap, kind) == 20, "layout");
_Static_assert(offsetof(wrt_gto_srcmap, part) == 24, "layout");
_Static_assert(offsetof(wrt_gto_srcmap, flags) == 28, "layout");
_Static_assert(offsetof(wrt_gto_srcmap, twin_of) == 32, "layout");
_Static_assert(offsetof(wrt_gto_srcmap, reserved) == 36, "layout");
_Static_assert(offsetof(wrt_gto_srcmap, uv) == 40, "layout");
_Static_assert(sizeof(wrt_gto_normals) == 48, "normals record");
_Static_assert(sizeof(float) == 4 && sizeof(double) == 8, "IEEE 754 binary32/binary64");

static inline uint64_t gto_align_up(uint64_t x) { return (x + GTO_ALIGN - 1) & ~(uint64_t)(GTO_ALIGN - 1); }

enum {
    SEC_QUADS = 1, SEC_MATERIALS, SEC_LIGHTS, SEC_CAMERA, SEC_NAMES, SEC_FKEYS,
    SEC_COL_START, SEC_ROWS, SEC_VALS, SEC_STATS, SEC_PROVENANCE,
    /* version 1.1: the first-bounce operator K, all four or none */
    SEC_KKEYS, SEC_KCOL_START, SEC_KROWS, SEC_KVALS,
    /* version 1.2: the quad-to-source map, optional */
    SEC_SRCMAP,
    /* version 2.0: the compact operator, in place of rows and vals */
    SEC_OPCODE,
    /* version 1.3: the corner normals, optional */
    SEC_NORMALS = 18,
    /* version 1.3: base-colour textures, optional (docs/textures.md) */
    SEC_TEXTURES = 21,
    SEC_KNOWN_END
};
#define SEC_KNOWN (SEC_KNOWN_END - 1)
#define SEC_CRITICAL 256            /* ids from here on: a reader that does not know one refuses the file */
#define SEC_CTREE 257               /* the cluster tree (version 2.0) */
#define SEC_KCODE 260               /* the compact first-bounce operator (version 2.0), in place of krows, kvals */
#define SEC_OPSTREAM 261            /* the compact operator (version 3.0), in place of col_start and opcode */
#define SEC_CSEND 270              /* the cluster tree's basis on the senders' side only (version 2.0 on) */
#define GTO_MAX_WRITTEN (SEC_KNOWN + 4) /* sections a file can hold: the known ones, ctree, kcode, opstream, csend */
#define SEC_REQUIRED SEC_PROVENANCE /* ids 1 .. this are in every file */
#define GTO_MINOR_K 1               /* the minor version that added K */
#define GTO_MINOR_SRCMAP 2          /* the minor version that added the quad-to-source map */
#define GTO_MINOR_TEXTURES 3        /* the minor version that added the textures section */
#define GTO_MINOR_NORMALS 3         /* the minor version that added the corner normals */
#define GTO_CRITICAL_ID 256u        /* since 2.0: ids from here on must be known to be read */

/* The compact operator's section (opcode, version 2.0): this header, then at offsets
 * that are multiples of 64 from the payload's start (zero bytes between): bcol (u32,
 * nfuncs + 1), the blocks (wrt_gto_block, nblocks), the codes (u32, nnz) and the row
 * deltas (u8, nnz), which end the payload. */
typedef struct gto_opcode_head {
    uint32_t codec;      /* WRT_GTO_CODEC */
    uint32_t block_max;  /* WRT_GTO_BLOCK_MAX */
    uint64_t nblocks, nnz;
    uint8_t reserved[40];
} gto_opcode_head;
_Static_assert(sizeof(gto_opcode_head) == 64, "opcode header is 64 bytes");
_Static_assert(sizeof(wrt_gto_block) == 8, "block record");
_Static_assert(offsetof(wrt_gto_block, n) == 4 && offsetof(wrt_gto_block, base) == 6, "layout");

/* Where a compact section's arrays start (opcode and kcode share the layout), from its
 * counts and the bytes of a code (4 opcode, 2 kcode); its size is the deltas' end. */
typedef struct gto_opcode_layout { uint64_t bcol, blocks, codes, deltas, size; } gto_opcode_layout;
static inline gto_opcode_layout gto_blocks_place(uint32_t ncols, uint64_t nblocks, uint64_t nnz, uint32_t code_bytes) {
    gto_opcode_layout o;
    o.bcol = sizeof(gto_opcode_head);
    o.blocks = gto_align_up(o.bcol + 4 * ((uint64_t)ncols + 1));
    o.codes = gto_align_up(o.blocks + sizeof(wrt_gto_block) * nblocks);
    o.deltas = gto_align_up(o.codes + code_bytes * nnz);
    o.size = o.deltas + nnz;
    return o;
}
static inline gto_opcode_layout gto_opcode_place(uint32_t nfuncs, uint64_t nblocks, uint64_t nnz) {
    return gto_blocks_place(nfuncs, nblocks, nnz, 4);
}

/* The compact operator's stream (opstream, 261, version 3.0): the opcode's header (codec
 * WRT_GTO_CODEC3), then at multiples of 64 from the payload's start (zero bytes
 * between): bcol (u32, nfuncs + 1), each block's first row (u32, nblocks), the codes
 * (u32, nnz), each block's base (i8, nblocks) and the row deltas (u8, nnz; 0 exactly at
 * each block's first entry), which end the payload. No col_start: rebuilt on load. */
struct vctx;
typedef struct gto_opstream_layout { uint64_t bcol, row0, codes, base, deltas, size; } gto_opstream_layout;
static inline gto_opstream_layout gto_opstream_place(uint32_t nfuncs, uint64_t nblocks, uint64_t nnz) {
    gto_opstream_layout o;
    o.bcol = sizeof(gto_opcode_head);
    o.row0 = gto_align_up(o.bcol + 4 * ((uint64_t)nfuncs + 1));
    o.codes = gto_align_up(o.row0 + 4 * nblocks);
    o.base = gto_align_up(o.codes + 4 * nnz);
    o.deltas = gto_align_up(o.base + nblocks);
    o.size = o.deltas + nnz;
    return o;
}
/* The checker of section opstream (gto_opcode.c), once its last chunk has been summed:
 * its structure, and col_start rebuilt into v->col_out (the reader's, nfuncs + 1) or,
 * without one (the writer), compared with v->g->col_start. The encoder: float entries
 * into a new payload (*size bytes, malloc'd; NULL without memory), the same blocks,
 * codes and deltas as section opcode's. Deterministic. */
void gto_check_opstream(struct vctx *v, const uint8_t *base, uint64_t first, uint64_t n);
uint8_t *gto_opstream_encode(uint32_t nfuncs, const uint64_t *col_start, const uint32_t *rows,
                             const float *vals, uint64_t *size);

/* The compact operator (gto_opcode.c). The checker of section opcode: the whole
 * section's structure once its last chunk has been summed (GTO_FORMAT.md). */
struct vctx;
void gto_check_opcode(struct vctx *v, const uint8_t *base, uint64_t first, uint64_t n);
/* Shared by the compact sections' encoders and checkers (gto_opcode.c): the end of the
 * block that starts at entry a of a column ending at `end` (64 entries or a row step of
 * 256), whether bytes [a, b) of p are zero, and the first problem recorded in v. */
uint64_t gto_block_end(const uint32_t *rows, uint64_t a, uint64_t end);
int gto_step_exp(double m, double mant_max); /* the smallest E with mant_max 2^E >= m > 0 */
int gto_zero_bytes(const uint8_t *p, uint64_t a, uint64_t b);
void gto_obad(struct vctx *v, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Column col's blocks [k0, k1) against its entries [e0, e1) of col_start (both compact
 * sections' structure; `what` and `starts` name the column and its array in the
 * messages); row_ok, when not NULL, checks every entry's row (records the problem in v,
 * returns 0), else only each block's last row is checked against nfuncs. */
typedef int (*gto_row_check)(struct vctx *v, uint32_t col, uint64_t entry, uint64_t row);
void gto_check_column_blocks(struct vctx *v, const char *what, const char *starts, const wrt_gto_block *blk,
                             const uint8_t *d, uint32_t col, uint64_t k0, uint64_t k1, uint64_t e0, uint64_t e1,
                             gto_row_check row_ok);
/* The block layout both compact sections share (gto_opcode.c): ncols columns of entries
 * (col_start, rows ascending within a column) cut into blocks (gto_block_end), a new
 * payload (*size bytes, malloc'd; NULL if there is no memory) with its header (codec),
 * bcol, each block's first row, count and base, and each entry's row delta; `code`
 * writes one block's codes (entries [a, b) of vals, code_bytes each, at codes + a) and
 * returns its base exponent. Deterministic. */
typedef int16_t (*gto_block_coder)(const float *vals, uint64_t a, uint64_t b, void *codes);
uint8_t *gto_blocks_encode(uint32_t ncols, const uint64_t *col_start, const uint32_t *rows, const float *vals,
                           uint32_t codec, uint32_t code_bytes, gto_block_coder code, uint64_t *size);
/* Encodes float entries (col_start over nfuncs columns, rows, vals) into a new payload
 * of section opcode (*size bytes, malloc'd; NULL if there is no memory). Deterministic. */
uint8_t *gto_opcode_encode(uint32_t nfuncs, const uint64_t *col_start, const uint32_t *rows,
                           const float *vals, uint64_t *size);

/* The compact first-bounce operator's section (kcode, 260, version 2.0): the opcode's
 * header (codec WRT_GTO_KCODEC), then at multiples of 64 from the payload's start: bcol
 * (u32, nkcols + 1), the blocks (wrt_gto_block, nblocks), the codes (u16, knnz) and the
 * row deltas (u8, knnz), which end the payload. Blocks are cut as the operator's. */
static inline gto_opcode_layout gto_kcode_place(uint32_t nkcols, uint64_t nblocks, uint64_t knnz) {
    return gto_blocks_place(nkcols, nblocks, knnz, 2);
}
/* gto_kcode.c: the checker of section kcode (the whole section once its last chunk is
 * summed: structure, rows ascending below nfuncs and off the column's quad, no mantissa
 * -8192) and the encoder of K's float entries (malloc'd payload, NULL without memory;
 * deterministic). */
void gto_check_kcode(struct vctx *v, const uint8_t *base, uint64_t first, uint64_t n);
uint8_t *gto_kcode_encode(uint32_t nkcols, const uint64_t *kcol_start, const uint32_t *krows,
                          const float *kvals, uint64_t *size);

/* Name and element size of each known section id (gto_check.c). */
typedef struct gto_sec_desc { const char *name; uint32_t elem_size; } gto_sec_desc;
extern const gto_sec_desc gto_sec_info[SEC_KNOWN_END];

/* The textures section (gto_texture.c): the writer's encoding of the scene's base-colour
 * textures (NULL and *size 0 when it has none; free it) and the reader's check of one. */
struct wrt_scene;
uint8_t *gto_build_textures(const struct wrt_scene *s, uint64_t *size);
wrt_status gto_check_textures(const uint8_t *b, uint64_t size, uint32_t nmaterials);

/* 1 if this reader knows section id (the table has gaps: ids it does not know). */
static inline int gto_sec_known(uint32_t id) { return id >= 1 && id <= SEC_KNOWN && gto_sec_info[id].name; }

static inline const char *gto_sec_name(uint32_t id) {
    if (id == SEC_CTREE) return "ctree";
    if (id == SEC_KCODE) return "kcode";
    if (id == SEC_OPSTREAM) return "opstream";
    if (id == SEC_CSEND) return "csend";
    return gto_sec_known(id) ? gto_sec_info[id].name : "unknown";
}

/* Element size of a section this code writes or reads (known ids and ctree). */
static inline uint32_t gto_sec_elem(uint32_t id) {
    if (id == SEC_KCODE || id == SEC_OPSTREAM) return 1;
    if (id == SEC_CSEND) return 4;
    return id == SEC_CTREE ? (uint32_t)sizeof(wrt_gto_cnode) : gto_sec_info[id].elem_size;
}
_Static_assert(sizeof(wrt_gto_cnode) == 16, "ctree record");
_Static_assert(offsetof(wrt_gto_cnode, area) == 8, "layout");


/* ------------------------------------------------------------------------------------
 * Content checks (gto_check.c), shared by the reader (on the mapping) and the writer (on
 * its input). A chunk checker records the first problem in the context and keeps quiet
 * after it; the caller reports it only once the section's checksum is known to be right.
 * ---------------------------------------------------------------------------------- */

typedef struct vctx {
    const wrt_gto *g;   /* counts and pointers of the sections checked so far */
    int bad;
    char err[256];
    uint64_t col;       /* rows: current column */
    uint64_t kcol;      /* krows: current column */
    uint32_t kq;        /* krows: quad + 1 whose function range is [kq_lo, kq_hi) (0: none) */
    uint32_t kq_lo, kq_hi;
    uint64_t *col_out;  /* opstream: where the reader rebuilds col_start (NULL: the writer's, compared) */
} vctx;

/* Checks elements [first, first + n) of a section whose payload starts at `base`. */
typedef void (*chunk_check)(vctx *v, const uint8_t *base, uint64_t first, uint64_t n);

/* The checker of a section id (NULL: none). */
chunk_check gto_sec_checker(uint32_t id);
/* One pass over a section: checksum and checks, 8192 elements at a time. Returns the
 * checksum; v->bad tells whether a check failed. */
uint64_t gto_scan_section(const uint8_t *p, uint64_t count, uint32_t elem, chunk_check fn, vctx *v);
/* What needs a later section: each quad's function range against fkeys. */
void gto_check_quad_ranges(vctx *v);
/* The cluster tree's records against common/cluster_tree.h's rules (n nodes for nq
 * quads); on failure returns `fail` with a message that starts with `what`. */
wrt_status gto_check_ctree(const wrt_gto_cnode *nodes, uint32_t n, uint32_t nq, wrt_status fail, const char *what);

/* ------------------------------------------------------------------------------------
 * Reading (gto_read.c): three stages, then the mapping.
 * ---------------------------------------------------------------------------------- */

/* Where each section is, once the table has been checked (0 if absent). */
typedef struct gto_layout {
    gto_header h;
    const gto_section *table;
    const gto_section *sec[SEC_KNOWN_END];
    const gto_section *ctree; /* section ctree (257), or NULL */
    const gto_section *kcode; /* section kcode (260), or NULL */
    const gto_section *opstream; /* section opstream (261), or NULL */
    const gto_section *csend; /* section csend (270), or NULL */
} gto_layout;

/* Stage 1: the header and the section table, no payload byte read. */
wrt_status gto_parse_layout(const uint8_t *b, size_t len, gto_layout *L);
/* Stage 2: counts that must agree across sections, and zero padding; fills g's counts
 * and pointers. */
wrt_status gto_check_counts(const uint8_t *b, const gto_layout *L, wrt_gto *g);
/* Stage 3: the single pass over the payload. */
wrt_status gto_check_payload(const uint8_t *b, const gto_layout *L, const wrt_gto *g);

/* Maps the whole of an open regular file read-only. *map is NULL for an empty file. */
wrt_status gto_map_fd(int fd, const char *path, void **map, size_t *len);
/* Maps a whole file read-only (a FIFO or device is refused without blocking). */
wrt_status gto_map_file(const char *path, void **map, size_t *len);
/* Validates a mapping of `len` bytes of `path` (NULL when the file is empty) and hands it
 * to `out`, which then owns it; on failure unmaps it and names the path in the error. */
wrt_status gto_adopt_map(void *map, size_t len, const char *path, wrt_gto *out);

#endif
