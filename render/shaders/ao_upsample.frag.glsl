#version 430
// Half-resolution occlusion to full resolution: the four nearest half-resolution texels with
// bilinear weights, each also weighted by how close its surface lies to this pixel's
// (bilateral: occlusion does not bleed across depth edges).
uniform sampler2D u_ao_raw;
uniform sampler2D u_ao_depth;
uniform float u_depth_a;
uniform float u_depth_b;
uniform float u_ao_strength;

layout(location = 0) out vec4 out_ao;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    float depth = texelFetch(u_ao_depth, p, 0).r;
    if (depth >= 1.0) {
        out_ao = vec4(1.0, 0.0, 0.0, 1.0);
        return;
    }
    float den = depth * 2.0 - 1.0 + u_depth_a;  // view depth = b / (ndc_z + a)
    float dist = u_depth_b / (abs(den) > 1e-9 ? den : -1e-9);
    ivec2 last = textureSize(u_ao_raw, 0) - 1;
    vec2 c = (vec2(p) + 0.5) * 0.5 - 0.5;  // this pixel in half-resolution texel units
    ivec2 base = ivec2(floor(c));
    vec2 f = c - vec2(base);
    float tol = 0.03 * dist + 0.02;
    float sum = 0.0;
    float weight = 0.0;
    for (int k = 0; k < 4; ++k) {
        ivec2 o = ivec2(k & 1, k >> 1);
        vec2 raw = texelFetch(u_ao_raw, clamp(base + o, ivec2(0), last), 0).rg;
        vec2 b = mix(1.0 - f, f, vec2(o));
        float w = 1.0 / (1.0 + abs(raw.g - dist) / tol);
        w = b.x * b.y * w * w + 1e-6;
        sum += raw.r * w;
        weight += w;
    }
    float a = sum / weight;
    a = (isnan(a) || isinf(a)) ? 1.0 : clamp(a, 0.0, 1.0);
    out_ao = vec4(mix(1.0, a, u_ao_strength), 0.0, 0.0, 1.0);
}
