/* gto_read.c: maps and validates a .gto file, the baked light transport operator (the
 * sparse gathered or indirect GTO of Kontkanen et al. 2006, section 4.4, with the quads,
 * materials, lights and camera the run-time of section 5 needs). The reader checks the
 * header and every section's place against the file length before it touches a byte of
 * payload (stage 1), then the counts that must agree across sections (stage 2), then
 * reads each payload byte once (stage 3: a section's checksum and its index checks run
 * together, chunk by chunk, gto_check.c). The only part of the .gto code in the runtime
 * library (with gto_check.c): no writer, no signal handlers. The layout is specified in
 * GTO_FORMAT.md and gto_layout.h. Depends on gto_layout.h, wrt_common and POSIX (mmap). */
#include "gto_layout.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdalign.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

/* ------------------------------------------------------------------------------------
 * Reader
 * ---------------------------------------------------------------------------------- */

/* A reader that copies a file (wrt_runtime_open_path's WRT_OPEN_PRIVATE) checks its first
 * bytes before allocating for all of them: a 20 GB sparse file, or a bake with 20 GB of
 * zeros appended, was read whole (20 GB resident, then the kernel's out-of-memory kill)
 * only to be refused as "bad magic" or "trailing data". Only a full header is judged;
 * the reader says what a shorter file lacks. */
wrt_status wrt_gto_check_head(const void *head, size_t n, uint64_t file_len) {
    gto_header h;
    if (n < sizeof h) return WRT_OK;
    memcpy(&h, head, sizeof h);
    if (memcmp(h.magic, GTO_MAGIC, GTO_MAGIC_LEN) != 0) return wrt_fail(WRT_ERR_NOT_OURS, "not a .gto file (bad magic)");
    if (h.byte_order != GTO_BOM) return WRT_OK;
    if (h.file_size > file_len)
        return wrt_fail(WRT_ERR_CORRUPT, "truncated: expected %" PRIu64 " bytes, found %" PRIu64, h.file_size, file_len);
    if (h.file_size < file_len)
        return wrt_fail(WRT_ERR_CORRUPT, "trailing data: expected %" PRIu64 " bytes, found %" PRIu64, h.file_size,
                        file_len);
    return WRT_OK;
}

