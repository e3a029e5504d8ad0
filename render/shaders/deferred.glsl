// Reads one G-buffer texel and lights it; used by the compute and the fragment lighting stages.
#include "shading.glsl"

uniform sampler2D u_gb_albedo;
uniform sampler2D u_gb_normal;
uniform sampler2D u_gb_depth;
uniform mat4 u_inv_view_projection;
uniform vec3 u_eye;
uniform ivec2 u_size;
uniform vec3 u_background;
#ifdef SKY
uniform sampler2D u_gb_sky;  // the share of the sky each pixel's surface sees
#endif
#ifdef INDIRECT_FUSED
// The photon gather inside the lighting (photons.fused): the core and its GRID/KDTREE/HEAP
// defines, the map bound by GpuPhotonMap.bind.
#include "photon_gather.glsl"
#endif
#ifdef INDIRECT
// Photon-map irradiance E per pixel (photon_gather.comp.glsl); the indirect light leaving a
// diffuse surface is its diffuse colour / pi * E, scaled by the dimmer like the lights.
uniform sampler2D u_indirect;
#endif

vec3 light_texel(ivec2 p) {
#ifdef TILED_LIGHTS
    use_tile_of(p);
#endif
    use_ao_of(p);
    float depth = texelFetch(u_gb_depth, p, 0).r;
    if (depth >= 1.0) return u_background;
    vec4 albedo = texelFetch(u_gb_albedo, p, 0);
    vec4 normal = texelFetch(u_gb_normal, p, 0);
    g_material_occlusion = gbuffer_occlusion(normal.xyz);
    vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
    vec4 world = u_inv_view_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
    vec3 P = world.xyz / world.w;
    vec3 V = safe_normalize(u_eye - P, vec3(0.0, 0.0, 1.0));
    vec3 N = safe_normalize(normal.xyz, vec3(0.0, 1.0, 0.0));
    use_shadow_mask_of(p, depth, N);
#ifdef SKY
    g_sky_visibility = sky_share(P, N, texelFetch(u_gb_sky, p, 0).r);
#endif
    vec3 c = shade(P, N, V, albedo.rgb, normal.w, albedo.a);
#if defined(INDIRECT) || defined(INDIRECT_FUSED)
#ifdef INDIRECT_FUSED
    vec3 E = gather_irradiance(P, N);
#else
    vec3 E = texelFetch(u_indirect, p, 0).rgb;
#endif
    c = storable(c + albedo.rgb * (1.0 - albedo.a) / PI * E * u_light_scale);
#endif
    return c;
}
