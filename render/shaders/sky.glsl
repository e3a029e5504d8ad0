// Daylight in the shading: the sky's diffuse light (cd/m2), occluded by the room (the share of
// the sky seen: app/sky_field.py by place, app/sky_light.py per vertex where the field holds
// none). The sun is a directional light of the light loop (the renderer adds it to the frame's
// lights, so it gets its shadow map). Compiled in with SKY; without it the term is zero and
// costs nothing. #include after shading.glsl's uniforms (and field_grid.glsl).
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

// The sky's share by place (app/sky_field.py): per cell and way of facing, the mean share
// measured near it (-1: none measured); slab 0 of the texture holds +X, +Y, +Z, slab 1 -X,
// -Y, -Z.
uniform sampler3D u_sky_field;
uniform vec4 u_sf_origin_cell;
uniform ivec3 u_sf_dims;

// The share of the sky P sees facing N: the grids on N's side that N leans towards (its
// squared component above SKY_LEAN), trilinear, by those components; ``vertex`` (the share
// interpolated from the vertices) where none holds a share. SkyField.lookup is the CPU twin.
float sky_share(vec3 P, vec3 N, float vertex) {
    vec3 at = slab_coord(P, u_sf_origin_cell, u_sf_dims, 0.0, 2.0);
    vec3 plus = textureLod(u_sky_field, at, 0.0).rgb;
    vec3 minus = textureLod(u_sky_field, at + vec3(0.0, 0.0, 0.5), 0.0).rgb;
    vec3 share = mix(minus, plus, step(0.0, N));
    vec3 n2 = N * N;
    vec3 w = n2 * step(0.0, share) * step(SKY_LEAN, n2);
    float total = w.x + w.y + w.z;
    return total > 0.0 ? dot(w, share) / total : vertex;
}
#else
float sky_share(vec3 P, vec3 N, float vertex) {
    return vertex;
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