/* Stage 1: the header and the section table, no payload byte read. */
wrt_status gto_parse_layout(const uint8_t *b, size_t len, gto_layout *L) {
    memset(L, 0, sizeof *L);
    if (len == 0) return wrt_fail(WRT_ERR_CORRUPT, "empty file (0 bytes)");
    size_t m = len < GTO_MAGIC_LEN ? len : GTO_MAGIC_LEN;
    if (memcmp(b, GTO_MAGIC, m) != 0) return wrt_fail(WRT_ERR_NOT_OURS, "not a .gto file (bad magic)");
    if (len < sizeof(gto_header))
        return wrt_fail(WRT_ERR_CORRUPT, "truncated: expected at least %zu bytes of header, found %zu",
                        sizeof(gto_header), len);
    memcpy(&L->h, b, sizeof L->h);
    const gto_header *h = &L->h;
    if (h->byte_order == GTO_BOM_SWAPPED)
        return wrt_fail(WRT_ERR_UNSUPPORTED, "big-endian file; this reader reads little-endian only");
    if (h->byte_order != GTO_BOM)
        return wrt_fail(WRT_ERR_CORRUPT, "bad byte-order mark 0x%08x", h->byte_order);
    if (h->version_major > WRT_GTO_VERSION_MAX)
        return wrt_fail(WRT_ERR_UNSUPPORTED,
                        "file version %u.%u is newer than this reader's version %d.%d",
                        h->version_major, h->version_minor, WRT_GTO_VERSION, WRT_GTO_VERSION_MINOR);
    if (h->version_major < WRT_GTO_VERSION_FLOAT)
        return wrt_fail(WRT_ERR_UNSUPPORTED,
                        "file version %u.%u is older than any this reader's version %d.%d reads (from %d.0)",
                        h->version_major, h->version_minor, WRT_GTO_VERSION, WRT_GTO_VERSION_MINOR,
                        WRT_GTO_VERSION_FLOAT);
    if (h->file_size > len)
        return wrt_fail(WRT_ERR_CORRUPT, "truncated: expected %" PRIu64 " bytes, found %zu",
                        h->file_size, len);
    if (h->file_size < len)
        return wrt_fail(WRT_ERR_CORRUPT, "trailing data: expected %" PRIu64 " bytes, found %zu",
                        h->file_size, len);
    if (h->nsections == 0 || h->nsections > GTO_MAX_SECTIONS)
        return wrt_fail(WRT_ERR_CORRUPT, "bad section count %u", h->nsections);
    if (h->header_size != sizeof(gto_header) + sizeof(gto_section) * h->nsections)
        return wrt_fail(WRT_ERR_CORRUPT, "header size %u does not match %u sections",
                        h->header_size, h->nsections);
    if (h->header_size > len)
        return wrt_fail(WRT_ERR_CORRUPT, "section table (%u bytes) beyond end of file (%zu bytes)",
                        h->header_size, len);
    {
        alignas(8) uint8_t buf[sizeof(gto_header) + sizeof(gto_section) * GTO_MAX_SECTIONS];
        memcpy(buf, b, h->header_size);
        memset(buf + offsetof(gto_header, header_checksum), 0, 8);
        uint64_t sum = wrt_gto_checksum(buf, h->header_size);
        if (sum != h->header_checksum)
            return wrt_fail(WRT_ERR_CORRUPT, "header checksum mismatch (stored 0x%016" PRIx64
                            ", computed 0x%016" PRIx64 ")", h->header_checksum, sum);
    }
    L->table = (const gto_section *)(b + sizeof(gto_header));
    if (h->op_kind > WRT_GTO_OP_GATHERED)
        return wrt_fail(WRT_ERR_UNSUPPORTED, "unknown operator kind %u", h->op_kind);
    uint64_t prev_end = h->header_size;
    uint32_t prev_id = 0;
    for (uint32_t i = 0; i < h->nsections; i++) {
        const gto_section *s = &L->table[i];
        const char *nm = gto_sec_name(s->id);
        if (s->id <= prev_id)
            return wrt_fail(WRT_ERR_CORRUPT, "section table entry %u (id %u, %s) out of order or repeated",
                            i, s->id, nm);
        prev_id = s->id;
        if (s->offset > len || s->size > len - s->offset)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: offset %" PRIu64 " + size %" PRIu64
                            " beyond end of file (%zu bytes)", nm, s->offset, s->size, len);
        if (s->offset % GTO_ALIGN)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: offset %" PRIu64 " not %u-byte aligned",
                            nm, s->offset, GTO_ALIGN);
        if (s->offset != gto_align_up(prev_end))
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: offset %" PRIu64 ", expected %" PRIu64
                            " (sections follow each other)", nm, s->offset, gto_align_up(prev_end));
        int crit_known = s->id == SEC_CTREE || s->id == SEC_KCODE || s->id == SEC_OPSTREAM || s->id == SEC_CSEND;
        if (s->id >= SEC_CRITICAL && !crit_known)
            return wrt_fail(WRT_ERR_UNSUPPORTED, "section id %u is critical (ids from %u on must be understood) "
                            "and unknown to this reader: it cannot read this file", s->id, SEC_CRITICAL);
        int needs = s->id == SEC_OPSTREAM ? 3 : 2;
        if (crit_known && h->version_major < needs)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s in a version %u.%u file (it needs version %d.0)", nm,
                            h->version_major, h->version_minor, needs);
        if ((gto_sec_known(s->id) || crit_known) && s->elem_size != gto_sec_elem(s->id))
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: element size %u, expected %u", nm,
                            s->elem_size, gto_sec_elem(s->id));
        if (s->elem_size == 0 || s->count > s->size / s->elem_size ||
            s->count * s->elem_size != s->size)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: size %" PRIu64 " is not %" PRIu64
                            " elements of %u bytes", nm, s->size, s->count, s->elem_size);
        if (gto_sec_known(s->id)) L->sec[s->id] = s;
        if (s->id == SEC_CTREE) L->ctree = s;
        if (s->id == SEC_KCODE) L->kcode = s;
        if (s->id == SEC_OPSTREAM) L->opstream = s;
        if (s->id == SEC_CSEND) L->csend = s;
        prev_end = s->offset + s->size;
    }
    if (prev_end != len)
        return wrt_fail(WRT_ERR_CORRUPT, "last section ends at %" PRIu64 ", file has %zu bytes",
                        prev_end, len);
    /* The operator's entries: as floats (rows and vals) or compact (opcode, 2.0), one of them. */
    if (L->sec[SEC_OPCODE] && h->version_major < 2)
        return wrt_fail(WRT_ERR_CORRUPT, "section opcode in a version %u.%u file (the compact operator is 2.0)",
                        h->version_major, h->version_minor);
    if (L->sec[SEC_OPCODE] && (L->sec[SEC_ROWS] || L->sec[SEC_VALS]))
        return wrt_fail(WRT_ERR_CORRUPT, "section opcode beside section %s (the entries are compact or "
                        "float, not both)", L->sec[SEC_ROWS] ? "rows" : "vals");
    /* Or as the compact stream (opstream, 3.0), which also stands for col_start. */
    if (L->opstream) {
        uint32_t beside = L->sec[SEC_OPCODE] ? SEC_OPCODE : L->sec[SEC_ROWS] ? SEC_ROWS : L->sec[SEC_VALS] ? SEC_VALS
                          : L->sec[SEC_COL_START] ? SEC_COL_START : 0;
        if (beside)
            return wrt_fail(WRT_ERR_CORRUPT, "section opstream beside section %s (it holds the operator's entries and "
                            "the columns' starts are rebuilt from it)", gto_sec_name(beside));
    }
    for (uint32_t id = 1; id <= SEC_REQUIRED; id++)
        if (!L->sec[id] && !((id == SEC_ROWS || id == SEC_VALS) && (L->sec[SEC_OPCODE] || L->opstream)) &&
            !(id == SEC_COL_START && L->opstream))
            return wrt_fail(WRT_ERR_CORRUPT, "missing section %s", gto_sec_name(id));
    /* The first-bounce operator: all four sections or none; or kkeys, kcol_start and kcode
     * (2.0, its entries compact). */
    if (L->kcode && (L->sec[SEC_KROWS] || L->sec[SEC_KVALS]))
        return wrt_fail(WRT_ERR_CORRUPT, "section kcode beside section %s (K's entries are compact or "
                        "float, not both)", L->sec[SEC_KROWS] ? "krows" : "kvals");
    if (L->kcode && (!L->sec[SEC_KKEYS] || !L->sec[SEC_KCOL_START]))
        return wrt_fail(WRT_ERR_CORRUPT, "missing section %s (section kcode comes with kkeys and kcol_start)",
                        L->sec[SEC_KKEYS] ? "kcol_start" : "kkeys");
    int nk = 0;
    for (uint32_t id = SEC_KKEYS; id <= SEC_KVALS; id++) nk += L->sec[id] != NULL;
    if (nk != 0 && nk != SEC_KVALS - SEC_KKEYS + 1 && !L->kcode)
        for (uint32_t id = SEC_KKEYS; id <= SEC_KVALS; id++)
            if (!L->sec[id])
                return wrt_fail(WRT_ERR_CORRUPT, "missing section %s (the first-bounce sections kkeys, "
                                "kcol_start, krows and kvals come all four or none)", gto_sec_name(id));
    return WRT_OK;
}

