#version 430
// One step of the depth-bounds reduction for light culling: each output texel holds the
// nearest and farthest surface depth (r = min, g = max) of the 2x2 texels below it; texels
// that show only background hold (2, -1). FROM_DEPTH reads the G-buffer depth itself.
#ifdef FROM_DEPTH
uniform sampler2D u_depth;
#else
uniform sampler2D u_bounds;
#endif
uniform ivec2 u_src_size;

layout(location = 0) out vec2 out_bounds;

void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * 2;
    vec2 b = vec2(2.0, -1.0);
    for (int i = 0; i < 4; ++i) {
        ivec2 q = base + ivec2(i & 1, i >> 1);
        if (any(greaterThanEqual(q, u_src_size))) continue;
#ifdef FROM_DEPTH
        float d = texelFetch(u_depth, q, 0).r;
        if (d < 1.0) b = vec2(min(b.x, d), max(b.y, d));
#else
        vec2 c = texelFetch(u_bounds, q, 0).rg;
        b = vec2(min(b.x, c.x), max(b.y, c.y));
#endif
    }
    out_bounds = b;
}
