/* main.c: the wrt-bake command line. Parses options (cli/cli.h's number parsers and exit
 * codes), loads the scene, runs the bake (bake.h) with a progress bar on a terminal,
 * writes the .gto to a pending temporary, checks it against the path tracer for
 * --max-error (verify/compare.h: the only place the bake reaches the verification, after
 * the bake library has returned), renames it over the target and prints the summary
 * (text or --json); main() and bake() call these stages in order. Also --scan (what the
 * bake will see) and --info (inspect a .gto). Only this file exits. */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#if defined(__linux__) && defined(__GLIBC__)
#include <sys/auxv.h>
#endif

#include "../cli/cli.h"
#include "../common/outfile.h"
#include "../common/text.h"
#include "../formats/gto.h"
#include "../formats/scene.h"
#include "../verify/compare.h"
#include "bake.h"
#include "scan.h"
#include "bake_cli.h"
#include "dist.h"

static void usage(FILE *f) {
    fprintf(f,
        "usage: wrt-bake SCENE.gltf|.glb -o OUT.gto [options]\n"
        "       wrt-bake --scan SCENE.gltf [--json] [bake options]   what the bake will see and cost\n"
        "       wrt-bake --info FILE.gto [--json]       header, provenance, figures, integrity\n"
        "\n"
        "Precomputes the light transport of a static quad scene (Wavelet Radiance Transport):\n"
        "the direct transport operator by hierarchical refinement in a 4D Haar basis, then\n"
        "the global transport operator by a Neumann series, written to a mappable .gto file.\n"
        "\n"
        "options:\n"
        "  -o, --out FILE         the .gto to write (written to a temporary, then renamed;\n"
        "                         --output is the same)\n"
        "  -q, --quality Q        1 (coarse, fast) .. 9 (fine, slow); default 5. Sets the\n"
        "                         thresholds below consistently\n"
        "  --eps-receiver E       receiver refinement threshold (form-factor spread); alone,\n"
        "                         it sets --eps-receiver-coarse too\n"
        "  --eps-receiver-coarse E  the same for cells coarser than the display keeps\n"
        "                         (8 x 8 a quad); finer than --eps-receiver from quality 5\n"
        "  --eps-sender E         sender refinement threshold\n"
        "  --eps-compress E       drop operator entries below E after each product\n"
        "  --eps-final E          drop entries below E from the stored operator, once (at\n"
        "                         least the products' threshold; default: the quality's)\n"
        "  --drop-sender S        the stored operator's threshold grows as 2^(S d) with the\n"
        "                         sender's depth d (0 for a quad's mean, level + 1 for a\n"
        "                         wavelet; default 0.5; 0: a uniform threshold, as before;\n"
        "                         docs/bench.md \"Which entries are stored\")\n"
        "  --drop-receiver R      and as 2^(R (d - F)) with the receiver's depth d past F\n"
        "                         (default 1; 0: none)\n"
        "  --drop-receiver-from F (default 3: finer than the display's 8 x 8 cells a quad)\n"
        "  --drop-sender-size L   the sender's depth counts only on supports smaller than L x\n"
        "                         the scene's diagonal (a larger quad keeps its fine senders;\n"
        "                         default 0.05; 0: off)\n"
        "  --max-level L          deepest spatial refinement level (cells of 2^-L), <= 10\n"
        "  --min-level L          refine every link at least to level L\n"
        "  --max-angular-level L  cap on glossy materials' angular level (1..3; default 1 up\n"
        "                         to quality 5, 2 at 6-7, 3 from 8)\n"
        "  --glossy-quality G     refine the links that touch a glossy surface with quality\n"
        "                         G's thresholds and depth (1..Q; default Q up to 3, 3 at\n"
        "                         4-5, Q - 2 from 6)\n"
        "  --first-bounce-level L the direct light a glossy surface reflects enters as its\n"
        "                         exact lobe, projected on L levels of outgoing directions\n"
        "                         (the first-bounce operator; 1..4; default the material's\n"
        "                         need, 3 for roughness 0.35 and below; 0: off, the light's\n"
        "                         direction is truncated to the incident angular cells)\n"
        "  --gathered             store the gathered GTO (T_fine G) instead of G - I\n"
        "  --report-gathered      compute the gathered GTO's link count without storing it\n"
        "  --float-entries        store the operator as floats (a version 1.x file, 16 bytes an\n"
        "                         entry) instead of compact (version 3.0, about 5.3 bytes)\n"
        "  --compact-v2           the compact entries as version 2.0 (section opcode, with\n"
        "                         col_start: about 5.6 bytes an entry) for a 2.x reader; the\n"
        "                         same decoded operator as 3.0's\n"
        "  --float-k              with compact entries, keep the first-bounce operator K's as\n"
        "                         floats (8 bytes an entry) instead of compact (3 bytes)\n"
        "  --no-tail              do not add the estimated tail of the series\n"
        "  --series-block N       the series' sum waits in scratch files between bounces and is\n"
        "                         merged with each term by blocks of about N entries (default\n"
        "                         1048576; 0: the sum held in memory, as before; the same bytes)\n"
        "  --series-right F       bounces from --series-right-from B (default 2) on multiply\n"
        "                         by T compressed at F x --eps-compress (power kept) instead\n"
        "                         of the full T (default 1; 0: the full T, slower)\n"
        "  --series-skip F        the series' products do not sum a single contribution under\n"
        "                         F x --eps-compress (weighted as the compression); the plain\n"
        "                         series skips only those that carry no power, --clusters'\n"
        "                         keeps their power (default 1/64; 0: sum all)\n"
        "  --series-columns K     with --clusters, the series takes K blocks of columns one at a\n"
        "                         time through every bounce, each stored before the next\n"
        "                         starts (default 16; 0: the terms whole, held together)\n"
        "  --small-share F        a sender quad under F x eps_compress of the scene's area has\n"
        "                         its compression threshold scaled by its share over that\n"
        "                         (many small elements keep their multi-bounce light;\n"
        "                         default 10, 0: off); only a quad's mean is such a sender,\n"
        "                         toward the rows that carry power\n"
        "  --small-lost F         ... and only where the plain threshold would drop more\n"
        "                         than F of its column's power (default 0.05; 0: always)\n"
        "  --depth-share S        the oracle weighs a quad's detail by its share of the\n"
        "                         scene's area: under S, the kernel's spread over its cells\n"
        "                         is weighted by sqrt(share / S), so small elements stop at\n"
        "                         cells of an absolute size (default 1e-3; 0: off)\n"
        "  --series-coarse F      from the second bounce on, the light between bounces is\n"
        "                         kept on the functions whose support is at least F of the\n"
        "                         scene's area, each quad's mean always (power exact;\n"
        "                         default 1e-3 with --clusters, else off; 0: off;\n"
        "                         docs/clusters.md)\n"
        "  --no-balance           keep T's quad-to-quad power as the links integrate it (no\n"
        "                         power balance: loses energy conservation; for comparison)\n"
        "  --clusters             link well separated clusters of quads by one entry each\n"
        "                         instead of every quad pair (docs/clusters.md; diffuse\n"
        "                         scenes only). Without --clusters or --no-clusters,\n"
        "                         wrt-bake takes it for a diffuse scene with 1M ordered\n"
        "                         pairs of elements in sight of each other, or 10,000\n"
        "                         elements, and says so\n"
        "  --no-clusters          the plain bake (every quad pair) whatever the scene's size\n"
        "  --cluster-eps E        --clusters, and the oracle's power criterion: a cluster pair\n"
        "                         whose estimated error is at most E of the scene's power is\n"
        "                         linked at cluster level (default 1e-6; 0: off)\n"
        "  --clusters-keep-away   --clusters, and a pair whose sampled facing rays are all\n"
        "                         blocked while some point faces away refined, not dropped\n"
        "                         under the kernel's bound (before session 14; docs/clusters.md)\n"
        "  --clusters-albedo-split  --clusters, and the cluster tree split by albedo first,\n"
        "                         so that clusters of one albedo, which the oracle can link,\n"
        "                         are as large as the materials allow (docs/clusters.md)\n"
        "  --clusters-tree-basis  --clusters, and the operator stored in the cluster tree's\n"
        "                         basis when it has fewer entries there (a version 2.0 file;\n"
        "                         --clusters-tree-basis-always: whatever its size)\n"
        "  --clusters-quads-senders  --clusters, the operator's columns in the quads'\n"
        "                         basis (by default the senders' side is in the cluster\n"
        "                         tree's basis where that has fewer entries: a small\n"
        "                         quad's far light held once per cluster; section csend;\n"
        "                         --clusters-senders-always: whatever its size)\n"
        "  --clusters-quads-receivers  --clusters, the operator's rows in the quads'\n"
        "                         basis (by default, after the series in the senders' tree\n"
        "                         basis, the receivers' side is taken to the tree's basis\n"
        "                         too where that has fewer entries: a far cluster's light\n"
        "                         held on its node's function; section ctree without csend;\n"
        "                         --clusters-receivers-always: whatever its size)\n"
        "  --clusters-series-quads  --clusters, the series' terms in the quads' basis (by\n"
        "                         default they are in the senders' tree basis, multiplied\n"
        "                         from the left: a small quad's far light held once per\n"
        "                         cluster in every bounce; docs/clusters.md)\n"
        "  --clusters-pushed      --clusters, the series' products by T with the cluster\n"
        "                         links pushed down to the quads (by default T is kept as\n"
        "                         E1 U, the links' senders on their nodes; docs/clusters.md)\n"
        "  --max-bounces N        cap on the series (default 2000)\n"
        "  --max-memory MB        memory budget: the bake estimates what each stage needs\n"
        "                         before allocating it and refuses (exit 7, naming the figure)\n"
        "                         when it would pass; default half the physical memory\n"
        "  --threads N            worker threads (default: all cores); output is identical\n"
        "  --drop-bad             drop bad triangles with a warning instead of refusing\n"
        "  --allow-outside-files  let the scene's buffers and images lie outside its folder\n"
        "                         (refused by default: an absolute uri, '..' or a link out)\n"
        "  --provenance-timings   also store the bake's timings in the file (they differ from\n"
        "                         run to run: by default equal inputs give equal bytes)\n"
        "  --reproducible         the default (no timings stored, so equal bakes give equal bytes);\n"
        "                         kept for older scripts\n"
        "  --max-error E          check the bake against a path-traced reference (cell-average\n"
        "                         relative RMSE of the indirect light, 2 light positions) and\n"
        "                         fail with exit code 5, writing nothing, if it exceeds E\n"
        "  --check-paths N        reference paths per light for --max-error (default 1000000)\n"
        "  --json                 print one JSON object with the figures on stdout\n"
        "  --progress / --quiet   force or silence the progress lines, one per phase (load,\n"
        "                         dto, balance, series, write; default: when stderr is a terminal)\n"
        "  --print-config         print the resolved options and exit\n"
        "  -h, --help, --version\n"
        "\n");
    wrt_cli_exit_table(f);
}

