#version 430
// Half-resolution occlusion to full resolution: a 4x4 tent over the half-resolution texels
// (it spans the 4x4 turn pattern of ao_screen.frag.glsl), each weighted by how close its
// surface lies to this pixel's (bilateral: occlusion does not bleed across depth edges).
#include "common.glsl"

uniform sampler2D u_ao_raw;
uniform sampler2D u_ao_depth;
uniform mat4 u_inv_view_projection;
uniform vec3 u_eye;
uniform ivec2 u_size;  // full resolution
uniform float u_ao_strength;

layout(location = 0) out vec4 out_ao;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(u_ao_depth, p, 0).r;
    if (depth >= 1.0) {
        out_ao = vec4(1.0, 0.0, 0.0, 1.0);
        return;
    }
    vec2 uv = (vec2(p) + 0.5) / vec2(u_size);
    vec4 w4 = u_inv_view_projection * vec4(uv * 2.0 - 1.0, depth * 2.0 - 1.0, 1.0);
    float dist = length(w4.xyz / w4.w - u_eye);
    ivec2 half_size = textureSize(u_ao_raw, 0);
    vec2 c = (vec2(p) + 0.5) * 0.5 - 0.5;  // this pixel in half-resolution texel units
    ivec2 base = ivec2(floor(c)) - 1;
    float sum = 0.0;
    float weight = 0.0;
    float tol = 0.03 * dist + 0.02;
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 4; ++x) {
            ivec2 q = clamp(base + ivec2(x, y), ivec2(0), half_size - 1);
            vec2 raw = texelFetch(u_ao_raw, q, 0).rg;
            vec2 off = abs(vec2(base + ivec2(x, y)) - c);
            float w = max(0.0, 2.0 - off.x) * max(0.0, 2.0 - off.y);
            w *= 1.0 / (1.0 + abs(raw.g - dist) / tol);
            w *= w;
            sum += raw.r * w;
            weight += w;
        }
    }
    float a = weight > 1e-8 ? sum / weight : 1.0;
    a = (isnan(a) || isinf(a)) ? 1.0 : clamp(a, 0.0, 1.0);
    out_ao = vec4(mix(1.0, a, u_ao_strength), 0.0, 0.0, 1.0);
}
