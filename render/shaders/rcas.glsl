// Robust contrast-adaptive sharpening after FSR 1's RCAS (AMD FidelityFX Super Resolution 1,
// MIT, FsrRcasF): each pixel e and its 5-tap cross
//      b
//    d e f
//      h
// becomes (lobe * (b + d + f + h) + e) / (4 lobe + 1) with a negative lobe, the strongest
// that keeps every channel inside [0, 1] given the cross's minimum and maximum (the limiter:
// no clipping), capped at FSR's 0.25 - 1/16 and scaled by u_rcas_con =
// 2^-sharpness (stops; 0 strongest), the result clamped to the cross's range (no ringing:
// an addition to FSR, whose limiter alone lets an edge overshoot its sides). Works on display-encoded colour: the includer defines
// vec3 rcas_fetch(ivec2 p) (a clamped fetch).
uniform float u_rcas_con;

const float RCAS_LIMIT = 0.25 - 1.0 / 16.0;

vec3 rcas(ivec2 p) {
    vec3 b = rcas_fetch(p + ivec2(0, -1)), d = rcas_fetch(p + ivec2(-1, 0));
    vec3 e = rcas_fetch(p), f = rcas_fetch(p + ivec2(1, 0)), h = rcas_fetch(p + ivec2(0, 1));
    vec3 mn4 = min(min(b, d), min(f, h));
    vec3 mx4 = max(max(b, d), max(f, h));
    vec3 hit_min = min(mn4, e) / max(4.0 * mx4, 1e-6);
    vec3 hit_max = (1.0 - max(mx4, e)) / min(4.0 * mn4 - 4.0, -1e-6);
    vec3 lobe3 = max(-hit_min, hit_max);
    float lobe = max(-RCAS_LIMIT, min(max(lobe3.r, max(lobe3.g, lobe3.b)), 0.0)) * u_rcas_con;
    vec3 c = (lobe * (b + d + f + h) + e) / (4.0 * lobe + 1.0);
    // FSR's limiter only keeps the result inside [0, 1]; clamped to the cross's own range as
    // well, a soft step gets steeper without a dark or bright fringe beside it.
    return clamp(c, min(mn4, e), max(mx4, e));
}
