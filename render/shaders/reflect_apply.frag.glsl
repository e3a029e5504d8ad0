#version 430
// The reflections traced at half resolution (reflections.frag.glsl), enlarged bilinearly and
// added to the glossy pixels of the lit picture (the mask's depth test keeps the rest).
uniform sampler2D u_reflect_half;
uniform ivec2 u_size;  // the full size

layout(location = 0) out vec4 out_color;

void main() {
    vec2 uv = gl_FragCoord.xy / vec2(u_size);
    out_color = vec4(texture(u_reflect_half, uv).rgb, 0.0);
}
