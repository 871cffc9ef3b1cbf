/* bake.h: wrt-bake's computation as a library: the Direct Transport Operator by
 * hierarchical refinement in the 4D Haar basis (paper 4.3; dto.c), then the Global
 * Transport Operator by a Neumann series with non-linear compression (paper 4.4;
 * series.c). The command line (main.c) only parses options, draws progress and writes
 * the file. Depends on formats/scene.h, common/basis.h, common/brdf.h, Embree 3. */
#ifndef WRT_BAKE_H
#define WRT_BAKE_H

#include "../formats/scene.h"
#include "sparse.h"
#include "budget.h" /* the memory budget, which main.c reports */
#include "links.h"  /* wrt_fkey_find, wrt_count_links */
#include "../common/cluster_tree.h"

/* Progress: phase name ("dto", "balance", "gto") and fraction done, or < 0 when no
 * fraction is known; return 0 to cancel. */
typedef int (*wrt_progress_fn)(const char *phase, double done, void *user);

/* Zero means "default" for every field; wrt_bake_defaults() shows the defaults. */
typedef struct wrt_bake_options {
    int quality;           /* 1 (coarse, fast) .. 9 (fine, slow); sets the thresholds below */
    double eps_sender;     /* refine the sender when the kernel's variation over it exceeds this */
    double eps_receiver;   /* same for the receiver */
    double eps_receiver_coarse; /* the receiver's threshold for cells coarser than the display
                                 * keeps (levels < WRT_RECON_KEEP; default: eps_receiver,
                                 * finer from quality 5 on: wrt_bake_defaults) */
    double eps_compress;   /* drop operator entries below this (max over RGB) after each product */
    double eps_final;      /* the same once, on the operator that is stored (default: eps_compress;
                            * docs/bench.md "Thresholds by error per byte") */
    double drop_sender;    /* the final compression's threshold grows as 2^(drop_sender x the
                            * sender's depth) (drop_rule.h; 0: the default 0.5; negative: none,
                            * the uniform threshold of before) */
    double drop_receiver;  /* and as 2^(drop_receiver x the receiver's depth past drop_receiver_from)
                            * (0: the default 1; negative: none) */
    int drop_receiver_from;/* 0: the default 3 (finer than the display's 8 x 8 cells); negative: 0 */
    double drop_sender_size; /* > 0: the sender's depth counts from supports of this fraction of
                            * the scene's diagonal down (drop_rule.h size_ref; quads larger keep
                            * more of their fine senders); 0: the default 0.05; negative: none */
    int max_slevel;        /* deepest spatial level of refinement (cells 2^-l of a quad) */
    int min_slevel;        /* refine every link at least to this level (default 0) */
    int max_alevel;        /* cap on the angular level of glossy materials (1..3) */
    int glossy_quality;    /* the quality whose eps_receiver, eps_sender and max_slevel refine the
                            * links that touch a glossy quad (default: see wrt_bake_defaults) */
    double eps_receiver_glossy, eps_sender_glossy; /* resolved from glossy_quality */
    int max_slevel_glossy;
    int receiver_samples;  /* receiver samples per link, a multiple of 4 (default 16) */
    int threads;           /* 0 = all cores */
    int gathered;          /* 1: store T_fine G instead of G - I */
    int report_gathered;   /* 1: compute the gathered GTO's figures even when not stored */
    int dto_only;          /* 1: stop after the DTO (res->op stays empty): for tests */
    int consume_dto;       /* 1: the series may take T's arrays for its sum once what it needs of T
                            * is computed (res->dto empty after the bake; wrt-bake sets it:
                            * series.c, series_consume) */
    long long series_block; /* with consume_dto: the series' sum is held in scratch files between
                            * bounces and merged with each term by blocks of this many entries
                            * (series_stream.h; 0: WRT_SERIES_BLOCK_DEFAULT); < 0: held in
                            * memory, as before. The same bytes either way */
    int max_bounces;       /* cap on the Neumann series (default 2000) */
    int no_tail;           /* 1: do not add the geometric estimate of the series' tail */
    double series_right;   /* bounces from series_right_from on multiply by T compressed at
                            * series_right x eps_compress (power kept) instead of the full T
                            * (series.c); 0: the default, 1; < 0: the full T */
    int series_right_from; /* the first bounce that does (2 or more; default 2) */
    double series_skip;    /* the series' products: a single contribution under series_skip
                            * x eps_compress (weighted as the compression's test) is not
                            * summed; the factored tree series (--clusters) keeps its power
                            * (sparse.h wrt_csc_bands), the plain series skips only those that
                            * carry none (sparse.c mul_order); 0: the default,
                            * WRT_SERIES_SKIP_DEFAULT; < 0: off */
    int series_columns;    /* the factored tree series in one process (--clusters): this many
                            * blocks of columns, each taken through every bounce and stored
                            * before the next starts (series_cols.c); 0: the default,
                            * WRT_SERIES_COLUMNS_DEFAULT; < 0: off (the terms whole) */
    int no_balance;        /* 1: keep T's root rows as the links integrate them (no power balance) */
    double max_memory_mb;  /* memory budget; default half the physical memory (wrt_bake_memory_default) */
    int first_bounce_level; /* outgoing angular level of the first-bounce operator K of glossy
                             * materials (1..3; dto.c); 0: default (the material's angular
                             * need, at most 3); -1: no K (the direct light reflected by a glossy
                             * quad enters the operator through its incident angular cells) */
    int clusters;          /* 1: the cluster hierarchy (cluster.h, docs/clusters.md) */
    double cluster_sep;    /* its separation threshold (0: WRT_CLUSTER_SEP_DEFAULT) */
    double cluster_spread; /* its oracle's spread threshold (0: WRT_CLUSTER_SPREAD_DEFAULT) */
    double cluster_eps;    /* its power criterion (0: WRT_CLUSTER_EPS_DEFAULT; < 0: off) */
    int cluster_albedo_split; /* 1: the cluster tree splits a node of several albedos by albedo
                               * before orientation and position (cluster.c) */
    int cluster_keep_away; /* 1: the oracle refines a pair whose facing rays are all blocked
                            * and some point faces away, as before session 14 (by default it
                            * drops it under the kernel's bound: cluster_link.c) */
    int cluster_senders;   /* with --clusters: 0 (the default): the stored operator's columns
                            * in the tree's basis (the senders' side only, where the small
                            * senders' light is held once per cluster: cluster_send.c) when
                            * it has fewer entries there; 1: always; -1: the quads' basis */
    int cluster_receivers; /* with --clusters and the series in the senders' tree basis: 0
                            * (the default): the stored operator's rows taken to the tree's
                            * basis too, kept where it has fewer entries there (series_tree.c
                            * wrt_series_receivers); 2: kept always; -1: not tried */
    int cluster_series;    /* with --clusters and the senders' tree basis: 1: the series' terms
                            * held in that basis from the first on and multiplied from the
                            * left, P_{k+1} = T P_k (series.c "The series in the senders'
                            * tree basis"); 0: the default (on, where the senders' tree basis
                            * is stored and the operator is not gathered); -1: off, the terms
                            * in the quads' basis (the stored columns then chosen by size) */
    int cluster_factored;  /* with the series in the senders' tree basis: 0 (the default),
                            * 1: its products' left factor T kept as T = E1 U, the cluster
                            * links' senders not pushed down (series_tree.c); -1: off, T
                            * with the links pushed down; 2: on, with E1 kept in the result
                            * (dto_e1; tests); 3: that with T formed too and read by the
                            * series' first term, power iteration and power rule, as before
                            * T was left unformed (series_first.c; tests) */
    int cluster_tree;      /* 1: store the operator in the tree's basis when it has fewer entries
                            * there (a trial: a copy and a transform of G - I); 2: always */
    double series_coarse;  /* the series' right factor from the second term on keeps only the
                            * rows of spatial functions whose support is at least this share
                            * of the scene's area (a quad's scaling function always): the light
                            * between bounces is carried on a coarser cut, its power exact
                            * (series.c); 0: the default (off; with --clusters
                            * WRT_SERIES_COARSE_CLUSTERS); < 0: off */
    double small_share;    /* a sender whose quad holds less than small_share x eps_compress of
                            * the scene's area has its compression threshold (products and
                            * final) scaled by its share / (small_share x eps_compress): an entry is then weighed as a kernel
                            * (form factor per sender area), so a closed scene of N small
                            * elements, whose entries are each about rho / N, keeps its
                            * multi-bounce light at any N (series.c); 0: the default 10; < 0: off.
                            * Only a quad's scaling function (its mean) is such a sender, and
                            * only its entries at rows that carry power are held so */
    double small_lost;     /* the small senders' rule applies to a column only where the plain
                            * threshold would drop more than this share of the column's power
                            * (series.c series_small_area); 0: the default
                            * WRT_SMALL_LOST_DEFAULT; < 0: whenever the sender is small */
    double depth_share;    /* the oracle's share rule (dto.c refine()): a quad holding less than
                            * depth_share of the scene's area has the kernel's spreads over its
                            * cells weighted by sqrt(its share / depth_share), so small
                            * elements' pairs stop refining at cells of an absolute size;
                            * 0: the default WRT_DEPTH_SHARE_DEFAULT; < 0: off */
    wrt_progress_fn progress;
    void *progress_user;
    /* NULL: one process. wrt-bake-mpi: the ranks and their all-gather (dist.h); the DTO's
     * pairs and the series' products are divided among them, the result the same bytes */
    struct wrt_bake_dist *dist;
} wrt_bake_options;

