#version 430
// The coarse lighting reconstructed into the eye's HDR target, its own pass
// (cps_reconstruct.glsl; render.cps.CpsFilterPass). The present pass folds the same
// reconstruction in when nothing between them needs the pixels (render.present).
#include "cps_reconstruct.glsl"

layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(cps_reconstruct(ivec2(gl_FragCoord.xy)), 1.0);
}