/* A compressed-column operator's four sections: one column start per key and one past
 * the end, one value per row entry (the operator's and K's). */
static wrt_status check_csc_counts(const gto_section *const *S, uint32_t keys, uint32_t col_start,
                                   uint32_t rows, uint32_t vals, const char *columns) {
    if (S[col_start]->count != S[keys]->count + 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " entries, expected %" PRIu64 " (%s + 1)",
                        gto_sec_name(col_start), S[col_start]->count, S[keys]->count + 1, columns);
    if (S[vals]->count != S[rows]->count)
        return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " entries, %s has %" PRIu64,
                        gto_sec_name(vals), S[vals]->count, gto_sec_name(rows), S[rows]->count);
    return WRT_OK;
}

/* A compact section's header (opcode, kcode, opstream: read here, checksummed in stage 3):
 * its counts must lay out exactly the section's size for ncols columns (size_of, the
 * section's layout; at least min_block bytes a block). A header whose counts do not fit
 * is reported as the checksum mismatch when the checksum is wrong: the damage it is. */
static wrt_status compact_head(const uint8_t *b, const gto_section *s, uint64_t ncols, uint64_t min_block,
                               uint64_t (*size_of)(uint32_t, uint64_t, uint64_t), gto_opcode_head *h) {
    const char *nm = gto_sec_name(s->id);
    if (s->size < sizeof(gto_opcode_head))
        return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " bytes, less than its %zu-byte header", nm, s->size,
                        sizeof(gto_opcode_head));
    memcpy(h, b + s->offset, sizeof *h);
    if (h->nnz > s->size || h->nblocks > s->size / min_block || h->nblocks > UINT32_MAX || ncols > UINT32_MAX - 1 ||
        size_of((uint32_t)ncols, h->nblocks, h->nnz) != s->size) {
        uint64_t computed = wrt_gto_checksum(b + s->offset, (size_t)s->size);
        if (computed != s->checksum)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: checksum mismatch (stored 0x%016" PRIx64
                            ", computed 0x%016" PRIx64 ")", nm, s->checksum, computed);
        return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " bytes do not hold the %" PRIu64 " blocks and %"
                        PRIu64 " entries its header says (with %" PRIu64 " columns)", nm, s->size, h->nblocks, h->nnz,
                        ncols);
    }
    return WRT_OK;
}
static uint64_t opcode_size(uint32_t nc, uint64_t nb, uint64_t nnz) { return gto_opcode_place(nc, nb, nnz).size; }
static uint64_t kcode_size(uint32_t nc, uint64_t nb, uint64_t nnz) { return gto_kcode_place(nc, nb, nnz).size; }
static uint64_t opstream_size(uint32_t nc, uint64_t nb, uint64_t nnz) { return gto_opstream_place(nc, nb, nnz).size; }

