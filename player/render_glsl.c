/* render_glsl.c: the GLSL sources of render.c (render_glsl.h). The scene pass's fragment
 * shader holds the direct light (KHR_lights_punctual, the metallic-roughness BRDF as in
 * common/brdf.c), the shadow lookups from the smooth surface's point (common/smooth.h) and
 * the indirect light read from the atlas. Its SHADOW_NEAR must equal render.c's.
 * Depends on nothing. */
#include "render_glsl.h"

const char *const wrt_glsl_scene_vs =
    "#version 450 core\n"
    "layout(location=0) in vec3 a_pos;\n"
    "layout(location=1) in vec3 a_nrm;\n"
    "layout(location=2) in vec2 a_uv;\n"
    "layout(location=3) in vec4 a_base;\n"  /* base colour, metallic */
    "layout(location=4) in vec2 a_rough;\n" /* roughness, lambertian */
    "layout(location=5) in vec4 a_rect;\n"  /* atlas: first inner texel x, y; res */
    "layout(location=6) in vec3 a_emit;\n"  /* emitted radiance x the emitter's scale */
    "layout(location=7) in vec4 a_tex;\n"   /* base-colour texture in u_tex: x, y, w, h (w 0: none) */
    "layout(location=8) in vec4 a_tuv;\n"   /* TEXCOORD_0, wrap modes */
    "layout(location=9) in vec3 a_tfac;\n"  /* baseColorFactor */
    "layout(location=10) in vec3 a_snrm;\n"  /* the mesh's vertex normal at the corner (flat: a_nrm) */
    "layout(location=11) in vec4 a_w;\n"     /* the corner's weights over its smooth source (common/smooth.h) */
    "uniform mat4 u_vp;\n"
    "out vec3 v_pos; out vec2 v_uv; out vec3 v_snrm; out vec4 v_w; flat out int v_q;\n"
    "flat out vec3 v_nrm; flat out vec4 v_base; flat out vec2 v_rough; flat out vec4 v_rect;\n"
    "flat out vec3 v_emit;\n"
    "flat out vec4 v_tex; out vec2 v_tuv; flat out vec2 v_twrap; flat out vec3 v_tfac;\n"
    "void main() {\n"
    "  v_tex = a_tex; v_tuv = a_tuv.xy; v_twrap = a_tuv.zw; v_tfac = a_tfac;\n"
    "  v_pos = a_pos; v_nrm = a_nrm; v_uv = a_uv; v_base = a_base; v_rough = a_rough; v_rect = a_rect;\n"
    "  v_emit = a_emit;\n"
    "  v_snrm = a_snrm; v_w = a_w;\n"
    "  v_q = gl_VertexID / 4;\n" /* the quad: its corners are vertices 4q .. 4q + 3 */
    "  gl_Position = u_vp * vec4(a_pos, 1.0);\n"
    "}\n";

/* The BRDF is common/brdf.c's, formula for formula: glTF 2.0 Appendix B, alpha =
 * max(roughness^2, 1e-3), height-correlated Smith visibility, exactly base/pi for a
 * Lambertian material. */
