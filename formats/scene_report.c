/* scene_report.c: prints a loaded wrt_scene's summary (wrt_scene_print_summary, in
 * scene.h), as text or as JSON: its quads, materials, lights and camera, the pairing's
 * counts, and every problem triangle with mesh/primitive/triangle. The scene itself is
 * built by scene.c, which also names the problem kinds (scene_internal.h). Depends on
 * wrt_common and the one JSON string writer in common/text.h. */
#define _POSIX_C_SOURCE 200809L
#include "scene.h"
#include "../common/texture.h"
#include "scene_internal.h"
#include "../common/text.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char *single_name(int why) {
    switch (why) {
    case WRT_SINGLE_ALONE: return "no neighbour";
    case WRT_SINGLE_TAKEN: return "neighbours taken";
    case WRT_SINGLE_NONPLANAR: return "non-planar";
    case WRT_SINGLE_NONCONVEX: return "non-convex";
    case WRT_SINGLE_WINDING: return "opposite winding";
    case WRT_SINGLE_FAN: return "edge fan";
    default: return "?";
    }
}

/* Strings through the one JSON writer (common/text.h): valid JSON whatever the names. */
static void json_string(FILE *f, const char *s) { wrt_json_str(f, s); }

/* Numbers in JSON must be finite. */
static void json_num(FILE *f, double x) {
    if (isfinite(x)) fprintf(f, "%.9g", x);
    else fputs("null", f);
}

static void json_v3(FILE *f, wrt_v3 v) {
    fputc('[', f);
    json_num(f, v.x); fputc(',', f);
    json_num(f, v.y); fputc(',', f);
    json_num(f, v.z);
    fputc(']', f);
}

/* Single-precision fields print with the digits a float holds (0.8, not 0.800000012). */
static void json_numf(FILE *f, float x) {
    if (isfinite(x)) fprintf(f, "%.7g", (double)x);
    else fputs("null", f);
}

static void json_f3(FILE *f, const float *v) {
    fputc('[', f);
    json_numf(f, v[0]); fputc(',', f);
    json_numf(f, v[1]); fputc(',', f);
    json_numf(f, v[2]);
    fputc(']', f);
}

/* The JSON form: counts, bbox, materials, lights, camera and problems as one object. */
static void print_summary_json(const wrt_scene *s, int npara, const int *uses, FILE *f) {
    const wrt_camera *c = &s->camera;
    fprintf(f, "{\"quads\":%d,\"parallelograms\":%d,\"triangles\":%d,\"emissive\":%d,", s->nquads,
            npara, s->ntriangles, s->nemissive);
    fprintf(f, "\"elements\":{\"paired\":%d,\"triangles\":%d,\"triangle_quads\":%d,\"twins\":%d},",
            s->npaired, s->nsingle, 3 * s->nsingle, s->ntwins);
    fputs("\"triangles_alone\":{", f);
    for (int k = 0; k < WRT_SINGLE_NREASONS; k++)
        fprintf(f, "%s\"%s\":%d", k ? "," : "", single_name(k), s->why_single[k]);
    fprintf(f, "},\"dropped\":%d,\"non_finite\":%d,\"mirrored_instances\":%d,\"coincident_pairs\":%d,",
            s->ndropped, s->nnonfinite, s->nmirrored, s->ncoincident);
    fprintf(f, "\"source_hash\":\"%016llx\",\"bbox\":{\"min\":", (unsigned long long)s->source_hash);
    json_v3(f, s->bbox_min);
    fputs(",\"max\":", f);
    json_v3(f, s->bbox_max);
    fputs("},\"materials\":[", f);
    for (int i = 0; i < s->nmaterials; i++) {
        const wrt_material *m = &s->materials[i];
        fputs(i ? ",{\"name\":" : "{\"name\":", f);
        json_string(f, m->name);
        fputs(",\"base_color\":", f);
        json_f3(f, m->base_color);
        fputs(",\"metallic\":", f);
        json_numf(f, m->metallic);
        fputs(",\"roughness\":", f);
        json_numf(f, m->roughness);
        fputs(",\"emissive\":", f);
        json_f3(f, m->emissive);
        fprintf(f, ",\"lambertian\":%s,\"textured\":%s,\"quads\":%d}", m->lambertian ? "true" : "false",
                m->has_texture ? "true" : "false", uses[i]);
    }
    fputs("],\"lights\":[", f);
    for (int i = 0; i < s->nlights; i++) {
        const wrt_light *l = &s->lights[i];
        fprintf(f, "%s{\"type\":\"%s\",\"name\":", i ? "," : "", wrt_light_type_name(l->type));
        json_string(f, l->name);
        fputs(",\"position\":", f);
        json_v3(f, l->pos);
        fputs(",\"direction\":", f);
        json_v3(f, l->dir);
        fputs(",\"color\":", f);
        json_f3(f, l->color);
        fputs(",\"intensity\":", f);
        json_numf(f, l->intensity);
        fputs(",\"range\":", f);
        json_numf(f, l->range);
        fputs(",\"inner_cone\":", f);
        json_numf(f, l->inner_cone);
        fputs(",\"outer_cone\":", f);
        json_numf(f, l->outer_cone);
        fputc('}', f);
    }
    fputs("],\"camera\":{\"position\":", f);
    json_v3(f, c->pos);
    fputs(",\"direction\":", f);
    json_v3(f, c->dir);
    fputs(",\"up\":", f);
    json_v3(f, c->up);
    fputs(",\"yfov\":", f);
    json_num(f, c->yfov);
    fputs(",\"aspect\":", f);
    json_num(f, c->aspect);
    fputs(",\"znear\":", f);
    json_num(f, c->znear);
    fputs(",\"zfar\":", f);
    json_num(f, c->zfar);
    fprintf(f, ",\"from_file\":%s},\"double_sided_twins\":%d,\"ignored\":", c->from_file ? "true" : "false",
            s->ntwins);
    json_string(f, s->ignored ? s->ignored : "");
    fputs(",\"problems\":[", f);
    for (int i = 0; i < s->nproblems; i++) {
        const wrt_problem *p = &s->problems[i];
        fprintf(f, "%s{\"kind\":\"%s\",\"mesh\":%d,\"primitive\":%d,\"triangle\":%d,\"what\":",
                i ? "," : "", wrt_scene_problem_name(p->kind), p->mesh, p->prim, p->tri);
        json_string(f, p->what);
        fputc('}', f);
    }
    fputs("]}\n", f);
}

