/* drop_rule.h: which entries the stored operator keeps (issues 22 and 23). The series'
 * products drop an entry t of column s, row r below eps_compress, weighted by
 * sqrt(A_s / A_r) (series.c); the final compression of the stored operator may drop more,
 * by a rule that weighs an entry by the error it makes where it is seen:
 *   - the sender's depth d_s (0 for a quad's scaling function, node level + 1 for a
 *     spatial wavelet): a light's coefficient on a wavelet of depth d is typically 2^-d
 *     or less of the root's, so the entry's contribution |t| |x_s| is smaller by as much;
 *     the threshold grows as 2^(sender d_s);
 *   - the receiver's depth d_r: a receiver wavelet finer than the display's 8 x 8 cells
 *     a quad changes no cell average, only the interpolated image; the threshold grows as
 *     2^(receiver max(0, d_r - receiver_from)).
 * The scales multiply the series' weights (wrt_csc_weights: an entry is kept when its
 * largest channel x row_w x col_w reaches the threshold). Chosen by error per byte
 * against the path tracer with tools/codec_study (docs/bench.md, "Which entries are
 * stored"). Depends on common/basis.h only. */
#ifndef WRT_DROP_RULE_H
#define WRT_DROP_RULE_H

#include <stdint.h>

typedef struct wrt_drop_rule {
    double sender;     /* the threshold grows as 2^(sender x d_s); 0: as before */
    double receiver;   /* 2^(receiver x (d_r - receiver_from)) for d_r > receiver_from; 0: as before */
    int receiver_from; /* the receiver depth from which it grows */
    double size_ref;   /* > 0: the sender's depth counts only below supports of this side (the
                        * sender's support side sqrt(A_q) 2^-d: depth log2(size_ref / side),
                        * at most d, at least 0); 0: the depth d as it is */
} wrt_drop_rule;

/* The depth of a basis function (fkey of basis.h): 0 for a spatial scaling function,
 * node level + 1 for a spatial wavelet. */
int wrt_drop_depth(uint64_t fkey);
/* The factors by which the rule divides a column's (sender's) and a row's (receiver's)
 * weight: 1 for a rule of zeros. */
double wrt_drop_col_scale(const wrt_drop_rule *r, uint64_t fkey);
double wrt_drop_row_scale(const wrt_drop_rule *r, uint64_t fkey);
/* The column's factor for a sender on a quad of side quad_side (sqrt of its area): with
 * size_ref > 0, 2^-(sender x min(d, max(0, d + log2(size_ref / quad_side)))): a quad
 * larger than size_ref keeps more of its fine senders (a light near a large wall puts
 * much more than 2^-d of the wall's root coefficient on its fine wavelets); a smaller one
 * as wrt_drop_col_scale. */
double wrt_drop_col_scale_sized(const wrt_drop_rule *r, uint64_t fkey, double quad_side);

#endif