/* One line per phase on a terminal (cli/cli.h); the bake's "gto" phase is the series. */
static int progress_cb(const char *phase, double done, void *user) {
    (void)user;
    wrt_cli_progress(!strcmp(phase, "gto") ? "series" : phase, done);
    return 1;
}

/* SIGINT, SIGTERM, SIGHUP: remove the temporary being written (if it has a name; an
 * unnamed one goes with the process), say so, and exit with the documented code 4.
 * The target is the older file or none: it is only ever replaced by a rename. */
static void interrupt_exit(int sig) {
    (void)sig;
    wrt_gto_remove_temporaries();
    static const char msg[] = "\nwrt-bake: interrupted; nothing written, the output is as it was\n";
    ssize_t w = write(2, msg, sizeof msg - 1);
    (void)w;
    _exit(WRT_EXIT_INTERRUPTED);
}

static void install_interrupt_exit(void) {
    static const int sigs[] = {SIGINT, SIGTERM, SIGHUP};
    for (size_t i = 0; i < sizeof sigs / sizeof *sigs; i++) {
        struct sigaction old, sa;
        if (sigaction(sigs[i], NULL, &old) != 0 || old.sa_handler == SIG_IGN) continue;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = interrupt_exit;
        sigfillset(&sa.sa_mask);
        sigaction(sigs[i], &sa, NULL);
    }
}

static void json_counters(FILE *f, const wrt_bake_counters *c) {
    fprintf(f,
        "\"pairs\":{\"total\":%llu,\"exchange\":%llu,\"skipped_facing\":%llu,\"unoccluded\":%llu},"
        "\"links\":{\"dto\":%llu,\"dto_diffuse\":%llu,\"dto_glossy\":%llu,\"gto\":%llu,\"gathered\":%llu,"
        "\"refined\":%llu,\"leaves\":%llu,\"invisible\":%llu},"
        "\"entries\":{\"dto\":%llu,\"spatial\":%llu,\"angular\":%llu,\"gto\":%llu,\"gathered\":%llu},"
        "\"functions\":{\"total\":%u,\"angular\":%u},"
        "\"rays\":{\"traced\":%llu,\"skipped_unoccluded\":%llu,\"skipped_facing\":%llu},\"samples\":%llu,"
        "\"bounces\":%llu,\"energy_left\":%.6g,\"tail_fraction\":%.6g,\"series_ratio\":%.6g,\"balance_entries\":%llu,"
        "\"closed\":%s%s",
        (unsigned long long)c->pairs_total, (unsigned long long)c->pairs_exchange,
        (unsigned long long)c->pairs_skipped_facing, (unsigned long long)c->pairs_unoccluded,
        (unsigned long long)c->links_dto, (unsigned long long)c->links_dto_diffuse,
        (unsigned long long)c->links_dto_glossy, (unsigned long long)c->links_gto,
        (unsigned long long)c->links_gathered, (unsigned long long)c->links_refined,
        (unsigned long long)c->links_leaf, (unsigned long long)c->links_invisible,
        (unsigned long long)c->entries_dto, (unsigned long long)c->entries_spatial,
        (unsigned long long)c->entries_angular, (unsigned long long)c->entries_gto,
        (unsigned long long)c->entries_gathered, c->nfuncs, c->nfuncs_angular,
        (unsigned long long)c->rays_traced, (unsigned long long)c->rays_skipped_unoccluded,
        (unsigned long long)c->rays_skipped_facing, (unsigned long long)c->samples,
        (unsigned long long)c->bounces, c->energy_left, c->tail_fraction, c->series_ratio,
        (unsigned long long)c->balance_entries, c->closed ? "true" : "false", c->nkcols ? "," : "");
    /* only where there is one, so that the figures of a bake without glossy quads read as before */
    if (c->nkcols)
        fprintf(f, "\"first_bounce\":{\"columns\":%u,\"entries\":%llu,\"links\":%llu}", c->nkcols,
                (unsigned long long)c->entries_k, (unsigned long long)c->links_k);
    /* only with --clusters, likewise */
    if (c->cluster_visits || c->cluster_leaf_pairs || c->cluster_links)
        fprintf(f, ",\"clusters\":{\"links\":%llu,\"leaf_pairs\":%llu,\"visits\":%llu,\"oracle\":%llu,"
                "\"partial\":%llu,\"refused_visibility\":%llu,\"refused_spread\":%llu,\"rays\":%llu,\"closed_entries\":%llu,\"tree_entries\":%llu,\"tree_compressed\":%llu,"
                "\"tree_basis\":%s,\"senders_basis\":%s,\"senders_quads\":%llu,\"senders_raw\":%llu,"
                "\"receivers_raw\":%llu,\"receivers_entries\":%llu,\"depth\":%u",
                (unsigned long long)c->cluster_links, (unsigned long long)c->cluster_leaf_pairs,
                (unsigned long long)c->cluster_visits, (unsigned long long)c->cluster_oracle,
                (unsigned long long)c->cluster_partial, (unsigned long long)c->cluster_refused_visibility, (unsigned long long)c->cluster_refused_spread,
                (unsigned long long)c->cluster_rays, (unsigned long long)c->cluster_fix_entries,
                (unsigned long long)c->cluster_tree_entries, (unsigned long long)c->cluster_tree_compressed,
                c->cluster_tree_basis ? "true" : "false", c->cluster_senders_basis ? "true" : "false",
                (unsigned long long)c->cluster_senders_quads, (unsigned long long)c->cluster_senders_raw,
                (unsigned long long)c->cluster_receivers_raw, (unsigned long long)c->cluster_receivers_entries, c->cluster_depth);
    /* the series' products by T = E1 U: E1's entries (only then: the files of the
     * products by T pushed down keep their bytes) */
    if (c->cluster_factored_entries)
        fprintf(f, ",\"factored_entries\":%llu", (unsigned long long)c->cluster_factored_entries);
    if (c->cluster_apart_nodes) fprintf(f, ",\"apart_nodes\":%u", c->cluster_apart_nodes);
    if (c->cluster_visits || c->cluster_leaf_pairs || c->cluster_links) fputc('}', f);
}