/* The text form: one line per count, then the materials, lights, camera and problems. */
/* Each emissive material: its radiance, its quads and area, the power it sends (pi L_e A,
 * W per channel), whether the operator carries it (Lambertian, albedo > 0 in each
 * emitting channel) and what it costs a light change (docs/emitters.md). */
static void print_emitters(const wrt_scene *s, const int *uses, FILE *f) {
    for (int i = 0; i < s->nmaterials; i++) {
        const wrt_material *m = &s->materials[i];
        if (!(m->emissive[0] > 0 || m->emissive[1] > 0 || m->emissive[2] > 0)) continue;
        double area = 0;
        for (int q = 0; q < s->nquads; q++)
            if (s->quads[q].material == i) area += s->quads[q].area;
        const char *carried = "carried by the operator";
        if (!m->lambertian) carried = "NOT carried (glossy: only Lambertian emitters light other surfaces)";
        else
            for (int c = 0; c < 3; c++)
                if (m->emissive[c] > 0 && !(m->base_color[c] > 0)) carried = "NOT carried in a channel of albedo 0";
        fprintf(f, "  emitter [%d] %-16s L_e (%g, %g, %g) on %d quads, %.4g m^2, power (%.4g, %.4g, %.4g) W; %s; "
                   "cost: %d coefficients added to E per change, no projection, no shadow rays\n",
                i, m->name, m->emissive[0], m->emissive[1], m->emissive[2], uses[i], area, WRT_PI * m->emissive[0] * area,
                WRT_PI * m->emissive[1] * area, WRT_PI * m->emissive[2] * area, carried, uses[i]);
    }
    for (int i = 0; i < s->nmaterials; i++) { /* base-colour textures (docs/textures.md) */
        const wrt_material *m = &s->materials[i];
        if (m->base_tex <= 0 || m->base_tex > s->ntextures) continue;
        const wrt_texture *t = &s->textures[m->base_tex - 1];
        int nuv = 0;
        for (int q = 0; q < s->nquads; q++) nuv += s->quads[q].material == i && s->quads[q].has_uv;
        fprintf(f, "  texture [%d] %-16s base colour %d x %d (%.3g MB), mean (%.3f, %.3f, %.3f); "
                   "%d of %d quads have UVs and get their own albedo; cost: the bake's albedo per element "
                   "(%s), nothing at run time\n",
                i, m->name, t->w, t->h, (double)t->w * t->h * 3 / 1e6, t->mean[0], t->mean[1], t->mean[2], nuv,
                uses[i], m->lambertian ? "exact for a Lambertian material" : "glossy: its diffuse albedo only");
    }
}

