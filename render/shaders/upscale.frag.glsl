#version 430
// The second half of the present pass when the eyes are drawn smaller (render.scale): the
// eye, already tone-mapped and sRGB-encoded at its drawn size (u_eye_color, rgba8), enlarged
// into its half of the view with FSR 1's EASU (easu.glsl) or, for comparison, bilinearly;
// with RCAS defined EASU reads the eye sharpened (rcas.glsl, render.sharpen).
uniform sampler2D u_eye_color;
uniform ivec2 u_src_size;  // the drawn eye
uniform ivec2 u_dst_size;  // the eye in the view
uniform ivec2 u_origin;  // lower-left corner of this eye's viewport in the target

out vec4 out_color;

vec3 rcas_fetch(ivec2 p) {
    return texelFetch(u_eye_color, clamp(p, ivec2(0), u_src_size - 1), 0).rgb;
}

#ifdef RCAS
// Sharpening folded into the upscaler (render.sharpen): EASU's taps read the drawn eye
// sharpened by RCAS (rcas.glsl), so no extra full-screen pass is needed.
#include "rcas.glsl"
vec3 eye_tap(ivec2 p) { return rcas(clamp(p, ivec2(0), u_src_size - 1)); }
#else
vec3 eye_tap(ivec2 p) { return rcas_fetch(p); }
#endif

#include "easu.glsl"

void main() {
    ivec2 q = ivec2(gl_FragCoord.xy) - u_origin;
    vec2 src_pos = (vec2(q) + 0.5) * vec2(u_src_size) / vec2(u_dst_size);
#ifdef UPSCALE_BILINEAR
    vec3 c = bilinear(src_pos);
#else
    vec3 c = easu(src_pos);
#endif
    out_color = vec4(c, 1.0);
}
