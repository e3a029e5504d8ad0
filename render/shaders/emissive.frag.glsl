#version 430
// Deferred path: light-emitting surfaces (lamp shades, windows) add their glow after lighting.
// Drawn only for emissive meshes, depth-tested against the G-buffer, so it costs almost nothing.
#include "alpha_mask.glsl"

layout(location = 0) out vec4 out_color;

void main() {
    alpha_mask();
    out_color = vec4(storable(surface_emissive()), 0.0);
}
