// Daylight in the shading: the sun (a directional light, in lux) and the sky's diffuse light
// (cd/m2), occluded per vertex by the room (app/sky_light.py). Compiled in with SKY; without
// it both terms are zero and cost nothing. #include after shading.glsl's uniforms.
float g_sky_visibility = 0.0;  // the caller sets it: the share of the sky this point sees

#ifdef SKY
uniform vec3 u_sun_to;        // unit vector towards the sun
uniform vec3 u_sun_radiance;  // colour * illuminance (lux) * dimmer; zero below the horizon
uniform vec3 u_sky_sh[9];     // light leaving a white diffuse surface per normal (cd/m2, dimmed)

// Nine spherical harmonics (same order and constants as app/sky_model.py sh_basis).
vec3 sky_sh(vec3 n) {
    return u_sky_sh[0] * 0.282095
         + u_sky_sh[1] * (0.488603 * n.y) + u_sky_sh[2] * (0.488603 * n.z)
         + u_sky_sh[3] * (0.488603 * n.x) + u_sky_sh[4] * (1.092548 * n.x * n.y)
         + u_sky_sh[5] * (1.092548 * n.y * n.z) + u_sky_sh[6] * (0.315392 * (3.0 * n.z * n.z - 1.0))
         + u_sky_sh[7] * (1.092548 * n.x * n.z) + u_sky_sh[8] * (0.546274 * (n.x * n.x - n.y * n.y));
}
#endif

// The sky's light on a diffuse surface: its irradiance for this normal times the share of the
// sky the point sees, times the albedo.
vec3 sky_ambient(vec3 N, vec3 albedo) {
#ifdef SKY
    return albedo * max(sky_sh(N), vec3(0.0)) * g_sky_visibility;
#else
    return vec3(0.0);
#endif
}

// The sun as the light loop treats a lamp, without distance fall-off (no shadow here: the
// shadow maps' branch adds it).
vec3 sun_light(vec3 N, vec3 V, vec3 diffuse_color, vec3 spec_color, float shininess,
               float spec_norm) {
#ifdef SKY
    float ndl = dot(N, u_sun_to);
    if (ndl <= 0.0) return vec3(0.0);
    vec3 H = safe_normalize(u_sun_to + V, N);
    float spec = spec_norm * exp2(shininess * log2(max(dot(N, H), 1e-6)));
    return u_sun_radiance * ndl * (diffuse_color / PI + spec_color * spec);
#else
    return vec3(0.0);
#endif
}
