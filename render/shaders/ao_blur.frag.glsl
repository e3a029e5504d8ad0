#version 430
// Half resolution: the 2x2 average that takes out ao_screen.frag.glsl's 2x2 turn pattern (every
// 2x2 window holds each turn once), weighted by depth so occlusion does not bleed across edges.
uniform sampler2D u_ao_raw;

layout(location = 0) out vec4 out_ao;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    ivec2 last = textureSize(u_ao_raw, 0) - 1;
    vec2 centre = texelFetch(u_ao_raw, p, 0).rg;
    float tol = 0.03 * centre.g + 0.02;
    float sum = 0.0;
    float weight = 0.0;
    for (int k = 0; k < 4; ++k) {
        vec2 raw = texelFetch(u_ao_raw, min(p + ivec2(k & 1, k >> 1), last), 0).rg;
        float w = 1.0 / (1.0 + abs(raw.g - centre.g) / tol);
        w *= w;
        sum += raw.r * w;
        weight += w;
    }
    out_ao = vec4(sum / max(weight, 1e-8), centre.g, 0.0, 1.0);
}
