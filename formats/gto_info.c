/* gto_info.c: `wrt-bake --info FILE.gto`: prints what a .gto file holds (header,
 * section table, counts, figures of the operator and of the first-bounce operator K, the
 * bake's statistics, its provenance) and the result of the reader's integrity check,
 * timed; as text or as one JSON object, and as much as could be read when the file is
 * not sound. Not part of the runtime library. Depends on gto_layout.h and gto_read.c
 * (the three validation stages, run one by one so that each can be reported), basis.h
 * and wrt_common. */
#include "gto_layout.h"

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "../common/basis.h"
#include "../common/text.h"

/* ------------------------------------------------------------------------------------
 * Inspection
 * ---------------------------------------------------------------------------------- */

/* The first value of "key" in the provenance JSON, a string (unescaped quotes end it)
 * or a number, into out (empty if absent); printable ASCII only. */
static void prov_value(const char *p, size_t n, const char *key, char *out, size_t outn) {
    out[0] = 0;
    char pat[64];
    int pl = snprintf(pat, sizeof pat, "\"%s\":", key);
    if (pl <= 0 || (size_t)pl >= sizeof pat || !p) return;
    for (size_t i = 0; i + (size_t)pl < n; i++) {
        if (memcmp(p + i, pat, (size_t)pl)) continue;
        size_t j = i + (size_t)pl, o = 0;
        int str = j < n && p[j] == '"';
        if (str) j++;
        for (; j < n && o + 1 < outn; j++) {
            char c = p[j];
            if (str ? c == '"' : (c == ',' || c == '}' || c == ' ')) break;
            if (str && c == '\\' && j + 1 < n) c = p[++j];
            out[o++] = (c >= 0x20 && c < 0x7f) ? c : '?';
        }
        out[o] = 0;
        return;
    }
}

/* Minimal JSON syntax check (so --info --json can embed the provenance as is). */
static const char *js_ws(const char *p, const char *e) {
    while (p < e && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) p++;
    return p;
}
static const char *js_value(const char *p, const char *e, int depth);
static const char *js_string(const char *p, const char *e) {
    if (p >= e || *p != '"') return NULL;
    for (p++; p < e; p++) {
        unsigned char ch = (unsigned char)*p;
        if (ch == '"') return p + 1;
        if (ch < 0x20) return NULL;
        if (ch == '\\') {
            if (++p >= e) return NULL;
            if (*p == 'u') {
                for (int i = 0; i < 4; i++)
                    if (++p >= e || !strchr("0123456789abcdefABCDEF", *p) || !*p) return NULL;
            } else if (!strchr("\"\\/bfnrt", *p) || !*p) return NULL;
        }
    }
    return NULL;
}
static const char *js_value(const char *p, const char *e, int depth) {
    if (depth > 64) return NULL;
    p = js_ws(p, e);
    if (p >= e) return NULL;
    if (*p == '"') return js_string(p, e);
    if (*p == '{' || *p == '[') {
        char close = *p == '{' ? '}' : ']';
        int obj = *p == '{';
        p = js_ws(p + 1, e);
        if (p < e && *p == close) return p + 1;
        for (;;) {
            if (obj) {
                p = js_string(js_ws(p, e), e);
                if (!p) return NULL;
                p = js_ws(p, e);
                if (p >= e || *p != ':') return NULL;
                p++;
            }
            p = js_value(p, e, depth + 1);
            if (!p) return NULL;
            p = js_ws(p, e);
            if (p < e && *p == ',') { p++; continue; }
            if (p < e && *p == close) return p + 1;
            return NULL;
        }
    }
    static const char *const lits[] = {"true", "false", "null"};
    for (int i = 0; i < 3; i++) {
        size_t n = strlen(lits[i]);
        if ((size_t)(e - p) >= n && memcmp(p, lits[i], n) == 0) return p + n;
    }
    /* number: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)? */
    const char *q = p;
    if (q < e && *q == '-') q++;
    if (q >= e || *q < '0' || *q > '9') return NULL;
    if (*q == '0') q++;
    else while (q < e && *q >= '0' && *q <= '9') q++;
    if (q < e && *q == '.') {
        if (++q >= e || *q < '0' || *q > '9') return NULL;
        while (q < e && *q >= '0' && *q <= '9') q++;
    }
    if (q < e && (*q == 'e' || *q == 'E')) {
        q++;
        if (q < e && (*q == '+' || *q == '-')) q++;
        if (q >= e || *q < '0' || *q > '9') return NULL;
        while (q < e && *q >= '0' && *q <= '9') q++;
    }
    return q;
}

