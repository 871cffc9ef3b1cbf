/* scan.h: what `wrt-bake --scan` reports before anything is baked: the scene summary
 * (formats/scene.h), the elements by kind, what would be dropped or refused and why,
 * and an estimate of the bake's time, peak memory and file size at the chosen quality
 * from a simple model fitted to measured bakes (scan.c says which). */
#ifndef WRT_SCAN_H
#define WRT_SCAN_H

#include <stdio.h>
#include "bake.h"
#include "../formats/scene.h"

typedef struct wrt_scan_estimate {
    int quality;        /* the quality the estimate is for (1..9) */
    int elements;       /* quads the bake would see (pairs, triangles' parts, twins) */
    double visible;     /* share of the ordered pairs of elements that see each other
                           (wrt_scan_visible_fraction; -1 if it could not be sampled) */
    double exchange;    /* share of the ordered pairs of elements, counted by element, that face
                           each other (wrt_scan_exchange_fraction): the plain bake's pairs */
    double seconds;     /* CPU seconds (user + system; wall on 2 idle cores: about half) */
    double memory_mb;   /* peak resident memory */
    double bytes;       /* size of the .gto */
} wrt_scan_estimate;

/* The share of ordered pairs of distinct elements of s that face and see each other,
 * sampled (a fixed sequence of random pairs and points: deterministic); 0 under two
 * elements, -1 if Embree failed. */
double wrt_scan_visible_fraction(const wrt_scene *s);
/* Of SCAN_VIS_SAMPLES ordered pairs of distinct elements drawn uniformly by element (a
 * fixed sequence), the share that face each other as the plain bake's pair list counts
 * them (some corner of each in front of the other's plane): its pairs over N (N - 1). */
double wrt_scan_exchange_fraction(const wrt_scene *s);

/* The estimate for scene s under options o (zero fields: defaults). Pure. */
wrt_scan_estimate wrt_scan_estimate_cost(const wrt_scene *s, const wrt_bake_options *o);

/* wrt-bake's choice when neither --clusters nor --no-clusters is given (docs/clusters.md
 * "When wrt-bake clusters by itself"): 1 (the cluster hierarchy) for a scene whose
 * materials are all diffuse, baked without the gathered operator (what --clusters
 * bakes), with at least WRT_CLUSTERS_AUTO_PAIRS ordered pairs of elements in sight of
 * each other (N^2 times wrt_scan_visible_fraction: the plain bake's links grow with them)
 * or at least WRT_CLUSTERS_AUTO_ELEMENTS elements (its pair list grows as N^2 whatever
 * is in sight); 0 (the plain bake) otherwise. *pairs (if not NULL) gets the pairs in
 * sight, 0 where not sampled. A function of the scene and the options alone: the same
 * on every machine and thread count. */
#define WRT_CLUSTERS_AUTO_PAIRS 1e6
#define WRT_CLUSTERS_AUTO_ELEMENTS 10000
int wrt_scan_clusters_auto(const wrt_scene *s, const wrt_bake_options *o, double *pairs);

/* Prints the scan of s (loaded with report_only) to f: the summary, then what the bake
 * would drop or refuse given drop_bad, then the estimate (clusters_auto: o->clusters was
 * set by wrt-bake's own choice, wrt_scan_clusters_auto, and the text says so). With json,
 * one JSON object (the summary's members plus "refused" and "estimate"). */
void wrt_scan_print(const wrt_scene *s, const wrt_bake_options *o, int drop_bad, int clusters_auto, int json, FILE *f);

/* Before a bake, on a terminal: one line with the estimate at the options the bake will
 * use and the memory budget; for a diffuse scene baked without --clusters whose
 * estimate passes the budget or an hour of CPU, what --clusters would cost at the same
 * quality and at quality 1; and, when the estimate passes the budget, what happens then. */
void wrt_scan_print_bake_hint(const wrt_scene *s, const wrt_bake_options *o, FILE *f);

#endif
