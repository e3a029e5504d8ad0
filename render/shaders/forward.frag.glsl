#version 430
// The papers' "no mitigation" baseline: every fragment lit in the fragment shader. With
// ALPHA_BLEND (the blend pass) the colour goes out with its coverage, over the opaque frame.
#include "alpha_mask.glsl"
#include "shading.glsl"

uniform vec3 u_eye;

layout(location = 0) out vec4 out_color;

void main() {
    alpha_mask();
    use_ao_of(ivec2(gl_FragCoord.xy));
    vec3 V = safe_normalize(u_eye - v_world, vec3(0.0, 0.0, 1.0));
    g_material_occlusion = surface_occlusion();
    vec3 N = surface_normal();
    g_sky_visibility = sky_share(v_world, N, surface_sky());
    vec3 lit = shade(v_world, N, V, surface_albedo(), surface_roughness(), surface_metallic());
#ifdef ALPHA_BLEND
    out_color = vec4(storable(lit + surface_emissive()), clamp(surface_alpha(), 0.0, 1.0));
#else
    out_color = vec4(storable(lit + surface_emissive()), 1.0);
#endif
}
