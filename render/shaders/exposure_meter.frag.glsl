#version 430
// Automatic exposure's meter: one eye's HDR colour reduced to a small grid (64 x 36 per eye),
// each cell the mean log2 luminance of the surfaces among 4 x 4 pixels spread over it (the
// void around a model, where nothing is drawn, is not metered; a cell of only void writes
// NO_SURFACE). Where the sky is drawn it is no void: it is metered as a camera would, so a
// model seen from outside under the sky shows its sky, not a white screen. The CPU reads the grid a frame later (no stall) and meters it
// (app/exposure.py: metered_ev).

uniform sampler2D u_eye_color;
uniform sampler2D u_gb_depth;
uniform ivec2 u_origin;  // this eye's cells start here in the meter target
uniform ivec2 u_cells;   // cells per eye
uniform bool u_meter_sky;  // the sky is drawn where no surface is: meter it too

out float out_log2;

const vec3 LUMA = vec3(0.2126, 0.7152, 0.0722);  // Rec. 709 / sRGB luminance weights
const int SAMPLES = 4;
const float NO_SURFACE = -1000.0;  // app/exposure.py: NO_SURFACE

void main() {
    ivec2 cell = ivec2(gl_FragCoord.xy) - u_origin;
    ivec2 size = textureSize(u_eye_color, 0);
    vec2 span = vec2(size) / vec2(u_cells);
    float sum = 0.0;
    int surfaces = 0;
    for (int j = 0; j < SAMPLES; ++j) {
        for (int i = 0; i < SAMPLES; ++i) {
            vec2 at = (vec2(cell) + (vec2(i, j) + 0.5) / float(SAMPLES)) * span;
            ivec2 p = clamp(ivec2(at), ivec2(0), size - 1);
            if (!u_meter_sky && texelFetch(u_gb_depth, p, 0).r >= 1.0) continue;  // nothing drawn
            // min(): an overflowed half float (inf) meters as the largest finite one.
            float y = min(dot(max(texelFetch(u_eye_color, p, 0).rgb, 0.0), LUMA), 65504.0);
            sum += log2(max(y, 5.96e-8));  // the smallest half float: black is finite
            surfaces += 1;
        }
    }
    out_log2 = surfaces > 0 ? sum / float(surfaces) : NO_SURFACE;
}
