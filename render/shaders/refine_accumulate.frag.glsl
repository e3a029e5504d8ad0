#version 430
// Progressive refinement (render/refine.py): a running mean of each eye's linear HDR colour
// over jittered samples. One full-screen draw per eye reads this frame's colour and the mean
// so far (one texture of a ping-pong pair) and writes the new mean into the other one.
// rgb: the mean so far; a: how many samples this pixel has. The fovea takes every sample; the
// periphery only those the schedule gives it (app/refine.py), so the fovea converges first.
// COPY: the second draw, the mean written back into the colour (rgb only; the colour's own
// alpha stays), so the exposure meter and the presenter see it.
#ifdef COPY
uniform sampler2D u_history;  // the new mean

layout(location = 0) out vec4 out_color;

void main() {
    vec4 acc = texelFetch(u_history, ivec2(gl_FragCoord.xy), 0);
    if (acc.a <= 0.0) discard;  // no sample yet: the frame as drawn
    out_color = vec4(acc.rgb, 1.0);
}
#else
uniform sampler2D u_current;  // this frame's colour (rgba16f)
uniform sampler2D u_history;  // the mean so far (rgba32f)

uniform int u_restart;         // 1: forget the mean (the first sample at rest)
uniform int u_hold;            // 1: refined; keep the mean as it is
uniform int u_periphery_turn;  // 1: the periphery takes this sample too
uniform vec2 u_gaze_px;        // the gaze in pixels (GL rows, origin bottom-left)
uniform float u_fovea_px;      // the fovea's radius in pixels

layout(location = 0) out vec4 out_mean;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 acc = u_restart != 0 ? vec4(0.0) : texelFetch(u_history, p, 0);
    bool fovea = distance(vec2(p) + 0.5, u_gaze_px) <= u_fovea_px;
    bool take = u_hold == 0 && (u_restart != 0 || fovea || u_periphery_turn != 0);
    if (take) {
        vec3 now = texelFetch(u_current, p, 0).rgb;
        // A non-finite or overflowed sample keeps the mean (or adds black to an empty one).
        bool ok = all(lessThan(abs(now), vec3(65504.0)));
        vec3 rgb = ok ? now : (acc.a > 0.0 ? acc.rgb : vec3(0.0));
        float n = acc.a;
        acc = vec4(mix(acc.rgb, rgb, 1.0 / (n + 1.0)), n + 1.0);
    }
    out_mean = acc;
}
#endif
