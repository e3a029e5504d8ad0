// Coarse pixel shading: the detail level of a pixel (SPEC C; the numpy reference is app/cps.py,
// and tests compare the two). Pixel coordinates are GL window coordinates of one eye's viewport.
//
// desired(c): 0 within the fovea, then one level per u_deg_per_level degrees of angle from the
// gaze ray, capped by the side caps from the edge rays (see side_cap) and by u_max_level. The block-aligned level of pixel p is the largest s whose
// aligned 2^s block has desired(centre) >= s; so every aligned block of level s is uniform, and
// since s = 1 blocks are 2x2 the whole map is stored at half resolution.

uniform ivec2 u_size;          // eye viewport, pixels
uniform mat4 u_inv_projection; // this eye's (off-axis) projection, inverted
uniform vec3 u_gaze_dir;       // view-space unit ray through the gaze point, this eye
uniform vec3 u_caps;           // side caps: left, right, bottom
uniform float u_fovea_deg;
uniform float u_deg_per_level;
uniform int u_max_level;

vec3 view_dir(vec2 c) {
    vec2 ndc = c / vec2(u_size) * 2.0 - 1.0;
    vec4 p = u_inv_projection * vec4(ndc, -1.0, 1.0);
    return normalize(p.xyz / p.w);
}

// The side caps blended over the view: the left cap on the left quarter, the right cap on the
// right quarter, linear between them; the bottom cap ramps in over the lower half.
float side_cap(vec2 c) {
    float u = c.x / float(u_size.x);
    float v = 1.0 - c.y / float(u_size.y);  // 0 at the top, as EyeView.ray's v
    float horizontal = mix(u_caps.x, u_caps.y, clamp((u - 0.25) / 0.5, 0.0, 1.0));
    return max(horizontal, u_caps.z * clamp((v - 0.5) / 0.25, 0.0, 1.0));
}

int desired_level(vec2 c) {
    vec3 d = view_dir(c);
    float theta = degrees(atan(length(cross(d, u_gaze_dir)), dot(d, u_gaze_dir)));
    int e = theta <= u_fovea_deg ? 0 : int(floor((theta - u_fovea_deg) / u_deg_per_level)) + 1;
    int cap = int(floor(side_cap(c)));
    return max(0, min(min(e, cap), u_max_level));
}

int block_level(ivec2 p) {
    for (int s = u_max_level; s >= 1; --s) {
        int size = 1 << s;
        ivec2 origin = p & ~(size - 1);
        vec2 centre = clamp(vec2(origin) + 0.5 * float(size), vec2(0.5), vec2(u_size) - 0.5);
        if (desired_level(centre) >= s) return s;
    }
    return 0;
}
