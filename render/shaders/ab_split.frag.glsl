#version 430
// The presenter's A/B split, one eye at a time (render/ab_split.py).
// Default: right of the divider the full-quality frame, and the divider line (2 px light,
// a 1 px dark edge each side); the pass's scissor keeps everything left of the line as it is.
// CAPTION: one caption image, blended at its place.

out vec4 out_color;

#ifdef CAPTION
uniform sampler2D u_text;
uniform ivec2 u_caption_origin;  // lower-left of the caption in the target

void main() {
    ivec2 q = ivec2(gl_FragCoord.xy) - u_caption_origin;
    vec4 c = texelFetch(u_text, q, 0);
    if (c.a <= 0.0) discard;
    out_color = c;
}
#else
uniform sampler2D u_ab_reference;  // both eyes at full quality, side by side
uniform ivec2 u_origin;            // lower-left of this eye in the target
uniform ivec2 u_reference_origin;  // lower-left of this eye in the reference image
uniform int u_divider;             // first full-quality column of the eye
uniform vec3 u_line_colour;
uniform vec3 u_edge_colour;

void main() {
    ivec2 q = ivec2(gl_FragCoord.xy) - u_origin;
    int d = q.x - u_divider;
    if (d == -1 || d == 0) {
        out_color = vec4(u_line_colour, 1.0);
    } else if (d == -2 || d == 1) {
        out_color = vec4(u_edge_colour, 1.0);
    } else if (d > 1) {
        out_color = vec4(texelFetch(u_ab_reference, q + u_reference_origin, 0).rgb, 1.0);
    } else {
        discard;
    }
}
#endif
