// Ambient occlusion of the ambient term (render/ao.py, AoPass). The pass leaves each eye a
// full-resolution occlusion image (1: open, already mixed with the strength setting); the
// lighting reads this pixel's value before shading (use_ao_of) and the ambient line multiplies
// by ambient_occlusion(). Without AO the function is exactly 1: today's picture.
#ifdef AO
uniform sampler2D u_ao;
float g_ao = 1.0;

void use_ao_of(ivec2 pixel) {
    float a = texelFetch(u_ao, pixel, 0).r;
    g_ao = (isnan(a) || isinf(a)) ? 1.0 : clamp(a, 0.0, 1.0);
}

float ambient_occlusion() {
    return g_ao;
}
#else
void use_ao_of(ivec2 pixel) {}

float ambient_occlusion() {
    return 1.0;
}
#endif
