#version 430
// Deferred lighting in a fragment shader (same arithmetic as lighting.comp.glsl).
#include "deferred.glsl"

layout(location = 0) out vec4 out_color;

void main() {
    out_color = vec4(light_texel(ivec2(gl_FragCoord.xy)), 1.0);
}
