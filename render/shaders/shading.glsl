// Direct lighting from point, spot and directional lights, shared by the deferred lighting
// (compute or fragment) and the forward path, so both paths give the same picture.
#include "common.glsl"
#include "material_occlusion.glsl"
#include "ao.glsl"

// A uniform block, not a storage buffer: on llvmpipe, SSBO loads in this loop cost 2.5x more
// (measured: 161 ms vs 65 ms for 4 lights at 2x640x720).
// MAX_LIGHTS: injected by the shader loader (render/constants.py).
// Rows filled by render/gpu_scene.py light_rows().
layout(std140, binding = 0) uniform Lights {
    vec4 light_position_range[MAX_LIGHTS];   // xyz world position, w range in metres (-1: sun)
    vec4 light_color_intensity[MAX_LIGHTS];  // rgb linear colour, a candela (sun: lux)
    vec4 light_cone[MAX_LIGHTS];             // spot: axis * scale, offset; sun: its direction
};

uniform int u_light_count;

#ifdef TILED_LIGHTS
// The lights of this pixel's tile (light_cull.comp.glsl); the caller sets the tile first.
#include "light_tiles.glsl"
uniform usampler2D u_tile_counts;
uniform usampler2D u_tile_lists;
ivec2 g_tile = ivec2(0);

void use_tile_of(ivec2 pixel) {
    g_tile = pixel / LIGHT_TILE;
}
#endif
#include "shadows.glsl"
#include "shadow_mask.glsl"
uniform float u_light_scale;  // brightness setting times exposure-independent scale
uniform float u_ambient;
uniform vec3 u_ambient_gradient;  // the even light of normal N: max(u_ambient + g . N, 0)
uniform float u_occluder_return;  // what hides a crease's light sends back (< 0: unknown)
#include "field_grid.glsl"
#ifdef AMBIENT_FIELD
// The even light by place (app/ambient_field.py, render.ambient_by_place): per cell and way of
// facing, the bounce light found there (the one level where none was); slab 0 of the texture
// holds (+X, -X, +Y, -Y), slab 1 (+Z, -Z).
uniform sampler3D u_ambient_field;
uniform vec4 u_af_origin_cell;
uniform ivec3 u_af_dims;

// The bounce light at P for normal N: the three grids on N's side, trilinear, by N's squared
// components, in the colour found there (red and blue stored, green from the luminance;
// AmbientField.lookup and colour_at are the CPU twins). The one level is already in the grid
// where it is unsure (build_field), so ``level`` serves only the variant without a field.
vec3 even_light(vec3 P, vec3 N, float level) {
    vec3 at = slab_coord(P, u_af_origin_cell, u_af_dims, 0.0, 2.0);
    vec4 a = textureLod(u_ambient_field, at, 0.0);
    vec4 b = textureLod(u_ambient_field, at + vec3(0.0, 0.0, 0.5), 0.0);  // the next slab
    vec3 n2 = N * N;
    float lum = n2.x * (N.x >= 0.0 ? a.r : a.g) + n2.y * (N.y >= 0.0 ? a.b : a.a)
                + n2.z * (N.z >= 0.0 ? b.r : b.g);
    float green = max((1.0 - 0.2126 * b.b - 0.0722 * b.a) / 0.7152, 0.0);
    return lum * vec3(b.b, green, b.a);
}
#else
vec3 even_light(vec3 P, vec3 N, float level) {
    return vec3(level);
}
#endif
#include "sky.glsl"

// Smooth window: 1 near the light, exactly 0 at the range, so culling by range is exact.
float range_window(float d2, float range) {
    float x = d2 / (range * range);
    float x2 = x * x;
    float w = clamp(1.0 - x2 * x2, 0.0, 1.0);
    return w * w;
}

// Physical inverse square (E = I cos / d^2 for I candela) with a 10 cm floor on the distance
// (LIGHT_MIN_DIST2, render/constants.py), times the range window: app/scene.py lamp_falloff.
float lamp_falloff(float d2, float range) {
    return range_window(d2, range) / max(d2, LIGHT_MIN_DIST2);
}

