#version 430
// Coarse lighting inside the graphics pipeline: for level s a pass at 1/2^s resolution into
// that level's rectangle of the atlas; a fragment is one 2^s block and is discarded unless the
// block has level s. Level 0 is the full-rate lighting of the fovea.
#include "deferred.glsl"
#include "cps_common.glsl"

uniform int u_level;
uniform ivec2 u_atlas_offset;  // this level's rectangle in the atlas

layout(location = 0) out vec4 out_color;

void main() {
    ivec2 block = ivec2(gl_FragCoord.xy) - u_atlas_offset;
    ivec2 origin = block << u_level;
    if (any(greaterThanEqual(origin, u_size)) || level_at(origin) != u_level) discard;
    out_color = vec4(light_texel(block_sample(origin, u_level, u_size)), float(u_level));
}
