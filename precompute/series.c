/* series.c: the Global Transport Operator by a Neumann series (paper 4.4, primer 5).
 * S = T + T^2 + ... (= G - I, the indirect part the player needs), each term the previous
 * one times T, with non-linear compression (entries below eps_compress dropped) after
 * every product. The series stops when a term is empty after compression, when its norm
 * falls under 1e-6 of the sum, or when the ratio of successive norms has settled (the
 * dominant eigenvalue of T has taken over); the remaining tail is then added as the
 * geometric estimate P_n r / (1 - r), which matters at albedos near 1 (0.99 needs hundreds
 * of bounces otherwise). The gathered GTO T + T S (the fine DTO applied last) is computed
 * too, for its figures, and stored instead when asked.
 *
 * Compression weighs an entry (r, s) by sqrt(A_s / A_r), the areas of the quads of its
 * functions: an entry t moves t E_s into X_r, and coefficients scale as sqrt(area)
 * (basis.h: uniform E0 gives E0 sqrt(A/pi)), so t sqrt(A_s/A_r) is the entry's share of
 * the receiver's irradiance, a form factor. One threshold then means the same relative
 * accuracy on a 1 mm quad beside 1 km walls as on the walls, and does not change when
 * the scene is scaled. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../formats/gto.h"
#include "bake_internal.h"

wrt_status wrt_series_run(const bake_ctx *b, wrt_bake_result *res) {
    wrt_bake_counters *C = &res->c;
    const wrt_csc *T = &res->dto;
    double eps = b->opt.eps_compress;
    int threads = b->opt.threads;
    double *rw = wrt_xmalloc(((size_t)T->n + 1) * sizeof *rw), *cw = wrt_xmalloc(((size_t)T->n + 1) * sizeof *cw);
    for (uint32_t i = 0; i < T->n; i++) {
        double a = b->quads[wrt_fkey_quad(res->fkeys[i])].area;
        rw[i] = 1 / sqrt(a);
        cw[i] = sqrt(a);
    }
    wrt_csc_weights W = {rw, cw};
    wrt_csc S = wrt_csc_copy(T), P = wrt_csc_copy(T);
    wrt_csc_compress(&P, eps, &W);
    double pn_prev = wrt_csc_norm(&P), ratio = 0, ratio_prev = -1;
    int stable = 0;
    C->bounces = 1;
    while ((int)C->bounces < b->opt.max_bounces && P.nnz) {
        wrt_csc N = wrt_csc_mul(&P, T, eps, &W, threads);
        wrt_csc_free(&P);
        P = N;
        if (!P.nnz) break;
        C->bounces++;
        wrt_csc S2 = wrt_csc_add(&S, &P, 1.0);
        wrt_csc_free(&S);
        S = S2;
        double pn = wrt_csc_norm(&P), sn = wrt_csc_norm(&S);
        ratio = pn_prev > 0 ? pn / pn_prev : 0;
        pn_prev = pn;
        C->energy_left = sn > 0 ? pn / sn : 0;
        stable = (ratio_prev > 0 && fabs(ratio - ratio_prev) < 1e-4 * ratio) ? stable + 1 : 0;
        ratio_prev = ratio;
        if (b->opt.progress && !b->opt.progress("gto", fmin(1.0, C->bounces / 50.0), b->opt.progress_user)) {
            wrt_csc_free(&P); wrt_csc_free(&S); free(rw); free(cw);
            return wrt_fail(WRT_ERR_CANCELLED, "bake cancelled");
        }
        if (C->energy_left < 1e-6) break;
        if (stable >= 3 && C->bounces >= 8) break;
    }
    C->series_ratio = ratio;
    if (!b->opt.no_tail && P.nnz && ratio > 0 && ratio < 1) {
        double k = ratio / (1 - ratio);
        wrt_csc S2 = wrt_csc_add(&S, &P, k);
        double sn = wrt_csc_norm(&S2);
        C->tail_fraction = sn > 0 ? k * wrt_csc_norm(&P) / sn : 0;
        wrt_csc_free(&S);
        S = S2;
    }
    wrt_csc_free(&P);
    wrt_csc_compress(&S, eps, &W);
    C->entries_gto = S.nnz;
    C->links_gto = wrt_count_links(&S, res->fkeys);
    /* gathered: T + T S, computed when stored or when its figures are asked for */
    if (b->opt.gathered || b->opt.report_gathered) {
        wrt_csc TS = wrt_csc_mul(T, &S, eps, &W, threads);
        wrt_csc Gg = wrt_csc_add(&TS, T, 1.0);
        wrt_csc_free(&TS);
        C->entries_gathered = Gg.nnz;
        C->links_gathered = wrt_count_links(&Gg, res->fkeys);
        if (b->opt.gathered) {
            wrt_csc_free(&S);
            S = Gg;
        } else {
            wrt_csc_free(&Gg);
        }
    }
    res->op = S;
    res->op_kind = b->opt.gathered ? WRT_GTO_OP_GATHERED : WRT_GTO_OP_INDIRECT;
    free(rw); free(cw);
    return WRT_OK;
}