// The share of an even surrounding light that a surface reflects by its specular lobe:
// the split-sum environment BRDF in Karis's analytic fit (Unreal Engine 4 on mobile, 2014),
// F0 * x + y for roughness and N.V.
vec2 env_brdf(float roughness, float ndv) {
    const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
    const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
    vec4 r = roughness * c0 + c1;
    float a004 = min(r.x * r.x, exp2(-9.28 * ndv)) * r.x + r.y;
    return vec2(-1.04, 1.04) * a004 + r.zw;
}

// Occlusion of the even light, with what the occluders send back: the part of the hemisphere
// a crease hides is a nearby surface, itself lit. The estimate knows how bright the room's
// surfaces are against the even light they would hide (u_occluder_return: their exitance
// rho (E_direct + E_indirect) over E_indirect; in a lamp-lit room about 1, so a crease is
// barely darker, as a path tracer shows it): visibility + (1 - visibility) x that, at most 1.
// Without it (the fixed ambient), the occluders are taken to be lit by the even light alone
// and as pale as the surface: Jimenez et al. 2016 ("Practical real-time strategies for
// accurate indirect occlusion"), the cubic fit of that multi-bounce occlusion.
vec3 occluded_share(float visibility, vec3 albedo) {
    float x = visibility;
    if (u_occluder_return >= 0.0) {
        return vec3(x + (1.0 - x) * min(u_occluder_return, 1.0));
    }
    vec3 a = 2.0404 * albedo - 0.3324;
    vec3 b = -4.7951 * albedo + 0.6417;
    vec3 c = 2.7552 * albedo + 0.6903;
    return clamp(((x * a + b) * x + c) * x, vec3(x), vec3(1.0));
}

vec3 shade(vec3 P, vec3 N, vec3 V, vec3 albedo, float roughness, float metallic) {
    vec3 diffuse_color = albedo * (1.0 - metallic);
    vec3 spec_color = mix(vec3(0.04), albedo, metallic);
    float shininess = exp2(10.0 * (1.0 - roughness) + 1.0);
    float spec_norm = (shininess + 8.0) / (8.0 * PI);
    // The ambient terms (even light and the sky through the windows), darkened in creases
    // by the material's occlusion map and the ambient occlusion (with their bounce). The even
    // light is reflected as the lamps' is: diffusely by the diffuse colour and by the
    // specular lobe (a varnished floor mirrors the lit walls a little).
    vec3 occlusion = occluded_share(material_occlusion() * ambient_occlusion(), albedo);
    vec2 env = env_brdf(roughness, clamp(dot(N, V), 0.0, 1.0));
    vec3 even = diffuse_color + spec_color * env.x + env.y;
    vec3 level = even_light(P, N, max(u_ambient + dot(u_ambient_gradient, N), 0.0));
    vec3 sum = (level * even + sky_ambient(N, albedo)) * occlusion;
#ifdef TILED_LIGHTS
    uint tile_count = texelFetch(u_tile_counts, g_tile, 0).r;
    bool every = tile_count == ALL_LIGHTS;
    int count = every ? u_light_count : int(tile_count);
    for (int k = 0; k < count; ++k) {
        int i = every ? k : int(texelFetch(u_tile_lists,
                                            ivec2(g_tile.x * MAX_PER_TILE + k, g_tile.y), 0).r);
#else
    for (int i = 0; i < u_light_count; ++i) {
#endif
        vec4 pr = light_position_range[i];
        vec3 L;
        float dist = 0.0;
        float falloff = 1.0;  // the sun: no distance falloff
        if (pr.w < 0.0) {
            L = -light_cone[i].xyz;
        } else {
            vec3 toL = pr.xyz - P;
            float d2 = dot(toL, toL);
            if (d2 >= pr.w * pr.w) continue;
            dist = sqrt(d2);
            L = toL / max(dist, 1e-6);
            falloff = lamp_falloff(d2, pr.w) * spot_cone(i, L);
            if (falloff <= 0.0) continue;
        }
        float ndl = dot(N, L);
        if (ndl <= 0.0) continue;
        falloff *= masked_shadow(i, P, N, L, dist);
        vec3 H = safe_normalize(L + V, N);
        float ndh = max(dot(N, H), 0.0);
        float spec = spec_norm * exp2(shininess * log2(max(ndh, 1e-6)));
        vec3 radiance = light_color_intensity[i].rgb * (light_color_intensity[i].a * u_light_scale)
                        * falloff;
        sum += radiance * ndl * (diffuse_color / PI + spec_color * spec);
    }
    return storable(sum);
}
