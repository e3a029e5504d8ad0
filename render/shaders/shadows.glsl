// Spot cones and shadow-map lookups for the light loop (shading.glsl includes this after its
// Lights block). render/shadows.py renders the maps into one depth atlas and fills the block:
// a point light has six tiles (cube faces +x, -x, +y, -y, +z, -z), a spot one perspective tile,
// the sun one orthographic tile fitted to the scene.

layout(std140, binding = 1) uniform Shadows {
    ivec4 shadow_mode;                      // x: 0 off, 1 hard, 2 soft; y: atlas size in texels
    ivec4 shadow_light[MAX_LIGHTS];         // per light: x first tile (-1: none), y tile count,
                                            // z slot in the shadow mask (-1: none)
    mat4 shadow_matrix[MAX_SHADOW_TILES];   // world -> atlas (u, v, depth) after the divide
    vec4 shadow_rect[MAX_SHADOW_TILES];     // the tile in atlas uv: min xy, max xy
    vec4 shadow_texel[MAX_SHADOW_TILES];    // x texel in uv; y texel in metres (per metre of
                                            // distance when z = 1: perspective); w the soft
                                            // edge's half width on the surface (metres)
};
layout(binding = TEXTURE_UNIT_SHADOW_ATLAS) uniform sampler2DShadow u_shadow_atlas;
#ifndef SHADOW_FILTER
#define SHADOW_FILTER 0
#endif

// glTF's smooth cone: full inside the inner angle, 0 outside the outer (points: 1).
float spot_cone(int i, vec3 L) {
    vec4 c = light_cone[i];
    float t = clamp(dot(c.xyz, -L) + c.w, 0.0, 1.0);
    return t * t;
}

// Soft shadows' taps: a Poisson disk of radius 1 (the first SHADOW_TAPS used; all eight over
// the shadow mask's footprint).
const int SHADOW_TAPS = 4;
const float CONTACT_M = 0.1;  // an occluder this near shadows with a hard edge (see below)
const vec2 POISSON[8] = vec2[8](
    vec2(-0.613, 0.617), vec2(0.645, 0.493), vec2(0.421, -0.689), vec2(-0.299, -0.792),
    vec2(0.170, -0.040), vec2(-0.651, -0.168), vec2(-0.108, 0.357), vec2(0.892, -0.091));

// One comparison of an atlas position (clip coordinates of the tile's matrix) against the
// tile's depth (1 lit); the atlas filters bilinearly for soft shadows, nearest for hard ones.
float shadow_tap(vec4 c, vec4 rect, float t) {
    if (c.w <= 0.0) return 1.0;
    vec3 s = c.xyz / c.w;
    if (s.z >= 1.0 || any(lessThan(s.xy, rect.xy)) || any(greaterThan(s.xy, rect.zw)))
        return 1.0;  // beyond the map (the sun's map covers the scene only)
    return texture(u_shadow_atlas, vec3(clamp(s.xy, rect.xy + 0.5 * t, rect.zw - 0.5 * t), s.z));
}

// 1 lit, 0 in shadow. P is moved along its normal by about a texel of the map at P (normal
// offset: no acne on flat floors), the depth pass adds a slope-scaled offset. Soft: taps of a
// rotated Poisson disk on the receiving surface itself (so a slanted floor does not shadow
// itself), each a bilinear comparison, the disk at least ``spread`` wide (metres; the shadow
// mask's footprint, shadow_mask.frag.glsl). SHADOW_FILTER (0 off, 1 hard, 2 soft) is a
// compile-time variant (render.shadows sets it): on llvmpipe a branch on a uniform costs both
// ways. ``taps``: a constant at every call (the loop unrolls once the call is inlined).
float shadow_lookup(int i, vec3 P, vec3 N, vec3 L, float dist, float spread, int taps) {
#if SHADOW_FILTER == 0
    return 1.0;
#else
    ivec4 info = shadow_light[i];
    if (info.x < 0) return 1.0;
    int tile = info.x;
    if (info.y == 6) {
        vec3 v = P - light_position_range[i].xyz;
        vec3 a = abs(v);
        int face = (a.x >= a.y && a.x >= a.z) ? (v.x > 0.0 ? 0 : 1)
                 : (a.y >= a.z) ? (v.y > 0.0 ? 2 : 3) : (v.z > 0.0 ? 4 : 5);
        tile += face;
    }
    vec4 texel = shadow_texel[tile];
    vec4 rect = shadow_rect[tile];
    mat4 M = shadow_matrix[tile];
    float metres = texel.z > 0.5 ? texel.y * dist : texel.y;
    float ndl = clamp(dot(N, L), 0.0, 1.0);
    vec3 Po = P + N * metres * (0.6 + 1.5 * sqrt(1.0 - ndl * ndl));
    vec4 c0 = M * vec4(Po, 1.0);
#if SHADOW_FILTER == 1
    return shadow_tap(c0, rect, texel.x);
#else
    vec3 T = normalize(cross(N, abs(N.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0)));
    vec3 B = cross(N, T);
    // Interleaved gradient noise: a fixed rotation per surface point, no pattern in the edge.
    float angle = 6.2831853 * fract(52.9829189 * fract(dot(P.xz * 173.0 + P.y * 97.0,
                                                              vec2(0.06711056, 0.00583715))));
    float r = max(max(texel.w, 1.5 * metres), spread);
    // The map is linear in the world point: project the disk's two axes once.
    vec4 cu = M * vec4((T * cos(angle) + B * sin(angle)) * r, 0.0);
    vec4 cv = M * vec4((B * cos(angle) - T * sin(angle)) * r, 0.0);
    float sum = 0.0;
    for (int k = 0; k < taps; ++k) {
        sum += shadow_tap(c0 + cu * POISSON[k].x + cv * POISSON[k].y, rect, texel.x);
    }
    // Contact: shut in at P, but lit CONTACT_M nearer the light, the occluder is within a few
    // centimetres, where a light's soft edge is a fraction of a millimetre: the point's own
    // comparison. The disk's taps there lie on the surface carried on past the occluder (a
    // cornice's top into the ceiling, the outside in the sun) and lit it in lines of light.
    float here = shadow_tap(c0, rect, texel.x);
    float nearer = shadow_tap(M * vec4(Po + L * CONTACT_M, 1.0), rect, texel.x);
    return mix(sum / float(taps), here, step(here, 0.5) * step(0.5, nearer));
#endif
#endif
}

// The light's own shadow factor (its soft edge, SHADOW_TAPS taps).
float shadow_factor(int i, vec3 P, vec3 N, vec3 L, float dist) {
    return shadow_lookup(i, P, N, L, dist, 0.0, SHADOW_TAPS);
}
