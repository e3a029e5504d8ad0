#version 430
// Stereo reuse (paper 3.3), the scatter half: every left-eye hit point that the right eye also
// sees claims its right-eye pixel. "Sees" is a depth test against the right G-buffer: the
// point the right pixel shows must lie within u_tolerance * depth of the left hit. Several left
// pixels may land on one right pixel; the smallest left index wins (imageAtomicMin), so the
// result does not depend on the order the invocations run in.
layout(local_size_x = 8, local_size_y = 8) in;
#include "common.glsl"
#ifdef BLOCK_RATE
// u_levels (cps_common.glsl): the LEFT eye's level map
#include "cps_common.glsl"
#endif

uniform sampler2D u_left_depth;
uniform sampler2D u_right_depth;
uniform mat4 u_left_inv_view_projection;
uniform mat4 u_right_view_projection;
uniform mat4 u_right_inv_view_projection;
uniform ivec2 u_size;
uniform float u_tolerance;
layout(r32ui, binding = IMAGE_UNIT_WINNER) uniform uimage2D u_winner;

vec3 world_at(sampler2D depth_tex, mat4 inv_vp, ivec2 p, out bool background) {
    float depth = texelFetch(depth_tex, p, 0).r;
    background = depth >= 1.0;
    vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
    vec4 w = inv_vp * vec4(ndc, depth * 2.0 - 1.0, 1.0);
    return w.xyz / w.w;
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_size))) return;
#ifdef BLOCK_RATE
    // Under coarse shading only a block's sample pixel holds a gathered value.
    int s = level_at(p);
    ivec2 origin = p & ~((1 << s) - 1);
    if (p != block_sample(origin, s, u_size)) return;
#endif
    bool background;
    vec3 P = world_at(u_left_depth, u_left_inv_view_projection, p, background);
    if (background || any(isnan(P)) || any(isinf(P))) return;
    vec4 clip = u_right_view_projection * vec4(P, 1.0);
    if (!(clip.w > 1e-6)) return;  // behind the right eye (or NaN)
    vec2 ndc = clip.xy / clip.w;
    vec2 f = floor((ndc * 0.5 + 0.5) * vec2(u_size));
    // Bounds checked in float first: a huge coordinate must not wrap when made an int.
    if (any(lessThan(f, vec2(0.0))) || any(greaterThanEqual(f, vec2(u_size)))) return;
    ivec2 q = ivec2(f);
    bool right_background;
    vec3 Q = world_at(u_right_depth, u_right_inv_view_projection, q, right_background);
    if (right_background) return;
    if (length(Q - P) > u_tolerance * clip.w) return;  // occluded, or another surface
    imageAtomicMin(u_winner, q, uint(p.y * u_size.x + p.x));
}