/* The compact operator's counts: its header (read here, checksummed in stage 3) says
 * how many blocks and entries, which must give the section's size exactly; fills g's
 * counts and pointers. */
static wrt_status check_opcode_counts(const uint8_t *b, const gto_section *const *S, wrt_gto *g) {
    const gto_section *s = S[SEC_OPCODE];
    if (S[SEC_COL_START]->count != S[SEC_FKEYS]->count + 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section col_start: %" PRIu64 " entries, expected %" PRIu64 " (functions + 1)",
                        S[SEC_COL_START]->count, S[SEC_FKEYS]->count + 1);
    gto_opcode_head h;
    uint64_t nf = S[SEC_FKEYS]->count;
    wrt_status st = compact_head(b, s, nf, 8, opcode_size, &h);
    if (st != WRT_OK) return st;
    gto_opcode_layout o = gto_opcode_place((uint32_t)nf, h.nblocks, h.nnz);
    const uint8_t *p = b + s->offset;
    g->nnz = h.nnz;
    g->nblocks = h.nblocks;
    g->op_bcol = (const uint32_t *)(p + o.bcol);
    g->op_codes = (const uint32_t *)(p + o.codes);
    g->op_deltas = p + o.deltas;
    return WRT_OK;
}

/* The reader's own arrays (g->owned): from the caller's allocator when it gave one. */
static void *gto_owned_alloc(const wrt_gto *g, size_t n) {
    return g->owned_alloc ? g->owned_alloc(g->owned_user, n) : malloc(n);
}
static void gto_owned_free(wrt_gto *g) {
    if (g->owned && g->owned_free) g->owned_free(g->owned_user, g->owned);
    else free(g->owned);
    g->owned = NULL;
}

/* The compact stream's counts (section opstream, 3.0): its header says how many blocks
 * and entries, which must give the section's size; fills g's counts and pointers, and
 * col_start with an array of its own (g->owned), filled when the section is checked. */
