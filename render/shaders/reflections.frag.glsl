#version 430
// Reflections on glossy surfaces (render/reflections.py): the reflected ray is marched through
// the eye's depth buffer; where it meets a surface on screen, the lit picture there replaces
// the even light that the ambient specular term assumed (shading.glsl: the even light times
// the split-sum environment BRDF), blurred by the surface's roughness. A varnished floor then
// mirrors the window, the lamps' shades and the sunlit patch as a path tracer shows them.
// REFLECT_SKY (the sky drawn this frame): a ray that meets nothing on its way and whose
// direction lands on the sky in the picture (an open window, the sky beyond a glass door)
// takes the sky there: the sky is infinitely far, so the point a direction tends to on screen
// is where the picture shows the sky in that direction.
// Traced at half resolution into the pass's own target; reflect_apply.frag.glsl adds it to the
// glossy pixels of the lit picture.
#include "shading.glsl"

uniform sampler2D u_gb_albedo;
uniform sampler2D u_gb_normal;
uniform sampler2D u_gb_depth;
uniform sampler2D u_reflect_source;  // the lit picture before this pass, with its mipmaps
uniform mat4 u_view_projection;
uniform mat4 u_inv_view_projection;
uniform vec3 u_eye;
uniform ivec2 u_size;  // the eye's full size (the G-buffer's)
uniform vec2 u_depth_terms;  // view distance = y / (ndc_z + x), from the eye's projection
uniform float u_max_roughness;  // rougher surfaces get nothing (their lobe is the even light)

layout(location = 0) out vec4 out_color;

const int STEPS = REFLECT_STEPS;      // geometric steps along the ray
const int REFINE = 3;                 // bisection steps at the first crossing
const float FIRST_STEP_M = 0.04;
const float GROWTH = 1.5;             // each step this much longer: about 10 m in 12 steps

