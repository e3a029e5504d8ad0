#version 430
// The level map at half resolution: one texel per 2x2 pixel block (see cps_detail.glsl).
#include "cps_detail.glsl"

uniform int u_level_offset;  // temporal filter: 1 on an eye's "weak" frames (one level finer)

layout(location = 0) out uint out_level;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) * 2;
    out_level = uint(max(0, block_level(p) - u_level_offset));
}
