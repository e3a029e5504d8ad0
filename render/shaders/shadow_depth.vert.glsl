#version 430
// Shadow maps: positions only, into one tile of the atlas (render/shadows.py).
layout(location = 0) in vec3 in_position;

uniform mat4 u_light_view_projection;

void main() {
    gl_Position = u_light_view_projection * vec4(in_position, 1.0);
}
