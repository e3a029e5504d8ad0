#version 430
// Indirect light from the irradiance cache (app/irradiance_cache.py): per G-buffer pixel the
// irradiance E looked up, not gathered, into u_out (rgb = E, a = 1 looked up, 0 background),
// the same target the photon gather writes, so the lighting reads it unchanged.
//
// u_irradiance_cache is a 3D RGBA32F texture: the six normal directions' grids (+X, -X, +Y, -Y,
// +Z, -Z) stacked along the axis u_ic_stack (the one with the fewest cells, so that a long hall
// fits GL's 2048 texels a side), each u_ic_dims[u_ic_stack] slices, one empty slice between
// them. rgb = a E, a = the cell's weight (1 where its photons counted for the direction, 0.5
// where it took its neighbours' mean, 0 where nothing is known): the hardware's trilinear
// filter gives sum(w a E) and sum(w a), whose ratio interpolates between the known cells only
// (an empty slice or cell has weight 0, so nothing bleeds between directions or from empty air).
layout(local_size_x = 8, local_size_y = 8) in;

uniform sampler2D u_gb_normal;
uniform sampler2D u_gb_depth;
uniform sampler3D u_irradiance_cache;
uniform mat4 u_inv_view_projection;
uniform ivec2 u_size;
uniform vec3 u_ic_origin;   // corner of cell (0, 0, 0), world metres
uniform float u_ic_cell;    // cell edge
uniform ivec3 u_ic_dims;    // cells per axis (one direction's grid)
uniform int u_ic_stack;     // the axis the grids stack along (0 x, 1 y, 2 z)
layout(rgba32f, binding = IMAGE_UNIT_OUT) writeonly uniform image2D u_out;

vec3 cache_direction(vec3 g, int bucket) {
    // g: the point in cells; the bucket's grid starts at slice bucket * (dims[stack] + 1).
    vec3 texel = clamp(g, vec3(0.5), vec3(u_ic_dims) - 0.5);
    vec3 extent = vec3(u_ic_dims);
    int slices = u_ic_dims[u_ic_stack] + 1;
    texel[u_ic_stack] += float(bucket * slices);
    extent[u_ic_stack] = float(6 * slices);
    vec4 s = textureLod(u_irradiance_cache, texel / extent, 0.0);
    return s.a > 1e-6 ? s.rgb / s.a : vec3(0.0);
}

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, u_size))) return;
    float depth = texelFetch(u_gb_depth, p, 0).r;
    if (depth >= 1.0) {
        imageStore(u_out, p, vec4(0.0));
        return;
    }
    vec2 ndc = (vec2(p) + 0.5) / vec2(u_size) * 2.0 - 1.0;
    vec4 world = u_inv_view_projection * vec4(ndc, depth * 2.0 - 1.0, 1.0);
    vec3 P = world.xyz / world.w;
    vec3 N = texelFetch(u_gb_normal, p, 0).xyz;
    float len2 = dot(N, N);
    N = len2 > 1e-12 ? N * inversesqrt(len2) : vec3(0.0, 1.0, 0.0);
    vec3 g = (P - u_ic_origin) / u_ic_cell;
    vec3 n2 = N * N;
    vec3 E = n2.x * cache_direction(g, N.x >= 0.0 ? 0 : 1)
           + n2.y * cache_direction(g, N.y >= 0.0 ? 2 : 3)
           + n2.z * cache_direction(g, N.z >= 0.0 ? 4 : 5);
    if (any(isnan(E)) || any(isinf(E))) E = vec3(0.0);
    imageStore(u_out, p, vec4(E, 1.0));
}
