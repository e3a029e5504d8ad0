#version 430
// Progressive refinement (render/refine.py): a running mean of each eye's linear HDR colour
// over jittered samples, written back into the colour so the presenter shows the mean.
// rgb: the mean so far; a: how many samples this pixel has. The fovea takes every sample; the
// periphery only those the schedule gives it (app/refine.py), so the fovea converges first.
layout(local_size_x = 8, local_size_y = 8) in;

layout(rgba16f, binding = IMAGE_UNIT_OUT) uniform image2D u_out;
layout(rgba32f, binding = IMAGE_UNIT_ACCUM) uniform image2D u_accum;

uniform ivec2 u_size;
uniform int u_restart;         // 1: forget the mean (the first sample at rest)
uniform int u_hold;            // 1: refined; show the mean as it is
uniform int u_periphery_turn;  // 1: the periphery takes this sample too
uniform vec2 u_gaze_px;        // the gaze in pixels (GL rows, origin bottom-left)
uniform float u_fovea_px;      // the fovea's radius in pixels

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_size))) return;
    vec4 now = imageLoad(u_out, p);
    vec4 acc = u_restart != 0 ? vec4(0.0) : imageLoad(u_accum, p);
    bool fovea = distance(vec2(p) + 0.5, u_gaze_px) <= u_fovea_px;
    bool take = u_hold == 0 && (u_restart != 0 || fovea || u_periphery_turn != 0);
    if (take) {
        float n = acc.a;
        vec3 rgb = all(lessThan(abs(now.rgb), vec3(65504.0))) ? now.rgb : acc.rgb;
        acc = vec4(mix(acc.rgb, rgb, 1.0 / (n + 1.0)), n + 1.0);
        imageStore(u_accum, p, acc);
    }
    if (acc.a > 0.0) imageStore(u_out, p, vec4(acc.rgb, now.a));
}