static void json_options(FILE *f, const wrt_bake_options *o) {
    fprintf(f,
        "{\"quality\":%d,\"eps_receiver\":%.6g,\"eps_receiver_coarse\":%.6g,\"eps_sender\":%.6g,\"eps_compress\":%.6g,"
        "\"max_level\":%d,\"min_level\":%d,\"receiver_samples\":%d,\"gathered\":%d,\"tail\":%d,"
        "\"max_bounces\":%d,\"max_alevel\":%d,\"glossy_quality\":%d,"
        "\"eps_receiver_glossy\":%.6g,\"eps_sender_glossy\":%.6g,\"max_level_glossy\":%d,\"balance\":%d,"
        "\"eps_final\":%.6g,\"drop_sender\":%.6g,\"drop_receiver\":%.6g,\"drop_receiver_from\":%d",
        o->quality, o->eps_receiver, o->eps_receiver_coarse, o->eps_sender, o->eps_compress, o->max_slevel, o->min_slevel,
        o->receiver_samples, o->gathered, !o->no_tail, o->max_bounces, o->max_alevel,
        o->glossy_quality, o->eps_receiver_glossy, o->eps_sender_glossy, o->max_slevel_glossy, !o->no_balance,
        o->eps_final, fmax(o->drop_sender, 0), fmax(o->drop_receiver, 0),
        o->drop_receiver_from > 0 ? o->drop_receiver_from : 0);
    if (o->drop_sender_size > 0) fprintf(f, ",\"drop_sender_size\":%.6g", o->drop_sender_size);
    fprintf(f, ",\"series_right\":%.6g,\"series_right_from\":%d", o->series_right > 0 ? o->series_right : 0,
            o->series_right_from);
    /* only when on (the default bake's provenance, and so its bytes, unchanged) */
    if (o->series_coarse > 0) fprintf(f, ",\"series_coarse\":%.6g", o->series_coarse);
    fprintf(f, ",\"series_skip\":%.6g", o->series_skip > 0 ? o->series_skip : 0);
    /* only when off: the blocks' count does not change the operator */
    if (o->clusters && o->series_columns < 0) fprintf(f, ",\"series_columns\":0");
    /* only when not the default 10 (the default bake's bytes unchanged); 0: off */
    if (o->small_share != 10) fprintf(f, ",\"small_share\":%.6g", fmax(o->small_share, 0));
    if (o->small_lost != WRT_SMALL_LOST_DEFAULT) fprintf(f, ",\"small_lost\":%.6g", fmax(o->small_lost, 0));
    /* only when not the default (the default bake's bytes unchanged); 0: off */
    if (o->depth_share != WRT_DEPTH_SHARE_DEFAULT) fprintf(f, ",\"depth_share\":%.6g", fmax(o->depth_share, 0));
    fputc('}', f);
}

/* ---------------------------------------------------------------- the command line */

/* The command line, parsed. */
typedef struct bake_args {
    const char *scene_path, *out_path, *scan, *info;
    int scan_positional; /* --scan followed by an option: the scene is the positional argument */
    int json, force_progress, quiet, print_config, timings, drop_bad, allow_outside;
    int float_entries;  /* --float-entries: a 1.x file, not the compact 3.0 */
    int compact_v2;     /* --compact-v2: the compact entries as 2.0's section opcode */
    int float_k;        /* --float-k: K's entries as floats in a compact file (sections 14, 15) */
    double max_error;   /* < 0: no accuracy check */
    int check_paths;
    int no_clusters;    /* --no-clusters: the plain bake whatever the scene's size */
    int clusters_auto;  /* the cluster hierarchy taken by wrt-bake itself (choose_clusters) */
    wrt_bake_options o;
} bake_args;

/* What parse_args and the early stages return when the program goes on. */
#define GO_ON (-1)

/* cli.h's number parsers, for the int and double fields of the options. */
static int opt_int(const char *opt, const char *val, long lo, long hi, int *out) {
    long n;
    if (!wrt_cli_int("wrt-bake", opt, val, lo, hi, &n)) return 0;
    *out = (int)n;
    return 1;
}

static int opt_num(const char *opt, const char *val, double lo, double hi, double *out) {
    return wrt_cli_num("wrt-bake", opt, val, lo, hi, out);
}

/* A file name option's value. */
static int opt_str(const char *opt, const char *val, const char **out) {
    if (!val) {
        fprintf(stderr, "wrt-bake: error: %s needs a value\n", opt);
        return 0;
    }
    *out = val;
    return 1;
}

/* An option given twice is refused (`-o a -o b` would silently take the last). */
static int given_twice(const char *a, const char **seen, int *nseen, int max) {
    if (a[0] != '-' || !a[1]) return 0;
    const char *canon = (!strcmp(a, "-o") || !strcmp(a, "--out")) ? "--output" : !strcmp(a, "-q") ? "--quality" : a;
    for (int k = 0; k < *nseen; k++)
        if (!strcmp(seen[k], canon)) {
            fprintf(stderr, "wrt-bake: error: %s given twice\n", a);
            return 1;
        }
    if (*nseen < max) seen[(*nseen)++] = canon;
    return 0;
}

/* Options that constrain each other. */
static int check_args(const bake_args *A) {
    const wrt_bake_options *o = &A->o;
    if (o->min_slevel && o->max_slevel && o->min_slevel > o->max_slevel) {
        fprintf(stderr, "wrt-bake: error: --min-level %d is deeper than --max-level %d\n", o->min_slevel, o->max_slevel);
        return WRT_EXIT_USAGE;
    }
    if (o->eps_final > 0) { /* the defaults, to compare with the products' threshold */
        wrt_bake_options d = *o;
        wrt_bake_defaults(&d);
        if (o->eps_final < d.eps_compress) {
            fprintf(stderr, "wrt-bake: error: --eps-final %g is below the products' threshold --eps-compress %g "
                    "(entries those dropped cannot come back)\n", o->eps_final, d.eps_compress);
            return WRT_EXIT_USAGE;
        }
    }
    if (A->no_clusters && o->clusters) {
        fprintf(stderr, "wrt-bake: error: --no-clusters with --clusters or a --cluster option: choose one\n");
        return WRT_EXIT_USAGE;
    }
    if (o->glossy_quality && o->glossy_quality > (o->quality ? o->quality : 5)) {
        fprintf(stderr, "wrt-bake: error: --glossy-quality %d must not exceed the quality (%d)\n", o->glossy_quality,
                o->quality ? o->quality : 5);
        return WRT_EXIT_USAGE;
    }
    return GO_ON;
}

