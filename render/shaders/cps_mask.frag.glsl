#version 430
// The comparison masks on full-rate lighting: where CPS would lower the detail, darken the
// periphery (BLACK_MASK, like Eagle Flight's) or blur it (else, like the CHIBA mask; the blur
// is the lit image's mipmap read at the continuous detail level, so it widens smoothly).
#include "cps_detail.glsl"

uniform sampler2D u_lit;  // full-rate lighting, with mipmaps for the blur

layout(location = 0) out vec4 out_color;

// The detail level as a continuous value (no flooring, no blocks): the mask has no steps.
float detail(vec2 c) {
    vec3 d = view_dir(c);
    float theta = degrees(atan(length(cross(d, u_gaze_dir)), dot(d, u_gaze_dir)));
    float e = max(0.0, (theta - u_fovea_deg) / u_deg_per_level);
    return clamp(min(e, side_cap(c)), 0.0, float(u_max_level));
}

void main() {
    vec2 c = gl_FragCoord.xy;
    float s = detail(c);
#ifdef BLACK_MASK
    vec3 lit = texelFetch(u_lit, ivec2(c), 0).rgb;
    out_color = vec4(lit * (1.0 - s / max(1.0, float(u_max_level))), 1.0);
#else
    out_color = vec4(textureLod(u_lit, c / vec2(u_size), s).rgb, 1.0);
#endif
}
