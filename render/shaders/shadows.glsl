// Spot cones and shadow-map lookups for the light loop (shading.glsl includes this after its
// Lights block). render/shadows.py renders the maps into one depth atlas and fills the block:
// a point light has six tiles (cube faces +x, -x, +y, -y, +z, -z), a spot one perspective tile,
// the sun one orthographic tile fitted to the scene.

layout(std140, binding = 1) uniform Shadows {
    ivec4 shadow_mode;                      // x: 0 off, 1 hard, 2 soft; y: atlas size in texels
    ivec4 shadow_light[MAX_LIGHTS];         // per light: x first tile (-1: none), y tile count
    mat4 shadow_matrix[MAX_SHADOW_TILES];   // world -> atlas (u, v, depth) after the divide
    vec4 shadow_rect[MAX_SHADOW_TILES];     // the tile in atlas uv: min xy, max xy
    vec4 shadow_texel[MAX_SHADOW_TILES];    // x texel in uv; y texel in metres (per metre of
                                            // distance when z = 1: perspective)
};
layout(binding = TEXTURE_UNIT_SHADOW_ATLAS) uniform sampler2DShadow u_shadow_atlas;

// glTF's smooth cone: full inside the inner angle, 0 outside the outer (points: 1).
float spot_cone(int i, vec3 L) {
    vec4 c = light_cone[i];
    float t = clamp(dot(c.xyz, -L) + c.w, 0.0, 1.0);
    return t * t;
}

float shadow_tap(vec2 uv, float depth, vec4 rect, float half_texel) {
    return texture(u_shadow_atlas, vec3(clamp(uv, rect.xy + half_texel, rect.zw - half_texel),
                                         depth));
}

// 1 lit, 0 in shadow. P is moved along its normal by about a texel of the map at P (normal
// offset: no acne on flat floors), the depth pass adds a slope-scaled offset.
float shadow_factor(int i, vec3 P, vec3 N, vec3 L, float dist) {
    if (shadow_mode.x == 0) return 1.0;
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
    float metres = texel.z > 0.5 ? texel.y * dist : texel.y;
    float soft = shadow_mode.x == 2 ? 1.0 : 0.0;
    float ndl = clamp(dot(N, L), 0.0, 1.0);
    vec3 Po = P + N * metres * (1.0 + soft) * (0.6 + sqrt(1.0 - ndl * ndl));
    vec4 c = shadow_matrix[tile] * vec4(Po, 1.0);
    if (c.w <= 0.0) return 1.0;
    vec3 s = c.xyz / c.w;
    vec4 rect = shadow_rect[tile];
    if (s.z >= 1.0 || any(lessThan(s.xy, rect.xy)) || any(greaterThan(s.xy, rect.zw)))
        return 1.0;  // beyond the map (the sun's map covers the scene only)
    float t = texel.x;
    if (shadow_mode.x == 1) {
        // Hard: one texel's comparison (the centre of a texel: the linear filter adds nothing).
        vec2 uv = (floor(s.xy / t) + 0.5) * t;
        return shadow_tap(uv, s.z, rect, 0.5 * t);
    }
    // Soft: four bilinear comparisons a texel apart (PCF over 4 x 4 texels, tent-weighted).
    float sum = shadow_tap(s.xy + vec2(-t, -t), s.z, rect, 0.5 * t)
              + shadow_tap(s.xy + vec2(t, -t), s.z, rect, 0.5 * t)
              + shadow_tap(s.xy + vec2(-t, t), s.z, rect, 0.5 * t)
              + shadow_tap(s.xy + vec2(t, t), s.z, rect, 0.5 * t);
    return 0.25 * sum;
}