/* Fills *A from argv; returns GO_ON, or the exit code (0 after --help, --version). */
static int parse_args(int argc, char **argv, bake_args *A) {
    const char *seen[64];
    int nseen = 0;
    memset(A, 0, sizeof *A);
    A->max_error = -1;
    A->check_paths = 1000000;
    wrt_bake_options *o = &A->o;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        int ok = 1;
        if (given_twice(a, seen, &nseen, (int)(sizeof seen / sizeof *seen))) return WRT_EXIT_USAGE;
        if (!strcmp(a, "-h") || !strcmp(a, "--help")) { usage(stdout); return 0; }
        else if (!strcmp(a, "--version")) { wrt_cli_version("wrt-bake"); return 0; }
        else if (!strcmp(a, "-o") || !strcmp(a, "--out") || !strcmp(a, "--output")) { ok = opt_str(a, v, &A->out_path); i++; }
        else if (!strcmp(a, "--scan")) {
            if (v && !(v[0] == '-' && v[1])) { A->scan = v; i++; }
            else A->scan_positional = 1; /* `wrt-bake SCENE --scan --clusters` */
        }
        else if (!strcmp(a, "--info")) { ok = opt_str(a, v, &A->info); i++; }
        else if (!strcmp(a, "-q") || !strcmp(a, "--quality")) { ok = opt_int(a, v, 1, 9, &o->quality); i++; }
        else if (!strcmp(a, "--eps-receiver")) { ok = opt_num(a, v, 1e-12, 10, &o->eps_receiver); i++; }
        else if (!strcmp(a, "--eps-receiver-coarse")) { ok = opt_num(a, v, 1e-12, 10, &o->eps_receiver_coarse); i++; }
        else if (!strcmp(a, "--eps-sender")) { ok = opt_num(a, v, 1e-12, 10, &o->eps_sender); i++; }
        else if (!strcmp(a, "--eps-compress")) { ok = opt_num(a, v, 1e-15, 1, &o->eps_compress); i++; }
        else if (!strcmp(a, "--eps-final")) { ok = opt_num(a, v, 1e-15, 1, &o->eps_final); i++; }
        else if (!strcmp(a, "--drop-sender") || !strcmp(a, "--drop-receiver")) { /* 0: none (stored as -1) */
            double *d = a[7] == 's' ? &o->drop_sender : &o->drop_receiver;
            ok = opt_num(a, v, 0, 4, d);
            if (ok && *d == 0) *d = -1;
            i++;
        }
        else if (!strcmp(a, "--drop-sender-size")) { /* 0: none (stored as -1) */
            ok = opt_num(a, v, 0, 10, &o->drop_sender_size);
            if (ok && o->drop_sender_size == 0) o->drop_sender_size = -1;
            i++;
        }
        else if (!strcmp(a, "--drop-receiver-from")) {
            ok = opt_int(a, v, 0, 11, &o->drop_receiver_from);
            if (ok && o->drop_receiver_from == 0) o->drop_receiver_from = -1;
            i++;
        }
        else if (!strcmp(a, "--max-level")) { ok = opt_int(a, v, 1, 10, &o->max_slevel); i++; }
        else if (!strcmp(a, "--min-level")) { ok = opt_int(a, v, 0, 10, &o->min_slevel); i++; }
        else if (!strcmp(a, "--max-angular-level")) { ok = opt_int(a, v, 1, 3, &o->max_alevel); i++; }
        else if (!strcmp(a, "--glossy-quality")) { ok = opt_int(a, v, 1, 9, &o->glossy_quality); i++; }
        else if (!strcmp(a, "--first-bounce-level")) {
            ok = opt_int(a, v, 0, 4, &o->first_bounce_level);
            if (ok && o->first_bounce_level == 0) o->first_bounce_level = -1;
            i++;
        }
        else if (!strcmp(a, "--max-memory")) { ok = opt_num(a, v, 1, 1e9, &o->max_memory_mb); i++; }
        else if (!strcmp(a, "--max-bounces")) { ok = opt_int(a, v, 1, 1000000, &o->max_bounces); i++; }
        else if (!strcmp(a, "--threads")) { ok = opt_int(a, v, 1, 64, &o->threads); i++; }
        else if (!strcmp(a, "--max-error")) { ok = opt_num(a, v, 0, 100, &A->max_error); i++; }
        else if (!strcmp(a, "--check-paths")) { ok = opt_int(a, v, 1000, 1000000000, &A->check_paths); i++; }
        else if (!strcmp(a, "--gathered")) o->gathered = 1;
        else if (!strcmp(a, "--report-gathered")) o->report_gathered = 1;
        else if (!strcmp(a, "--float-entries")) A->float_entries = 1;
        else if (!strcmp(a, "--compact-v2")) A->compact_v2 = 1;
        else if (!strcmp(a, "--float-k")) A->float_k = 1;
        else if (!strcmp(a, "--series-right")) {
            ok = opt_num(a, v, 0, 1e6, &o->series_right);
            if (ok && o->series_right == 0) o->series_right = -1; /* 0 on the command line: off */
            i++;
        }
        else if (!strcmp(a, "--series-block")) {
            double d = 0;
            ok = opt_num(a, v, 0, 1e12, &d);
            o->series_block = d >= 1 ? (long long)d : -1; /* 0 on the command line: the sum in memory */
            i++;
        }
        else if (!strcmp(a, "--series-skip")) {
            ok = opt_num(a, v, 0, 1, &o->series_skip);
            if (ok && o->series_skip == 0) o->series_skip = -1; /* 0 on the command line: off */
            i++;
        }
        else if (!strcmp(a, "--series-columns")) {
            ok = opt_int(a, v, 0, 1000000, &o->series_columns);
            if (ok && o->series_columns == 0) o->series_columns = -1; /* 0 on the command line: off */
            i++;
        }
        else if (!strcmp(a, "--series-right-from")) { ok = opt_int(a, v, 2, 1000000, &o->series_right_from); i++; }
        else if (!strcmp(a, "--series-coarse")) {
            ok = opt_num(a, v, 0, 1, &o->series_coarse);
            if (ok && o->series_coarse == 0) o->series_coarse = -1; /* 0 on the command line: off */
            i++;
        }
        else if (!strcmp(a, "--depth-share")) {
            ok = opt_num(a, v, 0, 1, &o->depth_share);
            if (ok && o->depth_share == 0) o->depth_share = -1; /* 0 on the command line: off */
            i++;
        }
        else if (!strcmp(a, "--small-share")) {
            ok = opt_num(a, v, 0, 1e6, &o->small_share);
            if (ok && o->small_share == 0) o->small_share = -1; /* 0 on the command line: off */
            i++;
        }
        else if (!strcmp(a, "--small-lost")) {
            ok = opt_num(a, v, 0, 1, &o->small_lost);
            if (ok && o->small_lost == 0) o->small_lost = -1; /* 0 on the command line: always */
            i++;
        }
        else if (!strcmp(a, "--no-tail")) o->no_tail = 1;
        else if (!strcmp(a, "--no-balance")) o->no_balance = 1;
        else if (!strcmp(a, "--clusters")) o->clusters = 1;
        else if (!strcmp(a, "--no-clusters")) A->no_clusters = 1;
        else if (!strcmp(a, "--cluster-eps")) {
            double e = 0;
            ok = opt_num(a, v, 0, 1, &e);
            o->clusters = 1;
            o->cluster_eps = e > 0 ? e : -1; /* 0: the power criterion off */
            i++;
        }
        else if (!strcmp(a, "--clusters-albedo-split")) { o->clusters = 1; o->cluster_albedo_split = 1; }
        else if (!strcmp(a, "--clusters-keep-away")) { o->clusters = 1; o->cluster_keep_away = 1; }
        else if (!strcmp(a, "--clusters-tree-basis")) { o->clusters = 1; o->cluster_tree = 1; }
        else if (!strcmp(a, "--clusters-quads-senders")) { o->clusters = 1; o->cluster_senders = -1; }
        else if (!strcmp(a, "--clusters-senders-always")) { o->clusters = 1; o->cluster_senders = 1; }
        else if (!strcmp(a, "--clusters-quads-receivers")) { o->clusters = 1; o->cluster_receivers = -1; }
        else if (!strcmp(a, "--clusters-receivers-always")) { o->clusters = 1; o->cluster_receivers = 2; }
        else if (!strcmp(a, "--clusters-series-tree")) { o->clusters = 1; o->cluster_series = 1; }
        else if (!strcmp(a, "--clusters-series-quads")) { o->clusters = 1; o->cluster_series = -1; }
        else if (!strcmp(a, "--clusters-pushed")) { o->clusters = 1; o->cluster_factored = -1; }
        else if (!strcmp(a, "--clusters-tree-basis-always")) { o->clusters = 1; o->cluster_tree = 2; }
        else if (!strcmp(a, "--drop-bad")) A->drop_bad = 1;
        else if (!strcmp(a, "--allow-outside-files")) A->allow_outside = 1;
        else if (!strcmp(a, "--reproducible")) A->timings = 0;
        else if (!strcmp(a, "--provenance-timings")) A->timings = 1;
        else if (!strcmp(a, "--json")) A->json = 1;
        else if (!strcmp(a, "--progress")) A->force_progress = 1;
        else if (!strcmp(a, "--quiet")) A->quiet = 1;
        else if (!strcmp(a, "--print-config")) A->print_config = 1;
        else if (a[0] == '-' && a[1]) { fprintf(stderr, "wrt-bake: error: unknown option '%s' (see --help)\n", a); return WRT_EXIT_USAGE; }
        else if (!A->scene_path) A->scene_path = a;
        else { fprintf(stderr, "wrt-bake: error: unexpected argument '%s'\n", a); return WRT_EXIT_USAGE; }
        if (!ok) return WRT_EXIT_USAGE;
    }
    if (A->scan_positional) {
        if (!A->scene_path) {
            fprintf(stderr, "wrt-bake: error: --scan needs a scene: wrt-bake --scan SCENE.gltf [options]\n");
            return WRT_EXIT_USAGE;
        }
        A->scan = A->scene_path;
        A->scene_path = NULL;
    }
    return check_args(A);
}