static wrt_status check_opstream_counts(const uint8_t *b, const gto_layout *L, wrt_gto *g) {
    const gto_section *s = L->opstream;
    gto_opcode_head h;
    uint64_t nf = L->sec[SEC_FKEYS]->count;
    wrt_status st = compact_head(b, s, nf, 5, opstream_size, &h);
    if (st != WRT_OK) return st;
    gto_opstream_layout o = gto_opstream_place((uint32_t)nf, h.nblocks, h.nnz);
    const uint8_t *p = b + s->offset;
    uint64_t *cs = gto_owned_alloc(g, ((size_t)nf + 1) * sizeof *cs);
    if (!cs) return wrt_fail(WRT_ERR_NOMEM, "no memory for the %" PRIu64 " columns' starts", nf + 1);
    memset(cs, 0, ((size_t)nf + 1) * sizeof *cs);
    g->owned = cs;
    g->col_start = cs;
    g->nnz = h.nnz;
    g->nblocks = h.nblocks;
    g->op_bcol = (const uint32_t *)(p + o.bcol);
    g->op_row0 = (const uint32_t *)(p + o.row0);
    g->op_base = (const int8_t *)(p + o.base);
    g->op_codes = (const uint32_t *)(p + o.codes);
    g->op_deltas = p + o.deltas;
    return WRT_OK;
}

/* A 2.0 file's blocks in the view both versions share (gto.h): each block's first row
 * and base copied out of its record (g->owned), once the file is known to be sound. */
static wrt_status opcode_view(const uint8_t *b, const gto_layout *L, wrt_gto *g) {
    gto_opcode_layout o = gto_opcode_place(g->nfuncs, g->nblocks, g->nnz);
    const wrt_gto_block *blk = (const wrt_gto_block *)(b + L->sec[SEC_OPCODE]->offset + o.blocks);
    uint32_t *row0 = gto_owned_alloc(g, g->nblocks ? 5 * (size_t)g->nblocks : 1);
    if (!row0) return wrt_fail(WRT_ERR_NOMEM, "no memory for the %" PRIu64 " blocks' rows", g->nblocks);
    int8_t *base = (int8_t *)(row0 + g->nblocks);
    for (uint64_t k = 0; k < g->nblocks; k++) { row0[k] = blk[k].row0; base[k] = (int8_t)blk[k].base; }
    g->owned = row0;
    g->op_row0 = row0;
    g->op_base = base;
    return WRT_OK;
}

/* The compact K's counts (section kcode): its header says how many blocks and entries,
 * which must give the section's size; fills g's K counts and pointers. */
static wrt_status check_kcode_counts(const uint8_t *b, const gto_layout *L, wrt_gto *g) {
    const gto_section *s = L->kcode, *const *S = L->sec;
    if (S[SEC_KCOL_START]->count != S[SEC_KKEYS]->count + 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section kcol_start: %" PRIu64 " entries, expected %" PRIu64
                        " (K's columns + 1)", S[SEC_KCOL_START]->count, S[SEC_KKEYS]->count + 1);
    gto_opcode_head h;
    uint64_t nk = S[SEC_KKEYS]->count;
    wrt_status st = compact_head(b, s, nk, 8, kcode_size, &h);
    if (st != WRT_OK) return st;
    gto_opcode_layout o = gto_kcode_place((uint32_t)nk, h.nblocks, h.nnz);
    const uint8_t *p = b + s->offset;
    g->knnz = h.nnz;
    g->knblocks = h.nblocks;
    g->k_bcol = (const uint32_t *)(p + o.bcol);
    g->k_blocks = (const wrt_gto_block *)(p + o.blocks);
    g->k_codes = (const uint16_t *)(p + o.codes);
    g->k_deltas = p + o.deltas;
    return WRT_OK;
}

