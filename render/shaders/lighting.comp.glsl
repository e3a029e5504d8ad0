#version 430
// Deferred lighting at full rate: one invocation per pixel.
layout(local_size_x = 8, local_size_y = 8) in;
#include "deferred.glsl"

layout(rgba16f, binding = IMAGE_UNIT_OUT) writeonly uniform image2D u_out;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_size))) return;
    imageStore(u_out, p, vec4(light_texel(p), 1.0));
}