static int is_json_object(const char *s, size_t n) {
    const char *e = s + n, *p = js_ws(s, e);
    if (p >= e || *p != '{') return 0;
    p = js_value(p, e, 0);
    return p && js_ws(p, e) == e;
}

/* common/text.h's one JSON writer: escapes, and invalid UTF-8 from a forged file as U+FFFD */
static void put_jstr(FILE *f, const char *s, size_t n) { wrt_json_strn(f, s, n); }

/* "512 B", "3.4 kB", "12.5 MB", "1.20 GB". */
static const char *human_bytes(uint64_t n, char buf[32]) {
    if (n < 1000) snprintf(buf, 32, "%" PRIu64 " B", n);
    else if (n < 1000000) snprintf(buf, 32, "%.1f kB", n / 1e3);
    else if (n < 1000000000) snprintf(buf, 32, "%.1f MB", n / 1e6);
    else snprintf(buf, 32, "%.2f GB", n / 1e9);
    return buf;
}

static const char *op_kind_name(uint32_t k) {
    return k == WRT_GTO_OP_INDIRECT ? "indirect" : k == WRT_GTO_OP_GATHERED ? "gathered" : "unknown";
}

/* What --info knows of a file: how far the checks got, and the figures. */
typedef struct gto_info {
    const char *path;
    size_t len;
    wrt_status st;
    gto_layout L;
    wrt_gto g;
    int have_header, have_layout, ok;
    double dt, mbs;            /* the check's seconds and MB/s */
    char err[1024];
    /* the operator */
    uint32_t max_sl, max_al, max_fpq, max_col;
    uint64_t op_bytes, nangular;
    double density;
    /* the first-bounce operator K, if any */
    uint32_t k_quads, k_max_sl, k_max_al, k_max_col;
    uint64_t k_bytes;
    /* the quad-to-source map, if any */
    uint32_t src_twins, src_uv, src_tri;
} gto_info;

/* The three stages of the reader one by one, timed, keeping what each found. */
static void info_check(const uint8_t *b, gto_info *I) {
    I->have_header = I->len >= sizeof(gto_header) && memcmp(b, GTO_MAGIC, GTO_MAGIC_LEN) == 0;
    if (I->have_header) memcpy(&I->L.h, b, sizeof I->L.h);
    double t0 = wrt_now();
    I->st = gto_parse_layout(b, I->len, &I->L);
    I->have_layout = I->st == WRT_OK;
    if (I->st == WRT_OK) I->st = gto_check_counts(b, &I->L, &I->g);
    if (I->st == WRT_OK) I->st = gto_check_payload(b, &I->L, &I->g);
    I->dt = wrt_now() - t0;
    I->ok = I->st == WRT_OK;
}

/* Figures of the operator and of K, from a sound file. */
static void info_figures(gto_info *I) {
    const wrt_gto *g = &I->g;
    const gto_layout *L = &I->L;
    if (I->ok) {
        for (uint32_t q = 0; q < g->nquads; q++) {
            if (g->quads[q].slevel > I->max_sl) I->max_sl = g->quads[q].slevel;
            if (g->quads[q].alevel > I->max_al) I->max_al = g->quads[q].alevel;
            if (g->quads[q].func_count > I->max_fpq) I->max_fpq = g->quads[q].func_count;
        }
        for (uint32_t s = 0; s < g->nfuncs; s++) {
            uint64_t n = g->col_start[s + 1] - g->col_start[s];
            if (n > I->max_col) I->max_col = (uint32_t)n;
            if (!wrt_fkey_angular_root(g->fkeys[s])) I->nangular++;
        }
        I->op_bytes = L->sec[SEC_FKEYS]->size + (L->opstream ? L->opstream->size : L->sec[SEC_COL_START]->size +
                      (L->sec[SEC_OPCODE] ? L->sec[SEC_OPCODE]->size : L->sec[SEC_ROWS]->size + L->sec[SEC_VALS]->size));
    }
    I->density = g->nfuncs ? (double)g->nnz / ((double)g->nfuncs * g->nfuncs) : 0;
    if (I->ok && g->nkcols) {
        for (uint32_t j = 0; j < g->nkcols; j++) {
            if (j == 0 || wrt_fkey_quad(g->kkeys[j]) != wrt_fkey_quad(g->kkeys[j - 1])) I->k_quads++;
            uint32_t sl = wrt_fkey_snode(g->kkeys[j]).level, al = wrt_fkey_anode(g->kkeys[j]).level;
            if (sl > I->k_max_sl) I->k_max_sl = sl;
            if (al > I->k_max_al) I->k_max_al = al;
            uint64_t n = g->kcol_start[j + 1] - g->kcol_start[j];
            if (n > I->k_max_col) I->k_max_col = (uint32_t)n;
        }
        I->k_bytes = L->sec[SEC_KKEYS]->size + L->sec[SEC_KCOL_START]->size +
                     (L->kcode ? L->kcode->size : L->sec[SEC_KROWS]->size + L->sec[SEC_KVALS]->size);
    }
    if (I->ok && g->srcmap)
        for (uint32_t q = 0; q < g->nquads; q++) {
            I->src_twins += (g->srcmap[q].flags & WRT_GTO_SRC_TWIN) != 0;
            I->src_uv += (g->srcmap[q].flags & WRT_GTO_SRC_UV) != 0;
            I->src_tri += g->srcmap[q].kind == WRT_ELEM_TRIANGLE;
        }
}