/* ---------------------------------------------------------------- the modes */

/* --info and --scan print text from the file (provenance, names): through
 * wrt_cli_print_safely, so that escape codes in it cannot drive the terminal. */
struct report_args { const char *path; const wrt_scene *scene; int json; const bake_args *A; };
static int print_info(void *u, FILE *f) {
    const struct report_args *a = u;
    return (int)wrt_gto_print_info(a->path, a->json, f);
}
static int print_summary(void *u, FILE *f) {
    const struct report_args *a = u;
    wrt_scan_print(a->scene, &a->A->o, a->A->drop_bad, a->A->clusters_auto, a->json, f);
    return 0;
}

/* --info FILE.gto */
static int run_info(const bake_args *A) {
    const char *info = A->info;
    if (access(info, R_OK) != 0) { /* one message, not a report of a file that is not there */
        fprintf(stderr, "wrt-bake: error: %s: %s\n", info, strerror(errno));
        return WRT_EXIT_INPUT;
    }
    struct report_args ia = {info, NULL, A->json, A};
    wrt_status st = (wrt_status)wrt_cli_print_safely(stdout, print_info, &ia); /* no raw escapes */
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        return st == WRT_ERR_NOMEM ? WRT_EXIT_INTERNAL : WRT_EXIT_INPUT; /* a .gto that cannot be read is bad input */
    }
    return 0;
}

/* 1 if path is a regular file that starts with the .gto magic (a FIFO is not opened). */
static int is_gto_file(const char *path) {
    struct stat sst;
    FILE *sf = stat(path, &sst) == 0 && S_ISREG(sst.st_mode) ? fopen(path, "rb") : NULL;
    char magic[8] = {0};
    size_t got = sf ? fread(magic, 1, sizeof magic, sf) : 0;
    if (sf) fclose(sf);
    return got == sizeof magic && !memcmp(magic, "\x89WRT\r\n\x1a\n", sizeof magic);
}

/* Neither --clusters nor --no-clusters: the cluster hierarchy for a large diffuse scene
 * (scan.c wrt_scan_clusters_auto: 1M ordered pairs of elements in sight, or 10,000
 * elements), said on stderr when say is set. The file is then the one `--clusters`
 * makes, byte for byte. */
static void choose_clusters(bake_args *A, const wrt_scene *s, int say) {
    double pairs = 0;
    if (A->o.clusters || A->no_clusters || !wrt_scan_clusters_auto(s, &A->o, &pairs)) return;
    A->o.clusters = 1;
    A->clusters_auto = 1;
    if (say)
        fprintf(stderr, "wrt-bake: %d diffuse elements, %.2gM of their ordered pairs in sight: baked with --clusters, "
                        "which wrt-bake takes from %.0fM pairs in sight or %d elements on (--no-clusters: the plain "
                        "bake; docs/clusters.md)\n",
                s->nquads, pairs / 1e6, WRT_CLUSTERS_AUTO_PAIRS / 1e6, WRT_CLUSTERS_AUTO_ELEMENTS);
}

/* --scan SCENE */
static int run_scan(const bake_args *A_in, const wrt_load_options *lo) {
    bake_args Ac = *A_in, *A = &Ac; /* the estimate for the bake wrt-bake would make */
    const char *scan = A->scan;
    /* a baked file given by mistake: say so rather than show the glTF parser's error */
    if (is_gto_file(scan)) {
        fprintf(stderr, "wrt-bake: error: %s is a baked .gto file, not a scene: use --info to inspect it\n", scan);
        return WRT_EXIT_INPUT;
    }
    wrt_scene s;
    wrt_load_options slo = *lo;
    slo.report_only = 1; /* a scene that can be read is reported, never refused */
    wrt_status st = wrt_scene_load(scan, &slo, &s);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        return st == WRT_ERR_NOMEM ? WRT_EXIT_INTERNAL : WRT_EXIT_INPUT; /* the C++ reader's bad_alloc: 7 */
    }
    if (s.nnonfinite == 0 || A->drop_bad) choose_clusters(A, &s, 0);
    struct report_args sa = {NULL, &s, A->json, A};
    wrt_cli_print_safely(stdout, print_summary, &sa); /* names' escape codes shown as \xNN */
    wrt_scene_free(&s);
    return 0;
}

/* ---------------------------------------------------------------- the bake's stages */

/* The output, checked before any work: not the scene (same file, also through a
 * link), not a directory, in a folder where a file can be made. */
static int check_output(const bake_args *A) {
    const char *inputs[1] = {A->scene_path};
    wrt_status cst = wrt_gto_check_output(A->out_path, inputs, 1);
    if (cst == WRT_OK) cst = wrt_output_check(A->out_path); /* a regular file or nothing (common/outfile.h) */
    if (cst != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        return cst == WRT_ERR_INVALID_ARG ? WRT_EXIT_USAGE : WRT_EXIT_OUTPUT;
    }
    return GO_ON;
}

