#version 430
// G-buffer: albedo+metallic, world normal+roughness; depth comes from the depth attachment.
#include "material.glsl"

layout(location = 0) out vec4 out_albedo;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_sky;

void main() {
    out_albedo = vec4(surface_albedo(), u_metallic);
    out_normal = vec4(surface_normal(), u_roughness);
    out_sky = vec4(surface_sky());
}