/* The emissive materials (docs/emitters.md): each one's radiance, quads and area, and
 * what it costs a light change; as text lines or a JSON array. */
static void print_emitters(FILE *f, const wrt_gto *g, int json) {
    int n = 0;
    if (json) fputs(", \"emitters\": [", f);
    for (uint32_t m = 0; m < g->nmaterials; m++) {
        const float *e = g->materials[m].emissive;
        if (!(e[0] > 0 || e[1] > 0 || e[2] > 0)) continue;
        uint32_t nq = 0;
        double area = 0;
        for (uint32_t q = 0; q < g->nquads; q++)
            if (g->quads[q].material == m) { nq++; area += g->quads[q].area; }
        if (json)
            fprintf(f, "%s{\"material\": %u, \"emissive\": [%.9g, %.9g, %.9g], \"quads\": %u, \"area\": %.9g, "
                    "\"lambertian\": %s}", n ? ", " : "", m, e[0], e[1], e[2], nq, area,
                    g->materials[m].lambertian ? "true" : "false");
        else
            fprintf(f, "emitter:    material %u L_e (%g, %g, %g) on %u quad%s, %.4g m^2%s; cost: %u coefficient%s "
                    "added to E per change, no projection, no rays\n", m, e[0], e[1], e[2], nq, nq == 1 ? "" : "s",
                    area, g->materials[m].lambertian ? "" : " (glossy: lights no other surface)", nq, nq == 1 ? "" : "s");
        n++;
    }
    if (json) fputc(']', f);
    else if (!n) fputs("emitters:   none\n", f);
    uint32_t nt = wrt_gto_texture_count(g); /* base-colour textures (docs/textures.md) */
    if (json) fputs(", \"textures\": [", f);
    for (uint32_t i = 0; i < nt; i++) {
        wrt_gto_texture t;
        wrt_gto_texture_get(g, i, &t);
        if (json)
            fprintf(f, "%s{\"material\": %u, \"width\": %u, \"height\": %u, \"bytes\": %u}", i ? ", " : "",
                    t.material, t.w, t.h, 3 * t.w * t.h);
        else
            fprintf(f, "texture:    material %u base colour %u x %u, %u bytes; cost: four texel fetches a pixel "
                    "(the bake used it per element)\n", t.material, t.w, t.h, 3 * t.w * t.h);
    }
    if (json) fputc(']', f);
}

