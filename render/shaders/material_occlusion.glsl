// The material's ambient occlusion (its occlusion map) for the ambient term of shade(): the
// caller sets g_material_occlusion per pixel before shading (forward: from the map; deferred:
// from the G-buffer, which keeps it as the length of the stored normal, since every reader of
// the normal normalises it anyway).
float g_material_occlusion = 1.0;

float material_occlusion() {
    return g_material_occlusion;
}

vec3 gbuffer_normal(vec3 n, float occlusion) {
    return n * clamp(occlusion, 1.0 / 64.0, 1.0);
}

float gbuffer_occlusion(vec3 stored) {
    float len = length(stored);
    return len > 0.0 ? min(len, 1.0) : 1.0;
}
