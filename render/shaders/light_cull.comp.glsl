#version 430
// Tiled light culling ("model only what a scene requires"): one invocation per 16x16 tile of
// one eye takes the tile's depth range (depth_bounds.frag.glsl, reduced to one texel per tile)
// and keeps the lights whose sphere of influence (position, range) meets the view-space box
// around the tile's slice of the frustum. Lighting then loops over the tile's list instead of
// every light. A tile whose list would overflow is marked ALL_LIGHTS, so culling never drops
// a light that reaches a pixel. A spot is culled by its range sphere (which holds its cone);
// the sun (range -1) reaches every tile.
layout(local_size_x = 8, local_size_y = 8) in;
#include "light_tiles.glsl"

layout(std140, binding = 0) uniform Lights {
    vec4 light_position_range[MAX_LIGHTS];
    vec4 light_color_intensity[MAX_LIGHTS];
    vec4 light_cone[MAX_LIGHTS];
};
uniform int u_light_count;
uniform sampler2D u_bounds;      // per tile: (nearest, farthest) depth; (2, -1) if no surface
uniform mat4 u_view;             // world -> view
uniform mat4 u_inv_projection;   // clip -> view
uniform ivec2 u_size;            // eye viewport, pixels
uniform ivec2 u_tiles;

layout(r16ui, binding = IMAGE_UNIT_COUNTS) writeonly uniform uimage2D u_counts;
layout(r16ui, binding = IMAGE_UNIT_LISTS) writeonly uniform uimage2D u_lists;

vec3 view_point(vec2 pixel, float depth) {
    vec2 ndc = pixel / vec2(u_size) * 2.0 - 1.0;
    vec4 p = u_inv_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
    return p.xyz / p.w;
}

void main() {
    ivec2 tile = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(tile, u_tiles))) return;
    vec2 range = texelFetch(u_bounds, tile, 0).rg;
    uint n = 0u;
    if (range.x <= range.y) {
        vec2 lo = vec2(tile * LIGHT_TILE);
        vec2 hi = vec2(min(tile * LIGHT_TILE + LIGHT_TILE, u_size));
        vec3 bmin = vec3(1e30), bmax = vec3(-1e30);
        vec3 near_corner[4];
        for (int i = 0; i < 8; ++i) {
            vec2 corner = vec2((i & 1) != 0 ? hi.x : lo.x, (i & 2) != 0 ? hi.y : lo.y);
            vec3 v = view_point(corner, (i & 4) != 0 ? range.y : range.x);
            bmin = min(bmin, v);
            bmax = max(bmax, v);
            if ((i & 4) == 0) near_corner[i] = v;
        }
        // The tile's four side planes through the eye (the box alone is loose where a tile
        // spans a long depth range); each normal is turned to face the tile's centre.
        vec3 centre = view_point(0.5 * (lo + hi), 0.5 * (range.x + range.y));
        vec4 planes[4];
        const ivec2 EDGES[4] = ivec2[4](ivec2(0, 2), ivec2(1, 3), ivec2(0, 1), ivec2(2, 3));
        for (int e = 0; e < 4; ++e) {
            vec3 n = cross(near_corner[EDGES[e].x], near_corner[EDGES[e].y]);
            float len = length(n);
            n = len > 1e-20 ? n / len : vec3(0.0);
            planes[e] = vec4(dot(n, centre) < 0.0 ? -n : n, 0.0);
        }
        for (int i = 0; i < u_light_count; ++i) {
            vec4 pr = light_position_range[i];
            vec3 c = (u_view * vec4(pr.xyz, 1.0)).xyz;
            vec3 d = c - clamp(c, bmin, bmax);
            bool sun = pr.w < 0.0;
            bool reaches = sun || dot(d, d) < pr.w * pr.w;
            for (int e = 0; e < 4 && reaches && !sun; ++e) {
                reaches = dot(planes[e].xyz, c) > -pr.w;
            }
            if (reaches) {
                if (n < uint(MAX_PER_TILE)) {
                    imageStore(u_lists, ivec2(tile.x * MAX_PER_TILE + int(n), tile.y), uvec4(i));
                }
                n += 1u;
            }
        }
    }
    imageStore(u_counts, tile, uvec4(n > uint(MAX_PER_TILE) ? ALL_LIGHTS : n));
}