static void print_summary_text(const wrt_scene *s, int npara, const int *uses, FILE *f) {
    const wrt_camera *c = &s->camera;
    int ndiffuse = 0;
    for (int i = 0; i < s->nmaterials; i++) ndiffuse += s->materials[i].lambertian;
    fprintf(f, "scene: %d quads (%d parallelograms, %d general convex) from %d triangles\n", s->nquads,
            npara, s->nquads - npara, s->ntriangles);
    fprintf(f, "elements: %d quads from triangle pairs, %d triangles as 3 quads each (%d quads)", s->npaired,
            s->nsingle, 3 * s->nsingle);
    if (s->ntwins) fprintf(f, ", %d double-sided twins", s->ntwins);
    fputc('\n', f);
    if (s->nsingle) {
        fputs("triangles on their own, why:", f);
        for (int k = 0, first = 1; k < WRT_SINGLE_NREASONS; k++)
            if (s->why_single[k]) {
                fprintf(f, "%s %s %d", first ? "" : ",", single_name(k), s->why_single[k]);
                first = 0;
            }
        fputc('\n', f);
    }
    fprintf(f, "dropped: %d triangles (zero area, or narrower than %g of the scene diagonal)\n", s->ndropped,
            WRT_SLIVER_REL);
    if (s->nnonfinite)
        fprintf(f, "non-finite: %d triangles, which refuse the scene unless --drop-bad drops them\n",
                s->nnonfinite);
    if (s->nmirrored)
        fprintf(f, "mirrored: %d mesh instances placed by a negative-determinant transform (winding flipped)\n",
                s->nmirrored);
    if (s->ncoincident)
        fprintf(f, "coincident: %d pairs of elements in the same place facing the same way (light counted "
                "twice; a bake warns naming them)\n", s->ncoincident);
    fprintf(f, "bbox: (%g, %g, %g) - (%g, %g, %g)\n", s->bbox_min.x, s->bbox_min.y, s->bbox_min.z,
            s->bbox_max.x, s->bbox_max.y, s->bbox_max.z);
    fprintf(f, "materials: %d (%d diffuse, %d glossy), %d emissive (sources: docs/emitters.md)\n", s->nmaterials,
            ndiffuse, s->nmaterials - ndiffuse, s->nemissive);
    for (int i = 0; i < s->nmaterials; i++) {
        const wrt_material *m = &s->materials[i];
        fprintf(f, "  [%d] %-24s %s base (%.3f, %.3f, %.3f) metallic %.3f roughness %.3f, %d quads\n", i,
                m->name, m->lambertian ? "diffuse" : "glossy ", m->base_color[0], m->base_color[1],
                m->base_color[2], m->metallic, m->roughness, uses[i]);
    }
    print_emitters(s, uses, f);
    fprintf(f, "lights: %d (numbered from 1, as --light N and --light-scale N=S take them)\n", s->nlights);
    for (int i = 0; i < s->nlights; i++) {
        const wrt_light *l = &s->lights[i];
        if (l->type == WRT_LIGHT_DIRECTIONAL)
            fprintf(f, "  [%d] %-5s %-16s dir (%.3f, %.3f, %.3f) intensity %g lux color (%.3f, %.3f, %.3f)", i + 1, "sun",
                    l->name, l->dir.x, l->dir.y, l->dir.z, l->intensity, l->color[0], l->color[1], l->color[2]);
        else if (l->type == WRT_LIGHT_SPOT)
            fprintf(f, "  [%d] %-5s %-16s at (%g, %g, %g) dir (%.3f, %.3f, %.3f) intensity %g cd color (%.3f, %.3f, %.3f)",
                    i + 1, "spot", l->name, l->pos.x, l->pos.y, l->pos.z, l->dir.x, l->dir.y, l->dir.z, l->intensity,
                    l->color[0], l->color[1], l->color[2]);
        else /* a point light shines every way: no direction to show (docs/walkthrough.md, 1) */
            fprintf(f, "  [%d] %-5s %-16s at (%g, %g, %g) intensity %g cd color (%.3f, %.3f, %.3f)", i + 1, "point",
                    l->name, l->pos.x, l->pos.y, l->pos.z, l->intensity, l->color[0], l->color[1], l->color[2]);
        if (l->type == WRT_LIGHT_SPOT)
            fprintf(f, " cone %.3f/%.3f rad", l->inner_cone, l->outer_cone);
        if (l->range > 0) fprintf(f, " range %g", l->range);
        fputc('\n', f);
    }
    fprintf(f, "camera: %s at (%g, %g, %g) looking (%.3f, %.3f, %.3f) yfov %.3f rad\n",
            c->from_file ? "from file" : "default framing", c->pos.x, c->pos.y, c->pos.z, c->dir.x,
            c->dir.y, c->dir.z, c->yfov);
    if (s->ntwins)
        fprintf(f, "double-sided: %d quads have a back-to-back twin (included in the count above)\n",
                s->ntwins);
    fprintf(f, "ignored (not used by the bake): %s\n", s->ignored && s->ignored[0] ? s->ignored : "nothing");
    fprintf(f, "problems: %d\n", s->nproblems);
    for (int i = 0; i < s->nproblems && i < 50; i++) {
        const wrt_problem *p = &s->problems[i];
        fprintf(f, "  mesh %d primitive %d triangle %d: %s: %s\n", p->mesh, p->prim, p->tri,
                wrt_scene_problem_name(p->kind), p->what);
    }
    if (s->nproblems > 50) fprintf(f, "  ... %d more\n", s->nproblems - 50);
}

void wrt_scene_print_summary(const wrt_scene *s, int json, FILE *f) {
    if (!s || !f) return;
    int npara = 0;
    int *uses = wrt_xcalloc((size_t)(s->nmaterials > 0 ? s->nmaterials : 1), sizeof *uses);
    for (int i = 0; i < s->nquads; i++) {
        npara += s->quads[i].parallelogram;
        if (s->quads[i].material >= 0 && s->quads[i].material < s->nmaterials)
            uses[s->quads[i].material]++;
    }
    if (json) print_summary_json(s, npara, uses, f);
    else print_summary_text(s, npara, uses, f);
    free(uses);
}
