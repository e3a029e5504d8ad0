#version 430
// The glossy pixels as depth (render/reflections.py): 0 where the reflections apply, 1 where
// they do not, so that the reflection passes' depth test leaves the other blocks unshaded
// (llvmpipe shades every pixel of a block through both sides of any branch, but skips a
// block the early depth test rejects whole). At half size (u_step 2) a pixel is glossy when
// the full-size pixel it traces is.
uniform sampler2D u_gb_normal;
uniform sampler2D u_gb_depth;
uniform float u_max_roughness;
uniform int u_step;

void main() {
    ivec2 p = min(ivec2(gl_FragCoord.xy) * u_step, textureSize(u_gb_depth, 0) - 1);
    bool glossy = texelFetch(u_gb_depth, p, 0).r < 1.0
                  && texelFetch(u_gb_normal, p, 0).w < u_max_roughness;
    gl_FragDepth = glossy ? 0.0 : 1.0;
}
