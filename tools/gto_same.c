/* tools/gto_same.c A.gto B.gto: whether two .gto files hold the same decoded operator,
 * whatever their versions (1.x floats, 2.0 section opcode, 3.0 section opstream): the
 * same functions (every key), the same columns (col_start, stored or rebuilt), and
 * entry by entry the same row and the same value bits; K the same way (its keys,
 * column starts, rows and value bits); the scene's records (quads, materials, lights,
 * camera, names, source map, corner normals, textures, cluster tree) byte for byte.
 * The bake's statistics and provenance are not compared (their times differ between
 * bakes). Prints what it compared, or the first difference; exit 0 when the same, 1 when
 * not, 2 when a file cannot be read. The check of format 3.0's losslessness (GTO_FORMAT.md,
 * docs/bench.md "Format 3.0"). Not installed. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../formats/gto.h"

static int differ(const char *what) {
    printf("gto_same: differ: %s\n", what);
    return 1;
}

/* n records of size bytes at a and b (either may be NULL when n is 0). */
static int same_bytes(const void *a, const void *b, size_t n) { return n == 0 || (a && b && memcmp(a, b, n) == 0); }

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: gto_same A.gto B.gto\n");
        return 2;
    }
    wrt_gto a, b;
    if (wrt_gto_open(argv[1], &a) != WRT_OK) { fprintf(stderr, "gto_same: %s\n", wrt_last_error()); return 2; }
    if (wrt_gto_open(argv[2], &b) != WRT_OK) {
        fprintf(stderr, "gto_same: %s\n", wrt_last_error());
        wrt_gto_close(&a);
        return 2;
    }
    int bad = 0;
    char msg[256];
    if (a.nquads != b.nquads || a.nmaterials != b.nmaterials || a.nlights != b.nlights || a.nnames != b.nnames ||
        a.nfuncs != b.nfuncs || a.nnz != b.nnz || a.op_kind != b.op_kind || a.nkcols != b.nkcols || a.knnz != b.knnz)
        bad = differ("counts (quads, materials, lights, names, functions, entries, kind, K)");
    if (!bad) {
        static const char *names[] = {"quads", "materials", "lights", "camera", "names", "source map", "normals",
                                      "cluster tree", "textures"};
        const void *pa[] = {a.quads, a.materials, a.lights, a.camera, a.names, a.srcmap, a.normals, a.ctree, a.textures};
        const void *pb[] = {b.quads, b.materials, b.lights, b.camera, b.names, b.srcmap, b.normals, b.ctree, b.textures};
        size_t sz[] = {sizeof *a.quads * a.nquads, sizeof *a.materials * a.nmaterials, sizeof *a.lights * a.nlights,
                       sizeof *a.camera, 64 * (size_t)a.nnames, a.srcmap ? sizeof *a.srcmap * a.nquads : 0,
                       a.normals ? sizeof *a.normals * a.nquads : 0, sizeof *a.ctree * a.nctree, a.textures_size};
        for (int i = 0; i < 9 && !bad; i++) {
            int present = (pa[i] != NULL) == (pb[i] != NULL);
            if (i == 8) present &= a.textures_size == b.textures_size;
            if (i == 7) present &= a.nctree == b.nctree;
            if (!present || !same_bytes(pa[i], pb[i], sz[i])) {
                snprintf(msg, sizeof msg, "%s", names[i]);
                bad = differ(msg);
            }
        }
    }
    if (!bad && !same_bytes(a.fkeys, b.fkeys, 8 * (size_t)a.nfuncs)) bad = differ("fkeys");
    if (!bad && !same_bytes(a.col_start, b.col_start, 8 * ((size_t)a.nfuncs + 1))) bad = differ("col_start");
    for (uint32_t s = 0; s < a.nfuncs && !bad; s++) {
        wrt_gto_walk wa = wrt_gto_walk_at(&a, s), wb = wrt_gto_walk_at(&b, s);
        for (uint64_t e = a.col_start[s]; e < a.col_start[s + 1] && !bad; e++) {
            float va[3], vb[3];
            uint32_t ra = wrt_gto_entry(&a, &wa, e, va), rb = wrt_gto_entry(&b, &wb, e, vb);
            if (ra != rb || memcmp(va, vb, sizeof va) != 0) {
                snprintf(msg, sizeof msg, "entry %" PRIu64 " (column %u, key 0x%016" PRIx64 "): row %u (%g %g %g) against "
                         "row %u (%g %g %g)", e, s, a.fkeys[s], ra, va[0], va[1], va[2], rb, vb[0], vb[1], vb[2]);
                bad = differ(msg);
            }
        }
    }
    if (!bad && a.nkcols) {
        if (!same_bytes(a.kkeys, b.kkeys, 8 * (size_t)a.nkcols) ||
            !same_bytes(a.kcol_start, b.kcol_start, 8 * ((size_t)a.nkcols + 1)))
            bad = differ("K's keys or column starts");
        uint32_t *ra = malloc(4 * a.knnz + 4), *rb = malloc(4 * a.knnz + 4);
        float *va = malloc(4 * a.knnz + 4), *vb = malloc(4 * a.knnz + 4);
        if (!ra || !rb || !va || !vb) {
            fprintf(stderr, "gto_same: no memory for K's %" PRIu64 " entries\n", a.knnz);
            free(ra); free(rb); free(va); free(vb);
            wrt_gto_close(&a); wrt_gto_close(&b);
            return 2;
        }
        wrt_gto_k_entries(&a, ra, va);
        wrt_gto_k_entries(&b, rb, vb);
        if (!bad && (memcmp(ra, rb, 4 * a.knnz) != 0 || memcmp(va, vb, 4 * a.knnz) != 0)) bad = differ("K's entries");
        free(ra); free(rb); free(va); free(vb);
    }
    if (!bad)
        printf("gto_same: the same operator: %u functions, %" PRIu64 " entries (versions %u.%u and %u.%u; %zu and "
               "%zu bytes), K %" PRIu64 " entries, scene records identical\n", a.nfuncs, a.nnz, a.version,
               a.version_minor, b.version, b.version_minor, a.size, b.size, a.knnz);
    wrt_gto_close(&a);
    wrt_gto_close(&b);
    return bad;
}
