#version 430
// Deferred path: light-emitting surfaces (lamp shades, windows) add their glow after lighting.
// Drawn only for emissive meshes, depth-tested against the G-buffer, so it costs almost nothing.
#include "common.glsl"

uniform vec3 u_emissive;

layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(storable(u_emissive), 0.0);
}