const char *const wrt_glsl_scene_fs =
    "#version 450 core\n"
    "#define MAXL 16\n"
    "#define SHADOW_NEAR 1e-3\n"
    "in vec3 v_pos; in vec2 v_uv; in vec3 v_snrm; in vec4 v_w; flat in int v_q;\n"
    /* per quad 8 records: its smooth source's vertices (w of the first: 1 if curved), then
     * their normals (common/smooth.h) */
    "layout(std430, binding = 0) readonly buffer smooth_src { vec4 u_src[]; };\n"
    "uniform int u_smooth;\n"
    "flat in vec3 v_nrm; flat in vec4 v_base; flat in vec2 v_rough; flat in vec4 v_rect;\n"
    "flat in vec3 v_emit;\n"
    "flat in vec4 v_tex; in vec2 v_tuv; flat in vec2 v_twrap; flat in vec3 v_tfac;\n"
    "uniform sampler2D u_tex;\n"
    "uniform int u_nlights;\n"
    "uniform vec4 u_lpos[MAXL];\n"  /* position, far distance of its shadow map (sun: its half-width) */
    "uniform vec4 u_lcol[MAXL];\n"  /* colour * intensity * scale, type (0 point, 1 spot, 2 sun) */
    "uniform vec4 u_ldir[MAXL];\n"  /* spot axis, range (0 infinite) */
    "uniform vec4 u_lcone[MAXL];\n" /* cos outer, cos inner, shadow layer, enabled */
    "uniform samplerCubeArrayShadow u_shadow;\n"
    "uniform sampler2DArrayShadow u_sun;\n"
    "uniform float u_sun_texel;\n" /* 2 / the sun maps' size */
    "uniform sampler2D u_atlas;\n"
    "uniform vec2 u_atlas_size;\n"
    "uniform vec3 u_eye;\n"
    "uniform int u_mode;\n"
    "uniform float u_shadow_texel;\n" /* 2 / shadow map size: a texel's angular size */
    "out vec4 o_color;\n"
    "const float PI = 3.14159265358979;\n"
    "vec3 g_base;\n" /* the base colour here: the material's, or its texture's (docs/textures.md) */
    /* glTF's wrap modes on texel index i of n (0 repeat, 1 clamp, 2 mirror) */
    "int twrap(int i, int n, float mode) {\n"
    "  if (mode > 0.5 && mode < 1.5) return clamp(i, 0, n - 1);\n"
    "  int p = mode > 1.5 ? 2 * n : n, k = i - p * int(floor(float(i) / float(p)));\n"
    "  return k < n ? k : p - 1 - k;\n"
    "}\n"
    /* the albedo clamp(factor x texel) at this pixel's TEXCOORD_0, bilinear */
    "vec3 tex_albedo() {\n"
    "  int w = int(v_tex.z), h = int(v_tex.w);\n"
    "  float x = v_tuv.x * v_tex.z - 0.5, y = v_tuv.y * v_tex.w - 0.5, fx = floor(x), fy = floor(y);\n"
    "  int x0 = twrap(int(fx), w, v_twrap.x), x1 = twrap(int(fx) + 1, w, v_twrap.x);\n"
    "  int y0 = twrap(int(fy), h, v_twrap.y), y1 = twrap(int(fy) + 1, h, v_twrap.y);\n"
    "  ivec2 o = ivec2(v_tex.xy);\n"
    "  vec3 a = mix(texelFetch(u_tex, o + ivec2(x0, y0), 0).rgb, texelFetch(u_tex, o + ivec2(x1, y0), 0).rgb, x - fx);\n"
    "  vec3 b = mix(texelFetch(u_tex, o + ivec2(x0, y1), 0).rgb, texelFetch(u_tex, o + ivec2(x1, y1), 0).rgb, x - fx);\n"
    "  return clamp(v_tfac * mix(a, b, y - fy), 0.0, 1.0);\n"
    "}\n"
    "vec3 brdf(vec3 n, vec3 l, vec3 v) {\n"
    "  float nl = dot(n, l), nv = dot(n, v);\n"
    "  if (nl <= 0.0 || nv <= 0.0) return vec3(0.0);\n"
    "  vec3 base = g_base;\n"
    "  if (v_rough.y > 0.5) return base / PI;\n"
    "  float metal = clamp(v_base.a, 0.0, 1.0), r = clamp(v_rough.x, 0.0, 1.0);\n"
    "  float a = max(r * r, 1e-3), a2 = a * a;\n"
    "  vec3 cdiff = mix(base, vec3(0.0), metal), f0 = mix(vec3(0.04), base, metal);\n"
    "  vec3 h = normalize(l + v);\n"
    "  float nh = clamp(dot(n, h), 0.0, 1.0), vh = clamp(dot(v, h), 0.0, 1.0);\n"
    "  vec3 F = f0 + (1.0 - f0) * pow(1.0 - vh, 5.0);\n"
    "  float dd = nh * nh * (a2 - 1.0) + 1.0;\n"
    "  float D = a2 / (PI * dd * dd);\n"
    "  float vis = 0.5 / (nl * sqrt(nv * nv * (1.0 - a2) + a2) + nv * sqrt(nl * nl * (1.0 - a2) + a2));\n"
    "  return (1.0 - F) * cdiff / PI + F * D * vis;\n"
    "}\n"
    "float lit(int i, vec3 p, vec3 n) {\n"
    "  vec3 d = p - u_lpos[i].xyz;\n"
    "  float dist = length(d);\n"
    /* normal offset of about one shadow texel, then a slope-scaled bias along the ray */
    "  float cosl = max(dot(n, -d / dist), 0.05);\n"
    "  vec3 q = d + n * (dist * u_shadow_texel * 1.5);\n"
    "  vec3 aq = abs(q);\n"
    "  float ma = max(aq.x, max(aq.y, aq.z));\n"
    "  ma -= ma * u_shadow_texel * (0.5 + 0.5 / cosl);\n"
    /* the depth the cube face's projection gave the occluder at that major-axis distance */
    "  float f = u_lpos[i].w, nr = f * SHADOW_NEAR;\n"
    "  float ref = 0.5 * ((f + nr) / (f - nr) - 2.0 * f * nr / ((f - nr) * max(ma, nr))) + 0.5;\n"
    "  return texture(u_shadow, vec4(q, u_lcone[i].z), ref);\n"
    "}\n"
    /* a sun: orthographic map over the sphere of radius R about the scene's centre, its
     * frame as sun_view_projection's */
    "float lit_sun(int i, vec3 p, vec3 n) {\n"
    "  vec3 d = u_ldir[i].xyz;\n"
    "  float R = u_lpos[i].w, texel = R * u_sun_texel;\n"
    "  vec3 up0 = abs(d.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);\n"
    "  vec3 rt = normalize(cross(d, up0)), up = cross(rt, d);\n"
    "  float cosl = max(dot(n, -d), 0.05);\n"
    "  vec3 q = p + n * (texel * 1.5);\n"
    "  float s = 0.5 * dot(q, rt) / R + 0.5, t = 0.5 * dot(q, up) / R + 0.5;\n"
    "  float ref = 0.5 * (dot(q, d) - texel * (0.5 + 0.5 / cosl)) / R + 0.5;\n"
    "  return texture(u_sun, vec4(s, t, u_lcone[i].z, ref));\n"
    "}\n"
    "void main() {\n"
    "  g_base = v_base.rgb;\n"
    /* a textured Lambertian quad's indirect light is its mean albedo's (the runtime's):
     * scaled by the texel's albedo over that mean */
    "  vec3 tmod = vec3(1.0);\n"
    "  if (v_tex.z > 0.0) {\n"
    "    vec3 a = tex_albedo();\n"
    "    if (v_rough.y > 0.5) tmod = vec3(v_base.r > 0.0 ? a.r / v_base.r : 0.0, v_base.g > 0.0 ? a.g / v_base.g : 0.0,\n"
    "                                     v_base.b > 0.0 ? a.b / v_base.b : 0.0);\n"
    "    g_base = a;\n"
    "  }\n"
    /* the face's own normal decides which side is seen and offsets the shadow lookups;
     * the mesh's interpolated vertex normal shades (flat faces: the same). On a curved
     * element, the smooth surface of its source's vertex normals (common/smooth.h): the
     * normal interpolated over the source, and the shadow lookups from the point moved
     * onto the blend of the vertices' tangent planes where that lies outside the facet
     * (the shadow terminator of smooth normals on large facets) */
    "  vec3 fn = v_nrm, n = normalize(v_snrm), ps = v_pos;\n"
    "  if (u_smooth != 0 && u_src[8 * v_q].w > 0.5) {\n"
    "    vec3 ns = vec3(0.0), t = vec3(0.0);\n"
    "    for (int k = 0; k < 4; k++) {\n"
    "      vec3 P = u_src[8 * v_q + k].xyz, N = u_src[8 * v_q + 4 + k].xyz;\n"
    "      ns += v_w[k] * N;\n"
    "      t += v_w[k] * (v_pos - dot(v_pos - P, N) * N);\n"
    "    }\n"
    "    n = normalize(ns);\n"
    "    if (dot(t - v_pos, fn) > 0.0) ps = t;\n"
    "  }\n"
    "  vec3 v = u_eye - v_pos;\n"
    "  float vl = length(v);\n"
    "  v /= vl;\n"
    /* a curved mesh's grazing outline: a normal turned from the eye is bent toward it
     * (common/smooth.h, wrt_smooth_facing) */
    "  if (u_smooth != 0 && u_src[8 * v_q].w > 0.5 && dot(n, v) < 0.0) n = normalize(n + (0.01 - dot(n, v)) * v);\n"
    "  vec3 c = vec3(0.0);\n"
    "  if (dot(fn, v) > 0.0) {\n"
    "    if (u_mode != 2) for (int i = 0; i < u_nlights; i++) {\n"
    "      if (u_lcone[i].w == 0.0) continue;\n"
    "      if (u_lcol[i].w > 1.5) {\n" /* a sun */
    "        vec3 ls = -u_ldir[i].xyz;\n"
    "        float nls = dot(n, ls);\n"
    "        if (nls <= 0.0) continue;\n"
    "        c += lit_sun(i, ps, fn) * nls * u_lcol[i].rgb * brdf(n, ls, v);\n"
    "        continue;\n"
    "      }\n"
    "      vec3 l = u_lpos[i].xyz - v_pos;\n"
    "      float d2 = dot(l, l), d = sqrt(d2);\n"
    "      l /= d;\n"
    "      float nl = dot(n, l);\n"
    "      if (nl <= 0.0) continue;\n"
    "      float att = 1.0 / d2;\n"
    "      if (u_lcol[i].w > 0.5) {\n"
    "        float cd = dot(-l, u_ldir[i].xyz);\n"
    "        float co = u_lcone[i].x, ci = u_lcone[i].y;\n"
    "        float t = ci - co > 1e-6 ? clamp((cd - co) / (ci - co), 0.0, 1.0) : (cd >= co ? 1.0 : 0.0);\n"
    "        att *= t * t;\n"
    "      }\n"
    "      if (u_ldir[i].w > 0.0) {\n"
    "        float r = d / u_ldir[i].w, w = clamp(1.0 - r * r * r * r, 0.0, 1.0);\n"
    "        att *= w * w;\n"
    "      }\n"
    "      if (att <= 0.0) continue;\n"
    "      float s = lit(i, ps, fn);\n"
    "      c += s * att * nl * u_lcol[i].rgb * brdf(n, l, v);\n"
    "    }\n"
    "    if (u_mode != 2) c += v_emit;\n" /* an emissive surface, seen from its front */
    "    if (u_mode != 1 && v_rect.z > 0.0) {\n"
    "      vec2 uv = clamp(v_uv, 0.0, 1.0);\n"
    "      c += tmod * texture(u_atlas, (v_rect.xy + uv * v_rect.z) / u_atlas_size).rgb;\n"
    "    }\n"
    "  }\n"
    "  o_color = vec4(c, 1.0);\n"
    "}\n";

