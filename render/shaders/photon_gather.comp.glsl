#version 430
// Photon gather over one eye's G-buffer: E (irradiance from the photon map) per pixel into
// u_out (rgb = E, a = 1 gathered, 2 reused from the left eye, 0 background).
//   BLOCK_RATE  coarse pixel shading: only each block's light-sample pixel gathers; the other
//               pixels of a block write nothing (the CPS fill spreads the sample).
//   REUSE       right eye: a pixel whose u_reuse_winner is set copies the left eye's result.
//   COUNT       gathered / reused pixels (and the core's visited / within photons).
// Plus the core's defines (photon_gather.glsl): GRID | KDTREE, GRID_REACH, HEAP, HEAP_K, SHARED.
layout(local_size_x = 8, local_size_y = 8) in;
#include "photon_gather.glsl"
#ifdef BLOCK_RATE
#include "cps_common.glsl"
#endif

uniform sampler2D u_gb_normal;
uniform sampler2D u_gb_depth;
uniform mat4 u_inv_view_projection;
uniform ivec2 u_size;
layout(rgba32f, binding = IMAGE_UNIT_OUT) writeonly uniform image2D u_out;
#ifdef REUSE
// PM_NO_WINNER: none; else y * W + x of the left-eye pixel whose hit point lands here.
layout(r32ui, binding = IMAGE_UNIT_REUSE_WINNER) readonly uniform uimage2D u_reuse_winner;
uniform sampler2D u_left_result;
#endif

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    // No early return before the gather: SHARED needs every invocation at its barriers.
    bool inside = all(lessThan(p, u_size));
    bool writes = inside;
#ifdef BLOCK_RATE
    if (writes) {
        int s = clamp(level_at(p), 0, 15);
        ivec2 origin = p & ~((1 << s) - 1);
        writes = all(equal(p, block_sample(origin, s, u_size)));
    }
#endif
    bool has_query = false;  // this invocation gathers
    vec3 P = vec3(0.0);
    vec3 N = vec3(0.0, 1.0, 0.0);
    if (writes) {
        float depth = texelFetch(u_gb_depth, p, 0).r;
        bool reused = false;
#ifdef REUSE
        uint winner = imageLoad(u_reuse_winner, p).r;
        uint pixels = uint(u_size.x) * uint(u_size.y);
        if (depth < 1.0 && winner != PM_NO_WINNER && winner < pixels) {
            ivec2 src = ivec2(int(winner % uint(u_size.x)), int(winner / uint(u_size.x)));
            imageStore(u_out, p, vec4(texelFetch(u_left_result, src, 0).rgb, 2.0));
            reused = true;
#ifdef COUNT
            pm_count(1, 1u);
#endif
        }
#endif
        if (depth >= 1.0) {
            imageStore(u_out, p, vec4(0.0));
        } else if (!reused) {
            vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
            vec4 world = u_inv_view_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
            P = world.xyz / world.w;
            N = safe_normalize(texelFetch(u_gb_normal, p, 0).xyz, vec3(0.0, 1.0, 0.0));
            has_query = true;
        }
    }
    vec3 E = gather_query(P, N, has_query);
    if (has_query) {
        imageStore(u_out, p, vec4(storable(E), 1.0));
#ifdef COUNT
        pm_count(0, 1u);
#endif
    }
}
