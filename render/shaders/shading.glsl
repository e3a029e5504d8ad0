// Direct lighting from point lights with a finite range, shared by the deferred lighting
// (compute or fragment) and the forward path, so both paths give the same picture.
#include "common.glsl"

struct PointLight {
    vec4 position_range;   // xyz world position, w range in metres
    vec4 color_intensity;  // rgb linear colour, a intensity
};

layout(std430, binding = 0) readonly buffer Lights {
    PointLight lights[];
};

uniform int u_light_count;
uniform float u_light_scale;  // brightness setting times exposure-independent scale
uniform float u_ambient;

// Smooth window: 1 near the light, exactly 0 at the range, so culling by range is exact.
float range_window(float d2, float range) {
    float x = d2 / (range * range);
    float w = clamp(1.0 - x * x, 0.0, 1.0);
    return w * w;
}

vec3 shade(vec3 P, vec3 N, vec3 V, vec3 albedo, float roughness, float metallic) {
    vec3 diffuse_color = albedo * (1.0 - metallic);
    vec3 spec_color = mix(vec3(0.04), albedo, metallic);
    float shininess = exp2(10.0 * (1.0 - roughness) + 1.0);
    float spec_norm = (shininess + 8.0) / (8.0 * PI);
    vec3 sum = u_ambient * albedo;
    for (int i = 0; i < u_light_count; ++i) {
        vec3 toL = lights[i].position_range.xyz - P;
        float d2 = dot(toL, toL);
        float range = lights[i].position_range.w;
        if (d2 >= range * range) continue;
        vec3 L = toL * inversesqrt(max(d2, 1e-12));
        float ndl = dot(N, L);
        if (ndl <= 0.0) continue;
        vec3 H = safe_normalize(L + V, N);
        float ndh = max(dot(N, H), 0.0);
        float spec = spec_norm * exp2(shininess * log2(max(ndh, 1e-6)));
        vec3 radiance = lights[i].color_intensity.rgb * (lights[i].color_intensity.a * u_light_scale)
                        * range_window(d2, range) / (d2 + 1.0);
        sum += radiance * ndl * (diffuse_color / PI + spec_color * spec);
    }
    return storable(sum);
}
