// Reconstruction of the coarse lighting: the block colours back to pixels (SPEC C, paper
// 3.2.2), shared by the filter's own pass (cps_filter.frag.glsl) and the present pass that
// folds it in (present.frag.glsl, CPS_FOLD).
//   FROM_ATLAS: block colours in the per-level atlas (fragment pipeline), else a full-size
//               image where every pixel holds its block's colour (compute pipeline).
//   FILTER_HIERARCHICAL / FILTER_BILINEAR / neither: the paper's filter, ordinary bilinear on
//               each pixel's own block grid, or the raw blocks.
// Neighbours outside the viewport are clamped back into it, i.e. into the pixel's own block,
// so borders stay defined. The numpy reference is app/cps.py.
#include "cps_common.glsl"

uniform ivec2 u_size;
#ifdef FROM_ATLAS
uniform sampler2D u_atlas;
uniform ivec2 u_atlas_offsets[CPS_LEVELS];
vec3 block_colour(ivec2 q) {
    int s = level_at(q);
    return texelFetch(u_atlas, u_atlas_offsets[s] + (q >> s), 0).rgb;
}
#else
uniform sampler2D u_blocks;
vec3 block_colour(ivec2 q) {
    return texelFetch(u_blocks, q, 0).rgb;
}
#endif


ivec2 inside(ivec2 q) {
    return clamp(q, ivec2(0), u_size - 1);
}

// lerp(A, B, t) = t A + (1 - t) B, as written in the paper.
vec3 lerp(vec3 a, vec3 b, float t) {
    return mix(b, a, t);
}

vec3 hierarchical(ivec2 p) {
    int L = 1 << level_at(p);
    if (L == 1) return block_colour(p);  // full rate: l = 0, the weights pick t00 alone
    ivec2 O = p & ~(L - 1);
    vec2 l = (vec2(p - O) + 0.5) / float(L) - 0.5;
    int a0 = abs(l.y) > abs(l.x) ? 1 : 0;  // ties: x
    int a1 = 1 - a0;
    float l0 = l[a0];
    float l1 = l[a1];
    ivec2 P0 = p;
    P0[a0] = l0 < 0.0 ? O[a0] - 1 : O[a0] + L;
    P0 = inside(P0);
    ivec2 Q = p;
    Q[a1] = l1 < 0.0 ? O[a1] - 1 : O[a1] + L;
    Q = inside(Q);
    int L0 = 1 << level_at(P0);
    ivec2 O0 = P0 & ~(L0 - 1);
    ivec2 R = P0;
    R[a1] = l1 < 0.0 ? O0[a1] - 1 : O0[a1] + L0;
    R = inside(R);
    float l2 = (float(P0[a1] - O0[a1]) + 0.5) / float(L0) - 0.5;
    vec3 t00 = block_colour(p);
    vec3 t10 = block_colour(P0);
    vec3 t01 = block_colour(Q);
    vec3 t11 = block_colour(R);
    return lerp(lerp(t11, t10, abs(l2)), lerp(t01, t00, abs(l1)), abs(l0));
}

vec3 bilinear(ivec2 p) {
    int L = 1 << level_at(p);
    if (L == 1) return block_colour(p);
    vec2 f = (vec2(p) + 0.5) / float(L) - 0.5;
    ivec2 i = ivec2(floor(f));
    vec2 w = f - vec2(i);
    ivec2 h = ivec2(L >> 1);
    vec3 c00 = block_colour(inside(i * L + h));
    vec3 c10 = block_colour(inside((i + ivec2(1, 0)) * L + h));
    vec3 c01 = block_colour(inside((i + ivec2(0, 1)) * L + h));
    vec3 c11 = block_colour(inside((i + ivec2(1, 1)) * L + h));
    return mix(mix(c00, c10, w.x), mix(c01, c11, w.x), w.y);
}

// The reconstructed lighting of pixel p (eye-local).
vec3 cps_reconstruct(ivec2 p) {
#if defined(FILTER_HIERARCHICAL)
    return hierarchical(p);
#elif defined(FILTER_BILINEAR)
    return bilinear(p);
#else
    return block_colour(p);
#endif
}
