/* series.c: the Global Transport Operator by a Neumann series (paper 4.4, primer 5).
 * S = T + T^2 + ... (= G - I, the indirect part the player needs), each term the previous
 * one times T, with non-linear compression (entries below eps_compress dropped) after
 * every product. The series stops when a term is empty after compression, when its norm
 * falls under 1e-6 of the sum, or when the ratio of successive norms has settled (the
 * dominant eigenvalue of T has taken over); the remaining tail is then added as the
 * geometric estimate P_n r / (1 - r), which matters at albedos near 1 (0.99 needs hundreds
 * of bounces otherwise). The gathered GTO T + T S (the fine DTO applied last) is computed
 * too, for its figures, and stored instead when asked. */
#include <math.h>
#include <string.h>

#include "../formats/gto.h"
#include "bake_internal.h"

wrt_status wrt_series_run(const bake_ctx *b, wrt_bake_result *res) {
    wrt_bake_counters *C = &res->c;
    const wrt_csc *T = &res->dto;
    double eps = b->opt.eps_compress;
    int threads = b->opt.threads;
    wrt_csc S = wrt_csc_copy(T), P = wrt_csc_copy(T);
    wrt_csc_compress(&P, eps);
    double pn_prev = wrt_csc_norm(&P), ratio = 0, ratio_prev = -1;
    int stable = 0;
    C->bounces = 1;
    while ((int)C->bounces < b->opt.max_bounces && P.nnz) {
        wrt_csc N = wrt_csc_mul(&P, T, eps, threads);
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
            wrt_csc_free(&P); wrt_csc_free(&S);
            return wrt_fail(WRT_ERR_CANCELLED, "bake cancelled");
        }
        if (C->energy_left < 1e-6) break;
        if (stable >= 3 && C->bounces >= 8) break;
    }
    C->series_ratio = ratio;
    /* Terms that keep growing (the ratio settled at or above 1, or still above 1 at the
     * cap) mean the discrete operator's dominant eigenvalue is >= 1: the sum so far is
     * a truncation of a divergent series, not an approximation of G - I. */
    if (P.nnz && ratio >= 1 && C->energy_left >= 1e-6) {
        double rmax = 0;
        for (int q = 0; q < b->nq; q++) rmax = fmax(rmax, fmax(b->rho[q][0], fmax(b->rho[q][1], b->rho[q][2])));
        wrt_csc_free(&P); wrt_csc_free(&S);
        return wrt_fail(WRT_ERR_ACCURACY,
                        "the light transport series diverges: each bounce multiplies the light by %.4f after %llu "
                        "bounces (largest albedo %.4f; the discretised transport gains energy: lower the albedo or "
                        "raise the quality)", ratio, (unsigned long long)C->bounces, rmax);
    }
    if (!b->opt.no_tail && P.nnz && ratio > 0 && ratio < 1) {
        double k = ratio / (1 - ratio);
        wrt_csc S2 = wrt_csc_add(&S, &P, k);
        double sn = wrt_csc_norm(&S2);
        C->tail_fraction = sn > 0 ? k * wrt_csc_norm(&P) / sn : 0;
        wrt_csc_free(&S);
        S = S2;
    }
    wrt_csc_free(&P);
    wrt_csc_compress(&S, eps);
    C->entries_gto = S.nnz;
    C->links_gto = wrt_count_links(&S, res->fkeys);
    /* gathered: T + T S */
    wrt_csc TS = wrt_csc_mul(T, &S, eps, threads);
    wrt_csc Gg = wrt_csc_add(&TS, T, 1.0);
    wrt_csc_free(&TS);
    C->entries_gathered = Gg.nnz;
    C->links_gathered = wrt_count_links(&Gg, res->fkeys);
    if (b->opt.gathered) {
        res->op = Gg;
        res->op_kind = WRT_GTO_OP_GATHERED;
        wrt_csc_free(&S);
    } else {
        res->op = S;
        res->op_kind = WRT_GTO_OP_INDIRECT;
        wrt_csc_free(&Gg);
    }
    return WRT_OK;
}
