#version 430
// The quality panel's error heat map over the whole side-by-side view (blended; its alpha
// rises with the error, so correct pixels stay visible underneath).
uniform sampler2D u_heat;    // row 0 at the bottom, the size of the whole view
uniform ivec2 u_origin;
uniform ivec2 u_view_size;

out vec4 out_color;

void main() {
    vec2 uv = (gl_FragCoord.xy - vec2(u_origin)) / vec2(u_view_size);
    out_color = texture(u_heat, uv);
}
