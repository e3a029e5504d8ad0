#version 430
// G-buffer: albedo+metallic, world normal (its length: the material's occlusion)+roughness;
// depth comes from the depth attachment. Every material input is per pixel (material.glsl).
#include "alpha_mask.glsl"
#include "material_occlusion.glsl"

layout(location = 0) out vec4 out_albedo;
layout(location = 1) out vec4 out_normal;
layout(location = 2) out vec4 out_sky;

void main() {
    alpha_mask();
    out_albedo = vec4(surface_albedo(), surface_metallic());
    out_normal = vec4(gbuffer_normal(surface_normal(), surface_occlusion()), surface_roughness());
    out_sky = vec4(surface_sky());
}