/* Stage 2: counts that must agree across sections, and zero padding. */
wrt_status gto_check_counts(const uint8_t *b, const gto_layout *L, wrt_gto *g) {
    const gto_section *const *S = L->sec;
    static const uint32_t u32_counted[] = {SEC_QUADS, SEC_MATERIALS, SEC_LIGHTS, SEC_NAMES, SEC_FKEYS};
    for (size_t i = 0; i < sizeof u32_counted / sizeof *u32_counted; i++)
        if (S[u32_counted[i]]->count > UINT32_MAX - 1)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: %" PRIu64 " elements, too many",
                            gto_sec_name(u32_counted[i]), S[u32_counted[i]]->count);
    if (S[SEC_CAMERA]->count != 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section camera: %" PRIu64 " records, expected 1",
                        S[SEC_CAMERA]->count);
    if (S[SEC_STATS]->count != 1)
        return wrt_fail(WRT_ERR_CORRUPT, "section stats: %" PRIu64 " records, expected 1",
                        S[SEC_STATS]->count);
    wrt_status st = L->opstream ? WRT_OK : S[SEC_OPCODE] ? check_opcode_counts(b, S, g)
                                  : check_csc_counts(S, SEC_FKEYS, SEC_COL_START, SEC_ROWS, SEC_VALS, "functions");
    if (st != WRT_OK) return st;
    if (S[SEC_KKEYS]) { /* then all four (gto_parse_layout) */
        if (S[SEC_KKEYS]->count == 0)
            return wrt_fail(WRT_ERR_CORRUPT, "section kkeys: 0 columns (the first-bounce sections "
                            "are written only with a first-bounce operator)");
        if (S[SEC_KKEYS]->count > UINT32_MAX - 1)
            return wrt_fail(WRT_ERR_CORRUPT, "section kkeys: %" PRIu64 " elements, too many",
                            S[SEC_KKEYS]->count);
        st = L->kcode ? check_kcode_counts(b, L, g)
                      : check_csc_counts(S, SEC_KKEYS, SEC_KCOL_START, SEC_KROWS, SEC_KVALS, "K's columns");
        if (st != WRT_OK) return st;
    }
    if (S[SEC_SRCMAP] && S[SEC_SRCMAP]->count != S[SEC_QUADS]->count)
        return wrt_fail(WRT_ERR_CORRUPT, "section srcmap: %" PRIu64 " records, expected %" PRIu64 " (one per quad)",
                        S[SEC_SRCMAP]->count, S[SEC_QUADS]->count);
    if (S[SEC_NORMALS] && S[SEC_NORMALS]->count != S[SEC_QUADS]->count)
        return wrt_fail(WRT_ERR_CORRUPT, "section normals: %" PRIu64 " records, expected %" PRIu64 " (one per quad)",
                        S[SEC_NORMALS]->count, S[SEC_QUADS]->count);
    if (L->ctree && (S[SEC_QUADS]->count == 0 || L->ctree->count != 2 * S[SEC_QUADS]->count - 1))
        return wrt_fail(WRT_ERR_CORRUPT, "section ctree: %" PRIu64 " nodes, expected %" PRIu64 " (2 x quads - 1)",
                        L->ctree->count, S[SEC_QUADS]->count ? 2 * S[SEC_QUADS]->count - 1 : 0);
    if (L->csend && (!L->ctree || L->csend->count != 1))
        return wrt_fail(WRT_ERR_CORRUPT, "section csend: %s", !L->ctree ? "no section ctree (the senders' basis is its tree's)"
                                                                      : "not one u32");
    /* Every byte outside the sections is header, table or zero padding. */
    uint64_t prev_end = L->h.header_size;
    for (uint32_t i = 0; i < L->h.nsections; i++) {
        const gto_section *s = &L->table[i];
        for (uint64_t o = prev_end; o < s->offset; o++)
            if (b[o])
                return wrt_fail(WRT_ERR_CORRUPT, "non-zero padding byte at %" PRIu64 " before section %s",
                                o, gto_sec_name(s->id));
        prev_end = s->offset + s->size;
    }
    g->version = L->h.version_major;
    g->version_minor = L->h.version_minor;
    g->op_kind = L->h.op_kind;
    g->nquads = (uint32_t)S[SEC_QUADS]->count;
    g->nmaterials = (uint32_t)S[SEC_MATERIALS]->count;
    g->nlights = (uint32_t)S[SEC_LIGHTS]->count;
    g->nnames = (uint32_t)S[SEC_NAMES]->count;
    g->nfuncs = (uint32_t)S[SEC_FKEYS]->count;
    if (S[SEC_ROWS]) g->nnz = S[SEC_ROWS]->count;
