#version 430
// Tiled light culling ("model only what a scene requires"): one work group per 16x16 tile of
// one eye finds the view-space bounding box of the surface points its pixels show (from the
// G-buffer depth) and keeps the lights whose sphere of influence (position, range) meets it. Lighting then loops over the
// tile's list instead of every light. A tile whose list would overflow is marked "all lights"
// (ALL_LIGHTS), so culling can never drop a light that reaches a pixel.
#define TILE 16
layout(local_size_x = TILE, local_size_y = TILE) in;
#include "light_tiles.glsl"

layout(std140, binding = 0) uniform Lights {
    vec4 light_position_range[MAX_LIGHTS];
    vec4 light_color_intensity[MAX_LIGHTS];
};
uniform int u_light_count;
uniform sampler2D u_gb_depth;
uniform mat4 u_view;             // world -> view
uniform mat4 u_inv_projection;   // clip -> view
uniform ivec2 u_size;

layout(r16ui, binding = 1) writeonly uniform uimage2D u_counts;
layout(r16ui, binding = 2) writeonly uniform uimage2D u_lists;

shared uint s_lo[3];  // the box's corners as order-preserving uints (see sortable)
shared uint s_hi[3];
shared uint s_count;
shared uint s_list[MAX_PER_TILE];

vec3 view_point(vec2 pixel, float depth) {
    vec2 ndc = pixel / vec2(u_size) * 2.0 - 1.0;
    vec4 p = u_inv_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
    return p.xyz / p.w;
}

// Float bits as a uint that sorts like the float, so atomicMin/Max work for any sign.
uint sortable(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}

float unsortable(uint u) {
    return uintBitsToFloat((u & 0x80000000u) != 0u ? u & 0x7FFFFFFFu : ~u);
}

void main() {
    ivec2 tile = ivec2(gl_WorkGroupID.xy);
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    uint local = gl_LocalInvocationIndex;
    if (local < 3u) {
        s_lo[local] = 0xFFFFFFFFu;
        s_hi[local] = 0u;
    }
    if (local == 0u) s_count = 0u;
    barrier();
    if (all(lessThan(p, u_size))) {
        float d = texelFetch(u_gb_depth, p, 0).r;
        if (d < 1.0) {  // background pixels are not lit
            vec3 v = view_point(vec2(p) + 0.5, d);
            for (int a = 0; a < 3; ++a) {
                atomicMin(s_lo[a], sortable(v[a]));
                atomicMax(s_hi[a], sortable(v[a]));
            }
        }
    }
    barrier();
    if (s_hi[0] != 0u) {  // some pixel of the tile shows a surface
        // Pixel centres only: widen by the footprint of half a pixel at the farthest point so
        // the box also holds every point a pixel of the tile covers.
        vec3 bmin = vec3(unsortable(s_lo[0]), unsortable(s_lo[1]), unsortable(s_lo[2]));
        vec3 bmax = vec3(unsortable(s_hi[0]), unsortable(s_hi[1]), unsortable(s_hi[2]));
        float far_z = max(abs(bmin.z), abs(bmax.z));
        vec3 step = abs(view_point(vec2(1.0), 0.5) - view_point(vec2(0.0), 0.5));
        float pad = far_z * max(step.x, step.y) / max(abs(view_point(vec2(0.0), 0.5).z), 1e-6);
        bmin -= vec3(pad);
        bmax += vec3(pad);
        for (int i = int(local); i < u_light_count; i += TILE * TILE) {
            vec4 pr = light_position_range[i];
            vec3 c = (u_view * vec4(pr.xyz, 1.0)).xyz;
            vec3 q = clamp(c, bmin, bmax);
            vec3 d = c - q;
            if (dot(d, d) < pr.w * pr.w) {
                uint slot = atomicAdd(s_count, 1u);
                if (slot < uint(MAX_PER_TILE)) s_list[slot] = uint(i);
            }
        }
    }
    barrier();
    uint n = s_count;
    if (local == 0u) {
        imageStore(u_counts, tile, uvec4(n > uint(MAX_PER_TILE) ? ALL_LIGHTS : n));
    }
    if (n <= uint(MAX_PER_TILE)) {
        for (uint k = local; k < n; k += uint(TILE * TILE)) {
            imageStore(u_lists, ivec2(tile.x * MAX_PER_TILE + int(k), tile.y), uvec4(s_list[k]));
        }
    }
}
