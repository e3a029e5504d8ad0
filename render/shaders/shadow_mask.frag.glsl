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

void main() {
    ivec2 p = min(ivec2(gl_FragCoord.xy) * u_mask_step + u_mask_step / 2, u_size - 1);
    float depth = texelFetch(u_gb_depth, p, 0).r;
    vec3 N = safe_normalize(texelFetch(u_gb_normal, p, 0).xyz, vec3(0.0, 1.0, 0.0));
    vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
    vec4 world = u_inv_view_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
    vec3 P = world.xyz / world.w;
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
    vec4 m0 = vec4(1.0) - vec4((uvec4(away) >> uvec4(0u, 1u, 2u, 3u)) & 1u);
    vec4 m1 = vec4(1.0) - vec4((uvec4(away) >> uvec4(4u, 5u, 6u, 7u)) & 1u);
    while (todo != 0u) {
        int k = findLSB(todo);
        todo &= todo - 1u;
        int i = u_mask_lights[k >> 2][k & 3];
        vec3 L;
        float dist;
        reaches(i, P, N, L, dist);
        float s = shadow_factor(i, P, N, L, dist);
        m0 = mix(m0, vec4(s), vec4(equal(ivec4(k), ivec4(0, 1, 2, 3))));
        m1 = mix(m1, vec4(s), vec4(equal(ivec4(k), ivec4(4, 5, 6, 7))));
    }
    float den = depth * 2.0 - 1.0 + u_mask_depth.x;
    float dist = u_mask_depth.y / (abs(den) > 1e-9 ? den : -1e-9);
    out_mask = uvec4(packUnorm4x8(m0), packUnorm4x8(m1), floatBitsToUint(dist),
                    packSnorm4x8(vec4(N, 0.0)));
}