#define SECPTR(id) ((const void *)(b + S[id]->offset))
    g->quads = SECPTR(SEC_QUADS);
    g->materials = SECPTR(SEC_MATERIALS);
    g->lights = SECPTR(SEC_LIGHTS);
    g->camera = SECPTR(SEC_CAMERA);
    g->names = SECPTR(SEC_NAMES);
    g->fkeys = SECPTR(SEC_FKEYS);
    if (!L->opstream) g->col_start = SECPTR(SEC_COL_START);
    if (S[SEC_ROWS]) { g->rows = SECPTR(SEC_ROWS); g->vals = SECPTR(SEC_VALS); }
    g->stats = SECPTR(SEC_STATS);
    g->provenance = SECPTR(SEC_PROVENANCE);
    g->provenance_len = (size_t)S[SEC_PROVENANCE]->size;
    if (S[SEC_KKEYS]) {
        g->nkcols = (uint32_t)S[SEC_KKEYS]->count;
        g->kkeys = SECPTR(SEC_KKEYS);
        g->kcol_start = SECPTR(SEC_KCOL_START);
        if (!L->kcode) {
            g->knnz = S[SEC_KROWS]->count;
            g->krows = SECPTR(SEC_KROWS);
            g->kvals = SECPTR(SEC_KVALS);
        }
    }
    if (S[SEC_SRCMAP]) g->srcmap = SECPTR(SEC_SRCMAP);
    if (S[SEC_NORMALS]) g->normals = SECPTR(SEC_NORMALS);
    if (S[SEC_TEXTURES]) {
        g->textures = SECPTR(SEC_TEXTURES);
        g->textures_size = S[SEC_TEXTURES]->size;
        st = gto_check_textures(g->textures, g->textures_size, g->nmaterials);
        if (st != WRT_OK) return st;
    }
    if (L->ctree) { g->ctree = (const void *)(b + L->ctree->offset); g->nctree = (uint32_t)L->ctree->count; }
    if (L->csend) {
        uint32_t v;
        memcpy(&v, b + L->csend->offset, 4);
        if (v != 1) return wrt_fail(WRT_ERR_CORRUPT, "section csend: value %u, expected 1", v);
        g->ctree_senders = 1;
    }
#undef SECPTR
    if (L->opstream) return check_opstream_counts(b, L, g); /* last: it allocates */
    return WRT_OK;
}

/* Stage 3: the single pass over the payload. */
wrt_status gto_check_payload(const uint8_t *b, const gto_layout *L, const wrt_gto *g) {
    vctx v;
    memset(&v, 0, sizeof v);
    v.g = g;
    if (L->opstream) v.col_out = g->owned; /* col_start, rebuilt by the section's check */
    for (uint32_t i = 0; i < L->h.nsections; i++) {
        const gto_section *s = &L->table[i];
        uint64_t sum = gto_scan_section(b + s->offset, s->count, s->elem_size, gto_sec_checker(s->id), &v);
        if (sum != s->checksum)
            return wrt_fail(WRT_ERR_CORRUPT, "section %s: checksum mismatch (stored 0x%016" PRIx64
                            ", computed 0x%016" PRIx64 ")", gto_sec_name(s->id), s->checksum, sum);
        if (v.bad) return wrt_fail(WRT_ERR_CORRUPT, "section %s: %s", gto_sec_name(s->id), v.err);
    }
    gto_check_quad_ranges(&v);
    if (v.bad) return wrt_fail(WRT_ERR_CORRUPT, "section quads: %s", v.err);
    if (g->ctree) return gto_check_ctree(g->ctree, g->nctree, g->nquads, WRT_ERR_CORRUPT, "section ctree");
    return WRT_OK;
}

static wrt_status validate(const uint8_t *b, size_t len, wrt_gto *out) {
    gto_layout L;
    wrt_status st = gto_parse_layout(b, len, &L);
    if (st == WRT_OK) st = gto_check_counts(b, &L, out);
    if (st == WRT_OK) st = gto_check_payload(b, &L, out);
    if (st == WRT_OK && L.sec[SEC_OPCODE]) st = opcode_view(b, &L, out);
    if (st != WRT_OK) gto_owned_free(out);
    return st;
}

/* The allocator kept in out across the memset that starts every open. */
static void keep_alloc(wrt_gto *out, void *(*alloc)(void *, size_t), void (*free_fn)(void *, void *), void *user) {
    memset(out, 0, sizeof *out);
    out->owned_alloc = alloc;
    out->owned_free = free_fn;
    out->owned_user = user;
}

