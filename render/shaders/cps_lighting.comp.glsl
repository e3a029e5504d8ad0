#version 430
// Coarse lighting in compute, the paper's way. Writes every pixel of a block with the block's
// lighting and its level in alpha.
//   MULTI_LEVEL: one dispatch per level s; an invocation owns one 2^s block of that level.
//   otherwise:   one dispatch; an invocation owns a 32x32 tile and walks its blocks.
layout(local_size_x = 8, local_size_y = 8) in;
#include "deferred.glsl"
#include "cps_common.glsl"

layout(rgba16f, binding = IMAGE_UNIT_OUT) writeonly uniform image2D u_out;
uniform int u_level;  // MULTI_LEVEL only

void fill_block(ivec2 origin, int s) {
    vec4 c = vec4(light_texel(block_sample(origin, s, u_size)), float(s));
    ivec2 end = min(origin + (1 << s), u_size);
    for (int y = origin.y; y < end.y; ++y)
        for (int x = origin.x; x < end.x; ++x)
            imageStore(u_out, ivec2(x, y), c);
}

void main() {
#ifdef MULTI_LEVEL
    ivec2 origin = ivec2(gl_GlobalInvocationID.xy) << u_level;
    if (any(greaterThanEqual(origin, u_size)) || level_at(origin) != u_level) return;
    fill_block(origin, u_level);
#else
    ivec2 tile = ivec2(gl_GlobalInvocationID.xy) * 32;
    if (any(greaterThanEqual(tile, u_size))) return;
    ivec2 end = min(tile + 32, u_size);
    for (int y = tile.y; y < end.y; ++y) {
        for (int x = tile.x; x < end.x; ++x) {
            ivec2 p = ivec2(x, y);
            int s = level_at(p);
            if (any(notEqual(p & ((1 << s) - 1), ivec2(0)))) continue;  // not a block origin
            fill_block(p, s);
        }
    }
#endif
}
