// Daylight in the shading: the sky's diffuse light (cd/m2), occluded per vertex by the room
// (app/sky_light.py). The sun is a directional light of the light loop (the renderer adds it
// to the frame's lights, so it gets its shadow map). Compiled in with SKY; without it the term
// is zero and costs nothing. #include after shading.glsl's uniforms.
float g_sky_visibility = 0.0;  // the caller sets it: the share of the sky this point sees

#ifdef SKY
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