/* --info --json: the figures of a sound file (after the header and the sections). */
static void json_figures(FILE *f, const gto_info *I) {
    const wrt_gto *g = &I->g;
    const wrt_gto_stats *S = g->stats;
    fprintf(f, ", \"counts\": {\"quads\": %u, \"materials\": %u, \"lights\": %u, \"names\": %u, "
            "\"functions\": %u, \"entries\": %" PRIu64 ", \"k_columns\": %u, \"k_entries\": %" PRIu64 "}",
            g->nquads, g->nmaterials, g->nlights, g->nnames, g->nfuncs, g->nnz, g->nkcols, g->knnz);
    print_emitters(f, g, 1);
    fprintf(f, ", \"operator\": {\"compact\": %s, \"blocks\": %" PRIu64 ", \"bytes\": %" PRIu64 ", \"density\": %.6g, "
            "\"mean_entries_per_column\": %.3f, \"max_entries_per_column\": %u, "
            "\"max_functions_per_quad\": %u, \"angular_functions\": %" PRIu64 ", "
            "\"max_spatial_level\": %u, \"max_angular_level\": %u}",
            g->op_codes ? "true" : "false", g->nblocks, I->op_bytes, I->density,
            g->nfuncs ? (double)g->nnz / g->nfuncs : 0.0, I->max_col, I->max_fpq,
            I->nangular, I->max_sl, I->max_al);
    if (g->nkcols)
        fprintf(f, ", \"first_bounce\": {\"columns\": %u, \"entries\": %" PRIu64 ", \"bytes\": %" PRIu64
                ", \"glossy_quads\": %u, \"mean_entries_per_column\": %.3f, \"max_entries_per_column\": %u, "
                "\"max_spatial_level\": %u, \"max_angular_node_level\": %u}",
                g->nkcols, g->knnz, I->k_bytes, I->k_quads, (double)g->knnz / g->nkcols, I->k_max_col, I->k_max_sl,
                I->k_max_al);
    else
        fputs(", \"first_bounce\": null", f);
    if (g->srcmap)
        fprintf(f, ", \"source_map\": {\"twins\": %u, \"with_uv\": %u, \"triangle_quads\": %u}", I->src_twins,
                I->src_uv, I->src_tri);
    else
        fputs(", \"source_map\": null", f);
    fprintf(f, ", \"stats\": {\"t_dto\": %.6g, \"t_gto\": %.6g, \"t_write\": %.6g, \"t_total\": %.6g, "
            "\"links_dto\": %" PRIu64 ", \"links_gto\": %" PRIu64 ", \"links_gathered\": %" PRIu64 ", "
            "\"entries_dto\": %" PRIu64 ", \"entries_op\": %" PRIu64 ", \"rays_traced\": %" PRIu64 ", "
            "\"rays_skipped\": %" PRIu64 ", \"bounces\": %" PRIu64 ", \"energy_left\": %.6g}",
            S->t_dto, S->t_gto, S->t_write, S->t_total, S->links_dto, S->links_gto,
            S->links_gathered, S->entries_dto, S->entries_op, S->rays_traced, S->rays_skipped,
            S->bounces, S->energy_left);
    fputs(", \"provenance\": ", f);
    if (g->provenance_len == 0) fputs("null", f);
    else if (is_json_object(g->provenance, g->provenance_len)) fwrite(g->provenance, 1, g->provenance_len, f);
    else put_jstr(f, g->provenance, g->provenance_len);
    fprintf(f, ", \"check_seconds\": %.6f, \"check_mb_per_s\": %.1f", I->dt, I->mbs);
}

/* --info --json: one object. */
static void print_json(FILE *f, const gto_info *I) {
    const gto_layout *L = &I->L;
    fputs("{\"file\": ", f);
    put_jstr(f, I->path, strlen(I->path));
    fprintf(f, ", \"bytes\": %zu, \"ok\": %s, \"status\": \"%s\", \"error\": ", I->len,
            I->ok ? "true" : "false", wrt_status_str(I->st));
    put_jstr(f, I->err, strlen(I->err));
    if (I->have_header)
        fprintf(f, ", \"version\": \"%u.%u\", \"op_kind\": \"%s\", \"recorded_bytes\": %" PRIu64,
                L->h.version_major, L->h.version_minor, op_kind_name(L->h.op_kind), L->h.file_size);
    if (I->have_layout) {
        fputs(", \"sections\": [", f);
        for (uint32_t i = 0; i < L->h.nsections; i++) {
            const gto_section *s = &L->table[i];
            fprintf(f, "%s{\"id\": %u, \"name\": \"%s\", \"offset\": %" PRIu64 ", \"bytes\": %" PRIu64
                    ", \"count\": %" PRIu64 ", \"elem_size\": %u, \"checksum\": \"0x%016" PRIx64 "\"}",
                    i ? ", " : "", s->id, gto_sec_name(s->id), s->offset, s->size, s->count,
                    s->elem_size, s->checksum);
        }
        fputs("]", f);
    }
    if (I->ok) json_figures(f, I);
    fputs("}\n", f);
}

