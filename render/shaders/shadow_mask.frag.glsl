#version 430
// The shadow mask (render/shadow_mask.py): at every u_mask_step-th pixel of each axis the
// shadow factor of up to 8 shadowed lights, 1 lit, 0 in shadow (slots 0-3 in x, 4-7 in y, 8 bits
// each), the sample's view distance (z) and normal (w, 8 bits a component) for the lighting's
// upsample. The G-buffer point of the sample pixel is lit by light u_mask_lights[k]
// when it lies within the light's range and cone and faces it; only those lights look up
// their maps: the loop walks the bits of the lights that reach the point (on llvmpipe both
// sides of a branch run, but a loop stops when no lane has work left, so a pixel pays for the
// lights that reach its neighbourhood, not for all eight).
#include "shading.glsl"

uniform sampler2D u_gb_normal;
uniform sampler2D u_gb_depth;
uniform mat4 u_inv_view_projection;
uniform ivec2 u_size;          // the eye's full resolution
uniform ivec4 u_mask_lights[2];  // the light of each slot (-1: none)

uniform vec2 u_mask_depth;     // view distance = y / (ndc_z + x)
uniform int u_mask_step;       // a sample every this many pixels
uniform mat4 u_view_projection;
uniform float u_mask_spread;   // half a sample's spacing, metres per metre of view distance

layout(location = 0) out uvec4 out_mask;

// Whether light i reaches P (range, cone, facing), and the way to it and its distance.
bool reaches(int i, vec3 P, vec3 N, out vec3 L, out float dist) {
    vec4 pr = light_position_range[i];
    if (pr.w < 0.0) {  // the sun
        L = -light_cone[i].xyz;
        dist = 0.0;
        return dot(N, L) > 0.0;
    }
    vec3 toL = pr.xyz - P;
    float d2 = dot(toL, toL);
    dist = sqrt(d2);
    L = toL / max(dist, 1e-6);
    return d2 < pr.w * pr.w && dot(N, L) > 0.0 && spot_cone(i, L) > 0.0;
}

// The world point of an eye pixel at G-buffer depth d.
vec3 world_at(ivec2 q, float d) {
    vec2 ndc = (vec2(q) + 0.5) / vec2(u_size) * 2.0 - 1.0;
    vec4 w = u_inv_view_projection * vec4(ndc, d * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

#ifdef SUN_FOOTPRINT
// Whether the eye sees, at pixel q, the surface through P facing N (its plane and facing).
bool on_surface(ivec2 q, vec3 P, vec3 N) {
    q = clamp(q, ivec2(0), u_size - 1);
    float d = texelFetch(u_gb_depth, q, 0).r;
    vec3 W = world_at(q, d);
    vec3 Nq = safe_normalize(texelFetch(u_gb_normal, q, 0).xyz, N);
    return d < 1.0 && dot(Nq, N) > 0.9 && abs(dot(W - P, N)) < 0.005 + 0.05 * distance(W, P);
}

// The sun's factor over a sample's footprint on the surface. Through a venetian blind its
// stripes on a floor seen across the room are finer than the samples at every 4th pixel,
// finer even than a pixel (a path tracer's pixels average them into an even patch), and one
// lookup aliased them into blobs. The factor is eight taps over the footprint (half the
// samples' spacing on the surface, stretched as the surface turns from the eye) where the
// eye sees the same surface (its plane and facing) at the footprint's four ends; near an
// edge, where the widened disk would reach behind a wall (outside, in the sun), past a
// table's edge or off a skirting board's narrow top, it is the sun's own soft edge.
float sun_factor(int i, vec3 P, vec3 N, vec3 L, float view_dist, vec3 to_eye) {
    float r = u_mask_spread * view_dist / sqrt(max(abs(dot(N, to_eye)), 0.1));
    vec3 T = normalize(cross(N, abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 B = cross(N, T);
    bool inside = true;
    for (int k = 0; k < 4; ++k) {
        vec3 W = P + ((k & 1) == 0 ? T : B) * ((k & 2) == 0 ? r : -r);
        vec4 c = u_view_projection * vec4(W, 1.0);
        vec2 uv = c.xy / max(c.w, 1e-4) * 0.5 + 0.5;
        inside = inside && c.w > 1e-4 && on_surface(ivec2(uv * vec2(u_size)), P, N);
    }
    return inside ? shadow_lookup(i, P, N, L, 0.0, r, 8) : shadow_factor(i, P, N, L, 0.0);
}
#endif

void main() {
    ivec2 p = min(ivec2(gl_FragCoord.xy) * u_mask_step + u_mask_step / 2, u_size - 1);
    float depth = texelFetch(u_gb_depth, p, 0).r;
    vec3 N = safe_normalize(texelFetch(u_gb_normal, p, 0).xyz, vec3(0.0, 1.0, 0.0));
    vec3 P = world_at(p, depth);
    uint todo = 0u;
    // Lights the sample's surface faces away from: it is in their shadow (0). Kept as 1 they
    // lit the pixels that borrow this sample without one on their own surface: a skirting
    // board's top between samples on the wall and on its front, both facing away from the
    // sun, showed dots of full sunlight.
    uint away = 0u;
    for (int k = 0; k < SHADOW_MASK_SLOTS_USED; ++k) {
        int i = u_mask_lights[k >> 2][k & 3];
        vec3 L;
        float dist;
        if (i < 0) continue;
        if (reaches(i, P, N, L, dist)) {
            todo |= 1u << uint(k);
        } else if (dot(N, L) <= 0.0) {
            away |= 1u << uint(k);
        }
    }
    if (depth >= 1.0) todo = away = 0u;  // the background: nothing to shadow
    float den = depth * 2.0 - 1.0 + u_mask_depth.x;
    float view_dist = u_mask_depth.y / (abs(den) > 1e-9 ? den : -1e-9);
#ifdef SUN_FOOTPRINT
    vec4 near = u_inv_view_projection * vec4((vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0,
                                             -1.0, 1.0);
    vec3 to_eye = safe_normalize(near.xyz / near.w - P, N);
#endif
    vec4 m0 = vec4(1.0) - vec4((uvec4(away) >> uvec4(0u, 1u, 2u, 3u)) & 1u);
    vec4 m1 = vec4(1.0) - vec4((uvec4(away) >> uvec4(4u, 5u, 6u, 7u)) & 1u);
    while (todo != 0u) {
        int k = findLSB(todo);
        todo &= todo - 1u;
        int i = u_mask_lights[k >> 2][k & 3];
        vec3 L;
        float dist;
        reaches(i, P, N, L, dist);
#ifdef SUN_FOOTPRINT  // the sun (no distance) over the sample's footprint
        float s = dist == 0.0 ? sun_factor(i, P, N, L, abs(view_dist), to_eye)
                              : shadow_factor(i, P, N, L, dist);
#else
        float s = shadow_factor(i, P, N, L, dist);
#endif
        m0 = mix(m0, vec4(s), vec4(equal(ivec4(k), ivec4(0, 1, 2, 3))));
        m1 = mix(m1, vec4(s), vec4(equal(ivec4(k), ivec4(4, 5, 6, 7))));
    }
    out_mask = uvec4(packUnorm4x8(m0), packUnorm4x8(m1), floatBitsToUint(view_dist),
                    packSnorm4x8(vec4(N, 0.0)));
}
