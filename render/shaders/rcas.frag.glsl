#version 430
// RCAS at the drawn size (render.sharpen): the tone-mapped, sRGB-encoded eye (u_eye_color,
// rgba8) sharpened into a second target of the same size, which EASU then enlarges.
uniform sampler2D u_eye_color;
uniform ivec2 u_src_size;  // the drawn eye (or, placed after EASU, the eye in the view)
uniform ivec2 u_origin;  // lower-left corner of the viewport (0 when drawing a target)

out vec4 out_color;

vec3 rcas_fetch(ivec2 p) {
    return texelFetch(u_eye_color, clamp(p, ivec2(0), u_src_size - 1), 0).rgb;
}

#include "rcas.glsl"

void main() {
    out_color = vec4(rcas(ivec2(gl_FragCoord.xy) - u_origin), 1.0);
}
