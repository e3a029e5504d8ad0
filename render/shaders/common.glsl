// Shared helpers. Every value written to an HDR target goes through storable(): a NaN or inf
// from a degenerate input must never reach the screen or the next frame.
const float PI = 3.14159265358979;

vec3 storable(vec3 c) {
    bvec3 bad = bvec3(isnan(c.x) || isinf(c.x), isnan(c.y) || isinf(c.y), isnan(c.z) || isinf(c.z));
    return clamp(mix(c, vec3(0.0), bvec3(bad)), vec3(0.0), vec3(65000.0));
}

vec3 safe_normalize(vec3 v, vec3 fallback) {
    float len2 = dot(v, v);
    return (len2 > 1e-20 && !isinf(len2)) ? v * inversesqrt(len2) : fallback;
}