/* Loads the scene into *s; GO_ON, or the exit code with nothing left to free. */
static int load_scene(const bake_args *A, const wrt_load_options *lo, wrt_scene *s) {
    const char *out_path = A->out_path, *scene_path = A->scene_path;
    wrt_cli_progress("load", -1);
    wrt_status st = wrt_scene_load(scene_path, lo, s);
    wrt_cli_progress_end();
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        return st == WRT_ERR_NOMEM ? WRT_EXIT_INTERNAL : WRT_EXIT_INPUT; /* the C++ reader's bad_alloc: 7 */
    }
    /* ... nor any file the scene read (external buffers and images). */
    if (s->files && s->files[0]) {
        const char *ins[64];
        int nin = 0;
        for (char *l = s->files; *l && nin < 64;) {
            char *nl = strchr(l, '\n');
            if (nl) *nl = 0;
            ins[nin++] = l;
            if (!nl) break;
            l = nl + 1;
        }
        wrt_status cst = wrt_gto_check_output(out_path, ins, nin);
        for (int k = 0; k < nin - 1; k++) ((char *)ins[k])[strlen(ins[k])] = '\n';
        if (cst != WRT_OK) {
            fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
            wrt_scene_free(s);
            return cst == WRT_ERR_INVALID_ARG ? WRT_EXIT_USAGE : WRT_EXIT_OUTPUT;
        }
    }
    if (s->nquads == 0) {
        fprintf(stderr, "wrt-bake: error: %s: the scene has no quads\n", scene_path);
        wrt_scene_free(s);
        return WRT_EXIT_INPUT;
    }
    return GO_ON;
}

/* The bake itself (bake.h); then A->o holds the options it used. GO_ON, or the exit
 * code with the scene freed. */
static int run_bake(bake_args *A, wrt_scene *s, wrt_bake_result *r) {
    A->o.progress = progress_cb;
    A->o.consume_dto = 1; /* T is not written: the series' sum takes its arrays (series.c) */
    wrt_status st = wrt_bake_run(s, &A->o, r);
    wrt_cli_progress_end();
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        wrt_scene_free(s);
        return st == WRT_ERR_CANCELLED ? WRT_EXIT_INTERRUPTED : st == WRT_ERR_NOMEM ? WRT_EXIT_INTERNAL : WRT_EXIT_INPUT;
    }
    wrt_bake_defaults(&A->o);
    /* the write's own records (formats/gto_write.c: quads, names, materials; the operator
     * is written from the bake's arrays), about 256 bytes a quad */
    st = wrt_bake_memory_check(A->o.max_memory_mb, &r->c.mem_estimate_mb, (uint64_t)s->nquads * 256 + (1u << 20),
                               "writing the file");
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        wrt_bake_result_free(r);
        wrt_scene_free(s);
        return WRT_EXIT_INTERNAL;
    }
    return GO_ON;
}

/* The provenance the file records: one JSON object (malloc'd). */
static char *provenance_json(const bake_args *A, const wrt_scene *s, const wrt_bake_counters *c) {
    char *prov = NULL;
    size_t prov_len = 0;
    FILE *pf = open_memstream(&prov, &prov_len);
    fprintf(pf, "{\"tool\":\"wrt-bake\",\"version\":\"%s\",\"source\":", WRT_VERSION_STRING);
    wrt_json_str(pf, A->scene_path); /* common/text.h: valid JSON whatever the path holds */
    fprintf(pf, ",\"source_hash\":\"%016llx\",\"options\":", (unsigned long long)s->source_hash);
    json_options(pf, &A->o);
    fprintf(pf, ",");
    json_counters(pf, c);
    if (A->timings) fprintf(pf, ",\"seconds\":{\"dto\":%.3f,\"gto\":%.3f}", c->t_dto, c->t_gto);
    fprintf(pf, "}");
    fclose(pf);
    return prov;
}

/* The file is written to a private temporary in the target's folder (unnamed where
 * the file system allows); with --max-error it is checked there and only renamed
 * over the target when it passes: a rejected or interrupted bake leaves the target
 * as it was and no file behind. GO_ON, or the exit code. */
static int write_pending(const bake_args *A, const wrt_scene *s, const wrt_bake_result *r, wrt_gto_pending *pend,
                         double *t_write) {
    const wrt_bake_counters *c = &r->c;
    char *prov = provenance_json(A, s, c);
    /* a scene without a camera is stored without one (all zero, formats/GTO_FORMAT.md),
     * not with the loader's framing from outside its box: the reader then frames it
     * itself (wrt-play looks from where the light is seen, player/view.h) */
    wrt_scene stored = *s;
    if (!stored.camera.from_file) memset(&stored.camera, 0, sizeof stored.camera);
    wrt_gto_contents gc = {
        .scene = &stored, .fkeys = r->fkeys, .nfuncs = r->nfuncs,
        .col_start = r->op.col, .rows = r->op.row, .vals = r->op.val,
        .op_kind = (uint32_t)r->op_kind, .material_alevel = r->material_alevel, .provenance = prov,
        .nkcols = r->nkcols, .kkeys = r->kkeys, .kcol_start = r->kcol_start, .krows = r->krows, .kvals = r->kvals,
        .compact = !A->float_entries, .k_float = A->float_k, .opcode_v2 = A->compact_v2,
    };
    wrt_gto_cnode *cn = NULL;
    if (r->ctree.nnodes) { /* --clusters: the tree (section ctree, version 2.0) */
        cn = wrt_xmalloc(r->ctree.nnodes * sizeof *cn);
        for (uint32_t i = 0; i < r->ctree.nnodes; i++)
            cn[i] = (wrt_gto_cnode){r->ctree.left[i], r->ctree.right[i], r->ctree.area[i]};
        gc.ctree = cn;
        gc.nctree = r->ctree.nnodes;
        gc.ctree_senders = c->cluster_senders_basis;
    }
    gc.stats.links_dto = c->links_dto;
    gc.stats.links_gto = c->links_gto;
    gc.stats.links_gathered = c->links_gathered;
    gc.stats.entries_dto = c->entries_dto;
    gc.stats.entries_op = r->op.nnz;
    gc.stats.rays_traced = c->rays_traced;
    gc.stats.rays_skipped = c->rays_skipped_unoccluded + c->rays_skipped_facing;
    gc.stats.bounces = c->bounces;
    gc.stats.energy_left = c->energy_left;
    if (A->timings) { gc.stats.t_dto = c->t_dto; gc.stats.t_gto = c->t_gto; }
    double tw = wrt_now();
    wrt_cli_progress("write", -1);
    wrt_status st = wrt_gto_write_pending(A->out_path, &gc, pend);
    wrt_cli_progress_end();
    *t_write = wrt_now() - tw;
    free(prov);
    free(cn);
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
        return WRT_EXIT_OUTPUT;
    }
    return GO_ON;
}

/* --max-error: the pending file against the path tracer (verify/compare.h), the only
 * use of the verification in wrt-bake, after the bake library has returned. */
typedef struct accuracy { double error, floor, seconds; } accuracy;