const char *const wrt_glsl_shadow_vs =
    "#version 450 core\n"
    "layout(location=0) in vec3 a_pos;\n"
    "uniform mat4 u_vp;\n"
    "void main() { gl_Position = u_vp * vec4(a_pos, 1.0); }\n";

const char *const wrt_glsl_shadow_fs =
    "#version 450 core\n"
    "void main() {}\n";

const char *const wrt_glsl_present_vs =
    "#version 450 core\n"
    "out vec2 v_uv;\n"
    "void main() {\n"
    "  vec2 p = vec2((gl_VertexID & 1) * 4.0 - 1.0, (gl_VertexID & 2) * 2.0 - 1.0);\n"
    "  v_uv = p * 0.5 + 0.5; gl_Position = vec4(p, 0.0, 1.0);\n"
    "}\n";

const char *const wrt_glsl_present_fs =
    "#version 450 core\n"
    "in vec2 v_uv;\n"
    "uniform sampler2D u_img;\n"
    "uniform float u_scale;\n"
    "out vec4 o_color;\n"
    "float enc(float x) { return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055; }\n"
    "void main() {\n"
    "  vec3 c = max(texture(u_img, v_uv).rgb * u_scale, vec3(0.0));\n"
    "  c = c / (1.0 + c);\n"
    "  o_color = vec4(enc(c.r), enc(c.g), enc(c.b), 1.0);\n"
    "}\n";