/* the default depth_share (docs/bench.md "The oracle's depth by the scene's share") */
#define WRT_DEPTH_SHARE_DEFAULT 1e-3

/* the default small_lost: a small sender's column keeps the plain threshold where that
 * drops at most 5% of its power (docs/algorithm.md "Small senders") */
#define WRT_SMALL_LOST_DEFAULT 0.05

/* The products' skipped contributions' default share of the threshold (docs/clusters.md
 * "Contributions under the threshold not summed") */
#define WRT_SERIES_SKIP_DEFAULT (1.0 / 64)
#define WRT_SERIES_COLUMNS_DEFAULT 16
/* --clusters' default series_coarse (docs/clusters.md "The series on a coarser cut") */
#define WRT_SERIES_COARSE_CLUSTERS 1e-3

/* Resolves the zero fields of *o from o->quality (or the default quality 5). */
void wrt_bake_defaults(wrt_bake_options *o);

/* What the bake simulated and what it skipped. */
typedef struct wrt_bake_counters {
    uint64_t pairs_total;          /* ordered pairs of distinct quads */
    uint64_t pairs_exchange;       /* pairs that can exchange light */
    uint64_t pairs_skipped_facing; /* back-facing, coplanar or outside each other's hemisphere */
    uint64_t pairs_unoccluded;     /* exchanging pairs with no possible occluder: no rays */
    uint64_t links_refined;        /* links the oracle split */
    uint64_t links_leaf;           /* links integrated */
    uint64_t links_invisible;      /* leaves found mutually invisible */
    uint64_t links_dto;            /* links holding entries after analysis */
    uint64_t links_dto_diffuse, links_dto_glossy;
    uint64_t entries_dto;          /* stored RGB entries of T */
    uint64_t entries_spatial;      /* entries whose both angular factors are roots */
    uint64_t entries_angular;      /* entries with an angular wavelet on either side */
    uint64_t rays_traced;
    uint64_t rays_skipped_unoccluded; /* visibility known: no occluder can lie between */
    uint64_t rays_skipped_facing;     /* sample pair back-facing: no transfer */
    uint64_t samples;                 /* kernel samples (receiver point x sender cell) */
    uint64_t bounces;              /* terms of the series computed */
    uint64_t sum_kept, sum_written; /* streamed: terms added to the sum's overlay, and by
                                     * rewriting its file (series_stream.h) */
    uint64_t sum_held;             /* in memory: the sum's entries before the stored
                                    * compression (by shares, this rank's columns') */
    double energy_left;            /* norm of the last term kept / norm of the sum */
    double tail_fraction;          /* norm of the tail estimate added / norm of the sum */
    double series_ratio;           /* norm(T^n) / norm(T^(n-1)) at the stop */
    uint64_t links_gto, entries_gto;
    uint64_t links_gathered, entries_gathered;
    uint32_t nfuncs, nfuncs_angular;
    uint64_t balance_entries;      /* root entries the power balance set (balance.c) */
    int closed;                    /* the balance found the scene closed (no ray escapes) */
    double t_dto, t_gto;           /* seconds (t_dto includes t_balance) */
    double t_balance;
    /* The phases as the progress lines and the summaries name them (main.c): dto =
     * t_dto - t_balance_phase, balance = t_balance_phase (the balance and the operator's
     * assembly after it: from the "balance" progress call to the end of t_dto), series =
     * t_gto. t_balance_begin: wrt_now() at that call (0: no balance). */
    double t_balance_phase, t_balance_begin;
    int open_quad;                 /* an open scene: the first quad with a ray that met no surface (-1: closed) */
    double t_rays;                 /* thread-seconds spent in visibility rays (WRT_DTO_TIMES; else 0) */
    double mem_estimate_mb;        /* the largest memory need the bake estimated before allocating */
    uint64_t entries_k, links_k;   /* the first-bounce operator K: entries and links */
    uint32_t nkcols;               /* its columns (outgoing functions of glossy quads) */
    /* --clusters: links between clusters (one entry pair each), leaf pairs handed to the
     * DTO, node pairs visited, oracle calls and their rays, entries the closed-scene rule
     * added, the tree's depth */
    uint64_t cluster_links, cluster_leaf_pairs, cluster_visits, cluster_oracle, cluster_rays, cluster_fix_entries;
    uint64_t cluster_tree_entries;  /* G - I's entries in the tree basis before its compression */
    uint64_t cluster_tree_compressed; /* and after */
    int cluster_tree_basis;
    int cluster_senders_basis;      /* 1: the columns in the tree's basis (res->ctree set) */
    uint64_t cluster_receivers_raw, cluster_receivers_entries; /* the rows in the tree's basis too:
                                    * before and after the compression (0: not tried) */
    int t_unformed;                /* --clusters, factored: T never formed, only E1 (res->dto empty;
                                    * series_first.c); not in the JSON, which the file records */
    uint64_t cluster_factored_entries; /* the products' left factor E1's entries (T = E1 U;
                                        * 0: T itself, pushed down) */
    uint32_t cluster_apart_nodes;   /* the tree's nodes whose columns the series' products keep
                                     * finer (series_tree.c, wrt_clusters_apart) */
    uint64_t cluster_senders_raw;   /* the tree columns' entries before their compression */
    uint64_t cluster_senders_quads; /* G - I's entries in the quads' basis, before */
    uint64_t cluster_refused_visibility, cluster_refused_spread; /* the oracle's refusals */         /* 1: the operator is stored in the tree's basis (res->ctree set) */
    uint64_t cluster_partial;      /* cluster links with some of their rays blocked */
    uint32_t cluster_depth;
} wrt_bake_counters;