/* GO_ON, or the exit code with the pending file discarded. */
static int check_accuracy(const bake_args *A, const wrt_scene *s, wrt_gto_pending *pend, accuracy *acc) {
    double tc = wrt_now();
    wrt_light lights[2];
    int nl = wrt_compare_default_lights(s, 2, lights);
    wrt_compare_options co = {.cells = 4, .cell_paths = A->check_paths, .width = -1, .bench_updates = 1,
                              .threads = A->o.threads};
    wrt_compare_ref *ref = NULL;
    wrt_gto g;
    wrt_compare_result cr;
    wrt_status st = wrt_compare_ref_create(s, lights, nl, &co, &ref);
    if (st == WRT_OK) st = wrt_gto_open_pending(pend, &g);
    if (st == WRT_OK) {
        st = wrt_compare_gto(ref, &g, &cr);
        wrt_gto_close(&g);
    }
    wrt_compare_ref_destroy(ref);
    acc->seconds = wrt_now() - tc;
    if (st != WRT_OK) {
        fprintf(stderr, "wrt-bake: error: accuracy check failed to run: %s\n", wrt_last_error());
        wrt_gto_discard(pend);
        return WRT_EXIT_OUTPUT;
    }
    acc->error = cr.mean.cell_rmse;
    acc->floor = cr.mean.cell_floor;
    if (acc->error > A->max_error) {
        fprintf(stderr, "wrt-bake: error: accuracy not met: relative RMSE of the indirect light %.4f "
                "(reference noise %.4f) exceeds --max-error %.4f; %s not written\n",
                acc->error, acc->floor, A->max_error, A->out_path);
        wrt_gto_discard(pend);
        return WRT_EXIT_ACCURACY;
    }
    return GO_ON;
}

/* ---------------------------------------------------------------- the summary */

/* What the summary reports beyond the bake's counters. */
/* The phases, the same in the progress lines, the text summary and --json: load, dto,
 * balance, series, write (with the --max-error check inside write's span left out: it is
 * reported on its own), and the total. */
typedef struct bake_times { double t_load, t_write, t_total; long long bytes; accuracy acc; } bake_times;
static double phase_dto(const wrt_bake_counters *c) { return c->t_dto - c->t_balance_phase; }

/* The kernel's transparent huge pages (main's huge_pages_restart): 2 "always", 1 "madvise"
 * (given where a program asks), 0 "never" or unknown */
static int huge_pages_kernel(void) {
    FILE *f = fopen("/sys/kernel/mm/transparent_hugepage/enabled", "r");
    char mode[128] = "";
    if (!f) return 0;
    if (!fgets(mode, sizeof mode, f)) mode[0] = 0;
    fclose(f);
    return strstr(mode, "[always]") ? 2 : strstr(mode, "[madvise]") ? 1 : 0;
}

/* Whether this bake's large arrays could have huge pages: the kernel gives them to every
 * program, or where asked and glibc's allocator asks (--json memory_mb.huge_pages) */
static int huge_pages_on(void) {
    int k = huge_pages_kernel();
    const char *t = getenv("GLIBC_TUNABLES");
    return k == 2 || (k == 1 && t && strstr(t, "glibc.malloc.hugetlb=1"));
}

static void print_json_summary(const bake_args *A, const wrt_scene *s, const wrt_bake_result *r, const bake_times *T) {
    const wrt_bake_counters *c = &r->c;
    const wrt_bake_options *o = &A->o;
    printf("{\"scene\":");
    wrt_json_str(stdout, A->scene_path);
    printf(",\"output\":");
    wrt_json_str(stdout, A->out_path);
    printf(",\"quads\":%d,\"bytes\":%lld,", s->nquads, T->bytes);
    /* the phases of the progress lines and the text summary; "gto" is "series" under its
     * older name, for older scripts */
    printf("\"seconds\":{\"load\":%.4f,\"dto\":%.4f,\"balance\":%.4f,\"series\":%.4f,\"gto\":%.4f,"
           "\"write\":%.4f,\"total\":%.4f,\"rays_thread\":%.4f},", T->t_load, phase_dto(c), c->t_balance_phase,
           c->t_gto, c->t_gto, T->t_write, T->t_total, c->t_rays);
    if (A->max_error >= 0)
        printf("\"check\":{\"cell_rmse\":%.6g,\"floor\":%.6g,\"max_error\":%.6g,\"seconds\":%.3f},",
               T->acc.error, T->acc.floor, A->max_error, T->acc.seconds);
    printf("\"memory_mb\":{\"peak_rss\":%.1f,\"estimated\":%.1f,\"budget\":%.0f,\"huge_pages\":%s},",
           (double)wrt_bake_peak_rss_bytes() / (1024.0 * 1024.0), c->mem_estimate_mb, o->max_memory_mb,
           huge_pages_on() ? "true" : "false");
    /* the cluster hierarchy: given (--clusters or a --cluster option), auto (taken by
     * wrt-bake for the scene's size: choose_clusters) or none */
    printf("\"clusters_chosen\":\"%s\",", !o->clusters ? "none" : A->clusters_auto ? "auto" : "given");
    printf("\"operator\":\"%s\",\"options\":", r->op_kind == WRT_GTO_OP_GATHERED ? "gathered" : "indirect");
    json_options(stdout, o);
    printf(",");
    json_counters(stdout, c);
    printf("}\n");
}

static void print_text_summary(const bake_args *A, const wrt_scene *s, const wrt_bake_result *r, const bake_times *T) {
    const wrt_bake_counters *c = &r->c;
    const wrt_bake_options *o = &A->o;
    printf("baked %s -> %s (%lld bytes, %s operator)\n", A->scene_path, A->out_path, T->bytes,
           r->op_kind == WRT_GTO_OP_GATHERED ? "gathered" : "indirect");
    printf("  time      load %.2f s, dto %.2f s, balance %.2f s, series %.2f s, write %.2f s, total %.2f s\n",
           T->t_load, phase_dto(c), c->t_balance_phase, c->t_gto, T->t_write, T->t_total);
    printf("  memory    peak %.1f MB resident (largest estimate %.1f MB, budget %.0f MB)\n",
           (double)wrt_bake_peak_rss_bytes() / (1024.0 * 1024.0), c->mem_estimate_mb, o->max_memory_mb);
    printf("  quads     %d; pairs %llu exchanging of %llu (%llu skipped facing, %llu with no occluder)\n",
           s->nquads, (unsigned long long)c->pairs_exchange, (unsigned long long)c->pairs_total,
           (unsigned long long)c->pairs_skipped_facing, (unsigned long long)c->pairs_unoccluded);
    if (c->cluster_visits || c->cluster_leaf_pairs || c->cluster_links)
        printf("  clusters  %llu links (%llu partly visible), %llu leaf pairs; oracle %llu tries, refused "
               "%llu for visibility, %llu for spread; tree depth %u\n",
               (unsigned long long)c->cluster_links, (unsigned long long)c->cluster_partial,
               (unsigned long long)c->cluster_leaf_pairs, (unsigned long long)c->cluster_oracle,
               (unsigned long long)c->cluster_refused_visibility, (unsigned long long)c->cluster_refused_spread,
               c->cluster_depth);
    if (A->clusters_auto)
        printf("            taken by wrt-bake for the scene's size (--no-clusters: the plain bake; docs/clusters.md)\n");
    char gath[32] = "not computed";
    if (o->gathered || o->report_gathered) snprintf(gath, sizeof gath, "%llu", (unsigned long long)c->links_gathered);
    printf("  links     dto %llu, gto %llu, gathered %s (leaves %llu, invisible %llu)\n",
           (unsigned long long)c->links_dto, (unsigned long long)c->links_gto, gath,
           (unsigned long long)c->links_leaf, (unsigned long long)c->links_invisible);
    printf("  entries   dto %llu (spatial %llu, angular %llu), stored %llu; functions %u (angular %u)\n",
           (unsigned long long)c->entries_dto, (unsigned long long)c->entries_spatial,
           (unsigned long long)c->entries_angular, (unsigned long long)r->op.nnz, c->nfuncs, c->nfuncs_angular);
    if (c->nkcols)
        printf("  first bounce  %u outgoing functions of glossy quads, %llu entries, %llu links\n", c->nkcols,
               (unsigned long long)c->entries_k, (unsigned long long)c->links_k);
    printf("  rays      traced %llu, skipped %llu (no occluder) + %llu (facing)\n",
           (unsigned long long)c->rays_traced, (unsigned long long)c->rays_skipped_unoccluded,
           (unsigned long long)c->rays_skipped_facing);
    if (A->max_error >= 0)
        printf("  check     relative RMSE %.4f against the reference (its noise %.4f), limit %.4f, %.1f s\n",
               T->acc.error, T->acc.floor, A->max_error, T->acc.seconds);
    printf("  series    %llu bounces, energy left %.2e, tail added %.2e (ratio %.4f)\n",
           (unsigned long long)c->bounces, c->energy_left, c->tail_fraction, c->series_ratio);
    if (!o->no_balance && c->closed)
        printf("  balance   %llu power entries set; the scene is closed: no ray from any surface escapes, so each\n"
               "            function's light is made to land whole (what it emits)\n",
               (unsigned long long)c->balance_entries);
    else if (!o->no_balance) {
        const wrt_quad *q = c->open_quad >= 0 && c->open_quad < s->nquads ? &s->quads[c->open_quad] : NULL;
        const char *mesh = q && q->name >= 0 && q->name < s->nnames ? s->names[q->name] : "";
        printf("  balance   %llu power entries set; the scene is open: light leaves it (a ray from quad %d",
               (unsigned long long)c->balance_entries, c->open_quad);
        if (mesh[0]) printf(", mesh \"%.64s\"", mesh);
        printf(", meets no surface),\n            so the light that escapes is lost, as it should be; a closed "
               "scene would be balanced to lose none\n");
    }
}

