#version 430
// The papers' "no mitigation" baseline: every fragment lit in the fragment shader.
#include "material.glsl"
#include "shading.glsl"

uniform vec3 u_eye;
uniform vec3 u_emissive;

layout(location = 0) out vec4 out_color;

void main() {
    vec3 V = safe_normalize(u_eye - v_world, vec3(0.0, 0.0, 1.0));
    g_sky_visibility = surface_sky();
    vec3 lit = shade(v_world, surface_normal(), V, surface_albedo(), u_roughness, u_metallic);
    out_color = vec4(storable(lit + u_emissive), 1.0);
}
