#version 430
// Side-by-side presentation: left eye on the left half, right on the right; tone map + sRGB.
#include "common.glsl"

uniform sampler2D u_left;
uniform sampler2D u_right;
uniform float u_exposure;
uniform ivec2 u_eye_size;
uniform ivec2 u_origin;  // lower-left corner of the stereo view in the target

out vec4 out_color;

vec3 tonemap(vec3 x) {  // Narkowicz's ACES fit: filmic shoulder, keeps mid-tones.
    return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

vec3 srgb_encode(vec3 c) {
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(0.0031308, c));
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) - u_origin;
    bool right = p.x >= u_eye_size.x;
    ivec2 q = ivec2(right ? p.x - u_eye_size.x : p.x, p.y);
    q = clamp(q, ivec2(0), u_eye_size - 1);
    vec3 hdr = right ? texelFetch(u_right, q, 0).rgb : texelFetch(u_left, q, 0).rgb;
    out_color = vec4(srgb_encode(tonemap(storable(hdr) * u_exposure)), 1.0);
}
