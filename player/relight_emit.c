/* relight_emit.c: emissive surfaces as sources of the transport (docs/emitters.md).
 * A material's emission (glTF emissiveFactor x KHR_materials_emissive_strength, the
 * emitted radiance L_e) leaves each of its quads as a uniform radiosity B = pi L_e. The
 * baked operator's columns carry a sender's reflected light: T[r][s] holds the sender's
 * albedo rho (precompute/dto.c), so a source term u on the sender's (spatial root,
 * angular root) function reaches the receivers as rho u. Putting u = B / rho there (as a
 * uniform irradiance, coefficient u / mean_factor) makes the operator's first term T u
 * exactly the emitter's direct light on every other surface, and its later terms the
 * bounces: X = Op E then holds the emitters' direct and indirect light, with no change to
 * the bake. A channel of albedo 0 has no column to carry it (the bake stores nothing for
 * a black sender), and a glossy emitter's columns are its BRDF's, not a Lambertian
 * emission's: both are reported at creation and not carried. The emission itself (what
 * the camera sees on the emitter) is the display's: player/render.c draws L_e.
 * Each emissive material is scaled at run time like a light (0 switches it off); the
 * result is linear in the scale. Depends on relight_internal.h. */
#include "relight_internal.h"

/* 1 if material m emits (some channel of L_e > 0). */
static int emits(const wrt_material *m) { return m->emissive[0] > 0 || m->emissive[1] > 0 || m->emissive[2] > 0; }

wrt_status relight_setup_emitters(wrt_relight *r) {
    uint32_t nm = r->g->nmaterials;
    r->emit_scale = relight_calloc(r, nm ? nm : 1, sizeof(float));
    if (r->oom) return WRT_ERR_NOMEM;
    for (uint32_t m = 0; m < nm; m++) {
        const wrt_material *mm = &r->mats[m];
        r->emit_scale[m] = 1.0f;
        if (!emits(mm)) continue;
        int nq = 0;
        for (uint32_t q = 0; q < r->g->nquads; q++) nq += r->qi[q].material == (int)m;
        if (!nq) continue;
        r->nemitters++;
        r->e_dirty = 1;
        if (!mm->lambertian) {
            relight_log(r, WRT_LOG_WARN,
                        "relight: emissive material %u '%s' is glossy: its emission lights no other surface "
                        "(only Lambertian emitters are carried by the operator)", m, mm->name);
            continue;
        }
        for (int c = 0; c < 3; c++)
            if (mm->emissive[c] > 0 && !(mm->base_color[c] > 0))
                relight_log(r, WRT_LOG_WARN,
                            "relight: emissive material %u '%s' has albedo 0 in channel %d: its emission in that "
                            "channel lights no other surface (the operator has no column for a black sender)",
                            m, mm->name, c);
    }
    return WRT_OK;
}

/* E += each emitting quad's source term B / rho on its (root, root) function. */
void relight_add_emitters(wrt_relight *r) {
    if (!r->nemitters) return;
    for (uint32_t q = 0; q < r->g->nquads; q++) {
        const quad_info *qi = &r->qi[q];
        const wrt_material *m = &r->mats[qi->material];
        float s = r->emit_scale[qi->material];
        if (s == 0 || !m->lambertian || qi->root_func < 0 || !emits(m)) continue;
        for (int c = 0; c < 3; c++) {
            double rho = m->base_color[c];
            if (!(rho > 0) || !(m->emissive[c] > 0)) continue;
            double b = WRT_PI * m->emissive[c];
            r->E[(size_t)qi->root_func * 3 + c] += (float)(s * b / rho / qi->mean_factor);
        }
    }
}

int wrt_relight_emitter_count(const wrt_relight *r) { return r->nemitters; }

wrt_status wrt_relight_set_emitter_scale(wrt_relight *r, int material, float scale) {
    if (material < 0 || material >= (int)r->g->nmaterials)
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: emitter scale for material %d (the file has %u)", material,
                        r->g->nmaterials);
    if (!(scale >= 0) || !isfinite(scale))
        return wrt_fail(WRT_ERR_INVALID_ARG, "relight: material %d: emitter scale %g is not finite and >= 0",
                        material, (double)scale);
    if (r->emit_scale[material] != scale) {
        r->emit_scale[material] = scale;
        if (emits(&r->mats[material])) r->e_dirty = 1;
    }
    return WRT_OK;
}

float wrt_relight_emitter_scale(const wrt_relight *r, int material) {
    return material < 0 || material >= (int)r->g->nmaterials ? 0.0f : r->emit_scale[material];
}
