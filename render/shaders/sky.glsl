// Daylight in the shading: the sky's diffuse light (cd/m2), occluded by the room (the share of
// the sky seen: app/sky_field.py by place, app/sky_light.py per vertex where the field is thin). The sun is a directional light of the light loop (the renderer adds it
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

// The sky's share by place: per cell and way of facing, the sum of the shares measured near it
// and of their weights; slab k of the texture holds axis k's (+ sum, + weight, - sum, - weight).
uniform sampler3D u_sky_field;
uniform vec4 u_sf_origin_cell;
uniform ivec3 u_sf_dims;

// The share of the sky P sees facing N: the three grids on N's side, trilinear, by N's squared
// components, the sums over the weights; ``vertex`` (the share interpolated from the vertices)
// where the grids received little (SURE_WEIGHT). SkyField.lookup is the CPU twin.
float sky_share(vec3 P, vec3 N, float vertex) {
    vec3 dims = vec3(u_sf_dims);
    vec3 g = clamp((P - u_sf_origin_cell.xyz) / u_sf_origin_cell.w, vec3(0.5), dims - 0.5);
    vec2 xy = g.xy / dims.xy;
    vec4 x = textureLod(u_sky_field, vec3(xy, g.z / (3.0 * dims.z)), 0.0);
    vec4 y = textureLod(u_sky_field, vec3(xy, (g.z + dims.z) / (3.0 * dims.z)), 0.0);
    vec4 z = textureLod(u_sky_field, vec3(xy, (g.z + 2.0 * dims.z) / (3.0 * dims.z)), 0.0);
    vec3 n2 = N * N;
    vec2 s = n2.x * (N.x >= 0.0 ? x.rg : x.ba) + n2.y * (N.y >= 0.0 ? y.rg : y.ba)
             + n2.z * (N.z >= 0.0 ? z.rg : z.ba);
    float sure = clamp(s.y / SKY_SURE_WEIGHT, 0.0, 1.0);
    return mix(vertex, s.x / max(s.y, 1e-6), sure);
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
