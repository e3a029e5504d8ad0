#version 430
// Alternating temporal filter (paper 3.2.1), plus reprojection (beyond the paper): each eye
// blends its new image with its previous one, the finer of the two weighted more. With
// REPROJECT the history is read where this pixel's surface was in the previous frame, and
// rejected where that spot showed another surface (disocclusion) or lies off screen. Pixels
// shaded at full rate this frame (level 0: the fovea) are taken as they are.
#include "cps_common.glsl"
uniform sampler2D u_current;  // this frame, filtered
uniform sampler2D u_history;  // previous frame before blending: rgb, a = distance from the eye
uniform sampler2D u_gb_depth;
uniform mat4 u_inv_view_projection;
uniform mat4 u_prev_view_projection;
uniform vec3 u_eye;
uniform vec3 u_prev_eye;
uniform ivec2 u_size;
uniform float u_current_weight;  // the finer image's weight if this frame is the finer one
uniform int u_has_history;

layout(location = 0) out vec4 out_color;
layout(location = 1) out vec4 out_history;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 now = texelFetch(u_current, p, 0).rgb;
    float depth = texelFetch(u_gb_depth, p, 0).r;
    float dist = 0.0;  // 0: background (no surface to track)
    vec3 hist = now;
    bool ok = u_has_history != 0;
    if (depth < 1.0) {
        vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
        vec4 w = u_inv_view_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
        vec3 P = w.xyz / w.w;
        dist = length(P - u_eye);
#ifdef REPROJECT
        vec4 clip = u_prev_view_projection * vec4(P, 1.0);
        if (clip.w <= 0.0) {
            ok = false;
        } else {
            vec2 q = (clip.xy / clip.w * 0.5 + 0.5) * vec2(u_size);
            ok = ok && all(greaterThanEqual(q, vec2(0.0))) && all(lessThan(q, vec2(u_size)));
            if (ok) {
                vec4 h = texelFetch(u_history, ivec2(q), 0);
                float expected = length(P - u_prev_eye);
                ok = h.a > 0.0 && abs(h.a - expected) <= 0.03 * expected + 0.01;
                hist = h.rgb;
            }
        }
#else
        vec4 h = texelFetch(u_history, p, 0);
        hist = h.rgb;
#endif
    } else {
        hist = texelFetch(u_history, p, 0).rgb;
    }
    ok = ok && level_at(p) > 0;
    vec3 c = ok ? mix(hist, now, u_current_weight) : now;
    out_color = vec4(c, 1.0);
    out_history = vec4(now, dist);
}