/* ---------------------------------------------------------------- main */

/* Load, bake, write pending, check (--max-error), commit, report. */
static int bake(bake_args *A, const wrt_load_options *lo) {
    int rc = check_output(A);
    if (rc != GO_ON) return rc;
    bake_times T = {.acc = {-1, -1, 0}};
    double t0 = wrt_now();
    wrt_scene s;
    rc = load_scene(A, lo, &s);
    T.t_load = wrt_now() - t0;
    if (rc != GO_ON) return rc;
    choose_clusters(A, &s, wrt_cli_progress_enabled());
    if (wrt_cli_progress_enabled()) wrt_scan_print_bake_hint(&s, &A->o, stderr);
    wrt_bake_result r;
    rc = run_bake(A, &s, &r);
    if (rc != GO_ON) return rc;
    wrt_gto_pending pend;
    rc = write_pending(A, &s, &r, &pend, &T.t_write);
    if (rc == GO_ON && A->max_error >= 0) rc = check_accuracy(A, &s, &pend, &T.acc);
    if (rc == GO_ON) {
        double tw = wrt_now();
        wrt_status st = wrt_gto_commit(&pend);
        T.t_write += wrt_now() - tw;
        if (st != WRT_OK) {
            fprintf(stderr, "wrt-bake: error: %s\n", wrt_last_error());
            rc = WRT_EXIT_OUTPUT;
        }
    }
    if (rc == GO_ON) {
        T.t_total = wrt_now() - t0;
        T.bytes = -1;
        struct stat ob;
        if (stat(A->out_path, &ob) == 0) T.bytes = (long long)ob.st_size;
        if (A->json) print_json_summary(A, &s, &r, &T);
        else print_text_summary(A, &s, &r, &T);
        rc = 0;
    }
    wrt_bake_result_free(&r);
    wrt_scene_free(&s);
    return rc;
}

/* wrt-bake-mpi's ranks other than 0 (dist): the same load and bake, their shares of it
 * (dist.h), and nothing written or printed; 0, or the exit code. */
static int bake_rank(bake_args *A, const wrt_load_options *lo) {
    wrt_scene s;
    int rc = load_scene(A, lo, &s);
    if (rc != GO_ON) return rc;
    choose_clusters(A, &s, 0); /* rank 0's choice: a function of the scene and options alone */
    wrt_bake_result r;
    rc = run_bake(A, &s, &r);
    if (rc != GO_ON) return rc;
    wrt_bake_result_free(&r);
    wrt_scene_free(&s);
    return 0;
}

int wrt_bake_cli(int argc, char **argv, struct wrt_bake_dist *dist) {
    wrt_cli_init("wrt-bake"); /* stdout checked at exit (3), out of memory: exit 7 */
    install_interrupt_exit(); /* first: a signal from here on exits 4, writing nothing */
    bake_args A;
    int rc = parse_args(argc, argv, &A);
    if (rc != GO_ON) return rc;
    A.o.dist = dist;
    int writer = !dist || dist->rank == 0; /* the rank that reports and writes the file */
    if (!writer && (A.print_config || A.info || A.scan)) return 0;
    if (A.print_config) {
        wrt_bake_defaults(&A.o);
        json_options(stdout, &A.o);
        putchar('\n');
        return 0;
    }
    if (A.info) return run_info(&A);
    wrt_load_options lo = {.drop_bad = A.drop_bad, .allow_outside_files = A.allow_outside};
    if (A.scan) return run_scan(&A, &lo);
    if (!A.scene_path) { usage(stderr); return WRT_EXIT_USAGE; }
    if (is_gto_file(A.scene_path)) { /* not the JSON parser's complaint about its bytes */
        fprintf(stderr, "wrt-bake: error: %s: this is a .gto file; bake a .gltf, or use --info\n", A.scene_path);
        return WRT_EXIT_INPUT;
    }
    if (!A.out_path) { fprintf(stderr, "wrt-bake: error: no output file (-o OUT.gto)\n"); return WRT_EXIT_USAGE; }
    wrt_cli_progress_enable(writer && !A.quiet && (A.force_progress || isatty(2)));
    return writer ? bake(&A, &lo) : bake_rank(&A, &lo);
}

#ifndef WRT_BAKE_CLI_NO_MAIN /* wrt-bake-mpi has its own main (mpi/main_mpi.c) */
/* The bake's large arrays on the kernel's 2 MiB pages (docs/bench.md "Huge pages"). The
 * series' products scatter into accumulators of 32 bytes a function and read the right
 * factor's columns, its bands' index and the rows' weights in no order: on 4 KiB pages
 * nearly every such access misses the TLB. Debian's kernel gives transparent huge pages
 * only where a program asks ("madvise"), and glibc's allocator asks, on its fresh mappings
 * and heaps, only with the tunable glibc.malloc.hugetlb=1, which it reads once as the
 * process starts. So wrt-bake starts itself again with it set. Not where the kernel's
 * setting is not "madvise" (with "always" every program has them; with "never" none
 * can), where GLIBC_TUNABLES already names it (the user's choice, 0 included), with
 * WRT_HUGE_PAGES=0, or in a privileged process (glibc drops tunables there). Where the
 * exec fails the bake runs as it was started. The same bytes either way. */
static void huge_pages_restart(char **argv) {
#if defined(__linux__) && defined(__GLIBC__)
    const char *off = getenv("WRT_HUGE_PAGES");
    if ((off && strcmp(off, "0") == 0) || getauxval(AT_SECURE) || huge_pages_kernel() != 1) return;
    const char *was = getenv("GLIBC_TUNABLES");
    if (was && strstr(was, "glibc.malloc.hugetlb")) return;
    char old[2048], set[2100];
    if (was && strlen(was) >= sizeof old) return;
    snprintf(old, sizeof old, "%s", was ? was : "");
    snprintf(set, sizeof set, "%s%sglibc.malloc.hugetlb=1", old, old[0] ? ":" : "");
    if (setenv("GLIBC_TUNABLES", set, 1) != 0) return;
    execv("/proc/self/exe", argv);
    if (was) setenv("GLIBC_TUNABLES", old, 1);
    else unsetenv("GLIBC_TUNABLES");
#else
    (void)argv;
#endif
}

int main(int argc, char **argv) {
    huge_pages_restart(argv);
    return wrt_bake_cli(argc, argv, NULL);
}
#endif