wrt_status wrt_gto_open_memory_alloc(const void *data, size_t size, void *(*alloc)(void *, size_t),
                                     void (*free_fn)(void *, void *), void *user, wrt_gto *out) {
    keep_alloc(out, alloc, free_fn, user);
    if (!alloc != !free_fn) { memset(out, 0, sizeof *out); return wrt_fail(WRT_ERR_INVALID_ARG, "an allocator needs both alloc and free"); }
    if (!data && size) { memset(out, 0, sizeof *out); return wrt_fail(WRT_ERR_INVALID_ARG, "no data"); }
    if ((uintptr_t)data % 8) { memset(out, 0, sizeof *out); return wrt_fail(WRT_ERR_INVALID_ARG, ".gto image not 8-byte aligned"); }
    wrt_status st = validate(data, size, out);
    if (st != WRT_OK) { memset(out, 0, sizeof *out); return st; }
    out->map = (void *)data;
    out->size = size;
    out->owns_map = 0;
    return WRT_OK;
}

wrt_status wrt_gto_open_memory(const void *data, size_t size, wrt_gto *out) {
    return wrt_gto_open_memory_alloc(data, size, NULL, NULL, NULL, out);
}

/* Maps the whole of an open regular file read-only. *map is NULL for an empty file. */
wrt_status gto_map_fd(int fd, const char *path, void **map, size_t *len) {
    *map = NULL; *len = 0;
    struct stat st;
    if (fstat(fd, &st) != 0) return wrt_fail(WRT_ERR_IO, "%s: cannot stat: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode))
        return wrt_fail(WRT_ERR_NOT_OURS, "%s: not a regular file (%s)", path,
                        S_ISDIR(st.st_mode) ? "a directory" : S_ISFIFO(st.st_mode) ? "a FIFO"
                        : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "a device" : "a special file");
    if ((uint64_t)st.st_size > SIZE_MAX) return wrt_fail(WRT_ERR_IO, "%s: too large", path);
    *len = (size_t)st.st_size;
    if (*len) {
        void *p = mmap(NULL, *len, PROT_READ, MAP_PRIVATE | MAP_POPULATE, fd, 0);
        if (p == MAP_FAILED) return wrt_fail(WRT_ERR_IO, "%s: cannot map: %s", path, strerror(errno));
        *map = p;
    }
    return WRT_OK;
}

/* Maps a whole file read-only. O_NONBLOCK: a FIFO or device is refused by the fstat
 * that follows instead of blocking the open. */
wrt_status gto_map_file(const char *path, void **map, size_t *len) {
    *map = NULL; *len = 0;
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    if (fd < 0) return wrt_fail(WRT_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    wrt_status st = gto_map_fd(fd, path, map, len);
    close(fd);
    return st;
}

static wrt_status prefix_error(const char *path, wrt_status st) {
    char msg[1024];
    snprintf(msg, sizeof msg, "%s", wrt_last_error());
    return wrt_fail(st, "%s: %s", path, msg);
}

/* Validates a mapping of `len` bytes of `path` (NULL when the file is empty) and hands it
 * to `out`, which then owns it; on failure unmaps it and names the path in the error. */
wrt_status gto_adopt_map(void *map, size_t len, const char *path, wrt_gto *out) {
    static const uint64_t empty = 0;
    wrt_status st = validate(map ? map : (const void *)&empty, len, out);
    if (st != WRT_OK) {
        if (map) munmap(map, len);
        memset(out, 0, sizeof *out);
        return prefix_error(path, st);
    }
    out->map = map;
    out->size = len;
    out->owns_map = 1;
    return WRT_OK;
}

wrt_status wrt_gto_open_alloc(const char *path, void *(*alloc)(void *, size_t), void (*free_fn)(void *, void *),
                              void *user, wrt_gto *out) {
    keep_alloc(out, alloc, free_fn, user);
    if (!alloc != !free_fn) { memset(out, 0, sizeof *out); return wrt_fail(WRT_ERR_INVALID_ARG, "an allocator needs both alloc and free"); }
    void *map; size_t len;
    wrt_status st = gto_map_file(path, &map, &len);
    if (st != WRT_OK) { memset(out, 0, sizeof *out); return st; }
    return gto_adopt_map(map, len, path, out);
}

wrt_status wrt_gto_open(const char *path, wrt_gto *out) { return wrt_gto_open_alloc(path, NULL, NULL, NULL, out); }

void wrt_gto_close(wrt_gto *g) {
    if (!g) return;
    if (g->owns_map && g->map) munmap(g->map, g->size);
    gto_owned_free(g);
    memset(g, 0, sizeof *g);
}