/* The text form's provenance line: its main facts (all of it with --json). */
static void text_provenance(FILE *f, const wrt_gto *g) {
    char tool[64], ver[32], src[512], hash[40], q[16];
    prov_value(g->provenance, g->provenance_len, "tool", tool, sizeof tool);
    prov_value(g->provenance, g->provenance_len, "version", ver, sizeof ver);
    prov_value(g->provenance, g->provenance_len, "source", src, sizeof src);
    prov_value(g->provenance, g->provenance_len, "source_hash", hash, sizeof hash);
    prov_value(g->provenance, g->provenance_len, "quality", q, sizeof q);
    if (tool[0] || src[0])
        fprintf(f, "provenance: %s %s from %s (hash %s), quality %s; --info --json shows all of it\n",
                tool[0] ? tool : "?", ver, src[0] ? src : "?", hash[0] ? hash : "?", q[0] ? q : "?");
    else /* not wrt-bake's: as written, up to 300 bytes */
        fprintf(f, "provenance: %.*s%s\n", g->provenance_len > 300 ? 300 : (int)g->provenance_len,
                g->provenance, g->provenance_len > 300 ? "..." : "");
}

/* --info as text: the figures of a sound file (after the header and the sections). */
static void text_figures(FILE *f, const gto_info *I) {
    const wrt_gto *g = &I->g;
    const wrt_gto_stats *S = g->stats;
    fprintf(f, "scene:      %u quads, %u materials, %u lights, %u names\n", g->nquads,
            g->nmaterials, g->nlights, g->nnames);
    print_emitters(f, g, 0);
    char hb[32];
    fprintf(f, "operator:   %u functions (%" PRIu64 " with angular detail), %" PRIu64
            " entries, %s, density %.3g\n", g->nfuncs, I->nangular, g->nnz, human_bytes(I->op_bytes, hb),
            I->density);
    if (g->op_codes)
        fprintf(f, "            compact entries: %" PRIu64 " blocks (mean %.1f entries), %.2f bytes an entry\n",
                g->nblocks, g->nblocks ? (double)g->nnz / g->nblocks : 0.0,
                g->nnz ? (double)(I->L.opstream ? I->L.opstream : I->L.sec[SEC_OPCODE])->size / g->nnz : 0.0);
    fprintf(f, "            entries per column: mean %.1f, max %u; functions per quad: max %u; "
            "deepest level: spatial %u, angular %u\n",
            g->nfuncs ? (double)g->nnz / g->nfuncs : 0.0, I->max_col, I->max_fpq, I->max_sl, I->max_al);
    if (g->nkcols)
        fprintf(f, "first bounce: K, %u columns on %u glossy quad%s, %" PRIu64 " entries, %s; entries "
                "per column: mean %.1f, max %u; deepest level: spatial %u, angular node %u\n",
                g->nkcols, I->k_quads, I->k_quads == 1 ? "" : "s", g->knnz, human_bytes(I->k_bytes, hb),
                (double)g->knnz / g->nkcols, I->k_max_col, I->k_max_sl, I->k_max_al);
    if (g->k_codes)
        fprintf(f, "            compact K: %" PRIu64 " blocks (mean %.1f entries), %.2f bytes an entry\n",
                g->knblocks, g->knblocks ? (double)g->knnz / g->knblocks : 0.0,
                g->knnz ? (double)I->L.kcode->size / g->knnz : 0.0);
    else if (!g->nkcols)
        fprintf(f, "first bounce: none (no K sections)\n");
    if (g->srcmap)
        fprintf(f, "source map: %u quads, %u double-sided twins, %u from triangles cut in three, %u with "
                "TEXCOORD_0\n", g->nquads, I->src_twins, I->src_tri, I->src_uv);
    else
        fprintf(f, "source map: none (no srcmap section)\n");
    /* only the times the bake recorded (only with --provenance-timings) */
    if (S->t_dto > 0 || S->t_gto > 0) {
        fprintf(f, "bake:       DTO %.2f s, GTO %.2f s", S->t_dto, S->t_gto);
        if (S->t_write > 0) fprintf(f, ", write %.2f s", S->t_write);
        if (S->t_total > 0) fprintf(f, ", total %.2f s", S->t_total);
        fputc('\n', f);
    } else {
        fprintf(f, "bake:       no timings stored (wrt-bake stores them only with --provenance-timings, so that equal\n"
                "            bakes give equal bytes)\n");
    }
    fprintf(f, "            links: DTO %" PRIu64 ", GTO %" PRIu64 ", gathered %" PRIu64
            "; entries: DTO %" PRIu64 ", operator %" PRIu64 "\n", S->links_dto, S->links_gto,
            S->links_gathered, S->entries_dto, S->entries_op);
    fprintf(f, "            rays: %" PRIu64 " traced, %" PRIu64 " skipped; bounces %" PRIu64
            "; energy left %.3g\n", S->rays_traced, S->rays_skipped, S->bounces, S->energy_left);
    text_provenance(f, g);
    fprintf(f, "integrity:  ok (checksums and indices verified: %s in %.2f ms, %.0f MB/s)\n",
            human_bytes(I->len, hb), I->dt * 1e3, I->mbs);
}