typedef struct wrt_bake_result {
    uint32_t nfuncs;
    uint64_t *fkeys;       /* sorted basis function keys; index = matrix row/column */
    wrt_csc dto;           /* T (empty where c.t_unformed: --clusters' factored series, the DTO
                            * then held as E1 U only; dto_only keeps T) */
    wrt_csc dto_e1;        /* --clusters factored: T's left factor E1 (T = E1 U, cluster.h) */
    wrt_csc op;            /* what is stored: G - I, or T G if gathered */
    int op_kind;           /* WRT_GTO_OP_* */
    uint8_t *material_alevel;
    /* The first-bounce operator K (dto.c; nkcols 0: none): rows index fkeys, columns kkeys
     * (sorted outgoing functions of glossy quads), one value per entry. */
    uint32_t nkcols;
    uint64_t *kkeys, *kcol_start, knnz;
    uint32_t *krows;
    float *kvals;
    /* --clusters: the tree whose basis the quads' root slots hold (nq 0: none) */
    wrt_ctree ctree;
    wrt_bake_counters c;
} wrt_bake_result;

/* Runs the bake. The scene is not modified. On failure (cancel) returns a status and
 * leaves *res empty. */
wrt_status wrt_bake_run(const wrt_scene *scene, const wrt_bake_options *opt, wrt_bake_result *res);
void wrt_bake_result_free(wrt_bake_result *res);

/* Unoccluded form factor from a point x with unit normal n to a planar polygon
 * (vertices in order), clipped to the half-space in front of x: 
 * integral of cos cos / (pi d^2) dA. Closed form (Lambert). */
double wrt_ff_point_polygon(wrt_v3 x, wrt_v3 n, const wrt_v3 *poly, int count);

#endif
