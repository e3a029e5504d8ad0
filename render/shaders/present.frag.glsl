#version 430
// Presentation of one eye into its half of the side-by-side view: exposure, tone curve
// (exposure_tonemap.glsl: ACES, AgX or a clamp) and sRGB encoding. u_exposure is 1 / L_max,
// L_max = 1.2 * 2^EV100 cd/m2 the luminance shown as white (app/exposure.py), times the
// Brightness. The lighting output is finite (storable); an emissive surface brighter than a
// half float holds (inf) is clamped to the largest one, so the tone curves never see inf/inf.
#include "exposure_tonemap.glsl"
#ifdef CPS_FOLD
// The CPS filter folded in (render.cps.CpsFilterPass): the coarse lighting reconstructed here
// (cps_reconstruct.glsl, with its variant's defines), plus the eye's colour under FOLD_ADD,
// where the passes between added light to a cleared colour (emissive glow).
#include "cps_reconstruct.glsl"
#endif

uniform sampler2D u_eye_color;
uniform float u_exposure;
uniform ivec2 u_origin;  // lower-left corner of this eye's viewport in the target

out vec4 out_color;

#ifdef VISUALIZE
// CPS detail visualisation: finest level unpainted, then blue, cyan, green, yellow, red
// (CPS_LEVELS and CPS_LEVEL_COLOURS injected from render/constants.py).
#ifndef CPS_FOLD
uniform usampler2D u_levels;  // half-resolution level map (cps_common.glsl's when folded)
#endif
const vec3 LEVEL_COLOURS[CPS_LEVELS] = vec3[CPS_LEVELS](CPS_LEVEL_COLOURS);
#endif

#ifdef SHOW_REUSE
// Stereo reuse of the indirect light: right-eye pixels copied from the left eye green,
// gathered ones red (alpha of the irradiance target: 2 reused, 1 gathered).
uniform sampler2D u_indirect;
uniform int u_paint_reuse;  // 1 for the right eye
#endif

vec3 srgb_encode(vec3 c) {
    vec3 curve = 1.055 * exp2(log2(max(c, vec3(1e-7))) * (1.0 / 2.4)) - 0.055;
    return mix(c * 12.92, curve, step(0.0031308, c));
}

void main() {
    ivec2 q = ivec2(gl_FragCoord.xy) - u_origin;
#ifdef CPS_FOLD
    vec3 hdr = cps_reconstruct(q);
#ifdef FOLD_ADD
    hdr += texelFetch(u_eye_color, q, 0).rgb;
#endif
    hdr = min(hdr, vec3(65504.0));
#else
    vec3 hdr = min(texelFetch(u_eye_color, q, 0).rgb, vec3(65504.0));
#endif
    vec3 c = srgb_encode(tone_map(hdr * u_exposure));
#ifdef VISUALIZE
    int s = int(texelFetch(u_levels, q >> 1, 0).r);
    if (s > 0) c = mix(c, LEVEL_COLOURS[min(s, CPS_MAX_LEVEL)], 0.5);
#endif
#ifdef SHOW_REUSE
    if (u_paint_reuse == 1) {
        float how = texelFetch(u_indirect, q, 0).a;
        if (how == 2.0) c = mix(c, vec3(0.1, 0.85, 0.1), 0.45);
        else if (how == 1.0) c = mix(c, vec3(1.0, 0.1, 0.1), 0.45);
    }
#endif
    out_color = vec4(c, 1.0);
}
