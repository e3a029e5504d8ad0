#version 430
// Screen-space ambient occlusion at half resolution: from each pixel's surface point, rays in
// AO_DIRECTIONS cosine-weighted directions around the normal are marched in AO_STEPS steps up
// to the radius against the depth buffer; a step that ends behind a nearby visible surface is
// a hit. The share of rays that miss estimates the same cosine-weighted visibility the per-vertex
// bake casts with embree. The direction set turns with a fixed 2x2 pattern (no time, no noise
// texture: the same picture every frame) that ao_blur.frag.glsl's 2x2 average takes out.
// Output: r occlusion (1 open), g view depth (for the bilateral upsample).
#include "common.glsl"

uniform sampler2D u_ao_depth;
uniform sampler2D u_ao_normal;
uniform mat4 u_inv_view_projection;
uniform mat4 u_view_projection;
uniform ivec2 u_size;  // full resolution
uniform float u_radius;
uniform float u_depth_a;  // the projection's row 2, column 2
uniform float u_depth_b;  // and row 2, column 3: view depth = b / (ndc_z + a)

layout(location = 0) out vec4 out_ao;

const float TURNS[4] = float[4](0.0, 0.5, 0.75, 0.25);

vec3 world_at(vec2 uv, float depth) {
    vec4 w = u_inv_view_projection * vec4(uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

// View depth of a depth-buffer value (GL perspective: clip.w = B / (ndc_z + A)).
float view_depth(float depth) {
    float den = depth * 2.0 - 1.0 + u_depth_a;  // negative in front of the far plane
    return u_depth_b / (abs(den) > 1e-9 ? den : -1e-9);
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
    float dist = view_depth(depth);
    // Depth precision falls with distance: the bias follows it.
    float bias = 0.01 + 0.004 * dist;
    vec3 T = safe_normalize(cross(abs(N.y) < 0.99 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0), N),
                            vec3(1.0, 0.0, 0.0));
    vec3 B = cross(N, T);
    int cell = (half_p.x & 1) + 2 * (half_p.y & 1);
    float turn = TURNS[cell] / float(AO_DIRECTIONS);  // a quarter of the gap between rays
    float jitter = 0.125 + 0.25 * float(cell);  // and of the gap between steps
    // The projection is linear in homogeneous coordinates: clip(origin + t d) is
    // clip(origin) + t clip(d), one matrix product per ray, none per step.
    vec4 clip0 = u_view_projection * vec4(P + N * bias, 1.0);
    vec2 size = vec2(u_size);
    float open_rays = 0.0;
    for (int i = 0; i < AO_DIRECTIONS; ++i) {
        // cosine-weighted: radius sqrt(u) on the disk, lifted to the hemisphere
        float u = (float(i) + 0.5) / float(AO_DIRECTIONS);
        float r = sqrt(u) * 0.97;
        float phi = 6.2831853 * (float(i) * 0.618034 + turn);
        vec3 d = T * (r * cos(phi)) + B * (r * sin(phi)) + N * sqrt(1.0 - r * r);
        vec4 clip_d = u_view_projection * vec4(d * u_radius, 0.0);
        float hit = 0.0;
        for (int s = 0; s < AO_STEPS; ++s) {
            vec4 clip = clip0 + clip_d * ((float(s) + jitter) / float(AO_STEPS));
            if (clip.w <= 1e-6) break;
            vec2 ndc = clip.xy / clip.w;
            if (any(greaterThan(abs(ndc), vec2(1.0)))) break;  // off screen: open
            float sd = texelFetch(u_ao_depth, ivec2((ndc * 0.5 + 0.5) * size), 0).r;
            float dq = view_depth(sd);
            // behind a visible surface that is near (not a wall far in front of the point)
            if (sd < 1.0 && dq < clip.w - bias && clip.w - dq < u_radius) {
                hit = 1.0;
                break;
            }
        }
        open_rays += 1.0 - hit;
    }
    out_ao = vec4(open_rays / float(AO_DIRECTIONS), dist, 0.0, 1.0);
}
