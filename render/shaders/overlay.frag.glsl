#version 430
// Overlay: the statistics text (a small texture drawn by the host) and the gaze marker.
uniform sampler2D u_text;
uniform ivec2 u_text_size;
uniform ivec2 u_view_size;   // whole side-by-side view, pixels
uniform ivec2 u_origin;
uniform vec2 u_gaze;         // normalised in each eye viewport, (0,0) top-left
uniform int u_gaze_fixed;
uniform int u_show_text;

out vec4 out_color;

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy) - u_origin;
    ivec2 from_top = ivec2(p.x, u_view_size.y - 1 - p.y);
    vec4 c = vec4(0.0);
    if (u_show_text != 0 && all(lessThan(from_top, u_text_size)) && all(greaterThanEqual(from_top, ivec2(0)))) {
        c = texelFetch(u_text, ivec2(from_top.x, u_text_size.y - 1 - from_top.y), 0);
    }
    // Gaze ring in both eyes: filled when the gaze is fixed.
    float eye_w = float(u_view_size.x) * 0.5;
    for (int e = 0; e < 2; ++e) {
        vec2 centre = vec2((float(e) + u_gaze.x) * eye_w, (1.0 - u_gaze.y) * float(u_view_size.y));
        float d = length(vec2(p) + 0.5 - centre);
        float ring = u_gaze_fixed != 0 ? step(d, 6.0) : step(abs(d - 8.0), 1.2);
        c = mix(c, vec4(1.0, 0.35, 0.1, 0.9), ring);
    }
    if (c.a <= 0.0) discard;
    out_color = c;
}
