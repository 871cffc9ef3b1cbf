/* tools/op_kinds.c FILE.gto EPS_COMPRESS [EPS_FINAL [SMALL_SHARE]]: where a stored operator's
 * entries are (issue 22, docs/bench.md "The atrium's growth: where the entries are"). Reads
 * the operator and counts its entries by the sender's function (a quad's mean or a
 * wavelet), the receiver's (a mean or a wavelet), whether the sending quad is a small
 * sender (area under SMALL_SHARE x EPS_COMPRESS of the scene's, the bake's --small-share,
 * default 10) and whether the entry passes the final threshold without the small senders'
 * factor (the drop rule's default weights, drop_rule.h: sender 0.5, receiver 1 from depth 3,
 * size 0.05 of the scene's diagonal; those of a bake with other options differ). Prints one
 * JSON object. A file in the cluster tree's basis on both sides is refused (its root
 * slots are not the quads' means); one with it on the senders' side only (section csend)
 * has its root slots' columns counted as the tree's columns, by the receiver's kind
 * ("cluster_to_mean", "cluster_to_wavelet"). "by_depth" counts the entries by the sender's
 * depth (rows) and the receiver's (columns), drop_rule.h's depth: 0 for a quad's mean,
 * node level + 1 for a wavelet; a tree column (csend) counts as depth 0. Not installed. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "../common/basis.h"
#include "../formats/gto.h"
#include "../precompute/drop_rule.h"

/* counts[sender mean?][receiver mean?][small sender?][passes the plain threshold?] */
typedef struct { uint64_t n[2][2][2][2]; } kinds;

static double parse_pos(const char *s, const char *what) {
    char *end;
    double v = strtod(s, &end);
    if (*end || !(v > 0)) {
        fprintf(stderr, "op_kinds: %s must be a positive number, not '%s'\n", what, s);
        exit(2);
    }
    return v;
}

int main(int argc, char **argv) {
    if (argc < 3 || argc > 5) {
        fprintf(stderr, "usage: op_kinds FILE.gto EPS_COMPRESS [EPS_FINAL [SMALL_SHARE]]\n");
        return 2;
    }
    double eps = parse_pos(argv[2], "EPS_COMPRESS");
    double eps_final = argc > 3 ? parse_pos(argv[3], "EPS_FINAL") : eps;
    double share = argc > 4 ? parse_pos(argv[4], "SMALL_SHARE") : 10;
    wrt_gto g;
    if (wrt_gto_open(argv[1], &g) != WRT_OK) {
        fprintf(stderr, "op_kinds: %s: %s\n", argv[1], wrt_last_error());
        return 1;
    }
    if (g.ctree && !g.ctree_senders) {
        fprintf(stderr, "op_kinds: %s holds the operator in the cluster tree's basis\n", argv[1]);
        return 1;
    }
    double total = 0, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t q = 0; q < g.nquads; q++) {
        total += g.quads[q].area;
        for (int c = 0; c < 4; c++)
            for (int k = 0; k < 3; k++) {
                lo[k] = fmin(lo[k], g.quads[q].p[c][k]);
                hi[k] = fmax(hi[k], g.quads[q].p[c][k]);
            }
    }
    double diag = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    double small = share * eps * total;
    wrt_drop_rule r = {0.5, 1, 3, 0.05 * diag};
    double *rw = malloc(((size_t)g.nfuncs + 1) * sizeof *rw), *cw = malloc(((size_t)g.nfuncs + 1) * sizeof *cw);
    if (!rw || !cw) {
        fprintf(stderr, "op_kinds: out of memory\n");
        return 1;
    }
    for (uint32_t i = 0; i < g.nfuncs; i++) {
        double a = g.quads[wrt_fkey_quad(g.fkeys[i])].area;
        rw[i] = wrt_drop_row_scale(&r, g.fkeys[i]) / sqrt(a);
        cw[i] = wrt_drop_col_scale_sized(&r, g.fkeys[i], sqrt(a)) * sqrt(a);
    }
    kinds k = {0};
    uint64_t kc[2] = {0, 0}; /* the tree's columns (senders only), by the receiver's kind */
    uint64_t small_quads = 0;
    enum { ND = 12 }; /* depths 0..11: spatial levels up to 10 */
    uint64_t (*bd)[ND] = calloc(ND, sizeof *bd);
    if (!bd) {
        fprintf(stderr, "op_kinds: out of memory\n");
        return 1;
    }
    int dmax = 0;
    for (uint32_t q = 0; q < g.nquads; q++) small_quads += g.quads[q].area < small;
    for (uint32_t s = 0; s < g.nfuncs; s++) {
        int smean = wrt_fkey_stype(g.fkeys[s]) == 0;
        int ssmall = g.quads[wrt_fkey_quad(g.fkeys[s])].area < small;
        uint64_t e = g.col_start[s], end = g.col_start[s + 1];
        wrt_gto_walk wk = wrt_gto_walk_at(&g, s);
        for (; e < end; e++) {
            float v[3];
            uint32_t row = wrt_gto_entry(&g, &wk, e, v);
            double m = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
            int rmean = wrt_fkey_stype(g.fkeys[row]) == 0;
            int ds = g.ctree_senders && smean ? 0 : wrt_drop_depth(g.fkeys[s]), dr = wrt_drop_depth(g.fkeys[row]);
            ds = ds < ND ? ds : ND - 1;
            dr = dr < ND ? dr : ND - 1;
            bd[ds][dr]++;
            dmax = ds > dmax ? ds : dr > dmax ? dr : dmax;
            if (g.ctree_senders && smean) {
                kc[rmean]++;
                continue;
            }
            int plain = m * cw[s] * rw[row] >= eps_final;
            k.n[smean][rmean][ssmall][plain]++;
        }
    }
    static const char *fn[2] = {"wavelet", "mean"};
    printf("{\"file\": \"%s\", \"quads\": %u, \"small_quads\": %llu, \"functions\": %u, \"entries\": %llu",
           argv[1], g.nquads, (unsigned long long)small_quads, g.nfuncs, (unsigned long long)g.nnz);
    for (int sm = 1; sm >= 0; sm--)
        for (int rm = 1; rm >= 0; rm--)
            for (int sq = 1; sq >= 0; sq--)
                for (int p = 1; p >= 0; p--)
                    printf(",\n \"%s_to_%s_%s_%s\": %llu", fn[sm], fn[rm], sq ? "small" : "large",
                           p ? "plain" : "held", (unsigned long long)k.n[sm][rm][sq][p]);
    if (g.ctree_senders)
        printf(",\n \"cluster_to_mean\": %llu,\n \"cluster_to_wavelet\": %llu", (unsigned long long)kc[1],
               (unsigned long long)kc[0]);
    printf(",\n \"by_depth\": [");
    for (int a = 0; a <= dmax; a++) {
        printf("%s[", a ? ",\n  " : "");
        for (int b = 0; b <= dmax; b++) printf("%s%llu", b ? ", " : "", (unsigned long long)bd[a][b]);
        printf("]");
    }
    printf("]}\n");
    free(bd);
    free(rw); free(cw);
    return 0;
}
