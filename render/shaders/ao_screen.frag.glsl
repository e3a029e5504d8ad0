#version 430
// Screen-space ambient occlusion at half resolution: from each pixel's surface point, rays in
// AO_DIRECTIONS cosine-weighted directions around the normal are marched in AO_STEPS steps up
// to the radius against the depth buffer; a step that ends behind a nearby visible surface is
// a hit. The share of rays that miss estimates the same cosine-weighted visibility the per-vertex
// bake casts with embree. The direction set turns with a fixed 4x4 pattern (no time, no noise
// texture: the same picture every frame) that the upsample's 4x4 filter averages out.
// Output: r occlusion (1 open), g distance to the eye (for the bilateral upsample).
#include "common.glsl"

uniform sampler2D u_ao_depth;
uniform sampler2D u_ao_normal;
uniform mat4 u_inv_view_projection;
uniform mat4 u_view_projection;
uniform vec3 u_eye;
uniform ivec2 u_size;  // full resolution
uniform float u_radius;

layout(location = 0) out vec4 out_ao;

const float BAYER[16] = float[16](0.0, 8.0, 2.0, 10.0, 12.0, 4.0, 14.0, 6.0,
                                  3.0, 11.0, 1.0, 9.0, 15.0, 7.0, 13.0, 5.0);

vec3 world_at(vec2 uv, float depth) {
    vec4 w = u_inv_view_projection * vec4(uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

void main() {
    ivec2 half_p = ivec2(gl_FragCoord.xy);
    ivec2 p = min(half_p * 2, u_size - 1);
    float depth = texelFetch(u_ao_depth, p, 0).r;
    if (depth >= 1.0) {
        out_ao = vec4(1.0, 1e9, 0.0, 1.0);
        return;
    }
    vec2 uv = (vec2(p) + 0.5) / vec2(u_size);
    vec3 P = world_at(uv, depth);
    vec3 N = safe_normalize(texelFetch(u_ao_normal, p, 0).xyz, vec3(0.0, 1.0, 0.0));
    float dist = length(P - u_eye);
    // Depth precision grows with distance: the bias follows it.
    float bias = 0.01 + 0.004 * dist;
    vec3 T = safe_normalize(cross(abs(N.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0), N),
                            vec3(1.0, 0.0, 0.0));
    vec3 B = cross(N, T);
    int cell = (half_p.x & 3) + 4 * (half_p.y & 3);
    float turn = BAYER[cell] / 16.0;
    float jitter = fract(turn * 4.0 + 0.5 / 16.0);
    vec3 origin = P + N * bias;
    float open_rays = 0.0;
    for (int i = 0; i < AO_DIRECTIONS; ++i) {
        // cosine-weighted: radius sqrt(u) on the disk, lifted to the hemisphere
        float u = (float(i) + 0.5) / float(AO_DIRECTIONS);
        float r = sqrt(u) * 0.97;
        float phi = 6.2831853 * (float(i) * 0.618034 + turn);
        vec3 d = T * (r * cos(phi)) + B * (r * sin(phi)) + N * sqrt(1.0 - r * r);
        float hit = 0.0;
        for (int s = 0; s < AO_STEPS; ++s) {
            float t = u_radius * (float(s) + jitter) / float(AO_STEPS);
            vec3 S = origin + d * t;
            vec4 clip = u_view_projection * vec4(S, 1.0);
            if (clip.w <= 1e-6) break;
            vec3 ndc = clip.xyz / clip.w;
            if (any(greaterThan(abs(ndc.xy), vec2(1.0)))) break;  // off screen: open
            vec2 suv = ndc.xy * 0.5 + 0.5;
            float sd = texelFetch(u_ao_depth, ivec2(suv * vec2(u_size)), 0).r;
            if (sd >= 1.0) continue;
            vec3 Q = world_at(suv, sd);
            float dq = length(Q - u_eye);
            float ds = length(S - u_eye);
            // behind a visible surface that is near (not a wall far in front of the point)
            if (dq < ds - bias && ds - dq < u_radius) {
                hit = 1.0;
                break;
            }
        }
        open_rays += 1.0 - hit;
    }
    out_ao = vec4(open_rays / float(AO_DIRECTIONS), dist, 0.0, 1.0);
}
