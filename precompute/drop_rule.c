/* drop_rule.c: the stored operator's drop rule (drop_rule.h). */
#include <math.h>

#include "../common/basis.h"
#include "drop_rule.h"

int wrt_drop_depth(uint64_t fkey) {
    return wrt_fkey_stype(fkey) == 0 ? 0 : (int)wrt_fkey_snode(fkey).level + 1;
}

double wrt_drop_col_scale(const wrt_drop_rule *r, uint64_t fkey) {
    if (!r || r->sender == 0) return 1;
    return exp2(-r->sender * wrt_drop_depth(fkey));
}

double wrt_drop_col_scale_sized(const wrt_drop_rule *r, uint64_t fkey, double quad_side) {
    if (!r || r->sender == 0) return 1;
    double d = wrt_drop_depth(fkey);
    if (r->size_ref > 0 && quad_side > r->size_ref) d = fmax(0, d - log2(quad_side / r->size_ref));
    return exp2(-r->sender * d);
}

double wrt_drop_row_scale(const wrt_drop_rule *r, uint64_t fkey) {
    if (!r || r->receiver == 0) return 1;
    int d = wrt_drop_depth(fkey) - r->receiver_from;
    return d > 0 ? exp2(-r->receiver * d) : 1;
}