vec3 world_at(vec2 uv, float depth) {
    vec4 w = u_inv_view_projection * vec4(uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

// The ray's clip-space position is linear in its length: C0 + C1 t (no matrix per step).
vec4 g_c0;
vec4 g_c1;

// Where the ray's point at t lands on screen (uv), and how far behind the surface seen there
// it lies along the view axis (> 0: behind); false where it leaves the view.
bool probe(float t, out vec2 uv, out float behind) {
    vec4 c = g_c0 + g_c1 * t;
    behind = -1e9;
    if (c.w <= 1e-4) return false;
    uv = c.xy / c.w * 0.5 + 0.5;
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) return false;
    float d = texelFetch(u_gb_depth, min(ivec2(uv * vec2(u_size)), u_size - 1), 0).r;
    if (d < 1.0) {  // along the view axis, as the ray's c.w
        float den = 2.0 * d - 1.0 + u_depth_terms.x;
        behind = c.w - u_depth_terms.y / (abs(den) > 1e-9 ? den : -1e-9);
    }
    return true;
}

// A pixel's reflection: true and the light to add where its ray met a surface on screen.
bool reflection(ivec2 p, float depth, vec4 normal, out vec3 add) {
    add = vec3(0.0);
    float roughness = normal.w;
    vec4 albedo = texelFetch(u_gb_albedo, p, 0);
    vec2 uv0 = (vec2(p) + 0.5) / vec2(u_size);
    vec3 P = world_at(uv0, depth);
    vec3 N = safe_normalize(normal.xyz, vec3(0.0, 1.0, 0.0));
    vec3 V = safe_normalize(u_eye - P, vec3(0.0, 0.0, 1.0));
    float ndv = dot(N, V);
    if (ndv <= 0.0) return false;
    vec3 R = reflect(-V, N);

    // March: geometric steps, then bisection between the last point in front and the first
    // one behind; a crossing thicker than the step (a ray passing behind an object) is none.
    vec3 origin = P + N * 0.01;
    g_c0 = u_view_projection * vec4(origin, 1.0);
    g_c1 = u_view_projection * vec4(R, 0.0);
    float t = 0.0;
    float step_m = FIRST_STEP_M;
    float t_front = 0.0;
    bool met = false;
    bool passed_behind = false;  // behind a surface too thick to be this ray's hit
    vec2 hit_uv = uv0;
    for (int i = 0; i < STEPS; ++i) {
        t += step_m;
        vec2 uv;
        float b;
        if (!probe(t, uv, b)) break;
        if (b > 0.0) {
            if (b < max(0.15, 1.5 * step_m)) {
                float lo = t_front;
                float hi = t;
                for (int k = 0; k < REFINE; ++k) {
                    float mid = 0.5 * (lo + hi);
                    vec2 m_uv;
                    float mb;
                    probe(mid, m_uv, mb);
                    if (mb > 0.0) hi = mid; else lo = mid;
                }
                float hb;
                met = probe(hi, hit_uv, hb);
                t = hi;
            } else {
                passed_behind = true;
            }
            break;
        }
        t_front = t;
        step_m *= GROWTH;
    }
    bool sky = false;
    if (!met) {
#ifdef REFLECT_SKY
        // The direction's point at infinity on screen, and the sky there (far depth).
        if (passed_behind || g_c1.w <= 1e-4) return false;
        hit_uv = g_c1.xy / g_c1.w * 0.5 + 0.5;
        if (any(lessThan(hit_uv, vec2(0.0))) || any(greaterThan(hit_uv, vec2(1.0)))) return false;
        if (texelFetch(u_gb_depth, min(ivec2(hit_uv * vec2(u_size)), u_size - 1), 0).r < 1.0)
            return false;
        sky = true;
#else
        return false;
#endif
    }

    // The reflected light: the picture where the ray met, blurred over the lobe's footprint
    // there (the cone of the roughness, seen from the eye), faded towards the screen's edges
    // (where the picture ends) and towards the rough end.
    float cone = roughness * roughness * REFLECT_CONE;  // the lobe's half-width, radians (about)
    vec3 hit = origin + R * t;
    float focal_px = 0.5 * float(u_size.y) * abs(u_view_projection[1][1]);  // px at depth 1
    // The lobe's width at the hit as seen from the eye (at the sky: its angle alone).
    float footprint_px = sky ? 2.0 * cone * focal_px
                             : 2.0 * t * cone / max(distance(hit, u_eye), 1e-3) * focal_px;
    float lod = clamp(log2(max(footprint_px, 1.0)), 0.0, float(REFLECT_MIPS - 1));
    vec3 seen = textureLod(u_reflect_source, hit_uv, lod).rgb;
    vec2 edge = min(hit_uv, 1.0 - hit_uv);
    float fade = smoothstep(0.0, 0.08, min(edge.x, edge.y));
    fade *= 1.0 - smoothstep(0.6 * u_max_roughness, u_max_roughness, roughness);

    // What the ambient specular term drew for this pixel, to be replaced: the even light times
    // the environment BRDF, occluded as shade() occludes it.
    vec3 spec_color = mix(vec3(0.04), albedo.rgb, albedo.a);
    vec2 env = env_brdf(roughness, clamp(ndv, 0.0, 1.0));
    vec3 lobe = spec_color * env.x + env.y;
    g_material_occlusion = gbuffer_occlusion(normal.xyz);
    vec3 occlusion = occluded_share(material_occlusion(), albedo.rgb);
    vec3 level = even_light(P, N, max(u_ambient + dot(u_ambient_gradient, N), 0.0));
    vec3 here = texelFetch(u_reflect_source, p, 0).rgb;
    // Never below black where the reflection is darker than the even light assumed.
    add = max(lobe * (seen - level) * occlusion * fade, -here);
    return fade > 0.0;
}

void main() {
    // Half resolution: this pixel stands for the full-size pixels 2p .. 2p + 1 and traces 2p.
    // Only glossy pixels get here (the mask's early depth test, render/reflections.py).
    ivec2 p = min(ivec2(gl_FragCoord.xy) * 2, u_size - 1);
    float depth = texelFetch(u_gb_depth, p, 0).r;
    vec4 normal = texelFetch(u_gb_normal, p, 0);
    vec3 add;
    if (!reflection(p, depth, normal, add)) add = vec3(0.0);
    bvec3 bad = bvec3(isnan(add.x) || isinf(add.x), isnan(add.y) || isinf(add.y),
                      isnan(add.z) || isinf(add.z));
    out_color = vec4(clamp(mix(add, vec3(0.0), bad), vec3(-65000.0), vec3(65000.0)), 0.0);
}