/* What a file's version means to this reader, in words ("current", or what the later
 * minors add), so that an older file does not read like a warning. */
static void version_note(char *b, size_t n, unsigned major, unsigned minor) {
    /* what each version added, in order: 1.1 .. 1.3, then 2.0 */
    static const struct { unsigned major, minor; const char *what; } added[] = {
        {1, 1, "the optional first-bounce operator"}, {1, 2, "the optional source map"},
        {1, 3, "the optional corner normals and textures"}, {2, 0, "the compact operator and critical sections"}};
    int nadded = (int)(sizeof added / sizeof added[0]);
    if (major == WRT_GTO_VERSION && minor == WRT_GTO_VERSION_MINOR) {
        snprintf(b, n, "current");
    } else if (major > WRT_GTO_VERSION || (major == WRT_GTO_VERSION && minor > WRT_GTO_VERSION_MINOR)) {
        snprintf(b, n, "newer than this reader's %d.%d%s", WRT_GTO_VERSION, WRT_GTO_VERSION_MINOR,
                 major == WRT_GTO_VERSION ? ": its added optional sections are skipped" : ", which reads only up to 2.x");
    } else if (major < WRT_GTO_VERSION_FLOAT) {
        snprintf(b, n, "older than any version this reader reads");
    } else {
        size_t k = (size_t)snprintf(b, n, "older, read in full: later versions add");
        int first = 1;
        for (int i = 0; i < nadded && k < n; i++) {
            if (added[i].major < major || (added[i].major == major && added[i].minor <= minor)) continue;
            k += (size_t)snprintf(b + k, n - k, "%s %u.%u %s", first ? "" : ",", added[i].major, added[i].minor,
                                  added[i].what);
            first = 0;
        }
    }
}

/* --info as text. */
static void print_text(FILE *f, const gto_info *I) {
    const gto_layout *L = &I->L;
    fprintf(f, "file:       %s (%zu bytes)\n", I->path, I->len);
    char note[256];
    if (I->have_header) version_note(note, sizeof note, L->h.version_major, L->h.version_minor);
    if (I->have_header)
        fprintf(f, "format:     .gto version %u.%u (%s), little-endian, operator %s\n",
                L->h.version_major, L->h.version_minor, note,
                L->h.op_kind == WRT_GTO_OP_INDIRECT ? "indirect (G - I)"
                : L->h.op_kind == WRT_GTO_OP_GATHERED ? "gathered (T_fine G)" : "unknown");
    if (I->have_layout) {
        fprintf(f, "sections:   %-11s %10s %12s %12s  %s\n", "name", "offset", "bytes", "count", "checksum");
        for (uint32_t i = 0; i < L->h.nsections; i++) {
            const gto_section *s = &L->table[i];
            fprintf(f, "            %-11s %10" PRIu64 " %12" PRIu64 " %12" PRIu64 "  %016" PRIx64 "\n",
                    gto_sec_name(s->id), s->offset, s->size, s->count, s->checksum);
        }
    }
    if (I->ok) text_figures(f, I);
    else fprintf(f, "integrity:  FAILED (%s): %s\n", wrt_status_str(I->st), I->err);
}

wrt_status wrt_gto_print_info(const char *path, int json, FILE *f) {
    gto_info I;
    memset(&I, 0, sizeof I);
    I.path = path;
    void *map;
    I.st = gto_map_file(path, &map, &I.len);
    int map_ok = I.st == WRT_OK;
    static const uint64_t empty = 0;
    const uint8_t *b = map ? map : (const uint8_t *)&empty;
    if (map_ok) info_check(b, &I);
    if (!I.ok) snprintf(I.err, sizeof I.err, "%s", wrt_last_error());
    I.mbs = I.dt > 0 ? (double)I.len / I.dt / 1e6 : 0;
    info_figures(&I);
    if (json) print_json(f, &I);
    else print_text(f, &I);
    if (map) munmap(map, I.len);
    free(I.g.owned);
    if (!I.ok && map_ok) wrt_fail(I.st, "%s: %s", path, I.err);
    return I.st;
}
